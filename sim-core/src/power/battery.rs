//! Batteries (thesis §4.5.4 and §5.4): open-circuit voltage and series
//! resistance as fourth-order polynomials of the state of charge, SOC by
//! MESSY's trapezoidal rule, terminal voltage `v_oc − r_s·I`.
//!
//! # The polynomial variable
//!
//! The thesis names the variable of Eq. 4.2–4.3 and 5.1–5.6 "SOC" and plugs
//! them into MESSY's `Harvester_battery_battery_voc`, which evaluates them at
//! its `tmpsoc` (a fraction, 1 = full). Read literally ([`CurveAxis::Soc`]),
//! every curve *rises* as the battery empties: the UFX (Eq. 5.1) and Cyclone
//! (Eq. 5.3) go from 3.26 V and 3.41 V at SOC = 1 to 4.17 V and 4.16 V at
//! SOC = 0, the LiPol (Eq. 4.2) from 4.10 V to 4.23 V. Their shapes are the
//! datasheets' discharge curves plotted against the *discharged* fraction
//! (thesis Fig. 4.9), so the default, [`CurveAxis::Discharged`], evaluates
//! them at `1 − SOC`: voltages then fall as the battery empties, and the
//! battery ranking of §5.4 comes out as the thesis reports it (UFX 250
//! slightly better than LiPol 250, Cyclone 300 better, LiPol 350 best).
//! `battery_curve = "soc"` keeps the literal reading.
//!
//! # An empty battery
//!
//! The SOC is clamped at 0 (MESSY clamps it at 1 on the other side, when a
//! negative current would charge it past full). When the SOC reaches the
//! platform file's `soc_end` the battery is flagged empty
//! ([`Battery::is_empty`]); [`crate::power::PowerNetwork`] turns that into an
//! error, as MESSY stops the simulation (`sc_stop`) at `soc_end`.

use std::fmt;
use std::str::FromStr;

use crate::units::{Amps, Volts};

use super::sag::{self, BatteryLoad};
use super::Ohms;

/// Which variable the `v_oc`/`r_s` polynomials are evaluated at (see the
/// module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CurveAxis {
    /// The SOC itself (1 = full): the literal reading of the thesis and
    /// MESSY's battery module.
    Soc,
    /// The discharged fraction `1 − SOC` (the default; see the module docs).
    #[default]
    Discharged,
}

impl CurveAxis {
    /// The configuration name (`soc` or `discharged`).
    pub const fn name(self) -> &'static str {
        match self {
            CurveAxis::Soc => "soc",
            CurveAxis::Discharged => "discharged",
        }
    }
}

impl FromStr for CurveAxis {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "soc" => Ok(CurveAxis::Soc),
            "discharged" | "dod" | "1-soc" => Ok(CurveAxis::Discharged),
            _ => Err(format!(
                "unknown battery curve axis {s:?} (expected \"soc\" or \"discharged\")"
            )),
        }
    }
}

