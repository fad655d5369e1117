//! The conservative lockstep of several drones (DESIGN.md §7, docs/SWARM.md
//! §2), as pure logic: no sockets, no physics. The server feeds it the
//! requests as they arrive and asks it what to do next.
//!
//! Each drone d has a clock t_d (world ms) and a queue of requests received
//! but not processed. A flying drone whose queue is empty is *busy*: its
//! platform is computing and its next request will have a time ≥ t_d. The
//! time of a request is its drone's clock when it is processed. The head
//! request with the smallest key (t, i) is processed only when every busy
//! drone j has (t_j, j) > (t, i); before it is, the physics steps (one
//! basicTimeStep at a time, when a request needs it or as soon as every
//! flying clock is past T) until the world time T equals t. So every
//! change to the world happens in (time, drone order) whatever the order in
//! which the requests arrived, and T never passes a flying drone's clock.
//!
//! This order is the order of every *change* of the world (motor targets,
//! transmissions, STOP, failures) and of the world's trace. A *query* needs
//! less (DESIGN.md §15): it reads the world at T, which no change made at T
//! can alter (motor targets act from the next step on, a transmission
//! started at T ends after T), so the session answers a query as soon as
//! its time equals T, before its turn; its turn then only writes its trace
//! lines. So a busy drone never holds back another drone's reply at the
//! same time, and one thread may drive several drones.
//!
//! STOP takes a drone out of the lockstep (it never holds the world back
//! again); it is *stopping* until the server reports its propellers stopped.
//! When no drone is flying, the world steps on its own for the stopping ones.

use std::collections::VecDeque;

use crate::time::Millis;

/// Where a drone is in its run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// In the lockstep: its clock holds the world back.
    Flying,
    /// STOP processed at `since`; waiting for its propellers to stop.
    Stopping { since: Millis },
    /// Its STOP was answered.
    Done,
}

/// What the server must do next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    /// Process the head request of this drone ([`Lockstep::pop`]); the
    /// world time equals the drone's clock.
    Process { drone: usize },
    /// Step the physics one basicTimeStep, then call [`Lockstep::stepped`].
    Step,
    /// Nothing can happen before another request arrives.
    Wait,
    /// Every drone is done.
    Finished,
}

/// A request the lockstep cannot accept.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LockstepError {
    #[error("cannot advance {requested} ms: not a multiple of the {timestep} ms timestep")]
    NotMultiple { requested: u64, timestep: u64 },
    #[error("a request after STOP")]
    AfterStop,
}

#[derive(Debug)]
struct Slot<R> {
    clock: Millis,
    queue: VecDeque<R>,
    phase: Phase,
}

/// The scheduler: per-drone clocks and queues of requests `R`.
#[derive(Debug)]
pub struct Lockstep<R> {
    timestep: Millis,
    /// The physics time T.
    time: Millis,
    slots: Vec<Slot<R>>,
}

impl<R> Lockstep<R> {
    /// `drones` drones, every clock and the world at `start` (the end of the
    /// warm-up), stepping `timestep` at a time.
    pub fn new(drones: usize, start: Millis, timestep: Millis) -> Lockstep<R> {
        assert!(timestep.0 > 0, "the timestep is at least 1 ms");
        Lockstep {
            timestep,
            time: start,
            slots: (0..drones)
                .map(|_| Slot {
                    clock: start,
                    queue: VecDeque::new(),
                    phase: Phase::Flying,
                })
                .collect(),
        }
    }

    pub fn drones(&self) -> usize {
        self.slots.len()
    }

    /// The physics time T.
    pub fn time(&self) -> Millis {
        self.time
    }

    /// Drone `d`'s clock t_d.
    pub fn clock(&self, d: usize) -> Millis {
        self.slots[d].clock
    }

    pub fn phase(&self, d: usize) -> Phase {
        self.slots[d].phase
    }

    /// Requests of drone `d` received and not processed yet.
    pub fn queued(&self, d: usize) -> usize {
        self.slots[d].queue.len()
    }

    /// Drone `d`'s `k`-th request not processed yet (0: its head).
    pub fn queued_at(&self, d: usize, k: usize) -> Option<&R> {
        self.slots[d].queue.get(k)
    }

