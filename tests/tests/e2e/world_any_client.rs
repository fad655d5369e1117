//! Any client drives the world (DESIGN.md §15): a real `world-server`
//! process and a client written as a new user would write it — one thread,
//! three plain UNIX sockets, frames built by hand (4-byte little-endian
//! length + JSON) — that sends each drone's requests and then reads the
//! replies one after the other. Before §15 the second drone's reply never
//! came: the lockstep waited for the first drone's *next* request.

use crate::multi;

use std::io::{Read, Write};
use std::os::fd::{FromRawFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::{Duration, Instant};

use multi::World;
use serde_json::{json, Value};

const NAMES: [&str; 3] = ["alpha", "bravo", "charlie"];

/// Three flown drones 0.5 m apart on the ground, P2P radios without loss
/// or RSSI noise (every frame that does not collide is received).
const TRIO: &str = r#"
name = "trio"

[[drone]]
name = "alpha"
position = [0.0, 0.0, 0.015]
radios = ["p2p"]

[[drone]]
name = "bravo"
position = [0.5, 0.0, 0.015]
radios = ["p2p"]

[[drone]]
name = "charlie"
position = [0.0, 0.5, 0.015]
radios = ["p2p"]

[radio]
seed = 3
p2p_loss = 0.0
p2p_rssi_noise_db = 0.0
"#;

/// The world's basicTimeStep in these tests (`multi::World` passes 32).
const TS_MS: u64 = 32;
/// What each drone transmits (base64 of its name).
const DATA: [&str; 3] = ["YWxwaGE=", "YnJhdm8=", "Y2hhcmxpZQ=="];

/// A non-blocking `connect(2)`, as an event-loop client makes it: it must
/// succeed at once (the listen backlog holds every drone); then the socket
/// is made blocking for the plain reads and writes below.
fn connect_nonblocking(path: &Path) -> UnixStream {
    // SAFETY: a zeroed sockaddr_un filled with a path checked to fit; the
    // fd is owned from creation on.
    let fd = unsafe {
        let fd = libc::socket(
            libc::AF_UNIX,
            libc::SOCK_STREAM | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            0,
        );
        assert!(fd >= 0, "socket: {}", std::io::Error::last_os_error());
        let fd = OwnedFd::from_raw_fd(fd);
        let mut addr: libc::sockaddr_un = std::mem::zeroed();
        addr.sun_family = libc::AF_UNIX as libc::sa_family_t;
        let bytes = path.as_os_str().as_bytes();
        assert!(bytes.len() < addr.sun_path.len());
        for (d, s) in addr.sun_path.iter_mut().zip(bytes) {
            *d = *s as libc::c_char;
        }
        let len = std::mem::size_of::<libc::sockaddr_un>() as libc::socklen_t;
        let r = libc::connect(
            std::os::fd::AsRawFd::as_raw_fd(&fd),
            &addr as *const _ as *const libc::sockaddr,
            len,
        );
        assert_eq!(
            r,
            0,
            "non-blocking connect: {}",
            std::io::Error::last_os_error()
        );
        fd
    };
    let s = UnixStream::from(fd);
    s.set_nonblocking(false).unwrap();
    // A reply that never comes fails the test instead of hanging it.
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    s
}

/// Waits until the world listens on its socket.
fn wait_for_socket(path: &Path) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !path.exists() {
        assert!(Instant::now() < deadline, "world-server did not listen");
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn send(s: &mut UnixStream, msg: Value) {
    let body = serde_json::to_vec(&msg).unwrap();
    s.write_all(&(body.len() as u32).to_le_bytes()).unwrap();
    s.write_all(&body).unwrap();
}

/// The next frame, or `None` when the world closed the connection.
fn recv(s: &mut UnixStream) -> Option<Value> {
    let mut len = [0u8; 4];
    match s.read_exact(&mut len) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return None,
        Err(e) => panic!("no reply: {e}"),
    }
    let mut body = vec![0u8; u32::from_le_bytes(len) as usize];
    s.read_exact(&mut body).unwrap();
    Some(serde_json::from_slice(&body).unwrap())
}

fn reply(s: &mut UnixStream, command: &str) -> Value {
    let r = recv(s).expect("a reply");
    assert_eq!(r["command"], command, "{r}");
    r
}

/// One run of the single-threaded script; returns the world's trace and
/// radio log.
fn drive_three_drones() -> (String, String) {
    let mut w = World::start(TRIO, &["--radio-log", "radio.csv"]);
    wait_for_socket(&w.socket);
    let mut conns: Vec<UnixStream> = NAMES
        .iter()
        .map(|_| connect_nonblocking(&w.socket))
        .collect();
    // Three claims, then the three replies one after the other.
    for (c, name) in conns.iter_mut().zip(NAMES) {
        send(c, json!({"command": "GET_INIT_DATA", "drone": name}));
    }
    for (c, name) in conns.iter_mut().zip(NAMES) {
        let r = reply(c, "GET_INIT_DATA");
        assert_eq!(
            (r["drone"].as_str(), r["TIME"].as_f64()),
            (Some(name), Some(2.0))
        );
        assert_eq!(r["TIMESTEP"], TS_MS);
    }
    let mut clock = 2000;
    let mut heard = vec![Vec::new(); 3];
    for round in 0..6u64 {
        // The radio round: each drone asks, the reply is read before the
        // next drone asks (bravo's must not wait for alpha's next request).
        for (d, c) in conns.iter_mut().enumerate() {
            send(c, json!({"command": "RADIO_RECV"}));
            let r = reply(c, "RADIO_RECV");
            for p in r["packets"].as_array().unwrap() {
                let t = p["time_ps"].as_u64().unwrap();
                assert!(t <= clock * 1_000_000_000, "{p} at {clock} ms");
                heard[d].push((round, p["from"].as_str().unwrap().to_string()));
            }
        }
        // Lockstep checks: every drone reads the same world time, each
        // its own reply right after its request.
        for c in conns.iter_mut() {
            send(c, json!({"command": "GET_STATE"}));
            let r = reply(c, "GET_STATE");
            assert_eq!(r["TIME"].as_f64(), Some(clock as f64 / 1000.0), "{r}");
            assert_eq!(r["DRONE_DISTANCES"].as_object().unwrap().len(), 2);
        }
        // Transmit (staggered by 5 ms so the frames do not collide) and
        // step: nothing to read.
        for (d, c) in conns.iter_mut().enumerate() {
            let offset_ps = d as u64 * 5_000_000_000;
            send(
                c,
                json!({"command": "RADIO_SEND", "radio": "p2p", "data": DATA[d], "offset_ps": offset_ps}),
            );
            send(
                c,
                json!({"command": "SET_VELOCITY", "m1": 100.0, "m2": 100.0, "m3": 100.0, "m4": 100.0}),
            );
        }
        clock += TS_MS;
        // A drone's sensors, then the next drone's, last drone first (its
        // reply needs the physics at the new time before alpha asks): the
        // same time for all.
        for c in conns.iter_mut().rev() {
            send(c, json!({"command": "GET_SENSORS"}));
            let r = reply(c, "GET_SENSORS");
            assert_eq!(r["TIME"].as_f64(), Some(clock as f64 / 1000.0), "{r}");
        }
    }
    // Every drone heard the two others in every round after the first.
    for (d, h) in heard.iter().enumerate() {
        for round in 1..6 {
            let mut from: Vec<&str> = h
                .iter()
                .filter(|(r, _)| *r == round)
                .map(|(_, f)| f.as_str())
                .collect();
            from.sort_unstable();
            let others: Vec<&str> = NAMES.iter().copied().filter(|n| *n != NAMES[d]).collect();
            assert_eq!(from, others, "{} in round {round}", NAMES[d]);
        }
    }
    // STOP: a reply comes when the propellers stand still, which needs the
    // others out of the lockstep too: send the three, then read.
    for c in conns.iter_mut() {
        send(c, json!({"command": "STOP"}));
    }
    for c in conns.iter_mut() {
        let r = reply(c, "STOP");
        assert!(r["TIME"].as_f64().unwrap() >= clock as f64 / 1000.0, "{r}");
        assert!(recv(c).is_none(), "closed after STOP");
    }
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
    (w.read("world.trace"), w.read("radio.csv"))
}

#[test]
fn one_thread_drives_three_drones_twice_with_identical_traces() {
    let (trace, radio) = drive_three_drones();
    // The trace keeps the canonical order (time, drone) of DESIGN.md §7,
    // each reply right after its request, although the replies left
    // earlier.
    let lines = multi::trace_lines(&trace);
    multi::assert_canonical_order(&lines, &NAMES);
    let replies = lines.iter().filter(|l| l["dir"] == "to_platform").count();
    // 3 claims + 6 rounds × 3 drones × 3 queries + 3 STOPs.
    assert_eq!(replies, 3 + 6 * 3 * 3 + 3);
    let again = drive_three_drones();
    assert!(
        trace == again.0,
        "the world's traces differ between two runs"
    );
    assert!(radio == again.1, "the radio logs differ between two runs");
}

#[test]
fn a_connection_after_every_drone_is_claimed_gets_error_at_once() {
    let two = TRIO.replace(
        "[[drone]]\nname = \"charlie\"\nposition = [0.0, 0.5, 0.015]\nradios = [\"p2p\"]\n",
        "",
    );
    let mut w = World::start(&two, &[]);
    wait_for_socket(&w.socket);
    let mut conns: Vec<UnixStream> = (0..2).map(|_| connect_nonblocking(&w.socket)).collect();
    for (c, name) in conns.iter_mut().zip(NAMES) {
        send(c, json!({"command": "GET_INIT_DATA", "drone": name}));
    }
    for c in conns.iter_mut() {
        reply(c, "GET_INIT_DATA");
    }
    // Late: one that claims a drone already flown, one that sends nothing.
    for claim in [true, false] {
        let mut late = connect_nonblocking(&w.socket);
        if claim {
            send(
                &mut late,
                json!({"command": "GET_INIT_DATA", "drone": "alpha"}),
            );
        }
        let started = Instant::now();
        let r = reply(&mut late, "ERROR");
        assert_eq!(r["error"], "every drone is claimed");
        assert!(started.elapsed() < Duration::from_secs(5));
        assert!(recv(&mut late).is_none(), "closed after the ERROR");
    }
    // The run goes on untouched.
    for c in conns.iter_mut() {
        send(c, json!({"command": "GET_SENSORS"}));
        assert_eq!(reply(c, "GET_SENSORS")["TIME"], 2.0);
    }
    for c in conns.iter_mut() {
        send(c, json!({"command": "STOP"}));
    }
    for c in conns.iter_mut() {
        reply(c, "STOP");
    }
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
    assert!(err.contains("after every drone was claimed"), "{err}");
}
