//! `cosim run` with several drones (DESIGN.md §7, docs/SWARM.md §5,
//! docs/COSIM.md "Several drones"), end to end with the real processes:
//! `swarm-ping` (two carried drones ranging each other with
//! `radio_ping.elf`) writes every platform's outputs in its folder, a
//! summary with a `drones` map, a radio log, the report's measured against
//! true distance, and the same world trace twice; bad `[[platform]]` tables
//! are one-line errors before anything starts; a platform killed mid-run
//! ends the run non-zero with the outputs written so far flushed.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::{assert_same_files, output_text as text, repo_root, CosimBins as Bins};
use serde_json::Value;

fn json(path: &Path) -> Value {
    let t = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&t).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
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

fn col(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// Every line of a trace is one complete JSON object.
fn trace_lines(path: &Path) -> Vec<Value> {
    // Either form (`world.trace` or `world.trace.zst`).
    e2e_tests::read_series(path)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{}: {e}: {l}", path.display())))
        .collect()
}

fn is_png(path: &Path) {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "{}", path.display());
}

/// One platform's outputs (DESIGN.md §6) in its folder, consistent with
/// its summary.
fn check_platform(dir: &Path, s: &Value) {
    assert_eq!(s["completed"], true, "{}: {s}", dir.display());
    for f in [
        "summary.json",
        "power.csv",
        "motor_empirical.csv",
        "motor_dandrea.csv",
        "motor_stolaroff.csv",
        "console.log",
        "run.toml",
        "report.txt",
        "trajectory.csv",
    ] {
        let p = e2e_tests::series_file(&dir.join(f));
        assert!(p.is_file(), "{} missing", p.display());
    }
    assert_eq!(&json(&dir.join("summary.json")), s);
    // The platform's trace has every frame it exchanged.
    let lines = trace_lines(&dir.join("platform.trace"));
    assert_eq!(lines.len() as u64, s["messages"].as_u64().unwrap());
    assert_eq!(
        lines[0]["msg"]["command"],
        "GET_INIT_DATA",
        "{}",
        dir.display()
    );
    // Its trajectory: its rows of the world's, without the drone column.
    let (h, rows) = csv_rows(&dir.join("trajectory.csv"));
    assert!(!h.contains(&"drone".to_string()), "{h:?}");
    assert_eq!(h[0], "time_ms");
    assert!(!rows.is_empty());
    let stop_ms = (s["world_time_s"].as_f64().unwrap() * 1000.0).round();
    let last: f64 = rows.last().unwrap()[0].parse().unwrap();
    assert!(last >= stop_ms, "{last} < {stop_ms}");
    for png in ["power_models.png", "battery.png", "top_view.png"] {
        is_png(&dir.join(png));
    }
}

