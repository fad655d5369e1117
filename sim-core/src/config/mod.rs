//! Configuration: the platform file (MESSY's JSON shape, [`PlatformConfig`])
//! and the run configuration (the thesis's `simul_configs.hpp`, TOML,
//! [`RunConfig`]). Every error names the file (or the key) and what is wrong.

mod debug_level;
mod platform;
mod run;
mod run_keys;

use std::path::PathBuf;

use thiserror::Error;

pub use platform::{
    BusConfig, BusKind, ConverterConfig, CoreConfig, EfficiencySpec, HarvesterConfig, LutConfig,
    PeripheralsConfig, PlatformConfig, SensorConfig, StateConfig, CORE_STATES,
    DEFAULT_CRAZYFLIE_JSON, RADIO_SENSORS, RADIO_STATES, SENSOR_STATES,
};
pub use run::{flatten_run_table, DebugLevel, RunConfig, SyncMode, FIRMWARE_KEY_PREFIX};
pub use run_keys::{run_key, run_key_names, RunKey, ValueKind, Written, RUN_KEYS, RUN_KEY_COUNT};

/// A configuration that cannot be used.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Malformed JSON or a field of the wrong type or name (serde_json gives
    /// the line and column).
    #[error("{origin}: {source}")]
    Json {
        origin: String,
        source: serde_json::Error,
    },
    /// Malformed TOML (the message holds the line and column).
    #[error("{origin}: {message}")]
    Toml { origin: String, message: String },
    /// Well-formed but inconsistent or out of range.
    #[error("{origin}: {message}")]
    Invalid { origin: String, message: String },
    /// A run configuration key that does not exist.
    #[error("unknown run configuration key {key:?} (known keys: {known})")]
    UnknownKey { key: String, known: String },
    /// A value that does not fit its key.
    #[error("bad value {value:?} for {key}: {reason}")]
    BadValue {
        key: String,
        value: String,
        reason: String,
    },
    /// A command-line override without `=`.
    #[error("override {0:?} is not of the form key=value")]
    BadOverride(String),
}
