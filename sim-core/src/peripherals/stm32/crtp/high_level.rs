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
//! | 8 LAND_2 | group, height, yaw, use current yaw, duration | then motors off |
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
    pub landing: bool,
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
    /// A landing's plan is over (or the drone reached the ground first):
    /// flying on until the drone is down (see [`Touchdown`]).
    Touchdown(Touchdown),
}

/// A landing's end. The firmware stops the motors when the landing plan
/// ends (`TRAJECTORY_STATE_LANDING` → `IDLE`, `planner.c`), with its drone
/// on the floor: its z position and velocity PIDs track the plan. The
/// Webots height loop here lags a fast plan: cfclient's 0.5 m/s landing
/// ended with the drone 9–40 cm up, falling at 0.7–0.8 m/s. Cut then, the
/// world's rotors (which spin down at their limited rate, DESIGN.md §5)
/// kept most of the weight for a second while the drone hit the floor and
/// bounced with no attitude control, rotating at the rate the impact gave
/// it (the contact solver's, DESIGN.md §5: 1 iteration); flown on to the
/// floor and cut at the first contact it did the same on its bounce. So
/// the landing ends as EXT_LAND's does (`motion.rs`): the height set-point
/// descends from where the drone is at [`TOUCHDOWN_SPEED`], the position
/// loop holds the plan's end above [`LEVEL_HEIGHT_M`], below it the
/// attitude loop holds the drone level (no position loop fighting the
/// floor's friction: that skidded), and the motors stop once the drone
/// has rested within [`GROUND_M`] of the goal for [`LANDED_ITERATIONS`]
/// iterations, or [`TOUCHDOWN_TIMEOUT_S`] after the plan's end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touchdown {
    /// The plan's end (x, y, z, yaw).
    pub end: [f64; 4],
    /// The descending height set-point (m) and when it was last lowered.
    z: f64,
    at: Picos,
    deadline: Picos,
    resting: u32,
}

/// The touchdown's descent (m/s): slow enough that the drone meets the
/// floor without bouncing off it.
pub const TOUCHDOWN_SPEED: f64 = 0.2;
/// Height above the landing goal below which the drone is held level
/// (m): the last bounce-prone centimetres, without the position loop.
pub const LEVEL_HEIGHT_M: f64 = 0.10;
/// Within this of the landing goal the drone is on the floor (m): the
/// seed-004 room's drone rests with its centre 0.015 m up (its start).
pub const GROUND_M: f64 = 0.03;
/// Slower than this vertically (m/s) the drone rests (not bouncing).
pub const RESTING_SPEED: f64 = 0.05;
/// Iterations resting on the floor before the motors stop, as EXT_LAND's
/// (`motion.rs`, `LANDED_ITERATIONS`): a bounce restarts the count.
pub const LANDED_ITERATIONS: u32 = 3;
/// The longest the drone is flown after its landing plan ended (s): the
/// motors stop then wherever it is, as the firmware's would at once.
pub const TOUCHDOWN_TIMEOUT_S: f64 = 5.0;

