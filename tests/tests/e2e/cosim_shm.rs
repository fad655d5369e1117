//! Images through shared memory (`image_encoding = "shm"`, docs/PROTOCOL.md
//! "Images in shared memory"): `cosim run short-hop --set
//! image_encoding=shm` flies the same run as the thesis's array images —
//! trajectory, the platform's CSVs and console byte for byte, both traces
//! line for line but for what names the encoding (GET_INIT_DATA) and the
//! length of the image frames — while the platform receives ~1 % of the
//! bytes. The world's shared-memory file is gone after the run. The short
//! hop: 181 camera frames in about a second.

use std::path::Path;

use e2e_tests::{
    assert_same_files, output_text as text, summary, CosimBins as Bins, PLATFORM_FILES,
};
use serde_json::Value;

/// The trace's lines with `len` of image replies and GET_INIT_DATA lines
/// left out (they name or reflect the encoding); everything else verbatim.
fn comparable_trace(path: &Path) -> Vec<String> {
    e2e_tests::read_series(path)
        .lines()
        .filter(|l| !l.contains("\"GET_INIT_DATA\""))
        .map(|l| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            if v["dir"] == "to_platform" && v["msg"]["command"] == "GET_IMAGE" {
                assert!(v["msg"]["camera"]["sha256"].is_string(), "{l}");
                v["len"] = Value::Null;
            }
            v.to_string()
        })
        .collect()
}

fn shm_files() -> Vec<String> {
    match std::fs::read_dir("/dev/shm") {
        Ok(d) => d
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("cosim-img-"))
            .collect(),
        Err(_) => Vec::new(),
    }
}

#[test]
fn shm_images_fly_the_same_run_as_array_images() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let (a, s) = (tmp.path().join("array"), tmp.path().join("shm"));
    let before = shm_files();
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--quiet",
        "--no-plots",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--quiet",
        "--no-plots",
        "--set",
        "image_encoding=shm",
        "--out",
        s.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));

    assert_same_files(
        &a,
        &s,
        &[&["trajectory.csv"][..], &PLATFORM_FILES].concat(),
        "between array and shm images",
    );
    for t in ["platform.trace", "world.trace"] {
        let (x, y) = (comparable_trace(&a.join(t)), comparable_trace(&s.join(t)));
        assert_eq!(x.len(), y.len(), "{t}");
        for (i, (l, m)) in x.iter().zip(&y).enumerate() {
            assert_eq!(l, m, "{t} line {i}");
        }
    }
    let (sa, ss) = (summary(&a), summary(&s));
    assert_eq!(sa["image_encoding"], "array");
    assert_eq!(ss["image_encoding"], "shm");
    for k in ["messages", "platform_time_s", "world_time_s"] {
        assert_eq!(sa[k], ss[k], "{k}");
    }
    // The requests differ only in GET_INIT_DATA's "array" against "shm".
    assert_eq!(
        sa["bytes_to_world"].as_u64().unwrap(),
        ss["bytes_to_world"].as_u64().unwrap() + 2
    );
    let (ba, bs) = (
        sa["bytes_to_platform"].as_f64().unwrap(),
        ss["bytes_to_platform"].as_f64().unwrap(),
    );
    assert!(
        bs < 0.02 * ba,
        "shm: {bs} bytes to the platform, array: {ba}"
    );
    // The world removed its file.
    let left: Vec<String> = shm_files()
        .into_iter()
        .filter(|n| !before.contains(n))
        .collect();
    assert!(left.is_empty(), "left in /dev/shm: {left:?}");
}
