//! Golden frames: what the crate writes must equal, byte for byte, what the
//! thesis's `VirtualConnector::write_on_channel` (Appendix B) writes for the
//! same nlohmann object: `data.dump()` (keys in std::map order, no spaces,
//! doubles as nlohmann spells them) preceded by the 4 length bytes
//! `len & 0xFF, (len >> 8) & 0xFF, (len >> 16) & 0xFF, (len >> 24) & 0xFF`.
//! The expected JSON texts below are written by hand, not produced by the
//! crate.

use protocol::frame::{read_frame, write_frame, DEFAULT_MAX_FRAME};
use protocol::{
    decode_reply, decode_request, encode_reply, encode_request, Image, ImageEncoding, Reply,
    Request, Sensors, State,
};

/// `write_on_channel` of Appendix B, transcribed: length bytes, then the
/// string.
fn write_on_channel(json_string: &str) -> Vec<u8> {
    let json_length = json_string.len() as u32;
    let length_buffer = [
        (json_length & 0xFF) as u8,
        ((json_length >> 8) & 0xFF) as u8,
        ((json_length >> 16) & 0xFF) as u8,
        ((json_length >> 24) & 0xFF) as u8,
    ];
    let mut wire = length_buffer.to_vec();
    wire.extend_from_slice(json_string.as_bytes());
    wire
}

fn request_frame(r: &Request) -> Vec<u8> {
    let mut v = Vec::new();
    write_frame(&mut v, DEFAULT_MAX_FRAME, |o| encode_request(r, o)).unwrap();
    v
}

fn reply_frame(r: &Reply, enc: ImageEncoding) -> Vec<u8> {
    let mut v = Vec::new();
    write_frame(&mut v, DEFAULT_MAX_FRAME, |o| encode_reply(r, enc, o)).unwrap();
    v
}

/// Checks the frame bytes, then that the hand-written frame decodes back to
/// the same message (the reading side of the golden test).
fn check_request(r: Request, dump: &str) {
    let want = write_on_channel(dump);
    assert_eq!(
        String::from_utf8_lossy(&request_frame(&r)[4..]),
        dump,
        "body of {r:?}"
    );
    assert_eq!(request_frame(&r), want, "frame of {r:?}");
    let mut body = Vec::new();
    assert!(read_frame(&mut &want[..], &mut body, DEFAULT_MAX_FRAME).unwrap());
    assert_eq!(decode_request(&body).unwrap(), r);
}

fn check_reply(r: Reply, enc: ImageEncoding, dump: &str) {
    let want = write_on_channel(dump);
    assert_eq!(
        String::from_utf8_lossy(&reply_frame(&r, enc)[4..]),
        dump,
        "body of {r:?}"
    );
    assert_eq!(reply_frame(&r, enc), want, "frame of {r:?}");
    assert_eq!(decode_reply(&want[4..]).unwrap(), r);
}