/// What the planner asks of the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Aim {
    /// Follow this reference with the position loop.
    Track(Reference),
    /// Level attitude, the height loop at this height (m), yaw held.
    Level { z: f64 },
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
        let plan = |to: [f64; 4], duration: f64, linear: bool, landing: bool| {
            let ok = to.iter().all(|v| v.is_finite()) && duration.is_finite() && duration >= 0.0;
            ok.then_some(Move {
                start: now,
                duration,
                from: self.from(now, pose),
                to,
                linear,
                landing,
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
                plan([from[0], from[1], h, yaw], t, false, cmd == COMMAND_LAND_2)
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
                plan(to, t, linear != 0, false)
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
            landing: false,
        });
    }

    /// What to fly at `now` with the estimated height `z` and vertical
    /// speed `vz`; `None`: motors off. A landing ends in a [`Touchdown`]
    /// when its plan ends or when the drone gets within [`LEVEL_HEIGHT_M`]
    /// of the goal first (a slow plan), which stops the motors once the
    /// drone rests on the floor.
    pub fn aim(&mut self, now: Picos, z: f64, vz: f64) -> Option<Aim> {
        match self.state {
            State::Idle => None,
            State::Flying(m) if m.landing && (m.finished(now) || z <= m.to[2] + LEVEL_HEIGHT_M) => {
                // The plan's end plus the timeout (a huge duration
                // saturates).
                let wait = (m.duration + TOUCHDOWN_TIMEOUT_S) * Picos::PER_S as f64;
                self.state = State::Touchdown(Touchdown {
                    end: m.to,
                    z: z.max(m.to[2]),
                    at: now,
                    deadline: Picos(m.start.0.saturating_add(wait as u64)),
                    resting: 0,
                });
                self.aim(now, z, vz)
            }
            State::Flying(m) => Some(Aim::Track(m.reference(now))),
            State::Touchdown(mut t) => {
                let goal = t.end[2];
                let rests = z <= goal + GROUND_M && vz.abs() < RESTING_SPEED;
                t.resting = if rests { t.resting + 1 } else { 0 };
                if t.resting >= LANDED_ITERATIONS || now >= t.deadline {
                    self.state = State::Idle;
                    return None;
                }
                let dt = now.saturating_sub(t.at).as_secs_f64();
                t.z = (t.z - TOUCHDOWN_SPEED * dt).max(goal);
                t.at = now;
                self.state = State::Touchdown(t);
                Some(if z > goal + LEVEL_HEIGHT_M {
                    Aim::Track(Reference {
                        pos: [t.end[0], t.end[1], t.z],
                        vel: [0.0; 3],
                        yaw: t.end[3],
                    })
                } else {
                    Aim::Level { z: t.z }
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

    fn track(a: Option<Aim>) -> Reference {
        match a {
            Some(Aim::Track(r)) => r,
            other => panic!("expected a tracked reference, got {other:?}"),
        }
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
        // A landing tracks its plan while the drone is up ...
        let t2 = t1 + Picos::from_ms(5000);
        hl.command(&land(0.0, 1.0), t2, [9.0; 4]);
        assert!(hl.aim(t2 + Picos::from_ms(500), 0.5, -0.5).is_some());
        // ... and the motors stop once the drone rests on the floor.
        let mut t = t2 + Picos::from_ms(600);
        assert!(matches!(hl.aim(t, 0.015, -0.3), Some(Aim::Level { .. })));
        for _ in 0..LANDED_ITERATIONS - 1 {
            t = t + Picos::from_ms(32);
            assert!(matches!(hl.aim(t, 0.015, 0.0), Some(Aim::Level { .. })));
        }
        assert_eq!(hl.aim(t + Picos::from_ms(32), 0.015, 0.0), None);
        assert_eq!(hl.state, State::Idle);
        // Short or non-finite commands are ignored.
        hl.command(&takeoff(1.0, 2.0)[..8], t2, [0.0; 4]);
        hl.command(&takeoff(f32::NAN, 2.0), t2, [0.0; 4]);
        assert_eq!(hl.state, State::Idle);
    }

    #[test]
    fn a_landing_flies_on_until_the_drone_is_down() {
        let mut hl = HighLevel::default();
        let t0 = Picos::from_ms(1000);
        let ms = |s: f64| t0 + Picos::from_ms((s * 1000.0).round() as u64);
        hl.command(&land(0.0, 1.0), t0, [1.0, 2.0, 0.5, 0.0]);
        // The plan is over, the drone still 0.3 m up and falling: held over
        // the plan's end by the position loop, the height set-point
        // descending from the drone's height at TOUCHDOWN_SPEED ...
        let r = track(hl.aim(ms(1.1), 0.3, -0.7));
        assert_eq!(r.pos, [1.0, 2.0, 0.3]);
        let r = track(hl.aim(ms(1.6), 0.2, -0.3));
        assert!((r.pos[2] - (0.3 - 0.5 * TOUCHDOWN_SPEED)).abs() < 1e-9, "{r:?}");
        // ... then level below LEVEL_HEIGHT_M, down to the goal.
        let Some(Aim::Level { z }) = hl.aim(ms(2.0), 0.08, -0.2) else {
            panic!("level")
        };
        assert!((z - (0.2 - 0.4 * TOUCHDOWN_SPEED)).abs() < 1e-9, "{z}");
        assert_eq!(hl.aim(ms(4.0), 0.08, -0.2), Some(Aim::Level { z: 0.0 }));
        // Touching the floor while moving, or a bounce, is not resting.
        for (z, vz) in [(0.02, -0.3), (0.02, 0.0), (0.02, 0.2), (0.02, 0.0), (0.02, 0.01)] {
            assert!(hl.aim(ms(4.1), z, vz).is_some());
        }
        assert_eq!(hl.aim(ms(4.2), 0.02, 0.0), None);
        // Never down: the motors stop TOUCHDOWN_TIMEOUT_S after the plan's end.
        hl.command(&land(0.0, 1.0), t0, [1.0, 2.0, 0.5, 0.0]);
        assert!(hl.aim(ms(1.0 + TOUCHDOWN_TIMEOUT_S - 0.01), 0.3, 0.0).is_some());
        assert_eq!(hl.aim(ms(1.0 + TOUCHDOWN_TIMEOUT_S), 0.3, 0.0), None);
        // A slow landing that nears the floor before its plan ends is
        // levelled then (the position loop would skid it along the floor).
        hl.command(&land(0.0, 10.0), t0, [1.0, 2.0, 0.5, 0.0]);
        assert!(matches!(hl.aim(ms(5.0), 0.11, -0.1), Some(Aim::Track(_))));
        assert!(matches!(hl.aim(ms(5.0), 0.09, -0.1), Some(Aim::Level { .. })));
    }
}
