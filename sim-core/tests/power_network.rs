//! The power network end to end: hover endurance in closed form, the
//! selected model draining the battery, energies, a battery that empties,
//! and the CSV logs on every exit path.

use std::path::Path;

use sim_core::config::{PlatformConfig, RunConfig};
use sim_core::power::models::{EmpiricalModel, PowerModelKind};
use sim_core::power::{
    CoreState, Loads, MotorState, PowerError, PowerLogger, PowerNetwork, SensorState, SAMPLE_PERIOD,
};
use sim_core::units::Picos;

/// The world's hover speed: 4·4e-5·ω² = m·g with m = 0.05 kg (DESIGN.md §5).
fn world_hover_omega() -> f64 {
    (0.05 * 9.81 / (4.0 * 4e-5_f64)).sqrt()
}

fn hover_state() -> MotorState {
    let w = world_hover_omega();
    MotorState {
        omega: [-w, w, -w, w],
        ..MotorState::default()
    }
}

/// Flight loads: core running, camera idle, STM32 running the PID (read).
fn flight_loads() -> Loads {
    Loads {
        core: CoreState::Running,
        camera: SensorState::Idle,
        stm32: SensorState::Read,
        ..Loads::default()
    }
}

fn platform_with(edit: impl FnOnce(&mut serde_json::Value)) -> PlatformConfig {
    let mut v: serde_json::Value =
        serde_json::from_str(sim_core::config::DEFAULT_CRAZYFLIE_JSON).unwrap();
    edit(&mut v);
    PlatformConfig::from_json_str(&v.to_string(), "test platform").unwrap()
}

/// Reads a CSV file back with the csv crate: (header, rows).
fn read_csv(path: &Path) -> (Vec<String>, Vec<csv::StringRecord>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r.records().collect::<Result<Vec<_>, _>>().unwrap();
    (header, rows)
}

#[test]
fn hover_endurance_is_the_closed_form_and_is_reported() {
    let run = RunConfig::default();
    let mut net = PowerNetwork::new(&PlatformConfig::default_crazyflie(), &run).unwrap();
    let loads = flight_loads();
    let motor = hover_state();
    let first = net.sample(SAMPLE_PERIOD, &loads, &motor).unwrap();
    // The empirical current does not depend on the voltage, and the LDO
    // passes the VCC current through while V_bat > 3.0 V: the battery current
    // is constant, so the trapezoid is exact and the time to 10 % SOC is
    // 0.9·C·3600/I (C in Ah).
    let i = first.i_battery.0;
    let mut low_at = None;
    let mut t = SAMPLE_PERIOD;
    while low_at.is_none() {
        t += Picos::from_ms(1000);
        net.advance_to(t, &loads, &motor).unwrap();
        if net.low_battery() {
            low_at = Some(t);
        }
        assert!(t < Picos::from_ms(1_000_000), "never low");
    }
    // Find the exact crossing at 1 ms resolution from the expected time.
    let expected_s = 0.9 * 0.25 * 3600.0 / i;
    let low_s = low_at.unwrap().as_secs_f64();
    assert!(
        low_s >= expected_s && low_s < expected_s + 1.001,
        "low at {low_s} s, closed form {expected_s} s"
    );

    // The report asked for (printed, not asserted against the thesis).
    let w = world_hover_omega();
    let emp = EmpiricalModel::default().current_at(w).0;
    // Table 3.2 at 31 g (drone 19.9 + AI deck 4.4 + battery 7.1 = 31.4 g):
    // between 28.6 g / 2.11 A and 32.8 g / 2.39 A.
    let table_31 = 2.11 + (31.4 - 28.6) * (2.39 - 2.11) / (32.8 - 28.6);
    println!("world hover speed: {w:.3} rad/s");
    println!("empirical model (Eq. 3.1) at hover: {emp:.4} A");
    println!("Table 3.2 interpolated at 31.4 g: {table_31:.4} A");
    println!(
        "battery current at hover (motors + VCC {:.4} A): {i:.4} A",
        first.i_vcc_battery.0
    );
    println!(
        "LiPol 250 mAh from 100 % to 10 % SOC at hover: {expected_s:.1} s \
         (thesis estimate ~330 s for a full battery while moving; Bitcraze ~7 min hover)"
    );
    println!(
        "energy drawn by then: {:.1} J; empirical model {:.1} J",
        net.energy().battery.0,
        net.energy().model(PowerModelKind::Empirical).0
    );
}

