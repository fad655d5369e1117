//! The cluster's core count and its one range (DESIGN.md §19): the run key
//! `cluster.cores`, the platform file's `"cluster": {"cores": N}`, the
//! cluster itself, `cosim nn eval --cores` and `cosim bench cluster --cores`
//! all check it here, and every per-core array is [`MAX_CORES`] long.

use std::fmt;
use std::str::FromStr;

/// The most cores a cluster has (the GAP8's 8).
pub const MAX_CORES: usize = 8;

/// A number of cluster cores, 1 to [`MAX_CORES`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CoreCount(usize);

/// A core count out of range (the text as given).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("cluster.cores must be {min} to {max}, got {0}", min = CoreCount::MIN, max = MAX_CORES)]
pub struct CoreCountError(pub String);

impl CoreCount {
    /// The fewest cores.
    pub const MIN: usize = 1;
    /// The most cores.
    pub const MAX: usize = MAX_CORES;

    pub fn new(n: usize) -> Result<CoreCount, CoreCountError> {
        if (Self::MIN..=Self::MAX).contains(&n) {
            Ok(CoreCount(n))
        } else {
            Err(CoreCountError(n.to_string()))
        }
    }

    pub const fn get(self) -> usize {
        self.0
    }
}

impl FromStr for CoreCount {
    type Err = CoreCountError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().parse::<usize>() {
            Ok(n) => CoreCount::new(n),
            Err(_) => Err(CoreCountError(s.to_string())),
        }
    }
}

impl fmt::Display for CoreCount {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_range() {
        assert_eq!(CoreCount::new(1).unwrap().get(), 1);
        assert_eq!("8".parse::<CoreCount>().unwrap().to_string(), "8");
        for bad in ["0", "9", "x", "-1"] {
            let e = bad.parse::<CoreCount>().unwrap_err().to_string();
            assert_eq!(e, format!("cluster.cores must be 1 to 8, got {bad}"));
        }
    }
}
