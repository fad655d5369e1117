//! End-to-end tests of a world with several drones (DESIGN.md §7,
//! docs/SWARM.md §1–§2): a real `world-server` process and hand-written
//! platforms over real sockets, one thread each.

use crate::multi;

use std::thread;
use std::time::{Duration, Instant};

use multi::{error_of, init, set_velocity, stop, time_of, trace_lines, World};
use protocol::{Reply, Request};

const THREE: &str = r#"
name = "three"

[[drone]]
name = "A"
position = [0.0, 0.0, 0.015]

[[drone]]
name = "B"
position = [0.5, 0.0, 0.015]
yaw = 1.5707963267948966

[[drone]]
name = "C"
carried = [[0.0, 0.0, 1.0, 1.0], [2.5, 0.0, 1.0, 1.0], [4.0, 0.5, 1.0, 1.0]]
"#;

#[test]
fn three_drones_claim_and_run_in_lockstep() {
    let mut w = World::start(THREE, &[]);
    let names = ["A", "B", "C"];
    // Every platform's script: (its GET_STATE times, its STOP reply).
    let clients: Vec<_> = names
        .iter()
        .enumerate()
        .map(|(i, &name)| {
            let w_socket = w.socket.clone();
            thread::spawn(move || {
                let mut c = protocol::blocking::Client::connect_retry(
                    &protocol::Endpoint::Unix(w_socket),
                    Default::default(),
                    Duration::from_secs(30),
                )
                .unwrap();
                let init = c.request(&init(Some(name))).unwrap();
                let Some(Reply::InitData {
                    time_s, drone, x, ..
                }) = init
                else {
                    panic!("{init:?}")
                };
                assert_eq!((time_s, drone.as_deref()), (2.0, Some(name)));
                assert!((x - [0.0, 0.5, 0.0][i]).abs() < 1e-3, "{name}: x {x}");
                // Each drone its own pace: i + 1 steps per iteration.
                let mut clock = 2000u64;
                let mut states = Vec::new();
                for _ in 0..5 {
                    for _ in 0..=i {
                        c.send(&set_velocity(20.0)).unwrap();
                        clock += 32;
                    }
                    c.send(&Request::AdvanceTime { time: 64 }).unwrap();
                    clock += 64;
                    // Every reply comes at the drone's own clock.
                    assert_eq!(time_of(&mut c), clock as f64 / 1000.0);
                    match c.request(&Request::GetState).unwrap() {
                        Some(Reply::State(s)) => {
                            assert_eq!(s.time_s, clock as f64 / 1000.0);
                            let d = s.drone_distances.unwrap();
                            let others: Vec<&str> = d.keys().map(String::as_str).collect();
                            let expect: Vec<&str> =
                                names.iter().copied().filter(|n| *n != name).collect();
                            assert_eq!(others, expect);
                            states.push((clock, d));
                        }
                        other => panic!("{other:?}"),
                    }
                }
                (states, stop(&mut c))
            })
        })
        .collect();
    let results: Vec<_> = clients.into_iter().map(|h| h.join().unwrap()).collect();
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
    // A and B are both at 2384 ms once (A steps 96 ms per iteration, B
    // 128 ms): the distance each sees is the same.
    let at = |d: usize, t: u64| results[d].0.iter().find(|(c, _)| *c == t).map(|x| &x.1);
    let (a, b) = (at(0, 2384).unwrap(), at(1, 2384).unwrap());
    assert_eq!(a["B"], b["A"]);
    assert!((a["B"] - 0.5).abs() < 1e-3, "{a:?}");
    // C is carried: held at (0, 1, 1) until 2.5 s; A rests on the ground.
    assert!(
        (a["C"] - (1.0 + 0.985f64.powi(2)).sqrt()).abs() < 1e-3,
        "{a:?}"
    );
    // A and C are both at 2480 ms.
    let (a, c) = (at(0, 2480).unwrap(), at(2, 2480).unwrap());
    assert_eq!(a["C"], c["A"]);
    // STOP: the carried drone's propellers never turned.
    assert_eq!(results[2].1 .1, 0);
    for (d, r) in results.iter().enumerate() {
        let (time_s, stop_ms) = r.1;
        let clock = 2000 + 5 * (32 * (d as u64 + 1) + 64);
        assert_eq!(time_s, (clock + stop_ms) as f64 / 1000.0, "drone {d}");
    }
    // The trace: a drone field on every line, processed in (time, drone)
    // order, each reply right after its request.
    let lines = trace_lines(&w.read("world.trace"));
    multi::assert_canonical_order(&lines, &names);
    // The trajectory: one row per drone per step, a drone column second.
    let traj = w.read("traj.csv");
    let mut rows = traj.lines();
    assert!(rows.next().unwrap().starts_with("time_ms,drone,x,y,z,"));
    let rows: Vec<Vec<&str>> = rows.map(|r| r.split(',').collect()).collect();
    assert_eq!(rows.len() % 3, 0);
    for step in rows.chunks(3) {
        assert_eq!(step.iter().map(|r| r[1]).collect::<Vec<_>>(), names);
        assert!(step.iter().all(|r| r[0] == step[0][0]));
    }
    assert_eq!(rows[62 * 3][0], "2000", "the common warm-up");
}