impl fmt::Display for CurveAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The four batteries of the thesis (§4.5.4, §5.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BatteryModel {
    /// LiPol Battery LPHD6520030, 250 mAh, 7.1 g: the stand-in for the stock
    /// Crazyflie battery (Eq. 4.2/4.3).
    LiPol250,
    /// Guangdong UFine UFX402525, 250 mAh, 5.8 g (Eq. 5.1/5.2).
    Ufx250,
    /// Cyclone 300 mAh, 8.1 g (Eq. 5.3/5.4).
    Cyclone300,
    /// LiPol Battery LPHD7820030, 350 mAh, 9.1 g (Eq. 5.5/5.6).
    LiPol350,
}

impl BatteryModel {
    /// Every model, in the thesis's order.
    pub const ALL: [BatteryModel; 4] = [
        BatteryModel::LiPol250,
        BatteryModel::Ufx250,
        BatteryModel::Cyclone300,
        BatteryModel::LiPol350,
    ];

    /// Configuration name (`lipol250`, `ufx250`, `cyclone300`, `lipol350`).
    pub const fn name(self) -> &'static str {
        match self {
            BatteryModel::LiPol250 => "lipol250",
            BatteryModel::Ufx250 => "ufx250",
            BatteryModel::Cyclone300 => "cyclone300",
            BatteryModel::LiPol350 => "lipol350",
        }
    }

    /// The manufacturer's part name, as the thesis writes it.
    pub const fn part(self) -> &'static str {
        match self {
            BatteryModel::LiPol250 => "LiPol LPHD6520030 250 mAh",
            BatteryModel::Ufx250 => "UFX402525 250 mAh",
            BatteryModel::Cyclone300 => "Cyclone 300 mAh",
            BatteryModel::LiPol350 => "LiPol LPHD7820030 350 mAh",
        }
    }

    /// Nominal capacity in mAh (§4.5.4, §5.4).
    pub const fn capacity_mah(self) -> f64 {
        match self {
            BatteryModel::LiPol250 | BatteryModel::Ufx250 => 250.0,
            BatteryModel::Cyclone300 => 300.0,
            BatteryModel::LiPol350 => 350.0,
        }
    }

    /// Mass in kg (§4.5.4: 7.1 g with the Molex connector; §5.4: 5.8 g,
    /// 8.1 g, 9.1 g). Feeds the D'Andrea and Stolaroff models.
    pub const fn mass_kg(self) -> f64 {
        match self {
            BatteryModel::LiPol250 => 0.0071,
            BatteryModel::Ufx250 => 0.0058,
            BatteryModel::Cyclone300 => 0.0081,
            BatteryModel::LiPol350 => 0.0091,
        }
    }

    /// `v_oc` coefficients in volts, highest power first
    /// (`p4·x⁴ + p3·x³ + p2·x² + p1·x + p0`).
    pub const fn voc_coefficients(self) -> [f64; 5] {
        match self {
            // Eq. 4.2; Eq. 5.5 repeats it for the 350 mAh LiPol (same cell
            // chemistry and datasheet curves, §5.4).
            BatteryModel::LiPol250 | BatteryModel::LiPol350 => {
                [1.39609, -2.95149, 1.60142, -0.10038, 4.15517]
            }
            // Eq. 5.1
            BatteryModel::Ufx250 => [-3.55202, 5.59181, -1.95993, -0.98731, 4.16759],
            // Eq. 5.3
            BatteryModel::Cyclone300 => [-2.88116, 3.95055, -0.75681, -1.06078, 4.15788],
        }
    }

    /// `r_s` coefficients in ohms, highest power first.
    pub const fn rs_coefficients(self) -> [f64; 5] {
        match self {
            // Eq. 4.3
            BatteryModel::LiPol250 => [0.0027310, -0.0058076, 0.0031560, 0.00005570, 0.00001875],
            // Eq. 5.2
            BatteryModel::Ufx250 => [0.0013721, -0.0018010, 0.0006004, 0.00000473, 0.00017039],
            // Eq. 5.4
            BatteryModel::Cyclone300 => [0.00065739, -0.0008854, 0.00043203, -0.0001729, 0.0001722],
            // Eq. 5.6
            BatteryModel::LiPol350 => [0.0019507, -0.0041482, 0.0022543, 0.00003978, 0.00001339],
        }
    }

    /// Open-circuit voltage at polynomial variable `x` (see [`CurveAxis`]).
    pub fn v_oc_at(self, x: f64) -> Volts {
        Volts(horner(&self.voc_coefficients(), x))
    }

    /// Series resistance at polynomial variable `x` (see [`CurveAxis`]).
    pub fn r_s_at(self, x: f64) -> Ohms {
        Ohms(horner(&self.rs_coefficients(), x))
    }
}

/// Evaluates a polynomial given highest power first (Horner's rule; too
/// small a job for a crate).
fn horner(coefficients: &[f64], x: f64) -> f64 {
    coefficients.iter().fold(0.0, |acc, c| acc * x + c)
}

impl FromStr for BatteryModel {
    type Err = String;
    /// Accepts our names and the thesis's (part numbers, capacities).
    fn from_str(s: &str) -> Result<Self, String> {
        match super::name_key(s).as_str() {
            "lipol250" | "lphd6520030" | "lipol" | "lipolbattery" | "default" | "crazyflie" => {
                Ok(BatteryModel::LiPol250)
            }
            "ufx250" | "ufx402525" | "ufx" | "ufine" => Ok(BatteryModel::Ufx250),
            "cyclone300" | "cyclone" => Ok(BatteryModel::Cyclone300),
            "lipol350" | "lphd7820030" | "tattu350" => Ok(BatteryModel::LiPol350),
            _ => Err(format!(
                "unknown battery {s:?} (expected one of lipol250, ufx250, cyclone300, lipol350, \
                 or the thesis's part names LPHD6520030, UFX402525, Cyclone, LPHD7820030)"
            )),
        }
    }
}

