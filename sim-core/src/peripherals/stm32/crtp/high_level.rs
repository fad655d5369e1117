//! Port 8, the high-level commander (the firmware's
//! `crtp_commander_high_level.c` and `planner.c`, cflib's
//! `high_level_commander.py`): take-off, land, go-to with a duration, stop,
//! group masks. Trajectories (`COMMAND_DEFINE_TRAJECTORY`, `START_TRAJECTORY`,
//! spirals) need the firmware's trajectory memory and are not served.
//!
//! | command | layout after the command byte | |
//! |---|---|---|
//! | 0 SET_GROUP_MASK | mask | |
//! | 3 STOP | group | motors off |
//! | 4 GO_TO | group, relative, x, y, z, yaw (rad), duration (s) | |
//! | 7 TAKEOFF_2 | group, height, yaw, use current yaw (bool), duration | |
//! | 8 LAND_2 | group, height, yaw, use current yaw, duration | a [`Touchdown`]: down at ≤ 0.2 m/s, motors off just above the floor |
//! | 12 GO_TO_2 | group, relative, linear, x, y, z, yaw, duration | |
//!
//! The firmware plans a 7th-order polynomial per axis from the current
//! state to the goal at rest. Here every move starts from the current
//! estimate at rest too and follows the 7th-order "smootherstep"
//! `s(τ) = 35τ⁴ − 84τ⁵ + 70τ⁶ − 20τ⁷` (τ = t/T), whose velocity,
//! acceleration and jerk are zero at both ends: the same class of curve as
//! the firmware's rest-to-rest plans, with the duration the client asked
//! for. `linear` (GO_TO_2) follows `s(τ) = τ`.

use super::packet::f32_at;
use crate::units::Picos;

const COMMAND_SET_GROUP_MASK: u8 = 0;
const COMMAND_STOP: u8 = 3;
const COMMAND_GO_TO: u8 = 4;
const COMMAND_TAKEOFF_2: u8 = 7;
const COMMAND_LAND_2: u8 = 8;
const COMMAND_GO_TO_2: u8 = 12;

/// `s(τ)` and `ds/dτ` of the rest-to-rest 7th-order polynomial.
pub fn smootherstep(tau: f64) -> (f64, f64) {
    let t = tau.clamp(0.0, 1.0);
    let t3 = t * t * t;
    let s = t3 * t * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)));
    let ds = t3 * (140.0 + t * (-420.0 + t * (420.0 - 140.0 * t)));
    (s, ds)
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    pub start: Picos,
    pub duration: f64,
    pub from: [f64; 4],
    pub to: [f64; 4],
    pub linear: bool,
}

/// Position, velocity and yaw of the plan at `now`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    pub pos: [f64; 3],
    pub vel: [f64; 3],
    pub yaw: f64,
}

impl Move {
    pub fn reference(&self, now: Picos) -> Reference {
        let t = now.saturating_sub(self.start).as_secs_f64();
        let tau = if self.duration > 0.0 {
            t / self.duration
        } else {
            1.0
        };
        let (s, ds) = if self.linear {
            (tau.clamp(0.0, 1.0), if tau < 1.0 { 1.0 } else { 0.0 })
        } else {
            smootherstep(tau)
        };
        let k = if self.duration > 0.0 {
            ds / self.duration
        } else {
            0.0
        };
        let at = |i: usize| self.from[i] + (self.to[i] - self.from[i]) * s;
        let dyaw = super::super::motion::wrap_angle(self.to[3] - self.from[3]);
        Reference {
            pos: [at(0), at(1), at(2)],
            vel: [0, 1, 2].map(|i| (self.to[i] - self.from[i]) * k),
            yaw: self.from[3] + dyaw * s,
        }
    }