#[test]
fn requests_match_write_on_channel() {
    check_request(
        Request::GetInitData {
            image_encoding: None,
            drone: None,
        },
        r#"{"command":"GET_INIT_DATA"}"#,
    );
    check_request(
        Request::GetInitData {
            image_encoding: Some(ImageEncoding::Base64),
            drone: None,
        },
        r#"{"command":"GET_INIT_DATA","image_encoding":"base64"}"#,
    );
    check_request(Request::GetSensors, r#"{"command":"GET_SENSORS"}"#);
    check_request(Request::GetImage, r#"{"command":"GET_IMAGE"}"#);
    check_request(
        Request::SetVelocity {
            m1: 48.5,
            m2: 50.0,
            m3: 47.25,
            m4: 0.1,
        },
        r#"{"command":"SET_VELOCITY","m1":48.5,"m2":50.0,"m3":47.25,"m4":0.1}"#,
    );
    check_request(Request::GetData2, r#"{"command":"GET_DATA_2"}"#);
    check_request(Request::GetData3, r#"{"command":"GET_DATA_3"}"#);
    check_request(
        Request::AdvanceTime { time: 32 },
        r#"{"command":"ADVANCE_TIME","time":32}"#,
    );
    check_request(Request::Stop, r#"{"command":"STOP"}"#);
    check_request(Request::GetState, r#"{"command":"GET_STATE"}"#);
}

#[test]
fn the_documented_example_frame() {
    // docs/PROTOCOL.md shows this frame in hex.
    let f = request_frame(&Request::AdvanceTime { time: 32 });
    assert_eq!(
        hex::encode(&f),
        "24000000\
         7b22636f6d6d616e64223a22414456414e43455f54494d45222c2274696d65223a33327d"
    );
}

#[test]
fn replies_match_write_on_channel() {
    check_reply(
        Reply::InitData {
            x: -2.6,
            y: 0.0,
            z: 0.015,
            time_s: 2.0,
            timestep_ms: 32,
            image_encoding: ImageEncoding::Array,
            drone: None,
        },
        ImageEncoding::Array,
        r#"{"COORDINATE_X":-2.6,"COORDINATE_Y":0.0,"COORDINATE_Z":0.015,"TIME":2.0,"TIMESTEP":32,"command":"GET_INIT_DATA","image_encoding":"array"}"#,
    );
    check_reply(
        Reply::Sensors(Sensors {
            time_s: 2.032,
            x: -2.6,
            y: 1e-5,
            z: 0.25,
            altitude: 0.25,
            roll: -0.001,
            pitch: 2.5e-7,
            yaw: std::f64::consts::FRAC_PI_2,
            roll_rate: 0.0,
            pitch_rate: -0.0,
            yaw_rate: 12.5,
            range_front: 2000.0,
            range_left: 1234.5,
            range_back: 0.5,
            range_right: 1e16,
            ..Sensors::default()
        }),
        ImageEncoding::Array,
        concat!(
            r#"{"ALTITUDE":0.25,"COORDINATE_X":-2.6,"COORDINATE_Y":1e-05,"COORDINATE_Z":0.25,"#,
            r#""PITCH":2.5e-07,"PITCH_RATE":-0.0,"RANGE_BACK":0.5,"RANGE_FRONT":2000.0,"#,
            r#""RANGE_LEFT":1234.5,"RANGE_RIGHT":1e+16,"ROLL":-0.001,"ROLL_RATE":0.0,"#,
            r#""TIME":2.032,"YAW":1.5707963267948966,"YAW_RATE":12.5,"command":"GET_SENSORS"}"#
        ),
    );
    let img = Image {
        width: 2,
        height: 2,
        data: vec![0, 9, 10, 255],
    };
    check_reply(
        Reply::Image(img.clone()),
        ImageEncoding::Array,
        r#"{"camera":{"data":[0,9,10,255],"height":2,"width":2},"command":"GET_IMAGE"}"#,
    );
    check_reply(
        Reply::Image(img),
        ImageEncoding::Base64,
        r#"{"camera":{"data":"AAkK/w==","encoding":"base64","height":2,"width":2},"command":"GET_IMAGE"}"#,
    );
    check_reply(
        Reply::Data2 {
            velocity: 0.5,
            velocity_x: 0.3,
            velocity_y: -0.4,
        },
        ImageEncoding::Array,
        r#"{"VELOCITY":0.5,"VELOCITY_X":0.3,"VELOCITY_Y":-0.4,"command":"GET_DATA_2"}"#,
    );
    check_reply(
        Reply::Data3 {
            velocity: 0.5,
            velocity_z: -1.25,
            pitch: 0.125,
        },
        ImageEncoding::Array,
        r#"{"PITCH":0.125,"VELOCITY":0.5,"VELOCITY_Z":-1.25,"command":"GET_DATA_3"}"#,
    );
    check_reply(
        Reply::Stop {
            time_s: 146.208,
            stop_time_ms: 1024,
            gates_passed: None,
        },
        ImageEncoding::Array,
        r#"{"STOP_TIME":1024,"TIME":146.208,"command":"STOP"}"#,
    );
    check_reply(
        Reply::State(State {
            time_s: 3.0,
            x: 1.0,
            y: 2.0,
            z: 3.0,
            qw: 1.0,
            qx: 0.0,
            qy: 0.0,
            qz: 0.0,
            vx: 0.1,
            vy: 0.2,
            vz: 0.3,
            omega_x: 0.01,
            omega_y: 0.02,
            omega_z: 0.03,
            w1: -48.0,
            w2: 48.0,
            w3: -48.0,
            w4: 48.0,
            collisions: 2,
            drone_distances: None,
        }),
        ImageEncoding::Array,
        concat!(
            r#"{"COLLISIONS":2,"COORDINATE_X":1.0,"COORDINATE_Y":2.0,"COORDINATE_Z":3.0,"#,
            r#""OMEGA_X":0.01,"OMEGA_Y":0.02,"OMEGA_Z":0.03,"QW":1.0,"QX":0.0,"QY":0.0,"QZ":0.0,"#,
            r#""TIME":3.0,"VELOCITY_X":0.1,"VELOCITY_Y":0.2,"VELOCITY_Z":0.3,"#,
            r#""W1":-48.0,"W2":48.0,"W3":-48.0,"W4":48.0,"command":"GET_STATE"}"#
        ),
    );
    check_reply(
        Reply::error("unknown command \"FLY\"\n"),
        ImageEncoding::Array,
        r#"{"command":"ERROR","error":"unknown command \"FLY\"\n"}"#,
    );
}

#[test]
fn a_full_size_image_frame_has_the_right_header() {
    // 320×320 of value 255: "[" + 102400 × "255," with the last comma → "]".
    let img = Image {
        width: 320,
        height: 320,
        data: vec![255; 320 * 320],
    };
    let f = reply_frame(&Reply::Image(img), ImageEncoding::Array);
    let body = format!(
        r#"{{"camera":{{"data":[{}],"height":320,"width":320}},"command":"GET_IMAGE"}}"#,
        vec!["255"; 320 * 320].join(",")
    );
    assert_eq!(f, write_on_channel(&body));
    // 18 + (1 + 102,400 × 4 − 1 + 1) + 49 = 409,668 bytes = 0x00064044:
    // the header spans three bytes.
    assert_eq!(body.len(), 409_668);
    assert_eq!(&f[..4], &[0x44, 0x40, 0x06, 0x00]);
}

/// The multi-drone and radio messages (DESIGN.md §7–§8), spelled by hand.
#[test]
fn multi_drone_and_radio_frames() {
    check_request(
        Request::GetInitData {
            image_encoding: Some(ImageEncoding::Array),
            drone: Some("A".into()),
        },
        r#"{"command":"GET_INIT_DATA","drone":"A","image_encoding":"array"}"#,
    );
    check_request(
        Request::RadioSend {
            radio: protocol::Radio::Uwb,
            data: b"hi!".to_vec(),
            offset_ps: 1_500_000,
        },
        r#"{"command":"RADIO_SEND","data":"aGkh","offset_ps":1500000,"radio":"uwb"}"#,
    );
    check_request(Request::RadioRecv, r#"{"command":"RADIO_RECV"}"#);
    check_reply(
        Reply::InitData {
            x: 0.0,
            y: 1.0,
            z: 0.015,
            time_s: 2.0,
            timestep_ms: 16,
            image_encoding: ImageEncoding::Array,
            drone: Some("B".into()),
        },
        ImageEncoding::Array,
        r#"{"COORDINATE_X":0.0,"COORDINATE_Y":1.0,"COORDINATE_Z":0.015,"TIME":2.0,"TIMESTEP":16,"command":"GET_INIT_DATA","drone":"B","image_encoding":"array"}"#,
    );
    check_reply(
        Reply::RadioRecv {
            packets: vec![
                protocol::RadioPacket {
                    radio: protocol::Radio::Uwb,
                    from: "B".into(),
                    data: vec![1, 2, 3],
                    time_ps: 2_000_188_600_000,
                    rssi: -79.5,
                    rx_stamp: Some(127_795_200_123),
                },
                protocol::RadioPacket {
                    radio: protocol::Radio::P2p,
                    from: "C".into(),
                    data: vec![255],
                    time_ps: 2_001_000_000_000,
                    rssi: -48.25,
                    rx_stamp: None,
                },
            ],
            tx_done: vec![protocol::TxDone {
                radio: protocol::Radio::Uwb,
                time_ps: 2_000_100_000_000,
                tx_stamp: Some(127_795_000_000),
            }],
        },
        ImageEncoding::Array,
        r#"{"command":"RADIO_RECV","packets":[{"data":"AQID","from":"B","radio":"uwb","rssi":-79.5,"rx_stamp":127795200123,"time_ps":2000188600000},{"data":"/w==","from":"C","radio":"p2p","rssi":-48.25,"time_ps":2001000000000}],"tx_done":[{"radio":"uwb","time_ps":2000100000000,"tx_stamp":127795000000}]}"#,
    );
    check_reply(
        Reply::RadioRecv {
            packets: vec![],
            tx_done: vec![],
        },
        ImageEncoding::Array,
        r#"{"command":"RADIO_RECV","packets":[],"tx_done":[]}"#,
    );
    let mut d = std::collections::BTreeMap::new();
    d.insert("B".to_string(), 1.0);
    d.insert("C".to_string(), 1.118033988749895);
    check_reply(
        Reply::State(State {
            time_s: 2.0,
            collisions: 0,
            drone_distances: Some(d),
            qw: 1.0,
            ..State::default()
        }),
        ImageEncoding::Array,
        r#"{"COLLISIONS":0,"COORDINATE_X":0.0,"COORDINATE_Y":0.0,"COORDINATE_Z":0.0,"DRONE_DISTANCES":{"B":1.0,"C":1.118033988749895},"OMEGA_X":0.0,"OMEGA_Y":0.0,"OMEGA_Z":0.0,"QW":1.0,"QX":0.0,"QY":0.0,"QZ":0.0,"TIME":2.0,"VELOCITY_X":0.0,"VELOCITY_Y":0.0,"VELOCITY_Z":0.0,"W1":0.0,"W2":0.0,"W3":0.0,"W4":0.0,"command":"GET_STATE"}"#,
    );
    check_reply(
        Reply::Stop {
            time_s: 30.5,
            stop_time_ms: 64,
            gates_passed: Some(10),
        },
        ImageEncoding::Array,
        r#"{"GATES_PASSED":10,"STOP_TIME":64,"TIME":30.5,"command":"STOP"}"#,
    );
}
