//! `xcvmac` (CV32E40P manual, "Multiply-Accumulate": 32-bit `cv.mac` /
//! `cv.msu`, and the 16 x 16-bit multiplies and MACs with a normalisation
//! shift Is3 and optional rounding, on the low (`mul*N`) or high
//! (`mulhh*N`) halfwords). All run on the single-cycle multiplier: 1 cycle
//! ("Multiplication: 1 (mul)", pipeline.rst). Results are the low 32 bits;
//! the 16-bit forms add product, accumulator and rounding constant modulo
//! 2^32 and then shift (arithmetic for the signed forms), as the RTL's
//! `short_mac[31:0]` does.

use super::alu::round;

/// The `kind` in bits 16.. of `imm` of [`op::CV_MULN`](super::op::CV_MULN)
/// and [`op::CV_MACN`](super::op::CV_MACN): bit 0 high halfwords, bit 1
/// rounding, bit 2 signed.
pub const fn kind(hh: bool, round: bool, signed: bool) -> u32 {
    hh as u32 | (round as u32) << 1 | (signed as u32) << 2
}

/// `cv.mac rD, rs1, rs2`: rD + rs1 * rs2.
#[inline(always)]
pub fn mac(d: u32, a: u32, b: u32) -> u32 {
    d.wrapping_add(a.wrapping_mul(b))
}

/// `cv.msu rD, rs1, rs2`: rD - rs1 * rs2.
#[inline(always)]
pub fn msu(d: u32, a: u32, b: u32) -> u32 {
    d.wrapping_sub(a.wrapping_mul(b))
}

/// The 16-bit multiplies (`c` = 0) and MACs (`c` = rD): `imm` = kind << 16
/// | Is3.
#[inline]
pub fn mul_n(imm: u32, a: u32, b: u32, c: u32) -> u32 {
    let k = imm >> 16;
    let n = imm & 31;
    let (x, y) = if k & 1 != 0 {
        (a >> 16, b >> 16)
    } else {
        (a, b)
    };
    let signed = k & 4 != 0;
    let p = if signed {
        (x as i16 as i32).wrapping_mul(y as i16 as i32) as u32
    } else {
        (x & 0xffff) * (y & 0xffff)
    };
    let r = if k & 2 != 0 { round(n) } else { 0 };
    let s = p.wrapping_add(c).wrapping_add(r);
    if signed {
        ((s as i32) >> n) as u32
    } else {
        s >> n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mac_and_msu_wrap_at_32_bits() {
        assert_eq!(mac(1, 0x8000_0000, 2), 1);
        assert_eq!(mac(10, -3i32 as u32, 4), -2i32 as u32);
        assert_eq!(msu(0, 0x1_0000, 0x1_0000), 0);
        assert_eq!(msu(5, 2, 3), -1i32 as u32);
    }

    #[test]
    fn sixteen_bit_forms() {
        let s = |hh, r| kind(hh, r, true) << 16;
        let u = |hh, r| kind(hh, r, false) << 16;
        // -32768 * -32768 = 2^30, signed.
        assert_eq!(mul_n(s(false, false), 0x8000, 0x8000, 0), 1 << 30);
        // Unsigned: 0xffff^2.
        assert_eq!(mul_n(u(false, false), 0xffff, 0xffff, 0), 0xfffe_0001);
        // High halfwords, shift 4 with rounding: (3 * -5 + 8) >> 4 = -1.
        assert_eq!(mul_n(s(true, true) | 4, 3 << 16, 0xfffb_0000, 0), u32::MAX);
        // MAC: (rD + p) >>> n, rounding constant 2^(n-1).
        assert_eq!(mul_n(s(false, true) | 1, 3, 3, 4), 7);
        assert_eq!(
            mul_n(u(false, false) | 1, 0xffff, 0xffff, 0x1_fffe),
            0x7fff_ffff
        );
    }

    proptest::proptest! {
        #[test]
        fn mul_n_matches_wide_arithmetic(a: u32, b: u32, c: u32, n in 0u32..32, hh: bool, r: bool, signed: bool) {
            let (x, y) = if hh { (a >> 16, b >> 16) } else { (a & 0xffff, b & 0xffff) };
            let (x, y) = if signed {
                (x as u16 as i16 as i64, y as u16 as i16 as i64)
            } else {
                (x as i64, y as i64)
            };
            let rnd = if r && n > 0 { 1i64 << (n - 1) } else { 0 };
            let sum = (x * y + c as i64 + rnd) as u32;
            let want = if signed { ((sum as i32) >> n) as u32 } else { sum >> n };
            proptest::prop_assert_eq!(mul_n(kind(hh, r, signed) << 16 | n, a, b, c), want);
        }
    }
}
