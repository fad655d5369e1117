//! The lockstep against scripted platforms: hand-checked orders, a slow
//! drone, STOP while others fly, errors, and the central property: the order
//! of everything the world does does not depend on the order of arrival.

use proptest::prelude::*;

use super::*;

const TS: u64 = 32;
const T0: Millis = Millis(2000);

/// What a scripted platform sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Op {
    /// A request with a reply (GET_SENSORS, RADIO_RECV, …).
    Query,
    /// SET_VELOCITY / ADVANCE_TIME of this many ms (no reply).
    Advance(u64),
    /// STOP: its propellers stop after the given number of physics steps.
    Stop(u64),
}

/// What the world did, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Event {
    /// Drone, index of the op in its script, world time.
    Processed(usize, usize, Millis),
    /// The physics stepped to this time.
    Stepped(Millis),
    /// A STOP reply: drone, world time, STOP_TIME.
    Stopped(usize, Millis, Millis),
}

/// How the platforms' frames reach the world.
#[derive(Debug, Clone)]
enum Arrival {
    /// Each platform in turn.
    RoundRobin,
    /// Drone `0` only sends when no other platform can (the slow one).
    Slow(usize),
    /// These choices (indices into the ready platforms, modulo).
    Choices(Vec<usize>),
}

struct Harness {
    ls: Lockstep<(usize, usize)>,
    scripts: Vec<Vec<Op>>,
    cursor: Vec<usize>,
    waiting: Vec<bool>,
    stop_left: Vec<u64>,
    log: Vec<Event>,
}

impl Harness {
    fn new(scripts: Vec<Vec<Op>>) -> Harness {
        let n = scripts.len();
        Harness {
            ls: Lockstep::new(n, T0, Millis(TS)),
            scripts,
            cursor: vec![0; n],
            waiting: vec![false; n],
            stop_left: vec![0; n],
            log: Vec::new(),
        }
    }

    fn ready(&self) -> Vec<usize> {
        (0..self.scripts.len())
            .filter(|&d| !self.waiting[d] && self.cursor[d] < self.scripts[d].len())
            .collect()
    }

    fn send(&mut self, d: usize) {
        let k = self.cursor[d];
        self.cursor[d] += 1;
        if matches!(self.scripts[d][k], Op::Query | Op::Stop(_)) {
            self.waiting[d] = true;
        }
        self.ls.push(d, (d, k)).unwrap();
    }

    /// Does everything the lockstep allows.
    fn drain(&mut self) -> Next {
        loop {
            match self.ls.next() {
                Next::Process { drone } => {
                    let (d, k) = self.ls.pop(drone).unwrap();
                    assert_eq!(d, drone);
                    assert_eq!(self.ls.clock(d), self.ls.time());
                    self.log.push(Event::Processed(d, k, self.ls.time()));
                    match self.scripts[d][k] {
                        Op::Query => self.waiting[d] = false,
                        Op::Advance(ms) => self.ls.advance(d, ms).unwrap(),
                        Op::Stop(steps) => {
                            self.ls.begin_stop(d).unwrap();
                            self.stop_left[d] = steps;
                            self.finish_stops();
                        }
                    }
                }
                Next::Step => {
                    // T never passes a flying clock.
                    for d in 0..self.ls.drones() {
                        if self.ls.phase(d) == Phase::Flying {
                            assert!(self.ls.clock(d) > self.ls.time());
                        }
                    }
                    self.ls.stepped();
                    self.log.push(Event::Stepped(self.ls.time()));
                    for d in self.ls.stopping().collect::<Vec<_>>() {
                        self.stop_left[d] = self.stop_left[d].saturating_sub(1);
                    }
                    self.finish_stops();
                }
                other => return other,
            }
        }
    }

    fn finish_stops(&mut self) {
        for d in self.ls.stopping().collect::<Vec<_>>() {
            if self.stop_left[d] == 0 {
                let stop_time = self.ls.finish_stop(d).unwrap();
                self.waiting[d] = false;
                self.log.push(Event::Stopped(d, self.ls.time(), stop_time));
            }
        }
    }

    /// Runs the scripts to the end with this arrival order.
    fn run(mut self, arrival: &Arrival) -> Vec<Event> {
        let mut turn = 0usize;
        loop {
            let next = self.drain();
            let ready = self.ready();
            if ready.is_empty() {
                assert_eq!(next, Next::Finished, "deadlock: {:?}", self.log);
                return self.log;
            }
            let d = match arrival {
                Arrival::RoundRobin => ready[turn % ready.len()],
                Arrival::Slow(s) => match ready.iter().find(|&&d| d != *s) {
                    Some(&d) => d,
                    None => *s,
                },
                Arrival::Choices(c) => ready[c.get(turn).copied().unwrap_or(turn) % ready.len()],
            };
            turn += 1;
            self.send(d);
        }
    }
}

