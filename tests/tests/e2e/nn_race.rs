//! The network in the loop end to end (DESIGN.md §13, docs/NN.md
//! "nn-race"): on vision-race's short course (one gate displaced 0.45 m
//! sideways from its waypoint, `scenarios/worlds/short-gate-displaced.toml`,
//! which the blind race misses: tests/tests/e2e/vision_race.rs), nn_race_short.elf
//! (the int8 network on the AI deck's cluster, the shared guidance) passes
//! the gate without a collision; summary.json's `nn` block is there and
//! consistent with itself and with the platform; a second run gives the same
//! bytes; the cluster kept open flies the same and costs its leakage; bad
//! cluster settings are one line and exit code 2.

use std::path::Path;

use e2e_tests::{assert_same_files, output_text as text, summary, CosimBins};
use serde_json::Value;

const AIDECK: &str = "platform=sim-core/platforms/crazyflie-aideck.json";

fn run(bins: &CosimBins, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "run",
        "short-hop",
        "--world",
        "scenarios/worlds/short-gate-displaced.toml",
        "--set",
        "firmware=sim-core/firmware/bin/nn_race_short.elf",
        "--set",
        AIDECK,
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--no-mcap",
        "--quiet",
    ];
    args.extend_from_slice(extra);
    bins.cosim(&args)
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn the_network_on_the_cluster_flies_through_the_displaced_gate() {
    let bins = CosimBins::new();
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let o = run(&bins, &a, &[]);
    assert!(o.status.success(), "{}", text(&o));
    let s = summary(&a);
    assert_eq!(s["completed"], true, "{s:#}");
    assert_eq!(s["gates_passed"], 1, "{s:#}");
    assert_eq!(s["collisions"], 0, "{s:#}");

    // §13's block, measured: the network ran, every inference costs what
    // the network costs on 8 cores (nn eval: 416k cycles), MAC/cycle is
    // MACs over cycles, the energy is the cluster's.
    let nn = &s["nn"];
    let n = nn["inferences"].as_u64().unwrap();
    assert!(n >= 10, "{nn:#}");
    assert_eq!(nn["cores"], 8);
    assert_eq!(nn["cluster_mhz"], 175);
    let macs = f(&nn["mac_per_inference"]);
    let mean = f(&nn["cycles_per_inference"]["mean"]);
    let max = f(&nn["cycles_per_inference"]["max"]);
    assert!(mean > 300_000.0 && mean < 600_000.0, "{nn:#}");
    assert!(max >= mean, "{nn:#}");
    assert!(
        (f(&nn["mac_per_cycle"]) - macs / mean).abs() < 1e-9 * macs,
        "{nn:#}"
    );
    // The latency is at least the network's cycles at the cluster's clock.
    assert!(f(&nn["latency_ms"]) > mean / 175e3, "{nn:#}");
    assert!(f(&nn["latency_max_ms"]) >= f(&nn["latency_ms"]), "{nn:#}");
    assert!(f(&nn["fps"]) > 1.0 && f(&nn["fps"]) < 30.0, "{nn:#}");
    assert_eq!(nn["energy_j"], s["energy_j"]["cluster"], "{s:#}");
    assert!(f(&nn["energy_j"]) > 0.0);
    let per = f(&nn["energy_per_inference_mj"]);
    assert!(
        (per - f(&nn["energy_j"]) * 1000.0 / n as f64).abs() < 1e-9,
        "{nn:#}"
    );
    assert!(nn["sightings_used"].as_u64().unwrap() >= 1, "{nn:#}");
    assert!(nn["detections"].as_u64().unwrap() <= n, "{nn:#}");

    // Deterministic: a second run gives the same bytes and the same block.
    let b = dir.path().join("b");
    let o = run(&bins, &b, &[]);
    assert!(o.status.success(), "{}", text(&o));
    assert_same_files(
        &a,
        &b,
        &["trajectory.csv", "console.log", "power.csv"],
        "between two runs",
    );
    assert_eq!(summary(&b)["nn"], s["nn"]);

    // The cluster kept open between inferences (`firmware.nn_keep_open`):
    // the same flight, and the energy of a powered, sleeping cluster. Its
    // cores sleep between tasks, so what it adds is about the leakage
    // (4.8 mW, docs/CLUSTER.md "Power"); core 0 awake and polling would
    // add 8.4 mW more (48 pJ x 175 MHz).
    let k = dir.path().join("k");
    let o = run(&bins, &k, &["--set", "firmware.nn_keep_open=1"]);
    assert!(o.status.success(), "{}", text(&o));
    let sk = summary(&k);
    assert_eq!(sk["gates_passed"], 1, "{sk:#}");
    assert_same_files(&a, &k, &["trajectory.csv"], "kept open or not");
    assert_eq!(sk["nn"]["inferences"], nn["inferences"]);
    let extra_w =
        (f(&sk["energy_j"]["cluster"]) - f(&s["energy_j"]["cluster"])) / f(&sk["platform_time_s"]);
    assert!(extra_w > 1e-3 && extra_w < 6e-3, "{extra_w} W");

    // Fewer cores (`cluster.cores`, a run key): more cycles per inference.
    let c = dir.path().join("c");
    let o = run(&bins, &c, &["--set", "cluster.cores=2"]);
    assert!(o.status.success(), "{}", text(&o));
    let nn2 = &summary(&c)["nn"];
    assert_eq!(nn2["cores"], 2);
    assert!(
        f(&nn2["cycles_per_inference"]["mean"]) > 2.5 * mean,
        "{nn2:#}"
    );
}

#[test]
fn bad_cluster_settings_are_one_line_and_exit_code_2() {
    let bins = CosimBins::new();
    let dir = tempfile::tempdir().unwrap();
    for (set, needle) in [
        ("cluster.cores=9", "cluster.cores"),
        ("cluster.mhz=fast", "cluster.mhz"),
    ] {
        let o = run(&bins, &dir.path().join("bad"), &["--set", set]);
        assert_eq!(o.status.code(), Some(2), "{set}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{set}: {err}");
    }
    // A firmware parameter the start file would zero (in .bss) is refused
    // by sim-core, not silently lost.
    let bad = dir.path().join("bss");
    let o = run(&bins, &bad, &["--set", "firmware.nn_race_stats=1"]);
    assert!(!o.status.success(), "{}", text(&o));
    let err = summary(&bad)["error"]
        .as_str()
        .unwrap_or_default()
        .to_string();
    assert!(err.contains("nn_race_stats is in .bss"), "{err}");
}
