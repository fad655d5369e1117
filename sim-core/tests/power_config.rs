//! Platform file and run configuration: parsing errors name the place and
//! the problem; every run key can be set from the command line.

use std::io::Write;

use sim_core::config::{
    ConfigError, DebugLevel, PlatformConfig, RunConfig, SyncMode, ValueKind,
    DEFAULT_CRAZYFLIE_JSON, RUN_KEYS,
};
use sim_core::peripherals::stm32::PositionSource;
use sim_core::power::battery::{BatteryModel, CurveAxis};
use sim_core::power::converter::Converter;
use sim_core::power::models::PowerModelKind;
use sim_core::units::{Amps, Volts};

fn edited(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut v: serde_json::Value = serde_json::from_str(DEFAULT_CRAZYFLIE_JSON).unwrap();
    edit(&mut v);
    serde_json::to_string_pretty(&v).unwrap()
}

fn platform_err(text: &str) -> String {
    PlatformConfig::from_json_str(text, "crazy.json")
        .unwrap_err()
        .to_string()
}

#[test]
fn malformed_json_gives_file_and_line() {
    let text = "{\n  \"bus\": { \"vref\": 3.0 },\n  \"core\": { \"vref\": ,\n}";
    let msg = platform_err(text);
    assert!(msg.starts_with("crazy.json: "), "{msg}");
    assert!(msg.contains("line 3"), "{msg}");
}

#[test]
fn unknown_key_is_named() {
    let text = edited(|v| v["peripherals"]["sensors"]["camera"]["colour"] = "grey".into());
    let msg = platform_err(&text);
    assert!(msg.contains("unknown field `colour`"), "{msg}");
    assert!(msg.contains("line"), "{msg}");
}

#[test]
fn messy_tracing_blocks_are_accepted() {
    let text = edited(|v| {
        v["tracing"] = serde_json::json!({"messy_trace": {"filename": "t.log"}});
        v["peripherals"]["sensors"]["camera"]["tracing"] =
            serde_json::json!({"messy_trace": {"camera_I": "current"}});
    });
    assert!(PlatformConfig::from_json_str(&text, "x").is_ok());
}

#[test]
fn bad_values_are_explained() {
    let cases: Vec<(String, &str)> = vec![
        (
            edited(|v| {
                v["peripherals"]["sensors"]["stm32"]["states"]["read"]["current"] = "lots".into()
            }),
            "expected a number, got \"lots\"",
        ),
        (
            edited(|v| {
                v["peripherals"]["sensors"]["stm32"]["states"]["idle"]["current"] = (-1.0).into()
            }),
            "peripherals.sensors.stm32.states.idle.current must be a non-negative number of mA",
        ),
        (
            edited(|v| v["peripherals"]["harvesters"]["battery"]["capacity"] = 300.into()),
            "capacity 300 mAh does not match model lipol250 (250 mAh)",
        ),
        (
            edited(|v| v["peripherals"]["harvesters"]["battery"]["model"] = "lipo9000".into()),
            "unknown battery \"lipo9000\"",
        ),
        (
            edited(|v| v["core"]["converter"]["efficiency"] = 1.5.into()),
            "core.converter: efficiency 1.5 is not in (0, 1]",
        ),
        (
            edited(|v| {
                v["peripherals"]["sensors"]["camera"]["states"]
                    .as_object_mut()
                    .unwrap()
                    .remove("idle");
            }),
            "peripherals.sensors.camera.states needs a \"idle\" state",
        ),
        (
            edited(|v| {
                v["peripherals"]["sensors"]
                    .as_object_mut()
                    .unwrap()
                    .remove("stm32");
            }),
            "peripherals.sensors needs a \"stm32\" sensor",
        ),
        (
            edited(|v| {
                v["peripherals"]["sensors"]["camera"]["states"]["read"]["delay"] = "16.5".into()
            }),
            "delay must be a whole non-negative number of ms, got 16.5",
        ),
        (
            edited(|v| v["resolution"] = "SC_US".into()),
            "resolution \"SC_US\" is not supported",
        ),
        (
            edited(|v| v["peripherals"]["harvesters"]["battery"]["soc_end"] = 100.into()),
            "soc_end (100 %) must be below soc_init (100 %)",
        ),
        (
            edited(|v| {
                v["peripherals"]["harvesters"]["battery"]["converter"] = serde_json::json!({
                    "lut": {"input_values": [1, 2], "efficiency_values": [90]}
                })
            }),
            "LUT input_values has 2 entries but the values array has 1",
        ),
    ];
    for (text, expected) in cases {
        let msg = platform_err(&text);
        assert!(msg.starts_with("crazy.json: "), "{msg}");
        assert!(msg.contains(expected), "expected {expected:?} in {msg:?}");
    }
}

