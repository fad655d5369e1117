//! Typed messages (DESIGN.md §2) and their encoding to / decoding from frame
//! bodies.
//!
//! Rust names are Rust-style; the wire keys are exactly the contract's
//! (`COORDINATE_X`, `ROLL_RATE`, ...), given by `#[serde(rename)]` for
//! decoding and by the sorted key lists of the encoders below. Encoding goes
//! through [`crate::dump`] (nlohmann `dump()` spelling, keys in byte order);
//! decoding through [`crate::decode`] (serde for the small fields, a
//! hand-written fast path for the pixel array). Unknown keys are ignored.

use serde::{Deserialize, Deserializer, Serialize};
use serde_json::{Map, Value};

use crate::decode::{parse_message, Parsed};
use crate::dump::{write_key, write_object, write_str, write_u64, Val};
use crate::error::{ProtocolError, Result};
use crate::image::{write_image_data, Image, ImageEncoding};

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
    pub const ERROR: &str = "ERROR";
}

/// A request, virtual platform → world.
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// `{"command":"GET_INIT_DATA"}`, optionally with
    /// `"image_encoding":"array"|"base64"` (`None` = key absent = array, as in
    /// the thesis).
    GetInitData {
        image_encoding: Option<ImageEncoding>,
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
        }
    }

    /// False for the two commands the world never answers (`SET_VELOCITY`,
    /// `ADVANCE_TIME`), as in the thesis's controller (Appendix E returns
    /// before `sendMessage` for them).
    pub fn expects_reply(&self) -> bool {
        !matches!(
            self,
            Request::SetVelocity { .. } | Request::AdvanceTime { .. }
        )
    }
}

/// `GET_SENSORS` reply: what the thesis's `getSensors` sends.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
}

/// `GET_STATE` reply: ground truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    },
    Sensors(Sensors),
    /// `GET_IMAGE`: `"camera":{"width","height","data"}`.
    Image(Image),
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
    /// spent stopping them (ms).
    Stop {
        time_s: f64,
        stop_time_ms: u64,
    },
    State(State),
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
            Reply::Image(_) => GET_IMAGE,
            Reply::Data2 { .. } => GET_DATA_2,
            Reply::Data3 { .. } => GET_DATA_3,
            Reply::Stop { .. } => STOP,
            Reply::State(_) => GET_STATE,
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
            image_encoding: Some(enc),
        } => write_object(out, &[cmd, ("image_encoding", Val::Str(enc.as_str()))]),
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
        } => write_object(
            out,
            &[
                ("COORDINATE_X", Val::F64(*x)),
                ("COORDINATE_Y", Val::F64(*y)),
                ("COORDINATE_Z", Val::F64(*z)),
                ("TIME", Val::F64(*time_s)),
                ("TIMESTEP", Val::U64(*timestep_ms)),
                cmd,
                ("image_encoding", Val::Str(image_encoding.as_str())),
            ],
        ),
        Reply::Sensors(s) => write_object(
            out,
            &[
                ("ALTITUDE", Val::F64(s.altitude)),
                ("COORDINATE_X", Val::F64(s.x)),
                ("COORDINATE_Y", Val::F64(s.y)),
                ("COORDINATE_Z", Val::F64(s.z)),
                ("PITCH", Val::F64(s.pitch)),
                ("PITCH_RATE", Val::F64(s.pitch_rate)),
                ("RANGE_BACK", Val::F64(s.range_back)),
                ("RANGE_FRONT", Val::F64(s.range_front)),
                ("RANGE_LEFT", Val::F64(s.range_left)),
                ("RANGE_RIGHT", Val::F64(s.range_right)),
                ("ROLL", Val::F64(s.roll)),
                ("ROLL_RATE", Val::F64(s.roll_rate)),
                ("TIME", Val::F64(s.time_s)),
                ("YAW", Val::F64(s.yaw)),
                ("YAW_RATE", Val::F64(s.yaw_rate)),
                cmd,
            ],
        ),
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
        } => write_object(
            out,
            &[
                ("STOP_TIME", Val::U64(*stop_time_ms)),
                ("TIME", Val::F64(*time_s)),
                cmd,
            ],
        ),
        Reply::State(s) => write_object(
            out,
            &[
                ("COLLISIONS", Val::U64(s.collisions)),
                ("COORDINATE_X", Val::F64(s.x)),
                ("COORDINATE_Y", Val::F64(s.y)),
                ("COORDINATE_Z", Val::F64(s.z)),
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
            ],
        ),
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
                        format!("image_encoding must be \"array\" or \"base64\", got {v}"),
                    )
                })?),
            };
            Request::GetInitData { image_encoding }
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
            }
        }
        GET_SENSORS => Reply::Sensors(typed(GET_SENSORS, fields)?),
        GET_IMAGE => match camera {
            Some(r) => Reply::Image(r?),
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
            }
        }
        GET_STATE => Reply::State(typed(GET_STATE, fields)?),
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
}

#[derive(Deserialize)]
struct ErrorWire {
    error: String,
}
