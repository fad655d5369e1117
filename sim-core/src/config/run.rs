//! The run configuration: what the thesis's `simul_configs.hpp` holds
//! (§4.2.4 "Configuration files and debug mode") plus the few knobs the
//! platform needs, read from TOML and overridable key by key from the
//! command line (`--set key=value`).
//!
//! Both paths go through [`RunConfig::set`], so a TOML file and a command
//! line accept exactly the same names and values with the same messages.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::power::battery::{BatteryModel, CurveAxis};
use crate::power::models::{ModelParams, PowerModelKind};
use crate::power::sag::{BatteryLoad, OnEmpty};
pub use crate::sync::SyncMode;

pub use super::debug_level::DebugLevel;

use super::ConfigError;
use crate::peripherals::stm32::crtp::CrtpSpec;
use crate::peripherals::stm32::estimator::DEFAULT_FLOW_STD;
use crate::peripherals::stm32::PositionSource;

/// A table's keys with its sub-tables' keys as `table.key`
/// (`stm32.position_source = "flow"` in TOML is a table `stm32`).
pub fn flatten_run_table(table: &toml::Table) -> Vec<(String, toml::Value)> {
    let mut out = Vec::new();
    for (key, value) in table {
        match value {
            toml::Value::Table(sub) => {
                for (k, v) in flatten_run_table(sub) {
                    out.push((format!("{key}.{k}"), v));
                }
            }
            v => out.push((key.clone(), v.clone())),
        }
    }
    out
}

/// Every key with a one-line description (for `--help` texts and errors).
pub const RUN_KEYS: [(&str, &str); 26] = [
    (
        "power_model",
        "motor model that drains the battery: empirical | dandrea | stolaroff",
    ),
    (
        "battery",
        "lipol250 | ufx250 | cyclone300 | lipol350 | platform (the platform file's)",
    ),
    (
        "battery_curve",
        "variable of the v_oc/r_s polynomials: soc (thesis) | discharged (1 - SOC)",
    ),
    (
        "battery_load",
        "thesis (the thesis's curves, motors up to 600 rad/s) | sag (internal resistance, end-of-discharge knee, motor speed capped by the voltage; DESIGN.md §16)",
    ),
    (
        "battery_empty",
        "at soc_end: error (MESSY: the run fails) | end (the flight ends there, as a firmware exit ends it)",
    ),
    (
        "soc_low",
        "BATTERY_LOW threshold in % SOC (default: the platform file's, 10)",
    ),
    (
        "debug_level",
        "NONE | LOW | MED | HIGH (tracing warn | info | debug | trace)",
    ),
    ("tolerance", "PID target tolerance in m (0.1)"),
    (
        "target_cycles",
        "PID iterations inside the tolerance to reach a target (100)",
    ),
    (
        "unlock_cycles",
        "PID iterations before an unreached target is bypassed (5000)",
    ),
    ("sync", "time bookkeeping: thesis | bounded"),
    (
        "dandrea_efficiency",
        "D'Andrea power transfer efficiency (0.8; Table 4.4 says 0.9)",
    ),
    ("stolaroff_efficiency", "Stolaroff efficiency (0.8)"),
    (
        "stolaroff_factor",
        "Stolaroff correction factor (5, section 5.1)",
    ),
    (
        "platform",
        "platform JSON file (default: the embedded Crazyflie)",
    ),
    (
        "radio_id",
        "the radios' EUI, an unsigned 64-bit integer (0; cosim gives 1, 2, 3, ...)",
    ),
    (
        "stm32.position_source",
        "the STM32's position estimate: gps (thesis) | flow (dead reckoning on FLOW_VX/VY through the flow filter)",
    ),
    (
        "stm32.range_max_m",
        "range sensors' max range in m (2); a reading at or beyond it is 'nothing in range'",
    ),
    (
        "crtp",
        "serve cflib's CRTP link: off | udp:HOST:PORT | replay:FILE (a crtp.jsonl); the firmware starts it with EXT_CRTP (crtp_host.elf), docs/CFLIB.md",
    ),
    (
        "pace",
        "with a live CRTP link, simulated seconds per wall second (1.0; 0 = unpaced)",
    ),
    (
        "crtp_idle_s",
        "the CRTP link is closed after this many simulated seconds without a packet (10)",
    ),
    (
        "stm32.flow_std_m_s",
        "flow mode: the flow noise the STM32's filter assumes, m/s per sample (0.069, the Flow deck's at 0.3 m; 0 = the raw flow)",
    ),
    (
        "iss",
        "ISS back end: jit (block translator, default on x86-64) | interp (interpreter); identical results",
    ),
    (
        "cluster.cores",
        "the GAP8 cluster's cores, 1-8, in place of the platform file's (platform: the file's); the platform must have a cluster",
    ),
    (
        "cluster.mhz",
        "the GAP8 cluster's clock in MHz, in place of the platform file's (platform: the file's)",
    ),
    (
        "output.compress",
        "store the series (power.csv, motor_*.csv, trajectory.csv, time_map.csv) and the traces (world.trace, platform.trace) zstd-compressed as NAME.zst (true, default) or plain (false); same bytes once decompressed",
    ),
];

