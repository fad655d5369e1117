//! Time and offset bookkeeping between the platform and the world (thesis
//! §4.2.4 "Time accuracy" and "Adapting the simulation to the use-case
//! scenario", Listings 4.4 and 4.5; DESIGN.md §3).
//!
//! The platform counts integer picoseconds; the world advances only in whole
//! basicTimeSteps `ts`. Every device delay `d` (ms) is rounded to the nearest
//! multiple of `ts` with the thesis's rule ([`split_delay`]): the world is
//! advanced `q·ts` and the remainder `r` is added to `sensors_offset`. Core
//! time that passes outside device delays (the overshoot of the thesis's
//! `request_delay`, Listing 4.5) is added to `sim_off_accum`. At the end,
//!
//! ```text
//! world_estimate = platform_time − sensors_offset − sim_off_accum
//! ```
//!
//! which here is exact (integer arithmetic), so the estimate error is 0.
//!
//! In [`SyncMode::Bounded`] the remainder and the core time are carried into
//! the next advance instead, so platform and world never differ by more than
//! `ts/2` at a synchronisation point.

use crate::units::{Millis, Picos};

pub mod time_map;

/// How remainders are handled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SyncMode {
    /// The thesis's bookkeeping: every delay rounded on its own, remainders
    /// accumulated in `sensors_offset`.
    #[default]
    Thesis,
    /// Remainders (and core time) carried into the next advance.
    Bounded,
}

impl std::str::FromStr for SyncMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "thesis" => Ok(SyncMode::Thesis),
            "bounded" => Ok(SyncMode::Bounded),
            other => Err(format!(
                "unknown sync mode {other:?} (expected thesis or bounded)"
            )),
        }
    }
}

/// Every rule of the world's basicTimeStep under `mode` (DESIGN.md §19):
/// cosim checks a scenario with it before it starts any process, and the
/// STM32 the timestep the world reports at INIT_PID (a world cosim did not
/// start), with the same message.
pub fn check_timestep(
    ms: u64,
    mode: SyncMode,
) -> Result<protocol::TimestepMs, protocol::TimestepError> {
    protocol::TimestepMs::check(ms, mode == SyncMode::Thesis)
}

/// The thesis's rounding of a delay `d` to whole timesteps (Listing 4.4):
/// `q = d / ts`, `r = d % ts`, and if `r > ts/2` (integer division, strictly
/// greater) then `q += 1, r −= ts`. Returns `(q, r)` with `d = q·ts + r`.
///
/// Works on any integer unit (ms in the thesis mode, ps in the bounded
/// mode). A negative `d` (possible only for a carried remainder) never gives
/// a negative `q`: the world cannot go back, so the whole `d` stays as `r`.
pub fn split_delay(d: i64, ts: i64) -> (i64, i64) {
    assert!(ts > 0, "timestep must be positive");
    if d <= 0 {
        return (0, d);
    }
    let mut q = d / ts;
    let mut r = d % ts;
    if r > ts / 2 {
        q += 1;
        r -= ts;
    }
    (q, r)
}

/// The running bookkeeping of one simulation.
#[derive(Debug, Clone)]
pub struct TimeKeeper {
    mode: SyncMode,
    /// basicTimeStep in ms; 0 until GET_INIT_DATA told us (the thesis's
    /// `webots_timestep == 0` case: delays then only go to the offset).
    timestep_ms: u64,
    /// Σ r of every rounded delay (thesis mode) or the carried remainder
    /// (bounded mode), in picoseconds so the bounded mode can carry core time.
    sensors_offset_ps: i64,
    /// Core time outside device delays (thesis mode), picoseconds.
    sim_off_accum_ps: i64,
    /// Platform time up to which time has been accounted for.
    accounted_until: Picos,
    /// World time we have told the world to run (ms), excluding the warm-up.
    world_sent_ms: u64,
    /// Delays of the current PID iteration (camera + inference + PID path).
    iter_delay_ms: u64,
    /// Platform → world time as the bookkeeping goes ([`time_map`]).
    map: time_map::TimeMapRecorder,
}

/// Figures printed at PRINT_SIMUL_TIME and written to `summary.json`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeReport {
    pub platform_time: Picos,
    pub sensors_offset_ms: f64,
    pub sim_off_accum_ms: f64,
    pub world_time_estimate_ms: f64,
}

impl TimeKeeper {
    pub fn new(mode: SyncMode) -> Self {
        TimeKeeper {
            mode,
            timestep_ms: 0,
            sensors_offset_ps: 0,
            sim_off_accum_ps: 0,
            accounted_until: Picos::ZERO,
            world_sent_ms: 0,
            iter_delay_ms: 0,
            map: time_map::TimeMapRecorder::default(),
        }
    }

    /// Platform → world time so far (DESIGN.md §3; `time_map.csv`).
    pub fn time_map(&self) -> &time_map::TimeMapRecorder {
        &self.map
    }

