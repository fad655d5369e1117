//! The Bitcraze Webots flight controller (`pid_velocity_fixed_height_controller`
//! of the crazyflie-simulation repository's `controllers/pid_controller.c`),
//! which the thesis's STM32 model runs (§4.2.2, Appendix C).
//!
//! Cascade: horizontal body velocity → desired pitch/roll; fixed height →
//! collective command around the 48 rad/s base; attitude → roll/pitch/yaw
//! commands; mixing → four motor speed magnitudes (rad/s). The world applies
//! the spin signs (m1, m3 negative; m2, m4 positive).
//!
//! Every error is `desired − actual`; `d/dt` is the finite difference of the
//! error over `dt`; `c(x)` clamps to [−1, 1]. The past errors start at zero,
//! so the first step sees a derivative kick exactly as the C code does. The C
//! code clamps in `float` (`fminf`/`fmaxf`); we clamp in `f64`, which differs
//! only below single precision.

/// Gains of the controller, as set in the Bitcraze Webots controller's `main`
/// (`crazyflie_controller.c`) and DESIGN.md §4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidGains {
    pub kp_att_y: f64,
    pub kd_att_y: f64,
    pub kp_att_rp: f64,
    pub kd_att_rp: f64,
    pub kp_vel_xy: f64,
    pub kd_vel_xy: f64,
    pub kp_z: f64,
    pub ki_z: f64,
    pub kd_z: f64,
    /// Collective motor speed that roughly carries the drone (rad/s), added
    /// to the height controller's output.
    pub base_thrust: f64,
}

impl Default for PidGains {
    fn default() -> Self {
        PidGains {
            kp_att_y: 1.0,
            // Set in the Bitcraze `main` but unused: the yaw-rate loop is P only.
            kd_att_y: 0.5,
            kp_att_rp: 0.5,
            kd_att_rp: 0.1,
            kp_vel_xy: 2.0,
            kd_vel_xy: 0.5,
            kp_z: 10.0,
            ki_z: 5.0,
            kd_z: 5.0,
            base_thrust: 48.0,
        }
    }
}

/// What the drone measures (world sensors; velocities in the body frame).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ActualState {
    /// Roll (rad), InertialUnit.
    pub roll: f64,
    /// Pitch (rad), InertialUnit.
    pub pitch: f64,
    /// Yaw rate (rad/s), gyro z.
    pub yaw_rate: f64,
    /// Altitude (m), GPS z.
    pub altitude: f64,
    /// Forward body velocity (m/s).
    pub vx: f64,
    /// Sideways (left) body velocity (m/s).
    pub vy: f64,
}

/// What the controller is asked to hold. `roll` and `pitch` are overwritten
/// by the horizontal velocity loop (as in the C code, which writes them into
/// the desired state it is given).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DesiredState {
    pub roll: f64,
    pub pitch: f64,
    pub yaw_rate: f64,
    pub altitude: f64,
    pub vx: f64,
    pub vy: f64,
}

/// Motor speed magnitudes (rad/s) for m1..m4, before the spin signs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MotorCommands {
    pub m1: f64,
    pub m2: f64,
    pub m3: f64,
    pub m4: f64,
}

impl MotorCommands {
    pub fn as_array(&self) -> [f64; 4] {
        [self.m1, self.m2, self.m3, self.m4]
    }
}

/// Intermediate commands of the cascade (before mixing).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ControlCommands {
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    pub altitude: f64,
}

/// The controller with its memory (past errors and the height integrator).
#[derive(Debug, Clone, PartialEq)]
pub struct PidController {
    pub gains: PidGains,
    past_vx_error: f64,
    past_vy_error: f64,
    past_altitude_error: f64,
    past_pitch_error: f64,
    past_roll_error: f64,
    altitude_integrator: f64,
}

fn clamp1(x: f64) -> f64 {
    x.clamp(-1.0, 1.0)
}

impl PidController {
    pub fn new(gains: PidGains) -> Self {
        PidController {
            gains,
            past_vx_error: 0.0,
            past_vy_error: 0.0,
            past_altitude_error: 0.0,
            past_pitch_error: 0.0,
            past_roll_error: 0.0,
            altitude_integrator: 0.0,
        }
    }

    /// Forget the past errors and the integrator (`init_pid_attitude_fixed_height_controller`).
    pub fn reset(&mut self) {
        *self = PidController::new(self.gains);
    }

    /// One step of `pid_velocity_fixed_height_controller` over `dt` seconds.
    /// `desired.roll` and `desired.pitch` are set by the velocity loop.
    pub fn step(
        &mut self,
        actual: &ActualState,
        desired: &mut DesiredState,
        dt: f64,
    ) -> MotorCommands {
        self.step_limited(actual, desired, dt, None)
    }

