//! The Python example world server (`examples/python-world/world.py`,
//! standard library only) serves the platform unchanged: `sim-core` flies
//! the short firmware against it to the end. Skipped, with a message, when
//! `python3` is not installed.

use std::process::{Command, Stdio};

use e2e_tests::{binary, repo_root, summary};

fn python3() -> bool {
    Command::new("python3")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn sim_core_flies_against_the_python_world() {
    if !python3() {
        eprintln!("SKIPPED: python3 is not installed; the Python example world cannot run");
        return;
    }
    let sim_core = binary("sim-core", "sim-core");
    let tmp = tempfile::tempdir().unwrap();
    let sock = tmp.path().join("py.sock");
    let out = tmp.path().join("out");
    let world = Command::new("python3")
        .arg(repo_root().join("examples/python-world/world.py"))
        .arg("--socket")
        .arg(&sock)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    e2e_tests::wait_for_path(&sock, 20);
    let sim = Command::new(&sim_core)
        .arg("--socket")
        .arg(&sock)
        .arg("--firmware")
        .arg(repo_root().join("sim-core/firmware/bin/short.elf"))
        .arg("--out")
        .arg(&out)
        .args(["--quiet", "--no-progress", "--max-time", "120"])
        .output()
        .unwrap();
    let w = world.wait_with_output().unwrap();
    assert!(
        sim.status.success(),
        "sim-core: {}\n{}",
        String::from_utf8_lossy(&sim.stderr),
        String::from_utf8_lossy(&w.stderr)
    );
    assert!(
        w.status.success(),
        "world.py: {}",
        String::from_utf8_lossy(&w.stderr)
    );
    let s = summary(&out);
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["targets_reached"], 1, "{s}");
    // The same time bookkeeping holds with a foreign world: the platform's
    // estimate of the world's time is exact (DESIGN.md §3).
    assert_eq!(s["estimate_error_pct"], 0.0, "{s}");
    // The Python world reports its own STOP time; it must be later than
    // the take-off, the hop and the landing (> 10 s of world time).
    assert!(s["world_time_s"].as_f64().unwrap() > 10.0, "{s}");
}
