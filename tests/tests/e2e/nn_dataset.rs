//! `cosim dataset` end to end (DESIGN.md §13, docs/NN.md): the same world,
//! N and seed give the same bytes, another seed other images; every image is
//! a 320×320 PGM; every label is a projected square: the centre is where the
//! opening's diagonals cross (a projective map keeps incidence); bad input is
//! one line and exit code 2.

use std::path::Path;

use e2e_tests::{assert_same_files, output_text as text, world_file, CosimBins as Bins};

fn dataset(bins: &Bins, world: &Path, count: &str, seed: &str, out: &Path) {
    let o = bins.cosim(&[
        "dataset",
        world.to_str().unwrap(),
        "--count",
        count,
        "--seed",
        seed,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
}

/// Where the segments p0–p2 and p1–p3 cross.
fn diagonals_cross(c: &[f64]) -> (f64, f64) {
    let (p0, p1, p2, p3) = ((c[0], c[1]), (c[2], c[3]), (c[4], c[5]), (c[6], c[7]));
    let (d1, d2) = ((p2.0 - p0.0, p2.1 - p0.1), (p3.0 - p1.0, p3.1 - p1.1));
    let den = d1.0 * d2.1 - d1.1 * d2.0;
    let t = ((p1.0 - p0.0) * d2.1 - (p1.1 - p0.1) * d2.0) / den;
    (p0.0 + t * d1.0, p0.1 + t * d1.1)
}

/// gates.csv lists every gate in front of the camera; its nearest strictly
/// visible gate of each image is labels.csv's row, field for field; the
/// visible ones keep the labels' rules; some images see several gates, and
/// some gates are listed but not visible.
fn gates_csv_agrees_with_labels(dir: &Path) {
    let mut gates = csv::Reader::from_path(dir.join("gates.csv")).unwrap();
    assert_eq!(
        gates.headers().unwrap(),
        vec![
            "file",
            "gate",
            "u",
            "v",
            "distance_m",
            "off_normal_deg",
            "in_image",
            "visible",
            "corners"
        ]
    );
    let mut by_file = std::collections::BTreeMap::<String, Vec<csv::StringRecord>>::new();
    for row in gates.records() {
        let row = row.unwrap();
        by_file.entry(row[0].to_string()).or_default().push(row);
    }
    let (mut several, mut not_visible) = (0, 0);
    let mut labels = csv::Reader::from_path(dir.join("labels.csv")).unwrap();
    for label in labels.records() {
        let label = label.unwrap();
        let rows = by_file.remove(&label[0]).unwrap_or_default();
        let num = |r: &csv::StringRecord, k: usize| r[k].parse::<f64>().unwrap();
        let mut nearest: Option<&csv::StringRecord> = None;
        for r in &rows {
            if &r[7] == "1" {
                assert_eq!(&r[6], "1", "{r:?}");
                assert!(num(r, 4) <= world_server::dataset::MAX_RANGE_M, "{r:?}");
                assert!(num(r, 5) <= 70.0 + 1e-3, "{r:?}");
                assert_eq!(r[8].split(' ').count(), 8, "{r:?}");
                if nearest.is_none_or(|n| num(r, 4) < num(n, 4)) {
                    nearest = Some(r);
                }
            } else {
                not_visible += 1;
            }
        }
        several += usize::from(rows.iter().filter(|r| &r[7] == "1").count() > 1);
        match nearest {
            None => assert_eq!(&label[1], "0", "{label:?} but gates.csv: {rows:?}"),
            Some(n) => {
                assert_eq!(&label[1], "1");
                for (l, g) in [(2, 2), (3, 3), (4, 4), (5, 8)] {
                    assert_eq!(&label[l], &n[g], "{label:?} vs {n:?}");
                }
            }
        }
    }
    assert!(by_file.is_empty(), "gates.csv names other files");
    assert!(several > 0 && not_visible > 0, "{several} {not_visible}");
}

#[test]
fn dataset_is_seeded_and_its_labels_are_projected_gates() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let world = world_file("thesis-course");
    let (a, b, c) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("c"),
    );
    dataset(&bins, &world, "60", "7", &a);
    dataset(&bins, &world, "60", "7", &b);
    dataset(&bins, &world, "60", "8", &c);
    let mut files: Vec<String> = (0..60).map(|i| format!("img_{i:06}.pgm")).collect();
    files.push("labels.csv".into());
    files.push("gates.csv".into());
    files.push("dataset.json".into());
    assert_same_files(&a, &b, &files, "same seed");
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).unwrap();
    assert_ne!(
        read(&a, "labels.csv"),
        read(&c, "labels.csv"),
        "another seed"
    );

    let mut labels = csv::Reader::from_path(a.join("labels.csv")).unwrap();
    assert_eq!(
        labels.headers().unwrap(),
        vec!["file", "gate_visible", "u", "v", "distance_m", "corners"]
    );
    let mut visible = 0;
    for (i, row) in labels.records().enumerate() {
        let row = row.unwrap();
        assert_eq!(&row[0], format!("img_{i:06}.pgm"));
        let pgm = read(&a, &row[0]);
        assert_eq!(&pgm[..15], b"P5\n320 320\n255\n");
        assert_eq!(pgm.len(), 15 + 320 * 320);
        if &row[1] == "0" {
            assert!((2..6).all(|k| row[k].is_empty()), "{row:?}");
            continue;
        }
        visible += 1;
        let num = |k: usize| row[k].parse::<f64>().unwrap();
        let (u, v, d) = (num(2), num(3), num(4));
        assert!(
            (0.0..320.0).contains(&u) && (0.0..320.0).contains(&v),
            "{row:?}"
        );
        assert!(
            d > 0.0 && d <= world_server::dataset::MAX_RANGE_M,
            "{row:?}"
        );
        let corners: Vec<f64> = row[5].split(' ').map(|x| x.parse().unwrap()).collect();
        assert_eq!(corners.len(), 8);
        let (cu, cv) = diagonals_cross(&corners);
        assert!(
            (cu - u).abs() < 0.05 && (cv - v).abs() < 0.05,
            "centre ({u}, {v}) but the diagonals cross at ({cu}, {cv}): {row:?}"
        );
        // Top-left is left of top-right and above bottom-left (as seen).
        assert!(
            corners[0] < corners[2] && corners[1] < corners[7],
            "{row:?}"
        );
    }
    assert!(visible >= 20, "only {visible} of 60 images see a gate");
    gates_csv_agrees_with_labels(&a);

    for (args, want) in [
        (
            vec!["--count", "0", "--seed", "1"],
            "--count must be at least 1",
        ),
        (vec!["--count", "x", "--seed", "1"], "invalid value"),
    ] {
        let bad = tmp.path().join("bad");
        let mut all = vec!["dataset", world.to_str().unwrap()];
        all.extend(args);
        all.extend(["--out", bad.to_str().unwrap()]);
        let o = bins.cosim(&all);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
        assert!(text(&o).contains(want), "{}", text(&o));
    }
    let o = bins.cosim(&[
        "dataset",
        "no-such-world.toml",
        "--count",
        "1",
        "--seed",
        "1",
        "--out",
        tmp.path().join("bad").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(String::from_utf8_lossy(&o.stderr).trim().lines().count(), 1);
}

/// `world-server dataset` is the same renderer and labels as `cosim
/// dataset`: the same world, N and seed give the same bytes; a world file
/// that cannot be read is one line on stderr and a non-zero exit.
#[test]
fn world_server_dataset_writes_cosims_bytes() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let world = world_file("thesis-course");
    let (a, b) = (tmp.path().join("cosim"), tmp.path().join("world"));
    dataset(&bins, &world, "12", "5", &a);
    let ws = |args: &[&str]| {
        std::process::Command::new(&bins.world)
            .args(args)
            .output()
            .expect("run world-server")
    };
    let o = ws(&[
        "dataset",
        world.to_str().unwrap(),
        "--count",
        "12",
        "--seed",
        "5",
        "--out",
        b.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let mut files: Vec<String> = (0..12).map(|i| format!("img_{i:06}.pgm")).collect();
    files.extend(["labels.csv", "gates.csv", "dataset.json"].map(String::from));
    assert_same_files(&a, &b, &files, "world-server dataset = cosim dataset");

    let o = ws(&[
        "dataset",
        "no-such-world.toml",
        "--count",
        "1",
        "--seed",
        "1",
        "--out",
        tmp.path().join("bad").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert_eq!(err.matches("os error").count(), 1, "the cause once: {err}");
    // An output "directory" that is a file: both commands say so once.
    let file = tmp.path().join("a-file");
    std::fs::write(&file, b"").unwrap();
    let args = [
        "dataset",
        world.to_str().unwrap(),
        "--count",
        "1",
        "--seed",
        "1",
        "--out",
        file.to_str().unwrap(),
    ];
    for o in [ws(&args), bins.cosim(&args)] {
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert_eq!(err.matches("os error").count(), 1, "the cause once: {err}");
    }
    // The server's own flags still need no subcommand, and a subcommand
    // does not take them.
    let o = ws(&["dataset", world.to_str().unwrap(), "--socket", "/tmp/x"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}
