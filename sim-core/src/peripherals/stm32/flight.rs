//! One iteration of the thesis's flight controller (Appendix C): the
//! sensors, body velocities, the straight-path coefficients (Listing 4.2),
//! tolerance and target counting (Listing 4.3), the Bitcraze controller.

use protocol::Sensors;

use super::pid::{self, ActualState, DesiredState, MotorCommands, PidController};
use super::{invalid, Process, Stm32};
use crate::peripherals::{DeviceCtx, DeviceError};
use crate::units::Picos;

/// The thesis's `PIDController` state (Appendix C).
#[derive(Debug, Clone)]
pub(super) struct Flight {
    pub(super) pid: PidController,
    pub(super) target: [f64; 3],
    pub(super) target_counter: u32,
    pub(super) num_iteration: u32,
    /// The current target is already counted in the statistics (a firmware
    /// that keeps flying to a reached target, like the hover test, sees
    /// TARGET_REACHED again at every iteration).
    pub(super) counted: bool,
    pub(super) height_desired: f64,
    pub(super) past_time: f64,
    pub(super) past_x: f64,
    pub(super) past_y: f64,
    /// The firmware's cascaded PID, when `stabilizer.controller = pid`
    /// flies a CRTP client.
    pub(super) cascade: super::cascade::Cascade,
}

/// How an iteration ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Outcome {
    Flying,
    Reached,
    Bypassed,
}

impl Stm32 {
    /// The time since the last iteration and what the drone measures
    /// (Appendix C lines 5–13: body velocities from two GPS fixes).
    pub(super) fn measured(&self, s: &Sensors) -> (f64, ActualState) {
        let f = &self.flight;
        let mut dt = s.time_s - f.past_time;
        // The first iteration after INIT_PID sees the same world time as
        // GET_INIT_DATA (the platform's alignment does not move the world);
        // the C code would divide by zero there. Use one timestep instead.
        if dt <= 0.0 {
            dt = self.timestep.0 as f64 / 1000.0;
        }
        let (vx, vy) = pid::body_velocity(s.x - f.past_x, s.y - f.past_y, dt, s.yaw);
        let actual = ActualState {
            roll: s.roll,
            pitch: s.pitch,
            yaw_rate: s.yaw_rate,
            altitude: s.z,
            vx,
            vy,
        };
        (dt, actual)
    }

    /// The Bitcraze controller's step, checked, and the fix kept for the
    /// next iteration's velocities.
    pub(super) fn control(
        &mut self,
        s: &Sensors,
        actual: &ActualState,
        desired: &mut DesiredState,
        dt: f64,
        tilt_limit: Option<f64>,
    ) -> Result<MotorCommands, DeviceError> {
        let f = &mut self.flight;
        let commands = f.pid.step_limited(actual, desired, dt, tilt_limit);
        if commands.as_array().iter().any(|m| !m.is_finite()) {
            return Err(invalid(format!(
                "the controller produced non-finite motor commands {commands:?} from {s:?}"
            )));
        }
        f.past_time = s.time_s;
        f.past_x = s.x;
        f.past_y = s.y;
        Ok(commands)
    }

    /// One PID iteration (Appendix C): sensors, body velocities, the
    /// straight-path coefficients (Listing 4.2), tolerance and target
    /// counting (Listing 4.3), the Bitcraze controller, the motors.
    pub(super) fn pid_iteration(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
        integrate_height: bool,
    ) -> Result<(Outcome, MotorCommands), DeviceError> {
        let s = self.read_sensors(now, ctx)?;
        self.stats.pid_iterations += 1;
        let (dt, actual) = self.measured(&s);
        let cfg = &self.cfg;
        let f = &mut self.flight;

        // Listing 4.2: the straight path.
        let x_diff = s.x - f.target[0];
        let y_diff = s.y - f.target[1];
        let z_diff = s.z - f.target[2];
        let (x_abs, y_abs, z_abs) = (x_diff.abs(), y_diff.abs(), z_diff.abs());
        let max_abs = if x_abs > y_abs {
            if x_abs > z_abs {
                x_abs
            } else {
                z_abs
            }
        } else if y_abs > z_abs {
            y_abs
        } else {
            z_abs
        };
        // 0/0 only when the drone is exactly on the target, where no
        // coefficient is used (every diff is within tolerance).
        let coeff = |a: f64| if max_abs > 0.0 { a / max_abs } else { 0.0 };
        let (x_coeff, y_coeff, z_coeff) = (coeff(x_abs), coeff(y_abs), coeff(z_abs));

        // Listing 4.3: tolerance and target counting.
        let tol = cfg.tolerance;
        let mut sideways_desired = 0.0;
        let mut forward_desired = 0.0;
        let mut height_diff_desired = 0.0;
        let mut outside = 0;
        if x_diff > tol {
            sideways_desired = x_coeff * 0.5;
            outside += 1;
        }
        if x_diff < -tol {
            sideways_desired = -x_coeff * 0.5;
            outside += 1;
        }
        if y_diff > tol {
            forward_desired = -y_coeff * 0.5;
            outside += 1;
        }
        if y_diff < -tol {
            forward_desired = y_coeff * 0.5;
            outside += 1;
        }
        if z_diff > tol {
            height_diff_desired = -z_coeff * 0.2;
            outside += 1;
        }
        if z_diff < -tol {
            height_diff_desired = z_coeff * 0.2;
            outside += 1;
        }
        let mut outcome = Outcome::Flying;
        if outside == 0 {
            f.target_counter += 1;
            if f.target_counter >= cfg.target_cycles {
                outcome = Outcome::Reached;
                f.num_iteration = 0;
            }
        }
        f.num_iteration += 1;
        let unlock = (u64::from(cfg.unlock_cycles) * 32 / self.timestep.0.max(1)) as u32;
        if f.num_iteration >= unlock {
            if outcome == Outcome::Flying {
                outcome = Outcome::Bypassed;
            }
            f.num_iteration = 0;
        }

        if integrate_height {
            f.height_desired += height_diff_desired * dt;
        }
        // Appendix C's mapping, or rotated by the yaw toward a heading
        // target (motion.rs; unchanged without EXT_SET_HEADING).
        let (vx_desired, vy_desired, yaw_rate) =
            self.motion.steer(forward_desired, sideways_desired, s.yaw);
        let mut desired = DesiredState {
            yaw_rate,
            vy: vy_desired,
            vx: vx_desired,
            altitude: f.height_desired,
            ..DesiredState::default()
        };
        let commands = self.control(&s, &actual, &mut desired, dt, None)?;

        // Targets set by the firmware are counted (GET_STABLE and landing are
        // the STM32's own).
        let already = self.flight.counted;
        if outcome != Outcome::Flying {
            self.flight.counted = true;
        }
        let counts = matches!(self.process, Process::Idle | Process::Continuous) && !already;
        match outcome {
            Outcome::Reached if counts => self.stats.targets_reached += 1,
            Outcome::Bypassed => {
                if counts {
                    self.stats.targets_bypassed += 1;
                }
                let msg = format!(
                    "Warning: target position {:?} could not be reached! Bypassing to the next one...\n",
                    self.flight.target
                );
                tracing::warn!(target: "cosim::stm32", "{}", msg.trim_end());
                (ctx.console)(&msg);
            }
            _ => {}
        }
        Ok((outcome, commands))
    }
}
