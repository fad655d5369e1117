//! The STM32 of the Crazyflie as the thesis models it (§4.2.1, Tables 4.2
//! and 4.3, Appendix C): a control register, a status register and three
//! little-endian `f64` target registers; it runs the flight controller
//! ([`pid`]) on the world's sensors and drives the [`Motors`](super::Motors).
//!
//! Every operation shows its own code in the status register at the
//! simulated time it completes (DESIGN.md §4):
//!
//! | code | command | takes |
//! |---|---|---|
//! | 1 | INIT_PID | the world session (GET_INIT_DATA and the start-up alignment, the world's 2000 ms warm-up, unless a radio opened it already); the drone's clock is the STM32's from then on |
//! | 2 | GET_STABLE | PID iterations of one timestep each until the drone holds 1 m |
//! | 3 | SET_TARGET | 5 ms |
//! | 4 | RUN_SINGLE_STEP_PID | one iteration: 7 ms (PID + motor path); status 6 if the target is reached, 9 if the battery is low |
//! | 5 | RUN_PID | iterations of one timestep each until the target is reached |
//! | 7 | GO_DOWN | landing in two stages, then STOP and the motors' stop time |
//! | 8 | PRINT_SIMUL_TIME | prints the time bookkeeping, at once |
//! | 10 + v | ITER_ADVANCE | v ms (inference time), status 10 |
//! | 251 | SKIP_TARGET | our extension: a target skipped for low battery is counted, at once |
//!
//! The extension registers (state estimate, ranges, flow, MotionCommander-like
//! commands, a heading target) and their commands are in [`motion`].

pub mod cascade;
mod clock;
pub mod crtp;
pub mod estimator;
mod flight;
pub mod motion;
pub mod pid;

use self::estimator::FlowFilterParams;
use self::flight::{Flight, Outcome};
pub use self::motion::PositionSource;
use self::motion::{Mode, Motion};
use self::pid::{PidController, PidGains};
use super::world_session::SessionError;
use super::{DeviceCtx, DeviceError, DevicePower, LinkError, TimedReg};
use crate::units::{Millis, Picos};

/// Register offsets within the STM32 (Table 4.2).
pub const CTRL: u32 = 0;
pub const STATUS: u32 = 1;
pub const TARGET_X: u32 = 2;
pub const TARGET_Y: u32 = 10;
pub const TARGET_Z: u32 = 18;
/// The race's registers end at 26; the extension ([`motion`]) starts at 30
/// and ends the register file.
pub const REGISTER_MEMORY: u32 = motion::EXT_END;

/// Whether `offset` is one of the STM32's registers (bytes 26..30 fault).
pub fn is_register(offset: u32) -> bool {
    offset < REGISTER_MEMORY && !motion::GAP.contains(&offset)
}

/// Commands and status codes (Table 4.3).
pub const INIT_PID: u8 = 1;
pub const GET_STABLE: u8 = 2;
pub const SET_TARGET: u8 = 3;
pub const RUN_SINGLE_STEP_PID: u8 = 4;
pub const RUN_PID: u8 = 5;
pub const TARGET_REACHED: u8 = 6;
pub const GO_DOWN: u8 = 7;
pub const PRINT_SIMUL_TIME: u8 = 8;
pub const BATTERY_LOW: u8 = 9;
pub const ITER_ADVANCE: u8 = 10;
/// Our extension (not in Table 4.3), see the module docs.
pub const SKIP_TARGET: u8 = 251;

/// The STM32's settings (`simul_configs.hpp` and §4.2).
#[derive(Debug, Clone, PartialEq)]
pub struct Stm32Config {
    pub gains: PidGains,
    /// Distance (m) on every axis within which a target counts as reached.
    pub tolerance: f64,
    /// Iterations within tolerance before a target is reached.
    pub target_cycles: u32,
    /// Iterations (at 32 ms, scaled by 32/ts) after which a target is
    /// given up and the next one taken ("bypassed").
    pub unlock_cycles: u32,
    /// SET_TARGET's delay (§4.2.1: 5 ms).
    pub set_target_delay: Millis,
    /// The PID and motor path of one iteration (§4.2.4: 7 ms).
    pub pid_path_delay: Millis,
    /// Height GET_STABLE lifts the drone to (m).
    pub stable_height: f64,
    /// First landing stage: height above ground (m) before the final 0 m.
    pub landing_height: f64,
    /// Where the estimate's x, y come from (run key `stm32.position_source`).
    pub position_source: PositionSource,
    /// A range reading (mm) at or beyond this is "nothing within range"
    /// (run key `stm32.range_max_m`; the Webots DistanceSensor's lookup table
    /// saturates at 2000 mm, DESIGN.md §5).
    pub range_max_mm: f64,
    /// The flow-mode estimator's noise settings (run key
    /// `stm32.flow_std_m_s`; [`estimator`]).
    pub flow_filter: FlowFilterParams,
    /// Which controller flies a CRTP client's set-points (run key
    /// `stabilizer.controller`).
    pub controller: Controller,
}