#[test]
fn the_selected_model_drains_the_battery() {
    let motor = MotorState {
        omega: [50.0; 4],
        horizontal_speed: 1.5,
        vertical_speed: 0.2,
        pitch: 0.15,
    };
    let mut socs = Vec::new();
    for kind in PowerModelKind::ALL {
        let run = RunConfig {
            power_model: kind,
            ..RunConfig::default()
        };
        let mut net = PowerNetwork::new(&PlatformConfig::default_crazyflie(), &run).unwrap();
        let s = net
            .advance_to(Picos::from_ms(100), &flight_loads(), &motor)
            .unwrap()
            .unwrap();
        assert_eq!(s.selected, kind);
        assert_eq!(s.i_motor, s.models[kind.index()].current);
        assert!((s.i_battery.0 - s.i_vcc_battery.0 - s.i_motor.0).abs() < 1e-12);
        socs.push(s.soc);
    }
    // Different models give different drains.
    assert!(socs[0] != socs[1] && socs[1] != socs[2]);
}

#[test]
fn energy_of_a_constant_power_is_power_times_time() {
    let run = RunConfig {
        power_model: PowerModelKind::DAndrea,
        ..RunConfig::default()
    };
    let mut net = PowerNetwork::new(&PlatformConfig::default_crazyflie(), &run).unwrap();
    let motor = MotorState {
        omega: [50.0; 4],
        ..MotorState::default()
    };
    net.advance_to(Picos::from_ms(2000), &flight_loads(), &motor)
        .unwrap();
    // D'Andrea at v = 0: 0.35 + 8.7 = 9.05 W for 2 s = 18.1 J.
    let e = net.energy().model(PowerModelKind::DAndrea).0;
    assert!((e - 18.1).abs() < 1e-9, "{e}");
    // VCC: 3.0 V · (13 mA·1.2/3.0 + 0.14 mA + 150 mA) for 2 s
    // = (0.0156 + 0.00042 + 0.45) W · 2 s = 0.93204 J
    assert!((net.energy().vcc.0 - 0.93204).abs() < 1e-9);
}

#[test]
fn a_battery_that_empties_stops_with_a_clear_error_and_valid_logs() {
    let dir = tempfile::tempdir().unwrap();
    // 0.5 % of 250 mAh = 4.5 A·s: a few seconds at hover.
    let platform = platform_with(|v| {
        v["peripherals"]["harvesters"]["battery"]["soc_init"] = serde_json::json!(0.5);
    });
    let mut net = PowerNetwork::new(&platform, &RunConfig::default()).unwrap();
    net.attach_logger(PowerLogger::create(dir.path(), false).unwrap());
    let err = net
        .advance_to(Picos::from_ms(60_000), &flight_loads(), &hover_state())
        .unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, PowerError::BatteryEmpty { .. }), "{msg}");
    assert!(msg.contains("LiPol LPHD6520030 250 mAh is empty"), "{msg}");
    assert!(msg.contains("soc_end 0 %"), "{msg}");
    let last = *net.last_sample().unwrap();
    assert_eq!(last.soc, 0.0);
    // 4.5 A·s at ≈ 2.8 A: empty after ≈ 1.6 s.
    let expected_s = 4.5 / last.i_battery.0;
    assert!((last.t.as_secs_f64() - expected_s).abs() < 0.002);
    drop(net);
    let (header, rows) = read_csv(&dir.path().join("power.csv"));
    assert_eq!(header[0], "t_ps");
    assert_eq!(rows.len() as u64, last.t.as_ms_floor());
    assert_eq!(&rows.last().unwrap()[13], "0.0");
    for kind in PowerModelKind::ALL {
        let (_, rows_m) = read_csv(&dir.path().join(format!("motor_{}.csv", kind.name())));
        assert_eq!(rows_m.len(), rows.len());
    }
}

#[test]
fn logs_are_valid_csv_without_an_explicit_flush() {
    let dir = tempfile::tempdir().unwrap();
    {
        let mut net =
            PowerNetwork::new(&PlatformConfig::default_crazyflie(), &RunConfig::default()).unwrap();
        net.attach_logger(PowerLogger::create(dir.path(), false).unwrap());
        net.advance_to(Picos::from_ms(250), &flight_loads(), &hover_state())
            .unwrap();
        // dropped here, as on an error path
    }
    let (header, rows) = read_csv(&dir.path().join("power.csv"));
    assert_eq!(rows.len(), 250);
    assert_eq!(header.len(), rows[0].len());
    assert_eq!(&rows[0][0], "1000000000");
    let (header, rows) = read_csv(&dir.path().join("motor_stolaroff.csv"));
    assert_eq!(rows.len(), 250);
    assert_eq!(header[6], "current_a");
    // Only the selected model (empirical by default) is marked.
    assert_eq!(&rows[0][9], "0");
}

