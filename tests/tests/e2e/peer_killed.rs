//! A world killed mid-run (`kill -9`) leaves its `trajectory.csv` cut short
//! (a torn last row; compressed, a zstd frame without its end): `cosim run`
//! still reads what it holds, writes the report and the plots, says in the
//! report how much was dropped, and exits non-zero.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use e2e_tests::{output_text as text, CosimBins as Bins};

/// The pid of the world-server writing its trajectory to `trajectory`.
fn world_pid(trajectory: &Path) -> Option<u32> {
    e2e_tests::processes()
        .into_iter()
        .find(|p| p.has_path_arg("--trajectory", trajectory))
        .map(|p| p.pid)
}

/// Runs hover-endurance into `out`, kills its world once `trajectory` (the
/// world's file) holds `min_bytes`, and returns cosim's report text.
fn kill_world_mid_run(b: &Bins, out: &Path, trajectory: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "run",
        "hover-endurance",
        "--quiet",
        "--no-mcap",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let mut child = b
        .command(&args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // A few world steps' rows are on the disk: the drone is flying.
    let until = Instant::now() + Duration::from_secs(300);
    let pid = loop {
        assert!(Instant::now() < until, "the run never got going");
        assert!(
            child.try_wait().unwrap().is_none(),
            "cosim ended before the kill"
        );
        let written = std::fs::metadata(trajectory).map_or(0, |m| m.len());
        if written > 20_000 {
            if let Some(pid) = world_pid(trajectory) {
                break pid;
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    // SAFETY: kill(2) on a pid we found running our world-server.
    assert_eq!(unsafe { libc::kill(pid as i32, libc::SIGKILL) }, 0);
    let o = child.wait_with_output().unwrap();
    assert_ne!(o.status.code(), Some(0), "{}", text(&o));
    for png in ["power_models.png", "battery.png", "top_view.png"] {
        assert!(out.join(png).is_file(), "{png} missing\n{}", text(&o));
    }
    let report = std::fs::read_to_string(out.join("report.txt")).unwrap();
    assert!(report.contains("FAILED"), "{report}");
    // The report's summary is the one printed.
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(report.lines().next().unwrap()),
        "{}",
        text(&o)
    );
    report
}

/// The rows the report says it kept of `file` ("kept N rows").
fn kept_rows(report: &str, file: &Path) -> usize {
    let line = report
        .lines()
        .find(|l| l.contains("dropped") && l.contains(&*file.to_string_lossy()))
        .unwrap_or_else(|| panic!("no dropped line for {}:\n{report}", file.display()));
    let n = line
        .split("kept ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap();
    n.parse().unwrap()
}

#[test]
fn a_world_killed_mid_run_still_gives_the_report_and_plots() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();

    // Compressed (the default): the blocks that reached the disk.
    let out = tmp.path().join("zst");
    let file: PathBuf = out.join("trajectory.csv.zst");
    let report = kill_world_mid_run(&b, &out, &file, &[]);
    let read = protocol::series::read(&file).unwrap();
    assert!(read.torn.is_some());
    let rows = read.bytes.iter().filter(|&&c| c == b'\n').count() - 1;
    assert!(rows > 100, "{rows} rows");
    assert_eq!(kept_rows(&report, &file), rows);
    assert!(report.contains("zstd frame is incomplete"), "{report}");

    // Plain CSV: a torn last row, dropped and counted.
    let out = tmp.path().join("plain");
    let file: PathBuf = out.join("trajectory.csv");
    let report = kill_world_mid_run(&b, &out, &file, &["--set", "output.compress=false"]);
    let text = std::fs::read_to_string(&file).unwrap();
    // Every line that has its end, the header's included.
    let whole = text.matches('\n').count();
    assert_eq!(kept_rows(&report, &file), whole - 1);
    if !text.ends_with('\n') {
        assert!(report.contains("torn last row"), "{report}");
    }
}