/// The run configuration. [`RunConfig::default`] is the thesis's setting of
/// §5.1: empirical model, LiPol 250 mAh, debug NONE, tolerance 0.1 m,
/// TARGET_CYCLES 100, UNLOCK_CYCLES 5000.
#[derive(Debug, Clone, PartialEq)]
pub struct RunConfig {
    /// The model whose current drains the battery.
    pub power_model: PowerModelKind,
    /// The battery; `None` takes the platform file's.
    pub battery: Option<BatteryModel>,
    /// Which variable the battery polynomials are evaluated at.
    pub battery_curve: CurveAxis,
    /// How the battery behaves under load (sag, motor speed cap).
    pub battery_load: BatteryLoad,
    /// What the run does when the battery reaches `soc_end`.
    pub battery_empty: OnEmpty,
    /// BATTERY_LOW threshold (% SOC); `None` takes the platform file's.
    pub soc_low: Option<f64>,
    /// Debug level.
    pub debug_level: DebugLevel,
    /// PID tolerance in m.
    pub tolerance: f64,
    /// TARGET_CYCLES.
    pub target_cycles: u32,
    /// UNLOCK_CYCLES (at 32 ms; the PID scales it by 32/ts).
    pub unlock_cycles: u32,
    /// Time bookkeeping mode.
    pub sync: SyncMode,
    /// Motor model parameters.
    pub models: ModelParams,
    /// Platform file; `None` is the embedded Crazyflie.
    pub platform: Option<PathBuf>,
    /// The radios' identifier (their EUI register, docs/SWARM.md §4.3).
    pub radio_id: u64,
    /// Firmware parameters (`firmware.NAME = value`): before the core
    /// starts, the kernel writes each value as a 32-bit integer into the
    /// firmware's global `NAME` (found by its ELF symbol), so one ELF runs
    /// with the settings of a scenario or a sweep (docs/EXPLORE.md).
    pub firmware_params: BTreeMap<String, i32>,
    /// Where the STM32's position estimate comes from.
    pub position_source: PositionSource,
    /// The range sensors' max range (m).
    pub range_max_m: f64,
    /// The flow noise σ (m/s) the STM32's flow filter assumes.
    pub flow_std_m_s: f64,
    /// The CRTP link (docs/CFLIB.md).
    pub crtp: Option<CrtpSpec>,
    /// Pacing of a live CRTP link (simulated s per wall s).
    pub pace: f64,
    /// Simulated seconds without a packet that close the CRTP link.
    pub crtp_idle_s: f64,
    /// The ISS back end of every core (no effect on any result).
    pub iss: crate::iss::Backend,
    /// The cluster's cores and clock (MHz) in place of the platform
    /// file's (`None`: the file's), so that a sweep varies them.
    pub cluster_cores: Option<usize>,
    pub cluster_mhz: Option<u64>,
    /// How the series files are stored (a host-side choice: no simulated
    /// result depends on it).
    pub series: protocol::series::SeriesFormat,
}

