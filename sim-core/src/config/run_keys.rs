//! Every run key, declared once (DESIGN.md §19): its name, its description
//! (which names the accepted values or range), the form of its value in
//! TOML, whether a file names it at its default, how its text is checked
//! and set, and how it is read back. [`RunConfig::set`], [`RunConfig::get`],
//! [`RunConfig::to_toml`] and `cosim keys` all walk [`RUN_KEYS`]; the
//! defaults are [`RunConfig::default`]'s fields.
//!
//! A key's range lives in the parser its `set` calls (`parse_positive`,
//! [`CoreCount`], ...), so a TOML file, `--set` and a scenario's `[run]`
//! table refuse a value with the same message in every process.

use std::path::PathBuf;
use std::str::FromStr;

use protocol::series::SeriesFormat;

use super::run::{RunConfig, SyncMode};
use crate::cluster::CoreCount;

/// The form of a key's value in a TOML file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueKind {
    /// A string (names, paths, and the keys whose value may be `platform`).
    Text,
    /// A float.
    Float,
    /// An integer (text when it does not fit TOML's i64, or is `platform`).
    Integer,
    /// A boolean.
    Bool,
}

/// When [`RunConfig::to_toml`] writes a key.
#[derive(Debug, Clone, Copy)]
pub enum Written {
    /// Always (the thesis's keys: a run's `run.toml` names each).
    Always,
    /// Only away from its default: a key added after the thesis's (radios,
    /// the STM32's extension, CRTP, the cluster's overrides) or a host-side
    /// choice that changes no result (ISS back end, series form), so a file
    /// written without it stays as it was before the key existed.
    UnlessDefault,
    /// Unless the test holds (the embedded platform, which has no file to
    /// name even if a file's path reads like its text form).
    Unless(fn(&RunConfig) -> bool),
}

/// One run key.
#[derive(Clone, Copy)]
pub struct RunKey {
    /// `name` or `table.name`.
    pub name: &'static str,
    /// One line: accepted values, range, default's meaning.
    pub doc: &'static str,
    /// Its form in TOML.
    pub kind: ValueKind,
    /// When the TOML writer names it.
    pub written: Written,
    /// Checks the text form and sets it (the reason on refusal).
    set: fn(&mut RunConfig, &str) -> Result<(), String>,
    /// The text form, as `set` accepts it.
    get: fn(&RunConfig) -> String,
}

impl std::fmt::Debug for RunKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunKey")
            .field("name", &self.name)
            .field("kind", &self.kind)
            .field("written", &self.written)
            .finish_non_exhaustive()
    }
}

impl RunKey {
    /// Sets the key of `cfg` from its text form.
    pub fn set(&self, cfg: &mut RunConfig, value: &str) -> Result<(), String> {
        (self.set)(cfg, value)
    }

    /// The key's text form in `cfg`.
    pub fn get(&self, cfg: &RunConfig) -> String {
        (self.get)(cfg)
    }

    /// Whether [`RunConfig::to_toml`] writes the key of `cfg` (`default`:
    /// [`RunConfig::default`]).
    pub fn is_written(&self, cfg: &RunConfig, default: &RunConfig) -> bool {
        match self.written {
            Written::Always => true,
            Written::UnlessDefault => self.get(cfg) != self.get(default),
            Written::Unless(omit) => !omit(cfg),
        }
    }

    /// The key's value in `cfg` as TOML.
    pub fn toml_value(&self, cfg: &RunConfig) -> toml::Value {
        let text = self.get(cfg);
        match self.kind {
            ValueKind::Text => toml::Value::String(text),
            ValueKind::Float => match text.parse::<f64>() {
                Ok(f) => toml::Value::Float(f),
                Err(_) => toml::Value::String(text),
            },
            ValueKind::Integer => match text.parse::<i64>() {
                Ok(i) => toml::Value::Integer(i),
                Err(_) => toml::Value::String(text),
            },
            ValueKind::Bool => toml::Value::Boolean(text == "true"),
        }
    }
}

