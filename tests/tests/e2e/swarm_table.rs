//! Seed 003's positioning end to end (docs/SWARM_RESULTS.md): three
//! carried drones on a table run `swarm_node_short.elf` (the firmware of
//! `swarm-table`, 8 s) on three sim-cores against one world-server; A sits
//! at the seed's location 1, then is carried to location 2. A's estimate of
//! itself must be near the truth at both, and two runs must give the same
//! bytes.

use std::path::{Path, PathBuf};

use e2e_tests::{assert_same_files, output_text, repo_root, CosimBins};

/// B at (0, 0), C at (1, 0), A at location 1 (1, 0.5) until 5 s of world
/// time, carried in 0.5 s to location 2 (0.5, 0.25). Clocks and noise as
/// scenarios/worlds/swarm-table.toml (σ 0.10 m, the channel's default).
const WORLD: &str = r#"
name = "swarm table, short"
[[drone]]
name = "A"
clock_ppm = 12.0
radios = ["uwb"]
carried = [[0.0, 1.0, 0.5, 0.80], [5.0, 1.0, 0.5, 0.80], [5.5, 0.5, 0.25, 0.80]]
[[drone]]
name = "B"
clock_ppm = -18.0
radios = ["uwb"]
carried = [[0.0, 0.0, 0.0, 0.80]]
[[drone]]
name = "C"
clock_ppm = 7.0
radios = ["uwb"]
carried = [[0.0, 1.0, 0.0, 0.80]]
[radio]
seed = 11
"#;

/// Windows of world time: location 1 after the frame is built (the drones
/// come up 0.2 s apart from 2 s on, the frame within ~0.5 s: from 3 s,
/// 1 s of margin) and location 2 after 1.5 s to settle.
const SCENARIO: &str = r#"
world = "world.toml"
firmware = "FW/swarm_node_short.elf"
timestep_ms = 4
max_time_s = 30
[[platform]]
drone = "A"
[[platform]]
drone = "B"
[[platform]]
drone = "C"
[positioning]
observer = "A"
[[positioning.table]]
name = "location 1"
from_s = 3.5
to_s = 5.0
[[positioning.table]]
name = "location 2"
from_s = 7.0
to_s = 10.0
"#;

/// Bound on the mean error of A's estimate over a window (m), from the
/// noise: each DW1000 stamp carries σ_n = 0.10 m of arrival noise
/// (docs/SWARM.md §3.1), so one SDS-TWR distance (eq. 5.11, two stamps
/// per direction, averaged) has σ_d ≈ 0.07 m. A's filter takes ~200
/// distances per second (B and C each transmit at the 100 Hz ceiling of
/// §6.5) with the seed's σ = 0.25 m (§7.3) and a process noise q = 0.01
/// m²/s: its steady-state variance is P ≈ √(q·R/f) = √(0.01·0.0625/200)
/// = 1.8e-3 m², a gain k = P/R ≈ 0.028 per distance, i.e. an exponential
/// average over 1/k ≈ 35 distances (0.18 s). The random error of one
/// estimate is then σ_d·√(k/2) ≈ 8 mm per distance direction; the 2D
/// geometry at these locations (distances to B and C 30°–90° apart)
/// dilutes it by at most ~2.5, and B and C's own scatter (C's x std ~1.4 cm
/// in swarm-table) adds as much again: σ_e ≲ 0.03 m per sample. The mean
/// over a window of ≥ 1.5 s (≥ 8 independent averaging times) is well
/// inside that; 0.10 m is > 3σ_e for the mean even if every sample were
/// fully correlated, and far below the error of a wrong frame (a mirror
/// image is ≥ 0.5 m away, an undrifted but wrong σ several decimetres).
const MEAN_BOUND_M: f64 = 0.10;
/// Bound on any single estimate in the windows: ≈ 7σ_e, the seed's own
/// measurement σ (0.25 m) would be far looser.
const SAMPLE_BOUND_M: f64 = 0.20;

