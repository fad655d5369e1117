//! CRTP over UDP: cflib flies the drone (DESIGN.md §17).
//!
//! On a real Crazyflie the STM32's firmware answers CRTP; here the STM32
//! model does, with the firmware's port numbers, channels, packet layouts
//! and variable names. The firmware on the ISS starts it with the extension
//! command EXT_CRTP (7; `firmware/src/crtp_host.c`) after INIT_PID: from
//! then on the STM32 runs one iteration per world step on its own, as in
//! GET_STABLE — read the sensors, take the packets of the step (paced to the
//! wall clock, [`link`]), fly what the commander asks with the same PID and
//! motor path as every other mode, send the log blocks that are due — until
//! the link is closed: no packet for `crtp_idle_s` of simulated time after
//! the first one (cflib's UDP driver sends nothing when it disconnects).
//! Then the STM32 STOPs the drone and EXT_STAT shows EXT_CRTP.
//!
//! | port | file | served |
//! |---|---|---|
//! | 0 console | [`console`] | the console's lines |
//! | 2 param | [`param`] | TOC v2, read, write |
//! | 3 commander | [`commander`] | roll/pitch/yaw-rate/thrust |
//! | 4 mem | [`mem`] | the decks' 1-wire memories (number, details, read) |
//! | 5 log | [`log`] | TOC v2, blocks, periodic data |
//! | 6 localization | [`localization`] | external position / pose (and packed), fused into the flow estimate |
//! | 7 generic set-points | [`commander`] | stop, velocity world, z distance, hover, position, notify stop |
//! | 8 high-level commander | [`high_level`] | take-off, land, go-to, stop, group mask |
//! | 13 platform | here | protocol version, firmware version, device type |
//! | 15 link | here | echo, source (the "Bitcraze Crazyflie" magic), sink, null |

pub mod commander;
pub mod console;
pub mod high_level;
pub mod link;
pub mod localization;
pub mod log;
pub mod mem;
pub mod packet;
pub mod param;
pub mod telemetry;
pub mod toc;

use std::io;
use std::path::PathBuf;

use protocol::Sensors;

use self::commander::{Commander, Setpoint, Watched};
use self::console::ConsoleTap;
use self::high_level::HighLevel;
pub use self::link::CrtpSpec;
pub use self::link::PacingSummary;
use self::link::{Pacer, Recorder, Source};
use self::packet::*;
use self::param::{Decks, Known, Params};
pub use self::telemetry::PowerTelemetry;
use self::telemetry::{LogGroups, Telemetry, PWM_FULL};
use super::cascade::{self, Axis};
use super::estimator::Metres;
use super::flight::Outcome;
use super::motion::{wrap_angle, K_HEADING, MAX_YAW_RATE};
use super::pid::{to_body, DesiredState, MotorCommands};
use super::{invalid, Controller, Stm32};
use crate::peripherals::motors::MAX_SPEED;
use crate::peripherals::{DeviceCtx, DeviceError};
use crate::units::Picos;

/// The CRTP protocol version announced (platform port, `VERSION_GET_PROTOCOL`):
/// ≥ 4 makes cflib use TOC v2, > 8 the current generic set-point types.
pub const PROTOCOL_VERSION: u8 = 10;
/// `VERSION_GET_FIRMWARE` and `VERSION_GET_DEVICE_TYPE` answers.
const FIRMWARE_NAME: &[u8] = b"crazyflie-cosim";
const DEVICE_TYPE: &[u8] = b"CF21 (cosim)";
/// The link service's source answer (cflib's `platformservice.py` checks
/// the first 18 bytes).
const LINK_MAGIC: &[u8] = b"Bitcraze Crazyflie";
/// The null packet (port 15, channel 3, link bits set): cflib's scan probe.
const NULL_PACKET: u8 = 0xFF;