/// The controller a CRTP client's set-points are flown with (run key
/// `stabilizer.controller`, DESIGN.md §20).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Controller {
    /// The thesis's: the Bitcraze Webots controller of [`pid`], with
    /// velocity and position loops on top (the race's, and the default).
    #[default]
    Thesis,
    /// The Crazyflie firmware's cascaded PID ([`cascade`]): position →
    /// velocity at 100 Hz, attitude → rate every step, PWM to the motors.
    Pid,
}

impl std::str::FromStr for Controller {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "thesis" => Ok(Controller::Thesis),
            "pid" => Ok(Controller::Pid),
            _ => Err("expected thesis | pid".into()),
        }
    }
}

impl std::fmt::Display for Controller {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Controller::Thesis => "thesis",
            Controller::Pid => "pid",
        })
    }
}

impl Default for Stm32Config {
    fn default() -> Self {
        Stm32Config {
            gains: PidGains::default(),
            tolerance: 0.1,
            target_cycles: 100,
            unlock_cycles: 5000,
            set_target_delay: Millis(5),
            pid_path_delay: Millis(7),
            stable_height: 1.0,
            landing_height: 0.2,
            position_source: PositionSource::Gps,
            range_max_mm: 2000.0,
            flow_filter: FlowFilterParams::default(),
            controller: Controller::Thesis,
        }
    }
}

/// Counters reported in `summary.json`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stm32Stats {
    pub targets_total: u32,
    pub targets_reached: u32,
    pub targets_bypassed: u32,
    /// Targets the firmware replaced by a new SET_TARGET before they were
    /// reached or bypassed (a vision firmware moving its target to the gate
    /// it sees, docs/VISION.md): total = reached + bypassed + replaced +
    /// skipped, plus the last target if the run ended before it.
    pub targets_replaced: u32,
    pub targets_skipped_low_battery: u32,
    pub pid_iterations: u64,
}

/// What the STM32 does on its own between core accesses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Process {
    Idle,
    /// GET_STABLE: hold the start point at the stable height.
    Stabilising,
    /// RUN_PID: fly to the target without the core.
    Continuous,
    /// GO_DOWN: first the landing height, then the ground.
    Landing {
        stage: u8,
    },
    /// EXT_TAKEOFF: climb to the take-off height.
    TakingOff,
    /// EXT_LAND: descend to the ground, then STOP.
    ExtLanding,
    /// EXT_CRTP: serve the CRTP link until it closes, then STOP ([`crtp`]).
    Crtp,
}

pub struct Stm32 {
    cfg: Stm32Config,
    control: u8,
    status: TimedReg,
    target_regs: [u8; 24],
    flight: Flight,
    timestep: Millis,
    initialised: bool,
    process: Process,
    next_iteration: Option<Picos>,
    motion: Motion,
    pub power: DevicePower,
    pub stats: Stm32Stats,
    /// The CRTP link, when the run has one (`--crtp`).
    crtp: Option<Box<crtp::CrtpServer>>,
}

impl Stm32 {
    /// The flow estimate's drift from the GPS (flow mode, once it has read
    /// the sensors; `None` otherwise).
    pub fn flow_drift(&self) -> Option<estimator::Drift> {
        self.motion.drift
    }

    pub fn new(cfg: Stm32Config, power: DevicePower) -> Self {
        let pid = PidController::new(cfg.gains);
        let motion = Motion::new(cfg.position_source, cfg.range_max_mm, cfg.flow_filter);
        Stm32 {
            cfg,
            control: 0,
            status: TimedReg::default(),
            target_regs: [0; 24],
            flight: Flight {
                pid,
                target: [0.0; 3],
                target_counter: 0,
                num_iteration: 0,
                counted: false,
                height_desired: 0.0,
                past_time: 0.0,
                past_x: 0.0,
                past_y: 0.0,
                cascade: cascade::Cascade::new(),
            },
            timestep: Millis(0),
            initialised: false,
            process: Process::Idle,
            next_iteration: None,
            motion,
            power,
            stats: Stm32Stats::default(),
            crtp: None,
        }
    }

    pub fn config(&self) -> &Stm32Config {
        &self.cfg
    }

