//! `Connection::request_deferred`: a reply read whole, decoded by the next
//! deferred request or at `wait`, gives exactly what `request` gives for the same
//! frame: the same image, the same errors.

use std::thread;

use protocol::blocking::{Client, Connection, Server};
use protocol::{Endpoint, Image, ProtocolError, Reply, Request};

/// A world that answers each request with the next of `bodies`, raw.
fn world(bodies: Vec<String>) -> (tempfile::TempDir, Endpoint, thread::JoinHandle<()>) {
    let dir = tempfile::tempdir().unwrap();
    let ep = Endpoint::Unix(dir.path().join("w.sock"));
    let server = Server::bind(&ep).unwrap();
    let handle = thread::spawn(move || {
        let mut conn = server.accept().unwrap();
        for body in bodies {
            if conn.recv_request().unwrap().is_none() {
                return;
            }
            conn.send_raw(body.as_bytes()).unwrap();
        }
    });
    (dir, ep, handle)
}

const GOOD: &str = r#"{"camera":{"data":[0,255,7,30],"height":2,"width":2},"command":"GET_IMAGE"}"#;
/// 256 is no pixel: the fast path's error.
const BAD: &str = r#"{"camera":{"data":[0,256,7,30],"height":2,"width":2},"command":"GET_IMAGE"}"#;
const REFUSED: &str = r#"{"command":"ERROR","error":"no camera here"}"#;
/// A reply to another command.
const OTHER: &str = r#"{"command":"GET_DATA_2","VELOCITY":0.5,"VELOCITY_X":0.3,"VELOCITY_Y":-0.4}"#;

/// What `request(GET_IMAGE)` gives for each body, one at a time.
fn at_once(bodies: &[&str]) -> Vec<Result<Reply, String>> {
    let (_dir, ep, w) = world(bodies.iter().map(|s| s.to_string()).collect());
    let mut conn = Client::connect(&ep).unwrap();
    let out = bodies
        .iter()
        .map(|_| {
            conn.request(&Request::GetImage)
                .map(Option::unwrap)
                .map_err(|e| e.to_string())
        })
        .collect();
    drop(conn);
    w.join().unwrap();
    out
}

fn deferred(conn: &mut Connection) -> protocol::blocking::PendingReply {
    conn.request_deferred(&Request::GetImage).unwrap()
}

#[test]
fn a_deferred_reply_is_the_reply_or_the_error_request_gives() {
    let bodies = [GOOD, BAD, REFUSED, OTHER];
    let expected = at_once(&bodies);
    assert_eq!(
        expected[0],
        Ok(Reply::Image(Image {
            width: 2,
            height: 2,
            data: vec![0, 255, 7, 30]
        }))
    );
    assert!(
        expected[1].as_ref().unwrap_err().contains("256"),
        "{expected:?}"
    );
    assert!(expected[2].as_ref().unwrap_err().contains("no camera here"));
    assert!(expected[3].as_ref().unwrap_err().contains("GET_DATA_2"));

    // Waited at once.
    let (_dir, ep, w) = world(bodies.iter().map(|s| s.to_string()).collect());
    let mut conn = Client::connect(&ep).unwrap();
    for want in &expected {
        let got = deferred(&mut conn).wait().map_err(|e| e.to_string());
        assert_eq!(&got, want);
    }
    drop(conn);
    w.join().unwrap();

    // Waited late: each decoded by the next deferred request (the last
    // by `wait`), the error kept for `wait`.
    let (_dir, ep, w) = world(bodies.iter().map(|s| s.to_string()).collect());
    let mut conn = Client::connect(&ep).unwrap();
    let pending: Vec<_> = bodies.iter().map(|_| deferred(&mut conn)).collect();
    for (p, want) in pending.into_iter().zip(&expected) {
        assert_eq!(&p.wait().map_err(|e| e.to_string()), want);
    }
    drop(conn);
    w.join().unwrap();
}

#[test]
fn a_deferred_reply_survives_other_exchanges_and_a_refusal_is_remote() {
    let (_dir, ep, w) = world(vec![BAD.into(), OTHER.into(), REFUSED.into()]);
    let mut conn = Client::connect(&ep).unwrap();
    let bad = deferred(&mut conn);
    // This exchange leaves the image undecoded; `wait` decodes it.
    let r = conn.request(&Request::GetData2).unwrap().unwrap();
    assert_eq!(r.command(), "GET_DATA_2");
    let e = bad.wait().unwrap_err();
    assert!(matches!(e, ProtocolError::BadField { .. }), "{e:?}");
    let e = deferred(&mut conn).wait().unwrap_err();
    assert!(
        matches!(e, ProtocolError::Remote(ref m) if m == "no camera here"),
        "{e:?}"
    );
    drop(conn);
    w.join().unwrap();
}
