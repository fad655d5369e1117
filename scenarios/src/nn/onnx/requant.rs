//! Float scale ratios as integer multipliers and right shifts, the form the
//! deck's kernels apply (docs/NN_ONNX.md): a real ratio
//! `r = s_in · s_w[c] / s_out` becomes `m / 2^shift` with `m` a 31-bit
//! integer, and an int32 accumulator `acc` becomes
//! `(acc · m + 2^(shift−1)) >> shift`: the product in 64 bits (RISC-V
//! `mul` + `mulh`), rounding half up (−1.5 → −1, 1.5 → 2) as the
//! project's cluster kernels do (docs/NN_KERNELS.md).

/// One requantization record: the ratio `multiplier / 2^shift`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Requant {
    /// In [2^30, 2^31) for a non-zero ratio: 31 significant bits.
    pub multiplier: i32,
    /// The right shift, 0..=63.
    pub shift: u32,
}

/// Why a ratio has no record.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RequantError {
    #[error("scale ratio {0} is not a positive finite number")]
    NotPositive(f64),
    #[error("scale ratio {0} is 2^31 or more")]
    TooLarge(f64),
}

impl Requant {
    /// The record nearest to `ratio`: `ratio = f · 2^e` with f in [0.5, 1),
    /// `multiplier = round(f · 2^31)`, `shift = 31 − e`. A ratio below
    /// 2^−32 gives the zero record (every accumulator maps to 0 anyway
    /// after rounding, for |acc| < 2^31).
    pub fn from_ratio(ratio: f64) -> Result<Self, RequantError> {
        if !(ratio.is_finite() && ratio > 0.0) {
            return Err(RequantError::NotPositive(ratio));
        }
        let (f, mut e) = frexp(ratio);
        let mut m = (f * (1u64 << 31) as f64).round() as i64;
        if m == 1 << 31 {
            m = 1 << 30;
            e += 1;
        }
        if e > 31 {
            return Err(RequantError::TooLarge(ratio));
        }
        let shift = 31 - e;
        if shift > 63 {
            return Ok(Self {
                multiplier: 0,
                shift: 0,
            });
        }
        Ok(Self {
            multiplier: m as i32,
            shift: shift as u32,
        })
    }

    /// `(acc · multiplier + 2^(shift−1)) >> shift`, the product in 64 bits
    /// (|acc| < 2^31 and multiplier < 2^31 keep it below 2^62).
    pub fn apply(&self, acc: i64) -> i64 {
        let p = acc * self.multiplier as i64;
        match self.shift {
            0 => p,
            63 => 0,
            s => (p + (1i64 << (s - 1))) >> s,
        }
    }

    /// The ratio the record stands for.
    pub fn ratio(&self) -> f64 {
        self.multiplier as f64 / (self.shift as f64).exp2()
    }
}

/// `x = f · 2^e`, f in [0.5, 1), for a positive finite x.
fn frexp(x: f64) -> (f64, i32) {
    let mut e = x.log2().floor() as i32 + 1;
    let mut f = x / (e as f64).exp2();
    // log2 may land one off at exact powers of two.
    if f >= 1.0 {
        f /= 2.0;
        e += 1;
    } else if f < 0.5 {
        f *= 2.0;
        e -= 1;
    }
    (f, e)
}

/// `x` rounded half to even and clamped to [lo, hi]: ONNX's QuantizeLinear
/// (onnx.ai operator docs) on an already divided value.
pub fn round_clamp(x: f64, lo: i32, hi: i32) -> i32 {
    let r = x.round_ties_even();
    r.clamp(lo as f64, hi as f64) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powers_of_two_are_exact() {
        let r = Requant::from_ratio(0.5).unwrap();
        assert_eq!(
            r,
            Requant {
                multiplier: 1 << 30,
                shift: 31
            }
        );
        let r = Requant::from_ratio(1.0).unwrap();
        assert_eq!((r.multiplier, r.shift), (1 << 30, 30));
        let r = Requant::from_ratio(2.0f64.powi(-20)).unwrap();
        assert_eq!((r.multiplier, r.shift), (1 << 30, 50));
        assert_eq!(Requant::from_ratio(4.0).unwrap().apply(-7), -28);
    }

    /// Rounding half up: 1.5 → 2, 2.5 → 3, −1.5 → −1, −2.5 → −2, and
    /// 0.49.. → 0.
    #[test]
    fn rounds_half_up() {
        let half = Requant::from_ratio(0.5).unwrap();
        assert_eq!(half.apply(3), 2);
        assert_eq!(half.apply(5), 3);
        assert_eq!(half.apply(-3), -1);
        assert_eq!(half.apply(-5), -2);
        assert_eq!(half.apply(0), 0);
        let quarter = Requant::from_ratio(0.25).unwrap();
        assert_eq!(quarter.apply(1), 0);
        assert_eq!(quarter.apply(2), 1);
        assert_eq!(quarter.apply(-2), 0);
        assert_eq!(quarter.apply(-3), -1);
    }

    /// A third: the multiplier is round(2^32 / 3) / 2 at shift 32, and
    /// 3k/3 = k exactly over the int32 range the kernels see.
    #[test]
    fn a_third() {
        let r = Requant::from_ratio(1.0 / 3.0).unwrap();
        assert_eq!(r.shift, 32);
        assert_eq!(r.multiplier, 1_431_655_765); // round(2^32 / 3)
        for k in [-1_000_000i64, -7, -1, 0, 1, 2, 100, 33_333_333] {
            assert_eq!(r.apply(3 * k), k);
        }
        assert_eq!(r.apply(1), 0);
        assert_eq!(r.apply(2), 1);
        assert_eq!(r.apply(-2), -1);
    }

    /// The record's ratio is within 2^−31 (relative) of the asked one, and
    /// the multiplier keeps 31 significant bits.
    #[test]
    fn relative_error_below_2_pow_minus_31() {
        for &x in &[1e-9, 3.1e-5, 0.0123, 0.7, 0.999_999_999_9, 1.5, 77.0, 1e6] {
            let r = Requant::from_ratio(x).unwrap();
            assert!((1 << 30..=i32::MAX).contains(&r.multiplier), "{x}: {r:?}");
            let rel = (r.ratio() - x).abs() / x;
            assert!(rel <= 2f64.powi(-31), "{x}: {rel}");
        }
    }

    #[test]
    fn tiny_large_and_invalid_ratios() {
        assert_eq!(
            Requant::from_ratio(1e-30).unwrap().apply(i32::MAX as i64),
            0
        );
        assert!(matches!(
            Requant::from_ratio(3e9),
            Err(RequantError::TooLarge(_))
        ));
        assert!(Requant::from_ratio(0.0).is_err());
        assert!(Requant::from_ratio(f64::NAN).is_err());
        assert!(Requant::from_ratio(-1.0).is_err());
    }

    #[test]
    fn quantize_rounds_half_to_even() {
        assert_eq!(round_clamp(2.5, -128, 127), 2);
        assert_eq!(round_clamp(3.5, -128, 127), 4);
        assert_eq!(round_clamp(-2.5, -128, 127), -2);
        assert_eq!(round_clamp(300.0, 0, 255), 255);
        assert_eq!(round_clamp(-0.6, 0, 255), 0);
    }
}
