//! The platform file: JSON in the shape of MESSY's configuration
//! (`messy/codegen/*.json`), so a MESSY user recognises it (DESIGN.md §4).
//!
//! ```json
//! { "resolution": "SC_MS",
//!   "bus":  { "vref": 3.0 },
//!   "core": { "vref": 1.2, "frequency": 250000000,
//!             "states": { "running": { "current": "13" }, "sleeping": { "current": "0.002" } },
//!             "converter": { "efficiency": 1.0 } },
//!   "peripherals": {
//!     "sensors": { "camera": { "vref": 3.0, "register_memory": 102402,
//!                              "states": { "read": { "current": "1.75", "delay": "16" }, … } }, … },
//!     "harvesters": { "battery": { "harvester_type": "battery", "model": "lipol250",
//!                                  "capacity": 250, "soc_init": 100, "soc_end": 0,
//!                                  "converter": { "efficiency": "ldo" } } } } }
//! ```
//!
//! Units are MESSY's: currents in mA, delays in ms, voltages in V, capacity
//! in mAh, SOC thresholds in percent. Like MESSY, numbers may be written as
//! JSON numbers or as strings (`"current": "1.75"`). MESSY's `tracing`
//! blocks are accepted and ignored; any other unknown key is an error.
//!
//! What our file adds to MESSY's shape: the core's `states` (`running`,
//! `sleeping`) and `frequency`, the optional radios `uwb` and `p2p` (states
//! `tx`, `rx`, `idle`, `sleep`, each defaulting to its datasheet current;
//! a platform file without them still has both radios, with those currents), a sensor's `bus` (`vcc`, the default, or
//! `battery` for the motors, §4.5.2), the battery's `model` and `soc_low`
//! (the BATTERY_LOW threshold, 10 %), and a converter `efficiency` of
//! `"ldo"` (Eq. 4.1).
//!
//! The default Crazyflie file (`sim-core/platforms/crazyflie.json`) holds the
//! thesis's values: VCC 3.0 V (§4.5), camera 1.75/1.75/0.14 mA and STM32
//! 150/150/60 mA (§4.5.1), camera read delay 16 ms and STM32 7 ms (the
//! camera and PID/motor parts of `iter_delay`, §4.2.4), the LiPol 250 mAh
//! battery (§4.5.4) behind the LDO. The core's 13 mA running / 0.002 mA
//! sleeping at 1.2 V are MESSY's own defaults (`CPU_ON_I_ON`, `CPU_I_IDLE`
//! in its `config.h`), not GAP8 measurements: the thesis takes the core's
//! power from MESSY without giving numbers.

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::de::{self, Deserializer};
use serde::{Deserialize, Serialize};

use crate::power::battery::BatteryModel;
use crate::power::converter::{Converter, InputVariable, Lut};
use crate::units::{Amps, Hertz, Millis, Volts};

use super::ConfigError;

/// The embedded default platform file.
pub const DEFAULT_CRAZYFLIE_JSON: &str = include_str!("../../platforms/crazyflie.json");

/// A number written either as a JSON number or as a numeric string (MESSY
/// writes currents and delays as strings).
fn number_or_string<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum NumOrStr {
        Num(f64),
        Str(String),
    }
    match NumOrStr::deserialize(d)? {
        NumOrStr::Num(v) => Ok(v),
        NumOrStr::Str(s) => s
            .trim()
            .parse::<f64>()
            .map_err(|_| de::Error::custom(format!("expected a number, got {s:?}"))),
    }
}

fn optional_number_or_string<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    number_or_string(d).map(Some)
}

/// Deserializes a string through the type's `FromStr`, so that JSON and the
/// run configuration accept the same names with the same messages.
fn from_str_value<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: FromStr<Err = String>,
{
    let s = String::deserialize(d)?;
    s.parse().map_err(de::Error::custom)
}

