//! Real sockets: a tiny world served by each transport, a platform client of
//! each transport, and the UNIX-socket rules (stale file, 0600, live server).

use std::io::Write;
use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::{Arc, Mutex};
use std::thread;

use futures::{SinkExt, StreamExt};
use protocol::blocking::{Client, Server};
use protocol::tokio_transport::{self, Listener};
use protocol::trace::{TraceClock, TraceReader, TraceWriter};
use protocol::{
    sha256_hex, Endpoint, Image, ImageEncoding, ProtocolError, Reply, Request, Sensors,
};

/// A world that is easy to check: time advances by 32 ms per SET_VELOCITY
/// and by `time` per ADVANCE_TIME; GET_SENSORS reports the last motor
/// command in its fields; the image's pixels depend on the time.
#[derive(Default)]
struct TinyWorld {
    ms: u64,
    last_m: [f64; 4],
}

impl TinyWorld {
    fn image(&self) -> Image {
        let data = (0..40 * 30)
            .map(|i| ((i as u64 + self.ms) % 256) as u8)
            .collect();
        Image {
            width: 40,
            height: 30,
            data,
        }
    }

    fn handle(&mut self, req: &Request) -> Option<Reply> {
        match *req {
            Request::GetInitData { image_encoding, .. } => Some(Reply::InitData {
                x: -2.6,
                y: 0.0,
                z: 0.015,
                time_s: 2.0,
                timestep_ms: 32,
                image_encoding: image_encoding.unwrap_or_default(),
                drone: None,
            }),
            Request::SetVelocity { m1, m2, m3, m4 } => {
                self.last_m = [m1, m2, m3, m4];
                self.ms += 32;
                None
            }
            Request::AdvanceTime { time } => {
                self.ms += time;
                None
            }
            Request::GetSensors => Some(Reply::Sensors(Sensors {
                time_s: self.ms as f64 / 1000.0,
                x: self.last_m[0],
                y: self.last_m[1],
                z: self.last_m[2],
                altitude: self.last_m[3],
                roll: 0.0,
                pitch: 0.0,
                yaw: 0.0,
                roll_rate: 0.0,
                pitch_rate: 0.0,
                yaw_rate: 0.0,
                range_front: 2000.0,
                range_left: 2000.0,
                range_back: 2000.0,
                range_right: 2000.0,
                ..Sensors::default()
            })),
            Request::GetImage => Some(Reply::Image(self.image())),
            Request::Stop => Some(Reply::Stop {
                time_s: self.ms as f64 / 1000.0,
                stop_time_ms: 0,
                gates_passed: None,
            }),
            _ => Some(Reply::error(format!("{} not supported", req.command()))),
        }
    }
}

/// The blocking world: serves one client, stops after STOP.
fn blocking_world(server: Server) -> thread::JoinHandle<u64> {
    thread::spawn(move || {
        let mut conn = server.accept().unwrap();
        let mut w = TinyWorld::default();
        let mut frames = 0;
        while let Some(req) = conn.recv_request().unwrap() {
            frames += 1;
            let stop = req == Request::Stop;
            if let Some(r) = w.handle(&req) {
                conn.send_reply(&r).unwrap();
            }
            if stop {
                break;
            }
        }
        frames
    })
}

/// The tokio world, same behaviour.
async fn tokio_world(listener: Listener) -> u64 {
    let mut conn = listener.accept().await.unwrap();
    let mut w = TinyWorld::default();
    let mut frames = 0;
    while let Some(req) = conn.next().await {
        let req = req.unwrap();
        frames += 1;
        let stop = req == Request::Stop;
        if let Some(r) = w.handle(&req) {
            conn.send(&r).await.unwrap();
        }
        if stop {
            break;
        }
    }
    frames
}

