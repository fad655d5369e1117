//! Busy polling (`busy_poll_us`, docs/COSIM.md "Performance") changes when
//! the two processes notice each other's frames, never what is simulated:
//! `cosim run short-hop` with the default budget and with polling off gives
//! the same trajectory, CSVs, console and both traces byte for byte, and
//! `summary.json` records the budget each run used. A bad value is a
//! one-line error before anything starts.

use e2e_tests::{
    assert_same_files, output_text as text, summary, CosimBins as Bins, PLATFORM_FILES,
};

#[test]
fn polling_or_not_the_run_is_the_same_bytes() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let (on, off) = (tmp.path().join("on"), tmp.path().join("off"));
    for (dir, sets) in [(&on, &[][..]), (&off, &["--set", "busy_poll_us=0"][..])] {
        let mut args = vec![
            "run",
            "short-hop",
            "--quiet",
            "--no-plots",
            "--out",
            dir.to_str().unwrap(),
        ];
        args.extend_from_slice(sets);
        let o = b.cosim(&args);
        assert!(o.status.success(), "{}", text(&o));
    }
    assert_same_files(
        &on,
        &off,
        &[
            &["trajectory.csv", "world.trace", "platform.trace"][..],
            &PLATFORM_FILES,
        ]
        .concat(),
        "busy polling on and off",
    );
    assert_eq!(
        summary(&on)["busy_poll_us"],
        protocol::busy_poll::DEFAULT_US
    );
    assert_eq!(summary(&off)["busy_poll_us"], 0);
    assert!(summary(&on)["completed"].as_bool().unwrap());
}

#[test]
fn a_bad_budget_is_one_line() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    for bad in [
        "busy_poll_us=-1",
        "busy_poll_us=fast",
        "busy_poll_us=2000000",
    ] {
        let o = b.cosim(&[
            "run",
            "short-hop",
            "--set",
            bad,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{bad}: {err}");
        assert!(lines[0].contains("busy_poll_us"), "{bad}: {err}");
        assert!(!out.exists(), "{bad}: something was started");
    }
}
