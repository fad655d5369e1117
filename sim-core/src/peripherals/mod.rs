//! The devices on the functional bus (thesis §4.2.1): the camera, the STM32
//! (with the PID of §4.2.2), the motors, and the radios of DESIGN.md §8. Each has a functional side (its
//! registers and what a write does) and a power side ([`DevicePower`]: its
//! states, each with a current, as MESSY's sensors).
//!
//! Devices talk to the world through a [`WorldLink`] and account their
//! delays in the [`TimeKeeper`](crate::sync::TimeKeeper) passed to them in a
//! [`DeviceCtx`].

pub mod camera;
pub mod hyperram;
pub mod motors;
pub mod power_state;
pub mod radio;
pub mod solo_world;
pub mod stm32;
pub mod world_link;
pub mod world_session;

pub use camera::Camera;
pub use motors::Motors;
pub use power_state::DevicePower;
pub use solo_world::SoloWorld;
pub use stm32::Stm32;
pub use world_link::{DeferredReply, LinkError, LinkStats, SocketWorld, WorldLink};
pub use world_session::WorldSession;

use thiserror::Error;

use crate::sync::TimeKeeper;
use crate::units::Picos;

/// A status register (one byte unless said otherwise) whose next value
/// becomes visible at a given simulated time (a device's "operation
/// completed" flag, §4.2.1: the code shows when the operation completes, not
/// before).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TimedReg<T = u8> {
    value: T,
    pending: Option<(Picos, T)>,
}

impl<T: Copy> TimedReg<T> {
    /// The value a read at `now` returns.
    pub fn get(&self, now: Picos) -> T {
        match self.pending {
            Some((t, v)) if now >= t => v,
            _ => self.value,
        }
    }

    /// Makes `value` visible from time `at` on.
    pub fn set_at(&mut self, at: Picos, value: T) {
        self.settle(at);
        self.pending = Some((at, value));
    }

    /// A write by the core at `now` (the firmware clears status registers).
    pub fn write(&mut self, now: Picos, value: T) {
        self.settle(now);
        match self.pending {
            // A completion still to come keeps its time; the core's write
            // holds until then.
            Some((t, _)) if t > now => self.value = value,
            _ => {
                self.pending = None;
                self.value = value;
            }
        }
    }

    /// Folds a pending value that is already visible at `now`.
    fn settle(&mut self, now: Picos) {
        if let Some((t, v)) = self.pending {
            if now >= t {
                self.value = v;
                self.pending = None;
            }
        }
    }

    /// When a read could next return something else: the pending time, or
    /// never (`Picos::MAX`) when nothing is scheduled.
    pub fn stable_until(&self, now: Picos) -> Picos {
        match self.pending {
            Some((t, _)) if t > now => t,
            _ => Picos::MAX,
        }
    }
}

/// Why a device could not serve an access.
#[derive(Debug, Error)]
pub enum DeviceError {
    #[error("{device}: unknown command {value} written to the control register")]
    UnknownCommand { device: &'static str, value: u8 },
    #[error("{device}: {message}")]
    Invalid {
        device: &'static str,
        message: String,
    },
    /// The exchange with the world failed (its message is part of ours,
    /// so it is not also a `source`, which would print it twice).
    #[error("{device}: {error}")]
    World {
        device: &'static str,
        error: LinkError,
    },
    #[error("battery empty at {at}: the run cannot go on")]
    BatteryEmpty { at: Picos },
}

/// What a device may use while it reacts to an access or an event.
pub struct DeviceCtx<'a> {
    pub world: &'a mut dyn WorldLink,
    /// The platform's one session with the world (GET_INIT_DATA once, the
    /// drone's clock, STOP).
    pub session: &'a mut WorldSession,
    pub time: &'a mut TimeKeeper,
    pub motors: &'a mut Motors,
    /// The battery is under its low threshold (set by the power network).
    pub battery_low: bool,
    /// Where the STM32 prints (PRINT_SIMUL_TIME, warnings): the console log.
    pub console: &'a mut dyn FnMut(&str),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timed_register_shows_its_value_only_from_its_time() {
        let mut r = TimedReg::default();
        r.set_at(Picos(100), 7);
        assert_eq!(r.get(Picos(99)), 0);
        assert_eq!(r.stable_until(Picos(50)), Picos(100));
        assert_eq!(r.get(Picos(100)), 7);
        assert_eq!(r.stable_until(Picos(100)), Picos::MAX);
        r.write(Picos(150), 0);
        assert_eq!(r.get(Picos(151)), 0);
    }

    #[test]
    fn a_core_write_before_completion_does_not_cancel_it() {
        let mut r = TimedReg::default();
        r.set_at(Picos(100), 4);
        r.write(Picos(10), 0);
        assert_eq!(r.get(Picos(50)), 0);
        assert_eq!(r.get(Picos(100)), 4);
    }
}
