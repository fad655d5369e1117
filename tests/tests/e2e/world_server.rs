//! End-to-end tests of the real `world-server` binary over real sockets
//! (DESIGN.md §2, §5).
//!
//! The binary must be built: `cargo test --workspace` builds every binary of
//! the workspace before running tests; with `cargo test -p e2e-tests` run
//! `cargo build -p world-server` first (same profile). A binary older than
//! its sources is reported on stderr.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant, SystemTime};

use protocol::blocking::{Client, Connection, Options};
use protocol::{Endpoint, ImageEncoding, Reply, Request};
use sim_core::peripherals::stm32::pid::{
    body_velocity, ActualState, DesiredState, PidController, PidGains,
};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Newest modification time of the files under `dir`.
fn newest_mtime(dir: &Path) -> SystemTime {
    let mut newest = SystemTime::UNIX_EPOCH;
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let p = entry.path();
        let t = if p.is_dir() {
            newest_mtime(&p)
        } else {
            entry.metadata().unwrap().modified().unwrap()
        };
        newest = newest.max(t);
    }
    newest
}

/// `<target>/<profile>/world-server`, next to this test's `deps/` directory.
fn world_server_bin() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let bin = exe
        .parent()
        .and_then(Path::parent)
        .unwrap()
        .join("world-server");
    let meta = std::fs::metadata(&bin).unwrap_or_else(|_| {
        panic!(
            "{} not found: run `cargo test --workspace`, or `cargo build -p world-server` \
             before `cargo test -p e2e-tests`",
            bin.display()
        )
    });
    // A warning, not a failure: in a tree being edited while tests run a
    // source can be newer than a binary built a moment ago.
    let built = meta.modified().unwrap();
    for src in ["world-server/src", "protocol/src"] {
        if newest_mtime(&repo_root().join(src)) > built {
            eprintln!(
                "warning: {} is older than {src}; run `cargo build -p world-server`",
                bin.display()
            );
        }
    }
    bin
}

struct WorldProcess {
    child: Child,
    socket: PathBuf,
    _dir: tempfile::TempDir,
    dir: PathBuf,
}

