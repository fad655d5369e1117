//! The Crazyflie of the Bitcraze Webots simulation repository (`Crazyflie.proto`),
//! with every constant from DESIGN.md §5, and its four motors.
//!
//! Body frame: x forward, y left, z up (ENU when the drone is level at yaw 0).

/// Mass of the whole drone (PROTO `physics Physics { mass 0.05 }`).
pub use protocol::airframe::MASS_KG;
/// The PROTO's bounding object is `Cylinder { height 0.03 radius 0.05 }`
/// centred on the body origin; Webots derives the inertia from it.
pub const BODY_RADIUS_M: f64 = 0.05;
pub const BODY_HEIGHT_M: f64 = 0.03;

/// Principal moments of inertia of a solid cylinder of `MASS_KG`, axis z:
/// Ixx = Iyy = m(3r² + h²)/12, Izz = m r²/2.
pub fn principal_inertia() -> [f64; 3] {
    let (m, r, h) = (MASS_KG, BODY_RADIUS_M, BODY_HEIGHT_M);
    let ixx = m * (3.0 * r * r + h * h) / 12.0;
    [ixx, ixx, m * r * r / 2.0]
}

/// `centerOfThrust` of the four `Propeller` nodes m1..m4 (body frame, m):
/// m1 front right, m2 back right, m3 back left, m4 front left.
pub const PROPELLER_POSITIONS: [[f64; 3]; 4] = [
    [0.031, -0.031, 0.008],
    [-0.031, -0.031, 0.008],
    [-0.031, 0.031, 0.008],
    [0.031, 0.031, 0.008],
];

/// Spin direction the Bitcraze Webots controller gives each motor: it calls
/// `m1->setVelocity(-m1)`, `m2->setVelocity(m2)`, … (DESIGN.md §2, SET_VELOCITY).
pub const SPIN_SIGNS: [f64; 4] = [-1.0, 1.0, -1.0, 1.0];
/// Sign of `thrustConstants` in the PROTO (−4e-5 for m1/m3, +4e-5 for m2/m4), so
/// that thrust = k·ω|ω|·s is positive (lifting) for the controller's spin signs.
pub const THRUST_SIGNS: [f64; 4] = [-1.0, 1.0, -1.0, 1.0];
/// `thrustConstants 4e-05 0`: thrust = 4e-5·ω|ω| N.
pub use protocol::airframe::THRUST_CONSTANT;
/// `torqueConstants 2.4e-06 0`: reaction torque 2.4e-6·ω|ω| N·m, applied by
/// Webots as −Q along the shaft axis (+z).
pub const TORQUE_CONSTANT: f64 = 2.4e-6;
/// `RotationalMotor { maxVelocity 600 }` (rad/s).
pub const MAX_MOTOR_SPEED: f64 = 600.0;
/// `maxTorque 30` with no `acceleration` set: Webots's kinematic velocity
/// control uses it as the acceleration limit, 30 rad/s per second (DESIGN.md §5).
pub const MOTOR_ACCELERATION: f64 = 30.0;

/// How the motors follow their speed targets (world file `[physics]
/// motors`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MotorResponse {
    /// The PROTO's velocity control: the speed moves toward the target by
    /// at most [`MOTOR_ACCELERATION`]·dt (the thesis's figures use it).
    #[default]
    Webots,
    /// A real Crazyflie's brushed motors: a first-order lag toward the
    /// target, [`TIME_CONSTANT_UP_S`] when speeding up and
    /// [`TIME_CONSTANT_DOWN_S`] when slowing down. The firmware's flight
    /// stack (500 Hz attitude loops, DESIGN.md §20) is tuned for motors
    /// this fast; the 30 rad/s² limit takes 1.85 s to reach hover.
    Crazyflie,
}

/// The Crazyflie 2's motor time constants (s) as CrazyS models them
/// (Silano et al., "CrazyS: a software-in-the-loop platform for the
/// Crazyflie 2.0 nano-quadcopter", 2018; `crazyflie2.xacro`,
/// `time_constant_up` 0.0125 s, `time_constant_down` 0.025 s).
pub const TIME_CONSTANT_UP_S: f64 = 0.0125;
pub const TIME_CONSTANT_DOWN_S: f64 = 0.025;

/// Standard gravity used by the Webots world (`WorldInfo { gravity 9.81 }`).
pub const GRAVITY: f64 = 9.81;

