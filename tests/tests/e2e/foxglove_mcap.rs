//! `run.mcap` (DESIGN.md §15, docs/FOXGLOVE.md), end to end with the real
//! binaries: a short flight through the thesis's course writes a complete
//! MCAP file with Foxglove's schemas — one transform per drone per world
//! step (the trajectory's rows), the course as a scene, decodable 320×320
//! mono8 camera frames, the platform's power and battery — log times in
//! world time and in order; two runs give the same bytes; `--no-mcap`
//! writes none and changes no other output; a swarm run shows every drone
//! and its radio links; a world file cut short (a world that died) still
//! merges into a complete file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use e2e_tests::{assert_same_files, output_text as text, repo_root, summary, CosimBins as Bins};
use serde_json::Value;

/// Every message of a file: (topic, schema name, log time, JSON).
fn messages(path: &Path) -> Vec<(String, String, u64, Value)> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            assert_eq!(m.log_time, m.publish_time, "publish time = log time");
            let schema = m.channel.schema.as_ref().unwrap();
            assert_eq!(schema.encoding, "jsonschema");
            assert_eq!(m.channel.message_encoding, "json");
            (
                m.channel.topic.clone(),
                schema.name.clone(),
                m.log_time,
                serde_json::from_slice(&m.data).unwrap(),
            )
        })
        .collect()
}

/// The file has a summary whose statistics count `n` messages.
fn assert_complete(path: &Path, n: usize) {
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("a summary section");
    let stats = summary.stats.expect("statistics");
    assert_eq!(stats.message_count as usize, n);
}