/// The key named `name`.
pub fn run_key(name: &str) -> Option<&'static RunKey> {
    RUN_KEYS.iter().find(|k| k.name == name)
}

/// Every key's name, `, `-separated (for errors).
pub fn run_key_names() -> String {
    RUN_KEYS
        .iter()
        .map(|k| k.name)
        .collect::<Vec<_>>()
        .join(", ")
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

/// `platform` (`None`: the platform file's) or a value.
fn or_platform<T>(
    value: &str,
    parse: impl FnOnce(&str) -> Result<T, String>,
) -> Result<Option<T>, String> {
    if value.trim().eq_ignore_ascii_case("platform") {
        Ok(None)
    } else {
        parse(value).map(Some)
    }
}

fn show_or_platform<T: ToString>(v: &Option<T>) -> String {
    v.as_ref()
        .map_or_else(|| "platform".to_string(), |v| v.to_string())
}

/// The number of run keys.
pub const RUN_KEY_COUNT: usize = 27;

/// Every run key, in the order of `cosim keys` and of a written file.
pub static RUN_KEYS: [RunKey; RUN_KEY_COUNT] = [
    RunKey {
        name: "power_model",
        doc: "motor model that drains the battery: empirical | dandrea | stolaroff",
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| parse(v).map(|x| c.power_model = x),
        get: |c| c.power_model.to_string(),
    },
    RunKey {
        name: "battery",
        doc: "lipol250 | ufx250 | cyclone300 | lipol350 | platform (the platform file's)",
        kind: ValueKind::Text,
        written: Written::Always,
        // Unlike soc_low's, only the exact word is the platform's.
        set: |c, v| {
            c.battery = if v.trim().eq_ignore_ascii_case("platform") {
                None
            } else {
                Some(parse(v)?)
            };
            Ok(())
        },
        get: |c| show_or_platform(&c.battery),
    },
    RunKey {
        name: "battery_curve",
        doc: "variable of the v_oc/r_s polynomials: soc (thesis) | discharged (1 - SOC)",
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| parse(v).map(|x| c.battery_curve = x),
        get: |c| c.battery_curve.to_string(),
    },
    RunKey {
        name: "battery_load",
        doc: "thesis (the thesis's curves, motors up to 600 rad/s) | sag (internal resistance, end-of-discharge knee, motor speed capped by the voltage; DESIGN.md §16)",
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| parse(v).map(|x| c.battery_load = x),
        get: |c| c.battery_load.to_string(),
    },
    RunKey {
        name: "battery_empty",
        doc: "at soc_end: error (MESSY: the run fails) | end (the flight ends there, as a firmware exit ends it)",
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| parse(v).map(|x| c.battery_empty = x),
        get: |c| c.battery_empty.to_string(),
    },
    RunKey {
        name: "soc_low",
        doc: "BATTERY_LOW threshold in % SOC (default: the platform file's, 10)",
        // Text: `platform` or a number, as files have always had it.
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| {
            c.soc_low = or_platform(v, |v| {
                let v = parse_non_negative(v)?;
                if v > 100.0 {
                    return Err("a percentage in [0, 100]".into());
                }
                Ok(v)
            })?;
            Ok(())
        },
        get: |c| show_or_platform(&c.soc_low),
    },
    RunKey {
        name: "debug_level",
        doc: "NONE | LOW | MED | HIGH (tracing warn | info | debug | trace)",
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| parse(v).map(|x| c.debug_level = x),
        get: |c| c.debug_level.to_string(),
    },
    RunKey {
        name: "tolerance",
        doc: "PID target tolerance in m (0.1)",
        kind: ValueKind::Float,
        written: Written::Always,
        set: |c, v| parse_positive(v).map(|x| c.tolerance = x),
        get: |c| c.tolerance.to_string(),
    },
    RunKey {
        name: "target_cycles",
        doc: "PID iterations inside the tolerance to reach a target (100)",
        kind: ValueKind::Integer,
        written: Written::Always,
        set: |c, v| parse_count(v).map(|x| c.target_cycles = x),
        get: |c| c.target_cycles.to_string(),
    },
    RunKey {
        name: "unlock_cycles",
        doc: "PID iterations before an unreached target is bypassed (5000)",
        kind: ValueKind::Integer,
        written: Written::Always,
        set: |c, v| parse_count(v).map(|x| c.unlock_cycles = x),
        get: |c| c.unlock_cycles.to_string(),
    },
    RunKey {
        name: "sync",
        doc: "time bookkeeping: thesis | bounded",
        kind: ValueKind::Text,
        written: Written::Always,
        set: |c, v| parse(v).map(|x| c.sync = x),
        get: |c| {
            match c.sync {
                SyncMode::Thesis => "thesis",
                SyncMode::Bounded => "bounded",
            }
            .to_string()
        },
    },
    RunKey {
        name: "dandrea_efficiency",
        doc: "D'Andrea power transfer efficiency (0.8; Table 4.4 says 0.9)",
        kind: ValueKind::Float,
        written: Written::Always,
        set: |c, v| parse_fraction(v).map(|x| c.models.dandrea_efficiency = x),
        get: |c| c.models.dandrea_efficiency.to_string(),
    },
    RunKey {
        name: "stolaroff_efficiency",
        doc: "Stolaroff efficiency (0.8)",
        kind: ValueKind::Float,
        written: Written::Always,
        set: |c, v| parse_fraction(v).map(|x| c.models.stolaroff_efficiency = x),
        get: |c| c.models.stolaroff_efficiency.to_string(),
    },
    RunKey {
        name: "stolaroff_factor",
        doc: "Stolaroff correction factor (5, section 5.1)",
        kind: ValueKind::Float,
        written: Written::Always,
        set: |c, v| parse_positive(v).map(|x| c.models.stolaroff_factor = x),
        get: |c| c.models.stolaroff_factor.to_string(),
    },
    RunKey {
        name: "platform",
        doc: "platform JSON file (default: the embedded Crazyflie)",
        kind: ValueKind::Text,
        // The embedded platform has no file to name: left out, so that
        // reading the file back gives the same config.
        written: Written::Unless(|c| c.platform.is_none()),
        set: |c, v| {
            if v.trim().is_empty() {
                return Err("expected a file path".into());
            }
            c.platform = Some(PathBuf::from(v));
            Ok(())
        },
        get: |c| {
            c.platform
                .as_ref()
                .map_or_else(|| "embedded".to_string(), |p| p.display().to_string())
        },
    },
    RunKey {
        name: "radio_id",
        doc: "the radios' EUI, an unsigned 64-bit integer (0; cosim gives 1, 2, 3, ...)",
        // TOML integers are i64: larger identifiers stay text.
        kind: ValueKind::Integer,
        // Only a swarm member has one.
        written: Written::UnlessDefault,
        set: |c, v| {
            c.radio_id = v
                .trim()
                .parse::<u64>()
                .map_err(|_| "expected an unsigned 64-bit integer".to_string())?;
            Ok(())
        },
        get: |c| c.radio_id.to_string(),
    },
    RunKey {
        name: "stm32.position_source",
        doc: "the STM32's position estimate: gps (thesis) | flow (dead reckoning on FLOW_VX/VY through the flow filter)",
        kind: ValueKind::Text,
        written: Written::UnlessDefault,
        set: |c, v| v.parse().map(|x| c.position_source = x),
        get: |c| c.position_source.to_string(),
    },
    RunKey {
        name: "stm32.range_max_m",
        doc: "range sensors' max range in m (2); a reading at or beyond it is 'nothing in range'",
        kind: ValueKind::Float,
        written: Written::UnlessDefault,
        set: |c, v| parse_positive(v).map(|x| c.range_max_m = x),
        get: |c| c.range_max_m.to_string(),
    },
    RunKey {
        name: "crtp",
        doc: "serve cflib's CRTP link: off | udp:HOST:PORT | replay:FILE (a crtp.jsonl); the firmware starts it with EXT_CRTP (crtp_host.elf), docs/CFLIB.md",
        kind: ValueKind::Text,
        written: Written::UnlessDefault,
        set: |c, v| {
            c.crtp = match v.trim() {
                "" | "off" => None,
                v => Some(v.parse()?),
            };
            Ok(())
        },
        get: |c| c.crtp.as_ref().map_or("off".to_string(), |s| s.to_string()),
    },
    RunKey {
        name: "stabilizer.controller",
        doc: "the controller a CRTP client's set-points fly: thesis (default; the Webots controller with velocity and position loops) | pid (the Crazyflie firmware's cascaded PID, its default gains, PWM motors; a timestep of at most 4 ms), docs/CFLIB.md",
        kind: ValueKind::Text,
        written: Written::UnlessDefault,
        set: |c, v| v.parse().map(|x| c.controller = x),
        get: |c| c.controller.to_string(),
    },
    RunKey {
        name: "pace",
        doc: "with a live CRTP link, simulated seconds per wall second (1.0; 0 = unpaced)",
        kind: ValueKind::Float,
        written: Written::UnlessDefault,
        set: |c, v| parse_non_negative(v).map(|x| c.pace = x),
        get: |c| c.pace.to_string(),
    },
    RunKey {
        name: "crtp_idle_s",
        doc: "the CRTP link is closed after this many simulated seconds without a packet (10)",
        kind: ValueKind::Float,
        written: Written::UnlessDefault,
        set: |c, v| parse_positive(v).map(|x| c.crtp_idle_s = x),
        get: |c| c.crtp_idle_s.to_string(),
    },
    RunKey {
        name: "stm32.flow_std_m_s",
        doc: "flow mode: the flow noise the STM32's filter assumes, m/s per sample (0.069, the Flow deck's at 0.3 m; 0 = the raw flow)",
        kind: ValueKind::Float,
        written: Written::UnlessDefault,
        set: |c, v| parse_non_negative(v).map(|x| c.flow_std_m_s = x),
        get: |c| c.flow_std_m_s.to_string(),
    },
    RunKey {
        name: "iss",
        doc: "ISS back end: jit (block translator, default on x86-64) | interp (interpreter); identical results",
        kind: ValueKind::Text,
        // No result depends on it: named only away from the host's default.
        written: Written::UnlessDefault,
        set: |c, v| parse(v).map(|x| c.iss = x),
        get: |c| c.iss.to_string(),
    },
    RunKey {
        name: "cluster.cores",
        doc: "the GAP8 cluster's cores, 1-8, in place of the platform file's (platform: the file's); the platform must have a cluster",
        kind: ValueKind::Integer,
        written: Written::UnlessDefault,
        set: |c, v| {
            c.cluster_cores = match v.trim() {
                "platform" => None,
                v => Some(
                    v.parse::<CoreCount>()
                        .map_err(|e| format!("{e}; or platform"))?,
                ),
            };
            Ok(())
        },
        get: |c| show_or_platform(&c.cluster_cores),
    },
    RunKey {
        name: "cluster.mhz",
        doc: "the GAP8 cluster's clock in MHz, in place of the platform file's (platform: the file's)",
        kind: ValueKind::Integer,
        written: Written::UnlessDefault,
        set: |c, v| {
            c.cluster_mhz = match v.trim() {
                "platform" => None,
                v => match v.parse::<u64>() {
                    Ok(f) if (1..=10_000).contains(&f) => Some(f),
                    _ => return Err("expected a whole number of MHz, or platform".into()),
                },
            };
            Ok(())
        },
        get: |c| show_or_platform(&c.cluster_mhz),
    },
    RunKey {
        name: "output.compress",
        doc: "store the series (power.csv, motor_*.csv, trajectory.csv, time_map.csv) and the traces (world.trace, platform.trace) zstd-compressed as NAME.zst (true, default) or plain (false); same bytes once decompressed",
        kind: ValueKind::Bool,
        // Like the back end, the series' form changes no result.
        written: Written::UnlessDefault,
        set: |c, v| {
            c.series = match v.trim() {
                "true" => SeriesFormat::Zstd,
                "false" => SeriesFormat::Plain,
                _ => return Err("expected true or false".into()),
            };
            Ok(())
        },
        get: |c| (c.series == SeriesFormat::Zstd).to_string(),
    },
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::{CoreCountError, MAX_CORES};

    #[test]
    fn names_are_unique_and_found() {
        for (i, key) in RUN_KEYS.iter().enumerate() {
            assert!(!key.doc.is_empty(), "{}", key.name);
            assert_eq!(run_key(key.name).map(|k| k.name), Some(key.name));
            assert!(
                RUN_KEYS[i + 1..].iter().all(|k| k.name != key.name),
                "{} twice",
                key.name
            );
        }
        assert!(run_key("gravity").is_none());
        assert_eq!(run_key_names().split(", ").count(), RUN_KEY_COUNT);
    }

    #[test]
    fn every_default_is_accepted_by_its_own_check() {
        let d = RunConfig::default();
        for key in &RUN_KEYS {
            // The embedded platform has no file to name.
            if key.name == "platform" {
                continue;
            }
            let mut c = RunConfig::default();
            key.set(&mut c, &key.get(&d))
                .unwrap_or_else(|e| panic!("{}: {e}", key.name));
            assert_eq!(c, d, "{}", key.name);
        }
    }

    #[test]
    fn the_writer_names_the_thesis_keys_and_leaves_out_the_rest_at_defaults() {
        let text = RunConfig::default().to_toml();
        let table: toml::Table = toml::from_str(&text).unwrap();
        for key in &RUN_KEYS {
            assert_eq!(
                table.contains_key(key.name),
                matches!(key.written, Written::Always),
                "{}:\n{text}",
                key.name
            );
        }
        // A platform file whose path reads like the embedded one's text.
        let mut c = RunConfig::default();
        c.set("platform", "embedded").unwrap();
        let back = RunConfig::from_toml_str(&c.to_toml(), "t").unwrap();
        assert_eq!(back.platform, Some(PathBuf::from("embedded")));
        assert_eq!(
            RunConfig::from_toml_str(&text, "t").unwrap(),
            RunConfig::default()
        );
    }

    #[test]
    fn the_core_count_has_one_range_and_one_message() {
        let key = run_key("cluster.cores").unwrap();
        assert!(key.doc.contains(&format!("1-{MAX_CORES}")), "{}", key.doc);
        let mut c = RunConfig::default();
        for n in 1..=MAX_CORES {
            key.set(&mut c, &n.to_string()).unwrap();
            assert_eq!(key.get(&c), n.to_string());
        }
        for bad in ["0", "9", "many"] {
            let e = c.set("cluster.cores", bad).unwrap_err().to_string();
            assert!(
                e.contains(&CoreCountError(bad.into()).to_string()),
                "{bad}: {e}"
            );
        }
        // The platform file and the cluster itself: the same message.
        let aideck = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("platforms/crazyflie-aideck.json");
        let mut p = crate::config::PlatformConfig::from_path(&aideck).unwrap();
        let cluster = p.cluster.as_mut().unwrap();
        cluster.cores = MAX_CORES + 1;
        let cfg = cluster.cluster_config(false, crate::iss::Backend::DEFAULT);
        let nine = CoreCountError((MAX_CORES + 1).to_string()).to_string();
        assert_eq!(p.validate().unwrap_err(), nine);
        let mut mem = crate::iss::Memory::new();
        let e = crate::cluster::Cluster::new(cfg, &mut mem).unwrap_err();
        assert_eq!(e.to_string(), nine);
    }
}
