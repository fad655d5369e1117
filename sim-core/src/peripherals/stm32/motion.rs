//! The STM32 extension (not in the thesis; DESIGN.md
//! §9–§10, register map in `firmware/src/cosim_regs.h`, "STM32 extension"):
//! the state estimate, the six ranges and the optical flow the STM32 read at
//! its last sensor update, and MotionCommander-like commands (cflib's
//! `motion_commander`) plus a heading target for the race's position
//! controller.
//!
//! Beyond the indoor-flight registers, EST_ROLL and EST_PITCH (+206, +214)
//! give the InertialUnit's roll and pitch of the same sensor read: the
//! vision firmware levels the camera's view of a gate with them. EST_TIME
//! (+222) is the world time (s) of that sensor read, the `time_s`
//! the world returned with the state: a flying swarm firmware stamps its
//! estimates with it (docs/SWARM_RESULTS.md §5), since its core clock does
//! not run with the world's between the STM32's steps.
//!
//! Commands are written as one 32-bit word to EXT_CTRL (the command starts
//! when its last byte is written); EXT_STAT is 0 from then until the command
//! completes, then shows its code, or `EXT_ERROR`:
//!
//! | code | command | takes |
//! |---|---|---|
//! | 1 | EXT_SET_HEADING | at once: the race's position controller holds the heading CMD_YAW (yaw rate `K_HEADING`·error, at most [`MAX_YAW_RATE`]) and rotates its world-frame velocity demand into the body frame by the current yaw |
//! | 2 | EXT_SET_VELOCITY | at once: velocity mode with CMD_VX/VY (body frame, the horizontal speed clamped to the speed limit), CMD_HEIGHT (approached at the speed limit), CMD_YAW_RATE; each RUN_SINGLE_STEP_PID then flies one iteration (7 ms, as in race mode) of it |
//! | 3 | EXT_SET_SPEED_LIMIT | at once: CMD_SPEED_LIMIT (> 0; default 0.2 m/s, cflib's) |
//! | 4 | EXT_TAKEOFF | iterations of one timestep each (as GET_STABLE) climbing at the speed limit to CMD_HEIGHT above the start, until within the tolerance; then velocity mode, hovering |
//! | 5 | EXT_LAND | iterations of one timestep each descending at the speed limit to the ground, until within the tolerance of it for 3 iterations (cflib's MotionCommander lands, then stops the motors at once), then STOP and the motors' stop time |
//! | 7 | EXT_CRTP | iterations of one timestep each serving the CRTP link ([`super::crtp`]) until it closes, then STOP and the motors' stop time |
//! | 6 | EXT_POSITION_MODE | at once: back to the race's position targets (SET_TARGET, RUN_SINGLE_STEP_PID, RUN_PID), the target set to the current position |
//! | 0xFFFFFFFF | EXT_ERROR | an unknown command, a non-finite or out-of-range argument, a command before INIT_PID or while a process (GET_STABLE, RUN_PID, GO_DOWN, take-off, landing) runs |
//!
//! Without EXT_SET_HEADING the position controller is exactly Appendix C's
//! (x error → body y, y error → body x, yaw rate 0): the thesis's race never
//! writes EXT_CTRL, so its outputs do not change by a bit. With a heading
//! target the world-frame demand is rotated by the current yaw; at yaw
//! exactly +π/2 that is Appendix C's mapping (up to cos(π/2) = 6e-17 in f64).
//!
//! Every flying command goes through the same PID ([`super::pid`]) and the
//! same motor path (SET_VELOCITY steps, the 1 ms motor power model, GET_DATA
//! for the D'Andrea and Stolaroff models) as the race's iterations, and
//! marks the STM32 busy until it completes: their energy is accounted as the
//! race's is.

use protocol::{Reply, Request, Sensors};

use super::estimator::{Attitude, Drift, FlowFilter, FlowFilterParams, Metres, Seconds};
use super::pid::{to_body, DesiredState, MotorCommands};
use super::{invalid, world_err, Outcome, Process, Stm32};
use crate::peripherals::{DeviceCtx, DeviceError, LinkError, TimedReg};
use crate::units::Picos;

