//! Property tests: every message round-trips; any split of a frame across
//! reads decodes; random bytes never panic the decoders; the hand-written
//! pixel-array parser agrees with serde_json on what is a valid array.

use std::io::{self, Read};

use proptest::prelude::*;
use protocol::frame::{read_frame, write_frame, DEFAULT_MAX_FRAME};
use protocol::tokio_transport::{FrameCodec, ServerCodec};
use protocol::{
    decode_reply, decode_request, encode_reply, encode_request, Image, ImageEncoding,
    ProtocolError, Radio, RadioPacket, Reply, Request, Sensors, State, TxDone,
};
use serde_json::Value;
use tokio_util::bytes::BytesMut;
use tokio_util::codec::Decoder;

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        -1e3..1e3f64,
        Just(0.0),
        Just(-0.0),
        (-2000i32..2000).prop_map(f64::from),
    ]
}

fn encoding() -> impl Strategy<Value = ImageEncoding> {
    prop_oneof![Just(ImageEncoding::Array), Just(ImageEncoding::Base64)]
}

fn request() -> impl Strategy<Value = Request> {
    prop_oneof![
        (prop::option::of(encoding()), prop::option::of(name())).prop_map(
            |(image_encoding, drone)| Request::GetInitData {
                image_encoding,
                drone
            }
        ),
        Just(Request::GetSensors),
        Just(Request::GetImage),
        (finite(), finite(), finite(), finite())
            .prop_map(|(m1, m2, m3, m4)| Request::SetVelocity { m1, m2, m3, m4 }),
        Just(Request::GetData2),
        Just(Request::GetData3),
        any::<u64>().prop_map(|time| Request::AdvanceTime { time }),
        Just(Request::Stop),
        Just(Request::GetState),
        radio()
            .prop_flat_map(|radio| (
                Just(radio),
                prop::collection::vec(any::<u8>(), 1..=radio.max_payload()),
                any::<u64>()
            ))
            .prop_map(|(radio, data, offset_ps)| Request::RadioSend {
                radio,
                data,
                offset_ps
            }),
        Just(Request::RadioRecv),
    ]
}

fn radio() -> impl Strategy<Value = Radio> {
    prop_oneof![Just(Radio::Uwb), Just(Radio::P2p)]
}

/// Drone names: any non-empty string (escapes included).
fn name() -> impl Strategy<Value = String> {
    prop_oneof!["[a-zA-Z][a-zA-Z0-9_-]{0,8}", any::<String>()]
        .prop_filter("non-empty", |s| !s.is_empty())
}

fn packet() -> impl Strategy<Value = RadioPacket> {
    (
        radio(),
        name(),
        prop::collection::vec(any::<u8>(), 1..128),
        any::<u64>(),
        finite(),
        prop::option::of(0u64..1 << 40),
    )
        .prop_map(|(radio, from, data, time_ps, rssi, rx_stamp)| RadioPacket {
            radio,
            from,
            data,
            time_ps,
            rssi,
            rx_stamp,
        })
}

fn tx_done() -> impl Strategy<Value = TxDone> {
    (radio(), any::<u64>(), prop::option::of(0u64..1 << 40)).prop_map(
        |(radio, time_ps, tx_stamp)| TxDone {
            radio,
            time_ps,
            tx_stamp,
        },
    )
}

fn image() -> impl Strategy<Value = Image> {
    (0u32..24, 0u32..24).prop_flat_map(|(w, h)| {
        prop::collection::vec(any::<u8>(), (w * h) as usize).prop_map(move |data| Image {
            width: w,
            height: h,
            data,
        })
    })
}

