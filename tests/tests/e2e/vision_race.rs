//! Vision in the loop end to end (DESIGN.md §10, docs/VISION.md): on a course of
//! one gate displaced 0.45 m sideways from its waypoint
//! (`scenarios/worlds/short-gate-displaced.toml`), race.c's short flight to
//! the waypoint (`short_far`) misses the gate, and the vision firmware
//! (`vision_race_short`: the gate detector on the ISS, EXT_SET_HEADING, the
//! STM32's target moved to the seen gate) passes it, without a collision;
//! two vision runs are byte-identical.

use std::path::Path;

use e2e_tests::{assert_same_files, output_text as text, summary, CosimBins};

fn run(bins: &CosimBins, firmware: &str, out: &Path) -> std::process::Output {
    let fw = format!("firmware=sim-core/firmware/bin/{firmware}.elf");
    bins.cosim(&[
        "run",
        "short-hop",
        "--world",
        "scenarios/worlds/short-gate-displaced.toml",
        "--set",
        &fw,
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--quiet",
    ])
}

/// The last row's `collisions` and `gates_passed` (the world's running
/// counts, there even when the run never reached STOP).
fn last_counts(dir: &Path) -> (u64, u64) {
    let t = e2e_tests::read_series(&dir.join("trajectory.csv"));
    let header: Vec<&str> = t.lines().next().unwrap().split(',').collect();
    let last: Vec<&str> = t.lines().last().unwrap().split(',').collect();
    let col = |name: &str| {
        let i = header.iter().position(|h| *h == name).unwrap();
        last[i].parse::<u64>().unwrap()
    };
    (col("collisions"), col("gates_passed"))
}

#[test]
fn the_race_misses_a_displaced_gate_and_the_vision_race_passes_it() {
    let bins = CosimBins::new();
    let dir = tempfile::tempdir().unwrap();

    // Without eyes: the waypoint is outside the opening.
    let race = dir.path().join("race");
    run(&bins, "short_far", &race);
    let (collisions, passed) = last_counts(&race);
    assert_eq!(passed, 0, "the race passed the displaced gate");
    assert!(collisions >= 1, "the race should hit the gate's bar");
    assert_eq!(summary(&race)["gates_total"], 1);

    // With the detector in the loop: passed, no collision, and the STM32's
    // target went to the gate's true centre (-2.15, 2.0, 1.0) within 5 cm.
    let a = dir.path().join("vision-a");
    let o = run(&bins, "vision_race_short", &a);
    assert!(o.status.success(), "{}", text(&o));
    let s = summary(&a);
    assert_eq!(s["completed"], true, "{s:#}");
    assert_eq!(s["gates_passed"], 1, "{s:#}");
    assert_eq!(s["gates_total"], 1);
    assert_eq!(s["collisions"], 0);
    let console = std::fs::read_to_string(a.join("console.log")).unwrap();
    let line = console
        .lines()
        .find_map(|l| l.strip_prefix("[vision] waypoint 1 reached at "))
        .unwrap_or_else(|| panic!("{console}"));
    let mm: Vec<f64> = line
        .trim_end_matches(" mm")
        .split(' ')
        .map(|v| v.parse().unwrap())
        .collect();
    let err =
        ((mm[0] + 2150.0).powi(2) + (mm[1] - 2000.0).powi(2) + (mm[2] - 1000.0).powi(2)).sqrt();
    assert!(err < 50.0, "target {mm:?} is {err:.0} mm from the gate");
    // The target counts (docs/VISION.md, "Target counts"): the two
    // waypoints reached, every target move of the firmware ("retargets N"
    // on its console) counted as replaced, and the counts add up.
    let retargets: u64 = console
        .lines()
        .find_map(|l| l.split("retargets ").nth(1))
        .and_then(|r| r.split(',').next())
        .unwrap_or_else(|| panic!("{console}"))
        .parse()
        .unwrap();
    assert!(retargets >= 1, "the target never moved to the seen gate");
    assert_eq!(s["targets_reached"], 2, "{s:#}");
    assert_eq!(s["targets_replaced"], retargets, "{s:#}");
    assert_eq!(s["targets_total"], 2 + retargets, "{s:#}");
    assert_eq!(s["targets_bypassed"], 0, "{s:#}");

    // Deterministic: a second run gives the same bytes.
    let b = dir.path().join("vision-b");
    let o = run(&bins, "vision_race_short", &b);
    assert!(o.status.success(), "{}", text(&o));
    assert_same_files(
        &a,
        &b,
        &[
            "trajectory.csv",
            "world.trace",
            "platform.trace",
            "console.log",
            "power.csv",
        ],
        "between two runs",
    );
}
