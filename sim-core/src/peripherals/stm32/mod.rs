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
//! | 1 | INIT_PID | GET_INIT_DATA, then the start-up alignment (the world's warm-up, 2000 ms) |
//! | 2 | GET_STABLE | PID iterations of one timestep each until the drone holds 1 m |
//! | 3 | SET_TARGET | 5 ms |
//! | 4 | RUN_SINGLE_STEP_PID | one iteration: 7 ms (PID + motor path); status 6 if the target is reached, 9 if the battery is low |
//! | 5 | RUN_PID | iterations of one timestep each until the target is reached |
//! | 7 | GO_DOWN | landing in two stages, then STOP and the motors' stop time |
//! | 8 | PRINT_SIMUL_TIME | prints the time bookkeeping, at once |
//! | 10 + v | ITER_ADVANCE | v ms (inference time), status 10 |
//! | 251 | SKIP_TARGET | our extension: a target skipped for low battery is counted, at once |

pub mod pid;

use protocol::{ImageEncoding, Reply, Request};

use self::pid::{ActualState, DesiredState, MotorCommands, PidController, PidGains};
use super::{DeviceCtx, DeviceError, DevicePower, LinkError, TimedReg};
use crate::units::{Millis, Picos};

/// Register offsets within the STM32 (Table 4.2).
pub const CTRL: u32 = 0;
pub const STATUS: u32 = 1;
pub const TARGET_X: u32 = 2;
pub const TARGET_Y: u32 = 10;
pub const TARGET_Z: u32 = 18;
pub const REGISTER_MEMORY: u32 = 26;

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
    /// Image encoding asked for in GET_INIT_DATA.
    pub image_encoding: ImageEncoding,
    /// SET_TARGET's delay (§4.2.1: 5 ms).
    pub set_target_delay: Millis,
    /// The PID and motor path of one iteration (§4.2.4: 7 ms).
    pub pid_path_delay: Millis,
    /// Height GET_STABLE lifts the drone to (m).
    pub stable_height: f64,
    /// First landing stage: height above ground (m) before the final 0 m.
    pub landing_height: f64,
}

impl Default for Stm32Config {
    fn default() -> Self {
        Stm32Config {
            gains: PidGains::default(),
            tolerance: 0.1,
            target_cycles: 100,
            unlock_cycles: 5000,
            image_encoding: ImageEncoding::Array,
            set_target_delay: Millis(5),
            pid_path_delay: Millis(7),
            stable_height: 1.0,
            landing_height: 0.2,
        }
    }
}

/// Counters reported in `summary.json`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stm32Stats {
    pub targets_total: u32,
    pub targets_reached: u32,
    pub targets_bypassed: u32,
    pub targets_skipped_low_battery: u32,
    pub pid_iterations: u64,
    /// The world's reply to STOP: its time (s) and the motors' stop time (ms).
    pub stop: Option<(f64, u64)>,
    /// Contacts begun in the world, from GET_STATE just before STOP (None
    /// if the world does not implement that extension).
    pub collisions: Option<u64>,
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
}

/// The thesis's `PIDController` state (Appendix C).
#[derive(Debug, Clone)]
struct Flight {
    pid: PidController,
    target: [f64; 3],
    target_counter: u32,
    num_iteration: u32,
    /// The current target is already counted in the statistics (a firmware
    /// that keeps flying to a reached target, like the hover test, sees
    /// TARGET_REACHED again at every iteration).
    counted: bool,
    height_desired: f64,
    past_time: f64,
    past_x: f64,
    past_y: f64,
}

/// How an iteration ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Flying,
    Reached,
    Bypassed,
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
    pub power: DevicePower,
    pub stats: Stm32Stats,
}