impl WorldProcess {
    fn start(world: &str, timestep: u64, extra: &[&str]) -> WorldProcess {
        let dir = tempfile::tempdir().unwrap();
        let socket = dir.path().join("world.sock");
        let child = Command::new(world_server_bin())
            .arg("--socket")
            .arg(&socket)
            .arg("--world")
            .arg(repo_root().join("scenarios/worlds").join(world))
            .arg("--timestep")
            .arg(timestep.to_string())
            .args(extra)
            .current_dir(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        WorldProcess {
            child,
            socket,
            dir: dir.path().to_path_buf(),
            _dir: dir,
        }
    }

    fn connect(&self) -> Connection {
        Client::connect_retry(
            &Endpoint::Unix(self.socket.clone()),
            Options::default(),
            Duration::from_secs(30),
        )
        .unwrap()
    }

    /// Waits for the exit (wall clock only bounds the wait) and returns the
    /// status and what the process wrote to stderr.
    fn finish(&mut self) -> (ExitStatus, String) {
        let deadline = Instant::now() + Duration::from_secs(30);
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            if Instant::now() > deadline {
                self.child.kill().unwrap();
                panic!("world-server did not exit");
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        let mut err = String::new();
        self.child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        (status, err)
    }
}

fn time_of(conn: &mut Connection) -> f64 {
    match conn.request(&Request::GetSensors).unwrap() {
        Some(Reply::Sensors(s)) => s.time_s,
        other => panic!("{other:?}"),
    }
}

fn set_velocity(m: f64) -> Request {
    Request::SetVelocity {
        m1: m,
        m2: m,
        m3: m,
        m4: m,
    }
}

#[test]
fn timing_semantics_and_stop() {
    let mut w = WorldProcess::start(
        "empty.toml",
        32,
        &["--trajectory", "traj.csv", "--trace", "trace.jsonl"],
    );
    let mut conn = w.connect();
    match conn
        .request(&Request::GetInitData {
            image_encoding: Some(ImageEncoding::Base64),
            drone: None,
        })
        .unwrap()
    {
        Some(Reply::InitData {
            time_s,
            timestep_ms,
            x,
            y,
            image_encoding,
            ..
        }) => {
            assert_eq!(time_s, 2.0, "TIME starts at 2.000 s after the warm-up");
            assert_eq!(timestep_ms, 32);
            // Resting on the ground for 2 s moves it by micrometres at most.
            assert!((x + 2.6).abs() < 1e-4 && y.abs() < 1e-4, "({x}, {y})");
            assert_eq!(image_encoding, ImageEncoding::Base64);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(time_of(&mut conn), 2.0);
    // One timestep per SET_VELOCITY.
    for k in 1..=3 {
        conn.send(&set_velocity(48.0)).unwrap();
        assert_eq!(time_of(&mut conn), (2000 + 32 * k) as f64 / 1000.0);
    }
    // `time` ms per ADVANCE_TIME.
    conn.send(&Request::AdvanceTime { time: 928 }).unwrap();
    assert_eq!(time_of(&mut conn), 3.024);
    match conn.request(&Request::GetImage).unwrap() {
        Some(Reply::Image(img)) => {
            assert_eq!((img.width, img.height, img.data.len()), (320, 320, 102_400))
        }
        other => panic!("{other:?}"),
    }
    // Motors after warm-up at 1 rad/s, then 32 steps towards 48 at 0.96 rad/s
    // per step: 1 + 32·0.96 = 31.72 rad/s.
    let w1 = match conn.request(&Request::GetState).unwrap() {
        Some(Reply::State(s)) => {
            assert_eq!(s.time_s, 3.024);
            assert!(
                (s.w1 + 31.72).abs() < 1e-9 && (s.w2 - 31.72).abs() < 1e-9,
                "{s:?}"
            );
            s.w2
        }
        other => panic!("{other:?}"),
    };
    // STOP: 31.72 rad/s at 0.96 rad/s per step needs ceil(33.04) = 34 steps.
    let steps = (w1 / 0.96).ceil() as u64;
    match conn.request(&Request::Stop).unwrap() {
        Some(Reply::Stop {
            time_s,
            stop_time_ms,
            ..
        }) => {
            assert_eq!(stop_time_ms, steps * 32);
            assert_eq!(time_s, (3024 + steps * 32) as f64 / 1000.0);
        }
        other => panic!("{other:?}"),
    }
    assert!(conn.recv_raw().unwrap().is_none(), "closed after STOP");
    let dir = w.dir.clone();
    let (status, err) = w.finish();
    let _keep_dir = w;
    assert!(status.success(), "{status:?}: {err}");

    // The trajectory: one row per step, from the warm-up to the stop, with
    // the propellers stopped in the last row.
    let traj = std::fs::read_to_string(dir.join("traj.csv")).unwrap();
    let rows: Vec<Vec<&str>> = traj
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    // Warm-up: 62 steps of 32 ms and one of 16 ms; then 3 + 29 + STOP's.
    assert_eq!(rows.len() as u64, 63 + 3 + 29 + steps);
    assert_eq!(rows[62][0], "2000");
    let last = rows.last().unwrap();
    assert_eq!(last[0], (3024 + steps * 32).to_string());
    assert_eq!(&last[10..14], &["0", "0", "0", "0"]);
    // The trace: every frame, in order, with the world clock.
    let trace = std::fs::read_to_string(dir.join("trace.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = trace
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // Requests with replies count 2 frames, SET_VELOCITY and ADVANCE_TIME 1:
    // 2 + 2 + 3·(1 + 2) + (1 + 2) + 2 + 2 + 2.
    assert_eq!(lines.len(), 22);
    assert_eq!(lines[0]["dir"], "to_world");
    assert_eq!(lines[0]["world_ms"], 2000);
    assert_eq!(lines.last().unwrap()["msg"]["command"], "STOP");
    let image = lines
        .iter()
        .find(|l| l["msg"]["command"] == "GET_IMAGE" && l["dir"] == "to_platform")
        .unwrap();
    assert_eq!(image["msg"]["camera"]["sha256"].as_str().unwrap().len(), 64);
}

/// Starts a world, sends `body` as one raw frame after GET_INIT_DATA, and
/// returns the reply body (if any), exit status and stderr.
fn bad_input(body: &[u8]) -> (Option<String>, ExitStatus, String) {
    let mut w = WorldProcess::start("empty.toml", 32, &[]);
    let mut conn = w.connect();
    conn.request(&Request::GetInitData {
        image_encoding: None,
        drone: None,
    })
    .unwrap();
    conn.send_raw(body).unwrap();
    let reply = conn
        .recv_raw()
        .ok()
        .flatten()
        .map(|b| String::from_utf8_lossy(b).into_owned());
    drop(conn);
    let (status, err) = w.finish();
    (reply, status, err)
}

#[test]
fn bad_input_gets_an_error_frame_and_a_non_zero_exit() {
    let cases: [(&[u8], &str); 5] = [
        (b"{not json", "JSON"),
        (br#"{"command":"FLY_AWAY"}"#, "FLY_AWAY"),
        (br#"{"command":"ADVANCE_TIME","time":33}"#, "multiple"),
        (
            br#"{"command":"SET_VELOCITY","m1":10.0,"m2":-1.0,"m3":10.0,"m4":10.0}"#,
            "negative",
        ),
        // nlohmann writes NaN as null.
        (
            br#"{"command":"SET_VELOCITY","m1":null,"m2":1.0,"m3":1.0,"m4":1.0}"#,
            "m1",
        ),
    ];
    for (body, needle) in cases {
        let (reply, status, err) = bad_input(body);
        let reply = reply.unwrap_or_else(|| panic!("no ERROR frame for {body:?}"));
        assert!(reply.contains(r#""command":"ERROR""#), "{reply}");
        assert!(reply.contains(needle), "{reply}");
        assert!(!status.success(), "{body:?}");
        assert!(
            err.contains("world-server:") && err.contains(needle),
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn a_client_leaving_before_stop_is_an_error_and_outputs_are_flushed() {
    let mut w = WorldProcess::start("empty.toml", 32, &["--trajectory", "traj.csv"]);
    let mut conn = w.connect();
    conn.send(&set_velocity(10.0)).unwrap();
    assert_eq!(time_of(&mut conn), 2.032);
    drop(conn);
    let dir = w.dir.clone();
    let (status, err) = w.finish();
    let _keep_dir = w;
    assert!(!status.success());
    assert!(err.contains("disconnected before STOP"), "{err}");
    let traj = std::fs::read_to_string(dir.join("traj.csv")).unwrap();
    assert_eq!(traj.lines().count(), 1 + 63 + 1);
    assert!(traj.lines().last().unwrap().starts_with("2032,"));
}

#[test]
fn frames_dir_gets_every_served_frame_as_png() {
    let mut w = WorldProcess::start("thesis-course.toml", 32, &["--frames-dir", "frames"]);
    let mut conn = w.connect();
    for _ in 0..2 {
        conn.request(&Request::GetImage).unwrap();
        conn.send(&set_velocity(0.0)).unwrap();
    }
    conn.request(&Request::Stop).unwrap();
    let dir = w.dir.clone();
    let (status, err) = w.finish();
    let _keep_dir = w;
    assert!(status.success(), "{err}");
    let mut names: Vec<String> = std::fs::read_dir(dir.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["frame-000000-2000ms.png", "frame-000001-2032ms.png"]
    );
}

#[test]
fn the_bitcraze_pid_takes_off_and_hovers_at_one_metre() {
    // An open-loop scripted client: the platform's PID code, one
    // SET_VELOCITY (one 32 ms step) per PID iteration, no virtual platform.
    let ts = 32;
    let dt = ts as f64 / 1000.0;
    let mut w = WorldProcess::start("empty.toml", ts, &[]);
    let mut conn = w.connect();
    let mut pid = PidController::new(PidGains::default());
    let mut last: Option<(f64, f64)> = None;
    let mut altitudes = Vec::new();
    for _ in 0..(20_000 / ts) {
        let s = match conn.request(&Request::GetSensors).unwrap() {
            Some(Reply::Sensors(s)) => s,
            other => panic!("{other:?}"),
        };
        let (vx, vy) = match last {
            Some((px, py)) => body_velocity(s.x - px, s.y - py, dt, s.yaw),
            None => (0.0, 0.0),
        };
        last = Some((s.x, s.y));
        let actual = ActualState {
            roll: s.roll,
            pitch: s.pitch,
            yaw_rate: s.yaw_rate,
            altitude: s.altitude,
            vx,
            vy,
        };
        let mut desired = DesiredState {
            altitude: 1.0,
            ..DesiredState::default()
        };
        let m = pid.step(&actual, &mut desired, dt);
        conn.send(&Request::SetVelocity {
            m1: m.m1.max(0.0),
            m2: m.m2.max(0.0),
            m3: m.m3.max(0.0),
            m4: m.m4.max(0.0),
        })
        .unwrap();
        altitudes.push((s.time_s, s.altitude, s.x, s.y));
    }
    conn.request(&Request::Stop).unwrap();
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
    let peak = altitudes.iter().map(|a| a.1).fold(0.0, f64::max);
    assert!(peak > 0.9, "never took off: peak {peak}");
    // The last 5 s: within ±5 cm of 1 m, and it did not wander off.
    for &(t, z, x, y) in altitudes.iter().filter(|a| a.0 >= 17.0) {
        assert!((z - 1.0).abs() <= 0.05, "t = {t}: altitude {z}");
        assert!((x + 2.6).hypot(y) < 0.3, "t = {t}: drifted to ({x}, {y})");
    }
}
