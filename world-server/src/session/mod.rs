//! The world serving its drones, without sockets: the thesis's Webots
//! controller (§4.4, Appendix E) for every drone, the lockstep that orders
//! their requests ([`crate::lockstep`], docs/SWARM.md §2) and the radio
//! channel between them ([`crate::radio`], DESIGN.md §8).
//!
//! The server ([`crate::server`]) pushes each connection's frames with
//! [`Session::push`] as they arrive and calls [`Session::run`], which
//! processes everything the lockstep allows and hands what must go out
//! (the trace's request lines, the replies) to an [`Outputs`] in processing
//! order. Tests drive it the same way.
//!
//! Error policy: a request that cannot be served (bad JSON, unknown command,
//! bad fields, ADVANCE_TIME not a multiple of the timestep, negative or NaN
//! motor speeds, a claim of another drone, RADIO_SEND the channel refuses),
//! a platform that disconnects before its STOP reply, or a broken frame end
//! the run: [`SessionError::Drone`] names the drone, the server sends ERROR to
//! every platform and exits non-zero. Only the last STOP ends a run well.

use std::path::{Path, PathBuf};

use protocol::radio::Picos;
use protocol::{ProtocolError, Reply, Request};

use crate::camera::Camera;
use crate::crazyflie::MotorCommands;
use crate::foxglove::McapLog;
use crate::lockstep::{Lockstep, Next};
use crate::physics::{StepConfig, World, WorldError};
use crate::radio::geometry::Obstacle;
use crate::radio::{Channel, DroneRadio};
use crate::time::Millis;
use crate::trajectory::TrajectoryWriter;
use crate::world_file::WorldDesc;

mod queries;

/// What a connection delivered.
#[derive(Debug)]
pub enum Input {
    /// One frame: its body as received (the trace records these bytes) and
    /// what it decoded to.
    Frame {
        body: Vec<u8>,
        request: Result<Request, ProtocolError>,
    },
    /// The stream broke inside a frame (truncated, too large, I/O error).
    Broken(ProtocolError),
    /// End of stream between frames.
    Closed,
}

/// Where the session's output goes, in processing order.
pub trait Outputs {
    /// Drone `drone`'s request is processed at world time `now`: its frame
    /// goes to the trace (`valid` false when it did not decode).
    fn request(
        &mut self,
        drone: usize,
        body: &[u8],
        valid: bool,
        now: Millis,
    ) -> Result<(), SessionError>;
    /// A reply to drone `drone` at world time `now`. After a STOP reply the
    /// connection is closed.
    fn reply(&mut self, drone: usize, reply: Reply, now: Millis) -> Result<(), SessionError>;
    /// A query's reply sent before the query's turn in the canonical order
    /// (DESIGN.md §15): it goes out now; its trace line waits for
    /// [`Outputs::trace_early`]. Outputs without a trace may keep this
    /// default, which is [`Outputs::reply`].
    fn reply_early(&mut self, drone: usize, reply: Reply, now: Millis) -> Result<(), SessionError> {
        self.reply(drone, reply, now)
    }
    /// The query answered early is in its turn: the trace line of drone
    /// `drone`'s oldest early reply (its request's line came just before).
    fn trace_early(&mut self, _drone: usize, _now: Millis) -> Result<(), SessionError> {
        Ok(())
    }
}

/// A request waiting in the lockstep. `answered`: its reply went out
/// before its turn (a query at the world's time, DESIGN.md §15); its turn
/// only traces it.
#[derive(Debug)]
pub struct Queued {
    pub input: Input,
    pub answered: bool,
}

