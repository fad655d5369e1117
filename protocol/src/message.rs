//! Typed messages (DESIGN.md §2) and their encoding to / decoding from frame
//! bodies.
//!
//! Rust names are Rust-style; the wire keys are exactly the contract's
//! (`COORDINATE_X`, `ROLL_RATE`, ...), given by `#[serde(rename)]` for
//! decoding and by the sorted key lists of the encoders below. Encoding goes
//! through [`crate::dump`] (nlohmann `dump()` spelling, keys in byte order);
//! decoding through [`crate::decode`] (serde for the small fields, a
//! hand-written fast path for the pixel array). Unknown keys are ignored.

use std::collections::BTreeMap;

use base64::Engine as _;
use serde::{Deserialize, Deserializer, Serialize};
use serde_json::{Map, Value};

use crate::decode::{parse_message, Camera, Parsed};
use crate::dump::{write_key, write_object, write_str, write_u64, Val};
use crate::error::{ProtocolError, Result};
use crate::image::{write_image_data, Image, ImageEncoding};
use crate::radio::{Radio, RadioPacket, TxDone};
use crate::shm::ShmFrame;

/// Command names on the wire.
pub mod command {
    pub const GET_INIT_DATA: &str = "GET_INIT_DATA";
    pub const GET_SENSORS: &str = "GET_SENSORS";
    pub const GET_IMAGE: &str = "GET_IMAGE";
    pub const SET_VELOCITY: &str = "SET_VELOCITY";
    pub const GET_DATA_2: &str = "GET_DATA_2";
    pub const GET_DATA_3: &str = "GET_DATA_3";
    pub const ADVANCE_TIME: &str = "ADVANCE_TIME";
    pub const STOP: &str = "STOP";
    pub const GET_STATE: &str = "GET_STATE";
    pub const RADIO_SEND: &str = "RADIO_SEND";
    pub const RADIO_RECV: &str = "RADIO_RECV";
    pub const ERROR: &str = "ERROR";
}

/// A request, virtual platform → world.
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// `{"command":"GET_INIT_DATA"}`, optionally with
    /// `"image_encoding":"array"|"base64"` (`None` = key absent = array, as in
    /// the thesis). In a world with several drones it claims one with
    /// `"drone":NAME` (DESIGN.md §7); `None` = key absent.
    GetInitData {
        image_encoding: Option<ImageEncoding>,
        drone: Option<String>,
    },
    GetSensors,
    GetImage,
    /// PID motor commands, rad/s magnitudes. No reply: the world applies the
    /// spin signs and steps exactly one basicTimeStep.
    SetVelocity {
        m1: f64,
        m2: f64,
        m3: f64,
        m4: f64,
    },
    GetData2,
    GetData3,
    /// No reply: the world steps `time` ms (a multiple of basicTimeStep)
    /// holding the motor targets.
    AdvanceTime {
        time: u64,
    },
    /// The world stops the propellers, replies with [`Reply::Stop`], closes.
    Stop,
    /// Ground truth (extension of the thesis's protocol).
    GetState,
    /// DESIGN.md §8, no reply: a transmission starting at this drone's clock
    /// plus `offset_ps`. `data` is 1 to `radio.max_payload()` bytes (base64
    /// on the wire).
    RadioSend {
        radio: Radio,
        data: Vec<u8>,
        offset_ps: u64,
    },
    /// DESIGN.md §8: the receptions and finished transmissions of this
    /// drone up to its clock.
    RadioRecv,
}

impl Request {
    /// The `"command"` string of this request.
    pub fn command(&self) -> &'static str {
        use command::*;
        match self {
            Request::GetInitData { .. } => GET_INIT_DATA,
            Request::GetSensors => GET_SENSORS,
            Request::GetImage => GET_IMAGE,
            Request::SetVelocity { .. } => SET_VELOCITY,
            Request::GetData2 => GET_DATA_2,
            Request::GetData3 => GET_DATA_3,
            Request::AdvanceTime { .. } => ADVANCE_TIME,
            Request::Stop => STOP,
            Request::GetState => GET_STATE,
            Request::RadioSend { .. } => RADIO_SEND,
            Request::RadioRecv => RADIO_RECV,
        }
    }

    /// False for the commands the world never answers (`SET_VELOCITY`,
    /// `ADVANCE_TIME` as in the thesis's controller, whose Appendix E returns
    /// before `sendMessage` for them, and `RADIO_SEND`).
    pub fn expects_reply(&self) -> bool {
        !matches!(
            self,
            Request::SetVelocity { .. } | Request::AdvanceTime { .. } | Request::RadioSend { .. }
        )
    }
}