fn write_scenario(dir: &Path) -> PathBuf {
    std::fs::write(dir.join("world.toml"), WORLD).unwrap();
    let fw = repo_root().join("sim-core/firmware/bin");
    let p = dir.join("s.toml");
    std::fs::write(&p, SCENARIO.replace("FW", fw.to_str().unwrap())).unwrap();
    p
}

/// A row of positions.csv (the columns this test reads).
struct Row {
    time_s: f64,
    observer: String,
    drone: String,
    est_x: f64,
    est_y: f64,
    true_x: f64,
    true_y: f64,
}

fn read_rows(path: &Path) -> Vec<Row> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h = r.headers().unwrap().clone();
    let col = |n: &str| {
        h.iter()
            .position(|c| c == n)
            .unwrap_or_else(|| panic!("no {n}"))
    };
    let (t, o, d, ex, ey, tx, ty) = (
        col("time_s"),
        col("observer"),
        col("drone"),
        col("est_x"),
        col("est_y"),
        col("true_x"),
        col("true_y"),
    );
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            let f = |i: usize| rec[i].parse::<f64>().unwrap();
            Row {
                time_s: f(t),
                observer: rec[o].to_string(),
                drone: rec[d].to_string(),
                est_x: f(ex),
                est_y: f(ey),
                true_x: f(tx),
                true_y: f(ty),
            }
        })
        .collect()
}