/// Why a run ended badly.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// Drone `drone`'s platform sent what cannot be served, or left.
    #[error("drone {name}: {message}")]
    Drone {
        drone: usize,
        name: String,
        message: String,
    },
    #[error(transparent)]
    World(#[from] WorldError),
    #[error("cannot write the trajectory: {0}")]
    Trajectory(#[from] csv::Error),
    #[error("cannot write the MCAP file: {0}")]
    Mcap(#[from] mcap::McapError),
    #[error("cannot write {path}: {source}")]
    Output {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl SessionError {
    /// The drone at fault, if a drone is.
    pub fn drone(&self) -> Option<usize> {
        match self {
            SessionError::Drone { drone, .. } => Some(*drone),
            _ => None,
        }
    }

    /// What the drone at fault is told (without its own name).
    pub fn message(&self) -> String {
        match self {
            SessionError::Drone { message, .. } => message.clone(),
            other => other.to_string(),
        }
    }
}

/// Where a run stands after [`Session::run`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// Waiting for requests.
    Waiting,
    /// Every drone's STOP was answered.
    Finished,
}

/// Every drone's centre at one step boundary.
struct Snapshot {
    time: Millis,
    positions: Vec<[f64; 3]>,
}

/// The world and its drones' lockstep.
pub struct Session {
    world: World,
    camera: Camera,
    lockstep: Lockstep<Queued>,
    channel: Channel,
    names: Vec<String>,
    multi: bool,
    /// Positions at the last two step boundaries (radio interpolation).
    before: Snapshot,
    after: Snapshot,
    trajectory: Option<TrajectoryWriter>,
    trajectory_error: Option<csv::Error>,
    frames_dir: Option<PathBuf>,
    frames: Vec<u64>,
    mcap: Option<McapLog>,
}

/// Optional outputs of a session.
#[derive(Debug, Clone, Default)]
pub struct SessionOutputs<'a> {
    pub trajectory: Option<&'a Path>,
    pub frames_dir: Option<&'a Path>,
    pub radio_log: Option<&'a Path>,
    /// `--mcap`: the world's channels for Foxglove ([`crate::foxglove`]).
    pub mcap: Option<&'a Path>,
    /// Keep every Nth camera frame in the MCAP file (0: none).
    pub mcap_image_every: u64,
}

impl Session {
    /// Builds the world; no time passes yet.
    pub fn new(
        desc: &WorldDesc,
        step: StepConfig,
        outputs: SessionOutputs<'_>,
    ) -> Result<Session, SessionError> {
        let world = World::new(desc, step)?;
        let camera = Camera::new(desc, world.scene_boxes());
        let multi = desc.is_multi();
        let trajectory = outputs
            .trajectory
            .map(|p| TrajectoryWriter::create(p, multi))
            .transpose()?;
        if let Some(dir) = outputs.frames_dir {
            std::fs::create_dir_all(dir).map_err(|source| SessionError::Output {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        let mut channel = Channel::new(
            desc.radio.clone(),
            desc.drones
                .iter()
                .map(|d| DroneRadio {
                    name: d.name.clone(),
                    clock_ppm: d.clock_ppm,
                    radios: d.radios.clone(),
                })
                .collect(),
        )
        .with_obstacles(desc.boxes.iter().map(Obstacle::from).collect());
        if let Some(path) = outputs.radio_log {
            let f = std::fs::File::create(path).map_err(|source| SessionError::Output {
                path: path.to_path_buf(),
                source,
            })?;
            channel.set_log(Box::new(std::io::BufWriter::new(f)));
        }
        let names: Vec<String> = desc.drones.iter().map(|d| d.name.clone()).collect();
        let mcap = match outputs.mcap {
            Some(path) => {
                channel.keep_events();
                Some(McapLog::create(
                    path,
                    &names,
                    world.scene_boxes(),
                    outputs.mcap_image_every,
                )?)
            }
            None => None,
        };
        let n = desc.drones.len();
        let positions = world.positions();
        Ok(Session {
            lockstep: Lockstep::new(n, world.time(), step.timestep),
            camera,
            channel,
            names,
            multi,
            before: Snapshot {
                time: world.time(),
                positions: positions.clone(),
            },
            after: Snapshot {
                time: world.time(),
                positions,
            },
            world,
            trajectory,
            trajectory_error: None,
            frames_dir: outputs.frames_dir.map(Path::to_path_buf),
            frames: vec![0; n],
            mcap,
        })
    }

    pub fn world(&self) -> &World {
        &self.world
    }

    pub fn lockstep(&self) -> &Lockstep<Queued> {
        &self.lockstep
    }

    /// The drones' names, in world-file order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// True with several drones (claims by name, `drone` fields).
    pub fn is_multi(&self) -> bool {
        self.multi
    }

    /// The thesis's 2000 ms warm-up at ±1 rad/s (before the first request),
    /// one for all drones; the lockstep starts at its end.
    pub fn warm_up(&mut self) -> Result<(), SessionError> {
        let (traj, err, names) = (
            &mut self.trajectory,
            &mut self.trajectory_error,
            &self.names,
        );
        let (before, after) = (&mut self.before, &mut self.after);
        let mcap = &mut self.mcap;
        self.world.warm_up(|w| {
            record(traj, err, names, w);
            if let Some(m) = mcap.as_mut() {
                m.step(w);
            }
            snapshot(before, after, w);
        });
        self.lockstep = Lockstep::new(
            self.names.len(),
            self.world.time(),
            self.world.config().timestep,
        );
        self.take_trajectory_error()
    }

    /// A connection delivered `input` for drone `drone`. A drone that has
    /// sent STOP sends nothing more; a broken or closed stream of a drone
    /// that is still flying is processed in its turn (the run ends there,
    /// deterministically); one of a drone waiting for its STOP reply ends
    /// the run at once.
    pub fn push(&mut self, drone: usize, input: Input) -> Result<(), SessionError> {
        use crate::lockstep::Phase;
        match (self.lockstep.phase(drone), &input) {
            (Phase::Flying, _) => self
                .lockstep
                .push(
                    drone,
                    Queued {
                        input,
                        answered: false,
                    },
                )
                .map_err(|e| self.fail(drone, e.to_string())),
            (Phase::Done, Input::Closed | Input::Broken(_)) => Ok(()),
            (Phase::Stopping { .. }, Input::Closed) => {
                Err(self.fail(drone, "the platform disconnected before its STOP reply"))
            }
            (_, Input::Broken(e)) => Err(self.fail(drone, e.to_string())),
            (_, Input::Frame { request, .. }) => {
                let what = match request {
                    Ok(r) => r.command().to_string(),
                    Err(_) => "an invalid frame".to_string(),
                };
                Err(self.fail(drone, format!("{what} after STOP")))
            }
        }
    }

    /// Processes everything the lockstep allows, then answers the queries
    /// that need not wait for their turn.
    pub fn run(&mut self, out: &mut dyn Outputs) -> Result<Progress, SessionError> {
        loop {
            match self.lockstep.next() {
                Next::Process { drone } => {
                    let queued = self
                        .lockstep
                        .pop(drone)
                        .expect("the lockstep processes a queued request");
                    self.process(drone, queued, out)?;
                }
                Next::Step => self.step(out)?,
                Next::Wait => {
                    self.answer_early(out);
                    return Ok(Progress::Waiting);
                }
                Next::Finished => return Ok(Progress::Finished),
            }
        }
    }

    /// DESIGN.md §15: a query of drone d at time t is answered once every
    /// flying drone's clock has reached t, never later because another drone
    /// has not sent its next request. The world's time T never passes a
    /// flying drone's clock, so that is when t = T. No change at T alters
    /// what a query reads at T (motor targets act from the next step on; a
    /// transmission started at T ends after T, and RADIO_RECV reports only
    /// what ended by T), so the reply is the one its turn would give. A
    /// query may pass its own drone's earlier RADIO_SEND and ADVANCE_TIME 0
    /// (same time), when they will be served; anything else of its drone
    /// before it (a step, STOP, a bad frame) makes it wait for its turn.
    /// A query that would fail waits for its turn too, which fails the run
    /// in the canonical order.
    fn answer_early(&mut self, out: &mut dyn Outputs) {
        use crate::lockstep::Phase;
        let now = self.lockstep.time();
        for d in 0..self.names.len() {
            if self.lockstep.phase(d) != Phase::Flying || self.lockstep.clock(d) != now {
                continue;
            }
            for k in 0..self.lockstep.queued(d) {
                let queued = self.lockstep.queued_at(d, k).expect("k < queued");
                if queued.answered {
                    continue;
                }
                let Input::Frame {
                    request: Ok(req), ..
                } = &queued.input
                else {
                    break;
                };
                if !is_query(req) {
                    if self.passes_at_same_time(d, req) {
                        continue;
                    }
                    break;
                }
                let req = req.clone();
                let answered = match self.query(d, req, now) {
                    Ok(reply) => out.reply_early(d, reply, now).is_ok(),
                    Err(_) => false,
                };
                if !answered {
                    break;
                }
                self.lockstep
                    .queued_at_mut(d, k)
                    .expect("k < queued")
                    .answered = true;
            }
        }
    }

    /// A change that leaves drone `d`'s clock where it is and will be
    /// served (the checks of [`Session::process`] and `Channel::send`).
    fn passes_at_same_time(&self, d: usize, req: &Request) -> bool {
        match req {
            Request::AdvanceTime { time } => *time == 0,
            Request::RadioSend {
                radio,
                data,
                offset_ps,
            } => send_start(self.lockstep.clock(d), *offset_ps).is_some_and(|start| {
                self.channel
                    .check_send(d, *radio, data.len(), start)
                    .is_ok()
            }),
            _ => false,
        }
    }

    /// Ends the trajectory, flushes the radio log and finishes the MCAP file
    /// (every exit path calls it; the MCAP file is closed even when another
    /// output failed).
    pub fn flush(&mut self) -> Result<(), SessionError> {
        let mcap = self.mcap.as_mut().map_or(Ok(()), McapLog::finish);
        if let Some(t) = self.trajectory.as_mut() {
            t.finish().map_err(|e| SessionError::Trajectory(e.into()))?;
        }
        mcap?;
        self.channel
            .flush_log()
            .map_err(|source| SessionError::Output {
                path: PathBuf::from("the radio log"),
                source,
            })
    }

    fn fail(&self, drone: usize, message: impl Into<String>) -> SessionError {
        SessionError::Drone {
            drone,
            name: self.names[drone].clone(),
            message: message.into(),
        }
    }

    /// One physics step of every drone, then what depends on it: the
    /// trajectory, the radio channel up to the new time, STOP replies.
    fn step(&mut self, out: &mut dyn Outputs) -> Result<(), SessionError> {
        self.world.step();
        record(
            &mut self.trajectory,
            &mut self.trajectory_error,
            &self.names,
            &self.world,
        );
        self.take_trajectory_error()?;
        if let Some(m) = self.mcap.as_mut() {
            m.step(&self.world);
        }
        snapshot(&mut self.before, &mut self.after, &self.world);
        self.lockstep.stepped();
        let now = self.world.time();
        debug_assert_eq!(now, self.lockstep.time());
        let (world, before, after) = (&self.world, &self.before, &self.after);
        self.channel.resolve(Picos::from_ms(now.0), &|d, t| {
            position_at(world, before, after, d, t)
        });
        if let Some(m) = self.mcap.as_mut() {
            let events = self.channel.take_events();
            m.radio(&events, |d, ps| {
                position_at(world, before, after, d, Picos(ps))
            });
        }
        let stopping: Vec<usize> = self.lockstep.stopping().collect();
        for d in stopping {
            if self.world.propellers_stopped(d) {
                self.answer_stop(d, out)?;
            }
        }
        Ok(())
    }

    fn answer_stop(&mut self, d: usize, out: &mut dyn Outputs) -> Result<(), SessionError> {
        let stop = self
            .lockstep
            .finish_stop(d)
            .expect("only a stopping drone is answered");
        let now = self.world.time();
        tracing::info!(
            drone = %self.names[d],
            time_ms = now.0,
            stop_ms = stop.0,
            collisions = self.world.state(d).collisions,
            "STOP: propellers stopped"
        );
        out.reply(
            d,
            Reply::Stop {
                time_s: now.as_secs_f64(),
                stop_time_ms: stop.0,
                // Only a world with gates counts them (DESIGN.md §10): a
                // world without keeps the thesis's STOP reply.
                gates_passed: (self.world.gates_total() > 0)
                    .then(|| self.world.state(d).gates_passed),
            },
            now,
        )
    }

    /// Serves drone `d`'s request at its clock (= the world time); one
    /// answered early is only traced.
    fn process(
        &mut self,
        d: usize,
        queued: Queued,
        out: &mut dyn Outputs,
    ) -> Result<(), SessionError> {
        let now = self.world.time();
        let req = match queued.input {
            Input::Frame { body, .. } if queued.answered => {
                out.request(d, &body, true, now)?;
                return out.trace_early(d, now);
            }
            Input::Closed => {
                return Err(self.fail(d, "the platform disconnected before STOP"));
            }
            Input::Broken(e) => return Err(self.fail(d, e.to_string())),
            Input::Frame { body, request } => {
                out.request(d, &body, request.is_ok(), now)?;
                request.map_err(|e| self.fail(d, e.to_string()))?
            }
        };
        match req {
            Request::SetVelocity { m1, m2, m3, m4 } => {
                self.world
                    .set_motor_commands(d, MotorCommands([m1, m2, m3, m4]))
                    .map_err(|e| self.fail(d, e.to_string()))?;
                let ts = self.world.config().timestep.0;
                self.lockstep
                    .advance(d, ts)
                    .map_err(|e| self.fail(d, e.to_string()))
            }
            Request::AdvanceTime { time } => self
                .lockstep
                .advance(d, time)
                .map_err(|e| self.fail(d, e.to_string())),
            Request::RadioSend {
                radio,
                data,
                offset_ps,
            } => {
                let start = send_start(now, offset_ps).ok_or_else(|| {
                    self.fail(
                        d,
                        format!("RADIO_SEND offset_ps {offset_ps} is beyond the end of time"),
                    )
                })?;
                self.channel
                    .send(d, radio, data, start)
                    .map_err(|e| self.fail(d, format!("RADIO_SEND: {e}")))
            }
            Request::Stop => {
                self.lockstep
                    .begin_stop(d)
                    .map_err(|e| self.fail(d, e.to_string()))?;
                self.world.stop_propellers(d);
                self.channel.retire(d);
                if self.world.propellers_stopped(d) {
                    self.answer_stop(d, out)?;
                }
                Ok(())
            }
            query => {
                let reply = self.query(d, query, now)?;
                out.reply(d, reply, now)
            }
        }
    }

    fn take_trajectory_error(&mut self) -> Result<(), SessionError> {
        match self.trajectory_error.take() {
            Some(e) => Err(SessionError::Trajectory(e)),
            None => Ok(()),
        }
    }
}

/// A RADIO_SEND's start: the drone's time plus its offset (`None` past
/// the end of time).
fn send_start(now: Millis, offset_ps: u64) -> Option<Picos> {
    Picos::from_ms(now.0).0.checked_add(offset_ps).map(Picos)
}

/// A request that only reads the world and has a reply (STOP has a reply
/// but changes the world).
fn is_query(req: &Request) -> bool {
    req.expects_reply() && !matches!(req, Request::Stop)
}

/// Appends one trajectory row per drone, keeping the first error for the caller.
fn record(
    traj: &mut Option<TrajectoryWriter>,
    err: &mut Option<csv::Error>,
    names: &[String],
    w: &World,
) {
    if let (Some(t), None) = (traj.as_mut(), err.as_ref()) {
        for (d, name) in names.iter().enumerate() {
            if let Err(e) = t.row(&w.state(d), name) {
                *err = Some(e);
                return;
            }
        }
    }
}

/// Shifts the step boundaries: `after` becomes `before`, the world's
/// present becomes `after` (no allocation).
fn snapshot(before: &mut Snapshot, after: &mut Snapshot, w: &World) {
    std::mem::swap(before, after);
    after.time = w.time();
    for (d, p) in after.positions.iter_mut().enumerate() {
        *p = w.position(d).to_array();
    }
}

/// Drone `d`'s centre at world time `t` within the last physics step:
/// linear between its positions at the step's two boundaries; a carried
/// drone's exactly on its path.
fn position_at(w: &World, before: &Snapshot, after: &Snapshot, d: usize, t: Picos) -> [f64; 3] {
    let t_ms = t.0 as f64 / Picos::PER_MS as f64;
    if let Some(path) = w.carried_path(d) {
        return path.at(t_ms / 1000.0);
    }
    let (t0, t1) = (before.time.0 as f64, after.time.0 as f64);
    let (a, b) = (before.positions[d], after.positions[d]);
    if t1 <= t0 {
        return b;
    }
    let f = ((t_ms - t0) / (t1 - t0)).clamp(0.0, 1.0);
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * f)
}