/// `GET_SENSORS` reply: what the thesis's `getSensors` sends, plus the
/// optional indoor-flight keys of DESIGN.md §9 (absent unless the world has
/// them, so the thesis's frames are unchanged).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Sensors {
    /// World time, s.
    #[serde(rename = "TIME", deserialize_with = "f64_or_null")]
    pub time_s: f64,
    /// GPS position, m (ENU).
    #[serde(rename = "COORDINATE_X", deserialize_with = "f64_or_null")]
    pub x: f64,
    #[serde(rename = "COORDINATE_Y", deserialize_with = "f64_or_null")]
    pub y: f64,
    #[serde(rename = "COORDINATE_Z", deserialize_with = "f64_or_null")]
    pub z: f64,
    /// Altitude, m.
    #[serde(rename = "ALTITUDE", deserialize_with = "f64_or_null")]
    pub altitude: f64,
    /// Webots InertialUnit angles, rad.
    #[serde(rename = "ROLL", deserialize_with = "f64_or_null")]
    pub roll: f64,
    #[serde(rename = "PITCH", deserialize_with = "f64_or_null")]
    pub pitch: f64,
    #[serde(rename = "YAW", deserialize_with = "f64_or_null")]
    pub yaw: f64,
    /// Gyro, body axes, rad/s.
    #[serde(rename = "ROLL_RATE", deserialize_with = "f64_or_null")]
    pub roll_rate: f64,
    #[serde(rename = "PITCH_RATE", deserialize_with = "f64_or_null")]
    pub pitch_rate: f64,
    #[serde(rename = "YAW_RATE", deserialize_with = "f64_or_null")]
    pub yaw_rate: f64,
    /// Range sensors, mm (0–2000).
    #[serde(rename = "RANGE_FRONT", deserialize_with = "f64_or_null")]
    pub range_front: f64,
    #[serde(rename = "RANGE_LEFT", deserialize_with = "f64_or_null")]
    pub range_left: f64,
    #[serde(rename = "RANGE_BACK", deserialize_with = "f64_or_null")]
    pub range_back: f64,
    #[serde(rename = "RANGE_RIGHT", deserialize_with = "f64_or_null")]
    pub range_right: f64,
    /// Upward and downward range sensors, mm (DESIGN.md §9).
    #[serde(rename = "RANGE_UP", default, deserialize_with = "opt_f64_or_null")]
    pub range_up: Option<f64>,
    #[serde(rename = "RANGE_DOWN", default, deserialize_with = "opt_f64_or_null")]
    pub range_down: Option<f64>,
    /// Optical-flow velocity, body frame, m/s (DESIGN.md §9).
    #[serde(rename = "FLOW_VX", default, deserialize_with = "opt_f64_or_null")]
    pub flow_vx: Option<f64>,
    #[serde(rename = "FLOW_VY", default, deserialize_with = "opt_f64_or_null")]
    pub flow_vy: Option<f64>,
}