    /// [`Self::step`] with the velocity loop's roll/pitch output limited to
    /// ±`tilt_limit` (rad) when given, as the Crazyflie firmware's velocity
    /// controller limits its attitude output (`position_controller_pid.c`,
    /// `rLimit`/`pLimit` = 20°). `None` is the Webots C code unchanged (no
    /// output limit: `pid_horizontal_velocity_controller`).
    pub fn step_limited(
        &mut self,
        actual: &ActualState,
        desired: &mut DesiredState,
        dt: f64,
        tilt_limit: Option<f64>,
    ) -> MotorCommands {
        self.horizontal_velocity(actual, desired, dt);
        if let Some(l) = tilt_limit {
            desired.roll = desired.roll.clamp(-l, l);
            desired.pitch = desired.pitch.clamp(-l, l);
        }
        let mut cmd = ControlCommands {
            altitude: self.fixed_height(actual, desired, dt),
            ..ControlCommands::default()
        };
        self.attitude(actual, desired, dt, &mut cmd);
        mix(&cmd)
    }

    /// One step without the velocity loop: `desired.roll` and
    /// `desired.pitch` are given (CRTP attitude set-points); the collective
    /// is `collective` (rad/s) or, when `None`, the height loop's output.
    pub fn step_attitude(
        &mut self,
        actual: &ActualState,
        desired: &DesiredState,
        dt: f64,
        collective: Option<f64>,
    ) -> MotorCommands {
        let mut cmd = ControlCommands {
            altitude: match collective {
                Some(c) => c,
                None => self.fixed_height(actual, desired, dt),
            },
            ..ControlCommands::default()
        };
        self.attitude(actual, desired, dt, &mut cmd);
        mix(&cmd)
    }

    fn horizontal_velocity(&mut self, actual: &ActualState, desired: &mut DesiredState, dt: f64) {
        let g = &self.gains;
        let vx_error = desired.vx - actual.vx;
        let vx_derivative = (vx_error - self.past_vx_error) / dt;
        let vy_error = desired.vy - actual.vy;
        let vy_derivative = (vy_error - self.past_vy_error) / dt;
        desired.pitch = g.kp_vel_xy * clamp1(vx_error) + g.kd_vel_xy * vx_derivative;
        desired.roll = -g.kp_vel_xy * clamp1(vy_error) - g.kd_vel_xy * vy_derivative;
        self.past_vx_error = vx_error;
        self.past_vy_error = vy_error;
    }

    fn fixed_height(&mut self, actual: &ActualState, desired: &DesiredState, dt: f64) -> f64 {
        let g = &self.gains;
        let error = desired.altitude - actual.altitude;
        let derivative = (error - self.past_altitude_error) / dt;
        // No integrator limit and no output limit in the C version.
        self.altitude_integrator += error * dt;
        self.past_altitude_error = error;
        g.kp_z * clamp1(error)
            + g.kd_z * derivative
            + g.ki_z * self.altitude_integrator
            + g.base_thrust
    }

    fn attitude(
        &mut self,
        actual: &ActualState,
        desired: &DesiredState,
        dt: f64,
        cmd: &mut ControlCommands,
    ) {
        let g = &self.gains;
        let pitch_error = desired.pitch - actual.pitch;
        let pitch_derivative = (pitch_error - self.past_pitch_error) / dt;
        let roll_error = desired.roll - actual.roll;
        let roll_derivative = (roll_error - self.past_roll_error) / dt;
        let yaw_rate_error = desired.yaw_rate - actual.yaw_rate;
        cmd.roll = g.kp_att_rp * clamp1(roll_error) + g.kd_att_rp * roll_derivative;
        cmd.pitch = -g.kp_att_rp * clamp1(pitch_error) - g.kd_att_rp * pitch_derivative;
        cmd.yaw = g.kp_att_y * clamp1(yaw_rate_error);
        self.past_pitch_error = pitch_error;
        self.past_roll_error = roll_error;
    }
}

/// Motor mixing of the Bitcraze controller (X configuration).
pub fn mix(c: &ControlCommands) -> MotorCommands {
    MotorCommands {
        m1: c.altitude - c.roll + c.pitch + c.yaw,
        m2: c.altitude - c.roll - c.pitch - c.yaw,
        m3: c.altitude + c.roll - c.pitch + c.yaw,
        m4: c.altitude + c.roll + c.pitch - c.yaw,
    }
}

/// Body-frame velocities from two GPS fixes `dt` seconds apart and the yaw
/// (Appendix C lines 5–13): the global finite difference rotated by −yaw.
pub fn body_velocity(dx: f64, dy: f64, dt: f64, yaw: f64) -> (f64, f64) {
    to_body(dx / dt, dy / dt, yaw)
}