#[test]
fn logs_written_while_waiting_are_the_same_bytes() {
    // One logger written only by flush, one by its idle work (as the socket
    // link runs it between polls) after every 32 ms step: the same files.
    let run = |idle: bool| {
        let dir = tempfile::tempdir().unwrap();
        let mut net =
            PowerNetwork::new(&PlatformConfig::default_crazyflie(), &RunConfig::default()).unwrap();
        let logger = PowerLogger::create(dir.path(), false).unwrap();
        let mut work = logger.idle_work();
        net.attach_logger(logger);
        let mut slices = 0;
        for step in 1..=40u64 {
            let motor = MotorState {
                omega: [40.0 + step as f64; 4],
                ..hover_state()
            };
            net.advance_to(Picos::from_ms(32 * step), &flight_loads(), &motor)
                .unwrap();
            if idle {
                loop {
                    slices += 1;
                    if !work() {
                        break;
                    }
                }
            }
        }
        net.flush().unwrap();
        let files: Vec<Vec<u8>> = [
            "power.csv",
            "motor_empirical.csv",
            "motor_dandrea.csv",
            "motor_stolaroff.csv",
        ]
        .iter()
        .map(|f| std::fs::read(dir.path().join(f)).unwrap())
        .collect();
        (files, slices)
    };
    let (by_flush, _) = run(false);
    let (by_idle_work, slices) = run(true);
    assert_eq!(by_flush, by_idle_work);
    // 1280 samples, two per slice; the last slice of a step says "done".
    assert_eq!(slices, 640);
    let text = String::from_utf8(by_flush[0].clone()).unwrap();
    assert_eq!(text.lines().count(), 1 + 1280);
}

#[test]
fn a_panic_still_leaves_valid_logs() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().to_path_buf();
    let result = std::panic::catch_unwind(move || {
        let mut net =
            PowerNetwork::new(&PlatformConfig::default_crazyflie(), &RunConfig::default()).unwrap();
        net.attach_logger(PowerLogger::create(&path, false).unwrap());
        net.advance_to(Picos::from_ms(40), &flight_loads(), &hover_state())
            .unwrap();
        panic!("simulated failure");
    });
    assert!(result.is_err());
    let (_, rows) = read_csv(&dir.path().join("power.csv"));
    assert_eq!(rows.len(), 40);
}

#[test]
fn same_inputs_same_bits() {
    let run = || {
        let mut net =
            PowerNetwork::new(&PlatformConfig::default_crazyflie(), &RunConfig::default()).unwrap();
        let mut out = Vec::new();
        for k in 1..=500u64 {
            let motor = MotorState {
                omega: [40.0 + (k % 7) as f64; 4],
                horizontal_speed: (k % 13) as f64 * 0.1,
                vertical_speed: 0.0,
                pitch: (k % 5) as f64 * 0.02,
            };
            let s = net
                .sample(Picos::from_ms(k), &flight_loads(), &motor)
                .unwrap();
            out.push((s.soc.to_bits(), s.v_battery.0.to_bits()));
        }
        out
    };
    assert_eq!(run(), run());
}

#[test]
fn low_battery_is_raised_once_at_ten_percent() {
    // Start at 10.05 %: 0.05 % of 250 mAh = 0.45 A·s, ≈ 0.16 s at hover.
    let platform = platform_with(|v| {
        v["peripherals"]["harvesters"]["battery"]["soc_init"] = serde_json::json!(10.05);
    });
    let mut net = PowerNetwork::new(&platform, &RunConfig::default()).unwrap();
    let mut crossings = Vec::new();
    for k in 1..=400u64 {
        let s = net
            .sample(Picos::from_ms(k), &flight_loads(), &hover_state())
            .unwrap();
        if s.low_battery_crossed {
            crossings.push((k, s.soc));
        }
        assert_eq!(s.low_battery, s.soc < 0.10);
    }
    assert_eq!(crossings.len(), 1, "{crossings:?}");
    let (k, soc) = crossings[0];
    assert!(soc < 0.10);
    // 0.45 A·s / I, to the millisecond.
    let i = net.last_sample().unwrap().i_battery.0;
    assert!((k as f64 / 1000.0 - 0.45 / i).abs() <= 0.001, "k = {k}");
    assert!(net.low_battery());
}

#[test]
fn share_of_the_battery_used_in_160_s_at_hover_is_recorded() {
    // Thesis §5.1: "about 50 % of the battery charge was consumed in about
    // 160 s" with the empirical model. Recorded, not tuned: we check our
    // network against its own closed form and print the comparison.
    let mut net =
        PowerNetwork::new(&PlatformConfig::default_crazyflie(), &RunConfig::default()).unwrap();
    let s = net
        .advance_to(Picos::from_ms(160_000), &flight_loads(), &hover_state())
        .unwrap()
        .unwrap();
    let used = 1.0 - s.soc;
    // MESSY's trapezoid starts from i_prev = 0, so the first millisecond
    // counts half: charge = I·(160 − 0.0005) A·s.
    let closed_form = s.i_battery.0 * (160.0 - 0.0005) / 900.0;
    assert!((used - closed_form).abs() < 1e-9);
    println!(
        "LiPol 250 mAh used in 160 s at the world's hover: {:.1} % (thesis, moving: ~50 %)",
        used * 100.0
    );
}