/// `GET_STATE` reply: ground truth.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct State {
    #[serde(rename = "TIME", deserialize_with = "f64_or_null")]
    pub time_s: f64,
    #[serde(rename = "COORDINATE_X", deserialize_with = "f64_or_null")]
    pub x: f64,
    #[serde(rename = "COORDINATE_Y", deserialize_with = "f64_or_null")]
    pub y: f64,
    #[serde(rename = "COORDINATE_Z", deserialize_with = "f64_or_null")]
    pub z: f64,
    /// Orientation quaternion (w, x, y, z).
    #[serde(rename = "QW", deserialize_with = "f64_or_null")]
    pub qw: f64,
    #[serde(rename = "QX", deserialize_with = "f64_or_null")]
    pub qx: f64,
    #[serde(rename = "QY", deserialize_with = "f64_or_null")]
    pub qy: f64,
    #[serde(rename = "QZ", deserialize_with = "f64_or_null")]
    pub qz: f64,
    /// Linear velocity, world frame, m/s.
    #[serde(rename = "VELOCITY_X", deserialize_with = "f64_or_null")]
    pub vx: f64,
    #[serde(rename = "VELOCITY_Y", deserialize_with = "f64_or_null")]
    pub vy: f64,
    #[serde(rename = "VELOCITY_Z", deserialize_with = "f64_or_null")]
    pub vz: f64,
    /// Angular velocity, body frame, rad/s.
    #[serde(rename = "OMEGA_X", deserialize_with = "f64_or_null")]
    pub omega_x: f64,
    #[serde(rename = "OMEGA_Y", deserialize_with = "f64_or_null")]
    pub omega_y: f64,
    #[serde(rename = "OMEGA_Z", deserialize_with = "f64_or_null")]
    pub omega_z: f64,
    /// Signed propeller speeds, rad/s.
    #[serde(rename = "W1", deserialize_with = "f64_or_null")]
    pub w1: f64,
    #[serde(rename = "W2", deserialize_with = "f64_or_null")]
    pub w2: f64,
    #[serde(rename = "W3", deserialize_with = "f64_or_null")]
    pub w3: f64,
    #[serde(rename = "W4", deserialize_with = "f64_or_null")]
    pub w4: f64,
    /// Number of contacts begun since the start.
    #[serde(rename = "COLLISIONS")]
    pub collisions: u64,
    /// In a world with several drones: the distance (m) from this drone's
    /// centre to every other drone's (DESIGN.md §7). Absent otherwise.
    #[serde(rename = "DRONE_DISTANCES", default)]
    pub drone_distances: Option<BTreeMap<String, f64>>,
}

/// A reply, world → virtual platform. Each carries the `"command"` of the
/// request it answers (`ERROR` for [`Reply::Error`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// `GET_INIT_DATA`: start position (m), world time (s), basicTimeStep
    /// (ms) and the image encoding the world accepted.
    InitData {
        x: f64,
        y: f64,
        z: f64,
        time_s: f64,
        timestep_ms: u64,
        image_encoding: ImageEncoding,
        /// The claimed drone, echoed in a world with several drones only.
        drone: Option<String>,
    },
    Sensors(Sensors),
    /// `GET_IMAGE`: `"camera":{"width","height","data"}`.
    Image(Image),
    /// `GET_IMAGE` with `"image_encoding":"shm"` negotiated: where the
    /// pixels are (`"camera":{"encoding":"shm","height","path","seq","width"}`,
    /// [`crate::shm`]). The blocking transport reads the file and hands the
    /// platform a [`Reply::Image`]; worlds build this from an image with
    /// [`crate::shm::ShmWriter`].
    ShmImage(ShmFrame),
    /// `GET_DATA_2`: horizontal speed and world-frame x/y velocity, m/s.
    Data2 {
        velocity: f64,
        velocity_x: f64,
        velocity_y: f64,
    },
    /// `GET_DATA_3`: horizontal speed, vertical velocity (m/s), pitch (rad).
    Data3 {
        velocity: f64,
        velocity_z: f64,
        pitch: f64,
    },
    /// `STOP`: world time when the propellers stood still (s) and the time
    /// spent stopping them (ms); `GATES_PASSED` (DESIGN.md §10) when the
    /// world counts gates.
    Stop {
        time_s: f64,
        stop_time_ms: u64,
        gates_passed: Option<u64>,
    },
    State(State),
    /// `RADIO_RECV` (DESIGN.md §8): receptions in the order they ended, and
    /// this drone's own finished transmissions.
    RadioRecv {
        packets: Vec<RadioPacket>,
        tx_done: Vec<TxDone>,
    },
    /// `{"command":"ERROR","error":"..."}`.
    Error {
        error: String,
    },
}

