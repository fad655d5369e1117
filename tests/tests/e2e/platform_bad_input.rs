//! Bad input to the platform: misbehaving firmware, a world that dies
//! mid-run, a battery that empties. Each ends in a clear one-line error and
//! a non-zero exit, with summary.json and the CSVs written and valid.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use e2e_tests::{binary, firmware, repo_root, world_file};

struct KillOnDrop(Child);
impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_world(dir: &Path) -> KillOnDrop {
    KillOnDrop(
        Command::new(binary("world-server", "world-server"))
            .arg("--socket")
            .arg(dir.join("world.sock"))
            .arg("--world")
            .arg(world_file("thesis-course"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start world-server"),
    )
}

fn platform(dir: &Path, elf: &str) -> Command {
    let mut cmd = Command::new(binary("sim-core", "sim-core"));
    cmd.arg("--socket")
        .arg(dir.join("world.sock"))
        .arg("--firmware")
        .arg(firmware(elf))
        .arg("--out")
        .arg(dir.join("out"))
        .args(["--quiet", "--no-progress", "--connect-timeout", "20"]);
    cmd
}

/// Runs to the end; returns the last stderr line (the error) and the summary.
fn failed_run(mut cmd: Command, dir: &Path) -> (String, serde_json::Value) {
    let out = cmd.output().expect("run sim-core");
    assert!(!out.status.success(), "sim-core should have failed");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let last = stderr.lines().last().unwrap_or_default().to_string();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .expect("summary.json is valid JSON");
    assert_eq!(summary["completed"], false);
    assert_ne!(summary["exit_code"], 0);
    // Every CSV is complete: same number of fields on every line.
    for csv in [
        "power.csv",
        "motor_empirical.csv",
        "motor_dandrea.csv",
        "motor_stolaroff.csv",
    ] {
        let text = e2e_tests::read_series(&dir.join("out").join(csv));
        let widths: Vec<usize> = text.lines().map(|l| l.split(',').count()).collect();
        assert!(!widths.is_empty(), "{csv} is empty");
        assert!(
            widths.iter().all(|w| *w == widths[0]),
            "{csv} has a torn line"
        );
        assert!(text.ends_with('\n'), "{csv} ends mid-line");
    }
    (last, summary)
}

#[test]
fn unknown_stm32_command_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let _world = start_world(dir.path());
    let (err, _) = failed_run(platform(dir.path(), "bad_command"), dir.path());
    assert!(err.contains("stm32: unknown command 252"), "{err}");
}

#[test]
fn reading_past_the_peripheral_window_is_a_load_access_fault() {
    let dir = tempfile::tempdir().unwrap();
    let _world = start_world(dir.path());
    let (err, _) = failed_run(platform(dir.path(), "bad_read"), dir.path());
    assert!(err.contains("load access fault"), "{err}");
    assert!(err.contains("0x2001901c"), "{err}");
}

#[test]
fn a_world_that_dies_mid_run_is_reported_and_outputs_are_kept() {
    let dir = tempfile::tempdir().unwrap();
    let mut world = start_world(dir.path());
    let mut cmd = platform(dir.path(), "race");
    cmd.stderr(Stdio::piped());
    let child = cmd.spawn().unwrap();
    // Let the flight start, then kill the world.
    std::thread::sleep(Duration::from_millis(1500));
    world.0.kill().unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    let err = stderr.lines().last().unwrap_or_default();
    assert!(
        err.contains("closed the connection")
            || err.contains("Broken pipe")
            || err.contains("reset"),
        "{err}"
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(summary["completed"], false);
    assert!(summary["platform_time_s"].as_f64().unwrap() > 2.0);
}

/// The default platform with a battery that starts just above empty.
fn nearly_empty_platform(dir: &Path) -> std::path::PathBuf {
    let platform_file = repo_root().join("sim-core/platforms/crazyflie.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(platform_file).unwrap()).unwrap();
    let harvesters = json["peripherals"]["harvesters"].as_object_mut().unwrap();
    let battery = harvesters.values_mut().next().unwrap();
    battery["soc_init"] = serde_json::json!(0.5);
    battery["soc_end"] = serde_json::json!(0.0);
    let path = dir.join("platform.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    path
}

#[test]
fn an_emptying_battery_stops_the_run_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let path = nearly_empty_platform(dir.path());
    let _world = start_world(dir.path());
    let mut cmd = platform(dir.path(), "race");
    cmd.arg("--platform").arg(&path);
    let (err, summary) = failed_run(cmd, dir.path());
    assert!(err.contains("empty"), "{err}");
    assert!(summary["battery"]["soc_end"].as_f64().unwrap() <= 1e-9);
    assert!(summary["battery"]["empty_at_s"].as_f64().unwrap() > 0.0);
}

/// `battery_empty = "end"` (DESIGN.md §16, endurance runs): the cut-off
/// ends the flight as a firmware exit does: the world is told STOP, the
/// run succeeds, and summary.json says when the battery ran empty.
#[test]
fn with_battery_empty_end_the_cut_off_ends_the_flight_normally() {
    let dir = tempfile::tempdir().unwrap();
    let path = nearly_empty_platform(dir.path());
    let _world = start_world(dir.path());
    let mut cmd = platform(dir.path(), "race");
    cmd.arg("--platform")
        .arg(&path)
        .args(["--set", "battery_empty=end"]);
    let out = cmd.output().expect("run sim-core");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(summary["exit_code"], 0);
    assert!(summary["error"].is_null());
    let empty = summary["battery"]["empty_at_s"].as_f64().unwrap();
    let end = summary["platform_time_s"].as_f64().unwrap();
    // The race needs ~145 s; 0.5 % of 250 mAh lasts a few seconds.
    assert!(empty > 0.5 && empty < 20.0, "{empty}");
    // The run ends at the cut-off, plus the motors' spin-down after STOP
    // (1.3 s here, as at any firmware exit), not at the race's end.
    assert!(end > empty && end < empty + 2.0, "{end} vs {empty}");
    // The world was told STOP: its time is in the summary.
    assert!(summary["world_time_s"].as_f64().unwrap() > 0.0);
    // The cut-off falls on a 1 ms sample, inside a delay: the clocks are
    // settled before STOP, so the world estimate is exact (DESIGN.md §3).
    assert_eq!(summary["estimate_error_pct"].as_f64(), Some(0.0));
}