#[test]
fn a_fast_platform_waits_for_a_slow_one() {
    let two = "[[drone]]\nname = \"A\"\nposition = [0.0, 0.0, 0.015]\n\
               [[drone]]\nname = \"B\"\nposition = [1.0, 0.0, 0.015]\n";
    let mut w = World::start(two, &[]);
    let sock = w.socket.clone();
    let b = thread::spawn(move || {
        let w = World::attach(sock);
        let mut c = w.claim("B");
        thread::sleep(Duration::from_millis(400));
        let sent = Instant::now();
        c.send(&set_velocity(10.0)).unwrap();
        assert_eq!(time_of(&mut c), 2.032);
        stop(&mut c);
        sent
    });
    let mut a = w.claim("A");
    a.send(&set_velocity(10.0)).unwrap();
    // A's request at 2032 ms can only be answered once B has passed 2000.
    assert_eq!(time_of(&mut a), 2.032);
    let answered = Instant::now();
    stop(&mut a);
    let b_sent = b.join().unwrap();
    assert!(answered >= b_sent, "A was answered before B moved on");
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
}

/// A script of requests whose contents depend on what the world answers,
/// run by one platform; `pause` before every request.
fn script(w_socket: std::path::PathBuf, name: &'static str, pause: Duration) -> Vec<String> {
    let w = World::attach(w_socket);
    let mut c = w.claim(name);
    let mut replies = Vec::new();
    let mut ask = |c: &mut protocol::blocking::Connection, r: &Request| {
        thread::sleep(pause);
        let reply = c.request(r).unwrap();
        replies.push(format!("{reply:?}"));
        reply
    };
    for k in 0..40u64 {
        let z = match ask(&mut c, &Request::GetSensors) {
            Some(Reply::Sensors(s)) => s.z,
            other => panic!("{other:?}"),
        };
        // Full power until 0.3 m, then less: the commands follow the world.
        let m = if z < 0.3 { 70.0 } else { 40.0 };
        ask(&mut c, &set_velocity(m));
        if k % 8 == 3 {
            ask(&mut c, &Request::AdvanceTime { time: 64 });
            ask(&mut c, &Request::GetState);
            // The three drones' clocks agree: 0.4 ms apart on the air
            // (a 2-byte frame lasts ~0.16 ms), or they would all collide.
            let slot = u64::from(name.as_bytes()[0] - b'A');
            ask(
                &mut c,
                &Request::RadioSend {
                    radio: protocol::Radio::Uwb,
                    data: vec![name.as_bytes()[0], k as u8],
                    offset_ps: 1000 * k + slot * 400_000_000,
                },
            );
            ask(&mut c, &Request::RadioRecv);
        }
    }
    thread::sleep(pause);
    let (t, ms) = stop(&mut c);
    replies.push(format!("STOP {t} {ms}"));
    replies
}

