//! The basicTimeStep's rules, declared once (`protocol::TimestepMs`,
//! DESIGN.md §19), hold alike in the three processes: `cosim` refuses a
//! timestep its sync mode cannot run before it starts anything,
//! `world-server` refuses one out of range, and `sim-core` given such a
//! world directly stops at INIT_PID with cosim's very message.

use std::process::{Command, Stdio};

use e2e_tests::{firmware, output_text as text, wait_for_path, world_file, CosimBins as Bins};
use protocol::{TimestepError, TimestepMs};

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_bad_timestep_is_refused_alike_by_every_process() {
    let thesis = TimestepMs::check(2, true).unwrap_err().to_string();
    let range = TimestepError::Range("0".into()).to_string();
    let b = Bins::new();
    let dir = tempfile::tempdir().unwrap();

    // cosim: before any process starts (no world trace, no summary).
    let out = dir.path().join("cosim");
    let out_arg = out.to_str().unwrap();
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--set",
        "timestep_ms=2",
        "--out",
        out_arg,
    ]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(stderr(&o).contains(&thesis), "{}", text(&o));
    assert!(!out.join("world.trace").exists() && !out.join("summary.json").exists());
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--set",
        "timestep_ms=0",
        "--out",
        out_arg,
    ]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(stderr(&o).contains(&range), "{}", text(&o));

    // world-server: the range.
    let o = Command::new(&b.world)
        .arg("--socket")
        .arg(dir.path().join("never.sock"))
        .args(["--timestep", "0"])
        .output()
        .unwrap();
    assert!(!o.status.success(), "{}", text(&o));
    assert!(stderr(&o).contains(&range), "{}", text(&o));

    // sim-core against a 2 ms world under the thesis's sync (its default).
    let sock = dir.path().join("world.sock");
    let mut world = Command::new(&b.world)
        .arg("--socket")
        .arg(&sock)
        .arg("--world")
        .arg(world_file("thesis-course"))
        .args(["--timestep", "2"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    assert!(
        wait_for_path(&sock, 30),
        "the world's socket never appeared"
    );
    let o = Command::new(&b.sim_core)
        .arg("--socket")
        .arg(&sock)
        .arg("--firmware")
        .arg(firmware("race"))
        .arg("--out")
        .arg(dir.path().join("sim-core"))
        .args(["--quiet", "--no-progress", "--connect-timeout", "20"])
        .output()
        .unwrap();
    let _ = world.kill();
    let _ = world.wait();
    assert!(!o.status.success(), "{}", text(&o));
    assert!(stderr(&o).contains(&thesis), "{}", text(&o));
}
