//! The platform's clock ticker (docs/SWARM.md §4.1–§4.2) end to end in one
//! process: the `radio_tick` firmware (UWB only, never INIT_PID) on the ISS
//! against [`SoloWorld`], the lockstep's contract for one drone. Checked
//! against closed-form expectations: the clock moves by ADVANCE_TIME ts at
//! p₀ + k·ts, RADIO_RECV follows every tick, transmissions carry the exact
//! offset and stamp, a core sleeping in wfi wakes at the tick that delivers
//! TX_DONE, the platform sends STOP when the firmware ends, and the world
//! time estimate is exact.

use std::path::PathBuf;

use protocol::radio::{dw1000_stamp, Picos as WorldPicos, Radio};
use protocol::{ImageEncoding, Request};
use sim_core::config::{PlatformConfig, RunConfig};
use sim_core::kernel::{simulate, KernelConfig};
use sim_core::peripherals::solo_world::Logged;
use sim_core::peripherals::SoloWorld;
use sim_core::units::{Millis, Picos};

fn firmware(name: &str) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("firmware/bin")
        .join(format!("{name}.elf"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn config(out: &std::path::Path, drone: Option<&str>) -> KernelConfig {
    KernelConfig {
        platform: PlatformConfig::default_crazyflie(),
        run: RunConfig::default(),
        image_encoding: ImageEncoding::Array,
        busy_poll_us: 0,
        drone: drone.map(str::to_string),
        idle_skip: true,
        mmio_latency: 0,
        out_dir: Some(out.to_path_buf()),
        echo_console: false,
        progress: false,
        max_time: Some(Picos::from_ms(60_000)),
        gates_total: None,
    }
}

/// What the firmware printed for one frame.
struct Printed {
    sent: u64,
    stamp: u64,
    woke: u64,
}

fn printed(console: &str) -> Vec<Printed> {
    console
        .lines()
        .filter(|l| l.starts_with("frame "))
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            Printed {
                sent: w[3].parse().unwrap(),
                stamp: w[5].parse().unwrap(),
                woke: w[7].parse().unwrap(),
            }
        })
        .collect()
}

const CYCLE: u64 = 4_000; // ps at 250 MHz

