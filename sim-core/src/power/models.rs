//! The three motor power models of §3.4.3 and §4.5.3. All three are computed
//! at every sample and logged; the one chosen by the run configuration
//! drains the battery through the motor bus.
//!
//! Every model returns the motor-bus current and the power it attributes to
//! the motors. With every motor stopped all three return zero: the motors
//! draw nothing, and the thesis notes that once the motors are set to 0 "the
//! only power drawn from the battery comes from the electronics" (§5.1).

use std::fmt;
use std::str::FromStr;

use crate::units::{Amps, Volts};

use super::Watts;

/// Gravity in m/s² (Table 4.4; the world uses the same value).
pub const G: f64 = 9.81;
/// Crazyflie 2.1 structure mass in kg (Table 4.4).
pub const MASS_DRONE_KG: f64 = 0.0199;
/// AI deck mass in kg (Table 4.4).
pub const MASS_AIDECK_KG: f64 = 0.0044;

/// What the models need to know about the drone at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorState {
    /// Motor speeds commanded by the PID (rad/s; the sign is the spin
    /// direction and is ignored).
    pub omega: [f64; 4],
    /// Horizontal speed in m/s (`VELOCITY` of `GET_DATA_2`).
    pub horizontal_speed: f64,
    /// Vertical speed in m/s (`VELOCITY_Z` of `GET_DATA_3`); logged, not
    /// used by the thesis's three models.
    pub vertical_speed: f64,
    /// Pitch angle in rad (`PITCH` of `GET_DATA_3`), the Stolaroff angle of attack.
    pub pitch: f64,
}

impl MotorState {
    /// Mean of the four motor speed magnitudes in rad/s (the thesis's
    /// `get_data_model_1`).
    pub fn mean_omega(&self) -> f64 {
        self.omega.iter().map(|w| w.abs()).sum::<f64>() / 4.0
    }

    /// True when every motor is stopped.
    pub fn motors_off(&self) -> bool {
        self.omega.iter().all(|w| *w == 0.0)
    }
}

/// The three models, in the thesis's order (its log files 1, 2, 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PowerModelKind {
    /// Quadratic fit of Bitcraze's measurements (Eq. 3.1–3.3).
    Empirical,
    /// D'Andrea (2014) with the thesis's hover and avionics terms (Table 4.4).
    DAndrea,
    /// Stolaroff et al. (2018) with Table 4.5 and the ×5 factor.
    Stolaroff,
}

impl PowerModelKind {
    /// Every model, in log-file order.
    pub const ALL: [PowerModelKind; 3] = [
        PowerModelKind::Empirical,
        PowerModelKind::DAndrea,
        PowerModelKind::Stolaroff,
    ];

    /// Configuration and file name (`empirical`, `dandrea`, `stolaroff`).
    pub const fn name(self) -> &'static str {
        match self {
            PowerModelKind::Empirical => "empirical",
            PowerModelKind::DAndrea => "dandrea",
            PowerModelKind::Stolaroff => "stolaroff",
        }
    }

    /// Position in [`PowerModelKind::ALL`] and in per-model arrays.
    pub const fn index(self) -> usize {
        match self {
            PowerModelKind::Empirical => 0,
            PowerModelKind::DAndrea => 1,
            PowerModelKind::Stolaroff => 2,
        }
    }
}

impl FromStr for PowerModelKind {
    type Err = String;
    /// Accepts our names, the thesis's spellings and its model numbers 1–3.
    fn from_str(s: &str) -> Result<Self, String> {
        match super::name_key(s).as_str() {
            "empirical" | "1" | "model1" | "empiricalmodel" => Ok(PowerModelKind::Empirical),
            "dandrea" | "2" | "model2" | "dandreamodel" => Ok(PowerModelKind::DAndrea),
            "stolaroff" | "3" | "model3" | "stolaroffmodel" => Ok(PowerModelKind::Stolaroff),
            _ => Err(format!(
                "unknown power model {s:?} (expected empirical, dandrea or stolaroff, or 1/2/3)"
            )),
        }
    }
}

