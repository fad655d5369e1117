//! Seed 004's drone-to-drone radar end to end (§4.3.2.A, docs/SWARM.md
//! "Radar"): `radar.elf` on two ISSs, flying through the STM32 extension,
//! broadcasting P2P packets through the world's channel over real sockets.
//! B starts 1.5 m from the hovering A (the seed's trial, shortened) and
//! approaches at 0.2 m/s: a packet above −48 dBm is detected, the detector's
//! LAND packet lands the other, nobody collides, and the run is
//! byte-identical twice. The detection must be the world's first received
//! A↔B frame above the threshold (radio.csv): the firmware acts on the
//! channel's draws, not on anything else.

use std::path::Path;

use e2e_tests::{assert_same_files, output_text as text, CosimBins as Bins};
use serde_json::Value;

const WORLD: &str = r#"
name = "radar test: B 1.5 m from A"
[[drone]]
name = "A"
position = [0.0, 0.0, 0.015]
yaw = 0.0
radios = ["p2p"]
[[drone]]
name = "B"
position = [1.5, 0.0, 0.015]
yaw = 3.141592653589793
radios = ["p2p"]
[radio]
seed = 1
"#;

fn run(bins: &Bins, out: &Path, world: &Path) {
    let world = format!("world={}", world.display());
    let o = bins.cosim(&[
        "run",
        "seed004-radar",
        "--quiet",
        "--no-trace",
        "--out",
        out.to_str().unwrap(),
        "--set",
        &world,
        "--set",
        "radio_seed=5",
        "--set",
        "max_time_s=30",
    ]);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn b_is_detected_both_land_without_collision_and_twice_the_same() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let world = tmp.path().join("radar-1.5m.toml");
    std::fs::write(&world, WORLD).unwrap();
    let dirs = [tmp.path().join("a"), tmp.path().join("b")];
    for d in &dirs {
        run(&bins, d, &world);
    }
    let r: Value =
        serde_json::from_str(&std::fs::read_to_string(dirs[0].join("radar.json")).unwrap())
            .unwrap();
    let by = r["detected_by"].as_str().expect("a detection");
    let rssi = r["rssi_dbm"].as_f64().unwrap();
    let d = r["distance_m"].as_f64().unwrap();
    assert!(rssi > -48.0, "{r}");
    assert!(d > 0.15 && d < 1.5, "detected at {d} m: {r}");
    assert_eq!(r["landed"], serde_json::json!(["A", "B"]), "{r}");
    assert_eq!(r["collisions"], 0, "{r}");
    assert!(r["min_distance_m"].as_f64().unwrap() > 0.15, "{r}");
    // The other drone landed on the LAND packet, not on its own detection.
    let other = if by == "A" { "B" } else { "A" };
    let console = std::fs::read_to_string(dirs[0].join(other).join("console.log")).unwrap();
    assert!(
        console.contains("RADAR land_cmd") && !console.contains("RADAR timeout"),
        "{console}"
    );
    // The detection is the channel's first A<->B frame above -48 dBm.
    let log = std::fs::read_to_string(dirs[0].join("radio.csv")).unwrap();
    let first = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|c| c[2] == "p2p" && c[7] == "received")
        .find(|c| c[6].parse::<f64>().unwrap() > -48.0)
        .expect("a frame above -48 dBm");
    assert_eq!(first[4], by, "{first:?} vs {r}");
    assert!((first[6].parse::<f64>().unwrap() - rssi).abs() < 1e-9);
    assert_same_files(
        &dirs[0],
        &dirs[1],
        &[
            "radar.json",
            "radio.csv",
            "trajectory.csv",
            "A/console.log",
            "B/console.log",
            "A/power.csv",
        ],
        "between two runs",
    );
}
