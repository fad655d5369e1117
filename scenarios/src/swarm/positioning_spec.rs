//! The scenario's `[positioning]` table and the rows of `positions.csv`:
//! what the scenario files, the positioning report and its accuracy
//! figures share, in a leaf below all three.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// The scenario's `[positioning]` table.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositioningSpec {
    /// Whose estimates the tables and plots show (default: the first platform).
    #[serde(default)]
    pub observer: Option<String>,
    /// Windows of world time, each a table.
    #[serde(default)]
    pub table: Vec<TableSpec>,
    /// Whose estimates are plotted (default: the observer); with several,
    /// one pair of plots each, named after the drone.
    #[serde(default)]
    pub plot: Vec<String>,
    /// Seconds of start-up transient after each plotted observer's first
    /// estimate: with it, the estimation error after them is summarised per
    /// drone (mean, p95, max) in `positioning.md` and drawn on its own in a
    /// second panel of the error plot. None: neither.
    #[serde(default)]
    pub settle_s: Option<f64>,
}

/// A `[positioning]` table serde accepts but the report cannot use.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("positioning.settle_s = {0}: expected a finite number of seconds >= 0")]
pub struct BadSettle(pub f64);

impl PositioningSpec {
    /// Checks what serde cannot: `settle_s` finite and ≥ 0.
    pub fn validate(&self) -> Result<(), BadSettle> {
        match self.settle_s {
            Some(v) if !(v.is_finite() && v >= 0.0) => Err(BadSettle(v)),
            _ => Ok(()),
        }
    }
}

/// One table (seed 003 Tables 7.1–7.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    pub name: String,
    /// Whose estimates (default: the `[positioning]` observer).
    #[serde(default)]
    pub observer: Option<String>,
    /// World time window [from_s, to_s).
    pub from_s: f64,
    pub to_s: f64,
    /// The seed's row per drone: [x real, x estimated, y real, y estimated,
    /// x std, y std].
    #[serde(default)]
    pub seed: BTreeMap<String, [f64; 6]>,
}

/// One row of `positions.csv` (read back by the end-to-end tests).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PositionRow {
    /// World time (s).
    pub time_s: f64,
    pub observer: String,
    pub drone: String,
    pub est_x: f64,
    pub est_y: f64,
    pub est_z: f64,
    /// The filter's largest position σ (m).
    pub sigma_m: f64,
    /// 1 when the filter is stable (§6.8.3).
    pub stable: u8,
    pub true_x: f64,
    pub true_y: f64,
    pub true_z: f64,
}

impl PositionRow {
    pub fn error(&self) -> f64 {
        ((self.est_x - self.true_x).powi(2)
            + (self.est_y - self.true_y).powi(2)
            + (self.est_z - self.true_z).powi(2))
        .sqrt()
    }
}
