//! Seed 004's mapping and frontier exploration end to end (docs/EXPLORE.md,
//! DESIGN.md §9): `explore_app.elf` on the ISS, fed by the STM32's estimate
//! and ranges, flying in the world over real sockets, its map copied out of
//! the core at the end and scored against the world's true floor plan.
//!
//! - A room the firmware has never seen (`seed004-lroom.toml`, L-shaped,
//!   an obstacle turned 35°, a pillar, take-off facing −x): at least 90 % of
//!   its free space covered, no collision, landed, and byte-identical
//!   outputs when run twice.
//! - Bad input ends with a clear message and never hangs: a grid over the
//!   firmware's memory budget, a start inside an obstacle, and a frontier
//!   that can only be reached through a slot narrower than the drone.

use std::path::Path;

use e2e_tests::{assert_same_files, output_text as text, repo_root, summary, CosimBins as Bins};

/// The L room's explorable area around its take-off point (3.4, 0.6) m:
/// the room is x in [0, 4], y in [0, 3.5]; 0.5 m of margin.
const LROOM_AREA: [&str; 4] = [
    "firmware.explore_param_x_min_mm=-3900",
    "firmware.explore_param_x_max_mm=1100",
    "firmware.explore_param_y_min_mm=-1100",
    "firmware.explore_param_y_max_mm=3400",
];

fn explore(bins: &Bins, out: &Path, world: &Path, extra: &[&str]) -> std::process::Output {
    let world = format!("world={}", world.display());
    let mut args = vec![
        "run",
        "seed004-explore",
        "--quiet",
        "--no-trace",
        "--out",
        out.to_str().unwrap(),
        "--set",
        &world,
    ];
    for s in extra {
        args.extend(["--set", s]);
    }
    bins.cosim(&args)
}

#[test]
fn an_unseen_room_is_explored_landed_and_reproduced() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let world = repo_root().join("scenarios/worlds/seed004-lroom.toml");
    let dirs = [tmp.path().join("a"), tmp.path().join("b")];
    for d in &dirs {
        let o = explore(&bins, d, &world, &LROOM_AREA);
        assert!(o.status.success(), "{}", text(&o));
    }
    let s = summary(&dirs[0]);
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["collisions"], 0, "{s}");
    let m = &s["map"];
    // The goal: "still covers ≥ 90 % of its free space without a collision".
    assert!(m["coverage_pct"].as_f64().unwrap() >= 90.0, "{m}");
    // Accuracy: the self-test's synthetic flights reach 89-98 % with the
    // seed's compromise (a 20° nearest-return ranger, a 4° map cone: walls
    // seen obliquely move in by up to a cell). 85 % leaves room for the
    // real flight's attitude; a map that were mostly wrong fails.
    assert!(m["accuracy_pct"].as_f64().unwrap() >= 85.0, "{m}");
    assert_eq!(
        (m["cell_m"].as_f64(), m["fov_deg"].as_f64()),
        (Some(0.05), Some(4.0))
    );
    assert_eq!(m["cells"], 100 * 90);
    assert!(m["goals"].as_u64().unwrap() >= 1, "{m}");
    assert!(m["map_cycles"].as_u64().unwrap() > 0, "{m}");
    // Landed: the trajectory ends on the ground.
    let traj = e2e_tests::read_series(&dirs[0].join("trajectory.csv"));
    let last: Vec<f64> = traj
        .lines()
        .last()
        .unwrap()
        .split(',')
        .take(4)
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(last[3] < 0.05, "not on the ground at the end: {last:?}");
    // The outputs of DESIGN §9 exist and agree with the summary.
    let csv = std::fs::read_to_string(dirs[0].join("map.csv")).unwrap();
    assert!(csv.starts_with("ix,iy,x,y,p_occupied\n"));
    assert_eq!(csv.lines().count(), 1 + 100 * 90);
    let goals = std::fs::read_to_string(dirs[0].join("exploration.csv")).unwrap();
    assert_eq!(
        goals.lines().count() as u64,
        1 + m["goals"].as_u64().unwrap()
    );
    assert!(dirs[0].join("map.png").exists());
    // Twice the same run: the same bytes.
    assert_same_files(
        &dirs[0],
        &dirs[1],
        &[
            "map.cfog",
            "map.csv",
            "exploration.csv",
            "trajectory.csv",
            "console.log",
        ],
        "between two identical runs",
    );
}

