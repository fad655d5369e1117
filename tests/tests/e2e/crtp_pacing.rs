//! Pacing holds (DESIGN.md §20, docs/CFLIB.md "Pacing"): `cosim run
//! cflib-lab` at pace 4 with a client that connects and goes quiet runs
//! its paced part at about 4 simulated seconds per wall second, and says so
//! in `summary.json`'s `pacing`, in `pacing.csv` and in the printed report;
//! unpaced (pace 0) the run has none of them.
//!
//! Not a timing test: the machine running the tests may be busy, so the
//! achieved pace is only asked to be within a wide band, and the warning
//! only to agree with the figures it reports.

use std::net::UdpSocket;
use std::path::Path;
use std::process::Output;
use std::time::{Duration, Instant};

use e2e_tests::{output_text, summary, CosimBins};

/// Above cflib's scan range and the other tests' ports (crtp_link: 19890,
/// python/tests: 19870–19879); one a test, as they run at once.
const PACED_PORT: u16 = 19892;
const UNPACED_PORT: u16 = 19893;
const PACE: f64 = 4.0;
/// Simulated seconds of silence that close the link: 2 s of wall at pace 4.
const IDLE_S: f64 = 8.0;

/// Runs cflib-lab at `pace` on `port` while a client connects (the null probe until
/// answered, then one echo) and goes quiet, so the run ends `IDLE_S` later.
fn paced_run(out: &Path, pace: f64, port: u16) -> Output {
    let bins = CosimBins::new();
    let spec = format!("crtp=udp:127.0.0.1:{port}");
    let pace_key = format!("pace={pace}");
    let idle = format!("crtp_idle_s={IDLE_S}");
    let child = bins
        .command(&[
            "run",
            "cflib-lab",
            "--out",
            out.to_str().unwrap(),
            "--no-plots",
            "--no-mcap",
            "--set",
            &spec,
            "--set",
            &pace_key,
            "--set",
            &idle,
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(300)))
        .unwrap();
    let until = Instant::now() + Duration::from_secs(60);
    let mut buf = [0u8; 64];
    loop {
        // The link answers once the firmware serves it; before, nothing is
        // bound and the send may be refused.
        let _ = s.send(&[0xFF]);
        if matches!(s.recv(&mut buf), Ok(1) if buf[0] == 0xFF) {
            break;
        }
        assert!(Instant::now() < until, "the link never answered");
    }
    s.send(&[0xF0, 1]).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn a_paced_run_reports_its_achieved_pace_and_lag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("paced");
    let o = paced_run(&out, PACE, PACED_PORT);
    assert!(o.status.success(), "{}", output_text(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let s = summary(&out);
    let p = &s["pacing"];
    let f = |k: &str| {
        p[k].as_f64()
            .unwrap_or_else(|| panic!("pacing.{k} missing: {p}"))
    };
    assert_eq!(f("pace"), PACE);
    // Never faster than asked (a step waits for its deadline); not much
    // slower on any host that can run the tests at all.
    let achieved = f("achieved_pace");
    assert!(
        (0.5 * PACE..=PACE * 1.001).contains(&achieved),
        "achieved pace {achieved}\n{text}"
    );
    // The paced part: from the first CRTP step to the link's close, which
    // is IDLE_S after the echo.
    assert!(f("paced_s") >= IDLE_S, "{p}");
    assert!((f("paced_s") / f("wall_s") - achieved).abs() < 1e-9, "{p}");
    assert!(f("worst_lag_ms") >= f("mean_lag_ms") && f("mean_lag_ms") >= 0.0);
    let steps = p["steps"].as_u64().unwrap();
    assert!(p["steps_late"].as_u64().unwrap() <= steps);
    // One row a step, the 2 ms steps of the paced part (cflib-lab flies
    // the firmware's 500 Hz loops).
    let csv = std::fs::read_to_string(out.join("pacing.csv")).unwrap();
    assert_eq!(csv.lines().next(), Some("platform_s,wall_s,lag_ms"));
    assert_eq!(csv.lines().count() as u64, steps + 1);
    assert_eq!(steps, (f("paced_s") / 0.002).round() as u64 + 1);
    // The report says it, and warns exactly when the figures are out of
    // their limits.
    assert!(text.contains("   pacing         pace 4 asked,"), "{text}");
    let kept_up = p["kept_up"].as_bool().unwrap();
    assert_eq!(
        kept_up,
        achieved >= 0.95 * PACE && f("worst_lag_ms") <= 100.0,
        "{p}"
    );
    assert_eq!(text.contains("WARNING"), !kept_up, "{text}");
}

#[test]
fn an_unpaced_run_has_no_pacing_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("unpaced");
    let o = paced_run(&out, 0.0, UNPACED_PORT);
    assert!(o.status.success(), "{}", output_text(&o));
    let s = summary(&out);
    assert!(s.get("pacing").is_none(), "{s}");
    assert!(!out.join("pacing.csv").exists());
    assert!(!String::from_utf8_lossy(&o.stdout).contains("   pacing "));
}
