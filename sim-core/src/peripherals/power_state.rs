//! The power side of a device (MESSY's `sensor_*_power`, thesis §4.5.1):
//! which state (read, write, idle) the device is in at any simulated time.
//!
//! Our reading of MESSY's read/write/idle states for the thesis's devices:
//! a device is in `read` while an operation that produces data is in
//! progress (the camera capturing and transferring an image, the STM32
//! running the controller), in `write` for the write delay after the core
//! writes one of its registers, and `idle` otherwise. Polling a status
//! register does not change the state (otherwise the idle-skipping of the
//! ISS could not be exact, and the thesis's firmware would keep the devices
//! in `read` for the whole flight).

//! The currents of the states are the platform file's; the power network
//! (`crate::power`) turns a state into a current at each 1 ms sample.

pub use crate::power::SensorState as PowerState;
use crate::units::Picos;

/// The state of a device's power side over time.
#[derive(Debug, Clone, PartialEq)]
pub struct DevicePower {
    /// How long a register write keeps the device in `write` (the platform
    /// file's `states.write.delay`).
    pub write_delay: Picos,
    read_until: Picos,
    write_until: Picos,
}

impl DevicePower {
    pub fn new(write_delay: Picos) -> Self {
        DevicePower {
            write_delay,
            read_until: Picos::ZERO,
            write_until: Picos::ZERO,
        }
    }

    /// The device produces data during `[from, until)`.
    pub fn busy_reading(&mut self, until: Picos) {
        self.read_until = self.read_until.max(until);
    }

    /// The core wrote a register at `now`.
    pub fn written(&mut self, now: Picos) {
        self.write_until = self.write_until.max(now + self.write_delay);
    }

    pub fn state_at(&self, t: Picos) -> PowerState {
        if t < self.read_until {
            PowerState::Read
        } else if t < self.write_until {
            PowerState::Write
        } else {
            PowerState::Idle
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_follow_the_activity() {
        let mut p = DevicePower::new(Picos::from_ms(1));
        assert_eq!(p.state_at(Picos::ZERO), PowerState::Idle);
        p.written(Picos::from_ms(10));
        assert_eq!(p.state_at(Picos::from_ms(10)), PowerState::Write);
        assert_eq!(p.state_at(Picos::from_ms(11)), PowerState::Idle);
        p.busy_reading(Picos::from_ms(20));
        assert_eq!(p.state_at(Picos::from_ms(15)), PowerState::Read);
        assert_eq!(p.state_at(Picos::from_ms(20)), PowerState::Idle);
    }
}