impl fmt::Display for PowerModelKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One model's output at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelOutput {
    /// Motor-bus current (A).
    pub current: Amps,
    /// Power the model attributes to the motors (W).
    pub power: Watts,
}

/// The empirical model (§3.4.3, Eq. 3.1–3.3).
///
/// `I = 0.00100706·ω̄² − 0.0143·ω̄ + 0.32618` A, with ω̄ the mean of the four
/// motor speeds *in the simulator's rad/s* (§4.5.3: "the motor velocity is
/// expressed in rad/s … obtained as the average velocity from the four
/// motors"), not Table 3.2's RPM. The coefficients already hold the
/// correction factor of §3.4.3: a least-squares quadratic of Table 3.2's
/// current against `RPM/k` reproduces them with k ≈ 340 RPM per simulator
/// rad/s (both `√(a_fit/a)` and `b_fit/b` give 340, and the constant term
/// 0.32617 matches), i.e. the hover point of the Webots drone (≈ 52 rad/s)
/// mapped onto the real hover (≈ 17 700 RPM at 31 g). The test
/// `empirical_coefficients_are_table_3_2_in_scaled_rpm` checks that fit.
/// The thesis text says "mA", but Eq. 3.1 yields amperes (2.6 at hover),
/// as its own note after Eq. 3.3 states.
///
/// The power is Eq. 3.3, `V·I` with `V = −0.16302·I + 4.03495` (Eq. 3.2, the
/// battery voltage Bitcraze measured at that current).
///
/// Range: the fit holds over Table 3.2, i.e. up to full throttle (23 882 RPM,
/// 4.44 A). The PID's commands can ask far more (its derivative kick at
/// take-off asks ~200 rad/s), where Eq. 3.1 would give tens of amperes and
/// Eq. 3.2 a *negative* voltage, hence a negative power. The mean speed is
/// therefore capped at Table 3.2's full-throttle speed in simulator units,
/// 23 882 RPM / 340 ≈ 70.2 rad/s: a real motor cannot draw more than at full
/// PWM.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmpiricalModel {
    /// Eq. 3.1 coefficients `[a, b, c]` (A per (rad/s)², A per rad/s, A).
    pub current_coefficients: [f64; 3],
    /// Eq. 3.2 `[slope (V/A), intercept (V)]`.
    pub voltage_coefficients: [f64; 2],
    /// Highest mean speed the fit is used at (rad/s): Table 3.2's full
    /// throttle, 23 882 RPM / 340.
    pub max_mean_omega: f64,
}

impl Default for EmpiricalModel {
    fn default() -> Self {
        EmpiricalModel {
            current_coefficients: [0.00100706, -0.0143, 0.32618],
            voltage_coefficients: [-0.16302, 4.03495],
            max_mean_omega: 23_882.0 / 340.0,
        }
    }
}

impl EmpiricalModel {
    /// Eq. 3.1: battery current (A) at mean motor speed `mean_omega` (rad/s).
    pub fn current_at(&self, mean_omega: f64) -> Amps {
        let [a, b, c] = self.current_coefficients;
        Amps(a * mean_omega * mean_omega + b * mean_omega + c)
    }

    /// Eq. 3.2: battery voltage estimate (V) at current `i`.
    pub fn voltage_at(&self, i: Amps) -> Volts {
        let [slope, intercept] = self.voltage_coefficients;
        Volts(slope * i.0 + intercept)
    }

    /// Current and power (Eq. 3.3) for the drone state.
    pub fn evaluate(&self, state: &MotorState) -> ModelOutput {
        if state.motors_off() {
            return ModelOutput::default();
        }
        let current = self.current_at(state.mean_omega().min(self.max_mean_omega));
        ModelOutput {
            current,
            power: Watts(self.voltage_at(current).0 * current.0),
        }
    }
}