/// Position loop of the position set-point and the high-level commander:
/// velocity demand per metre of error, and its horizontal limit.
///
/// The firmware's `position_controller_pid.c` uses kp = 2 (1/s) on x, y
/// over a velocity loop of 25°, 0.44 rad, per m/s (`PID_VEL_X_KP`,
/// `platform_defaults_cf2.h`): 0.87 rad of tilt per metre of position
/// error. The velocity loop here is the Webots controller's, 2 rad per m/s
/// (DESIGN.md §4), 4.6 times stiffer; with the firmware's kp on top the
/// loop was marginal: in one of four cfclient-button sessions the moves
/// grew into an oscillation that hit a wall (docs/CFLIB.md). kp = 1 keeps
/// every recorded session stable with the tilt within 0.15 rad; it is not
/// the firmware's value but closer to its loop gain (2 rad/m, against
/// 4 rad/m with kp 2).
pub const KP_POSITION: f64 = 1.0;
pub const MAX_HORIZONTAL_SPEED: f64 = 1.0;
/// Largest roll/pitch the velocity loop may ask for when a CRTP client
/// flies by velocity or position (rad): the firmware's
/// `PID_VEL_ROLL_MAX`/`PID_VEL_PITCH_MAX`, 20° (`position_controller_pid.c`
/// constrains the velocity PID's attitude output to it).
pub const TILT_LIMIT: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// The CRTP link's settings (run keys `crtp`, `pace`, `crtp_idle_s`).
#[derive(Debug, Clone, PartialEq)]
pub struct CrtpConfig {
    pub spec: CrtpSpec,
    /// Simulated seconds per wall second with a live link (0: unpaced).
    pub pace: f64,
    /// The link is closed after this much simulated time without a packet.
    pub idle: Picos,
    /// Where the arrivals are recorded (`crtp.jsonl` in the output directory).
    pub record: Option<PathBuf>,
    /// Where a paced live link writes its steps' timing (`pacing.csv`).
    pub pacing_log: Option<PathBuf>,
    /// The platform has the AI deck (a camera or the GAP8 cluster).
    pub ai_deck: bool,
    /// The platform has the GAP8 cluster (`gap8.*` log variables).
    pub cluster: bool,
    /// The estimate is the flow filter's, which keeps a position variance
    /// (`kalman.varPX`, `varPY` log variables).
    pub position_variance: bool,
}

/// Counters printed when the link closes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CrtpStats {
    pub packets_in: u64,
    pub packets_out: u64,
    pub malformed: u64,
    pub ignored: u64,
    /// External positions received (port 6) and fused into the estimate.
    pub external_positions: u64,
    pub fused: u64,
}

/// What the controller flies in one iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Demand {
    Off,
    /// Attitude (rad), yaw rate (rad/s) and a collective motor speed
    /// (rad/s), or a height (m) for the height loop.
    Attitude {
        roll: f64,
        pitch: f64,
        yaw_rate: f64,
        collective: Option<f64>,
        z: f64,
    },
    /// Body velocity, height, yaw rate: the Bitcraze velocity controller.
    Track {
        vx: f64,
        vy: f64,
        z: f64,
        yaw_rate: f64,
    },
}

pub struct CrtpServer {
    cfg: CrtpConfig,
    source: Source,
    recorder: Option<Recorder>,
    pacer: Pacer,
    log: log::Log,
    params: Option<Params>,
    /// The decks' memories (port 4), with the params from the first sensors.
    mems: Option<mem::Memories>,
    commander: Commander,
    hl: HighLevel,
    pub telemetry: Telemetry,
    last_packet: Option<Picos>,
    /// The height a velocity-world set-point integrates (its vz).
    z_hold: Option<f64>,
    /// The drone's radio id when its firmware runs seed 004's radar.
    radar: Option<u8>,
    /// External positions of this step, for the estimator.
    external: Vec<[f64; 3]>,
    /// The console's unsent text (port 0), and whether a client has
    /// connected (sent more than the null packet of a scan's probe).
    console: ConsoleTap,
    client: bool,
    pub stats: CrtpStats,
}

fn io_device(e: io::Error) -> DeviceError {
    invalid(format!("CRTP link: {e}"))
}