    pub fn finished(&self, now: Picos) -> bool {
        now.saturating_sub(self.start).as_secs_f64() >= self.duration
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum State {
    /// Motors off (the planner's `TRAJECTORY_STATE_IDLE`).
    #[default]
    Idle,
    Flying(Move),
    /// Landing (see [`Touchdown`]).
    Touchdown(Touchdown),
}

/// A landing. The firmware plans it as any move (a 7th-order polynomial
/// to the goal height in the duration asked) and stops the motors when the
/// plan ends (`TRAJECTORY_STATE_LANDING` → `IDLE`, `planner.c`), with its
/// drone on the floor: its z position and velocity PIDs track the plan.
/// Here that tipped the drone over in most landings (docs/CFLIB.md,
/// "cfclient's Land"), for two reasons of this platform's:
///
/// - the Webots height loop (DESIGN.md §4) lags a fast plan and the
///   world's motors change speed at a limited rate (DESIGN.md §5): at the
///   end of cfclient's 0.5 m/s landing (peak 1.09 m/s) the drone was 9–40
///   cm up, falling at 0.7–1.1 m/s, and could not brake in what was left;
/// - a drone that meets the floor with its rotors near the hover speed has
///   no weight on it: the impact's small asymmetry becomes a free rotation
///   that the Webots attitude loop (0.5 per rad) is far too weak to stop.
///   world-server's `a_touchdown_below_the_hover_thrust_settles_flat`:
///   at the hover speed a 0.3 m/s touchdown tilts the body 0.64 rad and
///   0.7 m/s turns it over; at 70 % of it, or with the motors off, the
///   largest tilt is 0.07–0.34 rad and it settles flat. Cut at the plan's
///   end, the rotors (spinning down at their limited rate) still held the
///   weight when the drone hit the floor.
///
/// So a landing here is flown as a pilot (or EXT_LAND, `motion.rs`) lands:
/// the position loop holds x, y and the yaw while the height set-point
/// descends from the drone's height at the plan's mean speed, at most
/// [`TOUCHDOWN_SPEED`], slowing down over the last 0.2 m
/// ([`APPROACH_RATE`]), to [`CUT_HEIGHT_M`] above the goal; once the drone
/// hovers there ([`LANDED_ITERATIONS`] iterations within [`CUT_TOLERANCE_M`]
/// and slower than [`RESTING_SPEED`]) the motors stop and it sinks the last
/// centimetres on its spinning-down rotors, meeting the floor slowly with
/// the thrust below its weight. [`TOUCHDOWN_TIMEOUT_S`] after the descent's
/// end the motors stop wherever the drone is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touchdown {
    /// The goal (x, y, z, yaw).
    pub end: [f64; 4],
    /// The descending height set-point (m), its speed (m/s) and when it
    /// was last lowered.
    z: f64,
    speed: f64,
    at: Picos,
    deadline: Picos,
    hovering: u32,
}

/// The fastest descent (m/s): 60 seeded cfclient sessions landed upright
/// at 0.2 m/s, 19 of 20 at 0.3 (`scripts/cfclient-landings.py`, before
/// the [`APPROACH_RATE`] slow-down).
pub const TOUCHDOWN_SPEED: f64 = 0.2;
/// Near the cut height the descent slows to this rate times the height
/// left (1/s: from 0.2 m above it, exponentially with a 1 s time
/// constant). The height loop lags (DESIGN.md §4, the world's limited
/// motor acceleration): a set-point that stopped at 0.2 m/s carried the
/// drone through the cut height onto the floor with its motors on, where
/// it tipped (0.22 rad on average) and skidded (17 cm on average, up to
/// 43 cm); slowing from 0.1 m above (2/s), 7 cm and 31 cm; from 0.2 m,
/// 3 mm and 1.1 cm, the largest tilt 0.06 rad on average (40 seeded
/// sessions each, `scripts/cfclient-landings.py --seed 2`).
pub const APPROACH_RATE: f64 = 1.0;
/// Where the motors stop, above the landing goal (m): the drone's centre
/// rests 0.015 m up, so 3.5 cm of fall on spinning-down rotors.
pub const CUT_HEIGHT_M: f64 = 0.05;
/// Within this of the cut height and slower than [`RESTING_SPEED`]
/// vertically (m/s), the drone hovers there.
pub const CUT_TOLERANCE_M: f64 = 0.02;
pub const RESTING_SPEED: f64 = 0.05;
/// Iterations hovering at the cut height before the motors stop, as
/// EXT_LAND's (`motion.rs`, `LANDED_ITERATIONS`).
pub const LANDED_ITERATIONS: u32 = 3;
/// How long after the descent's end the motors stop at the latest (s).
pub const TOUCHDOWN_TIMEOUT_S: f64 = 3.0;

impl Touchdown {
    /// A landing from height `z` to `to` asked to take `duration` s;
    /// `None` for a non-finite or negative argument.
    fn new(now: Picos, z: f64, to: [f64; 4], duration: f64) -> Option<Touchdown> {
        let ok = to.iter().all(|v| v.is_finite()) && z.is_finite() && duration.is_finite();
        if !ok || duration < 0.0 {
            return None;
        }
        let cut = to[2] + CUT_HEIGHT_M;
        let drop = (z - cut).max(0.0);
        let mean = if duration > 0.0 {
            drop / duration
        } else {
            f64::INFINITY
        };
        // At least 1 mm/s: a landing asked to take ages still ends.
        let speed = mean.clamp(1e-3, TOUCHDOWN_SPEED);
        // The descent plus the timeout (a huge time saturates).
        let wait = (drop / speed + TOUCHDOWN_TIMEOUT_S) * Picos::PER_S as f64;
        Some(Touchdown {
            end: to,
            z: z.max(cut),
            speed,
            at: now,
            deadline: Picos(now.0.saturating_add(wait as u64)),
            hovering: 0,
        })
    }
}

#[derive(Debug, Clone, Copy, Default)]
pub struct HighLevel {
    pub state: State,
    group_mask: u8,
}

impl HighLevel {
    fn mine(&self, group: u8) -> bool {
        // ALL_GROUPS = 0 addresses every drone (`planner.h`).
        group == 0 || self.group_mask & group != 0
    }