#[test]
fn swarm_ping_runs_end_to_end_and_repeats_bit_for_bit() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str| -> PathBuf {
        let out = tmp.path().join(name);
        let o = b.cosim(&[
            "run",
            "swarm-ping",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        out
    };
    let a = run("a");
    let s = json(&a.join("summary.json"));
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["scenario"], "swarm-ping");
    assert_eq!(s["world_exit_code"], 0);
    assert_eq!(s["platforms"], serde_json::json!(["A", "B"]));
    let drones = s["drones"].as_object().unwrap();
    assert_eq!(drones.keys().collect::<Vec<_>>(), ["A", "B"]);
    let mut messages = 0;
    for (name, d) in drones {
        check_platform(&a.join(name), d);
        messages += d["messages"].as_u64().unwrap();
        assert_eq!(s["platform_exit_codes"][name], 0);
    }
    assert_eq!(s["messages"].as_u64().unwrap(), messages);
    assert!(s["wall_time_s"].as_f64().unwrap() > 0.0);
    assert!(s["realtime_factor"].as_f64().unwrap() > 0.0);

    // The world's trajectory: one row per drone per step, the drone second.
    let (h, rows) = csv_rows(&a.join("trajectory.csv"));
    assert_eq!(h[1], "drone");
    for d in ["A", "B"] {
        let own = rows.iter().filter(|r| r[1] == d).count();
        let (_, split) = csv_rows(&a.join(d).join("trajectory.csv"));
        assert_eq!(own, split.len(), "{d}");
    }
    // The drones stay on the table, 1.5 m apart.
    let (x, y) = (col(&h, "x"), col(&h, "y"));
    for r in &rows {
        let want = if r[1] == "A" { 0.0 } else { 1.5 };
        let (rx, ry): (f64, f64) = (r[x].parse().unwrap(), r[y].parse().unwrap());
        assert!((rx - want).abs() < 1e-9 && ry.abs() < 1e-9, "{r:?}");
    }

    // Frames went both ways; the summary counts the radio log's rows.
    let (rh, rrows) = csv_rows(&a.join("radio.csv"));
    let (from, to, outcome) = (col(&rh, "from"), col(&rh, "to"), col(&rh, "outcome"));
    let received = |f: &str, t: &str| {
        rrows
            .iter()
            .filter(|r| r[from] == f && r[to] == t && r[outcome] == "received")
            .count() as u64
    };
    assert!(received("A", "B") > 0 && received("B", "A") > 0);
    assert_eq!(s["radio"]["rows"].as_u64().unwrap(), rrows.len() as u64);
    assert_eq!(
        s["radio"]["links"]["A->B"].as_u64().unwrap(),
        received("A", "B")
    );
    assert_eq!(
        s["radio"]["links"]["B->A"].as_u64().unwrap(),
        received("B", "A")
    );

    // The report sets the measured distances against the true 1.5 m.
    let ranging = s["ranging"].as_array().unwrap();
    assert!(!ranging.is_empty(), "no distances in the consoles: {s}");
    for r in ranging {
        assert!((r["true_m"].as_f64().unwrap() - 1.5).abs() < 1e-9, "{r}");
        let m = r["measured_mean_m"].as_f64().unwrap();
        // 5 cm of ranging noise per stamp (the world file): the mean of a
        // few rounds is within 10 cm.
        assert!((m - 1.5).abs() < 0.1, "{r}");
        assert!(r["count"].as_u64().unwrap() > 0);
    }
    // cosim numbered the radios in [[platform]] order.
    for (d, id, peer) in [("A", 1, 2), ("B", 2, 1)] {
        let run = std::fs::read_to_string(a.join(d).join("run.toml")).unwrap();
        assert!(run.contains(&format!("radio_id = {id}")), "{run}");
        let console = std::fs::read_to_string(a.join(d).join("console.log")).unwrap();
        assert!(
            console.contains(&format!("EUI {id}, peer {peer}")),
            "{console}"
        );
    }
    let report = std::fs::read_to_string(a.join("report.txt")).unwrap();
    assert!(
        report.contains("ranging") && report.contains("true 1.500 m"),
        "{report}"
    );
    assert!(
        report.lines().any(|l| l.trim_start().starts_with("A ")),
        "{report}"
    );
    is_png(&a.join("top_view.png"));

    // The world's trace names the drone on every line; a second run gives
    // the same world trace and the same platform traces, byte for byte.
    let lines = trace_lines(&a.join("world.trace"));
    assert!(lines.iter().all(|l| l["drone"] == "A" || l["drone"] == "B"));
    let again = run("b");
    assert_same_files(
        &a,
        &again,
        &[
            "world.trace",
            "A/platform.trace",
            "B/platform.trace",
            "radio.csv",
            "trajectory.csv",
        ],
        "between two runs",
    );

    // The recorded world trace agrees with a live world, drone by drone.
    let world = repo_root().join("scenarios/worlds/swarm-ping.toml");
    let o = b.cosim(&[
        "trace-check",
        a.join("world.trace").to_str().unwrap(),
        "--world",
        world.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    // Without --world it says what is missing.
    let o = b.cosim(&["trace-check", a.join("world.trace").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--world"));
}

/// A drone's summary without the figures that depend on the machine's speed.
fn deterministic(mut s: Value) -> Value {
    let o = s.as_object_mut().unwrap();
    o.remove("wall_time_s");
    o.remove("realtime_factor");
    s
}

#[test]
fn two_hovering_drones_repeat_replay_check_and_sweep() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a");
    let o = b.cosim(&[
        "run",
        "swarm-hover-2",
        "--quiet",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s = json(&a.join("summary.json"));
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["platforms"], serde_json::json!(["d1", "d2"]));
    let mut instructions = 0;
    for d in ["d1", "d2"] {
        let ds = &s["drones"][d];
        check_platform(&a.join(d), ds);
        // Held 60 s of platform time after the take-off, then landed.
        let console = std::fs::read_to_string(a.join(d).join("console.log")).unwrap();
        assert!(console.contains("Held for 60000 ms"), "{console}");
        assert!(ds["world_time_s"].as_f64().unwrap() > 62.0, "{ds}");
        instructions += ds["instructions"].as_u64().unwrap();
    }
    assert_eq!(s["instructions"].as_u64().unwrap(), instructions);
    assert_eq!(s["collisions"], 0);
    // What a table built from run directories reads back (sweeps merged
    // from shards).
    let top = std::fs::read(a.join("summary.json")).unwrap();
    assert!(scenarios::swarm::is_swarm_summary(&top));
    assert!(!scenarios::swarm::is_swarm_summary(
        &std::fs::read(a.join("d1/summary.json")).unwrap()
    ));
    let back = scenarios::swarm::read_drones(&a);
    let names: Vec<&str> = back.iter().map(|d| d.drone.as_str()).collect();
    assert_eq!(names, ["d1", "d2"]);
    for d in &back {
        assert!(d.summary.as_ref().is_some_and(|s| s.completed));
        assert_eq!(d.exit_code, Some(0));
        assert_eq!(d.plots.len(), 3);
        assert_eq!(d.raw.as_ref(), Some(&s["drones"][&d.drone]));
    }
    // Each drone holds its own start point, 1.5 m from the other's.
    let (h, rows) = csv_rows(&a.join("trajectory.csv"));
    let (x, z) = (col(&h, "x"), col(&h, "z"));
    for r in rows.iter().filter(|r| r[z].parse::<f64>().unwrap() > 0.9) {
        let want = if r[1] == "d1" { 0.0 } else { 1.5 };
        assert!((r[x].parse::<f64>().unwrap() - want).abs() < 0.2, "{r:?}");
    }
    is_png(&a.join("top_view.png"));

    // Twice the same run, byte for byte.
    let second = tmp.path().join("b");
    let o = b.cosim(&[
        "run",
        "swarm-hover-2",
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
            "trajectory.csv",
            "d1/platform.trace",
            "d2/platform.trace",
            "d1/power.csv",
        ],
        "between two runs",
    );
    for d in ["d1", "d2"] {
        assert_eq!(
            deterministic(json(&a.join(d).join("summary.json"))),
            deterministic(json(&second.join(d).join("summary.json")))
        );
    }

    // One drone's frames of the world trace replayed to a lone platform:
    // the same platform trace and summary, without the other drone.
    let c = tmp.path().join("c");
    let sock = tmp.path().join("replay.sock");
    let replay = b
        .command(&[
            "replay",
            a.join("world.trace").to_str().unwrap(),
            "--drone",
            "d2",
            "--socket",
            sock.to_str().unwrap(),
        ])
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    e2e_tests::wait_for_path(&sock, 20);
    let sim = Command::new(&b.sim_core)
        .arg("--socket")
        .arg(&sock)
        .args(["--drone", "d2", "--firmware"])
        .arg(repo_root().join("sim-core/firmware/bin/hover_hold.elf"))
        .arg("--config")
        .arg(a.join("d2/run.toml"))
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
    assert!(
        e2e_tests::read_series(&a.join("d2/platform.trace"))
            == e2e_tests::read_series(&c.join("platform.trace")),
        "the replayed platform trace differs from the recorded one"
    );
    assert_eq!(
        deterministic(json(&a.join("d2/summary.json"))),
        deterministic(json(&c.join("summary.json")))
    );
    // Without --drone, replay says which drones the trace has.
    let o = b.cosim(&[
        "replay",
        a.join("world.trace").to_str().unwrap(),
        "--socket",
        tmp.path().join("x.sock").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("d1, d2"));

    // A live world agrees with the recorded trace, drone by drone...
    let world = repo_root().join("scenarios/worlds/swarm-hover-2.toml");
    let check = |trace: &Path| {
        b.cosim(&[
            "trace-check",
            trace.to_str().unwrap(),
            "--world",
            world.to_str().unwrap(),
        ])
    };
    let o = check(&a.join("world.trace"));
    assert!(o.status.success(), "{}", text(&o));
    // ... and finds one altered reply of d2.
    let mut altered = String::new();
    let mut target = None;
    for l in e2e_tests::read_series(&a.join("world.trace")).lines() {
        let mut v: Value = serde_json::from_str(l).unwrap();
        if target.is_none()
            && v["drone"] == "d2"
            && v["dir"] == "to_platform"
            && v["msg"]["command"] == "GET_SENSORS"
            && v["seq"].as_u64().unwrap() > 1000
        {
            let alt = v["msg"]["ALTITUDE"].as_f64().unwrap();
            v["msg"]["ALTITUDE"] = serde_json::json!(alt + 0.01);
            target = v["seq"].as_u64();
        }
        altered += &v.to_string();
        altered.push('\n');
    }
    let altered_path = tmp.path().join("altered.trace");
    std::fs::write(&altered_path, altered).unwrap();
    let o = check(&altered_path);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(&format!("#{} (GET_SENSORS of d2)", target.unwrap()))
            && out.contains("ALTITUDE"),
        "{out}"
    );

    // A sweep of one platform's key: a row per drone and run.
    let sw = tmp.path().join("sweep");
    let o = b.cosim(&[
        "sweep",
        "swarm-hover-2",
        "--param",
        "d2.battery=lipol250,ufx250",
        "--param",
        "power_model=stolaroff",
        "--out",
        sw.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let (h, rows) = csv_rows(&sw.join("sweep.csv"));
    assert_eq!(h[1..4], ["d2.battery", "power_model", "drone"]);
    let drones: Vec<&str> = rows.iter().map(|r| r[3].as_str()).collect();
    assert_eq!(drones, ["d1", "d2", "d1", "d2"]);
    let soc = col(&h, "soc_end_pct");
    let status = col(&h, "status");
    assert!(rows.iter().all(|r| r[status] == "ok"), "{rows:?}");
    // Only d2's battery changed: d1 discharges the same in both runs, d2
    // does not (Stolaroff: the battery's mass matters, thesis §5.4).
    assert_eq!(rows[0][soc], rows[2][soc]);
    assert_ne!(rows[1][soc], rows[3][soc]);
}

/// A scenario file next to the shipped worlds, in a temporary directory.
fn scenario(dir: &Path, body: &str) -> PathBuf {
    let p = dir.join("s.toml");
    let worlds = repo_root().join("scenarios/worlds");
    let fw = repo_root().join("sim-core/firmware/bin");
    let text = body
        .replace("WORLDS", worlds.to_str().unwrap())
        .replace("FW", fw.to_str().unwrap());
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn bad_platform_tables_are_one_line_errors_before_anything_starts() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let cases = [
        (
            "unknown drone",
            r#"
            world = "WORLDS/swarm-hover-2.toml"
            firmware = "FW/hover_hold.elf"
            [[platform]]
            drone = "d1"
            [[platform]]
            drone = "zz"
            "#,
            vec!["\"zz\"", "no such drone", "d1, d2"],
        ),
        (
            "missing firmware",
            r#"
            world = "WORLDS/swarm-hover-2.toml"
            firmware = "FW/hover_hold.elf"
            [[platform]]
            drone = "d1"
            [[platform]]
            drone = "d2"
            firmware = "FW/no-such.elf"
            "#,
            vec!["\"d2\"", "no-such.elf", "does not exist"],
        ),
        (
            "a drone without a platform",
            r#"
            world = "WORLDS/swarm-hover-2.toml"
            firmware = "FW/hover_hold.elf"
            [[platform]]
            drone = "d1"
            "#,
            vec!["without a [[platform]]: d2"],
        ),
    ];
    for (what, body, needles) in cases {
        let s = scenario(tmp.path(), body);
        let out = tmp.path().join("out");
        let o = b.cosim(&["run", s.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{what}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{what}: {err}");
        for n in needles {
            assert!(lines[0].contains(n), "{what}: {n:?} not in {err}");
        }
        assert!(!out.exists(), "{what}: something was started");
    }
    // A per-platform override of an unknown platform or key is refused too.
    let o = b.cosim(&["run", "swarm-hover-2", "--set", "d3.battery=ufx250"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("d3.battery"));
}

/// The pid of the sim-core flying `drone` whose outputs go under `out`.
fn platform_pid(out: &Path, drone: &str) -> Option<u32> {
    e2e_tests::processes()
        .into_iter()
        .find(|p| p.has_arg("--drone", drone) && p.has_path_arg("--out", &out.join(drone)))
        .map(|p| p.pid)
}

#[test]
fn killing_one_platform_ends_the_run_with_the_outputs_flushed() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    // Two drones hovering 60 s at 4 ms: long enough to be killed mid-run.
    let mut child = b
        .command(&[
            "run",
            "swarm-hover-2",
            "--quiet",
            "--no-plots",
            "--set",
            "timestep_ms=4",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until both drones fly (d2 has exchanged a few thousand frames),
    // then kill d2's sim-core.
    let trace = out.join("world.trace");
    let until = Instant::now() + Duration::from_secs(120);
    let pid = loop {
        assert!(Instant::now() < until, "the run never got going");
        assert!(
            child.try_wait().unwrap().is_none(),
            "cosim ended before the kill"
        );
        // The trace being written: the part that reached the disk.
        let flying = protocol::series::read(&trace)
            .map(|t| {
                String::from_utf8_lossy(&t.bytes)
                    .lines()
                    .filter(|l| l.contains("\"drone\":\"d2\""))
                    .count()
                    > 2000
            })
            .unwrap_or(false);
        if flying {
            if let Some(pid) = platform_pid(&out, "d2") {
                break pid;
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let st = Command::new("kill")
        .args(["-9", &pid.to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let started = Instant::now();
    let o = child.wait_with_output().unwrap();
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "the run took {:?} to end after the kill",
        started.elapsed()
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let s = json(&out.join("summary.json"));
    assert_eq!(s["completed"], false);
    let err = s["error"].as_str().unwrap();
    assert!(
        err.contains("platform d2") && err.contains("SIGKILL"),
        "{err}"
    );
    assert_eq!(s["platform_exit_codes"]["d2"], Value::Null);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("platform d2"),
        "{}",
        text(&o)
    );
    // What was written is there and whole: the world's trace and
    // trajectory, and d1's outputs (it was told by the world and stopped).
    let lines = trace_lines(&trace);
    assert!(lines.len() > 2000);
    let (_, rows) = csv_rows(&out.join("trajectory.csv"));
    assert!(!rows.is_empty());
    let d1 = json(&out.join("d1/summary.json"));
    assert_eq!(d1["completed"], false, "{d1}");
    assert!(d1["error"].is_string(), "{d1}");
    assert!(!trace_lines(&out.join("d1/platform.trace")).is_empty());
    assert!(e2e_tests::series_file(&out.join("d1/power.csv")).is_file());
}
