//! The thesis's debug levels (§4.2.4 "Configuration files and debug
//! mode"): the run configuration's `debug_level` key.

use std::fmt;
use std::str::FromStr;

/// The thesis's debug levels (§4.2.4), mapped onto `tracing` levels:
/// NONE → WARN (only the program's own output and problems), LOW → INFO
/// (image sizes, bus operations), MED → DEBUG (world requests, sensor data
/// during the PID), HIGH → TRACE (every frame exchanged on the socket).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub enum DebugLevel {
    #[default]
    None,
    Low,
    Med,
    High,
}

impl DebugLevel {
    /// The `tracing` level this debug level enables.
    pub const fn tracing_level(self) -> tracing::Level {
        match self {
            DebugLevel::None => tracing::Level::WARN,
            DebugLevel::Low => tracing::Level::INFO,
            DebugLevel::Med => tracing::Level::DEBUG,
            DebugLevel::High => tracing::Level::TRACE,
        }
    }

    /// The same as an `EnvFilter` directive (`warn`, `info`, `debug`, `trace`).
    pub const fn filter_directive(self) -> &'static str {
        match self {
            DebugLevel::None => "warn",
            DebugLevel::Low => "info",
            DebugLevel::Med => "debug",
            DebugLevel::High => "trace",
        }
    }

    /// HIGH logs every frame (§4.2.4).
    pub const fn logs_every_frame(self) -> bool {
        matches!(self, DebugLevel::High)
    }

    /// The thesis's name (`NONE`, `LOW`, `MED`, `HIGH`).
    pub const fn name(self) -> &'static str {
        match self {
            DebugLevel::None => "NONE",
            DebugLevel::Low => "LOW",
            DebugLevel::Med => "MED",
            DebugLevel::High => "HIGH",
        }
    }
}

impl FromStr for DebugLevel {
    type Err = String;
    /// Accepts `NONE`/`LOW`/`MED`/`HIGH` in any case, with or without the
    /// thesis's `DEBUG_LEVEL_` prefix, `MEDIUM`, and 0–3.
    fn from_str(s: &str) -> Result<Self, String> {
        let upper = s.trim().to_ascii_uppercase();
        let key = upper.strip_prefix("DEBUG_LEVEL_").unwrap_or(&upper);
        match key {
            "NONE" | "0" => Ok(DebugLevel::None),
            "LOW" | "1" => Ok(DebugLevel::Low),
            "MED" | "MEDIUM" | "2" => Ok(DebugLevel::Med),
            "HIGH" | "3" => Ok(DebugLevel::High),
            _ => Err(format!(
                "unknown debug level {s:?} (expected NONE, LOW, MED or HIGH)"
            )),
        }
    }
}

impl fmt::Display for DebugLevel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