impl Stm32 {
    pub fn new(cfg: Stm32Config, power: DevicePower) -> Self {
        let pid = PidController::new(cfg.gains);
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
            },
            timestep: Millis(0),
            initialised: false,
            process: Process::Idle,
            next_iteration: None,
            power,
            stats: Stm32Stats::default(),
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
                self.new_target(target);
                self.stats.targets_total += 1;
                let d = self.cfg.set_target_delay;
                self.advance_world(d, now, ctx)?;
                self.complete(now + d.to_picos(), SET_TARGET);
                tracing::info!(target: "cosim::stm32", ?target, "new target");
                Ok(())
            }
            RUN_SINGLE_STEP_PID => {
                let (outcome, commands) = self.pid_iteration(now, ctx, true)?;
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

    fn init_pid(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        let request = Request::GetInitData {
            image_encoding: Some(self.cfg.image_encoding),
        };
        let reply = ctx.world.call(&request, now).map_err(world_err)?;
        let Reply::InitData {
            x,
            y,
            z,
            time_s,
            timestep_ms,
            ..
        } = reply
        else {
            return Err(world_err(LinkError::Unexpected {
                request: "GET_INIT_DATA",
                reply: reply.command(),
            }));
        };
        if timestep_ms == 0 {
            return Err(invalid("the world reported a basicTimeStep of 0 ms".into()));
        }
        if ctx.time.mode() == crate::sync::SyncMode::Thesis && timestep_ms < 3 {
            return Err(invalid(format!(
                "basicTimeStep {timestep_ms} ms is too small for the thesis's iteration scheme \
                 (one timestep minus 1 ms rounds to no step); use sync = \"bounded\""
            )));
        }
        self.timestep = Millis(timestep_ms);
        ctx.time.set_timestep(self.timestep);
        let f = &mut self.flight;
        f.pid.reset();
        f.past_time = time_s;
        f.past_x = x;
        f.past_y = y;
        f.height_desired = z;
        f.target = [x, y, z];
        self.initialised = true;
        // The world ran its warm-up (2000 ms, Appendix E) before serving us:
        // the platform spends the same time so both clocks agree (§4.2.1).
        let align = Millis((time_s * 1000.0).round().max(0.0) as u64);
        ctx.time.aligned(align, now, false);
        let done = now + align.to_picos();
        self.power.busy_reading(done);
        self.complete(done, INIT_PID);
        tracing::info!(target: "cosim::stm32", timestep_ms, x, y, z, "PID initialised");
        Ok(())
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

    /// Sends a pending iteration delay (an ITER_ADVANCE not followed by a
    /// PID step) to the world before another kind of operation starts.
    fn flush_iteration(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        let pending = ctx.time.take_iteration();
        if pending.0 > 0 {
            let steps = ctx.time.iteration_steps(pending);
            self.send_advance(steps, now, ctx)?;
        }
        Ok(())
    }

    fn advance_world(
        &mut self,
        d: Millis,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        let steps = ctx.time.delay(d, now);
        self.send_advance(steps, now, ctx)
    }

    fn send_advance(
        &mut self,
        steps: u64,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        if steps > 0 {
            let time = steps * self.timestep.0;
            ctx.world
                .send(&Request::AdvanceTime { time }, now)
                .map_err(world_err)?;
        }
        Ok(())
    }

    fn drive(
        commands: MotorCommands,
        now: Picos,
        iter: Millis,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        super::motors::drive_from_ctx(ctx, commands, iter, now).map_err(world_err)
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
        let (outcome, commands) = self.pid_iteration(now, ctx, integrate_height)?;
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
                self.next_iteration = None;
                self.process = Process::Idle;
                self.stop_world(end, ctx)?;
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

    /// End of the landing: STOP, the motors' stop time, then GO_DOWN done.
    fn stop_world(&mut self, at: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        // GET_STATE is our extension: a world that answers ERROR to it
        // (e.g. one written for the thesis's protocol only) is fine.
        match ctx.world.call(&Request::GetState, at) {
            Ok(Reply::State(state)) => self.stats.collisions = Some(state.collisions),
            Ok(_) | Err(LinkError::Remote { .. }) => {}
            Err(e) => return Err(world_err(e)),
        }
        let reply = ctx.world.call(&Request::Stop, at).map_err(world_err)?;
        let Reply::Stop {
            time_s,
            stop_time_ms,
        } = reply
        else {
            return Err(world_err(LinkError::Unexpected {
                request: "STOP",
                reply: reply.command(),
            }));
        };
        ctx.motors.stopped();
        self.stats.stop = Some((time_s, stop_time_ms));
        ctx.time.aligned(Millis(stop_time_ms), at, true);
        self.complete(at + Millis(stop_time_ms).to_picos(), GO_DOWN);
        tracing::info!(target: "cosim::stm32", time_s, stop_time_ms, "world stopped");
        Ok(())
    }

    fn print_simul_time(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) {
        let r = ctx.time.report(now);
        let mut text = format!(
            "\n[STM32] Platform time: {:.3} ms\n[STM32] Sensors offset: {:.3} ms, core overshoot (sim_off_accum): {:.6} ms\n[STM32] Estimated world time: {:.3} ms\n",
            r.platform_time.0 as f64 / Picos::PER_MS as f64,
            r.sensors_offset_ms,
            r.sim_off_accum_ms,
            r.world_time_estimate_ms
        );
        if let Some((time_s, _)) = self.stats.stop {
            let real = time_s * 1000.0;
            let err = (r.world_time_estimate_ms - real) / real * 100.0;
            text.push_str(&format!(
                "[STM32] Real world time (STOP): {real:.3} ms, error: {err:.4} %\n"
            ));
        }
        (ctx.console)(&text);
    }

    /// One PID iteration (Appendix C): sensors, body velocities, the
    /// straight-path coefficients (Listing 4.2), tolerance and target
    /// counting (Listing 4.3), the Bitcraze controller, the motors.
    fn pid_iteration(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
        integrate_height: bool,
    ) -> Result<(Outcome, MotorCommands), DeviceError> {
        let reply = ctx
            .world
            .call(&Request::GetSensors, now)
            .map_err(world_err)?;
        let Reply::Sensors(s) = reply else {
            return Err(world_err(LinkError::Unexpected {
                request: "GET_SENSORS",
                reply: reply.command(),
            }));
        };
        self.stats.pid_iterations += 1;
        let ts_s = self.timestep.0 as f64 / 1000.0;
        let cfg = &self.cfg;
        let f = &mut self.flight;
        let mut dt = s.time_s - f.past_time;
        // The first iteration after INIT_PID sees the same world time as
        // GET_INIT_DATA (the platform's alignment does not move the world);
        // the C code would divide by zero there. Use one timestep instead.
        if dt <= 0.0 {
            dt = ts_s;
        }
        let (vx, vy) = pid::body_velocity(s.x - f.past_x, s.y - f.past_y, dt, s.yaw);
        let actual = ActualState {
            roll: s.roll,
            pitch: s.pitch,
            yaw_rate: s.yaw_rate,
            altitude: s.z,
            vx,
            vy,
        };

        // Listing 4.2: the straight path.
        let x_diff = s.x - f.target[0];
        let y_diff = s.y - f.target[1];
        let z_diff = s.z - f.target[2];
        let (x_abs, y_abs, z_abs) = (x_diff.abs(), y_diff.abs(), z_diff.abs());
        let max_abs = if x_abs > y_abs {
            if x_abs > z_abs {
                x_abs
            } else {
                z_abs
            }
        } else if y_abs > z_abs {
            y_abs
        } else {
            z_abs
        };
        // 0/0 only when the drone is exactly on the target, where no
        // coefficient is used (every diff is within tolerance).
        let coeff = |a: f64| if max_abs > 0.0 { a / max_abs } else { 0.0 };
        let (x_coeff, y_coeff, z_coeff) = (coeff(x_abs), coeff(y_abs), coeff(z_abs));

        // Listing 4.3: tolerance and target counting.
        let tol = cfg.tolerance;
        let mut sideways_desired = 0.0;
        let mut forward_desired = 0.0;
        let mut height_diff_desired = 0.0;
        let mut outside = 0;
        if x_diff > tol {
            sideways_desired = x_coeff * 0.5;
            outside += 1;
        }
        if x_diff < -tol {
            sideways_desired = -x_coeff * 0.5;
            outside += 1;
        }
        if y_diff > tol {
            forward_desired = -y_coeff * 0.5;
            outside += 1;
        }
        if y_diff < -tol {
            forward_desired = y_coeff * 0.5;
            outside += 1;
        }
        if z_diff > tol {
            height_diff_desired = -z_coeff * 0.2;
            outside += 1;
        }
        if z_diff < -tol {
            height_diff_desired = z_coeff * 0.2;
            outside += 1;
        }
        let mut outcome = Outcome::Flying;
        if outside == 0 {
            f.target_counter += 1;
            if f.target_counter >= cfg.target_cycles {
                outcome = Outcome::Reached;
                f.num_iteration = 0;
            }
        }
        f.num_iteration += 1;
        let unlock = (u64::from(cfg.unlock_cycles) * 32 / self.timestep.0.max(1)) as u32;
        if f.num_iteration >= unlock {
            if outcome == Outcome::Flying {
                outcome = Outcome::Bypassed;
            }
            f.num_iteration = 0;
        }

        if integrate_height {
            f.height_desired += height_diff_desired * dt;
        }
        let mut desired = DesiredState {
            yaw_rate: 0.0,
            vy: sideways_desired,
            vx: forward_desired,
            altitude: f.height_desired,
            ..DesiredState::default()
        };
        let commands = f.pid.step(&actual, &mut desired, dt);
        if commands.as_array().iter().any(|m| !m.is_finite()) {
            return Err(invalid(format!(
                "the controller produced non-finite motor commands {commands:?} from {s:?}"
            )));
        }
        f.past_time = s.time_s;
        f.past_x = s.x;
        f.past_y = s.y;

        // Targets set by the firmware are counted (GET_STABLE and landing are
        // the STM32's own).
        let already = self.flight.counted;
        if outcome != Outcome::Flying {
            self.flight.counted = true;
        }
        let counts = matches!(self.process, Process::Idle | Process::Continuous) && !already;
        match outcome {
            Outcome::Reached if counts => self.stats.targets_reached += 1,
            Outcome::Bypassed => {
                if counts {
                    self.stats.targets_bypassed += 1;
                }
                let msg = format!(
                    "Warning: target position {:?} could not be reached! Bypassing to the next one...\n",
                    self.flight.target
                );
                tracing::warn!(target: "cosim::stm32", "{}", msg.trim_end());
                (ctx.console)(&msg);
            }
            _ => {}
        }
        Ok((outcome, commands))
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
