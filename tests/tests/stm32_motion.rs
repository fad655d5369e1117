//! The STM32 extension end to end (sim-core/src/peripherals/stm32/motion.rs):
//! the `motion_velocity` and `motion_heading` firmware on the ISS against the
//! real world server, run by `cosim run` on the short scenario's empty world
//! with another firmware. Each flight takes a few seconds of wall time.

use std::path::Path;

use e2e_tests::{output_text as text, CosimBins};
use serde_json::Value;

/// Runs `cosim run short-hop` with `firmware`; returns the output directory.
fn run(bins: &CosimBins, firmware: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let fw = format!("firmware=sim-core/firmware/bin/{firmware}.elf");
    let o = bins.cosim(&[
        "run",
        "short-hop",
        "--set",
        &fw,
        "--out",
        out,
        "--no-plots",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    dir
}

fn summary(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// "[motion] WHAT: est X Y Z mm yaw R mrad, ..." → (x, y, z) in m, yaw in rad.
fn estimate(console: &str, what: &str) -> [f64; 4] {
    let key = format!("[motion] {what}: est ");
    let line = console
        .lines()
        .find_map(|l| l.strip_prefix(&key))
        .unwrap_or_else(|| panic!("no {what:?} line in:\n{console}"));
    let n: Vec<f64> = line
        .split(|c: char| !(c.is_ascii_digit() || c == '-'))
        .filter(|t| !t.is_empty())
        .take(4)
        .map(|t| t.parse::<f64>().unwrap() / 1000.0)
        .collect();
    [n[0], n[1], n[2], n[3]]
}

/// The trajectory's rows as numbers (header skipped).
fn trajectory(dir: &Path) -> Vec<Vec<f64>> {
    let t = std::fs::read_to_string(dir.join("trajectory.csv")).unwrap();
    t.lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect()
}

#[test]
fn take_off_velocity_and_land_fly_the_closed_form_displacement() {
    let bins = CosimBins::new();
    let dir = run(&bins, "motion_velocity");
    let console = std::fs::read_to_string(dir.path().join("console.log")).unwrap();
    assert!(console.contains("bad command -> EXT_ERROR"), "{console}");
    assert!(console.contains("[motion] done"), "{console}");
    let s = summary(dir.path());
    assert_eq!(s["completed"], true, "{s:#}");
    assert_eq!(s["collisions"], 0);

    // Take-off: 1 m above the start (0.015 m), within the 0.1 m tolerance.
    let up = estimate(&console, "took off");
    assert!((up[2] - 1.015).abs() <= 0.1, "took off to {up:?}");
    // 0.2 m/s forward for 156 iterations of 32 ms = 0.998 m along the body
    // x axis, i.e. world +y (the drone faces +y), less the velocity loop's
    // lag at the start (about 0.2 s); none sideways.
    let a = estimate(&console, "velocity start");
    let b = estimate(&console, "velocity end");
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    assert!(
        (0.8..=1.1).contains(&dy),
        "forward {dy} m, closed form 0.998 m"
    );
    assert!(dx.abs() < 0.1, "sideways {dx} m");
    assert!((b[2] - 1.015).abs() < 0.1, "height {} m", b[2]);
    // Stopped: the hover adds little; then landed (the world's truth).
    let h = estimate(&console, "hover");
    assert!((h[1] - b[1]).abs() < 0.3, "drifted from {b:?} to {h:?}");
    let last = trajectory(dir.path()).pop().unwrap();
    assert!(last[3] < 0.05, "still {} m up", last[3]);
    assert!((last[2] - h[1]).abs() < 0.2, "landed at y {}", last[2]);
}

#[test]
fn a_heading_target_turns_the_race_controller_and_it_still_reaches_the_target() {
    let bins = CosimBins::new();
    let dir = run(&bins, "motion_heading");
    let console = std::fs::read_to_string(dir.path().join("console.log")).unwrap();
    assert!(console.contains("target reached after"), "{console}");
    let s = summary(dir.path());
    assert_eq!(s["completed"], true, "{s:#}");
    assert_eq!(s["targets_reached"], 1, "{s:#}");
    // At the target: facing +x (yaw 0, from +π/2 at the start) and within
    // the tolerance of (−1.6, 0, 1).
    let e = estimate(&console, "at target");
    assert!(e[3].abs() < 0.05, "yaw {} rad", e[3]);
    assert!((e[0] + 1.6).abs() <= 0.1 && e[1].abs() <= 0.1, "{e:?}");
    // The world agrees: the yaw column of the last airborne rows.
    let rows = trajectory(dir.path());
    let airborne: Vec<&Vec<f64>> = rows.iter().filter(|r| r[3] > 0.5).collect();
    let yaw = airborne.last().unwrap()[6];
    assert!(yaw.abs() < 0.05, "world yaw {yaw}");
}
