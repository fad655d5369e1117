//! The platform's one session with the world (docs/SWARM.md §4): whichever
//! device first needs the world (the STM32's INIT_PID, or a radio's INIT)
//! opens it with GET_INIT_DATA, once; the start-up alignment (the world's
//! 2000 ms warm-up, §4.2.1 of the thesis) is spent once; STOP closes it.
//!
//! It also knows who moves the drone's clock (§4.1):
//! - after INIT_PID the STM32, with the thesis's bookkeeping (DESIGN.md §3);
//! - when the world was claimed by a radio and INIT_PID never ran, the
//!   session's own **ticker**: at platform times p₀ + k·ts (p₀ = the end of
//!   the alignment, k ≥ 1) it sends `ADVANCE_TIME ts`, accounted as a device
//!   delay of exactly ts over [p₀ + (k−1)·ts, p₀ + k·ts]
//!   ([`TimeKeeper::clock_tick`]), so the drone's clock is t_d = warm-up + k·ts
//!   and corresponds to the platform time p_d = p₀ + k·ts exactly.
//!
//! The kernel runs the ticker as a device event ([`WorldSession::next_event`]).

use protocol::{ImageEncoding, Reply, Request};
use thiserror::Error;

use super::{LinkError, WorldLink};
use crate::sync::TimeKeeper;
use crate::units::{Millis, Picos};

/// What the world said at GET_INIT_DATA.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitData {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// The world's time when it answered (s): the end of its warm-up.
    pub time_s: f64,
    pub timestep: Millis,
}

/// The world's answer to STOP, and what GET_STATE said just before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopReport {
    /// The world's time when the propellers had stopped (s).
    pub time_s: f64,
    /// How long the propellers took to stop (ms).
    pub stop_time_ms: u64,
    /// Gates the drone passed (the world's extension, DESIGN.md §10).
    pub gates_passed: Option<u64>,
    /// Contacts begun in the world, from GET_STATE just before STOP (None
    /// if the world does not implement that extension).
    pub collisions: Option<u64>,
}

/// Who moves the drone's clock (docs/SWARM.md §4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockOwner {
    /// Nobody yet (the session is not open, or it is still aligning for a
    /// device that has not said).
    Nobody,
    /// The session's ticker; the next tick is due at this platform time.
    Ticker { next: Picos },
    /// The STM32 (INIT_PID was executed): its delays move the clock.
    Stm32,
}

/// Why the session could not do what a device asked.
#[derive(Debug, Error)]
pub enum SessionError {
    #[error(transparent)]
    World(#[from] LinkError),
    #[error("{0}")]
    Invalid(String),
}

/// The session (see the module documentation).
#[derive(Debug, Clone)]
pub struct WorldSession {
    drone: Option<String>,
    image_encoding: ImageEncoding,
    init: Option<InitData>,
    /// The world's clock at GET_INIT_DATA, whole ms (the warm-up).
    warmup: Millis,
    /// p₀: the platform time at which the start-up alignment ends.
    ready_at: Picos,
    clock: ClockOwner,
    stop: Option<StopReport>,
}

impl WorldSession {
    /// A session not yet opened; `drone` is the name claimed in
    /// GET_INIT_DATA (`--drone`), `None` for a world with one drone.
    pub fn new(drone: Option<String>, image_encoding: ImageEncoding) -> Self {
        WorldSession {
            drone,
            image_encoding,
            init: None,
            warmup: Millis(0),
            ready_at: Picos::ZERO,
            clock: ClockOwner::Nobody,
            stop: None,
        }
    }

    /// The drone this platform claims, if named.
    pub fn drone(&self) -> Option<&str> {
        self.drone.as_deref()
    }

    /// GET_INIT_DATA has been answered.
    pub fn is_open(&self) -> bool {
        self.init.is_some()
    }

    /// STOP has been answered (nothing more may be sent).
    pub fn is_stopped(&self) -> bool {
        self.stop.is_some()
    }

    /// Open and not stopped: requests may be sent.
    pub fn is_live(&self) -> bool {
        self.is_open() && !self.is_stopped()
    }

    pub fn init(&self) -> Option<&InitData> {
        self.init.as_ref()
    }

    pub fn stop_report(&self) -> Option<&StopReport> {
        self.stop.as_ref()
    }

    /// p₀, the end of the start-up alignment (0 before the session opens).
    pub fn ready_at(&self) -> Picos {
        self.ready_at
    }

    pub fn clock_owner(&self) -> ClockOwner {
        self.clock
    }

