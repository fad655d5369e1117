//! `cosim run` end to end on the short scenario (`scenarios/short-hop.toml`):
//! every output exists, parses and agrees with `summary.json`; a second run
//! gives byte-identical traces; the recorded world trace, replayed by
//! `world-server --replay`, gives the platform the same run; `cosim trace-check`
//! finds our world server identical to its own trace and finds a tampered
//! reply.

use std::path::Path;
use std::process::{Command, Stdio};

use e2e_tests::{assert_same_files, output_text as text, repo_root, summary, CosimBins as Bins};
use serde_json::Value;

/// The summary without the figures that depend on the machine's speed.
fn deterministic(mut s: Value) -> Value {
    let o = s.as_object_mut().unwrap();
    o.remove("wall_time_s");
    o.remove("realtime_factor");
    s
}

fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = e2e_tests::read_series(path);
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect::<Vec<_>>())
        .collect();
    (header, rows)
}

fn column(header: &[String], rows: &[Vec<String>], name: &str) -> Vec<f64> {
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    rows.iter().map(|r| r[i].parse::<f64>().unwrap()).collect()
}

fn trace_lines(path: &Path) -> Vec<Value> {
    // Either form (`world.trace` or `world.trace.zst`).
    e2e_tests::read_series(path)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn check_outputs(dir: &Path) {
    let s = summary(dir);
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["exit_code"], 0);
    assert_eq!(s["targets_total"], 1);
    assert_eq!(s["targets_reached"], 1);
    assert_eq!(s["timestep_ms"], 32);
    assert_eq!(s["battery"]["model"], "lipol250");
    assert_eq!(s["power_model"], "empirical");

    // power.csv: one row per simulated ms up to the platform's end, its
    // last SOC the summary's.
    let (h, rows) = csv_rows(&dir.join("power.csv"));
    let t = column(&h, &rows, "time_s");
    assert!(
        t.windows(2).all(|w| (w[1] - w[0] - 0.001).abs() < 1e-9),
        "1 ms rows"
    );
    let platform_time = s["platform_time_s"].as_f64().unwrap();
    assert!(
        (t.last().unwrap() - platform_time).abs() <= 0.001,
        "{} vs {platform_time}",
        t.last().unwrap()
    );
    let soc = column(&h, &rows, "soc");
    assert!((soc.last().unwrap() - s["battery"]["soc_end"].as_f64().unwrap()).abs() < 1e-6);
    assert!(soc.windows(2).all(|w| w[1] <= w[0]), "SOC never rises");

    // The three model files: same rows; the energy of each model, summed
    // from its 1 ms power samples, is the summary's.
    for (file, key) in [
        ("motor_empirical.csv", "empirical"),
        ("motor_dandrea.csv", "dandrea"),
        ("motor_stolaroff.csv", "stolaroff"),
    ] {
        let (mh, mrows) = csv_rows(&dir.join(file));
        assert_eq!(mrows.len(), rows.len(), "{file}");
        let energy: f64 = column(&mh, &mrows, "power_w").iter().sum::<f64>() * 0.001;
        let reported = s["energy_j"][key].as_f64().unwrap();
        assert!(
            (energy - reported).abs() <= 0.01 * reported.abs().max(1.0),
            "{file}: {energy} J from the CSV, {reported} J in summary.json"
        );
    }

    // trajectory.csv: one row per world step, ending at the world's STOP
    // time; after the 2000 ms warm-up every step is one 32 ms basicTimeStep.
    let (th, trows) = csv_rows(&dir.join("trajectory.csv"));
    let tms = column(&th, &trows, "time_ms");
    let stop_ms = (s["world_time_s"].as_f64().unwrap() * 1000.0).round();
    assert_eq!(*tms.last().unwrap(), stop_ms);
    assert!(tms.windows(2).all(|w| w[1] > w[0]));
    assert!(tms
        .iter()
        .filter(|t| **t >= 2000.0)
        .all(|t| (t - 2000.0) % 32.0 == 0.0));
    // It ends near the target (-2.6, 1.0), on the ground.
    let (x, y, z) = (
        column(&th, &trows, "x"),
        column(&th, &trows, "y"),
        column(&th, &trows, "z"),
    );
    let n = trows.len() - 1;
    assert!(
        (x[n] + 2.6).abs() < 0.2 && (y[n] - 1.0).abs() < 0.2 && z[n] < 0.1,
        "{} {} {}",
        x[n],
        y[n],
        z[n]
    );

    // The traces hold every message, with the byte counts of the summary
    // (which count the 4-byte length header of each frame too).
    for name in ["world.trace", "platform.trace"] {
        let lines = trace_lines(&dir.join(name));
        assert_eq!(
            lines.len() as u64,
            s["messages"].as_u64().unwrap(),
            "{name}"
        );
        let bytes = |d: &str| -> u64 {
            lines
                .iter()
                .filter(|l| l["dir"] == d)
                .map(|l| l["len"].as_u64().unwrap() + 4)
                .sum()
        };
        assert_eq!(
            bytes("to_world"),
            s["bytes_to_world"].as_u64().unwrap(),
            "{name}"
        );
        assert_eq!(
            bytes("to_platform"),
            s["bytes_to_platform"].as_u64().unwrap(),
            "{name}"
        );
    }
    let console = std::fs::read_to_string(dir.join("console.log")).unwrap();
    assert!(console.contains("reached!"), "{console}");
    for png in ["power_models.png", "battery.png", "top_view.png"] {
        let b = std::fs::read(dir.join(png)).unwrap();
        assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "{png}");
        assert!(b.len() > 10_000, "{png} is {} bytes", b.len());
    }
    let report = std::fs::read_to_string(dir.join("report.txt")).unwrap();
    assert!(
        report.contains("1/1 reached") && report.contains("top_view.png"),
        "{report}"
    );
}