fn reply() -> impl Strategy<Value = Reply> {
    let f = || prop::collection::vec(finite(), 19);
    prop_oneof![
        (f(), any::<u64>(), encoding(), prop::option::of(name())).prop_map(|(v, ts, e, drone)| {
            Reply::InitData {
                x: v[0],
                y: v[1],
                z: v[2],
                time_s: v[3],
                timestep_ms: ts,
                image_encoding: e,
                drone,
            }
        }),
        f().prop_map(|v| Reply::Sensors(Sensors {
            time_s: v[0],
            x: v[1],
            y: v[2],
            z: v[3],
            altitude: v[4],
            roll: v[5],
            pitch: v[6],
            yaw: v[7],
            roll_rate: v[8],
            pitch_rate: v[9],
            yaw_rate: v[10],
            range_front: v[11],
            range_left: v[12],
            range_back: v[13],
            range_right: v[14],
            ..Sensors::default()
        })),
        (f(), prop::collection::vec(prop::option::of(finite()), 4)).prop_map(|(v, o)| {
            Reply::Sensors(Sensors {
                time_s: v[0],
                x: v[1],
                range_up: o[0],
                range_down: o[1],
                flow_vx: o[2],
                flow_vy: o[3],
                ..Sensors::default()
            })
        }),
        image().prop_map(Reply::Image),
        f().prop_map(|v| Reply::Data2 {
            velocity: v[0],
            velocity_x: v[1],
            velocity_y: v[2]
        }),
        f().prop_map(|v| Reply::Data3 {
            velocity: v[0],
            velocity_z: v[1],
            pitch: v[2]
        }),
        (finite(), any::<u64>(), prop::option::of(any::<u64>())).prop_map(|(t, s, g)| {
            Reply::Stop {
                time_s: t,
                stop_time_ms: s,
                gates_passed: g,
            }
        }),
        (
            f(),
            any::<u64>(),
            prop::option::of(prop::collection::btree_map(name(), finite(), 0..5))
        )
            .prop_map(|(v, c, d)| Reply::State(State {
                time_s: v[0],
                x: v[1],
                y: v[2],
                z: v[3],
                qw: v[4],
                qx: v[5],
                qy: v[6],
                qz: v[7],
                vx: v[8],
                vy: v[9],
                vz: v[10],
                omega_x: v[11],
                omega_y: v[12],
                omega_z: v[13],
                w1: v[14],
                w2: v[15],
                w3: v[16],
                w4: v[17],
                collisions: c,
                drone_distances: d,
            })),
        (
            prop::collection::vec(packet(), 0..4),
            prop::collection::vec(tx_done(), 0..3)
        )
            .prop_map(|(packets, tx_done)| Reply::RadioRecv { packets, tx_done }),
        any::<String>().prop_map(|error| Reply::Error { error }),
    ]
}

/// A reader that hands out the wire in the given chunk sizes (as a socket
/// may), including zero-progress `Interrupted` errors between chunks.
struct Chunked<'a> {
    data: &'a [u8],
    cuts: Vec<usize>,
    interrupt: bool,
}

impl Read for Chunked<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.interrupt {
            self.interrupt = false;
            return Err(io::ErrorKind::Interrupted.into());
        }
        self.interrupt = true;
        let want = self.cuts.pop().unwrap_or(usize::MAX).max(1);
        let n = want.min(buf.len()).min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