fn run(scripts: &[Vec<Op>], arrival: Arrival) -> Vec<Event> {
    Harness::new(scripts.to_vec()).run(&arrival)
}

use Event::{Processed as P, Stepped as S, Stopped};
use Op::{Advance as Adv, Query as Q, Stop as Stp};

#[test]
fn requests_are_processed_by_time_then_drone_order() {
    let scripts = vec![vec![Adv(32), Q, Stp(0)], vec![Q, Adv(32), Q, Stp(0)]];
    let expect = vec![
        P(0, 0, Millis(2000)),
        P(1, 0, Millis(2000)),
        P(1, 1, Millis(2000)),
        S(Millis(2032)),
        P(0, 1, Millis(2032)),
        P(0, 2, Millis(2032)),
        Stopped(0, Millis(2032), Millis(0)),
        P(1, 2, Millis(2032)),
        P(1, 3, Millis(2032)),
        Stopped(1, Millis(2032), Millis(0)),
    ];
    // Drone 1 first, drone 0 first, or one slow: one order.
    assert_eq!(run(&scripts, Arrival::RoundRobin), expect);
    assert_eq!(run(&scripts, Arrival::Slow(0)), expect);
    assert_eq!(run(&scripts, Arrival::Slow(1)), expect);
}

#[test]
fn a_busy_drone_holds_back_later_requests() {
    let mut ls: Lockstep<&str> = Lockstep::new(2, T0, Millis(TS));
    // Drone 1 asks at 2000; drone 0 is busy at 2000 and comes first.
    ls.push(1, "q").unwrap();
    assert_eq!(
        ls.next(),
        Next::Wait,
        "drone 0 (busy at 2000) may still send at 2000"
    );
    ls.push(0, "adv").unwrap();
    assert_eq!(ls.next(), Next::Process { drone: 0 });
    assert_eq!(ls.pop(0), Some("adv"));
    ls.advance(0, 32).unwrap();
    ls.push(0, "q").unwrap();
    // (2000, 1) before (2032, 0).
    assert_eq!(ls.next(), Next::Process { drone: 1 });
    assert_eq!(ls.pop(1), Some("q"));
    // Drone 1 is busy at 2000 again (its platform computes): drone 0's
    // request at 2032 waits, and the physics does not step.
    assert_eq!(ls.next(), Next::Wait);
    assert_eq!(ls.time(), T0);
    ls.push(1, "adv").unwrap();
    assert_eq!(ls.next(), Next::Process { drone: 1 });
    ls.pop(1);
    ls.advance(1, 64).unwrap();
    // Now every flying clock is past 2000: step once, then answer drone 0.
    assert_eq!(ls.next(), Next::Step);
    ls.stepped();
    assert_eq!(ls.next(), Next::Process { drone: 0 });
    assert_eq!(ls.time(), Millis(2032));
    assert_eq!(ls.pop(0), Some("q"));
    // Drone 1 (at 2064) is busy, drone 0 too: nothing to do.
    assert_eq!(ls.next(), Next::Wait);
}

#[test]
fn a_slow_platform_gives_the_same_order() {
    let scripts = vec![
        vec![Q, Adv(32), Adv(32), Q, Adv(64), Q, Stp(2)],
        vec![Q, Adv(96), Q, Adv(32), Q, Adv(32), Q, Stp(1)],
        vec![Adv(160), Q, Stp(3)],
    ];
    let reference = run(&scripts, Arrival::RoundRobin);
    for slow in 0..3 {
        assert_eq!(
            run(&scripts, Arrival::Slow(slow)),
            reference,
            "drone {slow} slow"
        );
    }
}

#[test]
fn stop_leaves_the_lockstep_and_answers_when_the_propellers_stopped() {
    // Drone 0 stops at 2000 (its propellers need 3 steps); drone 1 flies on.
    let scripts = vec![vec![Stp(3)], vec![Adv(32), Q, Adv(64), Q, Adv(32), Stp(0)]];
    let log = run(&scripts, Arrival::RoundRobin);
    assert_eq!(
        log,
        vec![
            P(0, 0, Millis(2000)),
            P(1, 0, Millis(2000)),
            S(Millis(2032)),
            P(1, 1, Millis(2032)),
            P(1, 2, Millis(2032)),
            S(Millis(2064)),
            S(Millis(2096)),
            Stopped(0, Millis(2096), Millis(96)),
            P(1, 3, Millis(2096)),
            P(1, 4, Millis(2096)),
            S(Millis(2128)),
            P(1, 5, Millis(2128)),
            Stopped(1, Millis(2128), Millis(0)),
        ]
    );
}