impl fmt::Display for BatteryModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A battery being discharged: SOC bookkeeping as MESSY's `battery_voc`.
#[derive(Debug, Clone)]
pub struct Battery {
    model: BatteryModel,
    axis: CurveAxis,
    /// Capacity in ampere-hours.
    capacity_ah: f64,
    /// State of charge as a fraction (1 = full).
    soc: f64,
    /// SOC fraction at which the battery counts as empty.
    soc_end: f64,
    /// SOC fraction under which the battery is low (10 % in the thesis).
    soc_low: f64,
    /// Current of the previous step (A), for the trapezoid. MESSY starts it at 0.
    i_prev: f64,
    empty: bool,
    /// The thesis's curves, or the sag of [`super::sag`].
    load: BatteryLoad,
}

impl Battery {
    /// A battery of `model` at `soc_init` (fraction, 1 = full), empty at
    /// `soc_end` and low under `soc_low` (fractions).
    pub fn new(model: BatteryModel, soc_init: f64, soc_end: f64, soc_low: f64) -> Battery {
        Battery {
            model,
            axis: CurveAxis::default(),
            capacity_ah: model.capacity_mah() / 1000.0,
            soc: soc_init.clamp(0.0, 1.0),
            soc_end,
            soc_low,
            i_prev: 0.0,
            empty: soc_init <= soc_end,
            load: BatteryLoad::default(),
        }
    }

    /// A full battery with the thesis's thresholds (empty at 0 %, low under 10 %).
    pub fn full(model: BatteryModel) -> Battery {
        Battery::new(model, 1.0, 0.0, 0.10)
    }

    /// Chooses the variable the curves are evaluated at.
    pub fn with_axis(mut self, axis: CurveAxis) -> Battery {
        self.axis = axis;
        self
    }

    /// Chooses how the battery behaves under load.
    pub fn with_load(mut self, load: BatteryLoad) -> Battery {
        self.load = load;
        self
    }

    /// How the battery behaves under load.
    pub fn load(&self) -> BatteryLoad {
        self.load
    }

    /// The battery model.
    pub fn model(&self) -> BatteryModel {
        self.model
    }

    /// Capacity in ampere-hours.
    pub fn capacity_ah(&self) -> f64 {
        self.capacity_ah
    }

    /// State of charge as a fraction (1 = full).
    pub fn soc(&self) -> f64 {
        self.soc
    }

    /// Advances the SOC by `dt_s` seconds drawing `i` (positive = discharge)
    /// with MESSY's trapezoid `SOC -= (i + i_prev)·dt / (2·3600·C)`, C in Ah.
    /// The SOC is clamped to [0, 1]; reaching `soc_end` flags it empty.
    pub fn step(&mut self, i: Amps, dt_s: f64) {
        self.soc -= (i.0 + self.i_prev) * dt_s / (2.0 * 3600.0 * self.capacity_ah);
        self.i_prev = i.0;
        self.soc = self.soc.clamp(0.0, 1.0);
        if self.soc <= self.soc_end {
            self.empty = true;
        }
    }

    /// The polynomial variable for the current SOC.
    fn x(&self) -> f64 {
        match self.axis {
            CurveAxis::Soc => self.soc,
            CurveAxis::Discharged => 1.0 - self.soc,
        }
    }

    /// Open-circuit voltage at the current SOC.
    pub fn v_oc(&self) -> Volts {
        let v = self.model.v_oc_at(self.x());
        match self.load {
            BatteryLoad::Thesis => v,
            BatteryLoad::Sag => Volts(v.0 + sag::knee(self.soc)),
        }
    }

    /// Series resistance at the current SOC.
    pub fn r_s(&self) -> Ohms {
        match self.load {
            BatteryLoad::Thesis => self.model.r_s_at(self.x()),
            BatteryLoad::Sag => sag::resistance(sag::internal_resistance(self.model), self.soc),
        }
    }