impl CrtpServer {
    /// Binds the link (or reads the recording) and creates the recording.
    pub fn open(cfg: CrtpConfig, console: ConsoleTap) -> io::Result<CrtpServer> {
        let source = Source::open(&cfg.spec)?;
        let recorder = match &cfg.record {
            Some(p) if source.is_live() => Some(Recorder::create(p)?),
            _ => None,
        };
        let pace = if source.is_live() { cfg.pace } else { 0.0 };
        let pacer = match &cfg.pacing_log {
            Some(p) => Pacer::with_log(pace, p)?,
            None => Pacer::new(pace),
        };
        Ok(CrtpServer {
            log: log::Log::new(LogGroups {
                cluster: cfg.cluster,
                radar: false,
                variance: cfg.position_variance,
            }),
            cfg,
            source,
            recorder,
            pacer,
            params: None,
            mems: None,
            commander: Commander::default(),
            hl: HighLevel::default(),
            telemetry: Telemetry::default(),
            last_packet: None,
            z_hold: None,
            radar: None,
            external: Vec::new(),
            console,
            client: false,
            stats: CrtpStats::default(),
        })
    }

    pub fn config(&self) -> &CrtpConfig {
        &self.cfg
    }

    /// The firmware runs seed 004's radar as drone `id` (P2P_SELF, before
    /// EXT_CRTP, so before any packet is served): the `radar` log variables
    /// and parameters join the TOCs.
    pub fn enable_radar(&mut self, id: u8) {
        self.radar = Some(id);
        self.log = log::Log::new(LogGroups {
            cluster: self.cfg.cluster,
            radar: true,
            variance: self.cfg.position_variance,
        });
    }

    /// What the radar heard last (P2P_ID, P2P_RSSI), for the log.
    fn radar_heard(&mut self, heard: Option<(u8, f64)>) {
        let (id, rssi) = heard.map_or((0.0, 0.0), |(id, r)| (f64::from(id), r));
        self.telemetry.radar_id = id;
        self.telemetry.radar_rssi = rssi;
    }

    /// The `radar.enable` parameter (P2P_ENABLE).
    fn radar_enabled(&self) -> bool {
        self.params
            .as_ref()
            .is_some_and(|p| p.get(Known::RadarEnable) != 0.0)
    }

    /// The estimate and ranges of this step's sensor read; the decks from
    /// the first one (the param TOC is fixed from then on).
    fn observe(
        &mut self,
        s: &Sensors,
        est: &[f64; 15],
        world: [f64; 3],
        gains: &super::pid::PidGains,
        cascade: Option<&cascade::Cascade>,
    ) {
        let t = &mut self.telemetry;
        t.world = world;
        t.pos = [est[0], est[1], est[2]];
        t.yaw = est[3];
        t.vel = [est[4], est[5], est[6]];
        t.ranges.copy_from_slice(&est[7..13]);
        t.roll = s.roll;
        t.pitch = s.pitch;
        if self.params.is_none() {
            let decks = Decks {
                flow2: s.flow_vx.is_some(),
                multiranger: s.range_up.is_some(),
                ai: self.cfg.ai_deck,
            };
            self.mems = Some(mem::Memories::new(&decks));
            self.params = Some(Params::new(decks, gains, cascade, self.radar));
        }
    }

    fn pose(&self) -> [f64; 4] {
        let t = &self.telemetry;
        [t.pos[0], t.pos[1], t.pos[2], t.yaw]
    }

    /// Takes the packets of the step at `now` (waiting for the wall clock
    /// on a live link) and answers them.
    fn serve(&mut self, now: Picos) -> io::Result<()> {
        let deadline = self.pacer.deadline(now);
        loop {
            let got = self.source.receive(now, deadline)?;
            if got.is_empty() {
                // The wait is over: the step runs now.
                if let Some(d) = deadline {
                    self.pacer.ran(now, d, std::time::Instant::now())?;
                }
                return Ok(());
            }
            for bytes in got {
                self.dispatch(&bytes, now)?;
            }
        }
    }

