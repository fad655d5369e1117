//! The world's basicTimeStep: its rules declared once (DESIGN.md §19), for
//! the three processes that handle it. `cosim` checks a scenario's timestep
//! against its sync mode before it starts any process; `world-server`
//! checks `--timestep`; `sim-core` checks the timestep the world reports in
//! `GET_INIT_DATA` (a foreign world is not checked by cosim). All three call
//! [`TimestepMs::check`] (or [`TimestepMs::new`], which knows no sync mode),
//! so a bad timestep is refused with the same one-line message everywhere.

use std::fmt;
use std::str::FromStr;

/// A basicTimeStep in whole milliseconds, in [`TimestepMs::MIN`]..=
/// [`TimestepMs::MAX`] (DESIGN.md §3: 8, 16, 24, 32 …).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TimestepMs(u64);

/// Why a timestep is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TimestepError {
    /// Not a whole number of ms in the range.
    #[error(
        "basicTimeStep {0:?}: expected a whole number of ms in {min}..={max}",
        min = TimestepMs::MIN,
        max = TimestepMs::MAX
    )]
    Range(String),
    /// Under the thesis's time bookkeeping an iteration moves the world by
    /// (timestep − 1 ms) rounded to whole steps: below 3 ms that is no step.
    #[error(
        "basicTimeStep {0} ms is too small for the thesis's iteration scheme (one timestep \
         minus 1 ms rounds to no step): use at least {min} ms, or sync = \"bounded\"",
        min = TimestepMs::THESIS_MIN
    )]
    TooSmallForThesis(u64),
}

impl TimestepMs {
    /// The smallest timestep.
    pub const MIN: u64 = 1;
    /// The largest timestep (one second).
    pub const MAX: u64 = 1000;
    /// The smallest timestep under the thesis's sync mode.
    pub const THESIS_MIN: u64 = 3;

    /// A timestep in the range, whatever the sync mode.
    pub fn new(ms: u64) -> Result<TimestepMs, TimestepError> {
        if (Self::MIN..=Self::MAX).contains(&ms) {
            Ok(TimestepMs(ms))
        } else {
            Err(TimestepError::Range(ms.to_string()))
        }
    }

    /// Every rule of the timestep: the range, and under the thesis's sync
    /// mode (`thesis_sync`) at least [`TimestepMs::THESIS_MIN`].
    pub fn check(ms: u64, thesis_sync: bool) -> Result<TimestepMs, TimestepError> {
        let ts = Self::new(ms)?;
        if thesis_sync && ms < Self::THESIS_MIN {
            return Err(TimestepError::TooSmallForThesis(ms));
        }
        Ok(ts)
    }

    /// The timestep in ms.
    pub const fn get(self) -> u64 {
        self.0
    }

    /// The timestep white sensor noise is specified at (the thesis's
    /// 32 ms: a world file's `flow_noise_m_s` is σ per 32 ms sample).
    pub const NOISE_REFERENCE_MS: u64 = 32;

    /// What σ of white noise per sample at [`Self::NOISE_REFERENCE_MS`]
    /// becomes per sample at this timestep, for the same noise density:
    /// √(32 ms / ts). Dead reckoning on the samples then drifts as much per
    /// second at 2 ms as at 32 ms; exactly 1 at 32 ms.
    pub fn white_noise_scale(self) -> f64 {
        (Self::NOISE_REFERENCE_MS as f64 / self.0 as f64).sqrt()
    }
}

impl FromStr for TimestepMs {
    type Err = TimestepError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().parse::<u64>() {
            Ok(ms) => TimestepMs::new(ms),
            Err(_) => Err(TimestepError::Range(s.to_string())),
        }
    }
}

/// The bare number, as in files and on command lines.
impl fmt::Display for TimestepMs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_and_thesis_rule() {
        assert_eq!(TimestepMs::new(32).unwrap().get(), 32);
        assert_eq!("1000".parse::<TimestepMs>().unwrap().to_string(), "1000");
        for bad in ["0", "1001", "abc", "-1", "1.5"] {
            let e = bad.parse::<TimestepMs>().unwrap_err().to_string();
            assert!(e.contains("1..=1000"), "{bad}: {e}");
        }
        assert!(TimestepMs::check(2, false).is_ok());
        assert_eq!(
            TimestepMs::check(2, true),
            Err(TimestepError::TooSmallForThesis(2))
        );
        assert!(TimestepMs::check(3, true).is_ok());
        // The range comes first: 0 is out of range in either mode.
        assert!(matches!(
            TimestepMs::check(0, true),
            Err(TimestepError::Range(_))
        ));
    }
}
