//! Small named types for simulated time, so that picoseconds, milliseconds
//! and cycles can never be mixed up silently.
//!
//! Simulated time on the platform is an integer count of picoseconds (as
//! SystemC's resolution in MESSY); the world only knows whole milliseconds.

use std::fmt;
use std::ops::{Add, AddAssign, Sub, SubAssign};

/// Simulated time or duration in picoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Picos(pub u64);

impl Picos {
    pub const ZERO: Picos = Picos(0);
    pub const MAX: Picos = Picos(u64::MAX);
    pub const PER_NS: u64 = 1_000;
    pub const PER_US: u64 = 1_000_000;
    pub const PER_MS: u64 = 1_000_000_000;
    pub const PER_S: u64 = 1_000_000_000_000;

    pub const fn from_ms(ms: u64) -> Picos {
        Picos(ms * Self::PER_MS)
    }
    pub const fn from_us(us: u64) -> Picos {
        Picos(us * Self::PER_US)
    }
    pub const fn from_ns(ns: u64) -> Picos {
        Picos(ns * Self::PER_NS)
    }
    /// Seconds as f64 (for reports only; never feed back into time keeping).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / Self::PER_S as f64
    }
    /// Whole milliseconds, rounded down.
    pub const fn as_ms_floor(self) -> u64 {
        self.0 / Self::PER_MS
    }
    pub fn saturating_sub(self, rhs: Picos) -> Picos {
        Picos(self.0.saturating_sub(rhs.0))
    }
}

impl Add for Picos {
    type Output = Picos;
    fn add(self, rhs: Picos) -> Picos {
        Picos(self.0 + rhs.0)
    }
}
impl AddAssign for Picos {
    fn add_assign(&mut self, rhs: Picos) {
        self.0 += rhs.0;
    }
}
impl Sub for Picos {
    type Output = Picos;
    fn sub(self, rhs: Picos) -> Picos {
        Picos(self.0 - rhs.0)
    }
}
impl SubAssign for Picos {
    fn sub_assign(&mut self, rhs: Picos) {
        self.0 -= rhs.0;
    }
}
impl fmt::Display for Picos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.9} s", self.as_secs_f64())
    }
}

/// A whole number of milliseconds (world time, delays, timesteps).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Millis(pub u64);

impl Millis {
    pub const fn to_picos(self) -> Picos {
        Picos::from_ms(self.0)
    }
}

impl Add for Millis {
    type Output = Millis;
    fn add(self, rhs: Millis) -> Millis {
        Millis(self.0 + rhs.0)
    }
}

impl fmt::Display for Millis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ms", self.0)
    }
}

/// A whole number of nanoseconds (the radios' TX_DELAY register,
/// docs/SWARM.md §4.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Nanos(pub u32);

impl Nanos {
    pub const fn to_picos(self) -> Picos {
        Picos::from_ns(self.0 as u64)
    }
}

/// Core clock cycles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Cycles(pub u64);

/// Clock frequency in hertz; converts cycles to picoseconds exactly when the
/// period is a whole number of picoseconds (250 MHz → 4000 ps).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Hertz(pub u64);

impl Hertz {
    /// Clock period in picoseconds, rounded to the nearest picosecond.
    pub const fn period(self) -> Picos {
        Picos((Picos::PER_S + self.0 / 2) / self.0)
    }
}

/// Current in amperes (the power models work in A; the platform file in mA).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Amps(pub f64);

/// Voltage in volts.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Volts(pub f64);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_clock_period_is_4_ns() {
        assert_eq!(Hertz(250_000_000).period(), Picos(4_000));
    }

    #[test]
    fn ms_round_trip() {
        assert_eq!(Picos::from_ms(32).as_ms_floor(), 32);
        assert_eq!(Millis(16).to_picos(), Picos(16_000_000_000));
    }
}
