//! The columns of the CSV outputs that the launcher reads back: a leaf, so
//! the report and the figures it quotes (endurance) share them without
//! importing each other.

use serde::Deserialize;

/// The columns of `power.csv` the report uses.
#[derive(Debug, Clone, Deserialize)]
pub struct PowerRow {
    pub time_s: f64,
    pub i_battery_a: f64,
    pub v_battery_v: f64,
    pub soc: f64,
}

/// The columns of a motor model's CSV the report uses.
#[derive(Debug, Clone, Deserialize)]
pub struct ModelRow {
    pub time_s: f64,
    pub mean_omega_rad_s: f64,
    pub power_w: f64,
}

/// The columns of `trajectory.csv` the report uses.
#[derive(Debug, Clone, Deserialize)]
pub struct TrajectoryRow {
    pub time_ms: u64,
    pub x: f64,
    pub y: f64,
    pub z: f64,
}