/// Offsets within the STM32 (firmware offset − 102402).
pub const EXT_CTRL: u32 = 30;
pub const EXT_STAT: u32 = 34;
pub const EST_X: u32 = 38;
pub const EST_Y: u32 = 46;
pub const EST_Z: u32 = 54;
pub const EST_YAW: u32 = 62;
pub const EST_VX: u32 = 70;
pub const EST_VY: u32 = 78;
pub const EST_VZ: u32 = 86;
pub const RANGE_FRONT: u32 = 94;
pub const RANGE_BACK: u32 = 102;
pub const RANGE_LEFT: u32 = 110;
pub const RANGE_RIGHT: u32 = 118;
pub const RANGE_UP: u32 = 126;
pub const RANGE_DOWN: u32 = 134;
pub const FLOW_VX: u32 = 142;
pub const FLOW_VY: u32 = 150;
pub const CMD_VX: u32 = 158;
pub const CMD_VY: u32 = 166;
pub const CMD_HEIGHT: u32 = 174;
pub const CMD_YAW_RATE: u32 = 182;
pub const CMD_YAW: u32 = 190;
pub const CMD_SPEED_LIMIT: u32 = 198;
/// Roll and pitch (rad) of the last sensor read (added after the agreed map
/// for the vision firmware, which levels the camera's view).
pub const EST_ROLL: u32 = 206;
pub const EST_PITCH: u32 = 214;
/// World time (s) of the last sensor read (the last register before
/// EXT_END).
pub const EST_TIME: u32 = 222;
/// Seed 004's radar on a drone flown over CRTP (§4.3.1; `crtp_radar.c`,
/// docs/LAB.md): the nRF51 broadcasts and hears the P2P beacons, the STM32
/// serves the `radar` log variables and parameters. While EXT_CRTP runs
/// they share four u32 registers (the syslink of a real Crazyflie):
/// P2P_ENABLE (R) the `radar.enable` parameter, written by the STM32 each
/// iteration; P2P_SELF (W) the drone's radio id, written before EXT_CRTP
/// (0: no radar, no `radar` group in the TOCs); P2P_ID (W) the last drone
/// heard (0: none for 3 s) and P2P_RSSI (W, i32) its RSSI in centi-dBm.
pub const P2P_ENABLE: u32 = 230;
pub const P2P_SELF: u32 = 234;
pub const P2P_ID: u32 = 238;
pub const P2P_RSSI: u32 = 242;
/// End of the extension (and of the STM32's register file).
pub const EXT_END: u32 = 246;
/// The bytes between the race's registers and EXT_CTRL fault.
pub const GAP: std::ops::Range<u32> = 26..EXT_CTRL;

/// Extension commands and EXT_STAT codes.
pub const EXT_SET_HEADING: u32 = 1;
pub const EXT_SET_VELOCITY: u32 = 2;
pub const EXT_SET_SPEED_LIMIT: u32 = 3;
pub const EXT_TAKEOFF: u32 = 4;
pub const EXT_LAND: u32 = 5;
pub const EXT_POSITION_MODE: u32 = 6;
/// Serve the CRTP link until it closes (`super::crtp`; our extension).
pub const EXT_CRTP: u32 = 7;
pub const EXT_ERROR: u32 = 0xFFFF_FFFF;

/// Listing 4.3's largest horizontal demand per axis (m/s).
const RACE_AXIS_SPEED: f64 = 0.5;
/// Default speed limit (m/s): cflib's MotionCommander default velocity.
pub const DEFAULT_SPEED_LIMIT: f64 = 0.2;
/// Heading loop gain (1/s): yaw-rate demand per radian of heading error.
/// Not in the thesis (its race never turns); 2/s settles a 90° turn in about
/// 3 s on the world's Crazyflie without overshoot beyond the tolerance.
pub const K_HEADING: f64 = 2.0;
/// Largest yaw-rate demand (rad/s): cflib's MotionCommander turn rate
/// (`RATE = 360 / 5` °/s).
pub const MAX_YAW_RATE: f64 = 72.0 * std::f64::consts::PI / 180.0;

