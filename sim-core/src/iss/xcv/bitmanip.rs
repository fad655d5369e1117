//! `xcvbitmanip` (CV32E40P manual, "Bit Manipulation operations"):
//! extract, insert, bit clear/set over a field, find first/last one, count
//! leading bits, population count, rotate, bit reversal. One cycle each
//! ("Integer Computational"). A field is `[min(Is3 + Is2, 31) : Is2]`:
//! Is3 + 1 bits from bit Is2, cut at bit 31; the register forms take
//! Is3 = rs2[9:5], Is2 = rs2[4:0].

use super::alu::{
    BCLR, BCLRR, BITREV, BSET, BSETR, CLB, CNT, EXTRACT, EXTRACTR, EXTRACTU, EXTRACTUR, FF1, FL1,
    INSERT, INSERTR, ROR,
};

/// Mask of the field `[min(is3 + is2, 31) : is2]`.
#[inline(always)]
fn field(is3: u32, is2: u32) -> u32 {
    let hi = (is3 + is2).min(31);
    let width = hi - is2 + 1;
    let ones = if width >= 32 {
        u32::MAX
    } else {
        (1u32 << width) - 1
    };
    ones << is2
}

/// `cv.bitrev rD, rs1, Is3, Is2`: shift rs1 left by Is2, then reverse the
/// order of its groups of Is3 + 1 bits (Is3 = 3 acts as 0), counted from
/// bit 31; bits below the last whole group are dropped ("radix 2^(Is3+1)"
/// FFT index; the manual's examples are unit tests below).
pub fn bitrev(x: u32, is3: u32, is2: u32) -> u32 {
    let g = if is3 >= 3 { 1 } else { is3 + 1 };
    let x = x << (is2 & 31);
    let groups = 32 / g;
    let mask = (1u32 << g) - 1;
    (0..groups).fold(0, |acc, k| {
        let from = 32 - g * (k + 1);
        acc | ((x >> from) & mask) << (g * k)
    })
}

/// Execute bit-manipulation function `f` (`imm` = Is3 << 5 | Is2 for the
/// immediate forms).
pub fn exec(f: u32, imm: u32, a: u32, b: u32, d: u32) -> u32 {
    let (is3, is2) = match f {
        EXTRACTR | EXTRACTUR | INSERTR | BCLRR | BSETR => ((b >> 5) & 31, b & 31),
        _ => ((imm >> 5) & 31, imm & 31),
    };
    let m = field(is3, is2);
    match f {
        EXTRACT | EXTRACTR => {
            // Sign extension over the extracted field's top bit.
            let width = m.count_ones();
            let v = (a & m) >> is2;
            let s = 32 - width;
            (((v << s) as i32) >> s) as u32
        }
        EXTRACTU | EXTRACTUR => (a & m) >> is2,
        // rs1's low bits into rD's field; the rest of rD is kept.
        INSERT | INSERTR => (d & !m) | ((a << is2) & m),
        BCLR | BCLRR => a & !m,
        BSET | BSETR => a | m,
        BITREV => bitrev(a, is3, is2),
        ROR => a.rotate_right(b & 31),
        FF1 => a.trailing_zeros(),
        FL1 => {
            if a == 0 {
                32
            } else {
                31 - a.leading_zeros()
            }
        }
        // Leading bits equal to bit 31, minus one; 0 for 0.
        CLB => {
            if a == 0 {
                0
            } else {
                let lead = if a as i32 >= 0 {
                    a.leading_zeros()
                } else {
                    a.leading_ones()
                };
                lead - 1
            }
        }
        CNT => a.count_ones(),
        _ => unreachable!("not a bit-manipulation function: {f}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bitrev_examples_from_the_manual() {
        assert_eq!(bitrev(0xC64A_5933, 0, 4), 0x0CC9_A526);
        assert_eq!(bitrev(0xC64A_5933, 1, 4), 0x0CC6_5A19);
        assert_eq!(bitrev(0xC64A_5933, 2, 4), 0x216B_244B);
        assert_eq!(bitrev(0xC64A_5933, 3, 4), 0x0CC9_A526);
    }

    #[test]
    fn fields_and_counts() {
        // extract 4 bits (Is3 = 3) from bit 8.
        assert_eq!(exec(EXTRACT, 3 << 5 | 8, 0x0000_0f00, 0, 0), u32::MAX);
        assert_eq!(exec(EXTRACTU, 3 << 5 | 8, 0x0000_0f00, 0, 0), 0xf);
        assert_eq!(exec(EXTRACTR, 0, 0x0000_0700, 3 << 5 | 8, 0), 7);
        // A field reaching past bit 31 is cut there.
        assert_eq!(exec(EXTRACTU, 31 << 5 | 28, 0xf000_0000, 0, 0), 0xf);
        assert_eq!(exec(INSERT, 7 << 5 | 4, 0xab, 0, 0xffff_ffff), 0xffff_fabf);
        assert_eq!(exec(INSERTR, 0, 0xab, 7 << 5 | 4, 0), 0xab0);
        assert_eq!(exec(BCLR, 3 << 5 | 4, u32::MAX, 0, 0), 0xffff_ff0f);
        assert_eq!(exec(BSETR, 0, 0, 31 << 5, 0), u32::MAX);
        assert_eq!(exec(FF1, 0, 0, 0, 0), 32);
        assert_eq!(exec(FF1, 0, 0x8000_0000, 0, 0), 31);
        assert_eq!(exec(FL1, 0, 1, 0, 0), 0);
        assert_eq!(exec(FL1, 0, 0, 0, 0), 32);
        assert_eq!(exec(CLB, 0, 0, 0, 0), 0);
        assert_eq!(exec(CLB, 0, 1, 0, 0), 30);
        assert_eq!(exec(CLB, 0, u32::MAX, 0, 0), 31);
        assert_eq!(exec(CNT, 0, 0xf0f0_0001, 0, 0), 9);
        assert_eq!(exec(ROR, 0, 0x0000_0001, 33, 0), 0x8000_0000);
    }

    proptest::proptest! {
        #[test]
        fn extract_insert_round_trip(a: u32, d: u32, is3 in 0u32..32, is2 in 0u32..32) {
            // Bit by bit reference of the field.
            let hi = (is3 + is2).min(31);
            let mut want = 0u32;
            for (k, bit) in (is2..=hi).enumerate() {
                want |= ((a >> bit) & 1) << k;
            }
            let imm = is3 << 5 | is2;
            proptest::prop_assert_eq!(exec(EXTRACTU, imm, a, 0, 0), want);
            let ins = exec(INSERT, imm, want, 0, d);
            proptest::prop_assert_eq!(exec(EXTRACTU, imm, ins, 0, 0), want);
            proptest::prop_assert_eq!(ins & !field(is3, is2), d & !field(is3, is2));
        }
    }
}