    /// The current target (x, y, z), m.
    pub fn target(&self) -> [f64; 3] {
        self.flight.target
    }

    pub fn read(&self, offset: u32, now: Picos) -> u8 {
        match offset {
            CTRL => self.control,
            STATUS => self.status.get(now),
            o if o >= motion::EXT_CTRL => self.motion.read(o, now),
            _ => self.target_regs[(offset - TARGET_X) as usize],
        }
    }

    pub fn stable_until(&self, offset: u32, now: Picos) -> Picos {
        match offset {
            // A running process may set the status at its next iteration.
            STATUS => self
                .status
                .stable_until(now)
                .min(self.next_iteration.unwrap_or(Picos::MAX)),
            o if o >= motion::EXT_CTRL => self.motion.stable_until(o, now, self.next_iteration),
            _ => Picos::MAX,
        }
    }

    /// The next time the STM32 acts on its own.
    pub fn next_event(&self) -> Option<Picos> {
        self.next_iteration
    }

    pub fn write(
        &mut self,
        offset: u32,
        value: u8,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        self.power.written(now);
        match offset {
            CTRL => {
                self.control = value;
                self.command(value, now, ctx)
            }
            STATUS => {
                self.status.write(now, value);
                Ok(())
            }
            o if o >= motion::EXT_CTRL => self.write_ext(o, value, now, ctx),
            _ => {
                self.target_regs[(offset - TARGET_X) as usize] = value;
                Ok(())
            }
        }
    }

    fn command(
        &mut self,
        value: u8,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        if value != 0 && value != INIT_PID && value != PRINT_SIMUL_TIME && !self.initialised {
            return Err(invalid(format!(
                "command {value} before INIT_PID: the PID needs the world's timestep first"
            )));
        }
        if value != 0 && self.process != Process::Idle {
            return Err(invalid(format!(
                "command {value} while {:?} is still running",
                self.process
            )));
        }
        match value {
            0 => Ok(()),
            INIT_PID => self.init_pid(now, ctx),
            GET_STABLE => {
                self.flush_iteration(now, ctx)?;
                let (x, y) = (self.flight.past_x, self.flight.past_y);
                self.new_target([x, y, self.cfg.stable_height]);
                self.flight.height_desired = self.cfg.stable_height;
                self.start_process(Process::Stabilising, now);
                Ok(())
            }
            SET_TARGET => {
                self.flush_iteration(now, ctx)?;
                let reg =
                    |i: usize| f64::from_le_bytes(self.target_regs[i..i + 8].try_into().unwrap());
                let target = [reg(0), reg(8), reg(16)];
                if target.iter().any(|v| !v.is_finite()) {
                    return Err(invalid(format!(
                        "SET_TARGET with a non-finite target {target:?}"
                    )));
                }
                let s = &mut self.stats;
                let done = s.targets_reached
                    + s.targets_bypassed
                    + s.targets_replaced
                    + s.targets_skipped_low_battery;
                if s.targets_total > done {
                    s.targets_replaced += 1;
                }
                self.new_target(target);
                self.stats.targets_total += 1;
                let d = self.cfg.set_target_delay;
                self.advance_world(d, now, ctx)?;
                self.complete(now + d.to_picos(), SET_TARGET);
                tracing::info!(target: "cosim::stm32", ?target, "new target");
                Ok(())
            }
            RUN_SINGLE_STEP_PID => {
                let (outcome, commands) = match self.motion.mode {
                    Mode::Position => self.pid_iteration(now, ctx, true)?,
                    Mode::Velocity(_) => self.velocity_iteration(now, ctx)?,
                };
                ctx.time.add_to_iteration(self.cfg.pid_path_delay, now);
                let iter = ctx.time.take_iteration();
                let done = now + self.cfg.pid_path_delay.to_picos();
                Self::drive(commands, now, iter, ctx)?;
                let code = if ctx.battery_low {
                    BATTERY_LOW
                } else if outcome != Outcome::Flying {
                    TARGET_REACHED
                } else {
                    RUN_SINGLE_STEP_PID
                };
                self.complete(done, code);
                Ok(())
            }
            RUN_PID => {
                if self.motion.mode != Mode::Position {
                    return Err(invalid(
                        "RUN_PID in velocity mode (it runs until a position target is reached): \
                         use RUN_SINGLE_STEP_PID, or EXT_POSITION_MODE first"
                            .into(),
                    ));
                }
                self.flush_iteration(now, ctx)?;
                self.start_process(Process::Continuous, now);
                Ok(())
            }
            GO_DOWN => {
                self.flush_iteration(now, ctx)?;
                let (x, y) = (self.flight.past_x, self.flight.past_y);
                self.new_target([x, y, self.cfg.landing_height]);
                self.start_process(Process::Landing { stage: 1 }, now);
                Ok(())
            }
            PRINT_SIMUL_TIME => {
                self.flush_iteration(now, ctx)?;
                self.print_simul_time(now, ctx);
                self.complete(now, PRINT_SIMUL_TIME);
                Ok(())
            }
            SKIP_TARGET => {
                self.stats.targets_total += 1;
                self.stats.targets_skipped_low_battery += 1;
                Ok(())
            }
            v if v > ITER_ADVANCE && v < SKIP_TARGET => {
                let d = Millis(u64::from(v - ITER_ADVANCE));
                ctx.time.add_to_iteration(d, now);
                self.complete(now + d.to_picos(), ITER_ADVANCE);
                Ok(())
            }
            ITER_ADVANCE => {
                self.complete(now, ITER_ADVANCE);
                Ok(())
            }
            other => Err(DeviceError::UnknownCommand {
                device: "stm32",
                value: other,
            }),
        }
    }