fn serialize_display<S: serde::Serializer, T: fmt::Display>(
    v: &T,
    s: S,
) -> Result<S::Ok, S::Error> {
    s.collect_str(v)
}

fn yes() -> bool {
    true
}

fn default_resolution() -> String {
    "SC_MS".to_string()
}

fn default_soc_low() -> f64 {
    10.0
}

/// The whole platform file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlatformConfig {
    /// Power sampling resolution; only MESSY's `SC_MS` (1 ms, §4.5) is supported.
    #[serde(default = "default_resolution")]
    pub resolution: String,
    /// MESSY's trace settings: accepted, ignored (we write CSV files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracing: Option<serde_json::Value>,
    /// The VCC power bus.
    pub bus: BusConfig,
    /// The core (GAP8's fabric controller in the thesis).
    pub core: CoreConfig,
    /// The GAP8's cluster (DESIGN.md §12, docs/CLUSTER.md); absent: the
    /// FC alone, as the thesis's platform.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster: Option<ClusterSection>,
    /// Sensors and harvesters.
    pub peripherals: PeripheralsConfig,
}

/// The platform file's `"cluster"` (beside `"core"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterSection {
    /// Cluster cores, 1–8 (GAP8: 8).
    #[serde(default = "default_cluster_cores")]
    pub cores: usize,
    /// Cluster clock in MHz (GAP8's maximum: 175, GreenWaves).
    #[serde(default = "default_cluster_mhz")]
    pub mhz: u64,
    /// Cluster supply voltage in V (GAP8 at 175 MHz: 1.2 V).
    #[serde(default = "default_cluster_vref")]
    pub vref: f64,
    /// The AI deck's regulators between the battery and the cluster's
    /// supply (`power::deck`); absent: ideal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converter: Option<ConverterConfig>,
}

fn default_cluster_cores() -> usize {
    8
}
fn default_cluster_mhz() -> u64 {
    175
}
fn default_cluster_vref() -> f64 {
    1.2
}

impl ClusterSection {
    /// The deck's regulators, battery to cluster (ideal if absent).
    pub fn converter(&self) -> Result<Converter, String> {
        build_converter(&self.converter, "cluster")
    }

    /// The cluster's configuration for `crate::cluster`.
    pub fn cluster_config(
        &self,
        idle_skip: bool,
        iss: crate::iss::Backend,
    ) -> crate::cluster::ClusterConfig {
        crate::cluster::ClusterConfig {
            cores: self.cores,
            clock: Hertz(self.mhz.saturating_mul(1_000_000)),
            vref: self.vref,
            idle_skip,
            iss,
        }
    }
}

/// The VCC power bus (`bus` in MESSY).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusConfig {
    /// Bus voltage in V (3.0 V, the LP2985-30 output, §4.5).
    pub vref: f64,
}

/// The core.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoreConfig {
    /// Core supply voltage in V.
    pub vref: f64,
    /// Clock in Hz (250 MHz by default, DESIGN.md §4).
    pub frequency: u64,
    /// Which ISS (informative; MESSY's `iss`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iss: Option<String>,
    /// Power states; `running` and `sleeping` are required (current in mA).
    pub states: BTreeMap<String, StateConfig>,
    /// Converter from the core's supply to the VCC bus (ideal if absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converter: Option<ConverterConfig>,
    /// MESSY's trace settings: accepted, ignored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracing: Option<serde_json::Value>,
}

/// `peripherals` in MESSY.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeripheralsConfig {
    /// Sensors by name; `camera` and `stm32` are required.
    pub sensors: BTreeMap<String, SensorConfig>,
    /// Energy sources by name; exactly one battery.
    pub harvesters: BTreeMap<String, HarvesterConfig>,
}

/// Which power bus a sensor hangs on (§4.5.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BusKind {
    /// The regulated 3.0 V VCC bus.
    #[default]
    Vcc,
    /// The motor bus at the battery voltage.
    Battery,
}

