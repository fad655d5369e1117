//! Bad input gives a typed error naming the problem, never a panic.

use protocol::frame::{read_frame, DEFAULT_MAX_FRAME};
use protocol::tokio_transport::FrameCodec;
use protocol::{decode_reply, decode_request, ProtocolError};
use tokio_util::bytes::BytesMut;
use tokio_util::codec::Decoder;

fn frame(body: &[u8]) -> Vec<u8> {
    let mut v = (body.len() as u32).to_le_bytes().to_vec();
    v.extend_from_slice(body);
    v
}

fn read(wire: &[u8], max: usize) -> Result<Option<Vec<u8>>, ProtocolError> {
    let mut buf = Vec::new();
    let mut r = wire;
    read_frame(&mut r, &mut buf, max).map(|ok| ok.then_some(buf))
}

#[test]
fn length_above_the_limit_is_refused_before_reading_the_body() {
    // 4 GiB − 1 announced, nothing behind it: must fail on the header alone
    // (an attempt to allocate would abort the test process).
    let e = read(&[0xFF, 0xFF, 0xFF, 0xFF], DEFAULT_MAX_FRAME).unwrap_err();
    assert!(
        matches!(e, ProtocolError::FrameTooLarge { len: 0xFFFF_FFFF, max } if max == DEFAULT_MAX_FRAME),
        "{e}"
    );
    let e = read(&frame(b"{\"command\":\"STOP\"}"), 10).unwrap_err();
    assert!(
        matches!(e, ProtocolError::FrameTooLarge { len: 18, max: 10 }),
        "{e}"
    );
    assert!(e
        .to_string()
        .contains("18 bytes exceeds the maximum frame size of 10"));

    let mut codec = FrameCodec::new(10);
    let mut src = BytesMut::from(&frame(b"{\"command\":\"STOP\"}")[..]);
    let e = codec.decode(&mut src).unwrap_err();
    assert!(
        matches!(e, ProtocolError::FrameTooLarge { len: 18, max: 10 }),
        "{e}"
    );
}

#[test]
fn truncated_frames() {
    // Clean end between frames.
    assert_eq!(read(&[], DEFAULT_MAX_FRAME).unwrap(), None);
    // End inside the header.
    let e = read(&[5, 0], DEFAULT_MAX_FRAME).unwrap_err();
    assert!(
        matches!(
            e,
            ProtocolError::Truncated {
                expected: 4,
                got: 2
            }
        ),
        "{e}"
    );
    // End inside the body.
    let mut w = frame(b"{\"command\":\"STOP\"}");
    w.truncate(10);
    let e = read(&w, DEFAULT_MAX_FRAME).unwrap_err();
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

    // The tokio codec says the same at end of stream.
    let mut codec = FrameCodec::default();
    let mut src = BytesMut::from(&w[..]);
    assert!(codec.decode(&mut src).unwrap().is_none());
    let e = codec.decode_eof(&mut src).unwrap_err();
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
    let mut codec = FrameCodec::default();
    let mut src = BytesMut::from(&[1u8, 0, 0][..]);
    let e = codec.decode_eof(&mut src).unwrap_err();
    assert!(
        matches!(
            e,
            ProtocolError::Truncated {
                expected: 4,
                got: 3
            }
        ),
        "{e}"
    );
    let mut src = BytesMut::new();
    assert!(codec.decode_eof(&mut src).unwrap().is_none());
}

#[test]
fn invalid_utf8() {
    let e = decode_request(b"{\"command\":\"GET_\xff\"}").unwrap_err();
    assert!(
        matches!(e, ProtocolError::InvalidUtf8 { offset: 16 }),
        "{e}"
    );
    assert!(e.to_string().contains("UTF-8"));
}