#[test]
fn missing_file_is_named() {
    let msg = PlatformConfig::from_path(std::path::Path::new("/nonexistent/p.json"))
        .unwrap_err()
        .to_string();
    assert!(msg.starts_with("/nonexistent/p.json: "), "{msg}");
}

#[test]
fn a_messy_lut_converter_block_parses_and_interpolates() {
    // MESSY's battery converter block, verbatim shape (messy/codegen/pulp_open.json).
    let text = edited(|v| {
        v["peripherals"]["harvesters"]["battery"]["converter"] = serde_json::json!({
            "input_variable": "current",
            "out_dir": true,
            "lut": {
                "input_values": [1, 2, 3, 4, 5],
                "efficiency_values": [88.0165, 90.9091, 91.1157, 92.1488, 92.7686]
            }
        })
    });
    let p = PlatformConfig::from_json_str(&text, "x").unwrap();
    let c: Converter = p.battery().converter().unwrap();
    // 2.5 mA → 90.9091 + 0.5·(91.1157 − 90.9091) = 91.0124 %
    let eta = c.efficiency(Amps(0.0025), Volts(3.0), Volts(4.0));
    assert!((eta - 0.910124).abs() < 1e-12, "{eta}");
}

#[test]
fn numbers_or_strings_like_messy() {
    let text = edited(|v| {
        v["peripherals"]["sensors"]["camera"]["states"]["read"]["current"] = 1.75.into();
        v["peripherals"]["harvesters"]["battery"]["soc_init"] = "90".into();
    });
    let p = PlatformConfig::from_json_str(&text, "x").unwrap();
    assert_eq!(
        p.sensor("camera").unwrap().state("read").unwrap().current,
        1.75
    );
    assert_eq!(p.battery().soc_init, 90.0);
}

/// A non-default text value for every key (and the parsed check).
fn non_default(key: &str) -> &'static str {
    match key {
        "power_model" => "stolaroff",
        "battery" => "cyclone300",
        "battery_curve" => "soc",
        "battery_load" => "sag",
        "battery_empty" => "end",
        "soc_low" => "2.5",
        "debug_level" => "HIGH",
        "tolerance" => "0.25",
        "target_cycles" => "42",
        "unlock_cycles" => "777",
        "sync" => "bounded",
        "dandrea_efficiency" => "0.9",
        "stolaroff_efficiency" => "0.7",
        "stolaroff_factor" => "3.5",
        "platform" => "/tmp/other.json",
        // Above i64::MAX: the TOML round trip keeps it as text.
        "radio_id" => "18446744073709551615",
        "stm32.position_source" => "flow",
        "stm32.range_max_m" => "4.5",
        "stm32.flow_std_m_s" => "0.02",
        "crtp" => "udp:127.0.0.1:19850",
        "pace" => "4",
        "crtp_idle_s" => "2.5",
        "stabilizer.controller" => "pid",
        "cluster.cores" => "4",
        "cluster.mhz" => "90",
        "output.compress" => "false",
        // The ISS back end that is not the host's default.
        "iss" if cfg!(target_arch = "x86_64") => "interp",
        "iss" => "jit",
        _ => panic!("a key without a test value: {key}"),
    }
}

#[test]
fn every_key_can_be_set_and_read_back() {
    let mut c = RunConfig::default();
    for key in RUN_KEYS.iter().map(|k| k.name) {
        let before = c.get(key).unwrap();
        let value = non_default(key);
        assert_ne!(before, value, "{key} default equals the test value");
        c.set(key, value).unwrap();
        assert_eq!(c.get(key).unwrap(), value, "{key}");
    }
    assert_eq!(c.power_model, PowerModelKind::Stolaroff);
    assert_eq!(c.battery, Some(BatteryModel::Cyclone300));
    assert_eq!(c.battery_curve, CurveAxis::Soc);
    assert_eq!(c.debug_level, DebugLevel::High);
    assert_eq!(c.tolerance, 0.25);
    assert_eq!((c.target_cycles, c.unlock_cycles), (42, 777));
    assert_eq!(c.sync, SyncMode::Bounded);
    assert_eq!(c.models.dandrea_efficiency, 0.9);
    assert_eq!(c.models.stolaroff_efficiency, 0.7);
    assert_eq!(c.models.stolaroff_factor, 3.5);
    assert_eq!(
        c.platform.as_deref(),
        Some(std::path::Path::new("/tmp/other.json"))
    );
    assert_eq!(c.radio_id, u64::MAX);
    assert_eq!(c.position_source, PositionSource::Flow);
    assert_eq!(c.range_max_m, 4.5);
    // And the whole thing survives TOML.
    let back = RunConfig::from_toml_str(&c.to_toml(), "round trip").unwrap();
    assert_eq!(back, c);
}