#[test]
fn run_outputs_agree_repeat_bit_for_bit_and_replay() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a");
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--frames",
        "--quiet",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("completed") && stdout.contains("power_models.png"),
        "{stdout}"
    );
    check_outputs(&a);

    // Same scenario again: byte-identical traces and results.
    let second = tmp.path().join("b");
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--quiet",
        "--no-plots",
        "--out",
        second.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_same_files(
        &a,
        &second,
        &[
            "world.trace",
            "platform.trace",
            "power.csv",
            "trajectory.csv",
            "console.log",
        ],
        "between two runs",
    );
    assert_eq!(deterministic(summary(&a)), deterministic(summary(&second)));

    // Replay the world's trace (pixels from the frames) to a fresh sim-core,
    // with `world-server --replay` (the contract; `cosim replay` is the same).
    let c = tmp.path().join("c");
    let sock = tmp.path().join("replay.sock");
    let replay = Command::new(&b.world)
        .arg("--replay")
        .arg(a.join("world.trace"))
        .arg("--socket")
        .arg(&sock)
        .arg("--replay-frames")
        .arg(a.join("frames"))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    e2e_tests::wait_for_path(&sock, 20);
    let sim = Command::new(&b.sim_core)
        .arg("--socket")
        .arg(&sock)
        .arg("--firmware")
        .arg(repo_root().join("sim-core/firmware/bin/short.elf"))
        .arg("--out")
        .arg(&c)
        .arg("--trace")
        .arg(c.join("platform.trace"))
        .args(["--quiet", "--no-progress"])
        .output()
        .unwrap();
    let replay_out = replay.wait_with_output().unwrap();
    assert!(sim.status.success(), "{}", text(&sim));
    assert!(replay_out.status.success(), "{}", text(&replay_out));
    assert!(String::from_utf8_lossy(&replay_out.stderr).contains("all as recorded"));
    assert_eq!(deterministic(summary(&a)), deterministic(summary(&c)));
    assert!(
        e2e_tests::read_series(&a.join("platform.trace"))
            == e2e_tests::read_series(&c.join("platform.trace")),
        "the replayed run's platform trace differs from the recorded one"
    );

    // trace-check: our world server against its own trace.
    let world = repo_root().join("scenarios/worlds/empty.toml");
    let o = b.cosim(&[
        "trace-check",
        a.join("world.trace").to_str().unwrap(),
        "--world",
        world.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("replies compared"),
        "{}",
        text(&o)
    );

    // ... and against a trace with one altered altitude.
    let lines = e2e_tests::read_series(&a.join("world.trace"));
    let mut altered = String::new();
    let mut target_seq = None;
    for l in lines.lines() {
        let mut v: Value = serde_json::from_str(l).unwrap();
        if target_seq.is_none()
            && v["msg"]["command"] == "GET_SENSORS"
            && v["dir"] == "to_platform"
            && v["seq"].as_u64().unwrap() > 100
        {
            let alt = v["msg"]["ALTITUDE"].as_f64().unwrap();
            v["msg"]["ALTITUDE"] = serde_json::json!(alt + 0.01);
            target_seq = v["seq"].as_u64();
        }
        altered += &v.to_string();
        altered.push('\n');
    }
    let altered_path = tmp.path().join("altered.trace");
    std::fs::write(&altered_path, altered).unwrap();
    let o = b.cosim(&[
        "trace-check",
        altered_path.to_str().unwrap(),
        "--world",
        world.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(&format!("#{} (GET_SENSORS)", target_seq.unwrap()))
            && out.contains("ALTITUDE"),
        "{out}"
    );

    // trace show lists the frames and the totals.
    let o = b.cosim(&[
        "trace",
        "show",
        a.join("platform.trace").to_str().unwrap(),
        "--command",
        "STOP",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("STOP_TIME=") && out.contains("GET_IMAGE"),
        "{out}"
    );
}

#[test]
fn bad_input_is_one_clear_line() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &["run", "no-such-scenario"],
            "scenario no-such-scenario does not exist; `cosim list` lists the scenarios",
        ),
        (&["run", "short-hop", "--set", "battery=nine"], "battery"),
        (
            &["run", "short-hop", "--set", "wings=2"],
            "unknown key \"wings\"",
        ),
        (
            &["run", "short-hop", "--set", "timestep_ms=fast"],
            "timestep_ms",
        ),
    ];
    for (args, needle) in cases {
        let o = b.cosim(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    }
    // A scenario naming a missing world file, and one with an unknown key.
    let s = tmp.path().join("bad.toml");
    std::fs::write(&s, "world = \"nowhere.toml\"\nfirmware = \"x.elf\"\n").unwrap();
    let o = b.cosim(&["run", s.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("world file"),
        "{}",
        text(&o)
    );
    std::fs::write(
        &s,
        "world = \"w.toml\"\nfirmware = \"x.elf\"\nwingspan = 3\n",
    )
    .unwrap();
    let o = b.cosim(&["run", s.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("wingspan"),
        "{}",
        text(&o)
    );
}

#[test]
fn a_failed_run_is_a_row_of_the_sweep() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sweep");
    // max_time_s = 3 stops the platform long before the landing: a failed
    // run with partial outputs, next to a complete one.
    let o = b.cosim(&[
        "sweep",
        "short-hop",
        "--param",
        "max_time_s=3,100",
        "--jobs",
        "2",
        "--no-trace",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let (h, rows) = csv_rows(&out.join("sweep.csv"));
    assert_eq!(rows.len(), 2, "{rows:?}");
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    assert_eq!(rows[0][col("max_time_s")], "3");
    assert_eq!(rows[0][col("status")], "failed");
    assert!(!rows[0][col("error")].is_empty());
    assert_eq!(rows[1][col("status")], "ok", "{:?}", rows[1]);
    assert_eq!(rows[1][col("targets_reached")], "1");
    let md = std::fs::read_to_string(out.join("sweep.md")).unwrap();
    assert!(md.contains("| failed |") && md.contains("| ok |"), "{md}");
    assert!(out.join("sweep_soc.png").is_file());
    // The failed run's partial outputs are kept.
    let failed_dir = out.join("run-001_max_time_s=3");
    assert!(
        e2e_tests::series_file(&failed_dir.join("power.csv")).is_file()
            && failed_dir.join("cosim.log").is_file()
    );
}

#[test]
fn list_shows_every_scenario_file_and_nothing_else() {
    let b = Bins::new();
    let out = Command::new(&b.cosim)
        .arg("list")
        .current_dir(repo_root())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let listing = text(&out);
    assert!(!listing.contains("invalid"), "{listing}");
    let dir = repo_root().join("scenarios");
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if let Some(stem) = name.strip_suffix(".toml").filter(|_| name != "Cargo.toml") {
            assert!(
                listing.lines().any(|l| l.starts_with(stem)),
                "{stem} missing from:\n{listing}"
            );
        }
    }
}
