//! DC-DC converters between a load (or a bus) and what feeds it (§4.5).
//!
//! A converter delivers `I_out` at `V_out` and draws `I_in` at `V_in` with
//! `V_in·I_in·η = V_out·I_out`, so `I_in = V_out·I_out / (η·V_in)` — MESSY's
//! load converter (`current_out = i·v / (VREF_BUS·η)`). MESSY's battery-side
//! converter (`out_dir: true`) instead writes `η·i·VREF_BUS / v_batt`, which
//! makes a lossy converter draw *less* from the battery; we use the
//! power-conserving form on both sides.
//!
//! The efficiency is fixed, read from a look-up table exactly as MESSY's
//! `LUT::get_val`, or the LDO's `V_out/V_in` clamped to [0, 1] (Eq. 4.1 and the
//! clamp of §4.5.4).

use std::fmt;

use thiserror::Error;

use crate::units::{Amps, Volts};

/// A look-up table that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LutError {
    #[error("a LUT needs at least 2 points, got {0}")]
    TooShort(usize),
    #[error("LUT input_values has {inputs} entries but the values array has {values}")]
    LengthMismatch { inputs: usize, values: usize },
    #[error(
        "LUT input_values must be strictly increasing (entry {index}: {value} after {previous})"
    )]
    NotIncreasing {
        index: usize,
        previous: f64,
        value: f64,
    },
    #[error("LUT entry {index} is not a finite number")]
    NotFinite { index: usize },
}

/// A piecewise-linear table `key → value`, MESSY's `LUT` (`lut.cpp`).
#[derive(Debug, Clone, PartialEq)]
pub struct Lut {
    keys: Vec<f64>,
    values: Vec<f64>,
}

impl Lut {
    /// Builds a table; keys must be finite and strictly increasing (MESSY
    /// assumes so without checking).
    pub fn new(keys: Vec<f64>, values: Vec<f64>) -> Result<Lut, LutError> {
        if keys.len() != values.len() {
            return Err(LutError::LengthMismatch {
                inputs: keys.len(),
                values: values.len(),
            });
        }
        if keys.len() < 2 {
            return Err(LutError::TooShort(keys.len()));
        }
        if let Some(index) = keys
            .iter()
            .chain(values.iter())
            .position(|v| !v.is_finite())
        {
            return Err(LutError::NotFinite {
                index: index % keys.len(),
            });
        }
        if let Some(i) = (1..keys.len()).find(|&i| keys[i] <= keys[i - 1]) {
            return Err(LutError::NotIncreasing {
                index: i,
                previous: keys[i - 1],
                value: keys[i],
            });
        }
        Ok(Lut { keys, values })
    }

    /// The table's keys.
    pub fn keys(&self) -> &[f64] {
        &self.keys
    }

    /// The table's values.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Linear interpolation as MESSY's `LUT::get_val`: find the first `i`
    /// with `key[i+1] > query`, then `val[i] + (query − key[i])·Δval/Δkey`.
    ///
    /// Outside the table MESSY does not clamp: below the first key it
    /// extrapolates the first segment (we do the same). At or above the last
    /// key its loop leaves `i = size − 1` and reads `key[size]`, past the end
    /// of the array (undefined behaviour); we extrapolate the last segment
    /// there, which is what the loop means and gives `val[last]` at the last
    /// knot.
    pub fn get(&self, query: f64) -> f64 {
        let last_segment = self.keys.len() - 2;
        // Index of the first key strictly greater than the query, minus one;
        // `partition_point` is the binary search MESSY's TODO asks for.
        let upper = self.keys[1..].partition_point(|&k| k <= query);
        let i = upper.min(last_segment);
        let dx = self.keys[i + 1] - self.keys[i];
        let dy = self.values[i + 1] - self.values[i];
        self.values[i] + (query - self.keys[i]) * dy / dx
    }
}

/// What a LUT converter's efficiency is looked up by (MESSY's
/// `input_variable`): the load current in mA or the load voltage in V.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputVariable {
    /// The delivered current, in mA (MESSY's unit for currents).
    #[default]
    Current,
    /// The delivered voltage, in V.
    Voltage,
}

