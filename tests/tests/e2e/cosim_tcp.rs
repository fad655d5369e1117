//! A platform and its world as two separately started programs over TCP
//! (DESIGN.md §11): `cosim world short-hop --listen tcp:127.0.0.1:PORT`
//! (world-server --tcp) and `cosim run short-hop --world-endpoint
//! tcp:127.0.0.1:PORT` (sim-core --socket tcp:...). The run is the same as
//! over the private UNIX socket: both traces, the trajectory, the platform's
//! CSVs, its console and its summary (but for the wall-clock figures) are
//! byte for byte those of `cosim run short-hop`. A world of another
//! timestep is caught. The short hop rather than the race: the same traffic
//! (181 camera frames, 70 MB to the platform, 5947 messages) in a second.

use std::net::TcpListener;
use std::path::Path;
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::{output_text as text, series_file, CosimBins as Bins, PLATFORM_FILES};
use serde_json::Value;

/// `cosim world ... --listen tcp:127.0.0.1:PORT`, in the background.
fn start_world(b: &Bins, port: u16, out: &Path, extra: &[&str]) -> Child {
    let listen = format!("tcp:127.0.0.1:{port}");
    let mut args = vec![
        "world",
        "short-hop",
        "--listen",
        &listen,
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    b.command(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start cosim world")
}

/// A port nobody listens on now (the world binds it a moment later).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Waits for the world to exit by itself (it does after STOP), 30 s at most.
fn wait_exit(child: &mut Child) -> std::process::ExitStatus {
    let until = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return st;
        }
        if Instant::now() > until {
            let _ = child.kill();
            panic!("the world did not exit after the run");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn summary(dir: &Path) -> Value {
    let mut s: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let o = s.as_object_mut().unwrap();
    o.remove("wall_time_s");
    o.remove("realtime_factor");
    s
}

/// The same text in both files, each in either form (a trace `cosim`
/// compressed against one a binary started by hand wrote plain).
fn same_bytes(a: &Path, b: &Path) {
    let (x, y) = (e2e_tests::read_series(a), e2e_tests::read_series(b));
    assert!(
        x == y,
        "{} and {} differ ({} vs {} bytes)",
        a.display(),
        b.display(),
        x.len(),
        y.len()
    );
}

#[test]
fn the_short_hop_split_over_tcp_is_the_unix_socket_run() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();

    let unix = tmp.path().join("unix");
    let o = b.cosim(&["run", "short-hop", "--no-plots", "-q", "--out", &s(&unix)]);
    assert!(o.status.success(), "{}", text(&o));

    let port = free_port();
    let world_out = tmp.path().join("world");
    let mut world = start_world(&b, port, &world_out, &[]);
    let platform = tmp.path().join("platform");
    let endpoint = format!("tcp:127.0.0.1:{port}");
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--no-plots",
        "-q",
        "--world-endpoint",
        &endpoint,
        "--out",
        &s(&platform),
    ]);
    let st = wait_exit(&mut world);
    assert!(o.status.success(), "{}", text(&o));
    assert!(st.success(), "world: {st:?}");
    assert_eq!(summary(&platform)["completed"], true);
    assert_eq!(summary(&unix), summary(&platform));
    same_bytes(
        &unix.join("platform.trace"),
        &platform.join("platform.trace"),
    );
    same_bytes(&unix.join("world.trace"), &world_out.join("world.trace"));
    same_bytes(
        &series_file(&unix.join("trajectory.csv")),
        &series_file(&world_out.join("trajectory.csv")),
    );
    for f in PLATFORM_FILES {
        same_bytes(&series_file(&unix.join(f)), &series_file(&platform.join(f)));
    }
    // The world's outputs are where the world ran, not beside the platform's.
    assert!(!series_file(&platform.join("trajectory.csv")).exists());
    assert!(std::fs::read_to_string(platform.join("cosim.log"))
        .unwrap()
        .contains(&format!("world at {endpoint}")));
}

#[test]
fn a_remote_world_of_another_timestep_fails_the_run() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let port = free_port();
    let mut world = start_world(
        &b,
        port,
        &tmp.path().join("world"),
        &["--set", "timestep_ms=16", "--no-trace"],
    );
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--no-plots",
        "-q",
        "--no-trace",
        "--world-endpoint",
        &format!("tcp:127.0.0.1:{port}"),
        "--out",
        tmp.path().join("platform").to_str().unwrap(),
    ]);
    wait_exit(&mut world);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("ran at 16 ms, the scenario says 32 ms"),
        "{}",
        text(&o)
    );
}

#[test]
fn a_bad_world_endpoint_is_one_line_and_exit_2() {
    let b = Bins::new();
    for bad in ["tcp:nohost", "tcp::7000", "http://x:1"] {
        let o = b.cosim(&["run", "short-hop", "--world-endpoint", bad]);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", text(&o));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(bad),
            "{bad}: {}",
            text(&o)
        );
    }
    let o = b.cosim(&[
        "run",
        "short-hop",
        "--world-endpoint",
        "tcp:127.0.0.1:1",
        "--world-cmd",
        "true",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}