/// The lockstep session a platform runs, blocking transport.
fn blocking_platform(ep: &Endpoint, enc: ImageEncoding) {
    let mut c = Client::connect(ep).unwrap();
    let init = c
        .request(&Request::GetInitData {
            image_encoding: Some(enc),
            drone: None,
        })
        .unwrap()
        .unwrap();
    assert!(
        matches!(init, Reply::InitData { timestep_ms: 32, image_encoding, .. } if image_encoding == enc)
    );
    for k in 0..3 {
        assert_eq!(
            c.request(&Request::SetVelocity {
                m1: 48.0 + k as f64,
                m2: 49.0,
                m3: 50.0,
                m4: 51.5,
            })
            .unwrap(),
            None
        );
    }
    c.send(&Request::AdvanceTime { time: 64 }).unwrap();
    let Some(Reply::Sensors(s)) = c.request(&Request::GetSensors).unwrap() else {
        panic!("sensors")
    };
    assert_eq!(s.time_s, 0.16); // 3 × 32 + 64 ms
    assert_eq!((s.x, s.y, s.z, s.altitude), (50.0, 49.0, 50.0, 51.5));
    let Some(Reply::Image(img)) = c.request(&Request::GetImage).unwrap() else {
        panic!("image")
    };
    assert_eq!(
        img,
        TinyWorld {
            ms: 160,
            ..Default::default()
        }
        .image()
    );
    // An ERROR reply is an error for the caller.
    let e = c.request(&Request::GetData2).unwrap_err();
    assert!(
        matches!(&e, ProtocolError::Remote(m) if m == "GET_DATA_2 not supported"),
        "{e}"
    );
    let Some(Reply::Stop { time_s, .. }) = c.request(&Request::Stop).unwrap() else {
        panic!("stop")
    };
    assert_eq!(time_s, 0.16);
    // The world closed after STOP: a clean end of stream.
    assert!(c.recv_reply().unwrap().is_none());
}

fn sock(dir: &tempfile::TempDir, name: &str) -> Endpoint {
    Endpoint::Unix(dir.path().join(name))
}

#[test]
fn blocking_platform_with_tokio_world_over_unix_socket() {
    let dir = tempfile::tempdir().unwrap();
    let ep = sock(&dir, "w.sock");
    for enc in [ImageEncoding::Array, ImageEncoding::Base64] {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let listener = rt.block_on(Listener::bind(&ep)).unwrap();
        let world = thread::spawn(move || rt.block_on(tokio_world(listener)));
        blocking_platform(&ep, enc);
        assert_eq!(world.join().unwrap(), 9);
    }
}

#[test]
fn tokio_platform_with_blocking_world_over_unix_socket() {
    let dir = tempfile::tempdir().unwrap();
    let ep = sock(&dir, "w.sock");
    let world = blocking_world(Server::bind(&ep).unwrap());
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let mut c = tokio_transport::connect(&ep).await.unwrap();
        c.send(&Request::GetInitData {
            image_encoding: Some(ImageEncoding::Base64),
            drone: None,
        })
        .await
        .unwrap();
        assert!(matches!(
            c.next().await.unwrap().unwrap(),
            Reply::InitData {
                image_encoding: ImageEncoding::Base64,
                ..
            }
        ));
        c.send(&Request::AdvanceTime { time: 96 }).await.unwrap();
        c.send(&Request::GetImage).await.unwrap();
        match c.next().await.unwrap().unwrap() {
            Reply::Image(img) => assert_eq!(
                img,
                TinyWorld {
                    ms: 96,
                    ..Default::default()
                }
                .image()
            ),
            r => panic!("{r:?}"),
        }
        c.send(&Request::Stop).await.unwrap();
        assert!(matches!(
            c.next().await.unwrap().unwrap(),
            Reply::Stop { time_s, .. } if time_s == 0.096
        ));
        assert!(c.next().await.is_none(), "clean close after STOP");
    });
    assert_eq!(world.join().unwrap(), 4);
}

#[test]
fn tcp_endpoint_works_too() {
    let server = Server::bind(&"tcp:127.0.0.1:0".parse().unwrap()).unwrap();
    let ep = server.local_endpoint().unwrap();
    let world = blocking_world(server);
    blocking_platform(&ep, ImageEncoding::Array);
    assert_eq!(world.join().unwrap(), 9);
}