/// How a converter's efficiency is obtained.
#[derive(Debug, Clone, PartialEq)]
pub enum Efficiency {
    /// A constant in (0, 1].
    Fixed(f64),
    /// A table of efficiencies in percent (MESSY's `efficiency_values`).
    Lut { lut: Lut, input: InputVariable },
    /// A linear regulator: `V_out/V_in` clamped to [0, 1] (Eq. 4.1).
    Ldo,
}

/// A DC-DC converter or regulator.
#[derive(Debug, Clone, PartialEq)]
pub struct Converter {
    efficiency: Efficiency,
}

/// Efficiencies below this are treated as this when dividing, so an
/// extrapolated LUT that reaches 0 % cannot produce an infinite current.
const MIN_EFFICIENCY: f64 = 1e-6;

impl Converter {
    /// A converter with a constant efficiency (a fraction in (0, 1]).
    pub fn fixed(efficiency: f64) -> Converter {
        Converter {
            efficiency: Efficiency::Fixed(efficiency),
        }
    }

    /// The ideal converter (efficiency 1), MESSY's default for every load
    /// (§4.5: "the simulation automatically sets the efficiency to 1").
    pub fn ideal() -> Converter {
        Converter::fixed(1.0)
    }

    /// A converter whose efficiency (percent) is looked up in `lut` by `input`.
    pub fn lut(lut: Lut, input: InputVariable) -> Converter {
        Converter {
            efficiency: Efficiency::Lut { lut, input },
        }
    }

    /// The LDO of the VCC rail (LP2985-30, §4.5): efficiency `V_out/V_in`.
    pub fn ldo() -> Converter {
        Converter {
            efficiency: Efficiency::Ldo,
        }
    }

    /// How the efficiency is obtained.
    pub fn kind(&self) -> &Efficiency {
        &self.efficiency
    }

    /// Efficiency (fraction) when delivering `i_out` at `v_out` from `v_in`.
    pub fn efficiency(&self, i_out: Amps, v_out: Volts, v_in: Volts) -> f64 {
        match &self.efficiency {
            Efficiency::Fixed(eta) => *eta,
            Efficiency::Lut { lut, input } => {
                let query = match input {
                    InputVariable::Current => i_out.0 * 1000.0,
                    InputVariable::Voltage => v_out.0,
                };
                lut.get(query) / 100.0
            }
            Efficiency::Ldo => ldo_efficiency(v_out, v_in),
        }
    }

    /// Current drawn at `v_in` to deliver `i_out` at `v_out`:
    /// `I_in = V_out·I_out / (η·V_in)`. A non-positive `v_in` (a dead
    /// source) passes the current through unchanged.
    pub fn input_current(&self, i_out: Amps, v_out: Volts, v_in: Volts) -> Amps {
        if v_in.0 <= 0.0 {
            return i_out;
        }
        let eta = self.efficiency(i_out, v_out, v_in).max(MIN_EFFICIENCY);
        Amps(v_out.0 * i_out.0 / (eta * v_in.0))
    }
}

/// The LDO's efficiency `V_out/V_in` (Eq. 4.1), saturated to [0, 1] as the
/// thesis's battery converter does (§4.5.4). A non-positive input voltage
/// gives 1 (nothing sensible to divide by).
pub fn ldo_efficiency(v_out: Volts, v_in: Volts) -> f64 {
    if v_in.0 <= 0.0 {
        return 1.0;
    }
    (v_out.0 / v_in.0).clamp(0.0, 1.0)
}