#[test]
fn a_grid_over_the_memory_budget_is_refused_on_the_ground() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let world = repo_root().join("scenarios/worlds/seed004-room.toml");
    // 2 cm cells over the seed room's 7.5 x 3.5 m: 375 x 175 cells.
    let o = explore(
        &bins,
        tmp.path(),
        &world,
        &[
            "firmware.explore_param_cell_mm=20",
            "firmware.explore_param_x_min_mm=-1000",
            "firmware.explore_param_x_max_mm=6500",
            "firmware.explore_param_y_min_mm=-1000",
            "firmware.explore_param_y_max_mm=2500",
        ],
    );
    assert!(!o.status.success(), "{}", text(&o));
    let all = text(&o);
    assert!(
        all.contains("grid 375 x 175 = 65625 cells exceeds the budget of 25600 cells"),
        "{all}"
    );
    let console = std::fs::read_to_string(tmp.path().join("console.log")).unwrap();
    assert!(console.contains("EXPLORE error explore: grid"), "{console}");
    // It never took off.
    let s = summary(tmp.path());
    assert!(s["world_time_s"].as_f64().unwrap_or(0.0) < 5.0, "{s}");
}

/// Explores a world of walls (x0, y0, x1, y1 in m, 1 m high) written for
/// a test, with the seed room's sensors, taking off at `start` facing +x;
/// `area` is the explorable area around the take-off point (mm).
fn explore_walls(
    bins: &Bins,
    dir: &Path,
    start: [f64; 2],
    walls: &[[f64; 4]],
    area: [i32; 4],
    max_time_s: u32,
) -> (std::process::Output, std::path::PathBuf) {
    let mut text = format!(
        "name = \"test\"\n[start]\nposition = [{}, {}, 0.015]\n",
        start[0], start[1]
    );
    for [x0, y0, x1, y1] in walls {
        text.push_str(&format!(
            "[[box]]\ncentre = [{}, {}, 0.5]\nsize = [{}, {}, 1.0]\ngrey = 200\n",
            (x0 + x1) / 2.0,
            (y0 + y1) / 2.0,
            x1 - x0,
            y1 - y0
        ));
    }
    text.push_str("[sensors]\nrange_max_m = 4.0\nrange_fov_deg = 20.0\nrange_rays = 21\nup_down = true\nflow = true\n");
    let world = dir.join("world.toml");
    std::fs::write(&world, text).unwrap();
    let out = dir.join("out");
    let sets: Vec<String> = ["x_min", "x_max", "y_min", "y_max"]
        .iter()
        .zip(area)
        .map(|(k, v)| format!("firmware.explore_param_{k}_mm={v}"))
        .chain([format!("max_time_s={max_time_s}")])
        .collect();
    let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
    (explore(bins, &out, &world, &sets), out)
}

#[test]
fn a_frontier_behind_a_slot_narrower_than_the_drone_is_skipped() {
    // Two 2 x 2 m rooms joined by a 0.25 m slot (the drone needs 2 x 0.15 m
    // with its margin), as the firmware's "slot rooms": seen through from
    // the first room, the second's frontier is unreachable; the run ends by
    // itself, landed, without a collision.
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let walls = [
        [-0.1, -0.1, 4.1, 0.0],
        [-0.1, 2.0, 4.1, 2.1],
        [-0.1, 0.0, 0.0, 2.0],
        [4.0, 0.0, 4.1, 2.0],
        [2.0, 0.0, 2.1, 0.875],
        [2.0, 1.125, 2.1, 2.0],
    ];
    let area = [-2000, 3000, -1500, 1500];
    let (o, out) = explore_walls(&bins, tmp.path(), [1.5, 1.0], &walls, area, 200);
    assert!(o.status.success(), "{}", text(&o));
    let s = summary(&out);
    assert_eq!(s["collisions"], 0, "{s}");
    assert!(s["map"]["regions_unreachable"].as_u64().unwrap() > 0, "{s}");
    // Ended by the firmware (no frontier left), well before max_time_s.
    assert!(s["world_time_s"].as_f64().unwrap() < 150.0, "{s}");
}

#[test]
fn a_start_inside_an_obstacle_ends_with_a_clear_error() {
    // The take-off point inside a 0.4 m box: the physics pushes the drone
    // out or holds it; whatever it does, the run ends (by max_time_s at
    // worst) and the map cannot be scored: the report says why.
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let walls = [
        [-0.1, -0.1, 2.1, 0.0],
        [-0.1, 2.0, 2.1, 2.1],
        [-0.1, 0.0, 0.0, 2.0],
        [2.0, 0.0, 2.1, 2.0],
        [0.8, 0.8, 1.2, 1.2],
    ];
    let area = [-1500, 1500, -1500, 1500];
    let (o, out) = explore_walls(&bins, tmp.path(), [1.0, 1.0], &walls, area, 60);
    assert!(!o.status.success(), "{}", text(&o));
    let report = std::fs::read_to_string(out.join("report.txt")).unwrap();
    assert!(
        report.contains("inside an obstacle at the flight height"),
        "{report}"
    );
}
