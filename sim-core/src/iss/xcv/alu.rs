//! `xcvalu` (CV32E40P manual, "ALU" / "General ALU operations": abs,
//! set-less-equal, min/max, sign and zero extension, clips, add/sub with
//! normalisation and rounding) and the dispatch of `xcvbitmanip`
//! ([`super::bitmanip`]). One cycle each ("Integer Computational").
//!
//! Every [`op::CV_ALU`](super::op::CV_ALU) instruction carries its function
//! code (below) in `imm` bits 16.. and its immediate (Is2, Is3, or
//! Is3 << 5 | Is2) in bits 0..16; the `_RD` form passes rd's old value.

use super::bitmanip;

super::numbered!(u32;
    ABS, SLE, SLEU, MIN, MINU, MAX, MAXU, EXTHS, EXTHZ, EXTBS, EXTBZ,
    CLIP, CLIPU, CLIPR, CLIPUR,
    ADDN, ADDUN, ADDRN, ADDURN, SUBN, SUBUN, SUBRN, SUBURN,
    ADDNR, ADDUNR, ADDRNR, ADDURNR, SUBNR, SUBUNR, SUBRNR, SUBURNR,
    EXTRACT, EXTRACTU, INSERT, BCLR, BSET, BITREV,
    EXTRACTR, EXTRACTUR, INSERTR, BCLRR, BSETR, ROR, FF1, FL1, CLB, CNT,
);

/// The rounding constant 2^(n-1) of the "R" forms (0 for n = 0: the RTL's
/// `(1 << n) >> 1`).
#[inline(always)]
pub fn round(n: u32) -> u32 {
    (1u32 << n) >> 1
}

/// `cv.clip` bounds for Is2 = n: [-2^(n-1), 2^(n-1) - 1], which the manual
/// defines as [-1, 0] for n = 0.
#[inline(always)]
pub fn clip(x: u32, n: u32) -> u32 {
    let hi = (round(n) as i32).wrapping_sub(1).max(0);
    let lo = -hi - 1;
    (x as i32).clamp(lo, hi) as u32
}

/// `cv.clipu`: [0, 2^(n-1) - 1] (0 for n = 0).
#[inline(always)]
pub fn clipu(x: u32, n: u32) -> u32 {
    let hi = (round(n) as i32).wrapping_sub(1).max(0);
    (x as i32).clamp(0, hi) as u32
}

/// `cv.addN` ... `cv.subuRN` and their `Nr` forms: `(x ± y + round) >> n`
/// on 32 bits (the adder's carry out is lost), arithmetic shift for the
/// signed forms. `k` = the function's offset in its group of four (bit 0:
/// unsigned, bit 1: rounding).
#[inline(always)]
fn add_norm(sum: u32, k: u32, n: u32) -> u32 {
    let n = n & 31;
    let s = if k & 2 != 0 {
        sum.wrapping_add(round(n))
    } else {
        sum
    };
    if k & 1 != 0 {
        s >> n
    } else {
        ((s as i32) >> n) as u32
    }
}