impl Reply {
    /// The `"command"` string of this reply.
    pub fn command(&self) -> &'static str {
        use command::*;
        match self {
            Reply::InitData { .. } => GET_INIT_DATA,
            Reply::Sensors(_) => GET_SENSORS,
            Reply::Image(_) | Reply::ShmImage(_) => GET_IMAGE,
            Reply::Data2 { .. } => GET_DATA_2,
            Reply::Data3 { .. } => GET_DATA_3,
            Reply::Stop { .. } => STOP,
            Reply::State(_) => GET_STATE,
            Reply::RadioRecv { .. } => RADIO_RECV,
            Reply::Error { .. } => ERROR,
        }
    }

    /// Convenience for the world's error replies.
    pub fn error(msg: impl Into<String>) -> Self {
        Reply::Error { error: msg.into() }
    }
}

// ---------------------------------------------------------------- encoding

/// Appends the JSON body of `req` (no length prefix) to `out`.
pub fn encode_request(req: &Request, out: &mut Vec<u8>) {
    let cmd = ("command", Val::Str(req.command()));
    match req {
        Request::GetInitData {
            image_encoding,
            drone,
        } => {
            let mut e = vec![cmd];
            if let Some(d) = drone {
                e.push(("drone", Val::Str(d)));
            }
            if let Some(enc) = image_encoding {
                e.push(("image_encoding", Val::Str(enc.as_str())));
            }
            write_object(out, &e)
        }
        Request::RadioSend {
            radio,
            data,
            offset_ps,
        } => write_object(
            out,
            &[
                cmd,
                ("data", Val::Str(&BASE64.encode(data))),
                ("offset_ps", Val::U64(*offset_ps)),
                ("radio", Val::Str(radio.as_str())),
            ],
        ),
        Request::SetVelocity { m1, m2, m3, m4 } => write_object(
            out,
            &[
                cmd,
                ("m1", Val::F64(*m1)),
                ("m2", Val::F64(*m2)),
                ("m3", Val::F64(*m3)),
                ("m4", Val::F64(*m4)),
            ],
        ),
        Request::AdvanceTime { time } => write_object(out, &[cmd, ("time", Val::U64(*time))]),
        _ => write_object(out, &[cmd]),
    }
}