    fn dispatch(&mut self, bytes: &[u8], now: Picos) -> io::Result<()> {
        self.stats.packets_in += 1;
        // A scan (cflib's, cfclient's at start) probes with the null packet
        // and goes away: neither the link's idle time nor the console's
        // lines start with a probe, they wait for a client that connects.
        if bytes != [NULL_PACKET] {
            self.last_packet = Some(now);
            self.client = true;
        }
        if let Some(r) = &mut self.recorder {
            r.record(now, bytes)?;
        }
        let p = match Packet::parse(bytes) {
            Ok(p) => p,
            Err(e) => {
                self.stats.malformed += 1;
                tracing::debug!(target: "cosim::crtp", "dropped: {e}");
                return Ok(());
            }
        };
        let reply = self.answer(&p, now);
        match reply {
            Some(r) => {
                self.stats.packets_out += 1;
                self.source.send(&r.encode())
            }
            None => Ok(()),
        }
    }

    /// The firmware's answer to `p` (and its effect).
    fn answer(&mut self, p: &Packet, now: Picos) -> Option<Packet> {
        let d = &p.data[..];
        let params = self.params.as_mut().expect("observed before serving");
        let data = match (p.port, p.channel) {
            (PORT_LINK, 0) => Some(d.to_vec()),
            (PORT_LINK, 1) => Some(LINK_MAGIC.to_vec()),
            (PORT_LINK, 2) => None,
            // The null packet (0xFF): answered so cflib's scan finds us.
            (PORT_LINK, 3) => Some(Vec::new()),
            (PORT_PLATFORM, 1) => match d.first() {
                Some(0) => Some(vec![0, PROTOCOL_VERSION]),
                Some(1) => Some([&[1u8][..], FIRMWARE_NAME].concat()),
                Some(2) => Some([&[2u8][..], DEVICE_TYPE].concat()),
                _ => None,
            },
            (PORT_MEM, ch) => {
                let mems = self.mems.as_ref().expect("observed before serving");
                match ch {
                    mem::CHAN_INFO => mems.info(d),
                    mem::CHAN_READ => mems.read(d),
                    mem::CHAN_WRITE => mems.write(d),
                    _ => None,
                }
            }
            (PORT_LOG, log::CHAN_TOC) => self.log.toc(d),
            (PORT_LOG, log::CHAN_CONTROL) => self.log.control(d, now),
            (PORT_PARAM, param::CHAN_TOC) => params.toc(d),
            (PORT_PARAM, param::CHAN_READ) => params.read(d),
            (PORT_PARAM, param::CHAN_WRITE) => params.write(d).map(|(ans, k)| {
                if k == Known::EnHighLevel && params.get(Known::EnHighLevel) == 0.0 {
                    self.hl.state = high_level::State::Idle;
                }
                ans
            }),
            (PORT_COMMANDER, 0) => {
                self.low_level(Setpoint::rpyt(d), now);
                None
            }
            (PORT_SETPOINT_GENERIC, 0) => {
                self.low_level(Setpoint::generic(d), now);
                None
            }
            (PORT_SETPOINT_GENERIC, 1) => {
                if commander::is_notify_stop(d) {
                    self.commander.release();
                    if self.telemetry.collective > 0.0 {
                        let pose = self.pose();
                        self.hl.hold(now, pose);
                    }
                } else {
                    self.stats.ignored += 1;
                }
                None
            }
            (PORT_SETPOINT_HL, 0) => {
                if params.get(Known::EnHighLevel) != 0.0 {
                    let pose = self.pose();
                    self.hl.command(d, now, pose);
                } else {
                    self.stats.ignored += 1;
                }
                None
            }
            (PORT_LOCALIZATION, ch) => {
                match localization::positions(ch, d) {
                    Some(ps) => {
                        self.stats.external_positions += ps.len() as u64;
                        self.external.extend(ps);
                    }
                    None => self.stats.ignored += 1,
                }
                None
            }
            _ => {
                self.stats.ignored += 1;
                None
            }
        };
        data.map(|data| Packet::new(p.port, p.channel, data))
    }

