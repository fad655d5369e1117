//! `cosim run --world-cmd`: the launcher runs another world server (the
//! Python example) in place of ours, and the platform flies against it.

use std::process::Command;

use e2e_tests::{binary, repo_root};

#[test]
fn cosim_runs_the_python_world_in_place_of_ours() {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("skipped: python3 is not installed");
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let status = Command::new(binary("scenarios", "cosim"))
        .current_dir(repo_root())
        .args(["run", "short-hop", "--no-build", "--no-trace"])
        .arg("--out")
        .arg(out.path())
        .arg("--sim-core")
        .arg(binary("sim-core", "sim-core"))
        .arg("--world-server")
        .arg(binary("world-server", "world-server"))
        .args([
            "--world-cmd",
            "python3 examples/python-world/world.py --socket {socket}",
        ])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["completed"], true);
    assert_eq!(summary["targets_reached"], 1);
    assert_eq!(summary["estimate_error_pct"], 0.0);
    // Our world's trajectory is not there; the power plots are.
    assert!(!e2e_tests::series_file(&out.path().join("trajectory.csv")).exists());
    assert!(out.path().join("power_models.png").exists());
}