/// Appends the JSON body of `reply` (no length prefix) to `out`; an image is
/// written in `encoding` (the one negotiated by `GET_INIT_DATA`).
pub fn encode_reply(reply: &Reply, encoding: ImageEncoding, out: &mut Vec<u8>) {
    let cmd = ("command", Val::Str(reply.command()));
    match reply {
        Reply::InitData {
            x,
            y,
            z,
            time_s,
            timestep_ms,
            image_encoding,
            drone,
        } => {
            let mut e = vec![
                ("COORDINATE_X", Val::F64(*x)),
                ("COORDINATE_Y", Val::F64(*y)),
                ("COORDINATE_Z", Val::F64(*z)),
                ("TIME", Val::F64(*time_s)),
                ("TIMESTEP", Val::U64(*timestep_ms)),
                cmd,
            ];
            if let Some(d) = drone {
                e.push(("drone", Val::Str(d)));
            }
            e.push(("image_encoding", Val::Str(image_encoding.as_str())));
            write_object(out, &e)
        }
        Reply::Sensors(s) => {
            let mut e = Vec::with_capacity(22);
            e.push(("ALTITUDE", Val::F64(s.altitude)));
            e.push(("COORDINATE_X", Val::F64(s.x)));
            e.push(("COORDINATE_Y", Val::F64(s.y)));
            e.push(("COORDINATE_Z", Val::F64(s.z)));
            if let Some(v) = s.flow_vx {
                e.push(("FLOW_VX", Val::F64(v)));
            }
            if let Some(v) = s.flow_vy {
                e.push(("FLOW_VY", Val::F64(v)));
            }
            e.push(("PITCH", Val::F64(s.pitch)));
            e.push(("PITCH_RATE", Val::F64(s.pitch_rate)));
            e.push(("RANGE_BACK", Val::F64(s.range_back)));
            if let Some(v) = s.range_down {
                e.push(("RANGE_DOWN", Val::F64(v)));
            }
            e.push(("RANGE_FRONT", Val::F64(s.range_front)));
            e.push(("RANGE_LEFT", Val::F64(s.range_left)));
            e.push(("RANGE_RIGHT", Val::F64(s.range_right)));
            if let Some(v) = s.range_up {
                e.push(("RANGE_UP", Val::F64(v)));
            }
            e.push(("ROLL", Val::F64(s.roll)));
            e.push(("ROLL_RATE", Val::F64(s.roll_rate)));
            e.push(("TIME", Val::F64(s.time_s)));
            e.push(("YAW", Val::F64(s.yaw)));
            e.push(("YAW_RATE", Val::F64(s.yaw_rate)));
            e.push(cmd);
            write_object(out, &e)
        }
        Reply::Image(img) => {
            // {"camera":{"data":…,["encoding":"base64",]"height":H,"width":W},"command":"GET_IMAGE"}
            out.push(b'{');
            write_key(out, "camera");
            out.push(b'{');
            write_key(out, "data");
            write_image_data(out, &img.data, encoding);
            if encoding == ImageEncoding::Base64 {
                out.push(b',');
                write_key(out, "encoding");
                write_str(out, "base64");
            }
            out.push(b',');
            write_key(out, "height");
            write_u64(out, img.height.into());
            out.push(b',');
            write_key(out, "width");
            write_u64(out, img.width.into());
            out.extend_from_slice(b"},");
            write_key(out, "command");
            write_str(out, command::GET_IMAGE);
            out.push(b'}');
        }
        Reply::ShmImage(f) => {
            // {"camera":{"encoding":"shm","height":H,"path":P,"seq":N,"width":W},"command":"GET_IMAGE"}
            out.push(b'{');
            write_key(out, "camera");
            write_object(
                out,
                &[
                    ("encoding", Val::Str(ImageEncoding::Shm.as_str())),
                    ("height", Val::U64(f.height.into())),
                    ("path", Val::Str(&f.path)),
                    ("seq", Val::U64(f.seq)),
                    ("width", Val::U64(f.width.into())),
                ],
            );
            out.push(b',');
            write_key(out, "command");
            write_str(out, command::GET_IMAGE);
            out.push(b'}');
        }
        Reply::Data2 {
            velocity,
            velocity_x,
            velocity_y,
        } => write_object(
            out,
            &[
                ("VELOCITY", Val::F64(*velocity)),
                ("VELOCITY_X", Val::F64(*velocity_x)),
                ("VELOCITY_Y", Val::F64(*velocity_y)),
                cmd,
            ],
        ),
        Reply::Data3 {
            velocity,
            velocity_z,
            pitch,
        } => write_object(
            out,
            &[
                ("PITCH", Val::F64(*pitch)),
                ("VELOCITY", Val::F64(*velocity)),
                ("VELOCITY_Z", Val::F64(*velocity_z)),
                cmd,
            ],
        ),
        Reply::Stop {
            time_s,
            stop_time_ms,
            gates_passed,
        } => {
            let mut e = Vec::with_capacity(4);
            if let Some(g) = gates_passed {
                e.push(("GATES_PASSED", Val::U64(*g)));
            }
            e.push(("STOP_TIME", Val::U64(*stop_time_ms)));
            e.push(("TIME", Val::F64(*time_s)));
            e.push(cmd);
            write_object(out, &e)
        }
        Reply::State(s) => {
            let distances = s.drone_distances.as_ref().map(|d| {
                let mut o = Vec::new();
                o.push(b'{');
                for (i, (name, m)) in d.iter().enumerate() {
                    if i > 0 {
                        o.push(b',');
                    }
                    write_str(&mut o, name);
                    o.push(b':');
                    crate::dump::write_f64(&mut o, *m);
                }
                o.push(b'}');
                o
            });
            let mut e = vec![
                ("COLLISIONS", Val::U64(s.collisions)),
                ("COORDINATE_X", Val::F64(s.x)),
                ("COORDINATE_Y", Val::F64(s.y)),
                ("COORDINATE_Z", Val::F64(s.z)),
            ];
            if let Some(d) = &distances {
                e.push(("DRONE_DISTANCES", Val::Raw(d)));
            }
            e.extend([
                ("OMEGA_X", Val::F64(s.omega_x)),
                ("OMEGA_Y", Val::F64(s.omega_y)),
                ("OMEGA_Z", Val::F64(s.omega_z)),
                ("QW", Val::F64(s.qw)),
                ("QX", Val::F64(s.qx)),
                ("QY", Val::F64(s.qy)),
                ("QZ", Val::F64(s.qz)),
                ("TIME", Val::F64(s.time_s)),
                ("VELOCITY_X", Val::F64(s.vx)),
                ("VELOCITY_Y", Val::F64(s.vy)),
                ("VELOCITY_Z", Val::F64(s.vz)),
                ("W1", Val::F64(s.w1)),
                ("W2", Val::F64(s.w2)),
                ("W3", Val::F64(s.w3)),
                ("W4", Val::F64(s.w4)),
                cmd,
            ]);
            write_object(out, &e)
        }
        Reply::RadioRecv { packets, tx_done } => {
            // {"command":"RADIO_RECV","packets":[{"data","from","radio","rssi",
            // ["rx_stamp",]"time_ps"}…],"tx_done":[{"radio","time_ps"[,"tx_stamp"]}…]}
            out.push(b'{');
            write_key(out, "command");
            write_str(out, command::RADIO_RECV);
            out.push(b',');
            write_key(out, "packets");
            out.push(b'[');
            for (i, p) in packets.iter().enumerate() {
                if i > 0 {
                    out.push(b',');
                }
                let data = BASE64.encode(&p.data);
                let mut e = vec![
                    ("data", Val::Str(&data)),
                    ("from", Val::Str(&p.from)),
                    ("radio", Val::Str(p.radio.as_str())),
                    ("rssi", Val::F64(p.rssi)),
                ];
                if let Some(st) = p.rx_stamp {
                    e.push(("rx_stamp", Val::U64(st)));
                }
                e.push(("time_ps", Val::U64(p.time_ps)));
                write_object(out, &e);
            }
            out.extend_from_slice(b"],");
            write_key(out, "tx_done");
            out.push(b'[');
            for (i, t) in tx_done.iter().enumerate() {
                if i > 0 {
                    out.push(b',');
                }
                let mut e = vec![
                    ("radio", Val::Str(t.radio.as_str())),
                    ("time_ps", Val::U64(t.time_ps)),
                ];
                if let Some(st) = t.tx_stamp {
                    e.push(("tx_stamp", Val::U64(st)));
                }
                write_object(out, &e);
            }
            out.extend_from_slice(b"]}");
        }
        Reply::Error { error } => write_object(out, &[cmd, ("error", Val::Str(error))]),
    }
}