    fn low_level(&mut self, sp: Option<Setpoint>, now: Picos) {
        match sp {
            Some(sp) => {
                self.commander.set(sp, now);
                // Low-level set-points take priority: the planner stops.
                self.hl.state = high_level::State::Idle;
            }
            None => self.stats.ignored += 1,
        }
    }

    /// The position loop of the firmware's PID controller
    /// (`position_controller_pid.c`): a world-frame velocity toward the
    /// set-point `pos`, proportional to the error ([`KP_POSITION`], no feed-forward:
    /// `PID_POS_X_KFF` = 0, and with the high-level commander's absolute
    /// set-points the PID controller flies the planner's position only, not
    /// its velocity), limited, in the body frame; the yaw by the heading
    /// loop of the race's controller. Adding the plan's velocity on top
    /// (as this did before) made the loop unstable with the Webots velocity
    /// loop: cfclient's 0.5 m in 1 s overshot, oscillated with a growing
    /// amplitude and flipped the drone (docs/CFLIB.md).
    fn track(&self, pos: [f64; 3], yaw: f64) -> Demand {
        let t = &self.telemetry;
        let mut v = [0, 1].map(|i| KP_POSITION * (pos[i] - t.pos[i]));
        let n = v[0].hypot(v[1]);
        if n > MAX_HORIZONTAL_SPEED {
            v = v.map(|c| c * MAX_HORIZONTAL_SPEED / n);
        }
        let (vx, vy) = to_body(v[0], v[1], t.yaw);
        Demand::Track {
            vx,
            vy,
            z: pos[2],
            yaw_rate: (K_HEADING * wrap_angle(yaw - t.yaw)).clamp(-MAX_YAW_RATE, MAX_YAW_RATE),
        }
    }

    fn demand(&mut self, now: Picos, dt: f64) -> Demand {
        let t = self.telemetry;
        let watched = self.commander.watched(now);
        if !matches!(watched, Watched::Fresh(Setpoint::VelocityWorld { .. })) {
            self.z_hold = None;
        }
        let hold = |z: f64| Demand::Track {
            vx: 0.0,
            vy: 0.0,
            z,
            yaw_rate: 0.0,
        };
        match watched {
            Watched::Shutdown => Demand::Off,
            Watched::Stale(sp) => match sp {
                Setpoint::Stop => Demand::Off,
                Setpoint::Hover { z, .. }
                | Setpoint::ZDistance { z, .. }
                | Setpoint::Position { z, .. } => hold(z),
                _ => hold(t.pos[2]),
            },
            Watched::Fresh(sp) => match sp {
                Setpoint::Stop => Demand::Off,
                Setpoint::Attitude {
                    roll,
                    pitch,
                    yaw_rate,
                    thrust,
                } => Demand::Attitude {
                    roll,
                    pitch,
                    yaw_rate,
                    collective: Some(thrust / PWM_FULL * MAX_SPEED),
                    z: t.pos[2],
                },
                Setpoint::ZDistance {
                    roll,
                    pitch,
                    yaw_rate,
                    z,
                } => Demand::Attitude {
                    roll,
                    pitch,
                    yaw_rate,
                    collective: None,
                    z,
                },
                Setpoint::Hover {
                    vx,
                    vy,
                    yaw_rate,
                    z,
                } => Demand::Track {
                    vx,
                    vy,
                    z,
                    yaw_rate,
                },
                Setpoint::VelocityWorld {
                    vx,
                    vy,
                    vz,
                    yaw_rate,
                } => {
                    let z = self.z_hold.unwrap_or(t.pos[2]) + vz * dt;
                    self.z_hold = Some(z);
                    let (bx, by) = to_body(vx, vy, t.yaw);
                    Demand::Track {
                        vx: bx,
                        vy: by,
                        z,
                        yaw_rate,
                    }
                }
                Setpoint::Position { x, y, z, yaw } => self.track([x, y, z], yaw),
            },
            Watched::None => match self.hl.aim(now, t.pos[2], t.vel[2]) {
                Some(r) => self.track(r.pos, r.yaw),
                None => Demand::Off,
            },
        }
    }