#[test]
fn each_key_alone_round_trips_through_the_toml_writer() {
    for key in &RUN_KEYS {
        let mut c = RunConfig::default();
        c.set(key.name, non_default(key.name)).unwrap();
        let text = c.to_toml();
        // Changed from its default: every key is written, in its form.
        let table: toml::Table = toml::from_str(&text).unwrap();
        let written = &table[key.name];
        let kind_ok = match key.kind {
            ValueKind::Text => written.is_str(),
            ValueKind::Float => written.is_float(),
            // Beyond i64 an integer stays text.
            ValueKind::Integer => written.is_integer() || written.is_str(),
            ValueKind::Bool => written.is_bool(),
        };
        assert!(kind_ok, "{}: {written:?} is not {:?}", key.name, key.kind);
        let back = RunConfig::from_toml_str(&text, key.name).unwrap();
        assert_eq!(back, c, "{}:\n{text}", key.name);
    }
}

#[test]
fn bad_values_and_keys_are_errors() {
    let mut c = RunConfig::default();
    let bad = [
        ("power_model", "dorling"),
        ("battery", "aa"),
        ("battery_curve", "sideways"),
        ("debug_level", "LOUD"),
        ("tolerance", "-1"),
        ("tolerance", "NaN"),
        ("target_cycles", "0"),
        ("unlock_cycles", "5.5"),
        ("sync", "never"),
        ("dandrea_efficiency", "1.2"),
        ("stolaroff_efficiency", "0"),
        ("stolaroff_factor", "five"),
        ("platform", ""),
        ("stm32.position_source", "compass"),
        ("stm32.range_max_m", "-2"),
        ("stm32.range_max_m", "NaN"),
        ("stm32.flow_std_m_s", "-0.1"),
        ("stm32.flow_std_m_s", "inf"),
    ];
    for (key, value) in bad {
        let e = c.set(key, value).unwrap_err();
        assert!(
            matches!(e, ConfigError::BadValue { .. }),
            "{key}={value}: {e}"
        );
        assert!(e.to_string().contains(key), "{e}");
    }
    assert_eq!(c, RunConfig::default(), "a refused value changes nothing");
    let e = c.set("gravity", "1").unwrap_err().to_string();
    assert!(
        e.contains("unknown run configuration key \"gravity\""),
        "{e}"
    );
    assert!(e.contains("power_model"), "{e}");
    let e = c.apply_overrides(&["tolerance"]).unwrap_err();
    assert!(matches!(e, ConfigError::BadOverride(_)));
}

#[test]
fn thesis_names_are_accepted() {
    let mut c = RunConfig::default();
    c.apply_overrides(&[
        "battery=UFX402525",
        "power_model=D'Andrea",
        "debug_level=DEBUG_LEVEL_MED",
    ])
    .unwrap();
    assert_eq!(c.battery, Some(BatteryModel::Ufx250));
    assert_eq!(c.power_model, PowerModelKind::DAndrea);
    assert_eq!(c.debug_level.tracing_level(), tracing::Level::DEBUG);
    c.set("battery", "platform").unwrap();
    assert_eq!(c.battery, None);
}

#[test]
fn toml_files_and_their_errors() {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(
        f,
        "power_model = \"dandrea\"\ntolerance = 0.2\ntarget_cycles = 50"
    )
    .unwrap();
    let c = RunConfig::from_path(f.path()).unwrap();
    assert_eq!(c.power_model, PowerModelKind::DAndrea);
    assert_eq!(c.tolerance, 0.2);
    assert_eq!(c.target_cycles, 50);
    assert_eq!(c.unlock_cycles, 5000);

    let e = RunConfig::from_toml_str("tolerance = 0.1\nsync = \n", "run.toml")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("run.toml: "), "{e}");
    assert!(e.contains("line 2"), "{e}");
    let e = RunConfig::from_toml_str("tolrance = 0.1\n", "run.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("run.toml") && e.contains("\"tolrance\""), "{e}");
    let e = RunConfig::from_toml_str("target_cycles = -3\n", "run.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("target_cycles"), "{e}");
    let e = RunConfig::from_toml_str("battery = [1, 2]\n", "run.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("battery: expected a string or a number"), "{e}");
}

#[test]
fn the_default_configuration_survives_toml() {
    // The embedded platform has no path: it must not come back as a file
    // named "embedded".
    let c = RunConfig::default();
    let back = RunConfig::from_toml_str(&c.to_toml(), "default round trip").unwrap();
    assert_eq!(back, c);
    assert!(back.platform.is_none());
    // A single drone's file without the extension's settings is the file
    // from before the radios and the STM32 extension: no radio_id, no
    // stm32.* keys at their defaults; one set key comes back alone.
    let text = c.to_toml();
    assert!(
        !text.contains("radio_id") && !text.contains("stm32"),
        "{text}"
    );
    let mut flow = RunConfig::default();
    flow.set("stm32.position_source", "flow").unwrap();
    let text = flow.to_toml();
    assert_eq!(text.matches("stm32").count(), 1, "{text}");
}