#[test]
fn with_no_drone_flying_the_world_steps_on_its_own() {
    let mut ls: Lockstep<()> = Lockstep::new(2, T0, Millis(TS));
    for d in 0..2 {
        ls.push(d, ()).unwrap();
        assert_eq!(ls.next(), Next::Process { drone: d });
        ls.pop(d);
        ls.begin_stop(d).unwrap();
    }
    assert_eq!(ls.stopping().collect::<Vec<_>>(), vec![0, 1]);
    assert_eq!(ls.next(), Next::Step);
    ls.stepped();
    assert_eq!(ls.finish_stop(1), Some(Millis(32)));
    assert_eq!(ls.phase(1), Phase::Done);
    assert_eq!(ls.next(), Next::Step);
    ls.stepped();
    assert_eq!(ls.finish_stop(0), Some(Millis(64)));
    assert_eq!(ls.finish_stop(0), None, "answered once");
    assert_eq!(ls.next(), Next::Finished);
}

#[test]
fn bad_requests_are_errors() {
    let mut ls: Lockstep<u8> = Lockstep::new(1, T0, Millis(TS));
    assert_eq!(
        ls.advance(0, 33),
        Err(LockstepError::NotMultiple {
            requested: 33,
            timestep: 32
        })
    );
    assert_eq!(ls.clock(0), T0, "nothing moved");
    ls.advance(0, 0).unwrap();
    assert_eq!(ls.clock(0), T0);
    // STOP with another request already queued behind it.
    ls.push(0, 1).unwrap();
    ls.push(0, 2).unwrap();
    ls.pop(0);
    assert_eq!(ls.begin_stop(0), Err(LockstepError::AfterStop));
    ls.pop(0);
    ls.begin_stop(0).unwrap();
    assert_eq!(ls.push(0, 3), Err(LockstepError::AfterStop));
    assert_eq!(ls.begin_stop(0), Err(LockstepError::AfterStop));
}

#[test]
fn one_drone_is_the_single_drone_world() {
    // Eager equivalent: each request is processed as it comes, the physics
    // catching up just before.
    let scripts = vec![vec![Q, Adv(32), Adv(32), Q, Adv(96), Q, Stp(2)]];
    assert_eq!(
        run(&scripts, Arrival::RoundRobin),
        vec![
            P(0, 0, Millis(2000)),
            P(0, 1, Millis(2000)),
            S(Millis(2032)),
            P(0, 2, Millis(2032)),
            S(Millis(2064)),
            P(0, 3, Millis(2064)),
            P(0, 4, Millis(2064)),
            S(Millis(2096)),
            S(Millis(2128)),
            S(Millis(2160)),
            P(0, 5, Millis(2160)),
            P(0, 6, Millis(2160)),
            S(Millis(2192)),
            S(Millis(2224)),
            Stopped(0, Millis(2224), Millis(64)),
        ]
    );
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        3 => Just(Op::Query),
        3 => (0u64..4).prop_map(|k| Op::Advance(k * TS)),
    ]
}

fn script() -> impl Strategy<Value = Vec<Op>> {
    (prop::collection::vec(op(), 0..12), 0u64..4).prop_map(|(mut ops, stop)| {
        ops.push(Op::Stop(stop));
        ops
    })
}

proptest! {
    /// The central promise of docs/SWARM.md §2: the world's order is a
    /// function of the scripts only, never of the order of arrival.
    #[test]
    fn the_order_of_arrival_does_not_matter(
        scripts in prop::collection::vec(script(), 1..5),
        choices in prop::collection::vec(0usize..8, 0..80),
    ) {
        let reference = run(&scripts, Arrival::RoundRobin);
        prop_assert_eq!(&run(&scripts, Arrival::Choices(choices)), &reference);
        prop_assert_eq!(&run(&scripts, Arrival::Slow(0)), &reference);
        // Every op was processed once, every drone stopped once.
        let processed = reference.iter().filter(|e| matches!(e, Event::Processed(..))).count();
        prop_assert_eq!(processed, scripts.iter().map(Vec::len).sum::<usize>());
        let stopped = reference.iter().filter(|e| matches!(e, Event::Stopped(..))).count();
        prop_assert_eq!(stopped, scripts.len());
        // Processing times never decrease per drone and each is the drone's
        // clock: the sum of its advances so far.
        for (d, s) in scripts.iter().enumerate() {
            let mut clock = T0;
            for e in &reference {
                if let Event::Processed(dd, k, t) = *e {
                    if dd == d {
                        prop_assert_eq!(t, clock);
                        if let Op::Advance(ms) = s[k] { clock += Millis(ms); }
                    }
                }
            }
        }
    }
}
