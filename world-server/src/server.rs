//! The server: the thesis's Webots controller (§4.4, Appendix E) on top of
//! the protocol crate's tokio transport.
//!
//! [`Session`] answers one request at a time and knows nothing of sockets;
//! [`serve`] binds, accepts one client, warms up and feeds it the requests.
//! A replay of a trace (a later task) plugs in at [`Session::handle`]: feed
//! it the trace's `to_world` messages and compare its replies with the
//! trace's `to_platform` ones.
//!
//! Error policy: any request that cannot be served (bad JSON, unknown
//! command, bad fields, ADVANCE_TIME not a multiple of the timestep, negative
//! or NaN motor speeds) is answered with an ERROR frame, after which the
//! world closes the connection and exits non-zero — for the no-reply commands
//! DESIGN.md §2 requires it, and for the others the lockstep platform cannot
//! continue after an ERROR either. A client that disconnects before STOP is
//! an error too. Only STOP ends a run with exit status 0.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use futures::{SinkExt, StreamExt};
use protocol::tokio_transport::Listener;
use protocol::trace::{TraceClock, TraceWriter};
use protocol::{Endpoint, Image, ImageEncoding, Reply, Request, Sensors, State};

use crate::camera::{write_png, Camera};
use crate::crazyflie::MotorCommands;
use crate::physics::{StepConfig, World, WorldError};
use crate::trajectory::TrajectoryWriter;
use crate::world_file::WorldDesc;

