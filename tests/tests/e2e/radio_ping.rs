//! Two drones range each other over the UWB radio (DESIGN.md §7–§8,
//! docs/SWARM.md §4): two real `sim-core`s running the `radio_ping` firmware
//! (double-sided two-way ranging on the DW1000 stamps) and one real
//! `world-server` hosting both drones and the radio channel, over a real
//! UNIX socket. Clocks at ±20 ppm, no ranging noise: every printed distance
//! is the true centre distance within 2 cm. Two runs give byte-identical
//! traces, radio logs and consoles, also when one platform is slowed down on
//! purpose (sim-core's test-only `SIM_CORE_TEST_SLOW_LINK_US`).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use e2e_tests::{binary, firmware};

struct KillOnDrop(Child);
impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Two carried (static) drones A and B with UWB, B at `b` (m).
fn world(dir: &Path, b: [f64; 2]) -> PathBuf {
    let text = format!(
        r#"name = "two ranging drones"

[[drone]]
name = "A"
position = [0.0, 0.0, 0.015]
clock_ppm = 20.0
radios = ["uwb"]
carried = [[0.0, 0.0, 0.0, 0.015]]

[[drone]]
name = "B"
position = [{x}, {y}, 0.015]
clock_ppm = -20.0
radios = ["uwb"]
carried = [[0.0, {x}, {y}, 0.015]]

[radio]
seed = 7
uwb_noise_m = 0.0
"#,
        x = b[0],
        y = b[1]
    );
    let path = dir.join("two.toml");
    std::fs::write(&path, text).unwrap();
    path
}

struct Run {
    dir: tempfile::TempDir,
}

impl Run {
    fn read(&self, name: &str) -> String {
        e2e_tests::read_series(&self.dir.path().join(name))
    }

    /// The distances a drone printed (m).
    fn distances(&self, drone: &str) -> Vec<f64> {
        self.read(&format!("{drone}/console.log"))
            .lines()
            .filter_map(|l| l.split("distance ").nth(1))
            .map(|d| d.trim_end_matches(" m").parse().unwrap())
            .collect()
    }

    fn summary(&self, drone: &str) -> serde_json::Value {
        serde_json::from_str(&self.read(&format!("{drone}/summary.json"))).unwrap()
    }
}

/// One run at basicTimeStep `ts` ms; `slow_b` slows platform B (µs of wall
/// time per request).
fn run(ts: u32, b: [f64; 2], slow_b: Option<u64>) -> Run {
    // Built (if needed) before anything starts: a build must not eat the
    // world's connect timeout.
    let (world_bin, sim_core) = (
        binary("world-server", "world-server"),
        binary("sim-core", "sim-core"),
    );
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let socket = d.join("w.sock");
    let mut world = KillOnDrop(
        Command::new(world_bin)
            .arg("--socket")
            .arg(&socket)
            .arg("--world")
            .arg(world(d, b))
            .args(["--timestep", &ts.to_string(), "--connect-timeout", "30"])
            .arg("--trace")
            .arg(d.join("world.trace"))
            .arg("--radio-log")
            .arg(d.join("radio.csv"))
            .stdout(Stdio::null())
            .spawn()
            .expect("start world-server"),
    );
    let platform = |drone: &str, id: u32, slow: Option<u64>| {
        let mut cmd = Command::new(&sim_core);
        cmd.arg("--socket")
            .arg(&socket)
            .arg("--firmware")
            .arg(firmware("radio_ping"))
            .args(["--drone", drone, "--set", &format!("radio_id={id}")])
            .arg("--out")
            .arg(d.join(drone))
            .arg("--trace")
            .arg(d.join(format!("{drone}.trace")))
            .args(["--quiet", "--no-progress", "--connect-timeout", "30"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        if let Some(us) = slow {
            cmd.env("SIM_CORE_TEST_SLOW_LINK_US", us.to_string());
        }
        KillOnDrop(cmd.spawn().expect("start sim-core"))
    };
    let mut a = platform("A", 1, None);
    let mut bp = platform("B", 2, slow_b);
    for (name, p) in [("A", &mut a), ("B", &mut bp)] {
        let out = std::mem::replace(&mut p.0, Command::new("true").spawn().unwrap())
            .wait_with_output()
            .unwrap();
        assert!(
            out.status.success(),
            "sim-core {name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let status = world.0.wait().unwrap();
    assert!(status.success(), "world-server exited with {status}");
    Run { dir }
}

fn check_distances(r: &Run, truth: f64) {
    for drone in ["A", "B"] {
        let d = r.distances(drone);
        assert_eq!(
            d.len(),
            5,
            "{drone}: {}",
            r.read(&format!("{drone}/console.log"))
        );
        for m in d {
            assert!(
                (m - truth).abs() < 0.02,
                "{drone} printed {m} m, truth {truth} m"
            );
        }
        let s = r.summary(drone);
        assert_eq!(s["completed"], true, "{s:#}");
        assert_eq!(s["drone"], drone);
        assert_eq!(s["estimate_error_pct"], 0.0);
        assert_eq!(s["radios"]["uwb"]["frames_missed"], 0);
        assert!(s["energy_j"]["uwb"].as_f64().unwrap() > 0.0);
    }
}

const OUTPUTS: [&str; 8] = [
    "world.trace",
    "radio.csv",
    "A.trace",
    "B.trace",
    "A/console.log",
    "B/console.log",
    "A/power.csv",
    "B/power.csv",
];

#[test]
fn two_drones_range_each_other_within_2_cm_and_runs_repeat_byte_for_byte() {
    let b = [1.0, 0.5];
    let truth = (1.0f64 + 0.25).sqrt();
    let first = run(1, b, None);
    check_distances(&first, truth);
    let second = run(1, b, None);
    // B slowed down: the lockstep makes A wait; nothing else may change.
    let slowed = run(1, b, Some(2_000));
    for name in OUTPUTS {
        assert!(
            first.read(name) == second.read(name),
            "{name} differs between two runs"
        );
        assert!(
            first.read(name) == slowed.read(name),
            "{name} differs when platform B is slowed down"
        );
    }
}

#[test]
fn ranging_holds_at_a_coarser_timestep_and_a_longer_distance() {
    let b = [4.0, -3.0];
    let r = run(4, b, None);
    check_distances(&r, 5.0);
}