    /// A port-8 packet; `pose` is the current estimate (x, y, z, yaw).
    pub fn command(&mut self, d: &[u8], now: Picos, pose: [f64; 4]) {
        let Some(&cmd) = d.first() else { return };
        let group = d.get(1).copied().unwrap_or(0);
        if cmd != COMMAND_SET_GROUP_MASK && !self.mine(group) {
            return;
        }
        let f = |i: usize| f32_at(d, i);
        let plan = |to: [f64; 4], duration: f64, linear: bool| {
            let ok = to.iter().all(|v| v.is_finite()) && duration.is_finite() && duration >= 0.0;
            ok.then_some(Move {
                start: now,
                duration,
                from: self.from(now, pose),
                to,
                linear,
            })
        };
        let new = match cmd {
            COMMAND_SET_GROUP_MASK => {
                self.group_mask = group;
                return;
            }
            COMMAND_STOP => {
                self.state = State::Idle;
                return;
            }
            COMMAND_TAKEOFF_2 | COMMAND_LAND_2 => {
                let (Some(h), Some(yaw), Some(&cur), Some(t)) = (f(2), f(6), d.get(10), f(11))
                else {
                    return;
                };
                let from = self.from(now, pose);
                let yaw = if cur != 0 { from[3] } else { yaw };
                let to = [from[0], from[1], h, yaw];
                if cmd == COMMAND_LAND_2 {
                    if let Some(td) = Touchdown::new(now, from[2].max(pose[2]), to, t) {
                        self.state = State::Touchdown(td);
                    }
                    return;
                }
                plan(to, t, false)
            }
            COMMAND_GO_TO | COMMAND_GO_TO_2 => {
                let (rel, linear, o) = if cmd == COMMAND_GO_TO {
                    (d.get(2), Some(&0), 3)
                } else {
                    (d.get(2), d.get(3), 4)
                };
                let (Some(&rel), Some(&linear)) = (rel, linear) else {
                    return;
                };
                let (Some(x), Some(y), Some(z), Some(yaw), Some(t)) =
                    (f(o), f(o + 4), f(o + 8), f(o + 12), f(o + 16))
                else {
                    return;
                };
                let from = self.from(now, pose);
                let to = if rel != 0 {
                    [from[0] + x, from[1] + y, from[2] + z, from[3] + yaw]
                } else {
                    [x, y, z, yaw]
                };
                plan(to, t, linear != 0)
            }
            _ => None,
        };
        if let Some(m) = new {
            self.state = State::Flying(m);
        }
    }

    /// Where a new move starts: the current plan's point if flying (the
    /// firmware plans from its current set-point), else the estimate.
    fn from(&self, now: Picos, pose: [f64; 4]) -> [f64; 4] {
        match self.state {
            State::Flying(m) => {
                let r = m.reference(now);
                [r.pos[0], r.pos[1], r.pos[2], r.yaw]
            }
            State::Idle | State::Touchdown(_) => pose,
        }
    }