    /// The set-point the firmware's commander hands its controller
    /// (`crtp_commander_generic.c`'s decoders, `commander.c`'s watchdog,
    /// the high-level commander's absolute set-points): angles in degrees,
    /// pitch nose up, yaw counter-clockwise.
    fn firmware_setpoint(&mut self, now: Picos) -> cascade::Setpoint {
        use cascade::Setpoint as Fw;
        let t = self.telemetry;
        let level = |roll: f64, pitch: f64, yaw_rate: f64| Fw {
            x: Axis::Disable,
            y: Axis::Disable,
            // Packet pitch is nose-up positive; ours nose-down (see
            // `commander`).
            roll: roll.to_degrees(),
            pitch: -pitch.to_degrees(),
            yaw: Axis::Velocity(yaw_rate.to_degrees()),
            ..Fw::STOP
        };
        let decode = |sp: Setpoint| match sp {
            Setpoint::Stop => Fw::STOP,
            Setpoint::Attitude {
                roll,
                pitch,
                yaw_rate,
                thrust,
            } => Fw {
                thrust,
                ..level(roll, pitch, yaw_rate)
            },
            Setpoint::ZDistance {
                roll,
                pitch,
                yaw_rate,
                z,
            } => Fw {
                z: Axis::Abs(z),
                ..level(roll, pitch, yaw_rate)
            },
            Setpoint::Hover {
                vx,
                vy,
                yaw_rate,
                z,
            } => Fw {
                x: Axis::Velocity(vx),
                y: Axis::Velocity(vy),
                z: Axis::Abs(z),
                yaw: Axis::Velocity(yaw_rate.to_degrees()),
                velocity_body: true,
                ..Fw::STOP
            },
            Setpoint::VelocityWorld {
                vx,
                vy,
                vz,
                yaw_rate,
            } => Fw {
                x: Axis::Velocity(vx),
                y: Axis::Velocity(vy),
                z: Axis::Velocity(vz),
                yaw: Axis::Velocity(yaw_rate.to_degrees()),
                ..Fw::STOP
            },
            Setpoint::Position { x, y, z, yaw } => Fw {
                x: Axis::Abs(x),
                y: Axis::Abs(y),
                z: Axis::Abs(z),
                yaw: Axis::Abs(yaw.to_degrees()),
                ..Fw::STOP
            },
        };
        match self.commander.watched(now) {
            Watched::Shutdown => Fw::STOP,
            Watched::Fresh(sp) => decode(sp),
            // Past 500 ms: level, no yaw rate, z as the set-point had it.
            Watched::Stale(sp) => Fw {
                x: Axis::Disable,
                y: Axis::Disable,
                roll: 0.0,
                pitch: 0.0,
                yaw: Axis::Velocity(0.0),
                ..decode(sp)
            },
            Watched::None => match self.hl.aim(now, t.pos[2], t.vel[2]) {
                Some(r) => Fw {
                    x: Axis::Abs(r.pos[0]),
                    y: Axis::Abs(r.pos[1]),
                    z: Axis::Abs(r.pos[2]),
                    yaw: Axis::Abs(r.yaw.to_degrees()),
                    ..Fw::STOP
                },
                None => Fw::STOP,
            },
        }
    }

    /// The console's complete lines, once a client has connected (see
    /// [`console`]).
    fn send_console(&mut self) -> io::Result<()> {
        if !self.client {
            return Ok(());
        }
        for d in console::take_packets(&self.console) {
            self.stats.packets_out += 1;
            self.source
                .send(&Packet::new(PORT_CONSOLE, 0, d).encode())?;
        }
        Ok(())
    }

    /// The log blocks due at `now`.
    fn send_logs(&mut self, now: Picos) -> io::Result<()> {
        for d in self.log.due(now, &self.telemetry) {
            self.stats.packets_out += 1;
            self.source
                .send(&Packet::new(PORT_LOG, log::CHAN_DATA, d).encode())?;
        }
        Ok(())
    }

