//! Shared by the multi-drone end-to-end tests: a real `world-server`
//! process on a world file written by the test, and hand-written platforms
//! (`protocol::blocking` clients) over real sockets.

#![allow(dead_code)] // each test file uses its own part

use std::io::Read;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use protocol::blocking::{Client, Connection, Options};
use protocol::{Endpoint, Reply, Request};

/// A running world server.
pub struct World {
    child: Child,
    pub socket: PathBuf,
    pub dir: PathBuf,
    _tmp: tempfile::TempDir,
}

impl World {
    /// Starts `world-server` on `world` (TOML text) with `--timestep 32`,
    /// `--trace world.trace`, `--trajectory traj.csv` and `extra` arguments,
    /// in a fresh directory.
    pub fn start(world: &str, extra: &[&str]) -> World {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        std::fs::write(dir.join("world.toml"), world).unwrap();
        let socket = dir.join("world.sock");
        let child = Command::new(e2e_tests::binary("world-server", "world-server"))
            .arg("--socket")
            .arg(&socket)
            .args(["--world", "world.toml", "--timestep", "32"])
            .args(["--trace", "world.trace", "--trajectory", "traj.csv"])
            .args(extra)
            .current_dir(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        World {
            child,
            socket,
            dir,
            _tmp: tmp,
        }
    }

    /// The world's socket, for a platform in another thread.
    pub fn attach(socket: PathBuf) -> Socket {
        Socket(socket)
    }

    pub fn connect(&self) -> Connection {
        Socket(self.socket.clone()).connect()
    }

    /// Connects and claims `name`; blocks until every drone is claimed.
    pub fn claim(&self, name: &str) -> Connection {
        Socket(self.socket.clone()).claim(name)
    }

    /// Waits for the exit (at most 30 s of wall time, then kills it and
    /// fails the test) and returns the status and stderr.
    pub fn finish(&mut self) -> (ExitStatus, String) {
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

    pub fn read(&self, name: &str) -> String {
        std::fs::read_to_string(self.dir.join(name)).unwrap()
    }
}

/// A world's socket, as a platform sees it.
pub struct Socket(pub PathBuf);

impl Socket {
    pub fn connect(&self) -> Connection {
        Client::connect_retry(
            &Endpoint::Unix(self.0.clone()),
            Options::default(),
            Duration::from_secs(30),
        )
        .unwrap()
    }

    /// Connects and claims `name`; blocks until every drone is claimed.
    pub fn claim(&self, name: &str) -> Connection {
        let mut c = self.connect();
        match c.request(&init(Some(name))).unwrap() {
            Some(Reply::InitData { time_s, drone, .. }) => {
                assert_eq!(time_s, 2.0);
                assert_eq!(drone.as_deref(), Some(name));
            }
            other => panic!("{other:?}"),
        }
        c
    }

    /// Claims `name` (answered at once, DESIGN.md §15), steps once and
    /// returns the ERROR its GET_SENSORS meets: a reply one step after the
    /// start needs every other drone's clock there, so it waits for the
    /// others, and meets the end of the run when another drone failed it
    /// at the start.
    pub fn claim_step_and_fail(&self, name: &str) -> String {
        let mut c = self.claim(name);
        c.send(&set_velocity(10.0)).unwrap();
        error_of(&mut c, &Request::GetSensors)
    }
}

impl Drop for World {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn init(drone: Option<&str>) -> Request {
    Request::GetInitData {
        image_encoding: None,
        drone: drone.map(str::to_string),
    }
}

pub fn set_velocity(m: f64) -> Request {
    Request::SetVelocity {
        m1: m,
        m2: m,
        m3: m,
        m4: m,
    }
}

pub fn time_of(c: &mut Connection) -> f64 {
    match c.request(&Request::GetSensors).unwrap() {
        Some(Reply::Sensors(s)) => s.time_s,
        other => panic!("{other:?}"),
    }
}

/// STOP, its reply, then the world closes the connection.
pub fn stop(c: &mut Connection) -> (f64, u64) {
    let r = match c.request(&Request::Stop).unwrap() {
        Some(Reply::Stop {
            time_s,
            stop_time_ms,
            ..
        }) => (time_s, stop_time_ms),
        other => panic!("{other:?}"),
    };
    assert!(c.recv_raw().unwrap().is_none(), "closed after STOP");
    r
}

/// The ERROR a request meets (the run has ended).
pub fn error_of(c: &mut Connection, req: &Request) -> String {
    match c.request(req) {
        Err(protocol::ProtocolError::Remote(e)) => e,
        other => panic!("expected an ERROR reply, got {other:?}"),
    }
}

/// The JSON lines of a trace.
pub fn trace_lines(text: &str) -> Vec<serde_json::Value> {
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Checks a multi-drone world trace's order: its requests by (time, drone
/// in `names` order), the canonical order of docs/SWARM.md §2, each reply
/// (but a STOP's, which comes when the propellers stopped) right after its
/// request.
pub fn assert_canonical_order(lines: &[serde_json::Value], names: &[&str]) {
    let index = |l: &serde_json::Value| names.iter().position(|n| l["drone"] == *n).unwrap();
    let mut last = (0, 0);
    for (k, l) in lines.iter().enumerate() {
        let key = (l["world_ms"].as_u64().unwrap(), index(l));
        if l["dir"] == "to_world" {
            assert!(key >= last, "line {k}: {key:?} after {last:?}");
            last = key;
        } else if l["msg"]["command"] != "STOP" {
            assert_eq!(lines[k - 1]["dir"], "to_world", "line {k}");
            assert_eq!(lines[k - 1]["drone"], l["drone"], "line {k}");
            assert_eq!(lines[k - 1]["msg"]["command"], l["msg"]["command"]);
        }
    }
}