/// One sensor (`peripherals.sensors.<name>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// Whether the sensor has a power model (MESSY's `power`).
    #[serde(default = "yes")]
    pub power: bool,
    /// Supply voltage in V; the bus voltage if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vref: Option<f64>,
    /// The bus it draws from.
    #[serde(default)]
    pub bus: BusKind,
    /// Bytes of registers in the peripheral window (MESSY's `register_memory`).
    pub register_memory: u64,
    /// Power states by name (`read`, `write`, `idle`, …).
    pub states: BTreeMap<String, StateConfig>,
    /// Converter to its bus (ideal if absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converter: Option<ConverterConfig>,
    /// MESSY's trace settings: accepted, ignored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracing: Option<serde_json::Value>,
}

/// One power state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateConfig {
    /// Current in mA.
    #[serde(deserialize_with = "number_or_string")]
    pub current: f64,
    /// How long the operation takes, in whole ms (absent for `idle`).
    #[serde(
        default,
        deserialize_with = "optional_number_or_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub delay: Option<f64>,
}

impl StateConfig {
    /// The state's current in amperes.
    pub fn current(&self) -> Amps {
        Amps(self.current / 1000.0)
    }

    /// The state's delay (validated to be a whole number of ms).
    pub fn delay(&self) -> Option<Millis> {
        self.delay.map(|d| Millis(d as u64))
    }
}

/// A battery (`peripherals.harvesters.<name>` with `harvester_type: battery`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HarvesterConfig {
    /// Only `battery` is supported.
    pub harvester_type: String,
    /// Which of the four battery models (§4.5.4, §5.4); thesis names accepted.
    #[serde(
        deserialize_with = "from_str_value",
        serialize_with = "serialize_display"
    )]
    pub model: BatteryModel,
    /// Capacity in mAh; must be the model's.
    #[serde(deserialize_with = "number_or_string")]
    pub capacity: f64,
    /// Initial SOC in percent (MESSY: `soc_init / 100`).
    #[serde(deserialize_with = "number_or_string")]
    pub soc_init: f64,
    /// SOC in percent at which the battery is empty and the run stops.
    #[serde(deserialize_with = "number_or_string")]
    pub soc_end: f64,
    /// SOC in percent under which BATTERY_LOW is raised (10 %, §4.5.4).
    #[serde(default = "default_soc_low", deserialize_with = "number_or_string")]
    pub soc_low: f64,
    /// MESSY's nominal battery voltage; informative (the curves give the voltage).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vref: Option<f64>,
    /// Converter between the VCC bus and the battery (the LDO).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converter: Option<ConverterConfig>,
    /// MESSY's trace settings: accepted, ignored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracing: Option<serde_json::Value>,
}

/// A converter: a fixed `efficiency` (fraction), `"ldo"`, or a `lut`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConverterConfig {
    /// A fraction in (0, 1] or the string `"ldo"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub efficiency: Option<EfficiencySpec>,
    /// What the LUT is indexed by: `current` (mA, default) or `voltage` (V).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_variable: Option<String>,
    /// MESSY's converter direction; accepted and ignored (the position in the
    /// network gives the direction; see `power::converter`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out_dir: Option<bool>,
    /// A table of efficiencies in percent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lut: Option<LutConfig>,
}

/// `efficiency`: a number or a name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum EfficiencySpec {
    Value(f64),
    Named(String),
}

/// MESSY's LUT (`input_values`, `efficiency_values` in percent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LutConfig {
    pub input_values: Vec<f64>,
    pub efficiency_values: Vec<f64>,
}