/// Camera pose in the body frame (DESIGN.md §5): at (0.03, 0, 0.01), looking along +x.
pub const CAMERA_POSITION: [f64; 3] = [0.03, 0.0, 0.01];
/// Horizontal field of view of the camera (rad).
pub const CAMERA_FOV: f64 = 0.87;
/// Camera resolution set by the thesis (§4.4): 320×320.
pub const CAMERA_WIDTH: usize = 320;
pub const CAMERA_HEIGHT: usize = 320;

/// The multiranger deck's `Transform { translation 0 0 0.02 }`: all four
/// DistanceSensors sit 2 cm above the body origin.
pub const RANGE_SENSOR_POSITION: [f64; 3] = [0.0, 0.0, 0.02];
/// Lookup table `[0 0 0, 2 2000 0]` (DESIGN.md §5): 0–2 m map to 0–2000 mm.
pub const RANGE_MAX_M: f64 = 2.0;
pub const RANGE_MAX_MM: f64 = 2000.0;

/// The thesis's controller sets every motor to ±1 rad/s and runs 2000 ms
/// before serving the first request (Appendix E, `robot->step(2000)`).
pub const WARMUP_MS: u64 = 2000;
pub const WARMUP_SPEED: f64 = 1.0;

/// Hover speed of each motor: 4·k·ω² = m·g.
pub fn hover_speed() -> f64 {
    (MASS_KG * GRAVITY / (4.0 * THRUST_CONSTANT)).sqrt()
}

/// Motor commands as the PID sends them: magnitudes in rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorCommands(pub [f64; 4]);

/// An invalid motor command (the wire protocol reports it as an ERROR frame).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotorCommandError {
    #[error("motor m{motor} speed {value} is not a finite number")]
    NotFinite { motor: usize, value: f64 },
    #[error("motor m{motor} speed {value} is negative (commands are magnitudes; the world applies the spin signs)")]
    Negative { motor: usize, value: f64 },
}

impl MotorCommands {
    /// Checks that every command is a finite, non-negative magnitude.
    pub fn validate(&self) -> Result<(), MotorCommandError> {
        for (i, &value) in self.0.iter().enumerate() {
            let motor = i + 1;
            if !value.is_finite() {
                return Err(MotorCommandError::NotFinite { motor, value });
            }
            if value < 0.0 {
                return Err(MotorCommandError::Negative { motor, value });
            }
        }
        Ok(())
    }
}

/// The four motors: signed targets and signed current speeds (rad/s).
///
/// Webots's RotationalMotor in velocity mode moves the current velocity
/// towards the target by at most `acceleration·dt` per physics step and
/// clamps the target to `maxVelocity`.
#[derive(Debug, Clone, PartialEq)]
pub struct Motors {
    target: [f64; 4],
    speed: [f64; 4],
    response: MotorResponse,
}

impl Default for Motors {
    fn default() -> Self {
        Self::new()
    }
}

impl Motors {
    pub fn new() -> Self {
        Self::with_response(MotorResponse::Webots)
    }

    pub fn with_response(response: MotorResponse) -> Self {
        Motors {
            target: [0.0; 4],
            speed: [0.0; 4],
            response,
        }
    }

    /// Sets new targets from PID magnitudes, applying the spin signs and the
    /// `maxVelocity` clamp. The commands must have been validated.
    pub fn set_targets(&mut self, cmd: MotorCommands) {
        for ((t, s), c) in self.target.iter_mut().zip(SPIN_SIGNS).zip(cmd.0) {
            *t = s * c.min(MAX_MOTOR_SPEED);
        }
    }

    /// Sets signed targets directly (warm-up at ±1 rad/s, STOP at 0).
    pub fn set_signed_targets(&mut self, target: [f64; 4]) {
        for (t, v) in self.target.iter_mut().zip(target) {
            *t = v.clamp(-MAX_MOTOR_SPEED, MAX_MOTOR_SPEED);
        }
    }

    /// Forces the current speeds (tests and hover set-ups: no slew).
    pub fn set_speeds_now(&mut self, speed: [f64; 4]) {
        self.speed = speed;
        self.target = speed;
    }

    /// Advances the speeds by `dt_s` seconds under the acceleration limit
    /// or the first-order lag.
    pub fn advance(&mut self, dt_s: f64) {
        if self.response == MotorResponse::Crazyflie {
            for i in 0..4 {
                let (t, w) = (self.target[i], self.speed[i]);
                let tau = if t.abs() >= w.abs() {
                    TIME_CONSTANT_UP_S
                } else {
                    TIME_CONSTANT_DOWN_S
                };
                // The lag's exact solution over the step; a target of 0 is
                // reached once the speed is below 0.01 rad/s (STOP waits
                // for every propeller to stand still).
                let next = t + (w - t) * (-dt_s / tau).exp();
                self.speed[i] = if (next - t).abs() < 0.01 { t } else { next };
            }
            return;
        }
        let max_step = MOTOR_ACCELERATION * dt_s;
        for i in 0..4 {
            let diff = self.target[i] - self.speed[i];
            // Exactly reaching the target when within one step keeps "stopped"
            // an exact 0.0 (STOP waits for it).
            self.speed[i] = if diff.abs() <= max_step {
                self.target[i]
            } else {
                self.speed[i] + max_step.copysign(diff)
            };
        }
    }

