//! docs/PROTOCOL.md claims a world server can be written in another language
//! from that page alone, and shows one in Python. This test extracts that
//! program from the page, runs it as a real process on a UNIX socket and
//! drives a whole session with the Rust blocking client, in both image
//! encodings, plus the fatal-error path of a no-reply command.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use protocol::blocking::{Client, Connection, Options};
use protocol::{Endpoint, ImageEncoding, ProtocolError, Reply, Request};

fn python_world_source() -> String {
    let doc = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/PROTOCOL.md");
    let text = std::fs::read_to_string(&doc).expect("docs/PROTOCOL.md");
    let start = text.find("```python\n").expect("a ```python block") + "```python\n".len();
    let len = text[start..].find("\n```").expect("end of the block");
    text[start..start + len].to_owned()
}

fn have_python() -> bool {
    Command::new("python3")
        .arg("--version")
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

struct World {
    child: Child,
    ep: Endpoint,
    _dir: tempfile::TempDir,
}

fn start_world() -> World {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("world.py");
    std::fs::write(&script, python_world_source()).unwrap();
    let sock: PathBuf = dir.path().join("w.sock");
    let child = Command::new("python3")
        .arg(&script)
        .arg(&sock)
        .spawn()
        .expect("start python3");
    World {
        child,
        ep: Endpoint::Unix(sock),
        _dir: dir,
    }
}

fn connect(w: &World) -> Connection {
    Client::connect_retry(&w.ep, Options::default(), Duration::from_secs(20)).unwrap()
}

#[test]
fn python_world_from_the_docs_serves_a_session() {
    if !have_python() {
        eprintln!("python3 not found: skipping the foreign-world check");
        return;
    }
    for enc in [ImageEncoding::Array, ImageEncoding::Base64] {
        let mut w = start_world();
        let mut c = connect(&w);
        let Some(Reply::InitData {
            time_s,
            timestep_ms,
            image_encoding,
            ..
        }) = c
            .request(&Request::GetInitData {
                image_encoding: Some(enc),
                drone: None,
            })
            .unwrap()
        else {
            panic!("init data")
        };
        // 2000 ms warm-up before the first request.
        assert_eq!((time_s, timestep_ms, image_encoding), (2.0, 32, enc));
        for _ in 0..3 {
            c.send(&Request::SetVelocity {
                m1: 48.0,
                m2: 48.0,
                m3: 48.0,
                m4: 48.0,
            })
            .unwrap();
        }
        c.send(&Request::AdvanceTime { time: 64 }).unwrap();
        let Some(Reply::Sensors(s)) = c.request(&Request::GetSensors).unwrap() else {
            panic!("sensors")
        };
        assert_eq!(s.time_s, 2.16); // 2000 + 3 × 32 + 64 ms
        let Some(Reply::Image(img)) = c.request(&Request::GetImage).unwrap() else {
            panic!("image")
        };
        assert_eq!((img.width, img.height), (320, 320));
        assert!(img
            .data
            .iter()
            .enumerate()
            .all(|(i, &p)| p as usize == (i % 320 + i / 320) % 256));
        assert!(matches!(
            c.request(&Request::GetData2).unwrap(),
            Some(Reply::Data2 { .. })
        ));
        // An unknown command gets an ERROR reply and the session goes on.
        let e = c.request(&Request::GetState).unwrap_err();
        assert!(
            matches!(&e, ProtocolError::Remote(m) if m == "unknown command \"GET_STATE\""),
            "{e}"
        );
        let Some(Reply::Stop { time_s, .. }) = c.request(&Request::Stop).unwrap() else {
            panic!("stop")
        };
        assert_eq!(time_s, 2.16);
        assert!(c.recv_reply().unwrap().is_none(), "closed after STOP");
        assert!(w.child.wait().unwrap().success());
    }
}

#[test]
fn python_world_treats_a_bad_no_reply_command_as_fatal() {
    if !have_python() {
        eprintln!("python3 not found: skipping the foreign-world check");
        return;
    }
    let mut w = start_world();
    let mut c = connect(&w);
    c.request(&Request::GetInitData {
        image_encoding: None,
        drone: None,
    })
    .unwrap();
    c.send(&Request::AdvanceTime { time: 10 }).unwrap();
    // The platform finds the ERROR frame at its next read.
    let e = c.request(&Request::GetSensors).unwrap_err();
    assert!(
        matches!(&e, ProtocolError::Remote(m) if m.contains("not a multiple of 32")),
        "{e}"
    );
    assert_eq!(w.child.wait().unwrap().code(), Some(1));
}