#[test]
fn a_is_placed_within_the_noise_bound_and_runs_repeat_bit_for_bit() {
    let b = CosimBins::new();
    let tmp = tempfile::tempdir().unwrap();
    let s = write_scenario(tmp.path());
    let run = |name: &str| -> PathBuf {
        let out = tmp.path().join(name);
        let o = b.cosim(&[
            "run",
            s.to_str().unwrap(),
            "--quiet",
            "--no-plots",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", output_text(&o));
        out
    };
    let a = run("a");

    let rows = read_rows(&a.join("positions.csv"));
    assert!(!rows.is_empty());
    for (from, to, x, y) in [(3.5, 5.0, 1.0, 0.5), (7.0, 10.0, 0.5, 0.25)] {
        let sel: Vec<&Row> = rows
            .iter()
            .filter(|r| r.observer == "A" && r.drone == "A")
            .filter(|r| r.time_s >= from && r.time_s < to)
            .collect();
        // 100 estimates per second (§7.1).
        let expected = ((to - from) * 100.0) as usize;
        assert!(
            sel.len() + 2 >= expected,
            "{} estimates in [{from}, {to})",
            sel.len()
        );
        for r in &sel {
            assert!((r.true_x - x).abs() < 1e-9 && (r.true_y - y).abs() < 1e-9);
            let e = ((r.est_x - r.true_x).powi(2) + (r.est_y - r.true_y).powi(2)).sqrt();
            assert!(e < SAMPLE_BOUND_M, "A at {:.2} s: error {e:.3} m", r.time_s);
        }
        let n = sel.len() as f64;
        let mx = sel.iter().map(|r| r.est_x).sum::<f64>() / n;
        let my = sel.iter().map(|r| r.est_y).sum::<f64>() / n;
        let e = ((mx - x).powi(2) + (my - y).powi(2)).sqrt();
        assert!(
            e < MEAN_BOUND_M,
            "A's mean estimate ({mx:.3}, {my:.3}) is {e:.3} m from ({x}, {y})"
        );
    }
    let md = std::fs::read_to_string(a.join("positioning.md")).unwrap();
    assert!(md.contains("### location 2 (estimates of A)"), "{md}");

    let b2 = run("b");
    let mut files = vec![
        "positions.csv".to_string(),
        "positioning.md".into(),
        "radio.csv".into(),
        "world.trace".into(),
        "trajectory.csv".into(),
    ];
    for d in ["A", "B", "C"] {
        files.push(format!("{d}/console.log"));
        files.push(format!("{d}/platform.trace"));
    }
    assert_same_files(&a, &b2, &files, "between two runs");
}

/// The means of observer A's estimates of `drone` (x, y) and of the truth in
/// each of the four windows of `scenarios/swarm-table.toml` (Tables 7.1–7.4).
fn window_means(rows: &[Row], drone: &str) -> Vec<(f64, f64, f64, f64)> {
    [(5.0, 15.0), (18.0, 28.0), (31.0, 41.0), (44.0, 54.0)]
        .iter()
        .map(|&(from, to)| {
            let sel: Vec<&Row> = rows
                .iter()
                .filter(|r| r.observer == "A" && r.drone == drone)
                .filter(|r| r.time_s >= from && r.time_s < to)
                .collect();
            assert!(sel.len() > 900, "{drone} in [{from}, {to}): {}", sel.len());
            let n = sel.len() as f64;
            let m = |f: fn(&Row) -> f64| sel.iter().map(|r| f(r)).sum::<f64>() / n;
            (
                m(|r| r.est_x),
                m(|r| r.est_y),
                m(|r| r.true_x),
                m(|r| r.true_y),
            )
        })
        .collect()
}

/// `swarm-table` as shipped: the world's UWB is the DW1000 as measured
/// (per-chip antenna delays, the firmware's one 515.7 ns constant; DESIGN.md
/// §16). Seed 003's real boards put C, 1 m from B, at 0.85–0.94 m and A up
/// to 0.30 m off (Tables 7.1–7.4): C's estimate must be 2–20 cm from 1 m
/// and A's mean error 3–40 cm — the seed's band, neither ten times better
/// nor worse. The same run with the "ideal" profile (a copy of the world
/// with `profile = "ideal"`, no firmware correction) keeps the tables of
/// docs/SWARM_RESULTS.md §2: C within 1 cm of 1 m, A within 1 cm.
#[test]
fn swarm_table_as_measured_and_ideal() {
    let b = CosimBins::new();
    let tmp = tempfile::tempdir().unwrap();
    let root = repo_root();
    let world = std::fs::read_to_string(root.join("scenarios/worlds/swarm-table.toml")).unwrap();
    assert!(world.contains("profile = \"dw1000\""));
    let ideal_world = tmp.path().join("ideal.toml");
    std::fs::write(
        &ideal_world,
        world.replace("profile = \"dw1000\"", "profile = \"ideal\""),
    )
    .unwrap();
    let run = |name: &str, extra: &[&str]| -> Vec<Row> {
        let out = tmp.path().join(name);
        let mut args = vec![
            "run",
            "swarm-table",
            "--quiet",
            "--no-plots",
            "--no-trace",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = b.cosim(&args);
        assert!(o.status.success(), "{}", output_text(&o));
        read_rows(&out.join("positions.csv"))
    };
    let measured = run("dw1000", &[]);
    let c = window_means(&measured, "C");
    let a = window_means(&measured, "A");
    let a_err: Vec<f64> = a
        .iter()
        .map(|(x, y, tx, ty)| ((x - tx).powi(2) + (y - ty).powi(2)).sqrt())
        .collect();
    println!("dw1000: C x {c:?}\n        A errors {a_err:?}");
    for (x, ..) in &c {
        assert!((0.02..=0.20).contains(&(x - 1.0).abs()), "C at {x:.3} m");
    }
    let mean_a = a_err.iter().sum::<f64>() / 4.0;
    assert!(
        (0.03..=0.40).contains(&mean_a),
        "A's mean error {mean_a:.3} m"
    );

    let ideal = run(
        "ideal",
        &[
            "--world",
            ideal_world.to_str().unwrap(),
            "--set",
            "firmware.swarm_antenna_delay_ticks=0",
        ],
    );
    // SWARM_RESULTS.md §2: C at 0.999–1.006 m; A within 6 mm, but for
    // location 4 (on the X axis: y 0.050 for 0, no gradient to come back).
    let bounds = [("C", [0.01; 4]), ("A", [0.01, 0.01, 0.01, 0.06])];
    for (drone, bound) in bounds {
        for ((x, y, tx, ty), bound) in window_means(&ideal, drone).into_iter().zip(bound) {
            let e = ((x - tx).powi(2) + (y - ty).powi(2)).sqrt();
            assert!(
                e < bound,
                "ideal: {drone} at ({x:.3}, {y:.3}) for ({tx}, {ty})"
            );
        }
    }
}