/// The prefix of the firmware-parameter keys (`firmware.NAME`).
pub const FIRMWARE_KEY_PREFIX: &str = "firmware.";

/// A C identifier, as an ELF symbol of a global must be.
fn is_c_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            power_model: PowerModelKind::Empirical,
            battery: Some(BatteryModel::LiPol250),
            battery_curve: CurveAxis::Discharged,
            battery_load: BatteryLoad::Thesis,
            battery_empty: OnEmpty::Error,
            soc_low: None,
            debug_level: DebugLevel::None,
            tolerance: 0.1,
            target_cycles: 100,
            unlock_cycles: 5000,
            sync: SyncMode::Thesis,
            models: ModelParams::default(),
            platform: None,
            radio_id: 0,
            firmware_params: BTreeMap::new(),
            position_source: PositionSource::Gps,
            range_max_m: 2.0,
            flow_std_m_s: DEFAULT_FLOW_STD.0,
            crtp: None,
            pace: 1.0,
            crtp_idle_s: 10.0,
            iss: crate::iss::Backend::DEFAULT,
            cluster_cores: None,
            cluster_mhz: None,
            series: protocol::series::SeriesFormat::Zstd,
        }
    }
}

fn parse<T: FromStr<Err = String>>(value: &str) -> Result<T, String> {
    value.parse()
}

fn parse_number(value: &str) -> Result<f64, String> {
    value
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| "expected a number".to_string())
}

fn parse_fraction(value: &str) -> Result<f64, String> {
    let v = parse_number(value)?;
    if v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err("expected an efficiency in (0, 1]".into())
    }
}

fn parse_positive(value: &str) -> Result<f64, String> {
    let v = parse_number(value)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err("expected a positive number".into())
    }
}

fn parse_non_negative(value: &str) -> Result<f64, String> {
    let v = parse_number(value)?;
    if v >= 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err("expected a number >= 0".into())
    }
}

fn parse_count(value: &str) -> Result<u32, String> {
    match value.trim().parse::<u32>() {
        Ok(0) | Err(_) => Err("expected a whole number of iterations, at least 1".into()),
        Ok(v) => Ok(v),
    }
}