fn reply_frame(r: &Reply, enc: ImageEncoding) -> Vec<u8> {
    let mut v = Vec::new();
    write_frame(&mut v, DEFAULT_MAX_FRAME, |o| encode_reply(r, enc, o)).unwrap();
    v
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn requests_round_trip(r in request()) {
        let mut body = Vec::new();
        encode_request(&r, &mut body);
        prop_assert_eq!(decode_request(&body)?, r);
        // And serde_json reads the same object (our JSON is plain JSON).
        prop_assert!(serde_json::from_slice::<Value>(&body)?.is_object());
    }

    #[test]
    fn replies_round_trip(r in reply(), enc in encoding()) {
        let mut body = Vec::new();
        encode_reply(&r, enc, &mut body);
        prop_assert_eq!(decode_reply(&body)?, r);
        prop_assert!(serde_json::from_slice::<Value>(&body)?.is_object());
    }

    #[test]
    fn any_split_of_frames_decodes(
        rs in prop::collection::vec(reply(), 1..4),
        enc in encoding(),
        cuts in prop::collection::vec(1usize..64, 0..40),
    ) {
        let mut wire = Vec::new();
        for r in &rs {
            wire.extend(reply_frame(r, enc));
        }
        // Blocking reader, byte chunks of arbitrary sizes.
        let mut rd = Chunked { data: &wire, cuts: cuts.clone(), interrupt: false };
        let mut body = Vec::new();
        for r in &rs {
            prop_assert!(read_frame(&mut rd, &mut body, DEFAULT_MAX_FRAME)?);
            prop_assert_eq!(&decode_reply(&body)?, r);
        }
        prop_assert!(!read_frame(&mut rd, &mut body, DEFAULT_MAX_FRAME)?);

        // Tokio codec fed the same chunks.
        let mut codec = FrameCodec::default();
        let mut src = BytesMut::new();
        let mut got = Vec::new();
        let mut rest = &wire[..];
        let mut sizes = cuts.into_iter().cycle();
        while !rest.is_empty() {
            let n = sizes.next().unwrap_or(usize::MAX).min(rest.len());
            src.extend_from_slice(&rest[..n]);
            rest = &rest[n..];
            while let Some(f) = codec.decode(&mut src)? {
                got.push(decode_reply(&f)?);
            }
        }
        prop_assert!(codec.decode_eof(&mut src)?.is_none());
        prop_assert_eq!(got, rs);
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
        let _ = decode_request(&bytes);
        let _ = decode_reply(&bytes);
        let mut body = Vec::new();
        let _ = read_frame(&mut &bytes[..], &mut body, 1 << 10);
        let mut codec = ServerCodec::new(1 << 10);
        let mut src = BytesMut::from(&bytes[..]);
        while let Ok(Some(_)) = codec.decode(&mut src) {}
        let _ = codec.decode_eof(&mut src);
    }

    #[test]
    fn mutated_frames_never_panic(r in reply(), enc in encoding(), edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
        let mut body = Vec::new();
        encode_reply(&r, enc, &mut body);
        for (i, b) in edits {
            let i = i.index(body.len());
            body[i] = b;
        }
        let _ = decode_reply(&body);
        let _ = decode_request(&body);
    }

    /// The hand-written pixel parser accepts exactly the arrays serde_json
    /// reads as arrays of integral numbers 0–255, with the same values.
    #[test]
    fn pixel_parser_agrees_with_serde_json(
        parts in prop::collection::vec((
            prop::sample::select(vec![
                "0", "1", "9", "10", "99", "100", "199", "255", "256", "300", "1000",
                "-0", "-1", "7.0", "0.7e1", "70E-1", "2.55e+2", "2.56e2", "01", "1.5",
                "1.", ".5", "1e", "+1", "\"1\"", "null", "", "0x1", "25 5",
            ]),
            prop::sample::select(vec![",", ", ", " ,", ",\n\t", ",,", " ", ""]),
        ), 0..12),
        open in prop::sample::select(vec!["[", "[ ", "[\n"]),
        close in prop::sample::select(vec!["]", " ]", "\r\n]", ""]),
    ) {
        let mut text = String::from(open);
        for (i, (num, sep)) in parts.iter().enumerate() {
            if i > 0 {
                text.push_str(sep);
            }
            text.push_str(num);
        }
        text.push_str(close);
        let reference: Option<Vec<u8>> = match serde_json::from_str::<Value>(&text) {
            Ok(Value::Array(items)) => items
                .iter()
                .map(|v| v.as_f64().filter(|f| f.fract() == 0.0 && (0.0..=255.0).contains(f)).map(|f| f as u8))
                .collect(),
            _ => None,
        };
        let n = reference.as_ref().map_or(1, Vec::len);
        let msg = format!(r#"{{"camera":{{"data":{text},"height":1,"width":{n}}},"command":"GET_IMAGE"}}"#);
        match (decode_reply(msg.as_bytes()), reference) {
            (Ok(Reply::Image(img)), Some(want)) => prop_assert_eq!(img.data, want),
            (Err(_), None) => {}
            (got, want) => prop_assert!(false, "{text:?}: decoder {got:?}, serde_json {want:?}"),
        }
    }
}

#[test]
fn nan_and_infinity_travel_as_null_like_nlohmann() {
    let mut body = Vec::new();
    encode_request(
        &Request::SetVelocity {
            m1: f64::NAN,
            m2: f64::INFINITY,
            m3: 1.0,
            m4: 2.0,
        },
        &mut body,
    );
    assert_eq!(
        String::from_utf8(body.clone()).unwrap(),
        r#"{"command":"SET_VELOCITY","m1":null,"m2":null,"m3":1.0,"m4":2.0}"#
    );
    match decode_request(&body).unwrap() {
        Request::SetVelocity { m1, m2, m3, m4 } => {
            assert!(m1.is_nan() && m2.is_nan());
            assert_eq!((m3, m4), (1.0, 2.0));
        }
        r => panic!("{r:?}"),
    }
}

#[test]
fn images_in_other_spellings_decode() {
    // Other key orders, whitespace, escaped '/' in base64, missing padding.
    let want = Image {
        width: 2,
        height: 2,
        data: vec![0, 9, 10, 255],
    };
    for text in [
        r#"{"command":"GET_IMAGE","camera":{"width":2,"height":2,"data":[0,9,10,255]}}"#,
        "{ \"camera\" : { \"height\" : 2 , \"data\" : [ 0 , 9 ,\n10 , 255 ] , \"width\" : 2 } , \"command\" : \"GET_IMAGE\" }",
        r#"{"camera":{"data":"AAkK\/w==","encoding":"base64","height":2,"width":2},"command":"GET_IMAGE"}"#,
        r#"{"camera":{"data":"AAkK/w","height":2,"width":2,"extra":{"a":[1]}},"command":"GET_IMAGE"}"#,
    ] {
        assert_eq!(
            decode_reply(text.as_bytes()).unwrap(),
            Reply::Image(want.clone()),
            "{text}"
        );
    }
}

#[test]
fn unexpected_variants_are_reported_not_panicked() {
    // Deeply nested unknown value: serde_json's recursion limit, not a stack
    // overflow.
    let deep = format!(
        r#"{{"command":"STOP","x":{}{}}}"#,
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    assert!(matches!(
        decode_request(deep.as_bytes()),
        Err(ProtocolError::InvalidJson { .. })
    ));
}
