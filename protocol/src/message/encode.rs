//! Typed messages to frame bodies: the contract's keys in byte order,
//! nlohmann's spelling (`crate::dump`).

use super::*;

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