/// Invalid UTF-8 anywhere in an image reply (before, after or inside the
/// pixel array, in a key) is reported as such, at the first bad byte, even
/// though the decoder skips checking the array it decoded.
#[test]
fn invalid_utf8_around_an_image() {
    let good: &[u8] =
        b"{\"command\":\"GET_IMAGE\",\"camera\":{\"width\":2,\"height\":1,\"data\":[7,255]},\"k\":\"v\"}";
    assert!(decode_reply(good).is_ok());
    let array = good
        .windows(7)
        .position(|w| w == b"[7,255]")
        .expect("array");
    for at in [
        1,
        12,
        array - 3,
        array + 1,
        array + 3,
        array + 7,
        good.len() - 4,
        good.len() - 2,
    ] {
        for bad in [&b"\xff"[..], b"\xc3", b"\xe2\x82", b"\x80"] {
            let mut body = good.to_vec();
            body.splice(at..at, bad.iter().copied());
            let offset = std::str::from_utf8(&body).unwrap_err().valid_up_to();
            let e = decode_reply(&body).unwrap_err();
            assert!(
                matches!(e, ProtocolError::InvalidUtf8 { offset: o } if o == offset),
                "{at} {bad:?}: {e}"
            );
        }
    }
    // Valid multi-byte text right next to the array is fine.
    let mut body = good.to_vec();
    let end = array + 7;
    body.splice(end + 2..end + 3, "\"é\":1,\"".bytes());
    assert!(
        decode_reply(&body).is_ok(),
        "{}",
        String::from_utf8_lossy(&body)
    );
}