#[test]
fn a_slow_platform_does_not_change_the_run() {
    // Two flown drones side by side, a carried one passing over them.
    let world = format!("{THREE}\n[radio]\nseed = 3\n");
    let run = |slow: Option<&'static str>| {
        let mut w = World::start(&world, &["--radio-log", "radio.csv"]);
        let handles: Vec<_> = ["A", "B", "C"]
            .into_iter()
            .map(|name| {
                let sock = w.socket.clone();
                let pause = if slow == Some(name) {
                    Duration::from_millis(3)
                } else {
                    Duration::ZERO
                };
                thread::spawn(move || script(sock, name, pause))
            })
            .collect();
        let replies: Vec<Vec<String>> = handles.into_iter().map(|h| h.join().unwrap()).collect();
        let (status, err) = w.finish();
        assert!(status.success(), "{err}");
        (
            replies,
            w.read("world.trace"),
            w.read("traj.csv"),
            w.read("radio.csv"),
        )
    };
    let reference = run(None);
    assert!(
        reference.3.lines().any(|l| l.contains(",received,")),
        "the drones heard each other:\n{}",
        reference.3
    );
    for slow in ["A", "B", "C"] {
        let other = run(Some(slow));
        assert!(other.0 == reference.0, "{slow} slow: the replies differ");
        assert!(
            other.1 == reference.1,
            "{slow} slow: the world traces differ"
        );
        assert!(
            other.2 == reference.2,
            "{slow} slow: the trajectories differ"
        );
        assert!(other.3 == reference.3, "{slow} slow: the radio logs differ");
    }
}

#[test]
fn claims_of_unknown_duplicate_or_unnamed_drones_are_refused() {
    let two = "[[drone]]\nname = \"A\"\nposition = [0.0, 0.0, 0.015]\n\
               [[drone]]\nname = \"B\"\nposition = [1.0, 0.0, 0.015]\n";
    let mut w = World::start(two, &[]);
    let refused = |req: &Request| {
        let mut c = w.connect();
        let e = error_of(&mut c, req);
        assert!(c.recv_raw().unwrap().is_none(), "closed after the ERROR");
        e
    };
    let e = refused(&init(Some("Z")));
    assert!(
        e.contains("unknown drone \"Z\"") && e.contains("A, B"),
        "{e}"
    );
    let e = refused(&init(None));
    assert!(e.contains("must claim one with \"drone\""), "{e}");
    let e = refused(&Request::GetSensors);
    assert!(e.contains("first request must be GET_INIT_DATA"), "{e}");
    // A connection that closes without a word is forgotten.
    drop(w.connect());
    // Two platforms claim A: whichever comes second is refused at once,
    // the first waits for the start.
    let (tx, rx) = std::sync::mpsc::channel();
    for _ in 0..2 {
        let (sock, tx) = (World::attach(w.socket.clone()), tx.clone());
        thread::spawn(move || {
            let mut c = sock.connect();
            let r = match c.request(&init(Some("A"))) {
                Ok(Some(Reply::InitData { drone, .. })) => {
                    assert_eq!(drone.as_deref(), Some("A"));
                    Ok(c)
                }
                Err(protocol::ProtocolError::Remote(e)) => Err(e),
                other => panic!("{other:?}"),
            };
            tx.send(r).unwrap();
        });
    }
    let loser = rx.recv().unwrap().map(|_| ()).unwrap_err();
    assert!(loser.contains("drone \"A\" is already claimed"), "{loser}");
    // B's GET_INIT_DATA is answered at 2000 ms too, but after A's next
    // request (A before B at equal times): B waits in its own thread.
    let sock = World::attach(w.socket.clone());
    let b = thread::spawn(move || {
        let mut b = sock.claim("B");
        stop(&mut b);
    });
    let mut a = rx.recv().unwrap().unwrap();
    stop(&mut a);
    b.join().unwrap();
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
    assert!(err.contains("claim refused"), "{err}");
}

#[test]
fn a_single_drone_world_accepts_its_name_and_refuses_others() {
    let one = "[start]\nposition = [0.0, 0.0, 0.015]\n";
    let mut w = World::start(one, &[]);
    let mut c = w.connect();
    let e = error_of(&mut c, &init(Some("A")));
    assert!(
        e.contains("unknown drone \"A\"") && e.contains("cf1"),
        "{e}"
    );
    let mut c = w.connect();
    match c.request(&init(Some("cf1"))).unwrap() {
        // No drone key in a single-drone reply.
        Some(Reply::InitData { drone, .. }) => assert_eq!(drone, None),
        other => panic!("{other:?}"),
    }
    stop(&mut c);
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
    // No drone field on the lines (the claim's frame itself names cf1).
    let lines = trace_lines(&w.read("world.trace"));
    assert!(lines.iter().all(|l| l.get("drone").is_none()));
    assert!(lines[0]["msg"]["drone"] == "cf1");
}