#[test]
fn unix_socket_rules() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.sock");
    let ep = Endpoint::Unix(path.clone());

    // A stale socket file (its server is gone) is replaced.
    drop(UnixListener::bind(&path).unwrap());
    assert!(path.exists());
    let server = Server::bind(&ep).unwrap();
    // Owner-only permissions.
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "socket mode {mode:o}");

    // A live server keeps its path, with a clear message.
    let e = Server::bind(&ep).unwrap_err();
    assert!(matches!(e, ProtocolError::AddrInUse { .. }), "{e}");
    assert!(e.to_string().contains("in use by a live server"), "{e}");
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let e = rt.block_on(Listener::bind(&ep)).err().unwrap();
    assert!(matches!(e, ProtocolError::AddrInUse { .. }), "{e}");

    // Dropping the server removes its file.
    drop(server);
    assert!(!path.exists());

    // The tokio listener: same mode, same cleanup.
    let l = rt.block_on(Listener::bind(&ep)).unwrap();
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    drop(l);
    assert!(!path.exists());

    // A regular file is never removed.
    std::fs::write(&path, b"precious").unwrap();
    let e = Server::bind(&ep).unwrap_err();
    assert!(e.to_string().contains("not a socket"), "{e}");
    assert_eq!(std::fs::read(&path).unwrap(), b"precious");
}

#[test]
fn truncated_and_clean_ends_over_a_real_socket() {
    let dir = tempfile::tempdir().unwrap();
    let ep = sock(&dir, "w.sock");
    let Endpoint::Unix(path) = ep.clone() else {
        unreachable!()
    };
    let server = Server::bind(&ep).unwrap();
    let t = thread::spawn(move || {
        // Client 1: a complete frame, then half of one.
        let mut s = UnixStream::connect(&path).unwrap();
        s.write_all(b"\x12\x00\x00\x00{\"command\":\"STOP\"}")
            .unwrap();
        s.write_all(b"\x12\x00\x00\x00{\"comm").unwrap();
        drop(s);
        // Client 2: connects and leaves without a byte.
        drop(UnixStream::connect(&path).unwrap());
    });
    let mut c = server.accept().unwrap();
    assert_eq!(c.recv_request().unwrap(), Some(Request::Stop));
    let e = c.recv_request().unwrap_err();
    assert!(
        matches!(
            e,
            ProtocolError::Truncated {
                expected: 18,
                got: 6
            }
        ),
        "{e}"
    );
    let mut c = server.accept().unwrap();
    assert_eq!(c.recv_request().unwrap(), None);
    t.join().unwrap();
}

/// Both ends trace the same run: the two traces hold the same messages in
/// the same order, images as SHA-256 of the pixels.
#[test]
fn both_ends_trace_the_same_frames() {
    let dir = tempfile::tempdir().unwrap();
    let ep = sock(&dir, "w.sock");
    let world_trace = dir.path().join("world.jsonl");
    let platform_trace = dir.path().join("platform.jsonl");

    let server = Server::bind(&ep).unwrap();
    let wt = world_trace.clone();
    let world = thread::spawn(move || {
        let mut conn = server.accept().unwrap();
        let w = Arc::new(Mutex::new(TinyWorld::default()));
        let mut tw = TraceWriter::create(&wt, TraceClock::WorldMs, false).unwrap();
        let w2 = w.clone();
        conn.set_observer(Box::new(move |ev| {
            let now = w2.lock().unwrap().ms;
            tw.record(ev, now)?;
            tw.flush()
        }));
        while let Some(req) = conn.recv_request().unwrap() {
            let r = w.lock().unwrap().handle(&req);
            if let Some(r) = r {
                conn.send_reply(&r).unwrap();
            }
            if req == Request::Stop {
                break;
            }
        }
    });

    let mut c = Client::connect(&ep).unwrap();
    let mut tp = TraceWriter::create(&platform_trace, TraceClock::PlatformPs, false).unwrap();
    let mut ps = 0u64;
    c.set_observer(Box::new(move |ev| {
        ps += 1_000_000; // the test's stand-in for the platform clock
        tp.record(ev, ps)?;
        tp.flush()
    }));
    for req in [
        Request::GetInitData {
            image_encoding: None,
            drone: None,
        },
        Request::SetVelocity {
            m1: 1.0,
            m2: 2.0,
            m3: 3.0,
            m4: 4.0,
        },
        Request::GetImage,
        Request::Stop,
    ] {
        c.request(&req).unwrap();
    }
    drop(c);
    world.join().unwrap();

    let read = |p| {
        let mut r = TraceReader::open(p).unwrap();
        let v: Vec<_> = r.by_ref().map(Result::unwrap).collect();
        assert_eq!(r.truncated(), None);
        v
    };
    let (w, p) = (read(&world_trace), read(&platform_trace));
    assert_eq!(w.len(), 7); // 4 requests + 3 replies
    assert_eq!(
        w.iter()
            .map(|r| (r.seq, r.dir, r.len, &r.msg))
            .collect::<Vec<_>>(),
        p.iter()
            .map(|r| (r.seq, r.dir, r.len, &r.msg))
            .collect::<Vec<_>>()
    );
    assert!(w
        .iter()
        .all(|r| r.world_ms.is_some() && r.platform_ps.is_none()));
    assert!(p
        .iter()
        .all(|r| r.platform_ps.is_some() && r.world_ms.is_none()));
    let img = &w[4];
    assert_eq!(img.command(), Some("GET_IMAGE"));
    assert_eq!(
        img.msg["camera"]["sha256"],
        sha256_hex(
            &TinyWorld {
                ms: 32,
                ..Default::default()
            }
            .image()
            .data
        )
    );
    assert_eq!(img.msg["camera"]["width"], 40);
    assert!(img.msg["camera"].get("data").is_none());
    // Real frame length, not the length of the trace's summary.
    assert!(img.len > 40 * 30);
    assert_eq!(
        w[2].msg,
        serde_json::json!({"command":"SET_VELOCITY","m1":1.0,"m2":2.0,"m3":3.0,"m4":4.0})
    );
}