    /// The same, to mark it (the session marks a query answered early,
    /// DESIGN.md §15); the canonical order does not change.
    pub fn queued_at_mut(&mut self, d: usize, k: usize) -> Option<&mut R> {
        self.slots[d].queue.get_mut(k)
    }

    /// The drones that are stopping, in world-file order.
    pub fn stopping(&self) -> impl Iterator<Item = usize> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s.phase, Phase::Stopping { .. }))
            .map(|(i, _)| i)
    }

    /// A request of drone `d` arrived. A drone that has sent STOP sends
    /// nothing more.
    pub fn push(&mut self, d: usize, request: R) -> Result<(), LockstepError> {
        let s = &mut self.slots[d];
        if s.phase != Phase::Flying {
            return Err(LockstepError::AfterStop);
        }
        s.queue.push_back(request);
        Ok(())
    }

    /// What to do next (see the module's rules).
    pub fn next(&self) -> Next {
        // Smallest key among the heads, smallest key among the busy drones.
        let mut head: Option<(Millis, usize)> = None;
        let mut busy: Option<(Millis, usize)> = None;
        let (mut flying, mut stopping) = (false, false);
        // The smallest clock of a flying drone.
        let mut earliest: Option<Millis> = None;
        for (i, s) in self.slots.iter().enumerate() {
            match s.phase {
                Phase::Flying => {
                    flying = true;
                    earliest = Some(earliest.map_or(s.clock, |e| e.min(s.clock)));
                    let key = Some((s.clock, i));
                    let slot = if s.queue.is_empty() {
                        &mut busy
                    } else {
                        &mut head
                    };
                    // Keys grow with i, so the first one of a clock wins.
                    if slot.is_none() || key < *slot {
                        *slot = key;
                    }
                }
                Phase::Stopping { .. } => stopping = true,
                Phase::Done => {}
            }
        }
        match head {
            Some(key) if busy.is_none_or(|b| b > key) => {
                let (t, drone) = key;
                debug_assert!(t >= self.time, "a request in the world's past");
                if self.time < t {
                    Next::Step
                } else {
                    Next::Process { drone }
                }
            }
            // The head waits for a busy drone, but every flying clock is
            // past T: the physics may step (nothing can happen at T any
            // more), so that queries at the new T are answered before
            // their turn (DESIGN.md §15). The same steps, in the same
            // place among the requests, as stepping lazily.
            Some(_) if earliest.is_some_and(|e| e > self.time) => Next::Step,
            Some(_) => Next::Wait,
            None if flying => Next::Wait,
            None if stopping => Next::Step,
            None => Next::Finished,
        }
    }

    /// Takes drone `d`'s head request for processing (after
    /// [`Next::Process`]).
    pub fn pop(&mut self, d: usize) -> Option<R> {
        self.slots[d].queue.pop_front()
    }

    /// SET_VELOCITY / ADVANCE_TIME of drone `d`: its clock moves `ms` on
    /// (a multiple of the timestep; 0 is allowed and moves nothing).
    pub fn advance(&mut self, d: usize, ms: u64) -> Result<(), LockstepError> {
        let ts = self.timestep.0;
        if !ms.is_multiple_of(ts) {
            return Err(LockstepError::NotMultiple {
                requested: ms,
                timestep: ts,
            });
        }
        self.slots[d].clock += Millis(ms);
        Ok(())
    }

    /// The physics stepped one basicTimeStep.
    pub fn stepped(&mut self) {
        self.time += self.timestep;
    }

    /// STOP of drone `d`, processed at its clock: it leaves the lockstep.
    /// Requests it sent after STOP are an error.
    pub fn begin_stop(&mut self, d: usize) -> Result<(), LockstepError> {
        let s = &mut self.slots[d];
        if s.phase != Phase::Flying || !s.queue.is_empty() {
            return Err(LockstepError::AfterStop);
        }
        s.phase = Phase::Stopping { since: s.clock };
        Ok(())
    }

    /// Drone `d`'s propellers have stopped at the current world time: its
    /// STOP is answered. Returns STOP_TIME (T − the STOP's time); `None` if
    /// the drone was not stopping.
    pub fn finish_stop(&mut self, d: usize) -> Option<Millis> {
        let s = &mut self.slots[d];
        match s.phase {
            Phase::Stopping { since } => {
                s.phase = Phase::Done;
                s.clock = self.time;
                Some(Millis(self.time.0 - since.0))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;