// ---------------------------------------------------------------- decoding

/// Decodes a frame body sent by the platform.
pub fn decode_request(body: &[u8]) -> Result<Request> {
    let Parsed { fields, .. } = parse_message(body)?;
    let cmd = command_of(&fields)?;
    use command::*;
    Ok(match cmd.as_str() {
        GET_INIT_DATA => {
            let image_encoding = match fields.get("image_encoding") {
                None | Some(Value::Null) => None,
                Some(v) => Some(ImageEncoding::deserialize(v).map_err(|_| {
                    ProtocolError::bad(
                        GET_INIT_DATA,
                        format!("image_encoding must be \"array\", \"base64\" or \"shm\", got {v}"),
                    )
                })?),
            };
            let drone = match fields.get("drone") {
                None | Some(Value::Null) => None,
                Some(Value::String(s)) if !s.is_empty() => Some(s.clone()),
                Some(v) => {
                    return Err(ProtocolError::bad(
                        GET_INIT_DATA,
                        format!("drone must be a non-empty string, got {v}"),
                    ))
                }
            };
            Request::GetInitData {
                image_encoding,
                drone,
            }
        }
        GET_SENSORS => Request::GetSensors,
        GET_IMAGE => Request::GetImage,
        SET_VELOCITY => {
            let w: SetVelocityWire = typed(SET_VELOCITY, fields)?;
            Request::SetVelocity {
                m1: w.m1,
                m2: w.m2,
                m3: w.m3,
                m4: w.m4,
            }
        }
        GET_DATA_2 => Request::GetData2,
        GET_DATA_3 => Request::GetData3,
        ADVANCE_TIME => {
            let w: AdvanceTimeWire = typed(ADVANCE_TIME, fields)?;
            Request::AdvanceTime { time: w.time }
        }
        STOP => Request::Stop,
        GET_STATE => Request::GetState,
        RADIO_SEND => {
            let w: RadioSendWire = typed(RADIO_SEND, fields)?;
            let radio: Radio = w
                .radio
                .parse()
                .map_err(|e: String| ProtocolError::bad(RADIO_SEND, e))?;
            let data = BASE64
                .decode(w.data.as_bytes())
                .map_err(|e| ProtocolError::bad(RADIO_SEND, format!("data is not base64: {e}")))?;
            if data.is_empty() || data.len() > radio.max_payload() {
                return Err(ProtocolError::bad(
                    RADIO_SEND,
                    format!(
                        "a {radio} frame carries 1 to {} bytes, got {}",
                        radio.max_payload(),
                        data.len()
                    ),
                ));
            }
            let Some(offset_ps) = w.offset_ps.as_u64() else {
                return Err(ProtocolError::bad(
                    RADIO_SEND,
                    format!("offset_ps must be an integer >= 0, got {}", w.offset_ps),
                ));
            };
            Request::RadioSend {
                radio,
                data,
                offset_ps,
            }
        }
        RADIO_RECV => Request::RadioRecv,
        _ => return Err(ProtocolError::UnknownCommand(cmd)),
    })
}