    fn new_target(&mut self, target: [f64; 3]) {
        let f = &mut self.flight;
        f.target = target;
        f.target_counter = 0;
        f.num_iteration = 0;
        f.counted = false;
    }

    fn start_process(&mut self, process: Process, now: Picos) {
        self.process = process;
        self.next_iteration = Some(now);
    }

    fn complete(&mut self, at: Picos, code: u8) {
        self.status.set_at(at, code);
        self.power.busy_reading(at);
    }

    /// The kernel calls this when [`Stm32::next_event`] is due.
    pub fn handle_event(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        match self.next_iteration {
            Some(t) if t <= now => {}
            _ => return Ok(()),
        }
        // Iterations of the STM32's own loops last one timestep
        // (§4.2.4: iter_delay = timestep at the beginning and the end).
        let ts = self.timestep;
        let integrate_height = self.process != Process::Stabilising;
        let (outcome, commands) = match self.process {
            Process::TakingOff | Process::ExtLanding => self.velocity_iteration(now, ctx)?,
            Process::Crtp => self.crtp_iteration(now, ctx)?,
            _ => self.pid_iteration(now, ctx, integrate_height)?,
        };
        ctx.time.add_to_iteration(ts, now);
        let iter = ctx.time.take_iteration();
        Self::drive(commands, now, iter, ctx)?;
        let end = now + ts.to_picos();
        self.power.busy_reading(end);
        self.next_iteration = Some(end);
        if outcome == Outcome::Flying {
            if self.process == Process::Continuous && ctx.battery_low {
                self.finish(end, BATTERY_LOW);
            }
            return Ok(());
        }
        match self.process {
            Process::Stabilising => self.finish(end, GET_STABLE),
            Process::Continuous => self.finish(end, RUN_PID),
            Process::Landing { stage: 1 } => {
                let (x, y) = (self.flight.target[0], self.flight.target[1]);
                self.new_target([x, y, 0.0]);
                self.process = Process::Landing { stage: 2 };
            }
            Process::Landing { .. } => {
                let done = self.stop_world(end, ctx)?;
                self.finish(done, GO_DOWN);
            }
            Process::TakingOff => self.finish_ext(end, motion::EXT_TAKEOFF),
            Process::ExtLanding => {
                let done = self.stop_world(end, ctx)?;
                self.finish_ext(done, motion::EXT_LAND);
            }
            Process::Crtp => {
                let done = self.stop_world(end, ctx)?;
                self.finish_ext(done, motion::EXT_CRTP);
            }
            Process::Idle => unreachable!("an idle STM32 has no iteration scheduled"),
        }
        Ok(())
    }

    fn finish(&mut self, at: Picos, code: u8) {
        self.process = Process::Idle;
        self.next_iteration = None;
        self.complete(at, code);
    }

    fn finish_ext(&mut self, at: Picos, code: u32) {
        self.process = Process::Idle;
        self.next_iteration = None;
        self.power.busy_reading(at);
        self.motion.complete(at, code);
    }
}

fn session_err(e: SessionError) -> DeviceError {
    match e {
        SessionError::World(error) => world_err(error),
        SessionError::Invalid(message) => invalid(message),
    }
}

fn world_err(source: LinkError) -> DeviceError {
    DeviceError::World {
        device: "stm32",
        error: source,
    }
}

fn invalid(message: String) -> DeviceError {
    DeviceError::Invalid {
        device: "stm32",
        message,
    }
}
