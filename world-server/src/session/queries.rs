//! What a drone reads: the replies to its queries (GET_INIT_DATA,
//! GET_SENSORS, GET_IMAGE, GET_DATA_2/3, GET_STATE, RADIO_RECV; DESIGN.md
//! §2), computed from the world as it stands at the drone's clock.

use std::collections::BTreeMap;

use protocol::radio::Picos;
use protocol::{Image, ImageEncoding, Reply, Request, Sensors, State};

use super::{Session, SessionError};
use crate::camera::write_png;
use crate::time::Millis;

impl Session {
    /// The reply to a query of drone `d` at world time `now` (= its clock):
    /// what it reads does not depend on the changes made at `now`
    /// ([`Session::answer_early`]).
    pub(super) fn query(
        &mut self,
        d: usize,
        req: Request,
        now: Millis,
    ) -> Result<Reply, SessionError> {
        Ok(match req {
            Request::GetInitData {
                image_encoding,
                drone,
            } => {
                if let Some(name) = drone.filter(|n| *n != self.names[d]) {
                    return Err(self.fail(
                        d,
                        format!(
                            "GET_INIT_DATA claims drone {name:?}, but this connection flies {:?}",
                            self.names[d]
                        ),
                    ));
                }
                let p = self.world.sensors(d).gps;
                Reply::InitData {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                    time_s: now.as_secs_f64(),
                    timestep_ms: self.world.config().timestep.0,
                    image_encoding: image_encoding.unwrap_or(ImageEncoding::Array),
                    drone: self.multi.then(|| self.names[d].clone()),
                }
            }
            Request::GetSensors => Reply::Sensors(self.sensors(d)),
            Request::GetImage => Reply::Image(self.image(d)?),
            Request::GetData2 => {
                let s = self.world.state(d);
                Reply::Data2 {
                    velocity: s.horizontal_speed(),
                    velocity_x: s.velocity[0],
                    velocity_y: s.velocity[1],
                }
            }
            Request::GetData3 => {
                let s = self.world.state(d);
                Reply::Data3 {
                    velocity: s.horizontal_speed(),
                    velocity_z: s.velocity[2],
                    pitch: s.attitude()[1],
                }
            }
            Request::GetState => Reply::State(self.state(d)),
            Request::RadioRecv => {
                let (packets, tx_done) = self.channel.take(d, Picos::from_ms(now.0));
                Reply::RadioRecv { packets, tx_done }
            }
            change => return Err(self.fail(d, format!("{} is not a query", change.command()))),
        })
    }

    fn sensors(&self, d: usize) -> Sensors {
        let s = self.world.sensors(d);
        let [x, y, z] = s.gps;
        let [roll, pitch, yaw] = s.attitude;
        let [roll_rate, pitch_rate, yaw_rate] = s.gyro;
        let [range_front, range_left, range_back, range_right] = s.ranges_mm;
        Sensors {
            time_s: s.time.as_secs_f64(),
            x,
            y,
            z,
            altitude: z,
            roll,
            pitch,
            yaw,
            roll_rate,
            pitch_rate,
            yaw_rate,
            range_front,
            range_left,
            range_back,
            range_right,
            range_up: s.up_down_mm.map(|r| r[0]),
            range_down: s.up_down_mm.map(|r| r[1]),
            flow_vx: s.flow.map(|f| f[0]),
            flow_vy: s.flow.map(|f| f[1]),
        }
    }

    fn state(&self, d: usize) -> State {
        let s = self.world.state(d);
        let [x, y, z] = s.position;
        let [qw, qx, qy, qz] = s.quaternion;
        let [vx, vy, vz] = s.velocity;
        let [omega_x, omega_y, omega_z] = s.omega_body;
        let [w1, w2, w3, w4] = s.motor_speeds;
        let drone_distances = self.multi.then(|| {
            let here = self.world.position(d);
            (0..self.names.len())
                .filter(|&j| j != d)
                .map(|j| {
                    (
                        self.names[j].clone(),
                        (self.world.position(j) - here).length(),
                    )
                })
                .collect::<BTreeMap<_, _>>()
        });
        State {
            time_s: s.time.as_secs_f64(),
            x,
            y,
            z,
            qw,
            qx,
            qy,
            qz,
            vx,
            vy,
            vz,
            omega_x,
            omega_y,
            omega_z,
            w1,
            w2,
            w3,
            w4,
            collisions: s.collisions,
            drone_distances,
        }
    }

    fn image(&mut self, d: usize) -> Result<Image, SessionError> {
        let (pos, rot) = (self.world.position(d), self.world.rotation(d));
        let data = self.camera.render(pos, rot).to_vec();
        let (w, h) = (self.camera.width(), self.camera.height());
        if let Some(dir) = &self.frames_dir {
            // One drone keeps the single-drone names.
            let name = if self.multi {
                format!(
                    "frame-{}-{:06}-{}ms.png",
                    self.names[d],
                    self.frames[d],
                    self.world.time().0
                )
            } else {
                format!("frame-{:06}-{}ms.png", self.frames[d], self.world.time().0)
            };
            let path = dir.join(name);
            write_png(&path, w, h, &data)
                .map_err(|source| SessionError::Output { path, source })?;
        }
        if let Some(m) = self.mcap.as_mut() {
            m.image(d, self.frames[d], self.world.time(), w, h, &data);
        }
        self.frames[d] += 1;
        Ok(Image {
            width: w as u32,
            height: h as u32,
            data,
        })
    }
}