/// D'Andrea's model (§3.4.1) with the thesis's parameters (Table 4.4):
/// `P = m·g·v / (η·r) + P_avio + P_hover`, v the horizontal speed.
///
/// `P_hover` (8.7 W, Bitcraze's measurement at 32 g: 2.39 A × 3.65 V) is the
/// thesis's addition for a nano-drone; `P_avio` (0.35 W) is the equation's
/// `p`. Both are in the thesis's motor model although the VCC bus also
/// carries the electronics: we keep that double count, as the thesis did.
/// The current on the motor bus is `P / V_bus` (the battery's terminal
/// voltage).
///
/// Efficiency: Table 4.4 says 0.9, the text says 0.8 "to model any power
/// loss due to thermal, vibration and noise"; the text explains its choice,
/// so the default is 0.8 (`dandrea_efficiency` in the run configuration).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DAndreaModel {
    /// Total mass: drone + AI deck + battery (kg).
    pub mass_kg: f64,
    /// Lift-to-drag ratio r (Table 4.4: 3).
    pub lift_to_drag: f64,
    /// Power transfer efficiency η.
    pub efficiency: f64,
    /// Electronics power p (W, Table 4.4: 0.350).
    pub p_avio: Watts,
    /// Hover power (W, Table 4.4: 8.7).
    pub p_hover: Watts,
}

impl DAndreaModel {
    /// Table 4.4 with the given total mass and efficiency.
    pub fn new(mass_kg: f64, efficiency: f64) -> DAndreaModel {
        DAndreaModel {
            mass_kg,
            lift_to_drag: 3.0,
            efficiency,
            p_avio: Watts(0.350),
            p_hover: Watts(8.7),
        }
    }

    /// Power (W) at horizontal speed `v` (m/s).
    pub fn power_at(&self, v: f64) -> Watts {
        Watts(
            self.mass_kg * G * v.abs() / (self.efficiency * self.lift_to_drag)
                + self.p_avio.0
                + self.p_hover.0,
        )
    }

    /// Current on a motor bus at `v_bus` and power for the drone state.
    pub fn evaluate(&self, state: &MotorState, v_bus: Volts) -> ModelOutput {
        if state.motors_off() {
            return ModelOutput::default();
        }
        ModelOutput::from_power(self.power_at(state.horizontal_speed), v_bus)
    }
}

/// Stolaroff et al.'s model (§3.4.1) with Table 4.5, low-speed form
/// (§4.5.3 leaves out the high-speed correction):
/// `P = k·T^{3/2} / (√(½·π·D²·n·ρ)·η)` with
/// `T = m·g + ½·ρ·C_D·A·v²` and `C_D = 2·m·g·tan α / (ρ·v²·A)`.
///
/// Substituting C_D, the drag term is `m·g·tan α`: the projected area A
/// (0.008464 m²) and the speed cancel, so `T = m·g·(1 + |tan α|)` and no
/// division by v² is needed at v = 0. We take |α| because drag opposes the
/// motion whichever way the drone pitches. `½·π·D²` is `2·β` with β the disc
/// area of one propeller (Table 4.5: 0.001589 m², r = 22.5 mm).
///
/// The thesis multiplies the result by k = 5 "to obtain a plausible range of
/// values" (§5.1). It gives no efficiency for this model; we use the same η
/// as D'Andrea (0.8 by default; `stolaroff_efficiency`), which puts the
/// hover power at 5 × 1.37 W / 0.8 ≈ 8.6 W, next to the measured 8.7 W.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StolaroffModel {
    /// Total mass (kg).
    pub mass_kg: f64,
    /// Number of rotors n (Table 4.5: 4).
    pub rotors: f64,
    /// Disc area of one propeller β (m², Table 4.5).
    pub disc_area: f64,
    /// Air density ρ (kg/m³, Table 4.5).
    pub air_density: f64,
    /// Projected body area A (m², Table 4.5); cancels out (see above), kept
    /// for the record.
    pub body_area: f64,
    /// Efficiency η.
    pub efficiency: f64,
    /// The thesis's correction factor k (5).
    pub factor: f64,
}

impl StolaroffModel {
    /// Table 4.5 with the given total mass, efficiency and factor.
    pub fn new(mass_kg: f64, efficiency: f64, factor: f64) -> StolaroffModel {
        StolaroffModel {
            mass_kg,
            rotors: 4.0,
            disc_area: 0.001589,
            air_density: 1.225,
            body_area: 0.008464,
            efficiency,
            factor,
        }
    }