impl ConverterConfig {
    /// Builds the converter, or says what is wrong.
    pub fn build(&self) -> Result<Converter, String> {
        match (&self.efficiency, &self.lut) {
            (Some(_), Some(_)) => Err("give either efficiency or lut, not both".into()),
            (None, None) => Err("needs an efficiency or a lut".into()),
            (Some(EfficiencySpec::Value(eta)), None) => {
                if eta.is_finite() && *eta > 0.0 && *eta <= 1.0 {
                    Ok(Converter::fixed(*eta))
                } else {
                    Err(format!("efficiency {eta} is not in (0, 1]"))
                }
            }
            (Some(EfficiencySpec::Named(name)), None) => {
                if name.eq_ignore_ascii_case("ldo") {
                    Ok(Converter::ldo())
                } else {
                    Err(format!(
                        "efficiency {name:?} is neither a number nor \"ldo\""
                    ))
                }
            }
            (None, Some(lut)) => {
                let input = match self.input_variable.as_deref() {
                    None | Some("current") => InputVariable::Current,
                    Some("voltage") => InputVariable::Voltage,
                    Some(other) => {
                        return Err(format!(
                            "input_variable {other:?} is neither \"current\" nor \"voltage\""
                        ))
                    }
                };
                let table = Lut::new(lut.input_values.clone(), lut.efficiency_values.clone())
                    .map_err(|e| e.to_string())?;
                Ok(Converter::lut(table, input))
            }
        }
    }
}

fn build_converter(c: &Option<ConverterConfig>, at: &str) -> Result<Converter, String> {
    match c {
        None => Ok(Converter::ideal()),
        Some(c) => c.build().map_err(|e| format!("{at}.converter: {e}")),
    }
}

fn check_positive(v: f64, at: &str) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("{at} must be a positive number, got {v}"))
    }
}

fn check_states(
    states: &BTreeMap<String, StateConfig>,
    required: &[&str],
    at: &str,
) -> Result<(), String> {
    for name in required {
        if !states.contains_key(*name) {
            return Err(format!("{at}.states needs a {name:?} state"));
        }
    }
    for (name, s) in states {
        if !(s.current.is_finite() && s.current >= 0.0) {
            return Err(format!(
                "{at}.states.{name}.current must be a non-negative number of mA, got {}",
                s.current
            ));
        }
        if let Some(d) = s.delay {
            if !(d.is_finite() && d >= 0.0 && d.fract() == 0.0) {
                return Err(format!(
                    "{at}.states.{name}.delay must be a whole non-negative number of ms, got {d}"
                ));
            }
        }
    }
    Ok(())
}

/// Sensor states the network maps [`crate::power::SensorState`] onto.
pub const SENSOR_STATES: [&str; 3] = ["read", "write", "idle"];
/// The radios (DESIGN.md §8): optional sensors; absent, they have the
/// datasheets' currents (`peripherals::radio::{uwb, p2p}`).
pub const RADIO_SENSORS: [&str; 2] = ["uwb", "p2p"];
/// A radio's power states (currents in mA; any state left out takes the
/// datasheet's figure).
pub const RADIO_STATES: [&str; 4] = ["tx", "rx", "idle", "sleep"];
/// Core states the network maps [`crate::power::CoreState`] onto.
pub const CORE_STATES: [&str; 2] = ["running", "sleeping"];

impl PlatformConfig {
    /// The embedded Crazyflie platform (`sim-core/platforms/crazyflie.json`).
    pub fn default_crazyflie() -> PlatformConfig {
        // The file is compiled in and checked by a unit test, so a failure
        // here is a build defect, not bad input.
        PlatformConfig::from_json_str(DEFAULT_CRAZYFLIE_JSON, "<embedded crazyflie.json>")
            .expect("the embedded platform file is valid")
    }