/// Where the estimate's (and the controller's) x, y come from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum PositionSource {
    /// The world's GPS, as the thesis (Appendix C).
    #[default]
    Gps,
    /// Dead reckoning: FLOW_VX/VY fused with the attitude by the flow
    /// filter ([`super::estimator`]), its velocity integrated from the
    /// start position (so the estimate drifts with the flow's errors).
    Flow,
}

impl std::str::FromStr for PositionSource {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "gps" => Ok(PositionSource::Gps),
            "flow" => Ok(PositionSource::Flow),
            _ => Err("expected gps | flow".into()),
        }
    }
}

impl std::fmt::Display for PositionSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PositionSource::Gps => "gps",
            PositionSource::Flow => "flow",
        })
    }
}

/// A velocity-mode set-point (body frame).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Setpoint {
    pub vx: f64,
    pub vy: f64,
    pub height: f64,
    pub yaw_rate: f64,
}

/// Which controller RUN_SINGLE_STEP_PID runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Mode {
    /// The race's position targets (Appendix C).
    Position,
    /// MotionCommander-like velocity set-point.
    Velocity(Setpoint),
}

/// The extension's registers and state.
#[derive(Debug, Clone)]
pub(super) struct Motion {
    ctrl: [u8; 4],
    stat: TimedReg<u32>,
    /// EST_X .. FLOW_VY as f64 values, in register order.
    pub(super) est: [f64; 15],
    args: [u8; (EST_ROLL - CMD_VX) as usize],
    /// Roll, pitch and the world time (s) of the last sensor read
    /// (EST_ROLL, EST_PITCH, EST_TIME).
    tail: [f64; 3],
    pub(super) mode: Mode,
    heading: Option<f64>,
    speed_limit: f64,
    source: PositionSource,
    range_max_mm: f64,
    /// Start position (INIT_PID) and the flow filter's dead reckoning.
    start: [f64; 3],
    filter_params: FlowFilterParams,
    dead: FlowFilter,
    /// The flow estimate's distance from the GPS (flow mode only).
    pub(super) drift: Option<Drift>,
    last: Option<(f64, [f64; 3])>,
    /// Iterations on the ground while landing.
    pub(super) landed_for: u32,
    /// P2P_ENABLE, P2P_SELF, P2P_ID, P2P_RSSI.
    p2p: [u8; (EXT_END - P2P_ENABLE) as usize],
    /// The world's position of the last sensor read (its GPS), before the
    /// flow mode replaces x, y with the estimate.
    pub(super) world: [f64; 3],
}

impl Motion {
    pub(super) fn new(
        source: PositionSource,
        range_max_mm: f64,
        filter_params: FlowFilterParams,
    ) -> Self {
        Motion {
            ctrl: [0; 4],
            stat: TimedReg::default(),
            est: [0.0; 15],
            args: [0; (EST_ROLL - CMD_VX) as usize],
            tail: [0.0; 3],
            mode: Mode::Position,
            heading: None,
            speed_limit: DEFAULT_SPEED_LIMIT,
            source,
            range_max_mm,
            start: [0.0; 3],
            filter_params,
            dead: FlowFilter::new(filter_params, [0.0; 2]),
            drift: None,
            last: None,
            landed_for: 0,
            p2p: [0; (EXT_END - P2P_ENABLE) as usize],
            world: [0.0; 3],
        }
    }

    pub(super) fn read(&self, offset: u32, now: Picos) -> u8 {
        match offset {
            EXT_CTRL..EXT_STAT => self.ctrl[(offset - EXT_CTRL) as usize],
            EXT_STAT..EST_X => self.stat.get(now).to_le_bytes()[(offset - EXT_STAT) as usize],
            EST_X..CMD_VX => {
                let i = (offset - EST_X) as usize;
                self.est[i / 8].to_le_bytes()[i % 8]
            }
            CMD_VX..EST_ROLL => self.args[(offset - CMD_VX) as usize],
            P2P_ENABLE..EXT_END => self.p2p[(offset - P2P_ENABLE) as usize],
            _ => {
                let i = (offset - EST_ROLL) as usize;
                self.tail[i / 8].to_le_bytes()[i % 8]
            }
        }
    }