#[test]
fn unclaimed_drones_end_the_run_after_the_connect_timeout() {
    let mut w = World::start(THREE, &["--connect-timeout", "1.5"]);
    let mut a = w.connect();
    let started = Instant::now();
    let e = error_of(&mut a, &init(Some("A")));
    assert!(
        e.contains("\"B\", \"C\"") && e.contains("--connect-timeout"),
        "{e}"
    );
    let (status, err) = w.finish();
    assert!(started.elapsed() >= Duration::from_millis(1400));
    assert!(!status.success());
    assert!(
        err.contains("no platform claimed drones \"B\", \"C\""),
        "{err}"
    );
}

#[test]
fn a_platform_gone_before_stop_ends_the_run_for_everyone() {
    let mut w = World::start(THREE, &[]);
    let sock = w.socket.clone();
    // C is waiting for a reply the lockstep holds back when A leaves.
    let c = thread::spawn(move || {
        let w = World::attach(sock);
        let mut c = w.claim("C");
        c.send(&Request::AdvanceTime { time: 320 }).unwrap();
        error_of(&mut c, &Request::GetSensors)
    });
    let sock = w.socket.clone();
    let b = thread::spawn(move || {
        let w = World::attach(sock);
        let mut b = w.claim("B");
        let mut steps = 0;
        // B flies on until the world tells it the run is over.
        loop {
            b.send(&set_velocity(10.0)).unwrap();
            steps += 1;
            match b.request(&Request::GetSensors) {
                Ok(_) => assert!(steps < 1000),
                Err(protocol::ProtocolError::Remote(e)) => return (e, steps),
                Err(e) => panic!("{e}"),
            }
        }
    });
    let mut a = w.claim("A");
    for _ in 0..3 {
        a.send(&set_velocity(10.0)).unwrap();
    }
    assert_eq!(time_of(&mut a), 2.096);
    drop(a); // killed
    let (b_error, b_steps) = b.join().unwrap();
    let c_error = c.join().unwrap();
    for e in [&b_error, &c_error] {
        assert!(
            e.contains("drone A: the platform disconnected before STOP"),
            "{e}"
        );
    }
    // A left at 2096 ms: B's requests before were served; the one at 2096
    // is answered if it arrives before A's disconnection (DESIGN.md §15: a
    // reply never waits for another drone's next request), else it meets
    // the end of the run; B's next one, at 2128 ms, never comes.
    assert!(
        (3..=4).contains(&b_steps),
        "B served up to A's clock: {b_steps}"
    );
    let (status, err) = w.finish();
    assert!(!status.success());
    assert!(
        err.contains("drone A: the platform disconnected before STOP"),
        "{err}"
    );
    // The outputs were flushed: the trace ends with the ERRORs.
    let lines = trace_lines(&w.read("world.trace"));
    let errors: Vec<_> = lines
        .iter()
        .filter(|l| l["msg"]["command"] == "ERROR")
        .map(|l| l["drone"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(errors, ["B", "C"]);
}

#[test]
fn a_bad_request_ends_the_run_for_everyone() {
    let two = "[[drone]]\nname = \"A\"\nposition = [0.0, 0.0, 0.015]\n\
               [[drone]]\nname = \"B\"\nposition = [1.0, 0.0, 0.015]\n";
    let mut w = World::start(two, &[]);
    let sock = w.socket.clone();
    // B's claim is answered at once (DESIGN.md §15: every clock is at
    // 2000 ms); its next reply, at 2032 ms, needs A's clock there: it meets
    // the end of the run, A's bad request.
    let b = thread::spawn(move || World::attach(sock).claim_step_and_fail("B"));
    let mut a = w.claim("A");
    a.send_raw(br#"{"command":"ADVANCE_TIME","time":33}"#)
        .unwrap();
    let own = match a.recv_reply().unwrap() {
        Some(Reply::Error { error }) => error,
        other => panic!("{other:?}"),
    };
    // The world closes after the ERROR; the platform leaves, so the world
    // need not wait for it (server::DRAIN).
    assert!(a.recv_raw().unwrap().is_none());
    drop(a);
    assert!(
        own.contains("not a multiple") && !own.contains("drone A"),
        "{own}"
    );
    let other = b.join().unwrap();
    assert!(
        other.starts_with("drone A: ") && other.contains("not a multiple"),
        "{other}"
    );
    let (status, err) = w.finish();
    assert!(!status.success());
    assert!(err.contains("not a multiple"), "{err}");
}