impl RunConfig {
    /// Sets one key from its text form (the command line's `--set key=value`).
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), ConfigError> {
        let bad = |reason: String| ConfigError::BadValue {
            key: key.to_string(),
            value: value.to_string(),
            reason,
        };
        if let Some(name) = key.strip_prefix(FIRMWARE_KEY_PREFIX) {
            if !is_c_identifier(name) {
                return Err(bad(format!(
                    "{name:?} is not a C identifier (a firmware global)"
                )));
            }
            let v = value
                .trim()
                .parse::<i32>()
                .map_err(|_| bad("expected a 32-bit signed integer".into()))?;
            self.firmware_params.insert(name.to_string(), v);
            return Ok(());
        }
        match key {
            "power_model" => self.power_model = parse(value).map_err(bad)?,
            "battery" => {
                self.battery = if value.trim().eq_ignore_ascii_case("platform") {
                    None
                } else {
                    Some(parse(value).map_err(bad)?)
                }
            }
            "battery_curve" => self.battery_curve = parse(value).map_err(bad)?,
            "battery_load" => self.battery_load = parse(value).map_err(bad)?,
            "battery_empty" => self.battery_empty = parse(value).map_err(bad)?,
            "soc_low" if value.trim().eq_ignore_ascii_case("platform") => self.soc_low = None,
            "soc_low" => {
                let v = parse_non_negative(value).map_err(bad)?;
                if v > 100.0 {
                    return Err(bad("a percentage in [0, 100]".into()));
                }
                self.soc_low = Some(v)
            }
            "debug_level" => self.debug_level = parse(value).map_err(bad)?,
            "tolerance" => self.tolerance = parse_positive(value).map_err(bad)?,
            "target_cycles" => self.target_cycles = parse_count(value).map_err(bad)?,
            "unlock_cycles" => self.unlock_cycles = parse_count(value).map_err(bad)?,
            "sync" => self.sync = parse(value).map_err(bad)?,
            "iss" => self.iss = parse(value).map_err(bad)?,
            "dandrea_efficiency" => {
                self.models.dandrea_efficiency = parse_fraction(value).map_err(bad)?
            }
            "stolaroff_efficiency" => {
                self.models.stolaroff_efficiency = parse_fraction(value).map_err(bad)?
            }
            "stolaroff_factor" => {
                self.models.stolaroff_factor = parse_positive(value).map_err(bad)?
            }
            "platform" => {
                if value.trim().is_empty() {
                    return Err(bad("expected a file path".into()));
                }
                self.platform = Some(PathBuf::from(value))
            }
            "radio_id" => {
                self.radio_id = value
                    .trim()
                    .parse::<u64>()
                    .map_err(|_| bad("expected an unsigned 64-bit integer".into()))?
            }
            "crtp" => {
                self.crtp = match value.trim() {
                    "" | "off" => None,
                    v => Some(v.parse().map_err(bad)?),
                }
            }
            "pace" => self.pace = parse_non_negative(value).map_err(bad)?,
            "crtp_idle_s" => self.crtp_idle_s = parse_positive(value).map_err(bad)?,
            "stm32.position_source" => self.position_source = value.parse().map_err(bad)?,
            "stm32.range_max_m" => self.range_max_m = parse_positive(value).map_err(bad)?,
            "stm32.flow_std_m_s" => self.flow_std_m_s = parse_non_negative(value).map_err(bad)?,
            "cluster.cores" => {
                self.cluster_cores = match value.trim() {
                    "platform" => None,
                    v => match v.parse::<usize>() {
                        Ok(n) if (1..=8).contains(&n) => Some(n),
                        _ => return Err(bad("expected 1 to 8 cores, or platform".into())),
                    },
                }
            }
            "cluster.mhz" => {
                self.cluster_mhz = match value.trim() {
                    "platform" => None,
                    v => match v.parse::<u64>() {
                        Ok(f) if (1..=10_000).contains(&f) => Some(f),
                        _ => return Err(bad("expected a whole number of MHz, or platform".into())),
                    },
                }
            }
            "output.compress" => {
                self.series = match value.trim() {
                    "true" => protocol::series::SeriesFormat::Zstd,
                    "false" => protocol::series::SeriesFormat::Plain,
                    _ => return Err(bad("expected true or false".into())),
                }
            }
            _ => {
                return Err(ConfigError::UnknownKey {
                    key: key.to_string(),
                    known: RUN_KEYS.map(|(k, _)| k).join(", "),
                })
            }
        }
        Ok(())
    }

    /// The text form of one key, as `set` accepts it.
    pub fn get(&self, key: &str) -> Result<String, ConfigError> {
        if let Some(v) = key
            .strip_prefix(FIRMWARE_KEY_PREFIX)
            .and_then(|name| self.firmware_params.get(name))
        {
            return Ok(v.to_string());
        }
        Ok(match key {
            "power_model" => self.power_model.to_string(),
            "battery" => self
                .battery
                .map_or_else(|| "platform".to_string(), |b| b.to_string()),
            "battery_curve" => self.battery_curve.to_string(),
            "battery_load" => self.battery_load.to_string(),
            "battery_empty" => self.battery_empty.to_string(),
            "soc_low" => self
                .soc_low
                .map_or_else(|| "platform".to_string(), |v| v.to_string()),
            "debug_level" => self.debug_level.to_string(),
            "tolerance" => self.tolerance.to_string(),
            "target_cycles" => self.target_cycles.to_string(),
            "unlock_cycles" => self.unlock_cycles.to_string(),
            "sync" => match self.sync {
                SyncMode::Thesis => "thesis",
                SyncMode::Bounded => "bounded",
            }
            .to_string(),
            "dandrea_efficiency" => self.models.dandrea_efficiency.to_string(),
            "stolaroff_efficiency" => self.models.stolaroff_efficiency.to_string(),
            "stolaroff_factor" => self.models.stolaroff_factor.to_string(),
            "platform" => self
                .platform
                .as_ref()
                .map_or_else(|| "embedded".to_string(), |p| p.display().to_string()),
            "radio_id" => self.radio_id.to_string(),
            "crtp" => self
                .crtp
                .as_ref()
                .map_or("off".to_string(), |c| c.to_string()),
            "pace" => self.pace.to_string(),
            "crtp_idle_s" => self.crtp_idle_s.to_string(),
            "iss" => self.iss.to_string(),
            "stm32.position_source" => self.position_source.to_string(),
            "stm32.range_max_m" => self.range_max_m.to_string(),
            "stm32.flow_std_m_s" => self.flow_std_m_s.to_string(),
            "cluster.cores" => self
                .cluster_cores
                .map_or_else(|| "platform".to_string(), |v| v.to_string()),
            "cluster.mhz" => self
                .cluster_mhz
                .map_or_else(|| "platform".to_string(), |v| v.to_string()),
            "output.compress" => (self.series == protocol::series::SeriesFormat::Zstd).to_string(),
            _ => {
                return Err(ConfigError::UnknownKey {
                    key: key.to_string(),
                    known: RUN_KEYS.map(|(k, _)| k).join(", "),
                })
            }
        })
    }

    /// Applies `key=value` overrides in order (the command line's `--set`).
    pub fn apply_overrides<S: AsRef<str>>(&mut self, overrides: &[S]) -> Result<(), ConfigError> {
        for o in overrides {
            let o = o.as_ref();
            let (key, value) = o
                .split_once('=')
                .ok_or_else(|| ConfigError::BadOverride(o.to_string()))?;
            self.set(key.trim(), value.trim())?;
        }
        Ok(())
    }

    /// Parses TOML (`origin` names it in errors): the thesis's defaults with
    /// the file's keys set on top. Strings, numbers and booleans are given
    /// to [`RunConfig::set`] in their text form.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<RunConfig, ConfigError> {
        let table: toml::Table = toml::from_str(text).map_err(|e| ConfigError::Toml {
            origin: origin.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let mut cfg = RunConfig::default();
        for (key, value) in &flatten_run_table(&table) {
            let text = match value {
                toml::Value::String(s) => s.clone(),
                toml::Value::Integer(i) => i.to_string(),
                toml::Value::Float(f) => f.to_string(),
                toml::Value::Boolean(b) => b.to_string(),
                other => {
                    return Err(ConfigError::Invalid {
                        origin: origin.to_string(),
                        message: format!(
                            "{key}: expected a string or a number, got a {}",
                            other.type_str()
                        ),
                    })
                }
            };
            cfg.set(key, &text).map_err(|e| ConfigError::Invalid {
                origin: origin.to_string(),
                message: e.to_string(),
            })?;
        }
        Ok(cfg)
    }

    /// Reads a TOML run configuration file.
    pub fn from_path(path: &Path) -> Result<RunConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        RunConfig::from_toml_str(&text, &path.display().to_string())
    }

    /// The whole configuration as TOML (every key, `set`'s text form).
    pub fn to_toml(&self) -> String {
        let mut table = toml::Table::new();
        let default = RunConfig::default();
        for (key, _) in RUN_KEYS {
            // The embedded default platform has no file to name: leave the
            // key out, so that reading the file back gives the same config.
            if key == "platform" && self.platform.is_none() {
                continue;
            }
            // Only a swarm member has a radio identifier: a single drone's
            // file stays as it was before the radios existed.
            if key == "radio_id" && self.radio_id == 0 {
                continue;
            }
            // The back end changes no result: files and outputs name it
            // only when it is not the host's default.
            if key == "iss" && self.iss == crate::iss::Backend::DEFAULT {
                continue;
            }
            // Like the back end, the series' form changes no result: named
            // only when it is not the default.
            if key == "output.compress" && self.series == default.series {
                continue;
            }
            // The cluster keys only when they override the platform file.
            if (key == "cluster.cores" && self.cluster_cores.is_none())
                || (key == "cluster.mhz" && self.cluster_mhz.is_none())
            {
                continue;
            }
            let text = self.get(key).expect("RUN_KEYS are known keys");
            // Likewise the STM32 extension's settings at their defaults (a
            // value's text is its shortest round-trip form, so equal texts
            // are equal values).
            let crtp_key = matches!(key, "crtp" | "pace" | "crtp_idle_s");
            if (key.starts_with("stm32.") || crtp_key) && default.get(key).is_ok_and(|d| d == text)
            {
                continue;
            }
            let value = match key {
                "tolerance"
                | "dandrea_efficiency"
                | "stolaroff_efficiency"
                | "stolaroff_factor"
                | "stm32.range_max_m"
                | "stm32.flow_std_m_s"
                | "pace"
                | "crtp_idle_s" => toml::Value::Float(text.parse().expect("a number")),
                "target_cycles" | "unlock_cycles" | "cluster.cores" | "cluster.mhz" => {
                    toml::Value::Integer(text.parse().expect("an integer"))
                }
                // TOML integers are i64: larger identifiers stay text.
                "radio_id" => match i64::try_from(self.radio_id) {
                    Ok(i) => toml::Value::Integer(i),
                    Err(_) => toml::Value::String(text),
                },
                "output.compress" => toml::Value::Boolean(text == "true"),
                _ => toml::Value::String(text),
            };
            table.insert(key.to_string(), value);
        }
        if !self.firmware_params.is_empty() {
            let params = self
                .firmware_params
                .iter()
                .map(|(k, v)| (k.clone(), toml::Value::Integer(*v as i64)))
                .collect();
            table.insert(
                FIRMWARE_KEY_PREFIX.trim_end_matches('.').to_string(),
                toml::Value::Table(params),
            );
        }
        toml::to_string(&table).expect("a flat table serializes")
    }

    /// The platform file this run uses.
    /// The platform file this run uses, with `cluster.cores` and
    /// `cluster.mhz` applied.
    pub fn load_platform(&self) -> Result<super::PlatformConfig, ConfigError> {
        let mut p = match &self.platform {
            None => super::PlatformConfig::default_crazyflie(),
            Some(path) => super::PlatformConfig::from_path(path)?,
        };
        for (key, set) in [
            ("cluster.cores", self.cluster_cores.is_some()),
            ("cluster.mhz", self.cluster_mhz.is_some()),
        ] {
            if set && p.cluster.is_none() {
                return Err(ConfigError::BadValue {
                    key: key.to_string(),
                    value: self.get(key)?,
                    reason: "the platform file has no cluster (\"cluster\": {...})".into(),
                });
            }
        }
        if let Some(c) = p.cluster.as_mut() {
            c.cores = self.cluster_cores.unwrap_or(c.cores);
            c.mhz = self.cluster_mhz.unwrap_or(c.mhz);
        }
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_thesis_settings() {
        let c = RunConfig::default();
        assert_eq!(c.power_model, PowerModelKind::Empirical);
        assert_eq!(c.battery, Some(BatteryModel::LiPol250));
        assert_eq!(c.debug_level, DebugLevel::None);
        assert_eq!(c.tolerance, 0.1);
        assert_eq!(c.target_cycles, 100);
        assert_eq!(c.unlock_cycles, 5000);
        assert_eq!(c.sync, SyncMode::Thesis);
        assert_eq!(c.models.stolaroff_factor, 5.0);
    }

    #[test]
    fn debug_levels_map_to_tracing() {
        assert_eq!("DEBUG_LEVEL_HIGH".parse(), Ok(DebugLevel::High));
        assert_eq!("med".parse(), Ok(DebugLevel::Med));
        assert_eq!(DebugLevel::High.tracing_level(), tracing::Level::TRACE);
        assert_eq!(DebugLevel::None.tracing_level(), tracing::Level::WARN);
        assert!(DebugLevel::High.logs_every_frame());
        assert!(!DebugLevel::Med.logs_every_frame());
    }

    #[test]
    fn firmware_parameters_are_set_checked_and_round_trip() {
        let mut c = RunConfig::default();
        c.set("firmware.explore_param_cell_mm", "80").unwrap();
        c.set("firmware.explore_param_x_min_mm", "-1000").unwrap();
        assert_eq!(c.get("firmware.explore_param_cell_mm").unwrap(), "80");
        assert_eq!(c.firmware_params.len(), 2);
        let back = RunConfig::from_toml_str(&c.to_toml(), "t").unwrap();
        assert_eq!(back, c);
        // Written as a table in a file, or dotted.
        let t = RunConfig::from_toml_str("[firmware]\nexplore_param_cell_mm = 20\n", "t").unwrap();
        assert_eq!(t.firmware_params["explore_param_cell_mm"], 20);
        let e = c.set("firmware.2bad", "1").unwrap_err().to_string();
        assert!(e.contains("not a C identifier"), "{e}");
        let e = c.set("firmware.x", "1.5").unwrap_err().to_string();
        assert!(e.contains("32-bit signed integer"), "{e}");
        let e = c.set("firmware.x", "3000000000").unwrap_err().to_string();
        assert!(e.contains("32-bit signed integer"), "{e}");
    }

    #[test]
    fn cluster_keys_override_the_platform_file_and_round_trip() {
        let aideck = Path::new(env!("CARGO_MANIFEST_DIR")).join("platforms/crazyflie-aideck.json");
        let mut c = RunConfig::default();
        // Unset: absent from the file, the platform's own cluster.
        assert!(!c.to_toml().contains("cluster"));
        c.platform = Some(aideck.clone());
        let p = c.load_platform().unwrap();
        let file = super::super::PlatformConfig::from_path(&aideck).unwrap();
        assert_eq!(p.cluster, file.cluster);
        c.set("cluster.cores", "2").unwrap();
        c.set("cluster.mhz", "90").unwrap();
        let back = RunConfig::from_toml_str(&c.to_toml(), "test").unwrap();
        assert_eq!(back, c);
        let cl = c.load_platform().unwrap().cluster.unwrap();
        assert_eq!((cl.cores, cl.mhz), (2, 90));
        assert_eq!(cl.vref, file.cluster.unwrap().vref);
        c.set("cluster.cores", "platform").unwrap();
        assert_eq!(c.cluster_cores, None);
        for (k, v) in [
            ("cluster.cores", "0"),
            ("cluster.cores", "9"),
            ("cluster.mhz", "0"),
        ] {
            assert!(c.set(k, v).is_err(), "{k}={v}");
        }
        // A platform without a cluster: an error naming the key.
        let mut d = RunConfig::default();
        d.set("cluster.mhz", "50").unwrap();
        let e = d.load_platform().unwrap_err().to_string();
        assert!(e.contains("cluster.mhz") && e.contains("no cluster"), "{e}");
    }
}