    /// Terminal voltage while drawing `i`: `v_oc − r_s·I`.
    pub fn voltage(&self, i: Amps) -> Volts {
        Volts(self.v_oc().0 - self.r_s().0 * i.0)
    }

    /// True under the low-battery threshold (10 % SOC in the thesis, §4.5.4).
    pub fn is_low(&self) -> bool {
        self.soc < self.soc_low
    }

    /// True once the SOC has reached `soc_end`.
    pub fn is_empty(&self) -> bool {
        self.empty
    }

    /// SOC fraction at which the battery counts as empty.
    pub fn soc_end(&self) -> f64 {
        self.soc_end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn lipol_polynomials_at_hand_points() {
        let m = BatteryModel::LiPol250;
        // SOC 0: the constant terms of Eq. 4.2 / 4.3.
        assert!(close(m.v_oc_at(0.0).0, 4.15517, 1e-12));
        assert!(close(m.r_s_at(0.0).0, 0.00001875, 1e-15));
        // SOC 1: sum of coefficients
        // 1.39609 − 2.95149 + 1.60142 − 0.10038 + 4.15517 = 4.10081
        assert!(close(m.v_oc_at(1.0).0, 4.10081, 1e-9));
        // 0.0027310 − 0.0058076 + 0.0031560 + 0.0000557 + 0.00001875 = 0.00015385
        assert!(close(m.r_s_at(1.0).0, 0.00015385, 1e-12));
        // SOC 0.5: 1.39609/16 − 2.95149/8 + 1.60142/4 − 0.10038/2 + 4.15517
        // = 0.087255625 − 0.36893625 + 0.400355 − 0.05019 + 4.15517 = 4.223654375
        assert!(close(m.v_oc_at(0.5).0, 4.223654375, 1e-9));
    }

    #[test]
    fn other_batteries_at_soc_one_and_zero() {
        // Eq. 5.1 at 1: −3.55202 + 5.59181 − 1.95993 − 0.98731 + 4.16759 = 3.26014
        assert!(close(BatteryModel::Ufx250.v_oc_at(1.0).0, 3.26014, 1e-9));
        // Eq. 5.3 at 1: −2.88116 + 3.95055 − 0.75681 − 1.06078 + 4.15788 = 3.40968
        assert!(close(
            BatteryModel::Cyclone300.v_oc_at(1.0).0,
            3.40968,
            1e-9
        ));
        // Eq. 5.4 at 0.5: 0.00065739/16 − 0.0008854/8 + 0.00043203/4 − 0.0001729/2 + 0.0001722
        // = 0.0000410869 − 0.000110675 + 0.0001080075 − 0.00008645 + 0.0001722 = 0.0001241694
        assert!(close(
            BatteryModel::Cyclone300.r_s_at(0.5).0,
            0.000124169375,
            1e-12
        ));
        // Eq. 5.6 at 0: 0.00001339; Eq. 5.5 = Eq. 4.2
        assert!(close(
            BatteryModel::LiPol350.r_s_at(0.0).0,
            0.00001339,
            1e-15
        ));
        assert_eq!(
            BatteryModel::LiPol350.v_oc_at(0.3),
            BatteryModel::LiPol250.v_oc_at(0.3)
        );
        // Eq. 5.2 at 0: 0.00017039
        assert!(close(BatteryModel::Ufx250.r_s_at(0.0).0, 0.00017039, 1e-15));
    }

    #[test]
    fn discharged_axis_mirrors_the_variable() {
        // The default axis is the discharged fraction.
        let b = Battery::new(BatteryModel::Ufx250, 0.75, 0.0, 0.1);
        assert_eq!(b.v_oc(), BatteryModel::Ufx250.v_oc_at(0.25));
        let b = Battery::new(BatteryModel::Ufx250, 0.75, 0.0, 0.1).with_axis(CurveAxis::Soc);
        assert_eq!(b.v_oc(), BatteryModel::Ufx250.v_oc_at(0.75));
    }

    #[test]
    fn masses_and_capacities_from_the_thesis() {
        let table: [(BatteryModel, f64, f64); 4] = [
            (BatteryModel::LiPol250, 250.0, 7.1),
            (BatteryModel::Ufx250, 250.0, 5.8),
            (BatteryModel::Cyclone300, 300.0, 8.1),
            (BatteryModel::LiPol350, 350.0, 9.1),
        ];
        for (m, mah, grams) in table {
            assert_eq!(m.capacity_mah(), mah);
            assert!(close(m.mass_kg() * 1000.0, grams, 1e-9));
            assert_eq!(m.name().parse::<BatteryModel>().unwrap(), m);
        }
    }

    #[test]
    fn thesis_names_parse() {
        assert_eq!(
            "LPHD6520030".parse::<BatteryModel>(),
            Ok(BatteryModel::LiPol250)
        );
        assert_eq!(
            "UFX402525".parse::<BatteryModel>(),
            Ok(BatteryModel::Ufx250)
        );
        assert_eq!(
            "Cyclone".parse::<BatteryModel>(),
            Ok(BatteryModel::Cyclone300)
        );
        assert_eq!(
            "LPHD7820030".parse::<BatteryModel>(),
            Ok(BatteryModel::LiPol350)
        );
        assert!("lipo9000".parse::<BatteryModel>().is_err());
    }

    #[test]
    fn trapezoid_step_by_hand() {
        let mut b = Battery::full(BatteryModel::LiPol250);
        // First step: i_prev = 0 (MESSY's initial value), i = 1 A, dt = 1 ms:
        // ΔSOC = (1 + 0)·0.001 / (2·3600·0.25) = 0.001/1800 = 5.5556e-7
        b.step(Amps(1.0), 0.001);
        assert!(close(b.soc(), 1.0 - 0.001 / 1800.0, 1e-15));
        // Second step, 3 A: ΔSOC = (3 + 1)·0.001 / 1800
        b.step(Amps(3.0), 0.001);
        assert!(close(b.soc(), 1.0 - 0.005 / 1800.0, 1e-15));
    }

    #[test]
    fn terminal_voltage_is_voc_minus_rs_i() {
        let b = Battery::new(BatteryModel::Cyclone300, 0.5, 0.0, 0.1);
        let v = b.voltage(Amps(2.0));
        assert!(close(v.0, b.v_oc().0 - 2.0 * b.r_s().0, 1e-15));
        assert!(v.0 < b.v_oc().0);
    }

    #[test]
    fn sag_is_i_times_r() {
        // Half charge: the knee is e^-17.5 ≈ 2.5e-8 V, the resistance
        // 0.16302 Ω (Eq. 3.2's slope) within 1e-5 Ω: 2.8 A sag 0.4565 V.
        let b = Battery::new(BatteryModel::LiPol250, 0.5, 0.0, 0.1).with_load(BatteryLoad::Sag);
        let thesis = Battery::new(BatteryModel::LiPol250, 0.5, 0.0, 0.1);
        assert!((b.v_oc().0 - thesis.v_oc().0).abs() < 1e-7);
        let sag = b.v_oc().0 - b.voltage(Amps(2.8)).0;
        assert!((sag - 2.8 * b.r_s().0).abs() < 1e-12);
        assert!((sag - 2.8 * 0.16302).abs() < 1e-4, "{sag}");
        // Empty: v_oc 4.10081 − 1.031, R tripled.
        let e = Battery::new(BatteryModel::LiPol250, 0.0, 0.0, 0.1).with_load(BatteryLoad::Sag);
        assert!((e.v_oc().0 - (4.10081 - 1.031)).abs() < 1e-9);
        assert!((e.r_s().0 - 0.16302 * (1.0 + 0.1562 / 0.07446)).abs() < 1e-12);
    }

    #[test]
    fn battery_that_empties_is_clamped_and_flagged() {
        let mut b = Battery::new(BatteryModel::LiPol250, 0.001, 0.0, 0.1);
        assert!(b.is_low());
        assert!(!b.is_empty());
        // 0.001 of 0.25 Ah = 0.9 As; 10 A for 1 s removes 10 As.
        b.step(Amps(10.0), 1.0);
        assert_eq!(b.soc(), 0.0);
        assert!(b.is_empty());
    }

    #[test]
    fn charging_current_clamps_at_full() {
        let mut b = Battery::full(BatteryModel::LiPol250);
        b.step(Amps(-5.0), 10.0);
        assert_eq!(b.soc(), 1.0);
    }
}