fn run(b: &Bins, out: &Path, extra: &[&str]) {
    let course = repo_root().join("scenarios/worlds/thesis-course.toml");
    let mut args = vec![
        "run",
        "short-hop",
        "--quiet",
        "--no-plots",
        "--no-trace",
        "--world",
        course.to_str().unwrap(),
        "--set",
        "mcap_image_every=10",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = b.cosim(&args);
    assert!(o.status.success(), "{}", text(&o));
}

fn trajectory_times(path: &Path, drone: Option<&str>) -> Vec<u64> {
    let text = e2e_tests::read_series(path);
    let mut r = csv::Reader::from_reader(text.as_bytes());
    r.records()
        .map(|rec| rec.unwrap())
        .filter(|rec| drone.is_none_or(|d| &rec[1] == d))
        .map(|rec| rec[0].parse::<u64>().unwrap())
        .collect()
}

#[test]
fn a_flight_writes_a_complete_run_mcap_the_same_twice_and_none_with_no_mcap() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let (a, a2, none) = (
        tmp.path().join("a"),
        tmp.path().join("a2"),
        tmp.path().join("none"),
    );
    run(&b, &a, &[]);
    let mcap_path = a.join("run.mcap");
    assert!(
        !a.join("world.mcap").exists(),
        "the world's half is merged and removed"
    );
    let msgs = messages(&mcap_path);
    assert_complete(&mcap_path, msgs.len());

    let schemas: BTreeMap<&str, &str> = msgs.iter().map(|m| (m.0.as_str(), m.1.as_str())).collect();
    for (topic, schema) in [
        ("/tf", "foxglove.FrameTransform"),
        ("/scene", "foxglove.SceneUpdate"),
        ("/cf1/camera", "foxglove.RawImage"),
        ("/cf1/motors", "cosim.Motors"),
        ("/cf1/power", "cosim.Power"),
        ("/cf1/battery", "cosim.Battery"),
    ] {
        assert_eq!(schemas.get(topic), Some(&schema), "{topic}: {schemas:?}");
    }
    // Log times: world time, in order.
    assert!(
        msgs.windows(2).all(|w| w[0].2 <= w[1].2),
        "log times in order"
    );

    // One transform per world step: the trajectory's rows, at their times.
    let steps = trajectory_times(&a.join("trajectory.csv"), None);
    let tf: Vec<&(String, String, u64, Value)> = msgs.iter().filter(|m| m.0 == "/tf").collect();
    assert_eq!(tf.len(), steps.len());
    for (m, t_ms) in tf.iter().zip(&steps) {
        assert_eq!(m.2, t_ms * 1_000_000);
        assert_eq!(m.3["parent_frame_id"], "world");
        assert_eq!(m.3["child_frame_id"], "cf1");
        let ns = m.3["timestamp"]["sec"].as_u64().unwrap() * 1_000_000_000
            + m.3["timestamp"]["nsec"].as_u64().unwrap();
        assert_eq!(ns, m.2);
    }
    // The last pose is the trajectory's last position.
    let traj = e2e_tests::read_series(&a.join("trajectory.csv"));
    let mut r = csv::Reader::from_reader(traj.as_bytes());
    let last = r.records().last().unwrap().unwrap();
    let x: f64 = last[1].parse().unwrap();
    assert_eq!(
        tf.last().unwrap().3["translation"]["x"].as_f64().unwrap(),
        x
    );

    // The scene: the course's ten gates, at t = 0.
    let scene = msgs.iter().find(|m| m.0 == "/scene").unwrap();
    assert_eq!(scene.2, 0);
    let cubes = scene.3["entities"][0]["cubes"].as_array().unwrap();
    assert!(cubes.len() >= 10 * 4, "4 bars a gate: {}", cubes.len());

    // Camera frames: 320×320 mono8 that decode.
    let images: Vec<_> = msgs.iter().filter(|m| m.0 == "/cf1/camera").collect();
    assert!(!images.is_empty());
    for m in &images {
        assert_eq!(
            (m.3["width"].as_u64(), m.3["height"].as_u64()),
            (Some(320), Some(320))
        );
        assert_eq!(m.3["encoding"], "mono8");
        assert_eq!(m.3["step"], 320);
        let px = base64::engine::general_purpose::STANDARD
            .decode(m.3["data"].as_str().unwrap())
            .unwrap();
        assert_eq!(px.len(), 320 * 320);
        assert!(
            px.iter().any(|&p| p != px[0]),
            "a rendered view, not a blank"
        );
    }

    // Power and battery: rows 0, 10, 20, … of power.csv (the default
    // mcap_power_every) and its last, in order (their world times:
    // mcap_time_base.rs); the last SOC the summary's.
    let t_ps: Vec<u64> =
        csv::Reader::from_reader(e2e_tests::read_series(&a.join("power.csv")).as_bytes())
            .deserialize::<std::collections::HashMap<String, String>>()
            .map(|r| r.unwrap()["t_ps"].parse().unwrap())
            .collect();
    let kept: Vec<u64> = t_ps
        .iter()
        .enumerate()
        .filter(|(i, _)| i % 10 == 0 || *i == t_ps.len() - 1)
        .map(|(_, t)| t / 1000)
        .collect();
    assert!(kept.len() * 9 < t_ps.len(), "thinned");
    let battery: Vec<_> = msgs.iter().filter(|m| m.0 == "/cf1/battery").collect();
    assert_eq!(battery.len(), kept.len());
    let power: Vec<_> = msgs.iter().filter(|m| m.0 == "/cf1/power").collect();
    // The power channel keeps power.csv's own time_s (platform time).
    let power_rows: Vec<u64> = power
        .iter()
        .map(|m| (m.3["time_s"].as_f64().unwrap() * 1e9).round() as u64)
        .collect();
    assert_eq!(power_rows, kept, "the rows kept");
    let soc_end = summary(&a)["battery"]["soc_end"].as_f64().unwrap();
    assert!((battery.last().unwrap().3["soc"].as_f64().unwrap() - soc_end).abs() < 1e-6);
    assert!(battery[0].3["voltage_v"].as_f64().unwrap() > 3.0);

    check_cut_world_file_merges(&a, tmp.path());

    // Deterministic: the same bytes again.
    run(&b, &a2, &[]);
    assert!(
        std::fs::read(&mcap_path).unwrap() == std::fs::read(a2.join("run.mcap")).unwrap(),
        "run.mcap differs between two runs"
    );

    // --no-mcap: no file, and the other outputs are those of the run with one.
    run(&b, &none, &["--no-mcap"]);
    assert!(!none.join("run.mcap").exists() && !none.join("world.mcap").exists());
    assert_same_files(
        &a,
        &none,
        &[
            "trajectory.csv",
            "power.csv",
            "motor_empirical.csv",
            "console.log",
        ],
        "with and without run.mcap",
    );
}