    /// Hover where the drone is (a notify-setpoint-stop hands a flying
    /// drone to the high-level commander, which holds its last state).
    pub fn hold(&mut self, now: Picos, pose: [f64; 4]) {
        self.state = State::Flying(Move {
            start: now,
            duration: 0.0,
            from: pose,
            to: pose,
            linear: false,
        });
    }

    /// What to fly at `now` with the estimated height `z` and vertical
    /// speed `vz`; `None`: motors off (a [`Touchdown`] ends so).
    pub fn aim(&mut self, now: Picos, z: f64, vz: f64) -> Option<Reference> {
        match self.state {
            State::Idle => None,
            State::Flying(m) => Some(m.reference(now)),
            State::Touchdown(mut t) => {
                let cut = t.end[2] + CUT_HEIGHT_M;
                let there = (z - cut).abs() <= CUT_TOLERANCE_M && vz.abs() < RESTING_SPEED;
                t.hovering = if there { t.hovering + 1 } else { 0 };
                if t.hovering >= LANDED_ITERATIONS || now >= t.deadline {
                    self.state = State::Idle;
                    return None;
                }
                // The last centimetres slow down exponentially: the drone
                // arrives at the cut height instead of braking through it.
                let dt = now.saturating_sub(t.at).as_secs_f64();
                let v = t.speed.min(APPROACH_RATE * (t.z - cut));
                t.z = (t.z - v * dt).max(cut);
                t.at = now;
                self.state = State::Touchdown(t);
                Some(Reference {
                    pos: [t.end[0], t.end[1], t.z],
                    vel: [0.0; 3],
                    yaw: t.end[3],
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn takeoff(h: f32, t: f32) -> Vec<u8> {
        let mut d = vec![COMMAND_TAKEOFF_2, 0];
        d.extend(h.to_le_bytes());
        d.extend(0f32.to_le_bytes());
        d.push(1);
        d.extend(t.to_le_bytes());
        d
    }

    #[test]
    fn smootherstep_is_rest_to_rest() {
        assert_eq!(smootherstep(0.0), (0.0, 0.0));
        assert_eq!(smootherstep(1.0), (1.0, 0.0));
        let (s, ds) = smootherstep(0.5);
        assert!((s - 0.5).abs() < 1e-12);
        // Peak speed of the 7th-order rest-to-rest curve: 35/16 of the mean.
        assert!((ds - 35.0 / 16.0).abs() < 1e-12);
    }

    fn track(a: Option<Reference>) -> Reference {
        a.expect("a reference to track")
    }

    fn land(z: f32, t: f32) -> Vec<u8> {
        let mut l = takeoff(z, t);
        l[0] = COMMAND_LAND_2;
        l
    }

    #[test]
    fn takeoff_goto_land_plan_from_the_estimate_then_stop() {
        let mut hl = HighLevel::default();
        let t0 = Picos::from_ms(2000);
        hl.command(&takeoff(1.0, 2.0), t0, [0.5, -1.0, 0.0, 0.3]);
        let r = track(hl.aim(t0 + Picos::from_ms(1000), 0.4, 0.0));
        assert_eq!(r.pos[0], 0.5);
        assert!((r.pos[2] - 0.5).abs() < 1e-9);
        assert!((r.yaw - 0.3).abs() < 1e-6);
        let end = track(hl.aim(t0 + Picos::from_ms(2500), 1.0, 0.0));
        assert!((end.pos[2] - 1.0).abs() < 1e-9 && end.vel == [0.0; 3]);
        // Relative go-to from the plan's end.
        let mut g = vec![COMMAND_GO_TO_2, 0, 1, 0];
        for v in [1.0f32, 0.0, 0.0, 0.0, 4.0] {
            g.extend(v.to_le_bytes());
        }
        let t1 = t0 + Picos::from_ms(3000);
        hl.command(&g, t1, [9.0; 4]);
        let r = track(hl.aim(t1 + Picos::from_ms(4000), 1.0, 0.0));
        assert!((r.pos[0] - 1.5).abs() < 1e-6);
        // A landing descends at TOUCHDOWN_SPEED from the plan's height over
        // the plan's point, the motors stop once the drone hovers at the
        // cut height.
        let t2 = t1 + Picos::from_ms(5000);
        hl.command(&land(0.0, 1.0), t2, [9.0, 9.0, 0.8, 9.0]);
        let r = track(hl.aim(t2 + Picos::from_ms(500), 0.9, -0.1));
        assert_eq!([r.pos[0], r.pos[1]], [1.5, -1.0]);
        assert!(
            (r.pos[2] - (1.0 - 0.5 * TOUCHDOWN_SPEED)).abs() < 1e-9,
            "{r:?}"
        );
        let mut t = t2 + Picos::from_ms(6000);
        let cut = CUT_HEIGHT_M;
        assert_eq!(track(hl.aim(t, cut, -0.2)).pos[2], cut);
        for _ in 0..LANDED_ITERATIONS - 1 {
            t += Picos::from_ms(32);
            assert!(hl.aim(t, cut, 0.0).is_some());
        }
        assert_eq!(hl.aim(t + Picos::from_ms(32), cut, 0.0), None);
        assert_eq!(hl.state, State::Idle);
        // Short or non-finite commands are ignored.
        hl.command(&takeoff(1.0, 2.0)[..8], t2, [0.0; 4]);
        hl.command(&takeoff(f32::NAN, 2.0), t2, [0.0; 4]);
        assert_eq!(hl.state, State::Idle);
    }

    #[test]
    fn a_landing_descends_slowly_and_stops_the_motors_just_above_the_floor() {
        let mut hl = HighLevel::default();
        let t0 = Picos::from_ms(1000);
        let ms = |s: f64| t0 + Picos::from_ms((s * 1000.0).round() as u64);
        // From 0.45 m in 0.1 s: at TOUCHDOWN_SPEED (2 s to the cut height).
        hl.command(&land(0.0, 0.1), t0, [1.0, 2.0, 0.45, 0.0]);
        let r = track(hl.aim(ms(1.0), 0.3, -0.2));
        assert_eq!(r.pos, [1.0, 2.0, 0.45 - TOUCHDOWN_SPEED]);
        // 0.2 m above the cut height it slows down: 1/s x the height left.
        let z = track(hl.aim(ms(1.1), 0.25, -0.2)).pos[2];
        assert!((z - 0.23).abs() < 1e-9, "{z}");
        let z = track(hl.aim(ms(1.2), 0.24, -0.2)).pos[2];
        assert!(
            (z - (0.23 - 0.1 * APPROACH_RATE * (0.23 - CUT_HEIGHT_M))).abs() < 1e-9,
            "{z}"
        );
        assert_eq!(track(hl.aim(ms(2.5), 0.1, -0.2)).pos[2], CUT_HEIGHT_M);
        // Passing through the cut height, or bouncing, is not hovering there.
        let cut = CUT_HEIGHT_M;
        for (z, vz) in [(cut, -0.2), (cut, 0.0), (cut, 0.1), (cut, 0.0), (cut, 0.01)] {
            assert!(hl.aim(ms(2.6), z, vz).is_some());
        }
        assert_eq!(hl.aim(ms(2.7), cut, 0.0), None);
        // A slower landing keeps its own mean speed (0.4 m in 8 s).
        hl.command(&land(0.0, 8.0), t0, [1.0, 2.0, 0.45, 0.0]);
        assert!((track(hl.aim(ms(4.0), 0.3, -0.05)).pos[2] - 0.25).abs() < 1e-9);
        // Never there: the motors stop TOUCHDOWN_TIMEOUT_S after the descent.
        hl.command(&land(0.0, 0.1), t0, [1.0, 2.0, 0.45, 0.0]);
        assert!(hl
            .aim(ms(2.0 + TOUCHDOWN_TIMEOUT_S - 0.01), 0.3, 0.0)
            .is_some());
        assert_eq!(hl.aim(ms(2.0 + TOUCHDOWN_TIMEOUT_S), 0.3, 0.0), None);
        // Bad arguments are ignored.
        hl.command(&land(f32::NAN, 1.0), t0, [1.0, 2.0, 0.45, 0.0]);
        hl.command(&land(0.0, -1.0), t0, [1.0, 2.0, 0.45, 0.0]);
        assert_eq!(hl.state, State::Idle);
    }
}