/// A world-frame horizontal vector in the body (yaw) frame: rotated by −yaw.
pub fn to_body(x: f64, y: f64, yaw: f64) -> (f64, f64) {
    let (s, c) = yaw.sin_cos();
    (x * c + y * s, -x * s + y * c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_rest_on_target_outputs_the_base_thrust_on_every_motor() {
        let mut pid = PidController::new(PidGains::default());
        let actual = ActualState {
            altitude: 1.0,
            ..Default::default()
        };
        let mut desired = DesiredState {
            altitude: 1.0,
            ..Default::default()
        };
        let m = pid.step(&actual, &mut desired, 0.032);
        assert_eq!(m.as_array(), [48.0; 4]);
    }

    #[test]
    fn height_error_is_clamped_but_derivative_and_integral_are_not() {
        // Worked by hand from the C code: error 2 m over dt 0.5 s from rest:
        // P = 10·c(2) = 10, D = 5·(2 − 0)/0.5 = 20, I = 5·(2·0.5) = 5.
        let mut pid = PidController::new(PidGains::default());
        let actual = ActualState::default();
        let mut desired = DesiredState {
            altitude: 2.0,
            ..Default::default()
        };
        let m = pid.step(&actual, &mut desired, 0.5);
        assert_eq!(m.m1, 48.0 + 10.0 + 20.0 + 5.0);
        // Second step with the same error: D = 0, I = 5·2 = 10.
        let m = pid.step(&actual, &mut desired, 0.5);
        assert_eq!(m.m1, 48.0 + 10.0 + 10.0);
    }

    #[test]
    fn forward_velocity_demand_pitches_nose_down_through_the_mixer() {
        // vx demand 0.5 m/s from rest, dt 1 s: desired pitch = 2·0.5 + 0.5·0.5 = 1.25;
        // pitch command = −0.5·c(1.25) − 0.1·1.25 = −0.625.
        let mut pid = PidController::new(PidGains::default());
        let actual = ActualState {
            altitude: 1.0,
            ..Default::default()
        };
        let mut desired = DesiredState {
            altitude: 1.0,
            vx: 0.5,
            ..Default::default()
        };
        let m = pid.step(&actual, &mut desired, 1.0);
        assert_eq!(desired.pitch, 1.25);
        assert!((m.m1 - (48.0 - 0.625)).abs() < 1e-12);
        assert!((m.m2 - (48.0 + 0.625)).abs() < 1e-12);
        assert!((m.m3 - (48.0 + 0.625)).abs() < 1e-12);
        assert!((m.m4 - (48.0 - 0.625)).abs() < 1e-12);
    }

    #[test]
    fn tilt_limit_clamps_the_velocity_loops_attitude_only_when_given() {
        // vx demand 1 m/s from rest over 32 ms: 2·c(1) + 0.5·1/0.032 = 17.6
        // rad of pitch from the C code; 20° with the firmware's limit.
        let actual = ActualState {
            altitude: 1.0,
            ..Default::default()
        };
        let want = DesiredState {
            altitude: 1.0,
            vx: 1.0,
            vy: -1.0,
            ..Default::default()
        };
        let (mut free, mut limited) = (want, want);
        let mut a = PidController::new(PidGains::default());
        let mut b = PidController::new(PidGains::default());
        let ma = a.step(&actual, &mut free, 0.032);
        assert_eq!(b.step_limited(&actual, &mut want.clone(), 0.032, None), ma);
        assert!((free.pitch - 17.625).abs() < 1e-9, "{free:?}");
        let l = 20f64.to_radians();
        let mut c = PidController::new(PidGains::default());
        let mc = c.step_limited(&actual, &mut limited, 0.032, Some(l));
        assert_eq!((limited.pitch, limited.roll), (l, l));
        // The attitude loop then sees the limited demand: a smaller kick.
        assert!((mc.m2 - mc.m1).abs() < (ma.m2 - ma.m1).abs());
    }

    #[test]
    fn yaw_rate_error_is_proportional_only() {
        let mut pid = PidController::new(PidGains::default());
        let actual = ActualState {
            altitude: 1.0,
            yaw_rate: -0.25,
            ..Default::default()
        };
        let mut desired = DesiredState {
            altitude: 1.0,
            ..Default::default()
        };
        let m = pid.step(&actual, &mut desired, 0.032);
        assert_eq!(m.m1, 48.25);
        assert_eq!(m.m2, 47.75);
    }

    #[test]
    fn body_velocity_rotates_by_minus_yaw() {
        // Facing +y (yaw π/2), moving +y globally is moving forward.
        let (vx, vy) = body_velocity(0.0, 0.1, 0.1, std::f64::consts::FRAC_PI_2);
        assert!((vx - 1.0).abs() < 1e-12 && vy.abs() < 1e-12);
        // Moving −x globally while facing +y is moving to the left (+body y).
        let (vx, vy) = body_velocity(-0.1, 0.0, 0.1, std::f64::consts::FRAC_PI_2);
        assert!(vx.abs() < 1e-12 && (vy - 1.0).abs() < 1e-12);
    }
}