    /// Thrust (N) at pitch `alpha` (rad): `m·g·(1 + |tan α|)`.
    pub fn thrust_at(&self, alpha: f64) -> f64 {
        self.mass_kg * G * (1.0 + alpha.tan().abs())
    }

    /// Power (W) at pitch `alpha`, including the factor.
    pub fn power_at(&self, alpha: f64) -> Watts {
        let t = self.thrust_at(alpha);
        let denominator =
            (2.0 * self.rotors * self.air_density * self.disc_area).sqrt() * self.efficiency;
        Watts(self.factor * t.powf(1.5) / denominator)
    }

    /// Current on a motor bus at `v_bus` and power for the drone state.
    pub fn evaluate(&self, state: &MotorState, v_bus: Volts) -> ModelOutput {
        if state.motors_off() {
            return ModelOutput::default();
        }
        ModelOutput::from_power(self.power_at(state.pitch), v_bus)
    }
}

impl ModelOutput {
    /// A power drawn from a bus at `v_bus`: current `P / V`, or zero on a
    /// dead bus.
    pub fn from_power(power: Watts, v_bus: Volts) -> ModelOutput {
        let current = if v_bus.0 > 0.0 {
            Amps(power.0 / v_bus.0)
        } else {
            Amps(0.0)
        };
        ModelOutput { current, power }
    }
}

/// Parameters the run configuration may change (the rest is Tables 4.4/4.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelParams {
    /// D'Andrea's η (0.8, see [`DAndreaModel`]).
    pub dandrea_efficiency: f64,
    /// Stolaroff's η (0.8, see [`StolaroffModel`]).
    pub stolaroff_efficiency: f64,
    /// Stolaroff's correction factor (5, §5.1).
    pub stolaroff_factor: f64,
}

impl Default for ModelParams {
    fn default() -> Self {
        ModelParams {
            dandrea_efficiency: 0.8,
            stolaroff_efficiency: 0.8,
            stolaroff_factor: 5.0,
        }
    }
}

/// The three models for one drone (one total mass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorModels {
    pub empirical: EmpiricalModel,
    pub dandrea: DAndreaModel,
    pub stolaroff: StolaroffModel,
}

impl MotorModels {
    /// The models for a drone carrying a battery of `battery_mass_kg`
    /// (total mass = 19.9 g + 4.4 g + battery, Table 4.4).
    pub fn new(battery_mass_kg: f64, params: &ModelParams) -> MotorModels {
        let mass = MASS_DRONE_KG + MASS_AIDECK_KG + battery_mass_kg;
        MotorModels {
            empirical: EmpiricalModel::default(),
            dandrea: DAndreaModel::new(mass, params.dandrea_efficiency),
            stolaroff: StolaroffModel::new(
                mass,
                params.stolaroff_efficiency,
                params.stolaroff_factor,
            ),
        }
    }