#[test]
fn a_swarm_run_shows_every_drone_and_its_radio_links() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ping");
    let o = b.cosim(&[
        "run",
        "swarm-ping",
        "--quiet",
        "--no-plots",
        "--no-trace",
        "--set",
        "max_time_s=3",
        "--out",
        out.to_str().unwrap(),
    ]);
    // A run cut by max_time_s may report itself incomplete; its outputs
    // are what this test reads.
    let path = out.join("run.mcap");
    assert!(path.exists(), "{}", text(&o));
    let msgs = messages(&path);
    assert_complete(&path, msgs.len());
    assert!(
        msgs.windows(2).all(|w| w[0].2 <= w[1].2),
        "log times in order"
    );
    for d in ["A", "B"] {
        let steps = trajectory_times(&out.join("trajectory.csv"), Some(d));
        let tf = msgs
            .iter()
            .filter(|m| m.0 == "/tf" && m.3["child_frame_id"] == d)
            .count();
        assert_eq!(tf, steps.len(), "drone {d}");
        assert!(msgs.iter().any(|m| m.0 == format!("/{d}/battery")));
    }
    // Every received frame of the radio log is a packet and a link line.
    let mut r = csv::Reader::from_path(out.join("radio.csv")).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    let received = rows.iter().filter(|r| &r[7] == "received").count();
    assert!(received > 0, "the drones ranged each other");
    let packets: Vec<_> = msgs.iter().filter(|m| m.0 == "/radio/packets").collect();
    assert_eq!(packets.len(), rows.len());
    let links: Vec<_> = msgs.iter().filter(|m| m.0 == "/radio/links").collect();
    assert_eq!(links.len(), received);
    let line = &links[0].3["entities"][0]["lines"][0];
    assert_eq!(line["points"].as_array().unwrap().len(), 2);
    // The drones are 1.5 m apart on the table (scenarios/worlds/swarm-ping.toml).
    let p = |i: usize| {
        let q = &line["points"][i];
        [
            q["x"].as_f64().unwrap(),
            q["y"].as_f64().unwrap(),
            q["z"].as_f64().unwrap(),
        ]
    };
    let (a, c) = (p(0), p(1));
    let d = ((a[0] - c[0]).powi(2) + (a[1] - c[1]).powi(2) + (a[2] - c[2]).powi(2)).sqrt();
    assert!((d - 1.5).abs() < 0.05, "link length {d}");
}

/// A world file cut short (a world killed mid-run) still merges into a
/// complete run.mcap with what was written.
fn check_cut_world_file_merges(a: &Path, tmp: &Path) {
    // The run's file cut in the middle stands for a world killed mid-run.
    let bytes = std::fs::read(a.join("run.mcap")).unwrap();
    let cut: PathBuf = tmp.join("cut");
    std::fs::create_dir(&cut).unwrap();
    std::fs::write(cut.join("world.mcap"), &bytes[..bytes.len() / 2]).unwrap();
    let power = e2e_tests::series_file(&a.join("power.csv"));
    std::fs::copy(&power, cut.join(power.file_name().unwrap())).unwrap();
    let merged = scenarios::foxglove::write_run_mcap(
        &cut,
        &[scenarios::foxglove::DroneOutputs {
            name: "cf1".into(),
            dir: cut.clone(),
            map_cell_m: None,
        }],
        1,
    )
    .unwrap();
    assert!(merged.warning.is_some(), "the cut is reported");
    let msgs = messages(&merged.path);
    assert_complete(&merged.path, msgs.len());
    assert!(
        msgs.iter().any(|m| m.0 == "/tf"),
        "what was written is kept"
    );
    assert!(msgs.windows(2).all(|w| w[0].2 <= w[1].2));
}