/// Everything the command line configures.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    pub endpoint: Endpoint,
    pub world: WorldDesc,
    pub step: StepConfig,
    pub trace: Option<PathBuf>,
    pub trace_images: bool,
    pub frames_dir: Option<PathBuf>,
    pub trajectory: Option<PathBuf>,
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error(transparent)]
    Protocol(#[from] protocol::ProtocolError),
    #[error(transparent)]
    World(#[from] WorldError),
    #[error("bad request: {0}")]
    BadRequest(String),
    #[error("the client disconnected before STOP")]
    Disconnected,
    #[error("cannot write the trajectory: {0}")]
    Trajectory(#[from] csv::Error),
    #[error("cannot write {path}: {source}")]
    Output {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// What a request leads to.
#[derive(Debug)]
pub enum Outcome {
    /// Send this reply and go on.
    Reply(Reply),
    /// SET_VELOCITY, ADVANCE_TIME: nothing to send.
    NoReply,
    /// STOP: send this reply, close, exit 0.
    Stop(Reply),
}

/// The world serving one client.
pub struct Session {
    world: World,
    camera: Camera,
    trajectory: Option<TrajectoryWriter>,
    trajectory_error: Option<csv::Error>,
    frames_dir: Option<PathBuf>,
    frames: u64,
}

impl Session {
    /// Builds the world; no time passes yet.
    pub fn new(
        desc: &WorldDesc,
        step: StepConfig,
        trajectory: Option<&Path>,
        frames_dir: Option<&Path>,
    ) -> Result<Session, ServerError> {
        let world = World::new(desc, step)?;
        let camera = Camera::new(desc, world.scene_boxes());
        let trajectory = trajectory
            .map(TrajectoryWriter::create)
            .transpose()
            .map_err(ServerError::Trajectory)?;
        if let Some(dir) = frames_dir {
            std::fs::create_dir_all(dir).map_err(|source| ServerError::Output {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        Ok(Session {
            world,
            camera,
            trajectory,
            trajectory_error: None,
            frames_dir: frames_dir.map(Path::to_path_buf),
            frames: 0,
        })
    }

    pub fn world(&self) -> &World {
        &self.world
    }

    /// The thesis's 2000 ms warm-up at ±1 rad/s (before the first request).
    pub fn warm_up(&mut self) -> Result<(), ServerError> {
        let (traj, err) = (&mut self.trajectory, &mut self.trajectory_error);
        self.world.warm_up(|w| record(traj, err, w));
        self.take_trajectory_error()
    }

    /// Serves one request.
    pub fn handle(&mut self, req: Request) -> Result<Outcome, ServerError> {
        let out = match req {
            Request::GetInitData { image_encoding } => {
                let p = self.world.sensors().gps;
                Outcome::Reply(Reply::InitData {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                    time_s: self.world.time().as_secs_f64(),
                    timestep_ms: self.world.config().timestep.0,
                    image_encoding: image_encoding.unwrap_or(ImageEncoding::Array),
                })
            }
            Request::GetSensors => Outcome::Reply(Reply::Sensors(self.sensors())),
            Request::GetImage => Outcome::Reply(Reply::Image(self.image()?)),
            Request::SetVelocity { m1, m2, m3, m4 } => {
                self.world
                    .set_motor_commands(MotorCommands([m1, m2, m3, m4]))?;
                self.world.step();
                self.record_step();
                Outcome::NoReply
            }
            Request::AdvanceTime { time } => {
                let (traj, err) = (&mut self.trajectory, &mut self.trajectory_error);
                self.world
                    .advance_observed(time, |w| record(traj, err, w))?;
                Outcome::NoReply
            }
            Request::GetData2 => {
                let s = self.world.state();
                Outcome::Reply(Reply::Data2 {
                    velocity: s.horizontal_speed(),
                    velocity_x: s.velocity[0],
                    velocity_y: s.velocity[1],
                })
            }
            Request::GetData3 => {
                let s = self.world.state();
                Outcome::Reply(Reply::Data3 {
                    velocity: s.horizontal_speed(),
                    velocity_z: s.velocity[2],
                    pitch: s.attitude()[1],
                })
            }
            Request::GetState => Outcome::Reply(Reply::State(self.state())),
            Request::Stop => {
                let (traj, err) = (&mut self.trajectory, &mut self.trajectory_error);
                let stop = self.world.stop_motors(|w| record(traj, err, w));
                tracing::info!(
                    time_ms = self.world.time().0,
                    stop_ms = stop.0,
                    collisions = self.world.state().collisions,
                    "STOP: propellers stopped"
                );
                Outcome::Stop(Reply::Stop {
                    time_s: self.world.time().as_secs_f64(),
                    stop_time_ms: stop.0,
                })
            }
        };
        self.take_trajectory_error()?;
        Ok(out)
    }

    /// Flushes the trajectory (every exit path calls it).
    pub fn flush(&mut self) -> Result<(), ServerError> {
        if let Some(t) = self.trajectory.as_mut() {
            t.flush().map_err(|e| ServerError::Trajectory(e.into()))?;
        }
        Ok(())
    }

    fn record_step(&mut self) {
        record(
            &mut self.trajectory,
            &mut self.trajectory_error,
            &self.world,
        );
    }

    fn take_trajectory_error(&mut self) -> Result<(), ServerError> {
        match self.trajectory_error.take() {
            Some(e) => Err(ServerError::Trajectory(e)),
            None => Ok(()),
        }
    }

    fn sensors(&self) -> Sensors {
        let s = self.world.sensors();
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
        }
    }

    fn state(&self) -> State {
        let s = self.world.state();
        let [x, y, z] = s.position;
        let [qw, qx, qy, qz] = s.quaternion;
        let [vx, vy, vz] = s.velocity;
        let [omega_x, omega_y, omega_z] = s.omega_body;
        let [w1, w2, w3, w4] = s.motor_speeds;
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
        }
    }

    fn image(&mut self) -> Result<Image, ServerError> {
        let (pos, rot) = (self.world.position(), self.world.rotation());
        let data = self.camera.render(pos, rot).to_vec();
        let (w, h) = (self.camera.width(), self.camera.height());
        if let Some(dir) = &self.frames_dir {
            let path = dir.join(format!(
                "frame-{:06}-{}ms.png",
                self.frames,
                self.world.time().0
            ));
            write_png(&path, w, h, &data).map_err(|source| ServerError::Output { path, source })?;
        }
        self.frames += 1;
        Ok(Image {
            width: w as u32,
            height: h as u32,
            data,
        })
    }
}

/// Appends a trajectory row, keeping the first error for the caller.
fn record(traj: &mut Option<TrajectoryWriter>, err: &mut Option<csv::Error>, w: &World) {
    if let (Some(t), None) = (traj.as_mut(), err.as_ref()) {
        if let Err(e) = t.row(&w.state()) {
            *err = Some(e);
        }
    }
}

/// Binds, accepts one client, warms up, serves until STOP. Returns Ok only
/// after a clean STOP.
pub async fn serve(cfg: ServerConfig) -> Result<(), ServerError> {
    let mut session = Session::new(
        &cfg.world,
        cfg.step,
        cfg.trajectory.as_deref(),
        cfg.frames_dir.as_deref(),
    )?;
    let trace = match &cfg.trace {
        Some(path) => Some(Arc::new(Mutex::new(
            TraceWriter::create(path, TraceClock::WorldMs, cfg.trace_images).map_err(|source| {
                ServerError::Output {
                    path: path.clone(),
                    source,
                }
            })?,
        ))),
        None => None,
    };
    let result = serve_session(&cfg, &mut session, trace.clone()).await;
    // Flush outputs on every path; the first error wins.
    let flushed = session.flush();
    let traced = match trace {
        Some(t) => t
            .lock()
            .map_err(|_| ServerError::BadRequest("trace writer poisoned".into()))
            .and_then(|mut t| {
                t.flush().map_err(|source| ServerError::Output {
                    path: cfg.trace.clone().unwrap_or_default(),
                    source,
                })
            }),
        None => Ok(()),
    };
    result.and(flushed).and(traced)
}

async fn serve_session(
    cfg: &ServerConfig,
    session: &mut Session,
    trace: Option<Arc<Mutex<TraceWriter>>>,
) -> Result<(), ServerError> {
    let listener = Listener::bind(&cfg.endpoint).await?;
    tracing::info!(endpoint = %listener.local_endpoint()?, world = %cfg.world.name, "listening");
    let mut conn = listener.accept().await?;
    tracing::info!("client connected");
    // The world clock the trace records, shared with the codec's observer.
    let now_ms = Arc::new(AtomicU64::new(0));
    if let Some(t) = trace {
        let now = now_ms.clone();
        conn.codec_mut().set_observer(Box::new(move |ev| {
            let mut t = t
                .lock()
                .map_err(|_| std::io::Error::other("trace writer poisoned"))?;
            t.record(ev, now.load(Ordering::Relaxed))
        }));
    }
    session.warm_up()?;
    now_ms.store(session.world().time().0, Ordering::Relaxed);
    tracing::info!(time_ms = session.world().time().0, "warm-up done, serving");
    loop {
        let req = match conn.next().await {
            None => return Err(ServerError::Disconnected),
            Some(Err(e)) => {
                let msg = e.to_string();
                // Best effort: the client may already be gone.
                let _ = conn.send(&Reply::error(msg.clone())).await;
                return Err(ServerError::BadRequest(msg));
            }
            Some(Ok(req)) => req,
        };
        let outcome = session.handle(req);
        now_ms.store(session.world().time().0, Ordering::Relaxed);
        match outcome {
            Ok(Outcome::Reply(r)) => conn.send(&r).await?,
            Ok(Outcome::NoReply) => {}
            Ok(Outcome::Stop(r)) => {
                conn.send(&r).await?;
                conn.close().await?;
                return Ok(());
            }
            Err(e) => {
                let _ = conn.send(&Reply::error(e.to_string())).await;
                return Err(e);
            }
        }
    }
}