/// The world answers a bad no-reply command with ERROR and closes; the
/// platform's next write fails, and the ERROR it left is what gets reported.
#[test]
fn error_left_by_a_closed_world_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let ep = sock(&dir, "w.sock");
    let server = Server::bind(&ep).unwrap();
    let world = thread::spawn(move || {
        let mut conn = server.accept().unwrap();
        let req = conn.recv_request().unwrap().unwrap();
        assert_eq!(req, Request::AdvanceTime { time: 10 });
        conn.send_reply(&Reply::error("time 10 is not a multiple of 32 ms"))
            .unwrap();
    });
    let mut c = Client::connect(&ep).unwrap();
    c.send(&Request::AdvanceTime { time: 10 }).unwrap();
    world.join().unwrap(); // the world has closed
    let e = c.request(&Request::GetSensors).unwrap_err();
    assert!(
        matches!(&e, ProtocolError::Remote(m) if m == "time 10 is not a multiple of 32 ms"),
        "{e}"
    );
}

/// DESIGN.md §15: a world of N drones listens with a backlog of N, so that
/// one client may connect every drone with non-blocking connects (tokio's,
/// Python's asyncio) before the world accepts any. With the thesis's
/// backlog of 1 the kernel holds two and the third connect fails with
/// EAGAIN.
#[test]
fn the_backlog_holds_every_drone_s_connection() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let connect_all = |ep: &Endpoint, n: usize| -> Vec<std::io::Result<tokio::net::UnixStream>> {
        let Endpoint::Unix(path) = ep else {
            unreachable!()
        };
        // Nothing accepts: every connection waits in the backlog.
        (0..n)
            .map(|_| rt.block_on(tokio::net::UnixStream::connect(path)))
            .collect()
    };
    let ep = sock(&dir, "eight.sock");
    let l = rt
        .block_on(Listener::bind_backlog(
            &ep,
            protocol::frame::DEFAULT_MAX_FRAME,
            8,
        ))
        .unwrap();
    for (k, c) in connect_all(&ep, 8).into_iter().enumerate() {
        assert!(c.is_ok(), "connection {k}: {:?}", c.err());
    }
    drop(l);
    let ep = sock(&dir, "one.sock");
    let _l = rt.block_on(Listener::bind(&ep)).unwrap();
    let conns = connect_all(&ep, 3);
    let e = conns[2].as_ref().expect_err("a backlog of 1 holds two");
    assert_eq!(e.kind(), std::io::ErrorKind::WouldBlock, "{e}");
}