    /// Reads and validates a platform file.
    pub fn from_path(path: &Path) -> Result<PlatformConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        PlatformConfig::from_json_str(&text, &path.display().to_string())
    }

    /// Parses and validates platform JSON; `origin` names it in errors.
    pub fn from_json_str(text: &str, origin: &str) -> Result<PlatformConfig, ConfigError> {
        let cfg: PlatformConfig =
            serde_json::from_str(text).map_err(|source| ConfigError::Json {
                origin: origin.to_string(),
                source,
            })?;
        cfg.validate().map_err(|message| ConfigError::Invalid {
            origin: origin.to_string(),
            message,
        })?;
        Ok(cfg)
    }

    /// Checks what serde cannot: required entries, ranges, converters.
    pub fn validate(&self) -> Result<(), String> {
        if self.resolution != "SC_MS" {
            return Err(format!(
                "resolution {:?} is not supported (only \"SC_MS\": power is sampled every 1 ms)",
                self.resolution
            ));
        }
        check_positive(self.bus.vref, "bus.vref")?;
        check_positive(self.core.vref, "core.vref")?;
        if self.core.frequency == 0 {
            return Err("core.frequency must be a positive number of Hz".into());
        }
        check_states(&self.core.states, &CORE_STATES, "core")?;
        if let Some(c) = &self.cluster {
            crate::cluster::CoreCount::new(c.cores).map_err(|e| e.to_string())?;
            if c.mhz == 0 {
                return Err("cluster.mhz must be a positive number of MHz".into());
            }
            check_positive(c.vref, "cluster.vref")?;
            c.converter()?;
        }
        build_converter(&self.core.converter, "core")?;
        for required in ["camera", "stm32"] {
            if !self.peripherals.sensors.contains_key(required) {
                return Err(format!("peripherals.sensors needs a {required:?} sensor"));
            }
        }
        for (name, s) in &self.peripherals.sensors {
            let at = format!("peripherals.sensors.{name}");
            if let Some(v) = s.vref {
                check_positive(v, &format!("{at}.vref"))?;
            }
            let required: &[&str] = if name == "camera" || name == "stm32" {
                &SENSOR_STATES
            } else if RADIO_SENSORS.contains(&name.as_str()) {
                // Every state has the datasheet's figure as its default.
                &[]
            } else {
                &["idle"]
            };
            check_states(&s.states, required, &at)?;
            if RADIO_SENSORS.contains(&name.as_str()) {
                if let Some(bad) = s
                    .states
                    .keys()
                    .find(|k| !RADIO_STATES.contains(&k.as_str()))
                {
                    return Err(format!(
                        "{at}.states.{bad}: a radio's states are {}",
                        RADIO_STATES.join(", ")
                    ));
                }
                if s.bus != BusKind::Vcc {
                    return Err(format!("{at}.bus: the radios hang on the VCC bus"));
                }
            }
            build_converter(&s.converter, &at)?;
        }
        let batteries: Vec<_> = self.peripherals.harvesters.iter().collect();
        if batteries.len() != 1 {
            return Err(format!(
                "peripherals.harvesters must hold exactly one battery, found {}",
                batteries.len()
            ));
        }
        let (name, b) = batteries[0];
        let at = format!("peripherals.harvesters.{name}");
        if b.harvester_type != "battery" {
            return Err(format!(
                "{at}.harvester_type {:?} is not supported (only \"battery\")",
                b.harvester_type
            ));
        }
        if b.capacity != b.model.capacity_mah() {
            return Err(format!(
                "{at}.capacity {} mAh does not match model {} ({} mAh): the capacity comes \
                 with the model's discharge curves (§5.4)",
                b.capacity,
                b.model,
                b.model.capacity_mah()
            ));
        }
        let pct = |v: f64| v.is_finite() && (0.0..=100.0).contains(&v);
        if !(pct(b.soc_init) && pct(b.soc_end) && pct(b.soc_low)) {
            return Err(format!(
                "{at}: soc_init, soc_end and soc_low are percentages in [0, 100]"
            ));
        }
        if b.soc_end >= b.soc_init {
            return Err(format!(
                "{at}: soc_end ({} %) must be below soc_init ({} %)",
                b.soc_end, b.soc_init
            ));
        }
        build_converter(&b.converter, &at)?;
        Ok(())
    }

    /// A sensor by name.
    pub fn sensor(&self, name: &str) -> Option<&SensorConfig> {
        self.peripherals.sensors.get(name)
    }

    /// The battery harvester (validated to be the only one).
    pub fn battery(&self) -> &HarvesterConfig {
        self.peripherals
            .harvesters
            .values()
            .next()
            .expect("validated: exactly one battery")
    }

    /// The core clock.
    pub fn core_frequency(&self) -> Hertz {
        Hertz(self.core.frequency)
    }

    /// VCC bus voltage.
    pub fn vcc(&self) -> Volts {
        Volts(self.bus.vref)
    }

    /// The converter of the core (ideal if absent).
    pub fn core_converter(&self) -> Result<Converter, String> {
        build_converter(&self.core.converter, "core")
    }
}