/// Decodes a frame body sent by the world. The image encoding is detected
/// from the frame (array or base64 string), so no negotiated state is needed.
pub fn decode_reply(body: &[u8]) -> Result<Reply> {
    let Parsed { fields, camera } = parse_message(body)?;
    let cmd = command_of(&fields)?;
    use command::*;
    Ok(match cmd.as_str() {
        GET_INIT_DATA => {
            let w: InitDataWire = typed(GET_INIT_DATA, fields)?;
            Reply::InitData {
                x: w.x,
                y: w.y,
                z: w.z,
                time_s: w.time_s,
                timestep_ms: w.timestep_ms,
                image_encoding: w.image_encoding,
                drone: w.drone,
            }
        }
        GET_SENSORS => Reply::Sensors(typed(GET_SENSORS, fields)?),
        GET_IMAGE => match camera {
            Some(r) => match r? {
                Camera::Pixels(img) => Reply::Image(img),
                Camera::Shm(f) => Reply::ShmImage(f),
            },
            None => return Err(ProtocolError::bad(GET_IMAGE, "missing field `camera`")),
        },
        GET_DATA_2 => {
            let w: Data2Wire = typed(GET_DATA_2, fields)?;
            Reply::Data2 {
                velocity: w.velocity,
                velocity_x: w.velocity_x,
                velocity_y: w.velocity_y,
            }
        }
        GET_DATA_3 => {
            let w: Data3Wire = typed(GET_DATA_3, fields)?;
            Reply::Data3 {
                velocity: w.velocity,
                velocity_z: w.velocity_z,
                pitch: w.pitch,
            }
        }
        STOP => {
            let w: StopWire = typed(STOP, fields)?;
            Reply::Stop {
                time_s: w.time_s,
                stop_time_ms: w.stop_time_ms,
                gates_passed: w.gates_passed,
            }
        }
        GET_STATE => Reply::State(typed(GET_STATE, fields)?),
        RADIO_RECV => {
            let w: RadioRecvWire = typed(RADIO_RECV, fields)?;
            let packets = w
                .packets
                .into_iter()
                .map(|p| {
                    let data = BASE64.decode(p.data.as_bytes()).map_err(|e| {
                        ProtocolError::bad(RADIO_RECV, format!("packet data is not base64: {e}"))
                    })?;
                    Ok(RadioPacket {
                        radio: p.radio,
                        from: p.from,
                        data,
                        time_ps: p.time_ps,
                        rssi: p.rssi,
                        rx_stamp: p.rx_stamp,
                    })
                })
                .collect::<Result<Vec<_>>>()?;
            let tx_done = w
                .tx_done
                .into_iter()
                .map(|t| TxDone {
                    radio: t.radio,
                    time_ps: t.time_ps,
                    tx_stamp: t.tx_stamp,
                })
                .collect();
            Reply::RadioRecv { packets, tx_done }
        }
        ERROR => {
            let w: ErrorWire = typed(ERROR, fields)?;
            Reply::Error { error: w.error }
        }
        _ => return Err(ProtocolError::UnknownCommand(cmd)),
    })
}