#[test]
fn invalid_json() {
    for (body, offset) in [
        (&b"{\"command\":\"STOP\""[..], 17),
        (b"{\"command\" \"STOP\"}", 11),
        (b"{\"command\":STOP}", 11),
        (b"{\"command\":\"STOP\",}", 18),
        (b"{\"command\":\"STOP\"} x", 19),
        (b"", 0),
        (b"nul", 2),
    ] {
        let e = decode_request(body).unwrap_err();
        match &e {
            ProtocolError::InvalidJson { offset: o, .. } => assert_eq!(
                *o,
                offset,
                "offset for {:?}: {e}",
                String::from_utf8_lossy(body)
            ),
            _ => panic!(
                "{:?}: expected InvalidJson, got {e}",
                String::from_utf8_lossy(body)
            ),
        }
        assert!(e.to_string().starts_with("frame body is not valid JSON"));
    }
    // Valid JSON that is not an object.
    assert!(matches!(
        decode_request(b"[1,2]").unwrap_err(),
        ProtocolError::NotAnObject
    ));
    // Broken JSON inside an image.
    let e =
        decode_reply(br#"{"camera":{"data":[1,2,,3],"height":1,"width":3},"command":"GET_IMAGE"}"#)
            .unwrap_err();
    assert!(matches!(e, ProtocolError::InvalidJson { .. }), "{e}");
}

#[test]
fn missing_and_unknown_commands() {
    let e = decode_request(br#"{"time":32}"#).unwrap_err();
    assert!(matches!(e, ProtocolError::MissingCommand), "{e}");
    assert_eq!(e.to_string(), "message has no \"command\" key");
    let e = decode_reply(b"{}").unwrap_err();
    assert!(matches!(e, ProtocolError::MissingCommand), "{e}");

    let e = decode_request(br#"{"command":"FLY"}"#).unwrap_err();
    assert!(
        matches!(&e, ProtocolError::UnknownCommand(c) if c == "FLY"),
        "{e}"
    );
    assert_eq!(e.to_string(), "unknown command \"FLY\"");
    // ERROR is a reply, never a request.
    let e = decode_request(br#"{"command":"ERROR","error":"x"}"#).unwrap_err();
    assert!(
        matches!(&e, ProtocolError::UnknownCommand(c) if c == "ERROR"),
        "{e}"
    );
    let e = decode_reply(br#"{"command":"SET_VELOCITY"}"#).unwrap_err();
    assert!(
        matches!(&e, ProtocolError::UnknownCommand(c) if c == "SET_VELOCITY"),
        "{e}"
    );
}

#[test]
fn bad_fields_name_the_command_and_the_field() {
    let cases: &[(&[u8], &str, &str)] = &[
        (
            br#"{"command":"SET_VELOCITY","m1":1,"m2":2,"m3":3}"#,
            "SET_VELOCITY",
            "m4",
        ),
        (
            br#"{"command":"SET_VELOCITY","m1":"fast","m2":2,"m3":3,"m4":4}"#,
            "SET_VELOCITY",
            "fast",
        ),
        (
            br#"{"command":"ADVANCE_TIME","time":-32}"#,
            "ADVANCE_TIME",
            "-32",
        ),
        (
            br#"{"command":"ADVANCE_TIME","time":32.5}"#,
            "ADVANCE_TIME",
            "32.5",
        ),
        (
            br#"{"command":"GET_INIT_DATA","image_encoding":"png"}"#,
            "GET_INIT_DATA",
            "png",
        ),
        (br#"{"command":7}"#, "?", "command"),
    ];
    for (body, cmd, needle) in cases {
        let e = decode_request(body).unwrap_err();
        match &e {
            ProtocolError::BadField { command, detail } => {
                assert_eq!(command, cmd, "{e}");
                assert!(detail.contains(needle), "{e} should mention {needle}");
            }
            _ => panic!("expected BadField, got {e}"),
        }
    }
    let replies: &[(&[u8], &str)] = &[
        (br#"{"command":"GET_SENSORS","TIME":1.0}"#, "COORDINATE_X"),
        (br#"{"command":"GET_IMAGE"}"#, "camera"),
        (br#"{"camera":{"data":[1,2,3],"height":2,"width":2},"command":"GET_IMAGE"}"#, "3 pixels"),
        (br#"{"camera":{"data":[1,256],"height":1,"width":2},"command":"GET_IMAGE"}"#, "256"),
        (br#"{"camera":{"data":[1,2],"width":2},"command":"GET_IMAGE"}"#, "height"),
        (br#"{"camera":{"data":"@@@@","height":1,"width":3},"command":"GET_IMAGE"}"#, "base64"),
        (br#"{"camera":{"data":[1],"encoding":"base64","height":1,"width":1},"command":"GET_IMAGE"}"#, "encoding"),
        (br#"{"camera":[1,2],"command":"GET_IMAGE"}"#, "object"),
        (br#"{"command":"STOP","TIME":1.5}"#, "STOP_TIME"),
        (br#"{"command":"ERROR"}"#, "error"),
    ];
    for (body, needle) in replies {
        let e = decode_reply(body).unwrap_err();
        assert!(
            matches!(e, ProtocolError::BadField { .. }) && e.to_string().contains(needle),
            "{}: {e} should be a BadField mentioning {needle}",
            String::from_utf8_lossy(body)
        );
    }
}

#[test]
fn unknown_keys_are_ignored() {
    use protocol::{Reply, Request};
    assert_eq!(
        decode_request(br#"{"zzz":[1,{"a":null}],"command":"ADVANCE_TIME","time":64,"AAA":"x"}"#)
            .unwrap(),
        Request::AdvanceTime { time: 64 }
    );
    // A "camera" key on a message that is not an image is just unknown.
    assert_eq!(
        decode_reply(br#"{"camera":"off","command":"STOP","STOP_TIME":96,"TIME":1.5}"#).unwrap(),
        Reply::Stop {
            time_s: 1.5,
            stop_time_ms: 96,
            gates_passed: None
        }
    );
}

/// RADIO_SEND that cannot be served: each names the command and the fault.
#[test]
fn bad_radio_sends_are_refused_clearly() {
    let cases: &[(&str, &str)] = &[
        (
            r#"{"command":"RADIO_SEND","radio":"uwb","data":"%%%","offset_ps":0}"#,
            "not base64",
        ),
        (
            r#"{"command":"RADIO_SEND","radio":"uwb","data":"","offset_ps":0}"#,
            "1 to 127 bytes, got 0",
        ),
        (
            r#"{"command":"RADIO_SEND","radio":"p2p","data":"AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA","offset_ps":0}"#,
            "1 to 60 bytes, got 63",
        ),
        (
            r#"{"command":"RADIO_SEND","radio":"uwb","data":"AA==","offset_ps":-5}"#,
            "offset_ps",
        ),
        (
            r#"{"command":"RADIO_SEND","radio":"wifi","data":"AA==","offset_ps":0}"#,
            "unknown radio \"wifi\"",
        ),
        (
            r#"{"command":"RADIO_SEND","radio":"uwb","offset_ps":0}"#,
            "missing field `data`",
        ),
        (
            r#"{"command":"GET_INIT_DATA","drone":3}"#,
            "drone must be a non-empty string",
        ),
        (
            r#"{"command":"GET_INIT_DATA","drone":""}"#,
            "drone must be a non-empty string",
        ),
    ];
    for (body, want) in cases {
        let e = decode_request(body.as_bytes()).unwrap_err().to_string();
        assert!(e.contains(want), "{body}: {e}");
        assert!(
            e.contains("RADIO_SEND") || e.contains("GET_INIT_DATA"),
            "{e}"
        );
    }
}