    /// When a read of `offset` could change without a core access.
    pub(super) fn stable_until(&self, offset: u32, now: Picos, next: Option<Picos>) -> Picos {
        let next = next.unwrap_or(Picos::MAX);
        match offset {
            EXT_STAT..EST_X => self.stat.stable_until(now).min(next),
            EST_X..CMD_VX | EST_ROLL..P2P_SELF => next,
            _ => Picos::MAX,
        }
    }

    fn p2p_reg(&self, offset: u32) -> u32 {
        let i = (offset - P2P_ENABLE) as usize;
        u32::from_le_bytes(self.p2p[i..i + 4].try_into().expect("4 bytes"))
    }

    /// The drone's radio id if its firmware runs the radar (P2P_SELF).
    pub(super) fn p2p_self(&self) -> Option<u8> {
        match self.p2p_reg(P2P_SELF) {
            0 => None,
            id => Some(id as u8),
        }
    }

    /// The last drone heard and its RSSI (dBm), if any (P2P_ID, P2P_RSSI).
    pub(super) fn p2p_heard(&self) -> Option<(u8, f64)> {
        match self.p2p_reg(P2P_ID) {
            0 => None,
            id => Some((id as u8, self.p2p_reg(P2P_RSSI) as i32 as f64 / 100.0)),
        }
    }

    pub(super) fn set_p2p_enable(&mut self, on: bool) {
        self.p2p[..4].copy_from_slice(&u32::from(on).to_le_bytes());
    }

    fn arg(&self, offset: u32) -> f64 {
        let i = (offset - CMD_VX) as usize;
        f64::from_le_bytes(self.args[i..i + 8].try_into().expect("8 bytes"))
    }

    pub(super) fn complete(&mut self, at: Picos, code: u32) {
        self.stat.set_at(at, code);
    }

    /// At INIT_PID: the start pose, and the estimate from it.
    /// `ts`: the world's timestep, to which the flow noise the filter
    /// assumes (σ per 32 ms sample, as the world's) is scaled as the world
    /// scales its noise (`TimestepMs::white_noise_scale`).
    pub(super) fn init(&mut self, time_s: f64, pos: [f64; 3], ts: protocol::TimestepMs) {
        self.start = pos;
        let mut params = self.filter_params;
        params.flow_std.0 *= ts.white_noise_scale();
        self.dead = FlowFilter::new(params, [pos[0], pos[1]]);
        self.last = Some((time_s, pos));
        self.tail[2] = time_s;
        self.est[0..3].copy_from_slice(&pos);
        // GET_INIT_DATA has no attitude, velocities or ranges: yaw and
        // velocities 0, ranges "nothing seen" until the first sensor read.
        self.est[3..7].fill(0.0);
        self.est[7..13].fill(-1.0);
        self.est[13..15].fill(0.0);
    }

    /// The set-point's demand for the race's position controller: from
    /// Appendix C's body-frame values (`forward` = body x from the y error,
    /// `sideways` = body y from the x error, valid at yaw +π/2) to
    /// (vx, vy, yaw rate). Without a heading target, Appendix C unchanged.
    pub(super) fn steer(&self, forward: f64, sideways: f64, yaw: f64) -> (f64, f64, f64) {
        let Some(heading) = self.heading else {
            return (forward, sideways, 0.0);
        };
        // Appendix C at yaw +π/2: body y = −world x, body x = world y.
        let yaw_rate = (K_HEADING * wrap_angle(heading - yaw)).clamp(-MAX_YAW_RATE, MAX_YAW_RATE);
        let (vx, vy) = to_body(-sideways, forward, yaw);
        // Listing 4.3 demands at most 0.5 m/s per body axis; a rotated
        // diagonal demand would exceed it (0.71 m/s at 45°): scale it back,
        // direction kept, so the velocity loop sees what the race tuned it for.
        let m = vx.abs().max(vy.abs());
        let k = if m > RACE_AXIS_SPEED {
            RACE_AXIS_SPEED / m
        } else {
            1.0
        };
        (vx * k, vy * k, yaw_rate)
    }