    /// A knot of the map at the end of what has been accounted: there the
    /// world's time is the platform's minus the offsets.
    fn note_map(&mut self) {
        let p = self.accounted_until;
        let world = p.0 as i64 - self.sensors_offset_ps - self.sim_off_accum_ps;
        self.map.note(p, world);
    }

    pub fn mode(&self) -> SyncMode {
        self.mode
    }

    pub fn set_timestep(&mut self, ts: Millis) {
        self.timestep_ms = ts.0;
    }

    pub fn timestep(&self) -> Millis {
        Millis(self.timestep_ms)
    }

    /// Accounts the core time between the end of the last delay and `now`.
    fn account_gap(&mut self, now: Picos) {
        if now > self.accounted_until {
            let gap = (now - self.accounted_until).0 as i64;
            match self.mode {
                SyncMode::Thesis => self.sim_off_accum_ps += gap,
                SyncMode::Bounded => self.sensors_offset_ps += gap,
            }
            self.accounted_until = now;
            self.note_map();
        }
    }

    /// Accounts the core time up to `now`, then a device delay `d` from there.
    fn account_delay(&mut self, d: Millis, now: Picos) {
        self.account_gap(now);
        self.accounted_until = self.accounted_until.max(now) + d.to_picos();
        self.note_map();
    }

    /// A device delay of `d` starting at platform time `now` that the world
    /// must follow. Returns how many whole timesteps the world must advance.
    pub fn delay(&mut self, d: Millis, now: Picos) -> u64 {
        self.account_delay(d, now);
        self.iteration_steps(d)
    }

    /// One tick of the platform's own clock (docs/SWARM.md §4.1, a firmware
    /// that never ran INIT_PID): a device delay of exactly `ts` from `from`
    /// that the world follows with one `ADVANCE_TIME ts`. It is accounted
    /// like [`TimeKeeper::delay`] (the platform time of the delay is covered,
    /// so nothing goes to `sim_off_accum`), and the world advances by `ts`
    /// itself, never by a rounded or carried amount: in the thesis mode that
    /// is what `delay(ts)` gives anyway (`ts / ts` = 1, remainder 0); in the
    /// bounded mode a remainder carried from before the first tick (the core
    /// time before INIT) stays carried instead of changing the tick. Either
    /// way the estimate stays exact and the drone's clock is warm-up + k·ts.
    pub fn clock_tick(&mut self, ts: Millis, from: Picos) {
        self.account_delay(ts, from);
        self.world_sent_ms += ts.0;
    }

    /// Platform time up to which time has been accounted for: the end of
    /// the last device delay (docs/SWARM.md §4.2: the platform time `p_d`
    /// that corresponds to the drone's clock).
    pub fn accounted_until(&self) -> Picos {
        self.accounted_until
    }

    /// A delay both sides already spend on their own (the 2000 ms start-up
    /// alignment of INIT_PID, the motor stop time at STOP): no advance, no
    /// offset.
    pub fn aligned(&mut self, d: Millis, now: Picos, world_also: bool) {
        self.account_delay(d, now);
        if world_also {
            self.world_sent_ms += d.0;
        }
    }

    /// Starts a PID iteration with the camera's delay (the thesis sets
    /// `iter_delay` to the camera time at every image).
    pub fn begin_iteration(&mut self, camera: Millis, now: Picos) {
        self.account_delay(camera, now);
        self.iter_delay_ms = camera.0;
    }

    /// Adds a delay to the current iteration without advancing the world yet
    /// (ITER_ADVANCE, the PID/motor path).
    pub fn add_to_iteration(&mut self, d: Millis, now: Picos) {
        self.account_delay(d, now);
        self.iter_delay_ms += d.0;
    }

    /// Takes the accumulated iteration delay (resetting it) so the motors can
    /// send it as `(iter_delay − 1)` of SET_VELOCITY steps plus 1 ms.
    pub fn take_iteration(&mut self) -> Millis {
        Millis(std::mem::take(&mut self.iter_delay_ms))
    }

    /// Rounds a delay whose platform time has already been accounted (via
    /// `begin_iteration`/`add_to_iteration`, or by [`TimeKeeper::delay`]) into
    /// whole world steps, keeping the remainder as the mode says.
    pub fn iteration_steps(&mut self, d: Millis) -> u64 {
        if self.timestep_ms == 0 {
            self.sensors_offset_ps += d.to_picos().0 as i64;
            self.note_map();
            return 0;
        }
        let q = match self.mode {
            SyncMode::Thesis => {
                let (q, r) = split_delay(d.0 as i64, self.timestep_ms as i64);
                self.sensors_offset_ps += r * Picos::PER_MS as i64;
                q
            }
            SyncMode::Bounded => {
                let pending = self.sensors_offset_ps + d.to_picos().0 as i64;
                let ts_ps = (self.timestep_ms * Picos::PER_MS) as i64;
                let (q, r) = split_delay(pending, ts_ps);
                self.sensors_offset_ps = r;
                q
            }
        } as u64;
        self.world_sent_ms += q * self.timestep_ms;
        self.note_map();
        q
    }

    /// World time the platform has asked for (ms, excluding the warm-up).
    pub fn world_sent(&self) -> Millis {
        Millis(self.world_sent_ms)
    }

