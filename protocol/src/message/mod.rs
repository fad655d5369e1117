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

mod decode;
mod encode;

pub use decode::{decode_reply, decode_request};
pub use encode::{encode_reply, encode_request};