    /// A sensor read: the estimate, ranges and flow; in flow mode the
    /// dead-reckoned x, y replace the GPS's in `s` (the controller flies on
    /// the estimate).
    fn update(&mut self, s: &mut Sensors) -> Result<(), String> {
        let flow = match (s.flow_vx, s.flow_vy) {
            (Some(vx), Some(vy)) => Some((vx, vy)),
            _ => None,
        };
        self.world = [s.x, s.y, s.z];
        let (last_t, last_p) = self.last.unwrap_or((s.time_s, [s.x, s.y, s.z]));
        let dt = s.time_s - last_t;
        if self.source == PositionSource::Flow {
            let Some((fvx, fvy)) = flow else {
                return Err(
                    "stm32.position_source = flow, but the world sends no FLOW_VX/FLOW_VY".into(),
                );
            };
            let att = Attitude {
                roll: s.roll,
                pitch: s.pitch,
                yaw: s.yaw,
            };
            let truth = [s.x, s.y];
            self.dead.step(Seconds(dt), att, [fvx, fvy]);
            [s.x, s.y] = self.dead.position();
            self.drift
                .get_or_insert_with(Drift::default)
                .record(truth, [s.x, s.y]);
        }
        let pos = [s.x, s.y, s.z];
        let vel = if dt > 0.0 {
            [
                (pos[0] - last_p[0]) / dt,
                (pos[1] - last_p[1]) / dt,
                (pos[2] - last_p[2]) / dt,
            ]
        } else {
            [self.est[4], self.est[5], self.est[6]]
        };
        self.last = Some((s.time_s, pos));
        self.tail = [s.roll, s.pitch, s.time_s];
        let range = |mm: f64| {
            if mm.is_finite() && mm >= 0.0 && mm < self.range_max_mm {
                mm / 1000.0
            } else {
                -1.0
            }
        };
        let opt = |mm: Option<f64>| mm.map_or(-1.0, range);
        let (fvx, fvy) = flow.unwrap_or((0.0, 0.0));
        self.est = [
            pos[0],
            pos[1],
            pos[2],
            s.yaw,
            vel[0],
            vel[1],
            vel[2],
            range(s.range_front),
            range(s.range_back),
            range(s.range_left),
            range(s.range_right),
            opt(s.range_up),
            opt(s.range_down),
            fvx,
            fvy,
        ];
        Ok(())
    }

    /// An external position (x, y, z; m) with standard deviation `std`:
    /// in flow mode the dead-reckoned x, y are corrected
    /// ([`FlowFilter::fuse_position`]) and the corrected x, y returned; the
    /// GPS (already absolute) and the height (the world's) take nothing.
    pub(super) fn fuse_external(&mut self, m: [f64; 3], std: Metres) -> Option<[f64; 2]> {
        if self.source != PositionSource::Flow {
            return None;
        }
        let p = self.dead.fuse_position([m[0], m[1]], std);
        self.est[0..2].copy_from_slice(&p);
        // The next step's velocity is the position's difference from here:
        // from the corrected position, so a correction is not a velocity.
        if let Some((_, last)) = &mut self.last {
            last[0..2].copy_from_slice(&p);
        }
        Some(p)
    }

    /// The dead-reckoned position's error variance per axis (m²), in flow
    /// mode.
    pub(super) fn position_variance(&self) -> Option<f64> {
        (self.source == PositionSource::Flow).then(|| self.dead.position_variance())
    }

    /// The estimate's position.
    pub(super) fn position(&self) -> [f64; 3] {
        [self.est[0], self.est[1], self.est[2]]
    }

    pub(super) fn start(&self) -> [f64; 3] {
        self.start
    }
}

/// An angle in (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let r = a.rem_euclid(TAU);
    if r > PI {
        r - TAU
    } else {
        r
    }
}

