//! The power side of a device (MESSY's `sensor_*_power`, thesis §4.5.1):
//! a set of states, each with a current, and the state the device is in at
//! any simulated time.
//!
//! Our reading of MESSY's read/write/idle states for the thesis's devices:
//! a device is in `read` while an operation that produces data is in
//! progress (the camera capturing and transferring an image, the STM32
//! running the controller), in `write` for the write delay after the core
//! writes one of its registers, and `idle` otherwise. Polling a status
//! register does not change the state (otherwise the idle-skipping of the
//! ISS could not be exact, and the thesis's firmware would keep the devices
//! in `read` for the whole flight).

use crate::units::Picos;

/// Currents (mA) of the three states and the write delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerStates {
    pub read_ma: f64,
    pub write_ma: f64,
    pub idle_ma: f64,
    /// How long a register write keeps the device in `write`.
    pub write_delay: Picos,
}

/// The state of a device's power side over time.
#[derive(Debug, Clone, PartialEq)]
pub struct DevicePower {
    pub states: PowerStates,
    read_until: Picos,
    write_until: Picos,
}

/// The state a device is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerState {
    Read,
    Write,
    Idle,
}

impl DevicePower {
    pub fn new(states: PowerStates) -> Self {
        DevicePower {
            states,
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
        self.write_until = self.write_until.max(now + self.states.write_delay);
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

    /// Current drawn at time `t`, mA.
    pub fn current_ma(&self, t: Picos) -> f64 {
        match self.state_at(t) {
            PowerState::Read => self.states.read_ma,
            PowerState::Write => self.states.write_ma,
            PowerState::Idle => self.states.idle_ma,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_follow_the_activity() {
        let mut p = DevicePower::new(PowerStates {
            read_ma: 150.0,
            write_ma: 150.0,
            idle_ma: 60.0,
            write_delay: Picos::from_ms(1),
        });
        assert_eq!(p.current_ma(Picos::ZERO), 60.0);
        p.written(Picos::from_ms(10));
        assert_eq!(p.state_at(Picos::from_ms(10)), PowerState::Write);
        assert_eq!(p.state_at(Picos::from_ms(11)), PowerState::Idle);
        p.busy_reading(Picos::from_ms(20));
        assert_eq!(p.state_at(Picos::from_ms(15)), PowerState::Read);
        assert_eq!(p.current_ma(Picos::from_ms(20)), 60.0);
    }
}
