//! A run's series and traces (DESIGN.md §6, §19) in both forms: `cosim run
//! short-hop` writes `*.csv.zst` and `*.trace.zst` by default and plain
//! `*.csv` and `*.trace` with `--set output.compress=false`; the two hold
//! the same rows, byte for byte once decompressed, and the report and the
//! trace tools read either.

use std::path::Path;

use e2e_tests::{output_text as text, read_series, summary, CosimBins as Bins};

/// The series and traces of a single-drone run, by their plain names.
const SERIES: [&str; 8] = [
    "power.csv",
    "motor_empirical.csv",
    "motor_dandrea.csv",
    "motor_stolaroff.csv",
    "trajectory.csv",
    "time_map.csv",
    "world.trace",
    "platform.trace",
];

fn run(b: &Bins, out: &Path, extra: &[&str]) {
    let out_s = out.to_str().unwrap();
    let mut args = vec!["run", "short-hop", "--out", out_s, "--no-mcap", "-q"];
    args.extend_from_slice(extra);
    let o = b.cosim(&args);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn compressed_and_plain_series_hold_the_same_rows() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let (zst, plain) = (tmp.path().join("zst"), tmp.path().join("plain"));
    run(&b, &zst, &[]);
    run(&b, &plain, &["--set", "output.compress=false"]);
    for name in SERIES {
        let z = zst.join(format!("{name}.zst"));
        assert!(z.is_file(), "{} missing", z.display());
        assert!(!zst.join(name).exists(), "{name} beside its .zst");
        assert!(plain.join(name).is_file(), "{name} missing");
        assert!(!plain.join(format!("{name}.zst")).exists());
        // One zstd frame that the zstd library decodes on its own (what
        // pandas and polars do), equal to the plain file.
        let decoded = zstd::decode_all(&std::fs::read(&z).unwrap()[..]).unwrap();
        let csv = std::fs::read(plain.join(name)).unwrap();
        assert!(decoded == csv, "{name}: the two forms differ");
        assert!(csv.len() > 20, "{name}: {} bytes", csv.len());
        assert_eq!(read_series(&zst.join(name)).as_bytes(), &csv[..]);
    }
    // The trace tools take the compressed trace by its plain name.
    let o = b.cosim(&["trace", "show", zst.join("world.trace").to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("GET_INIT_DATA"), "{}", text(&o));
    // The runs are the same run: the summary and the report's plots.
    let strip = |mut s: serde_json::Value| {
        let o = s.as_object_mut().unwrap();
        o.remove("wall_time_s");
        o.remove("realtime_factor");
        s
    };
    assert_eq!(strip(summary(&zst)), strip(summary(&plain)));
    for png in ["power_models.png", "battery.png", "top_view.png"] {
        assert_eq!(
            std::fs::read(zst.join(png)).unwrap(),
            std::fs::read(plain.join(png)).unwrap(),
            "{png}"
        );
    }
    // The plain run says so in its run.toml; the default leaves it out.
    let toml = |d: &Path| std::fs::read_to_string(d.join("run.toml")).unwrap();
    let says_plain = |d: &Path| {
        toml(d)
            .lines()
            .any(|l| l.contains("output.compress") && l.trim_end().ends_with("false"))
    };
    assert!(says_plain(&plain), "{}", toml(&plain));
    assert!(!toml(&zst).contains("output.compress"), "{}", toml(&zst));
}