impl Stm32 {
    /// GET_SENSORS, with the extension's registers updated from the reply.
    pub(super) fn read_sensors(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<Sensors, DeviceError> {
        let reply = ctx
            .world
            .call(&Request::GetSensors, now)
            .map_err(world_err)?;
        let Reply::Sensors(mut s) = reply else {
            return Err(world_err(LinkError::Unexpected {
                request: "GET_SENSORS",
                reply: reply.command(),
            }));
        };
        self.motion.update(&mut s).map_err(invalid)?;
        Ok(s)
    }

    /// A write to the extension's registers.
    pub(super) fn write_ext(
        &mut self,
        offset: u32,
        value: u8,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        match offset {
            EXT_CTRL..EXT_STAT => {
                let i = (offset - EXT_CTRL) as usize;
                self.motion.ctrl[i] = value;
                if i == 3 {
                    let code = u32::from_le_bytes(self.motion.ctrl);
                    return self.ext_command(code, now, ctx);
                }
                Ok(())
            }
            CMD_VX..EST_ROLL => {
                self.motion.args[(offset - CMD_VX) as usize] = value;
                Ok(())
            }
            P2P_SELF..EXT_END => {
                self.motion.p2p[(offset - P2P_ENABLE) as usize] = value;
                Ok(())
            }
            // EXT_STAT, the estimate, ranges, flow, attitude and time are
            // read-only: a write is ignored, as a write to a read-only
            // register of the STM32.
            _ => Ok(()),
        }
    }

    fn ext_command(
        &mut self,
        code: u32,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        if code == 0 {
            return Ok(());
        }
        self.motion.stat.write(now, 0);
        match self.try_ext_command(code, now, ctx)? {
            Ok(()) => Ok(()),
            Err(why) => {
                let msg = format!("[STM32] extension command {code} refused: {why}\n");
                tracing::warn!(target: "cosim::stm32", "{}", msg.trim_end());
                (ctx.console)(&msg);
                self.motion.complete(now, EXT_ERROR);
                self.power.busy_reading(now);
                Ok(())
            }
        }
    }

    /// Runs an extension command; the inner error is a refusal (EXT_ERROR),
    /// the outer one a failure of the world link.
    fn try_ext_command(
        &mut self,
        code: u32,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<Result<(), String>, DeviceError> {
        if !self.initialised {
            return Ok(Err("before INIT_PID".into()));
        }
        if self.process != Process::Idle {
            return Ok(Err(format!("while {:?} is still running", self.process)));
        }
        let m = &self.motion;
        let finite = |o: u32, name: &str| {
            let v = m.arg(o);
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("{name} = {v} is not finite"))
            }
        };
        match code {
            EXT_SET_HEADING => match finite(CMD_YAW, "CMD_YAW") {
                Ok(yaw) => self.motion.heading = Some(wrap_angle(yaw)),
                Err(e) => return Ok(Err(e)),
            },
            EXT_SET_VELOCITY => {
                let sp = (|| {
                    let (vx, vy) = (finite(CMD_VX, "CMD_VX")?, finite(CMD_VY, "CMD_VY")?);
                    let height = finite(CMD_HEIGHT, "CMD_HEIGHT")?;
                    let yaw_rate = finite(CMD_YAW_RATE, "CMD_YAW_RATE")?;
                    if height < 0.0 {
                        return Err(format!("CMD_HEIGHT = {height} is below the ground"));
                    }
                    let (vx, vy) = clamp_speed(vx, vy, m.speed_limit);
                    Ok(Setpoint {
                        vx,
                        vy,
                        height,
                        yaw_rate,
                    })
                })();
                match sp {
                    Ok(sp) => self.motion.mode = Mode::Velocity(sp),
                    Err(e) => return Ok(Err(e)),
                }
            }
            EXT_SET_SPEED_LIMIT => match finite(CMD_SPEED_LIMIT, "CMD_SPEED_LIMIT") {
                Ok(v) if v > 0.0 => {
                    self.motion.speed_limit = v;
                    if let Mode::Velocity(sp) = &mut self.motion.mode {
                        (sp.vx, sp.vy) = clamp_speed(sp.vx, sp.vy, v);
                    }
                }
                Ok(v) => return Ok(Err(format!("CMD_SPEED_LIMIT = {v} is not positive"))),
                Err(e) => return Ok(Err(e)),
            },
            EXT_TAKEOFF => match finite(CMD_HEIGHT, "CMD_HEIGHT") {
                Ok(h) if h > 0.0 => {
                    self.flush_iteration(now, ctx)?;
                    let height = self.motion.start()[2] + h;
                    self.motion.mode = Mode::Velocity(Setpoint {
                        height,
                        ..Setpoint::default()
                    });
                    self.start_process(Process::TakingOff, now);
                    return Ok(Ok(()));
                }
                Ok(h) => return Ok(Err(format!("CMD_HEIGHT = {h} is not positive"))),
                Err(e) => return Ok(Err(e)),
            },
            EXT_LAND => {
                self.flush_iteration(now, ctx)?;
                self.motion.mode = Mode::Velocity(Setpoint::default());
                self.motion.landed_for = 0;
                self.start_process(Process::ExtLanding, now);
                return Ok(Ok(()));
            }
            EXT_CRTP => {
                if self.crtp.is_none() {
                    return Ok(Err("no CRTP link (sim-core --crtp udp:HOST:PORT)".into()));
                }
                self.flush_iteration(now, ctx)?;
                if let (Some(id), Some(crtp)) = (self.motion.p2p_self(), self.crtp.as_mut()) {
                    crtp.enable_radar(id);
                }
                self.start_process(Process::Crtp, now);
                return Ok(Ok(()));
            }
            EXT_POSITION_MODE => {
                self.motion.mode = Mode::Position;
                let p = self.motion.position();
                self.new_target(p);
            }
            other => return Ok(Err(format!("unknown command {other}"))),
        }
        self.motion.complete(now, code);
        self.power.busy_reading(now);
        Ok(Ok(()))
    }