    /// The link has been closed (see the module docs).
    pub fn closed(&self, now: Picos) -> bool {
        self.last_packet
            .is_some_and(|t| now.saturating_sub(t) > self.cfg.idle)
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.pacer.flush()?;
        match &mut self.recorder {
            Some(r) => r.flush(),
            None => Ok(()),
        }
    }

    /// How the pacing held (`None`: unpaced, a replay, or no paced steps).
    pub fn pacing(&self) -> Option<PacingSummary> {
        self.pacer.summary()
    }

    /// `kalman.resetEstimation` writes (counted; see docs/CFLIB.md).
    pub fn estimator_resets(&self) -> u64 {
        self.params.as_ref().map_or(0, |p| p.resets)
    }
}

impl Stm32 {
    /// The step's external positions into the estimate (flow mode; the
    /// GPS takes nothing), with `locSrv.extPosStdDev`: `s` and the
    /// telemetry get the corrected x, y before the controller flies on them.
    fn fuse_external(&mut self, server: &mut CrtpServer, s: &mut Sensors) {
        let std = server
            .params
            .as_ref()
            .map_or(localization::DEFAULT_EXT_POS_STD, |p| {
                p.get(Known::ExtPosStdDev)
            });
        for m in std::mem::take(&mut server.external) {
            if let Some(p) = self.motion.fuse_external(m, Metres(std)) {
                [s.x, s.y] = p;
                server.telemetry.pos[0..2].copy_from_slice(&p);
                server.stats.fused += 1;
            }
        }
        server.telemetry.position_variance = self.motion.position_variance();
    }

    /// Gives the STM32 its CRTP link (`--crtp`).
    pub fn attach_crtp(&mut self, server: CrtpServer) {
        self.crtp = Some(Box::new(server));
    }

    pub fn crtp(&self) -> Option<&CrtpServer> {
        self.crtp.as_deref()
    }

    /// Writes out what the link still buffers (the arrivals, the pacing's
    /// rows): a run that ends at `max_time_s` never closed its link.
    pub fn flush_crtp(&mut self) -> io::Result<()> {
        match self.crtp.as_mut() {
            Some(c) => c.flush(),
            None => Ok(()),
        }
    }

    /// The power network's sample, for the `pm`, `power` and `gap8` logs.
    pub fn crtp_power(&mut self, p: PowerTelemetry) {
        if let Some(c) = self.crtp.as_mut() {
            c.telemetry.power = p;
        }
    }