    /// Opens the session at `now` if nobody has (GET_INIT_DATA, then the
    /// start-up alignment: the world already ran its warm-up, so the
    /// platform spends the same time without advancing the world, §4.2.1).
    /// Returns the world's initial data.
    pub fn open(
        &mut self,
        now: Picos,
        world: &mut dyn WorldLink,
        time: &mut TimeKeeper,
    ) -> Result<InitData, SessionError> {
        if let Some(init) = self.init {
            return Ok(init);
        }
        let request = Request::GetInitData {
            image_encoding: Some(self.image_encoding),
            drone: self.drone.clone(),
        };
        let reply = world.call(&request, now)?;
        let Reply::InitData {
            x,
            y,
            z,
            time_s,
            timestep_ms,
            ..
        } = reply
        else {
            return Err(LinkError::Unexpected {
                request: "GET_INIT_DATA",
                reply: reply.command(),
            }
            .into());
        };
        // The range only: the sync mode's rule is the STM32's, at INIT_PID.
        if let Err(e) = protocol::TimestepMs::new(timestep_ms) {
            return Err(SessionError::Invalid(format!("the world reported {e}")));
        }
        if !(time_s.is_finite() && time_s >= 0.0) {
            return Err(SessionError::Invalid(format!(
                "the world reported a start time of {time_s} s"
            )));
        }
        let init = InitData {
            x,
            y,
            z,
            time_s,
            timestep: Millis(timestep_ms),
        };
        time.set_timestep(init.timestep);
        // The world ran its warm-up (2000 ms, Appendix E) before serving us:
        // the platform spends the same time so both clocks agree (§4.2.1).
        self.warmup = Millis((time_s * 1000.0).round() as u64);
        time.aligned(self.warmup, now, false);
        self.ready_at = now + self.warmup.to_picos();
        self.init = Some(init);
        tracing::info!(
            target: "cosim::world",
            drone = self.drone.as_deref().unwrap_or("-"),
            timestep_ms,
            "world session open"
        );
        Ok(init)
    }

    /// A radio needs the clock to move (docs/SWARM.md §4.1): unless the
    /// STM32 already owns it, the ticker starts, first tick at p₀ + ts.
    pub fn start_ticker(&mut self) {
        if let (ClockOwner::Nobody, Some(init)) = (self.clock, self.init) {
            self.clock = ClockOwner::Ticker {
                next: self.ready_at + init.timestep.to_picos(),
            };
        }
    }

    /// INIT_PID: from now on the STM32's delays move the clock; the ticker
    /// (if it ran) stops. Core time since its last tick is accounted by the
    /// STM32's next delay as any core time is (DESIGN.md §3).
    pub fn hand_clock_to_stm32(&mut self) {
        self.clock = ClockOwner::Stm32;
    }

    /// The next tick of the ticker, if it runs.
    pub fn next_event(&self) -> Option<Picos> {
        match self.clock {
            ClockOwner::Ticker { next } if !self.is_stopped() => Some(next),
            _ => None,
        }
    }

    /// Sends every tick due at `now`. Returns whether the clock moved.
    pub fn tick(
        &mut self,
        now: Picos,
        world: &mut dyn WorldLink,
        time: &mut TimeKeeper,
    ) -> Result<bool, SessionError> {
        let Some(init) = self.init else {
            return Ok(false);
        };
        let ts = init.timestep;
        let mut moved = false;
        while let Some(next) = self.next_event().filter(|t| *t <= now) {
            // The interval that just ended is the delay of this tick.
            time.clock_tick(ts, next - ts.to_picos());
            world.send(&Request::AdvanceTime { time: ts.0 }, next)?;
            self.clock = ClockOwner::Ticker {
                next: next + ts.to_picos(),
            };
            moved = true;
        }
        Ok(moved)
    }

    /// The drone's clock t_d (world time, ps): the warm-up plus every advance
    /// the platform has sent (docs/SWARM.md §4.2).
    pub fn world_clock(&self, time: &TimeKeeper) -> Picos {
        (self.warmup + time.world_sent()).to_picos()
    }

    /// The world's clock in seconds (for the PID's `past_time`).
    pub fn world_clock_s(&self, time: &TimeKeeper) -> f64 {
        (self.warmup + time.world_sent()).0 as f64 / 1000.0
    }

    /// Ends the session at platform time `at`: GET_STATE (for the collision
    /// count; a world that answers ERROR to this extension is fine), then
    /// STOP. The motors' stop time is an aligned delay both sides spend
    /// (§4.2.1), so the world estimate stays exact; the platform's time at
    /// the end of it is returned.
    pub fn stop(
        &mut self,
        at: Picos,
        world: &mut dyn WorldLink,
        time: &mut TimeKeeper,
    ) -> Result<Picos, SessionError> {
        if !self.is_live() {
            return Err(SessionError::Invalid(if self.is_stopped() {
                "STOP was already sent".into()
            } else {
                "STOP before the world session was opened".into()
            }));
        }
        let collisions = match world.call(&Request::GetState, at) {
            Ok(Reply::State(state)) => Some(state.collisions),
            Ok(_) | Err(LinkError::Remote { .. }) => None,
            Err(e) => return Err(e.into()),
        };
        let reply = world.call(&Request::Stop, at)?;
        let Reply::Stop {
            time_s,
            stop_time_ms,
            gates_passed,
        } = reply
        else {
            return Err(LinkError::Unexpected {
                request: "STOP",
                reply: reply.command(),
            }
            .into());
        };
        self.stop = Some(StopReport {
            time_s,
            stop_time_ms,
            gates_passed,
            collisions,
        });
        time.aligned(Millis(stop_time_ms), at, true);
        tracing::info!(target: "cosim::world", time_s, stop_time_ms, "world stopped");
        Ok(at + Millis(stop_time_ms).to_picos())
    }
}