    /// One iteration of the velocity mode (RUN_SINGLE_STEP_PID in velocity
    /// mode, take-off and landing): the set-point's body velocities and yaw
    /// rate, the height approached at the speed limit, the Bitcraze
    /// controller of Appendix C. `Reached` when a take-off or landing is
    /// done.
    pub(super) fn velocity_iteration(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(Outcome, MotorCommands), DeviceError> {
        let s = self.read_sensors(now, ctx)?;
        self.stats.pid_iterations += 1;
        let Mode::Velocity(sp) = self.motion.mode else {
            unreachable!("velocity iterations run in velocity mode only")
        };
        let (dt, actual) = self.measured(&s);
        let f = &mut self.flight;
        let step = self.motion.speed_limit * dt;
        f.height_desired += (sp.height - f.height_desired).clamp(-step, step);
        let mut desired = DesiredState {
            yaw_rate: sp.yaw_rate,
            vx: sp.vx,
            vy: sp.vy,
            altitude: f.height_desired,
            ..DesiredState::default()
        };
        let ramped = f.height_desired == sp.height;
        let commands = self.control(&s, &actual, &mut desired, dt, None)?;
        let near = (s.z - sp.height).abs() <= self.cfg.tolerance;
        let outcome = match self.process {
            Process::TakingOff if ramped && near => Outcome::Reached,
            Process::ExtLanding if ramped && near => {
                self.motion.landed_for += 1;
                if self.motion.landed_for >= LANDED_ITERATIONS {
                    Outcome::Reached
                } else {
                    Outcome::Flying
                }
            }
            Process::ExtLanding => {
                self.motion.landed_for = 0;
                Outcome::Flying
            }
            _ => Outcome::Flying,
        };
        Ok((outcome, commands))
    }
}

/// Iterations on the ground (height ramp at 0, within the tolerance) before
/// EXT_LAND stops the motors. cflib's `MotionCommander.land()` descends for
/// height / velocity and then sends the stop set-point at once; waiting
/// TARGET_CYCLES (100 iterations, 3.2 s at 32 ms) on the ground with the
/// attitude loop still driving the motors made the drone tilt against the
/// ground's friction and skid up to 2.4 m (seed004-radar, before this).
const LANDED_ITERATIONS: u32 = 3;

/// The horizontal speed clamped to `limit`, direction kept.
fn clamp_speed(vx: f64, vy: f64, limit: f64) -> (f64, f64) {
    let v = vx.hypot(vy);
    if v > limit {
        (vx * limit / v, vy * limit / v)
    } else {
        (vx, vy)
    }
}

#[cfg(test)]
mod tests;