impl fmt::Display for Converter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.efficiency {
            Efficiency::Fixed(eta) => write!(f, "fixed efficiency {eta}"),
            Efficiency::Lut { lut, input } => {
                write!(f, "LUT of {} points by {input:?}", lut.keys.len())
            }
            Efficiency::Ldo => f.write_str("LDO (Vout/Vin)"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lut() -> Lut {
        // Keys and values shaped like MESSY's battery converter table.
        Lut::new(vec![1.0, 2.0, 4.0, 10.0], vec![88.0, 90.0, 94.0, 97.0]).unwrap()
    }

    #[test]
    fn at_the_knots_it_returns_the_values() {
        let l = lut();
        for (k, v) in [(1.0, 88.0), (2.0, 90.0), (4.0, 94.0), (10.0, 97.0)] {
            assert_eq!(l.get(k), v, "knot {k}");
        }
    }

    #[test]
    fn inside_it_interpolates_linearly() {
        let l = lut();
        // Between 2 and 4: 90 + (3 − 2)·(94 − 90)/(4 − 2) = 92
        assert_eq!(l.get(3.0), 92.0);
        // Between 4 and 10: 94 + (5.5 − 4)·3/6 = 94.75
        assert_eq!(l.get(5.5), 94.75);
    }

    #[test]
    fn outside_it_extrapolates_the_end_segments_like_messy() {
        let l = lut();
        // MESSY below the range: i = 0, 88 + (0 − 1)·2/1 = 86
        assert_eq!(l.get(0.0), 86.0);
        // Above the range: the last segment, 94 + (16 − 4)·3/6 = 100
        assert_eq!(l.get(16.0), 100.0);
    }

    #[test]
    fn bad_tables_are_refused() {
        assert_eq!(Lut::new(vec![1.0], vec![1.0]), Err(LutError::TooShort(1)));
        assert!(matches!(
            Lut::new(vec![1.0, 2.0], vec![1.0]),
            Err(LutError::LengthMismatch { .. })
        ));
        assert!(matches!(
            Lut::new(vec![1.0, 1.0], vec![1.0, 2.0]),
            Err(LutError::NotIncreasing { index: 1, .. })
        ));
        assert!(matches!(
            Lut::new(vec![1.0, f64::NAN], vec![1.0, 2.0]),
            Err(LutError::NotFinite { index: 1 })
        ));
    }

    #[test]
    fn ldo_efficiency_is_clamped() {
        assert_eq!(ldo_efficiency(Volts(3.0), Volts(4.0)), 0.75);
        // Below the output voltage (dropout) the ratio would exceed 1.
        assert_eq!(ldo_efficiency(Volts(3.0), Volts(2.5)), 1.0);
        assert_eq!(ldo_efficiency(Volts(3.0), Volts(0.0)), 1.0);
        assert_eq!(ldo_efficiency(Volts(0.0), Volts(4.0)), 0.0);
    }

    #[test]
    fn ldo_passes_its_current_through() {
        // I_in = 3.0·0.2 / ((3.0/4.0)·4.0) = 0.2: a linear regulator burns the
        // voltage difference, it does not transform current.
        let c = Converter::ldo();
        let i = c.input_current(Amps(0.2), Volts(3.0), Volts(4.0));
        assert!((i.0 - 0.2).abs() < 1e-15);
        // In dropout (η clamped to 1) the input current is V_out·I/V_in.
        let i = c.input_current(Amps(0.2), Volts(3.0), Volts(2.5));
        assert!((i.0 - 0.24).abs() < 1e-15);
    }

    #[test]
    fn lut_converter_looks_up_milliamps() {
        let c = Converter::lut(lut(), InputVariable::Current);
        // 3 mA → 92 % → I_in = 3.0·0.003/(0.92·3.0)
        let i = c.input_current(Amps(0.003), Volts(3.0), Volts(3.0));
        assert!((i.0 - 0.003 / 0.92).abs() < 1e-15);
        let c = Converter::lut(lut(), InputVariable::Voltage);
        assert_eq!(c.efficiency(Amps(0.0), Volts(2.0), Volts(3.0)), 0.9);
    }

    #[test]
    fn fixed_converter_scales_by_power() {
        // 1.2 V · 10 mA at 80 % from 3.0 V: 0.012/(0.8·3.0) = 5 mA
        let c = Converter::fixed(0.8);
        let i = c.input_current(Amps(0.010), Volts(1.2), Volts(3.0));
        assert!((i.0 - 0.005).abs() < 1e-15);
    }
}