impl SensorConfig {
    /// A state by name.
    pub fn state(&self, name: &str) -> Option<&StateConfig> {
        self.states.get(name)
    }

    /// Its converter (ideal if absent).
    pub fn converter(&self) -> Result<Converter, String> {
        build_converter(&self.converter, "sensor")
    }
}

impl HarvesterConfig {
    /// Its converter (ideal if absent).
    pub fn converter(&self) -> Result<Converter, String> {
        build_converter(&self.converter, "battery")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_default_parses_with_the_thesis_values() {
        let p = PlatformConfig::default_crazyflie();
        assert_eq!(p.vcc(), Volts(3.0));
        assert_eq!(p.core_frequency(), Hertz(250_000_000));
        let cam = p.sensor("camera").unwrap();
        assert_eq!(cam.state("read").unwrap().current, 1.75);
        assert_eq!(cam.state("write").unwrap().current, 1.75);
        assert_eq!(cam.state("idle").unwrap().current, 0.14);
        assert_eq!(cam.state("read").unwrap().delay(), Some(Millis(16)));
        assert_eq!(cam.register_memory, 102_402);
        let stm = p.sensor("stm32").unwrap();
        assert_eq!(stm.state("read").unwrap().current(), Amps(0.150));
        assert_eq!(stm.state("idle").unwrap().current(), Amps(0.060));
        assert_eq!(p.sensor("motors").unwrap().bus, BusKind::Battery);
        let b = p.battery();
        assert_eq!(b.model, BatteryModel::LiPol250);
        assert_eq!((b.soc_init, b.soc_end, b.soc_low), (100.0, 0.0, 10.0));
        assert_eq!(b.converter().unwrap(), Converter::ldo());
    }

    #[test]
    fn radios_take_datasheet_defaults_and_reject_unknown_states() {
        let mut v: serde_json::Value = serde_json::from_str(DEFAULT_CRAZYFLIE_JSON).unwrap();
        v["peripherals"]["sensors"]["uwb"] = serde_json::json!({
            "register_memory": 320,
            "states": { "rx": { "current": "50" } }
        });
        let p = PlatformConfig::from_json_str(&v.to_string(), "t").unwrap();
        let c = crate::peripherals::radio::uwb::SPEC.currents(&p);
        assert_eq!(c.rx, Amps(0.050));
        assert_eq!(c.tx, Amps(0.031));
        // Absent: the datasheet's currents.
        let d = crate::peripherals::radio::p2p::SPEC.currents(&p);
        assert_eq!(d, crate::peripherals::radio::p2p::SPEC.default_currents);
        v["peripherals"]["sensors"]["uwb"]["states"]["read"] = serde_json::json!({"current": 1});
        let e = PlatformConfig::from_json_str(&v.to_string(), "t").unwrap_err();
        assert!(e.to_string().contains("uwb.states.read"), "{e}");
    }

    #[test]
    fn round_trips_through_serde() {
        let p = PlatformConfig::default_crazyflie();
        let text = serde_json::to_string_pretty(&p).unwrap();
        let q = PlatformConfig::from_json_str(&text, "round trip").unwrap();
        assert_eq!(p, q);
    }
}