    /// One world step of the CRTP process: sensors, the step's packets,
    /// the commander's demand through the PID, the due log blocks.
    /// `Reached` once the link is closed.
    pub(super) fn crtp_iteration(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(Outcome, MotorCommands), DeviceError> {
        let mut s = self.read_sensors(now, ctx)?;
        self.stats.pid_iterations += 1;
        let (dt, actual) = self.measured(&s);
        let mut server = self.crtp.take().expect("the CRTP process has a link");
        let firmware = self.cfg.controller == Controller::Pid;
        server.observe(
            &s,
            &self.motion.est,
            self.motion.world,
            &self.flight.pid.gains,
            firmware.then_some(&self.flight.cascade),
        );
        server.radar_heard(self.motion.p2p_heard());
        let result = (|| {
            server.serve(now).map_err(io_device)?;
            self.motion.set_p2p_enable(server.radar_enabled());
            server.send_console().map_err(io_device)?;
            self.fuse_external(&mut server, &mut s);
            if firmware {
                let commands = self.fly_cascade(&mut server, &s, now, dt);
                return Self::finish_crtp_step(&mut server, now, ctx, commands);
            }
            if let Some(p) = &server.params {
                p.apply_gains(&mut self.flight.pid.gains);
            }
            let demand = server.demand(now, dt);
            let mut desired = DesiredState::default();
            let commands = match demand {
                Demand::Off => {
                    // Motors off: the controller starts afresh next time
                    // (no integrator wound up on the ground).
                    self.flight.pid.reset();
                    self.flight.past_time = s.time_s;
                    self.flight.past_x = s.x;
                    self.flight.past_y = s.y;
                    MotorCommands::default()
                }
                Demand::Attitude {
                    roll,
                    pitch,
                    yaw_rate,
                    collective,
                    z,
                } => {
                    desired = DesiredState {
                        roll,
                        pitch,
                        yaw_rate,
                        altitude: z,
                        ..DesiredState::default()
                    };
                    let c = self
                        .flight
                        .pid
                        .step_attitude(&actual, &desired, dt, collective);
                    self.flight.past_time = s.time_s;
                    self.flight.past_x = s.x;
                    self.flight.past_y = s.y;
                    c
                }
                Demand::Track {
                    vx,
                    vy,
                    z,
                    yaw_rate,
                } => {
                    desired = DesiredState {
                        vx,
                        vy,
                        yaw_rate,
                        altitude: z,
                        ..DesiredState::default()
                    };
                    self.control(&s, &actual, &mut desired, dt, Some(TILT_LIMIT))?
                }
            };
            if commands.as_array().iter().any(|m| !m.is_finite()) {
                return Err(invalid(format!(
                    "the controller produced non-finite motor commands {commands:?}"
                )));
            }
            let t = &mut server.telemetry;
            t.motors = commands.as_array();
            t.collective = commands.as_array().iter().sum::<f64>() / 4.0;
            t.sp_roll = desired.roll;
            t.sp_pitch = desired.pitch;
            t.sp_yaw = s.yaw;
            Self::finish_crtp_step(&mut server, now, ctx, commands)
        })();
        self.crtp = Some(server);
        result
    }

    /// One step of the firmware's cascade: the commander's set-point
    /// through [`cascade::Cascade`], the power distribution, the motors'
    /// PWM as the world's propeller speeds.
    fn fly_cascade(
        &mut self,
        server: &mut CrtpServer,
        s: &Sensors,
        now: Picos,
        dt: f64,
    ) -> MotorCommands {
        if let Some(p) = &server.params {
            p.apply_cascade(&mut self.flight.cascade);
        }
        let sp = server.firmware_setpoint(now);
        let t = server.telemetry;
        let state = cascade::State::from_world(
            t.pos,
            t.vel,
            [s.roll, s.pitch, s.yaw],
            [s.roll_rate, s.pitch_rate, s.yaw_rate],
        );
        let control = self.flight.cascade.step(&sp, &state, dt);
        let pwm = cascade::power_distribution(&control);
        let speeds = pwm.map(cascade::world_speed);
        let commands = MotorCommands {
            m1: speeds[0],
            m2: speeds[1],
            m3: speeds[2],
            m4: speeds[3],
        };
        self.flight.past_time = s.time_s;
        self.flight.past_x = s.x;
        self.flight.past_y = s.y;
        let t = &mut server.telemetry;
        t.motors = speeds;
        t.collective = speeds.iter().sum::<f64>() / 4.0;
        t.pwm = Some((control.thrust, pwm));
        let att = self.flight.cascade.attitude_desired();
        t.sp_roll = att[0].to_radians();
        t.sp_pitch = -att[1].to_radians();
        t.sp_yaw = att[2].to_radians();
        commands
    }

    /// The end of every CRTP step: the due log blocks, and whether the link
    /// has closed.
    fn finish_crtp_step(
        server: &mut CrtpServer,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
        commands: MotorCommands,
    ) -> Result<(Outcome, MotorCommands), DeviceError> {
        {
            if commands.as_array().iter().any(|m| !m.is_finite()) {
                return Err(invalid(format!(
                    "the controller produced non-finite motor commands {commands:?}"
                )));
            }
            server.send_logs(now).map_err(io_device)?;
            let outcome = if server.closed(now) {
                server.flush().map_err(io_device)?;
                let st = server.stats;
                let msg = format!(
                    "[CRTP] link closed: {} packets in ({} malformed, {} ignored, {} external positions, {} fused), {} out\n",
                    st.packets_in, st.malformed, st.ignored, st.external_positions, st.fused, st.packets_out
                );
                (ctx.console)(&msg);
                Outcome::Reached
            } else {
                Outcome::Flying
            };
            Ok((outcome, commands))
        }
    }
}