/// Execute function `imm >> 16` on `a` = rs1, `b` = rs2, `d` = rd.
#[inline]
pub fn exec(imm: u32, a: u32, b: u32, d: u32) -> u32 {
    let f = imm >> 16;
    let small = imm & 0xffff;
    let (sa, sb) = (a as i32, b as i32);
    match f {
        ABS => sa.wrapping_abs() as u32,
        SLE => (sa <= sb) as u32,
        SLEU => (a <= b) as u32,
        MIN => sa.min(sb) as u32,
        MINU => a.min(b),
        MAX => sa.max(sb) as u32,
        MAXU => a.max(b),
        EXTHS => a as i16 as i32 as u32,
        EXTHZ => a & 0xffff,
        EXTBS => a as i8 as i32 as u32,
        EXTBZ => a & 0xff,
        CLIP => clip(a, small),
        CLIPU => clipu(a, small),
        // rs2' = rs2 & 0x7FFFFFFF: [-(rs2' + 1), rs2'] and [0, rs2'].
        CLIPR => {
            let hi = sb & 0x7fff_ffff;
            sa.clamp(-hi - 1, hi) as u32
        }
        CLIPUR => sa.clamp(0, sb & 0x7fff_ffff) as u32,
        ADDN..=ADDURN => add_norm(a.wrapping_add(b), f - ADDN, small),
        SUBN..=SUBURN => add_norm(a.wrapping_sub(b), f - SUBN, small),
        // rD = (rD ± rs1 + round) >> rs2[4:0].
        ADDNR..=ADDURNR => add_norm(d.wrapping_add(a), f - ADDNR, b),
        SUBNR..=SUBURNR => add_norm(d.wrapping_sub(a), f - SUBNR, b),
        _ => bitmanip::exec(f, small, a, b, d),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(f: u32, small: u32, a: u32, b: u32, d: u32) -> u32 {
        exec(f << 16 | small, a, b, d)
    }

    #[test]
    fn names_cover_the_functions() {
        assert_eq!(NAMES.len() as u32, CNT + 1);
        assert_eq!(NAMES[CLIP as usize], "CLIP");
    }

    #[test]
    fn clip_bounds_from_the_manual() {
        // Is2 = 8: [-128, 127]; Is2 = 0: [-1, 0]; Is2 = 1: [-1, 0].
        assert_eq!(run(CLIP, 8, 1000, 0, 0), 127);
        assert_eq!(run(CLIP, 8, -1000i32 as u32, 0, 0), -128i32 as u32);
        assert_eq!(run(CLIP, 8, 5, 0, 0), 5);
        assert_eq!(run(CLIP, 0, 7, 0, 0), 0);
        assert_eq!(run(CLIP, 0, -7i32 as u32, 0, 0), u32::MAX);
        assert_eq!(run(CLIP, 31, i32::MIN as u32, 0, 0), -(1 << 30) as u32);
        assert_eq!(run(CLIPU, 8, -5i32 as u32, 0, 0), 0);
        assert_eq!(run(CLIPU, 8, 300, 0, 0), 127);
        assert_eq!(run(CLIPR, 0, 300, 100, 0), 100);
        assert_eq!(run(CLIPR, 0, -300i32 as u32, 100, 0), -101i32 as u32);
        // rs2' drops rs2's sign bit.
        assert_eq!(run(CLIPUR, 0, 300, 0x8000_0064, 0), 100);
    }

    #[test]
    fn normalised_add_and_sub() {
        // (7 + 2) >>> 1 = 4; rounding: (7 + 2 + 1) >>> 1 = 5.
        assert_eq!(run(ADDN, 1, 7, 2, 0), 4);
        assert_eq!(run(ADDRN, 1, 7, 2, 0), 5);
        // Signed vs unsigned shift of a negative sum.
        assert_eq!(run(SUBN, 4, 0, 32, 0), -2i32 as u32);
        assert_eq!(run(SUBUN, 4, 0, 32, 0), 0x0fff_fffe);
        // Round with n = 0 adds nothing.
        assert_eq!(run(ADDURN, 0, 3, 4, 0), 7);
        // Nr: rD = (rD + rs1 + 2^(rs2-1)) >> rs2.
        assert_eq!(run(ADDRNR, 0, 5, 2, 10), 4);
        assert_eq!(run(SUBNR, 0, 30, 1, 10), -10i32 as u32);
        // The carry out of 32 bits is lost.
        assert_eq!(run(ADDUN, 1, u32::MAX, 1, 0), 0);
    }

    proptest::proptest! {
        #[test]
        fn alu_matches_a_plain_reference(a: u32, b: u32) {
            let (sa, sb) = (a as i32, b as i32);
            proptest::prop_assert_eq!(run(ABS, 0, a, 0, 0), if sa < 0 { sa.wrapping_neg() as u32 } else { a });
            proptest::prop_assert_eq!(run(SLE, 0, a, b, 0), (sa <= sb) as u32);
            proptest::prop_assert_eq!(run(MINU, 0, a, b, 0), if a < b { a } else { b });
            proptest::prop_assert_eq!(run(MAX, 0, a, b, 0), if sa < sb { b } else { a });
            proptest::prop_assert_eq!(run(EXTBS, 0, a, 0, 0), ((a & 0xff) ^ 0x80).wrapping_sub(0x80));
            let n = b % 32;
            let lo = if n == 0 { -1 } else { -(1i64 << (n - 1)) };
            let hi = if n == 0 { 0 } else { (1i64 << (n - 1)) - 1 };
            proptest::prop_assert_eq!(run(CLIP, n, a, 0, 0) as i32 as i64, (sa as i64).clamp(lo, hi));
            let sum = ((sa as i64 + sb as i64) as i32 as i64 + if n > 0 { 1 << (n - 1) } else { 0 }) as i32;
            proptest::prop_assert_eq!(run(ADDRN, n, a, b, 0), (sum >> n) as u32);
        }
    }
}
