//! The run configuration: what the thesis's `simul_configs.hpp` holds
//! (§4.2.4 "Configuration files and debug mode") plus the few knobs the
//! platform needs, read from TOML and overridable key by key from the
//! command line (`--set key=value`).
//!
//! Both paths go through [`RunConfig::set`], so a TOML file and a command
//! line accept exactly the same names and values with the same messages.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::power::battery::{BatteryModel, CurveAxis};
use crate::power::models::{ModelParams, PowerModelKind};
use crate::power::sag::{BatteryLoad, OnEmpty};
pub use crate::sync::SyncMode;

pub use super::debug_level::DebugLevel;

use super::run_keys::{run_key, run_key_names, RUN_KEYS};
use super::ConfigError;
use crate::cluster::CoreCount;
use crate::peripherals::stm32::crtp::CrtpSpec;
use crate::peripherals::stm32::estimator::DEFAULT_FLOW_STD;
use crate::peripherals::stm32::{Controller, PositionSource};

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
    /// The controller a CRTP client's set-points are flown with.
    pub controller: Controller,
    /// Pacing of a live CRTP link (simulated s per wall s).
    pub pace: f64,
    /// Simulated seconds without a packet that close the CRTP link.
    pub crtp_idle_s: f64,
    /// The ISS back end of every core (no effect on any result).
    pub iss: crate::iss::Backend,
    /// The cluster's cores and clock (MHz) in place of the platform
    /// file's (`None`: the file's), so that a sweep varies them.
    pub cluster_cores: Option<CoreCount>,
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
            controller: Controller::Thesis,
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

fn unknown_key(key: &str) -> ConfigError {
    ConfigError::UnknownKey {
        key: key.to_string(),
        known: run_key_names(),
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
        let spec = run_key(key).ok_or_else(|| unknown_key(key))?;
        spec.set(self, value).map_err(bad)
    }

    /// The text form of one key, as `set` accepts it.
    pub fn get(&self, key: &str) -> Result<String, ConfigError> {
        if let Some(v) = key
            .strip_prefix(FIRMWARE_KEY_PREFIX)
            .and_then(|name| self.firmware_params.get(name))
        {
            return Ok(v.to_string());
        }
        Ok(run_key(key).ok_or_else(|| unknown_key(key))?.get(self))
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
        for key in &RUN_KEYS {
            if key.is_written(self, &default) {
                table.insert(key.name.to_string(), key.toml_value(self));
            }
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
            c.cores = self.cluster_cores.map_or(c.cores, CoreCount::get);
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