fn run(ts_ms: u64) {
    let ts = Picos::from_ms(ts_ms);
    let dir = tempfile::tempdir().unwrap();
    let mut world = SoloWorld::new([0.0, 0.0, 0.015], Millis(ts_ms));
    let cfg = config(dir.path(), Some("A"));
    let outcome = simulate(&firmware("radio_tick"), &cfg, &mut world);
    let s = &outcome.summary;
    assert!(outcome.error.is_none(), "{:?}", outcome.error);
    assert!(s.completed, "{s:?}");
    assert_eq!(s.exit_code, 0);

    let log = &world.log;
    let init = &log[0];
    assert!(matches!(
        init.request,
        Request::GetInitData {
            drone: Some(ref d),
            ..
        } if d == "A"
    ));
    let p0 = init.platform + Picos::from_ms(2000);

    // Ticks: ADVANCE_TIME ts at p0 + k·ts, each followed by RADIO_RECV.
    let ticks: Vec<&Logged> = world.requests("ADVANCE_TIME");
    // Three frames 3.3 ms apart from 1.25 ms on: the run lasts ~8 ms.
    assert!(ticks.len() as u64 * ts_ms >= 8);
    for (k, t) in ticks.iter().enumerate() {
        let k = k as u64 + 1;
        assert_eq!(t.request, Request::AdvanceTime { time: ts_ms });
        assert_eq!(t.platform, p0 + Picos(k * ts.0), "tick {k}");
        assert_eq!(t.clock, Millis(2000 + (k - 1) * ts_ms));
    }
    let recvs = world.requests("RADIO_RECV");
    assert_eq!(recvs.len(), ticks.len());
    for (r, t) in recvs.iter().zip(&ticks) {
        assert_eq!(r.platform, t.platform);
        assert_eq!(r.clock, t.clock + Millis(ts_ms));
    }

    // Transmissions: the offset is p − p_d with p_d = p0 + (clock − 2000)·1 ms.
    let sends = world.requests("RADIO_SEND");
    let frames = printed(&std::fs::read_to_string(dir.path().join("console.log")).unwrap());
    assert_eq!(sends.len(), 3);
    assert_eq!(frames.len(), 3);
    let air = Radio::Uwb.airtime(10).0;
    for (send, f) in sends.iter().zip(&frames) {
        let Request::RadioSend { offset_ps, .. } = send.request else {
            unreachable!()
        };
        let p_d = p0 + Picos::from_ms(send.clock.0 - 2000);
        assert_eq!(offset_ps, (send.platform - p_d).0);
        assert!(offset_ps < ts.0);
        // The firmware read mtime a few instructions before TX_START.
        let sent = f.sent * CYCLE;
        assert!(send.platform.0 >= sent && send.platform.0 - sent < 100 * CYCLE);
        // The stamp is the world's for the transmission's start.
        let start = send.clock.to_picos().0 + offset_ps;
        assert_eq!(f.stamp, dw1000_stamp(WorldPicos(start), 0, WorldPicos(0)).0);
        // TX_DONE is delivered at the first tick at or after the frame's end,
        // and the sleeping core wakes there (a few instructions later).
        let end = send.platform.0 + air;
        let k = (end - p0.0).div_ceil(ts.0);
        let tick = p0.0 + k * ts.0;
        let woke = f.woke * CYCLE;
        assert!(
            woke >= tick && woke - tick < 100 * CYCLE,
            "woke {woke} tick {tick}"
        );
    }

    // The firmware ended with the session open: the platform sent STOP at
    // the drone's clock, and the estimate is exact.
    let stop = log.last().unwrap();
    assert_eq!(stop.request, Request::Stop);
    assert_eq!(stop.clock, Millis(2000 + ticks.len() as u64 * ts_ms));
    assert_eq!(s.world_time_s, Some(stop.clock.0 as f64 / 1000.0));
    assert_eq!(Some(s.world_time_estimate_s), s.world_time_s);
    assert_eq!(s.estimate_error_pct, Some(0.0));
    assert_eq!(s.sensors_offset_ms, 0.0);
    // Core time outside the ticks: before INIT and after the last tick.
    let exit = Picos((s.platform_time_s * Picos::PER_S as f64).round() as u64);
    assert!(exit >= ticks.last().unwrap().platform);
    assert!(exit.0 - ticks.last().unwrap().platform.0 < ts.0);

    // The radio is reported: three frames, and its energy is the integral
    // of its states (idle from INIT, TX for three airtimes) at 3.0 V over
    // the 1 ms samples taken.
    let radios = s
        .radios
        .as_ref()
        .expect("a swarm member reports its radios");
    assert!(radios.uwb.used && !radios.p2p.used);
    assert_eq!(radios.uwb.frames_sent, 3);
    let last_sample = exit.0 / Picos::PER_MS * Picos::PER_MS;
    let expected = 3.0
        * (0.012 * (last_sample - init.platform.0) as f64 + (0.031 - 0.012) * (3 * air) as f64)
        / Picos::PER_S as f64;
    let uwb = s.energy_j.uwb.unwrap();
    assert!(
        (uwb - expected).abs() < 1e-9 * expected,
        "{uwb} vs {expected}"
    );
    assert_eq!(s.energy_j.p2p, Some(0.0));
    let csv = series_text(&dir.path().join("power.csv"));
    assert!(csv.lines().next().unwrap().ends_with(",i_uwb_a,i_p2p_a"));
}

#[test]
fn the_ticker_moves_the_clock_by_whole_steps_at_1_ms() {
    run(1);
}

#[test]
fn the_ticker_moves_the_clock_by_whole_steps_at_4_ms() {
    run(4);
}

#[test]
fn a_single_drone_platform_reports_no_radio_columns() {
    let dir = tempfile::tempdir().unwrap();
    let mut world = SoloWorld::new([0.0, 0.0, 0.015], Millis(2));
    let outcome = simulate(
        &firmware("radio_tick"),
        &config(dir.path(), None),
        &mut world,
    );
    assert!(outcome.error.is_none(), "{:?}", outcome.error);
    let s = outcome.summary;
    assert!(s.radios.is_none() && s.energy_j.uwb.is_none());
    let Request::GetInitData { drone, .. } = &world.log[0].request else {
        unreachable!()
    };
    assert_eq!(*drone, None);
    let csv = series_text(&dir.path().join("power.csv"));
    assert!(csv.lines().next().unwrap().ends_with(",power_model"));
    let json = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
    assert!(!json.contains("\"drone\"") && !json.contains("\"radios\""));
}

/// A series file's text, in whichever form the run wrote it
/// (`power.csv` or `power.csv.zst`).
fn series_text(path: &std::path::Path) -> String {
    String::from_utf8(protocol::series::read(path).unwrap().bytes).unwrap()
}
