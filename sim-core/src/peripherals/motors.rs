//! The four motors (thesis §4.2.1 "send_data_to_motor", §4.5.1 "Motors"):
//! the functional side forwards the STM32's commands to the world; what the
//! power models need (commanded speeds, the drone's velocities and pitch)
//! is kept here for the power network to sample.
//!
//! Per PID iteration the motors send SET_VELOCITY q times, where q is
//! `iter_delay − 1` ms rounded to whole timesteps, then account 1 ms for the
//! motor power model (DESIGN.md §3), then ask the world for the data of the
//! D'Andrea (GET_DATA_2) and Stolaroff (GET_DATA_3) models.

use protocol::{Reply, Request};

use super::{DeviceCtx, LinkError};
use crate::peripherals::stm32::pid::MotorCommands;
use crate::power::MotorState;
use crate::units::{Millis, Picos};

#[derive(Debug, Default)]
pub struct Motors {
    pub state: MotorState,
    /// SET_VELOCITY frames sent.
    pub set_velocity_sent: u64,
    /// The highest speed the battery's voltage allows (rad/s), set by the
    /// power network after each sample with `battery_load = "sag"`
    /// (`crate::power::motor_drive`); `None`: [`MAX_SPEED`] only.
    pub speed_cap: Option<f64>,
}

impl Motors {
    /// Delivers `commands` for an iteration of `iter` ms of platform time
    /// (already accounted in the time keeper).
    pub fn drive(
        &mut self,
        commands: MotorCommands,
        iter: Millis,
        now: Picos,
        ctx_world: &mut dyn super::WorldLink,
        time: &mut crate::sync::TimeKeeper,
    ) -> Result<(), LinkError> {
        // The motor drivers cannot reverse a propeller nor exceed the
        // motors' 600 rad/s (DESIGN.md §5): the PID's outputs saturate here,
        // as the Crazyflie's PWM saturates in [0, 100 %]. The Bitcraze
        // controller does go below 0 on hard attitude corrections. A
        // sagging battery lowers the ceiling (DESIGN.md §16).
        let ceiling = self.speed_cap.map_or(MAX_SPEED, |c| c.min(MAX_SPEED));
        let commands = saturate_at(commands, ceiling);
        self.state.omega = commands.as_array();
        let steps = time.iteration_steps(Millis(iter.0.saturating_sub(1)));
        let request = Request::SetVelocity {
            m1: commands.m1,
            m2: commands.m2,
            m3: commands.m3,
            m4: commands.m4,
        };
        // The whole iteration's traffic goes out together (pipelining, one
        // write), the two replies are read together.
        let mut batch = Vec::with_capacity(steps as usize + 3);
        batch.extend(std::iter::repeat_n(request, steps as usize));
        // The last millisecond goes to the motor power model; it reaches the
        // world only when it rounds to a whole step.
        let extra = time.iteration_steps(Millis(iter.0.min(1)));
        if extra > 0 {
            let ms = extra * time.timestep().0;
            batch.push(Request::AdvanceTime { time: ms });
        }
        batch.extend([Request::GetData2, Request::GetData3]);
        let replies = ctx_world.exchange(&batch, now)?;
        self.set_velocity_sent += steps;
        self.use_model_data(replies)
    }

    /// Sets the commanded speeds without talking to the world (STOP).
    pub fn stopped(&mut self) {
        self.state.omega = [0.0; 4];
    }

    /// The replies to GET_DATA_2 and GET_DATA_3, in that order.
    fn use_model_data(&mut self, replies: Vec<Reply>) -> Result<(), LinkError> {
        let mut replies = replies.into_iter();
        match replies.next() {
            // The world-frame components are logged by the world's
            // trajectory; the D'Andrea model needs the horizontal speed.
            Some(Reply::Data2 { velocity, .. }) => self.state.horizontal_speed = velocity,
            other => {
                return Err(LinkError::Unexpected {
                    request: "GET_DATA_2",
                    reply: other.map_or("no reply", |r| r.command()),
                })
            }
        }
        match replies.next() {
            Some(Reply::Data3 {
                velocity,
                velocity_z,
                pitch,
            }) => {
                self.state.horizontal_speed = velocity;
                self.state.vertical_speed = velocity_z;
                self.state.pitch = pitch;
            }
            other => {
                return Err(LinkError::Unexpected {
                    request: "GET_DATA_3",
                    reply: other.map_or("no reply", |r| r.command()),
                })
            }
        }
        Ok(())
    }
}

/// Highest motor speed (rad/s): the PROTO's `maxVelocity` (DESIGN.md §5).
pub const MAX_SPEED: f64 = 600.0;

/// Clamps each command to `[0, ceiling]` (`ceiling` ≥ 0).
pub fn saturate_at(c: MotorCommands, ceiling: f64) -> MotorCommands {
    let s = |m: f64| m.clamp(0.0, ceiling.max(0.0));
    MotorCommands {
        m1: s(c.m1),
        m2: s(c.m2),
        m3: s(c.m3),
        m4: s(c.m4),
    }
}

/// Convenience for devices holding a [`DeviceCtx`].
pub fn drive_from_ctx(
    ctx: &mut DeviceCtx<'_>,
    commands: MotorCommands,
    iter: Millis,
    now: Picos,
) -> Result<(), LinkError> {
    ctx.motors.drive(commands, iter, now, ctx.world, ctx.time)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::power::motor_drive::speed_cap;
    use crate::units::Volts;

    #[test]
    fn a_sagging_battery_lowers_the_ceiling() {
        let c = MotorCommands {
            m1: -5.0,
            m2: 50.0,
            m3: 80.0,
            m4: 700.0,
        };
        assert_eq!(
            saturate_at(c, MAX_SPEED).as_array(),
            [0.0, 50.0, 80.0, MAX_SPEED]
        );
        // At 3.0 V the motors reach 21.0585 rad/s/V · 3.0 V = 63.18 rad/s:
        // above hover (55.37), below full throttle.
        let cap = speed_cap(Volts(3.0));
        assert!((cap - 63.175).abs() < 0.01, "{cap}");
        assert_eq!(saturate_at(c, cap).as_array(), [0.0, 50.0, cap, cap]);
        // At 2.5 V it cannot hold hover any more.
        assert!(speed_cap(Volts(2.5)) < 55.37);
    }
}