    /// All three outputs, indexed by [`PowerModelKind::index`].
    pub fn evaluate(&self, state: &MotorState, v_bus: Volts) -> [ModelOutput; 3] {
        [
            self.empirical.evaluate(state),
            self.dandrea.evaluate(state, v_bus),
            self.stolaroff.evaluate(state, v_bus),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hover(omega: f64) -> MotorState {
        MotorState {
            omega: [-omega, omega, -omega, omega],
            ..MotorState::default()
        }
    }

    #[test]
    fn empirical_at_hand_points() {
        let m = EmpiricalModel::default();
        // ω̄ = 50: 0.00100706·2500 − 0.0143·50 + 0.32618 = 2.51765 − 0.715 + 0.32618 = 2.12883 A
        let out = m.evaluate(&hover(50.0));
        assert!((out.current.0 - 2.12883).abs() < 1e-12);
        // Eq. 3.2: V = −0.16302·2.12883 + 4.03495 = 3.687905...; P = V·I
        let v = -0.16302 * 2.12883 + 4.03495;
        assert!((out.power.0 - v * 2.12883).abs() < 1e-12);
        // ω̄ = 10: 0.100706 − 0.143 + 0.32618 = 0.283886 A
        assert!((m.current_at(10.0).0 - 0.283886).abs() < 1e-12);
    }

    #[test]
    fn empirical_saturates_at_full_throttle() {
        // Full throttle (Table 3.2's last row, 23 882 RPM ≈ 70.2 rad/s) is
        // the most the model draws: ~4.4 A, and the power stays positive.
        let m = EmpiricalModel::default();
        let at = |w: f64| {
            m.evaluate(&MotorState {
                omega: [w; 4],
                ..MotorState::default()
            })
        };
        let full = at(23_882.0 / 340.0);
        assert!((full.current.0 - 4.3).abs() < 0.2, "{:?}", full.current);
        assert_eq!(at(200.0), full);
        assert!(at(600.0).power.0 > 0.0);
    }

    #[test]
    fn empirical_mean_takes_magnitudes() {
        let s = MotorState {
            omega: [-40.0, 50.0, -60.0, 70.0],
            ..MotorState::default()
        };
        assert_eq!(s.mean_omega(), 55.0);
    }

    #[test]
    fn motors_off_means_no_motor_current() {
        let models = MotorModels::new(0.0071, &ModelParams::default());
        for out in models.evaluate(&MotorState::default(), Volts(4.0)) {
            assert_eq!(out, ModelOutput::default());
        }
    }

    #[test]
    fn dandrea_at_hand_points() {
        // m = 0.0199 + 0.0044 + 0.0071 = 0.0314 kg, η = 0.8, r = 3.
        let m = DAndreaModel::new(0.0314, 0.8);
        // Hover: 0.35 + 8.7 = 9.05 W
        assert!((m.power_at(0.0).0 - 9.05).abs() < 1e-12);
        // v = 2 m/s: 0.0314·9.81·2/(0.8·3) = 0.616068/2.4 = 0.256695 W on top
        assert!((m.power_at(2.0).0 - (9.05 + 0.256695)).abs() < 1e-9);
        // Current at 4.0 V on the motor bus: 9.306695/4
        let s = MotorState {
            horizontal_speed: 2.0,
            ..hover(50.0)
        };
        let out = m.evaluate(&s, Volts(4.0));
        assert!((out.current.0 - 9.306695 / 4.0).abs() < 1e-9);
    }

    #[test]
    fn stolaroff_at_hand_points() {
        let m = StolaroffModel::new(0.0314, 0.8, 5.0);
        // Level: T = 0.0314·9.81 = 0.308034 N; T^1.5 = 0.170961...
        // √(2·4·1.225·0.001589) = √0.0155722 = 0.1247886
        // P = 5·0.1709609/(0.1247886·0.8) = 8.562...
        let t: f64 = 0.0314 * 9.81;
        let expected = 5.0 * t.powf(1.5) / ((2.0f64 * 4.0 * 1.225 * 0.001589).sqrt() * 0.8);
        assert!((m.power_at(0.0).0 - expected).abs() < 1e-12);
        assert!((expected - 8.562).abs() < 5e-3);
        // Pitch 0.2 rad: tan 0.2 = 0.20271; T = 0.308034·1.20271 = 0.370476 N
        assert!((m.thrust_at(0.2) - 0.308034 * (1.0 + 0.2f64.tan())).abs() < 1e-9);
        assert!((m.thrust_at(-0.2) - m.thrust_at(0.2)).abs() < 1e-15);
        // P scales with T^1.5: ratio 1.20271^1.5 = 1.31899
        let ratio = m.power_at(0.2).0 / m.power_at(0.0).0;
        assert!((ratio - (1.0 + 0.2f64.tan()).powf(1.5)).abs() < 1e-12);
    }

    #[test]
    fn heavier_battery_costs_more_in_mass_models() {
        let light = MotorModels::new(0.0058, &ModelParams::default());
        let heavy = MotorModels::new(0.0091, &ModelParams::default());
        let s = MotorState {
            horizontal_speed: 1.0,
            pitch: 0.1,
            ..hover(55.0)
        };
        let l = light.evaluate(&s, Volts(3.9));
        let h = heavy.evaluate(&s, Volts(3.9));
        assert!(h[1].power.0 > l[1].power.0);
        assert!(h[2].power.0 > l[2].power.0);
        // The empirical model ignores the mass (§5.4).
        assert_eq!(h[0], l[0]);
    }

    #[test]
    fn names_parse() {
        for k in PowerModelKind::ALL {
            assert_eq!(k.name().parse::<PowerModelKind>(), Ok(k));
            assert_eq!(PowerModelKind::ALL[k.index()], k);
        }
        assert_eq!("D'Andrea".parse(), Ok(PowerModelKind::DAndrea));
        assert_eq!("3".parse(), Ok(PowerModelKind::Stolaroff));
        assert!("dorling".parse::<PowerModelKind>().is_err());
    }

    /// Least-squares quadratic by the normal equations (3×3, Cramer's rule).
    fn quadratic_fit(x: &[f64], y: &[f64]) -> [f64; 3] {
        let s = |p: i32| x.iter().map(|v| v.powi(p)).sum::<f64>();
        let t = |p: i32| x.iter().zip(y).map(|(v, w)| v.powi(p) * w).sum::<f64>();
        let m = [
            [s(4), s(3), s(2)],
            [s(3), s(2), s(1)],
            [s(2), s(1), x.len() as f64],
        ];
        let r = [t(2), t(1), t(0)];
        let det = |m: [[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let d = det(m);
        let mut out = [0.0; 3];
        for (col, o) in out.iter_mut().enumerate() {
            let mut mc = m;
            for row in 0..3 {
                mc[row][col] = r[row];
            }
            *o = det(mc) / d;
        }
        out
    }

    #[test]
    fn empirical_coefficients_are_table_3_2_in_scaled_rpm() {
        // Table 3.2 (Bitcraze): current (A) and average RPM.
        let amps = [
            0.24, 0.37, 0.56, 0.75, 0.94, 1.15, 1.37, 1.59, 1.83, 2.11, 2.39, 2.71, 3.06, 3.46,
            3.88, 4.44,
        ];
        let rpm = [
            0.0, 4485.0, 7570.0, 9374.0, 10885.0, 12277.0, 13522.0, 14691.0, 15924.0, 17174.0,
            18179.0, 19397.0, 20539.0, 21692.0, 22598.0, 23882.0,
        ];
        let [a_rpm, b_rpm, c] = quadratic_fit(&rpm, &amps);
        let m = EmpiricalModel::default();
        let [a, b, c_thesis] = m.current_coefficients;
        // Scale k such that x = RPM/k: a = a_rpm·k², b = b_rpm·k.
        let k_from_a = (a / a_rpm).sqrt();
        let k_from_b = b / b_rpm;
        assert!((k_from_a - 340.0).abs() < 1.0, "k from a = {k_from_a}");
        assert!((k_from_b - 340.0).abs() < 1.0, "k from b = {k_from_b}");
        assert!((c - c_thesis).abs() < 1e-4, "c = {c}");
        // Eq. 3.2 is the linear fit of voltage against current.
        let volts = [
            4.01, 3.98, 3.95, 3.92, 3.88, 3.84, 3.80, 3.76, 3.71, 3.67, 3.65, 3.62, 3.56, 3.48,
            3.40, 3.30,
        ];
        let n = amps.len() as f64;
        let (sx, sy) = (amps.iter().sum::<f64>(), volts.iter().sum::<f64>());
        let sxx = amps.iter().map(|x| x * x).sum::<f64>();
        let sxy = amps.iter().zip(&volts).map(|(x, y)| x * y).sum::<f64>();
        let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
        let intercept = (sy - slope * sx) / n;
        assert!((slope - m.voltage_coefficients[0]).abs() < 1e-5);
        assert!((intercept - m.voltage_coefficients[1]).abs() < 1e-5);
    }
}
