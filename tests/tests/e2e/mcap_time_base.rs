//! One time base in `run.mcap` (DESIGN.md §20, docs/FOXGLOVE.md): the
//! platform's channels (power, battery), which sim-core logs in platform
//! time, are put on the world's time through the offset bookkeeping of §3,
//! so every channel that publishes through the run ends at the world's
//! STOP time, and the motors' current drops when the world's motors stop,
//! not the offsets later.

use std::collections::BTreeMap;
use std::path::Path;

use e2e_tests::{output_text as text, summary, CosimBins as Bins};
use serde_json::Value;

/// (topic, log time ns, JSON) of every message.
fn messages(path: &Path) -> Vec<(String, u64, Value)> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (
                m.channel.topic.clone(),
                m.log_time,
                serde_json::from_slice(&m.data).unwrap(),
            )
        })
        .collect()
}

#[test]
fn every_channel_ends_at_the_worlds_stop_and_the_power_lines_up_with_the_motors() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("hop");
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--quiet",
        "--no-plots",
        "--no-trace",
        "--set",
        "mcap_image_every=0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s = summary(&out);
    let stop_ns = (s["world_time_s"].as_f64().unwrap() * 1e9).round() as u64;
    let step_ns = s["timestep_ms"].as_u64().unwrap() * 1_000_000;
    // The platform runs ahead of the world by its offsets: without the
    // mapping its channels would end that much after STOP.
    let offset_ns = (s["platform_time_s"].as_f64().unwrap() * 1e9) as u64 - stop_ns;
    assert!(
        offset_ns > 2 * step_ns,
        "a run whose offsets exceed a step tests the mapping ({offset_ns} ns)"
    );

    let msgs = messages(&out.join("run.mcap"));
    let mut last: BTreeMap<&str, (usize, u64)> = BTreeMap::new();
    for (topic, t, _) in &msgs {
        let e = last.entry(topic.as_str()).or_insert((0, 0));
        *e = (e.0 + 1, e.1.max(*t));
    }
    for topic in ["/tf", "/cf1/motors", "/cf1/power", "/cf1/battery"] {
        assert!(last.contains_key(topic), "{topic} in {last:?}");
    }
    for (topic, (n, t)) in &last {
        if *n == 1 {
            // The scene: published once, at the start.
            assert_eq!(*t, 0, "{topic}");
            continue;
        }
        assert!(
            t.abs_diff(stop_ns) <= step_ns,
            "{topic} ends at {t} ns, the world stopped at {stop_ns} ns"
        );
    }
    // The battery's time_s is the log time, in seconds.
    for (topic, t, v) in &msgs {
        if topic == "/cf1/battery" {
            let ts = v["time_s"].as_f64().unwrap();
            assert!((ts * 1e9 - *t as f64).abs() < 1e3, "{ts} s at {t} ns");
        }
    }

    // The motors stop after the landing (the world's target speeds; the
    // warm-up's ±1 rad/s is not flying) and the motor current drops (the
    // platform's power) together. The world stamps a step's motors at the
    // step's end and the platform's current follows the command from the
    // iteration's start: within three steps. In platform time the current
    // drops about four steps late here (the offsets by then, 186 ms).
    let motors: Vec<(u64, bool)> = msgs
        .iter()
        .filter(|(topic, _, _)| topic == "/cf1/motors")
        .map(|(_, t, v)| {
            let on = v["target_rad_s"]
                .as_array()
                .unwrap()
                .iter()
                .any(|w| w.as_f64().unwrap().abs() > 1.5);
            (*t, on)
        })
        .collect();
    let current: Vec<(u64, bool)> = msgs
        .iter()
        .filter(|(topic, _, _)| topic == "/cf1/power")
        .map(|(_, t, v)| (*t, v["i_motor_a"].as_f64().unwrap() > 0.0))
        .collect();
    let first_off_after_flight = |series: &[(u64, bool)]| {
        let last_on = series
            .iter()
            .rposition(|(_, on)| *on)
            .expect("the motors turn");
        series[last_on + 1].0
    };
    let (motors_off, current_off) = (
        first_off_after_flight(&motors),
        first_off_after_flight(&current),
    );
    assert!(
        motors_off.abs_diff(current_off) <= 3 * step_ns,
        "the world's motors stop at {motors_off} ns, their current at {current_off} ns"
    );
}
