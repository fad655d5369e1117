//! Frame bodies to typed messages: serde for the small fields, the fast
//! path of `crate::decode` for the pixels; unknown keys ignored.

use super::*;

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