    /// The thesis's estimate of the world's time, as of platform time `now`.
    pub fn report(&mut self, now: Picos) -> TimeReport {
        self.account_gap(now);
        let ps_to_ms = |ps: i64| ps as f64 / Picos::PER_MS as f64;
        // platform − sensors_offset − sim_off_accum, in integer picoseconds.
        let estimate_ps = now.0 as i64 - self.sensors_offset_ps - self.sim_off_accum_ps;
        TimeReport {
            platform_time: now,
            sensors_offset_ms: ps_to_ms(self.sensors_offset_ps),
            sim_off_accum_ms: ps_to_ms(self.sim_off_accum_ps),
            world_time_estimate_ms: ps_to_ms(estimate_ps),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn thesis_worked_example() {
        // §4.2.4: 29 ms at an 8 ms timestep → q = 4, r = −3.
        assert_eq!(split_delay(29, 8), (4, -3));
    }

    #[test]
    fn half_a_step_rounds_down_and_more_rounds_up() {
        assert_eq!(split_delay(16, 32), (0, 16));
        assert_eq!(split_delay(17, 32), (1, -15));
        assert_eq!(split_delay(5, 32), (0, 5));
        assert_eq!(split_delay(5, 8), (1, -3));
        // 1 ms timestep: r must be strictly greater than 0 (= 1/2) to round up.
        assert_eq!(split_delay(7, 1), (7, 0));
    }

    proptest! {
        #[test]
        fn split_is_exact_and_nearest(d in 0i64..=200, ts in 1i64..=64) {
            let (q, r) = split_delay(d, ts);
            prop_assert_eq!(q * ts + r, d);
            prop_assert!(q >= 0);
            // The remainder lies in (−ts/2, ts/2] in the thesis's integer sense.
            prop_assert!(r <= ts / 2);
            prop_assert!(r > ts / 2 - ts);
            // No other multiple of ts is strictly closer than q·ts.
            for k in [q - 1, q + 1] {
                if k >= 0 {
                    prop_assert!((d - k * ts).abs() >= r.abs());
                }
            }
        }

        #[test]
        fn bounded_mode_never_drifts_more_than_half_a_step(
            delays in proptest::collection::vec(0u64..=200, 1..100),
            ts in 1u64..=64,
        ) {
            let mut tk = TimeKeeper::new(SyncMode::Bounded);
            tk.set_timestep(Millis(ts));
            let mut now = Picos::ZERO;
            for d in delays {
                tk.delay(Millis(d), now);
                now += Millis(d).to_picos();
                let diff = now.0 as i64 - (tk.world_sent().0 * Picos::PER_MS) as i64;
                prop_assert!(diff.abs() <= (ts * Picos::PER_MS / 2) as i64);
            }
        }

        #[test]
        fn estimate_is_exact_in_both_modes(
            delays in proptest::collection::vec((0u64..=200, 0u64..5_000_000), 1..60),
            ts in 1u64..=64,
            bounded in any::<bool>(),
        ) {
            let mode = if bounded { SyncMode::Bounded } else { SyncMode::Thesis };
            let mut tk = TimeKeeper::new(mode);
            tk.set_timestep(Millis(ts));
            let mut now = Picos::ZERO;
            for (d, core_ps) in delays {
                now += Picos(core_ps); // the core runs between device operations
                tk.delay(Millis(d), now);
                now += Millis(d).to_picos();
            }
            now += Picos(1234);
            let report = tk.report(now);
            let world_ms = tk.world_sent().0 as f64;
            prop_assert!((report.world_time_estimate_ms - world_ms).abs() < 1e-9);
            // The platform's last instant maps to the world's time (the
            // map of time_map.csv ends where the estimate does).
            let end = time_map::world_at(&tk.time_map().knots(), now.0);
            prop_assert_eq!(end, (tk.world_sent().0 * Picos::PER_MS) as i64);
        }
    }

    #[test]
    fn iteration_at_32_ms_sends_one_step_and_keeps_one_ms_offset() {
        // Camera 16 + inference 10 + PID path 7 = 33 ms: 32 ms as SET_VELOCITY
        // steps (q = 1), then 1 ms for the motor power model (q = 0, r = 1).
        let mut tk = TimeKeeper::new(SyncMode::Thesis);
        tk.set_timestep(Millis(32));
        let t0 = Picos::ZERO;
        tk.begin_iteration(Millis(16), t0);
        tk.add_to_iteration(Millis(10), Millis(16).to_picos());
        tk.add_to_iteration(Millis(7), Millis(26).to_picos());
        let it = tk.take_iteration();
        assert_eq!(it, Millis(33));
        assert_eq!(tk.iteration_steps(Millis(it.0 - 1)), 1);
        assert_eq!(tk.iteration_steps(Millis(1)), 0);
        let r = tk.report(Millis(33).to_picos());
        assert_eq!(r.sensors_offset_ms, 1.0);
        assert_eq!(r.world_time_estimate_ms, 32.0);
    }
}
