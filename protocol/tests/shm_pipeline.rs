//! Images in shared memory (`"image_encoding":"shm"`) and pipelining
//! (docs/PROTOCOL.md): the exact frames, round trips, and both over a real
//! socket with a real shared-memory file.

use std::sync::{Arc, Mutex};
use std::thread;

use proptest::prelude::*;
use protocol::blocking::{Client, Server};
use protocol::shm::{ShmFrame, ShmWriter};
use protocol::trace::{Direction, TraceClock, TraceWriter};
use protocol::{
    decode_reply, decode_request, encode_reply, encode_request, sha256_hex, Endpoint, Image,
    ImageEncoding, ProtocolError, Reply, Request,
};

fn reply_bytes(r: &Reply) -> String {
    let mut b = Vec::new();
    encode_reply(r, ImageEncoding::Shm, &mut b);
    String::from_utf8(b).unwrap()
}

#[test]
fn golden_shm_frames() {
    let mut b = Vec::new();
    encode_request(
        &Request::GetInitData {
            image_encoding: Some(ImageEncoding::Shm),
            drone: None,
        },
        &mut b,
    );
    assert_eq!(
        String::from_utf8(b.clone()).unwrap(),
        r#"{"command":"GET_INIT_DATA","image_encoding":"shm"}"#
    );
    assert_eq!(
        decode_request(&b).unwrap(),
        Request::GetInitData {
            image_encoding: Some(ImageEncoding::Shm),
            drone: None
        }
    );
    let f = ShmFrame {
        width: 320,
        height: 320,
        seq: 17,
        path: "/dev/shm/cosim-img-0000001234-0000".into(),
    };
    let text = reply_bytes(&Reply::ShmImage(f.clone()));
    assert_eq!(
        text,
        r#"{"camera":{"encoding":"shm","height":320,"path":"/dev/shm/cosim-img-0000001234-0000","seq":17,"width":320},"command":"GET_IMAGE"}"#
    );
    assert_eq!(decode_reply(text.as_bytes()).unwrap(), Reply::ShmImage(f));
    // Any key order and spacing a foreign world may use.
    let foreign = r#"{ "command" : "GET_IMAGE", "camera" : { "seq" : 2, "width" : 4, "path" : "/x", "height" : 1, "encoding" : "shm" } }"#;
    assert_eq!(
        decode_reply(foreign.as_bytes()).unwrap(),
        Reply::ShmImage(ShmFrame {
            width: 4,
            height: 1,
            seq: 2,
            path: "/x".into()
        })
    );
    // A pure encoder given pixels under "shm" writes the thesis's array.
    let img = Image {
        width: 2,
        height: 1,
        data: vec![0, 255],
    };
    assert_eq!(
        reply_bytes(&Reply::Image(img)),
        r#"{"camera":{"data":[0,255],"height":1,"width":2},"command":"GET_IMAGE"}"#
    );
}

