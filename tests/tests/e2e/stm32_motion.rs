//! The STM32 extension end to end (sim-core/src/peripherals/stm32/motion.rs):
//! the `motion_velocity` and `motion_heading` firmware on the ISS against the
//! real world server, run by `cosim run` on the short scenario's empty world
//! with another firmware. Each flight takes a few seconds of wall time.
//! Flow mode (DESIGN.md §9): the same flight on the Flow deck's noisy flow,
//! through the STM32's flow filter (`estimator.rs`), and without it.

use std::path::Path;

use e2e_tests::{output_text as text, summary, CosimBins};

/// Runs `cosim run short-hop` with `firmware`; returns the output directory.
fn run(bins: &CosimBins, firmware: &str) -> tempfile::TempDir {
    let (dir, o) = run_with(bins, firmware, &[]);
    assert!(o.status.success(), "{}", text(&o));
    dir
}

/// `cosim run short-hop` with `firmware` and `--set` overrides.
fn run_with(
    bins: &CosimBins,
    firmware: &str,
    sets: &[&str],
) -> (tempfile::TempDir, std::process::Output) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let fw = format!("firmware=sim-core/firmware/bin/{firmware}.elf");
    let mut args = vec![
        "run",
        "short-hop",
        "--set",
        &fw,
        "--out",
        out,
        "--no-plots",
        "--quiet",
    ];
    for s in sets {
        args.extend(["--set", s]);
    }
    let o = bins.cosim(&args);
    (dir, o)
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
    let t = e2e_tests::read_series(&dir.join("trajectory.csv"));
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

/// The short scenario's empty world with the Flow deck's noisy flow: σ =
/// 0.069 m/s per 32 ms sample (seed004-room.toml, the STM32's default
/// `stm32.flow_std_m_s`), no scale error, so that the drift is the noise's.
const NOISY_FLOW_WORLD: &str = r#"name = "empty-noisy-flow"
[start]
position = [-2.6, 0.0, 0.015]
yaw = 1.5707963267948966
[ground]
tile = 0.5
grey_dark = 90
grey_light = 140
[sky]
grey = 200
[sensors]
flow = true
flow_noise_m_s = 0.069
seed = 12
"#;

/// The largest |roll| or |pitch| (rad) in a trajectory.
fn max_tilt(rows: &[Vec<f64>]) -> f64 {
    rows.iter()
        .map(|r| r[4].abs().max(r[5].abs()))
        .fold(0.0, f64::max)
}

#[test]
fn flow_mode_flies_on_noisy_flow_through_the_filter_and_drifts_a_bounded_amount() {
    let bins = CosimBins::new();
    let tmp = tempfile::tempdir().unwrap();
    let world = tmp.path().join("world.toml");
    std::fs::write(&world, NOISY_FLOW_WORLD).unwrap();
    let world = format!("world={}", world.display());
    let flow = "stm32.position_source=flow";

    // Through the filter: the motion_velocity flight (take off to 1 m,
    // 0.2 m/s forward for 5 s, hover, land) as on the GPS.
    let (dir, o) = run_with(&bins, "motion_velocity", &[&world, flow]);
    assert!(o.status.success(), "{}", text(&o));
    let console = std::fs::read_to_string(dir.path().join("console.log")).unwrap();
    assert!(console.contains("[motion] done"), "{console}");
    let s = summary(dir.path());
    assert_eq!(
        (s["completed"].as_bool(), s["collisions"].as_u64()),
        (Some(true), Some(0))
    );
    let rows = trajectory(dir.path());
    // No flip: the GPS flight of the same firmware tilts up to 0.16 rad (the
    // take-off); 0.35 rad (20°) leaves room for the noise, a flip is π.
    let tilt = max_tilt(&rows);
    assert!(tilt < 0.35, "tilted {tilt} rad");
    // Flew the closed-form metre along world +y (estimate) and landed.
    let (a, b) = (
        estimate(&console, "velocity start"),
        estimate(&console, "velocity end"),
    );
    assert!((0.8..=1.1).contains(&(b[1] - a[1])), "{a:?} -> {b:?}");
    let last = rows.last().unwrap();
    assert!(last[3] < 0.05, "still {} m up", last[3]);
    // The drift (estimate − GPS, horizontal). The filter's gain at zero
    // frequency is 1, so the estimate's slow error is the flow's: the
    // position error is the noise's random walk, σ·√(dt·T) per axis =
    // 0.069·√(0.032·21) = 0.057 m over the 21 s flight; its length is
    // Rayleigh-distributed, above 4.4·0.057 = 0.25 m with probability
    // e^(−4.4²/2) = 6e-5. Below 0.1·σ_p (0.006 m) only with probability
    // 0.5 %, and never if the estimate were secretly the GPS.
    let d = &s["flow_drift"];
    let (max, last_d) = (d["max_m"].as_f64().unwrap(), d["final_m"].as_f64().unwrap());
    assert!(max <= 0.25, "drift {d}");
    assert!(last_d > 0.006, "no drift at all: {d}");
    // The same flight on the raw flow (σ = 0: the filter's gain is 1, the
    // STM32 without a flow filter): the velocity loop's derivative turns the
    // noise into attitude demands of 0.5·0.069·√2/0.032 = 1.5 rad per step;
    // the drone flips.
    let (dir, o) = run_with(
        &bins,
        "motion_velocity",
        &[&world, flow, "stm32.flow_std_m_s=0"],
    );
    let tilt = max_tilt(&trajectory(dir.path()));
    assert!(
        !o.status.success() || tilt > 1.5,
        "the raw flow flew: tilt {tilt} rad\n{}",
        text(&o)
    );
    assert!(tilt > 1.5, "the raw flow did not flip: {tilt} rad");
}