    /// Signed propeller speeds (rad/s).
    pub fn speeds(&self) -> [f64; 4] {
        self.speed
    }

    pub fn targets(&self) -> [f64; 4] {
        self.target
    }

    /// True when every propeller has stopped turning.
    pub fn all_stopped(&self) -> bool {
        self.speed.iter().all(|&w| w == 0.0)
    }

    /// Thrust of propeller `i` along body +z (N): k·ω|ω|·s_i.
    pub fn thrust(&self, i: usize) -> f64 {
        let w = self.speed[i];
        THRUST_CONSTANT * w * w.abs() * THRUST_SIGNS[i]
    }

    /// Reaction torque of propeller `i` about body +z (N·m): −Q = −c·ω|ω|.
    pub fn reaction_torque(&self, i: usize) -> f64 {
        let w = self.speed[i];
        -TORQUE_CONSTANT * w * w.abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_propeller_lifts_with_the_controller_signs() {
        let mut m = Motors::new();
        m.set_speeds_now([-50.0, 50.0, -50.0, 50.0]);
        for i in 0..4 {
            assert!((m.thrust(i) - 4e-5 * 2500.0).abs() < 1e-12);
        }
        // Equal speeds: the reaction torques cancel.
        let total: f64 = (0..4).map(|i| m.reaction_torque(i)).sum();
        assert_eq!(total, 0.0);
    }

    #[test]
    fn slew_from_zero_to_55_takes_55_over_30_seconds() {
        let mut m = Motors::new();
        m.set_targets(MotorCommands([55.0; 4]));
        let dt = 0.001;
        let mut steps = 0;
        while m.speeds()[1] != 55.0 {
            m.advance(dt);
            steps += 1;
        }
        // 55/30 s = 1833.3 ms → reached during the 1834th 1-ms step.
        assert_eq!(steps, 1834);
        assert_eq!(m.speeds(), [-55.0, 55.0, -55.0, 55.0]);
    }

    #[test]
    fn targets_clamp_to_max_velocity() {
        let mut m = Motors::new();
        m.set_targets(MotorCommands([1e9, 0.0, 700.0, 600.0]));
        assert_eq!(m.targets(), [-600.0, 0.0, -600.0, 600.0]);
    }

    #[test]
    fn invalid_commands_are_rejected() {
        assert!(MotorCommands([1.0, 2.0, 3.0, 4.0]).validate().is_ok());
        assert_eq!(
            MotorCommands([1.0, -2.0, 3.0, 4.0]).validate(),
            Err(MotorCommandError::Negative {
                motor: 2,
                value: -2.0
            })
        );
        assert!(matches!(
            MotorCommands([1.0, 2.0, f64::NAN, 4.0]).validate(),
            Err(MotorCommandError::NotFinite { motor: 3, .. })
        ));
    }

    #[test]
    fn hover_speed_balances_weight() {
        let w = hover_speed();
        assert!((4.0 * THRUST_CONSTANT * w * w - MASS_KG * GRAVITY).abs() < 1e-12);
    }

    #[test]
    fn crazyflie_motors_lag_with_their_time_constants() {
        // One time constant after a step to 55 rad/s: 1 − 1/e of it; down
        // from there to 0 with the slower constant, and exactly 0 at the end.
        let mut m = Motors::with_response(MotorResponse::Crazyflie);
        m.set_targets(MotorCommands([55.0; 4]));
        m.advance(TIME_CONSTANT_UP_S);
        let want = 55.0 * (1.0 - (-1.0f64).exp());
        assert!((m.speeds()[1] - want).abs() < 1e-9, "{:?}", m.speeds());
        assert!((m.speeds()[0] + want).abs() < 1e-9, "spin sign kept");
        let before = m.speeds()[1];
        m.set_targets(MotorCommands([0.0; 4]));
        m.advance(TIME_CONSTANT_DOWN_S);
        assert!((m.speeds()[1] - before * (-1.0f64).exp()).abs() < 1e-9);
        for _ in 0..100 {
            m.advance(0.01);
        }
        assert!(m.all_stopped());
    }
}