fn command_of(fields: &Map<String, Value>) -> Result<String> {
    match fields.get("command") {
        None => Err(ProtocolError::MissingCommand),
        Some(Value::String(s)) => Ok(s.clone()),
        Some(v) => Err(ProtocolError::bad(
            "?",
            format!("\"command\" must be a string, got {v}"),
        )),
    }
}

fn typed<T: for<'de> Deserialize<'de>>(cmd: &str, fields: Map<String, Value>) -> Result<T> {
    T::deserialize(Value::Object(fields)).map_err(|e| ProtocolError::bad(cmd, e.to_string()))
}

/// nlohmann writes NaN and infinities as `null`; read them back as NaN so a
/// frame written by either side always decodes.
fn f64_or_null<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// An optional key: absent = `None`, `null` = `Some(NaN)` (as above).
fn opt_f64_or_null<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Option<f64>, D::Error> {
    Ok(Some(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN)))
}

/// Standard base64 with padding, as DESIGN.md §8 and the image encoding use.
const BASE64: base64::engine::GeneralPurpose = base64::engine::general_purpose::STANDARD;

#[derive(Deserialize)]
struct RadioSendWire {
    radio: String,
    data: String,
    offset_ps: Value,
}

#[derive(Deserialize)]
struct RadioRecvWire {
    packets: Vec<PacketWire>,
    tx_done: Vec<TxDoneWire>,
}

#[derive(Deserialize)]
struct PacketWire {
    radio: Radio,
    from: String,
    data: String,
    time_ps: u64,
    #[serde(deserialize_with = "f64_or_null")]
    rssi: f64,
    #[serde(default)]
    rx_stamp: Option<u64>,
}

#[derive(Deserialize)]
struct TxDoneWire {
    radio: Radio,
    time_ps: u64,
    #[serde(default)]
    tx_stamp: Option<u64>,
}

#[derive(Deserialize)]
struct SetVelocityWire {
    #[serde(deserialize_with = "f64_or_null")]
    m1: f64,
    #[serde(deserialize_with = "f64_or_null")]
    m2: f64,
    #[serde(deserialize_with = "f64_or_null")]
    m3: f64,
    #[serde(deserialize_with = "f64_or_null")]
    m4: f64,
}

#[derive(Deserialize)]
struct AdvanceTimeWire {
    time: u64,
}

#[derive(Deserialize)]
struct InitDataWire {
    #[serde(rename = "COORDINATE_X", deserialize_with = "f64_or_null")]
    x: f64,
    #[serde(rename = "COORDINATE_Y", deserialize_with = "f64_or_null")]
    y: f64,
    #[serde(rename = "COORDINATE_Z", deserialize_with = "f64_or_null")]
    z: f64,
    #[serde(rename = "TIME", deserialize_with = "f64_or_null")]
    time_s: f64,
    #[serde(rename = "TIMESTEP")]
    timestep_ms: u64,
    /// Absent in a thesis-era world: then it can only mean the array form.
    #[serde(default)]
    image_encoding: ImageEncoding,
    #[serde(default)]
    drone: Option<String>,
}

#[derive(Deserialize)]
struct Data2Wire {
    #[serde(rename = "VELOCITY", deserialize_with = "f64_or_null")]
    velocity: f64,
    #[serde(rename = "VELOCITY_X", deserialize_with = "f64_or_null")]
    velocity_x: f64,
    #[serde(rename = "VELOCITY_Y", deserialize_with = "f64_or_null")]
    velocity_y: f64,
}

#[derive(Deserialize)]
struct Data3Wire {
    #[serde(rename = "VELOCITY", deserialize_with = "f64_or_null")]
    velocity: f64,
    #[serde(rename = "VELOCITY_Z", deserialize_with = "f64_or_null")]
    velocity_z: f64,
    #[serde(rename = "PITCH", deserialize_with = "f64_or_null")]
    pitch: f64,
}

#[derive(Deserialize)]
struct StopWire {
    #[serde(rename = "TIME", deserialize_with = "f64_or_null")]
    time_s: f64,
    #[serde(rename = "STOP_TIME")]
    stop_time_ms: u64,
    #[serde(rename = "GATES_PASSED", default)]
    gates_passed: Option<u64>,
}

#[derive(Deserialize)]
struct ErrorWire {
    error: String,
}