#[test]
fn bad_shm_frames_are_clear_errors() {
    for (body, why) in [
        (
            r#"{"camera":{"encoding":"shm","height":1,"path":"/x","width":1},"command":"GET_IMAGE"}"#,
            "camera.seq",
        ),
        (
            r#"{"camera":{"encoding":"shm","height":1,"seq":1,"width":1},"command":"GET_IMAGE"}"#,
            "camera.path",
        ),
        (
            r#"{"camera":{"data":[1],"encoding":"shm","height":1,"path":"/x","seq":1,"width":1},"command":"GET_IMAGE"}"#,
            "has data",
        ),
        (
            r#"{"camera":{"encoding":"shm","height":1,"path":"","seq":1,"width":1},"command":"GET_IMAGE"}"#,
            "camera.path must be a non-empty string",
        ),
        (
            r#"{"camera":{"encoding":"shm","height":1,"path":"/x","seq":-1,"width":1},"command":"GET_IMAGE"}"#,
            "camera.seq must be",
        ),
    ] {
        let e = decode_reply(body.as_bytes()).unwrap_err().to_string();
        assert!(e.contains(why), "{body}: {e}");
    }
    let e = decode_request(br#"{"command":"GET_INIT_DATA","image_encoding":"png"}"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains(r#""array", "base64" or "shm""#), "{e}");
}

fn frame() -> impl Strategy<Value = ShmFrame> {
    (
        any::<u32>(),
        any::<u32>(),
        any::<u64>(),
        "/[a-z0-9/_.\\- ]{0,40}",
    )
        .prop_map(|(width, height, seq, path)| ShmFrame {
            width,
            height,
            seq,
            path,
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn shm_replies_round_trip(f in frame()) {
        let text = reply_bytes(&Reply::ShmImage(f.clone()));
        prop_assert_eq!(decode_reply(text.as_bytes())?, Reply::ShmImage(f));
    }
}

/// A world on a blocking connection: images through shared memory after a
/// "shm" GET_INIT_DATA, GET_DATA_2 numbered by the requests seen.
fn serve(server: Server, shm_path: std::path::PathBuf) -> thread::JoinHandle<Vec<String>> {
    thread::spawn(move || {
        let mut conn = server.accept().unwrap();
        let mut shm = ShmWriter::create(shm_path).unwrap();
        let mut seen = Vec::new();
        let mut k = 0u8;
        while let Some(req) = conn.recv_request().unwrap() {
            seen.push(req.command().to_string());
            k = k.wrapping_add(1);
            let reply = match req {
                Request::GetInitData { image_encoding, .. } => Reply::InitData {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    time_s: 2.0,
                    timestep_ms: 32,
                    image_encoding: image_encoding.unwrap_or_default(),
                    drone: None,
                },
                Request::GetImage => {
                    let img = Image {
                        width: 16,
                        height: 8,
                        data: (0..128u8).map(|i| i.wrapping_mul(k)).collect(),
                    };
                    if conn.image_encoding() == ImageEncoding::Shm {
                        Reply::ShmImage(shm.write(&img).unwrap())
                    } else {
                        Reply::Image(img)
                    }
                }
                Request::GetData2 => Reply::Data2 {
                    velocity: f64::from(k),
                    velocity_x: 0.0,
                    velocity_y: 0.0,
                },
                Request::GetData3 => Reply::Data3 {
                    velocity: f64::from(k),
                    velocity_z: 0.0,
                    pitch: 0.0,
                },
                Request::Stop => {
                    conn.send_reply(&Reply::Stop {
                        time_s: 3.0,
                        stop_time_ms: 0,
                        gates_passed: None,
                    })
                    .unwrap();
                    break;
                }
                _ => continue,
            };
            conn.send_reply(&reply).unwrap();
        }
        seen
    })
}

/// The trace lines a client records, without the `len` of images (which
/// differs between encodings) and GET_INIT_DATA (which names the encoding).
fn client_trace(encoding: ImageEncoding, pipelined: bool) -> (Vec<String>, Vec<Image>) {
    let dir = tempfile::tempdir().unwrap();
    let ep = Endpoint::Unix(dir.path().join("w.sock"));
    let server = Server::bind(&ep).unwrap();
    let world = serve(server, dir.path().join("img"));
    let mut conn = Client::connect(&ep).unwrap();
    let trace = Arc::new(Mutex::new(TraceWriter::new(
        Vec::new(),
        TraceClock::PlatformPs,
        false,
    )));
    let t = Arc::clone(&trace);
    conn.set_observer(Box::new(move |ev| t.lock().unwrap().record(ev, 0)));
    conn.request(&Request::GetInitData {
        image_encoding: Some(encoding),
        drone: None,
    })
    .unwrap();
    let mut images = Vec::new();
    for _ in 0..3 {
        match conn.request(&Request::GetImage).unwrap() {
            Some(Reply::Image(img)) => images.push(img),
            other => panic!("{other:?}"),
        }
        let batch = [
            Request::SetVelocity {
                m1: 1.0,
                m2: 2.0,
                m3: 3.0,
                m4: 4.0,
            },
            Request::AdvanceTime { time: 32 },
            Request::GetData2,
            Request::GetData3,
        ];
        let replies = if pipelined {
            conn.pipeline(&batch).unwrap()
        } else {
            batch
                .iter()
                .filter_map(|r| conn.request(r).unwrap())
                .collect()
        };
        assert!(matches!(
            replies[..],
            [Reply::Data2 { .. }, Reply::Data3 { .. }]
        ));
    }
    conn.request(&Request::Stop).unwrap();
    assert_eq!(world.join().unwrap().len(), 1 + 3 * 5 + 1);
    drop(conn);
    let bytes = Arc::try_unwrap(trace)
        .ok()
        .unwrap()
        .into_inner()
        .unwrap()
        .into_inner();
    let lines = String::from_utf8(bytes)
        .unwrap()
        .lines()
        .filter(|l| !l.contains("GET_INIT_DATA"))
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            if v["msg"]["command"] == "GET_IMAGE" && v["dir"] == "to_platform" {
                v["len"] = serde_json::Value::Null;
            }
            v.to_string()
        })
        .collect();
    (lines, images)
}

#[test]
fn shm_images_and_pipelining_over_a_socket_trace_as_one_at_a_time_arrays() {
    let (reference, images) = client_trace(ImageEncoding::Array, false);
    assert_eq!(images.len(), 3);
    for (encoding, pipelined) in [
        (ImageEncoding::Array, true),
        (ImageEncoding::Shm, false),
        (ImageEncoding::Shm, true),
    ] {
        let (lines, imgs) = client_trace(encoding, pipelined);
        assert_eq!(imgs, images, "{encoding} pipelined={pipelined}");
        assert_eq!(lines, reference, "{encoding} pipelined={pipelined}");
    }
    // The image lines carry the pixels' hash.
    let hash = sha256_hex(&images[0].data);
    assert!(reference.iter().any(|l| l.contains(&hash)));
    // Requests before their replies, in the one-at-a-time order.
    let dirs: Vec<Direction> = reference
        .iter()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            serde_json::from_value(v["dir"].clone()).unwrap()
        })
        .take(7)
        .collect();
    use Direction::{ToPlatform as P, ToWorld as W};
    assert_eq!(dirs, [W, P, W, W, W, P, W]);
}

#[test]
fn a_missing_shm_file_is_a_clear_error_on_the_platform() {
    let dir = tempfile::tempdir().unwrap();
    let ep = Endpoint::Unix(dir.path().join("w.sock"));
    let server = Server::bind(&ep).unwrap();
    let world = thread::spawn(move || {
        let mut conn = server.accept().unwrap();
        let _ = conn.recv_request().unwrap();
        conn.send_reply(&Reply::ShmImage(ShmFrame {
            width: 2,
            height: 2,
            seq: 1,
            path: "/nonexistent/cosim-img".into(),
        }))
        .unwrap();
    });
    let mut conn = Client::connect(&ep).unwrap();
    let e = conn.request(&Request::GetImage).unwrap_err();
    assert!(matches!(e, ProtocolError::Shm(_)), "{e:?}");
    let e = e.to_string();
    assert!(
        e.contains("/nonexistent/cosim-img") && e.contains("one host"),
        "{e}"
    );
    world.join().unwrap();
}
