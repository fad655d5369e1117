//! The cluster's event unit (docs/CLUSTER.md "EU"): per-core event masks
//! and buffers, wait-for-event with the core's clock gated, one barrier,
//! one mutex and the dispatch FIFOs (the GAP8 event unit's blocks, gap_sdk
//! `archi/chips/gap/memory_map.h` `ARCHI_EU_OFFSET`, with our layout).
//!
//! A read that must wait returns [`Eu::Sleep`]: the bus answers
//! [`MmioError::Wait`](crate::iss::MmioError::Wait), the core stops with
//! its pc on the load and the scheduler gates it. When the condition
//! becomes true at time `t` (another core's access, a DMA completion) the
//! unit records a wake-up at `t +` [`WAKE_LATENCY_CYCLES`]; the core
//! retries the load then, and the retry completes (a woken barrier or
//! mutex waiter remembers it was released, so its retry does not arrive
//! or queue again).

use std::collections::VecDeque;

use super::MAX_CORES;
use crate::units::Picos;

/// Cycles from the event that releases a sleeping core to the core's next
/// instruction: the event unit raises the core's clock enable one cycle
/// after the event and the core re-executes the load in the next (PULP
/// event unit: a waiting core's `p.elw` completes "as soon as" the event
/// arrives; the two cycles of clock-enable propagation and load replay are
/// our assumption, documented in docs/CLUSTER.md).
pub const WAKE_LATENCY_CYCLES: u64 = 2;

/// Depth of each core's dispatch FIFO (docs/CLUSTER.md).
pub const DISPATCH_DEPTH: usize = 8;

/// The DMA completion event (docs/CLUSTER.md: bit 8).
pub const EVENT_DMA: u32 = 8;

/// The mailbox event (docs/CLUSTER.md: bit 9): set in core 0's buffer
/// when the FC writes a task to CTRL's `MAILBOX`, so core 0 waits for its
/// next task asleep, clock-gated, as DESIGN.md §12 asks of an idle core
/// (the GAP8's FC reaches the cluster's event unit through its software
/// event lines; gap_sdk's cluster runtime waits for tasks the same way).
pub const EVENT_MAILBOX: u32 = 9;

pub const EVT_MASK: u32 = 0x00;
pub const EVT_BUFFER: u32 = 0x04;
pub const EVT_WAIT: u32 = 0x08;
pub const EVT_WAIT_CLR: u32 = 0x0C;
pub const EVT_CLEAR: u32 = 0x10;
pub const CORE_ID: u32 = 0x14;
pub const SW_EVT_TRIG: u32 = 0x40;
pub const BARRIER_SETUP: u32 = 0x80;
pub const BARRIER_WAIT: u32 = 0x84;
pub const MUTEX_LOCK: u32 = 0x88;
pub const MUTEX_UNLOCK: u32 = 0x8C;
pub const TEAM_CONFIG: u32 = 0x90;
pub const DISPATCH_PUSH: u32 = 0x94;
pub const DISPATCH_POP: u32 = 0x98;

/// What a sleeping core waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sleep {
    Event,
    Barrier,
    Mutex,
    Pop,
    Push,
}

/// An access the unit cannot complete now: the core sleeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Eu {
    Sleep,
    /// No such register, or not with this access.
    Fault,
}

/// The event unit of a cluster of `n` cores.
#[derive(Debug, Clone)]
pub struct EventUnit {
    n: usize,
    all: u32,
    latency: Picos,
    mask: [u32; MAX_CORES],
    buffer: [u32; MAX_CORES],
    sleep: [Option<Sleep>; MAX_CORES],
    /// Released sleepers: the time their retry may happen.
    wake_at: [Option<Picos>; MAX_CORES],
    barrier_team: u32,
    barrier_arrived: u32,
    /// Arrived cores already released by the barrier (their retry returns).
    barrier_released: u32,
    mutex_owner: Option<usize>,
    mutex_waiters: u32,
    /// The mutex was handed to this core while it slept.
    mutex_granted: u32,
    team: u32,
    fifo: [VecDeque<u32>; MAX_CORES],
}

impl EventUnit {
    /// `period`: the cluster clock's period (the wake-up latency's unit).
    pub fn new(n: usize, period: Picos) -> EventUnit {
        let all = ((1u32 << n) - 1) & 0xff;
        EventUnit {
            n,
            all,
            latency: Picos(period.0 * WAKE_LATENCY_CYCLES),
            mask: [0; MAX_CORES],
            buffer: [0; MAX_CORES],
            sleep: [None; MAX_CORES],
            wake_at: [None; MAX_CORES],
            barrier_team: all,
            barrier_arrived: 0,
            barrier_released: 0,
            mutex_owner: None,
            mutex_waiters: 0,
            mutex_granted: 0,
            team: all,
            fifo: Default::default(),
        }
    }

    /// Whether core `i` sleeps in the unit.
    /// A released core: the time it wakes (taken once).
    pub fn take_wake(&mut self, i: usize) -> Option<Picos> {
        self.wake_at[i].take()
    }

    /// Forget core `i`'s waits and queued words (it was halted or
    /// restarted).
    pub fn reset_core(&mut self, i: usize) {
        self.sleep[i] = None;
        self.wake_at[i] = None;
        self.buffer[i] = 0;
        self.mask[i] = 0;
        self.fifo[i].clear();
        let bit = 1 << i;
        self.barrier_arrived &= !bit;
        self.barrier_released &= !bit;
        self.mutex_waiters &= !bit;
        self.mutex_granted &= !bit;
        if self.mutex_owner == Some(i) {
            self.mutex_owner = None;
        }
    }

    /// Wake core `j` (asleep outside the unit's own conditions: the DMA
    /// queue had no room) at `t`.
    pub fn release(&mut self, j: usize, t: Picos) {
        self.wake(j, t);
    }

    fn wake(&mut self, j: usize, t: Picos) {
        self.sleep[j] = None;
        self.wake_at[j] = Some(t + self.latency);
    }

    /// Wake the cores sleeping on their events whose buffer now matches.
    fn check_events(&mut self, t: Picos) {
        for j in 0..self.n {
            if self.sleep[j] == Some(Sleep::Event) && self.buffer[j] & self.mask[j] != 0 {
                self.wake(j, t);
            }
        }
    }

    /// Set event `e` in the buffers of the cores of `cores` at time `t`.
    pub fn trigger(&mut self, e: u32, cores: u32, t: Picos) {
        for j in 0..self.n {
            if cores & (1 << j) != 0 {
                self.buffer[j] |= 1 << e;
            }
        }
        self.check_events(t);
    }

    /// A 32-bit read by core `i` at time `t`.
    pub fn read(&mut self, i: usize, off: u32, t: Picos) -> Result<u32, Eu> {
        let bit = 1u32 << i;
        match off {
            EVT_MASK => Ok(self.mask[i]),
            EVT_BUFFER => Ok(self.buffer[i]),
            EVT_WAIT | EVT_WAIT_CLR => {
                let hit = self.buffer[i] & self.mask[i];
                if hit == 0 {
                    self.sleep[i] = Some(Sleep::Event);
                    return Err(Eu::Sleep);
                }
                if off == EVT_WAIT_CLR {
                    self.buffer[i] &= !hit;
                }
                Ok(hit)
            }
            CORE_ID => Ok(i as u32),
            BARRIER_WAIT => {
                if self.barrier_released & bit != 0 {
                    self.barrier_released &= !bit;
                    return Ok(0);
                }
                self.barrier_arrived |= bit;
                if self.barrier_arrived & self.barrier_team == self.barrier_team {
                    // The last arrival: release the others, go on.
                    let others = self.barrier_arrived & !bit;
                    self.barrier_arrived = 0;
                    for j in 0..self.n {
                        if others & (1 << j) != 0 {
                            self.barrier_released |= 1 << j;
                            self.wake(j, t);
                        }
                    }
                    return Ok(0);
                }
                self.sleep[i] = Some(Sleep::Barrier);
                Err(Eu::Sleep)
            }
            MUTEX_LOCK => {
                if self.mutex_granted & bit != 0 {
                    self.mutex_granted &= !bit;
                    return Ok(0);
                }
                if self.mutex_owner.is_none() {
                    self.mutex_owner = Some(i);
                    return Ok(0);
                }
                self.mutex_waiters |= bit;
                self.sleep[i] = Some(Sleep::Mutex);
                Err(Eu::Sleep)
            }
            DISPATCH_POP => match self.fifo[i].pop_front() {
                Some(v) => {
                    for j in 0..self.n {
                        if self.sleep[j] == Some(Sleep::Push) {
                            self.wake(j, t);
                        }
                    }
                    Ok(v)
                }
                None => {
                    self.sleep[i] = Some(Sleep::Pop);
                    Err(Eu::Sleep)
                }
            },
            _ => Err(Eu::Fault),
        }
    }

    /// A 32-bit write by core `i` at time `t`.
    pub fn write(&mut self, i: usize, off: u32, v: u32, t: Picos) -> Result<(), Eu> {
        match off {
            EVT_MASK => {
                self.mask[i] = v;
            }
            EVT_CLEAR => self.buffer[i] &= !v,
            o if (SW_EVT_TRIG..SW_EVT_TRIG + 32).contains(&o) && o % 4 == 0 => {
                self.trigger((o - SW_EVT_TRIG) / 4, v & self.all, t);
            }
            BARRIER_SETUP => {
                self.barrier_team = v & self.all;
                self.barrier_arrived = 0;
            }
            MUTEX_UNLOCK => {
                if self.mutex_owner != Some(i) {
                    return Ok(()); // not the owner: ignored, as a stray unlock
                }
                // Hand over to the next waiter after the unlocker (round
                // robin), which then holds it when its retry happens.
                let next = (1..=self.n)
                    .map(|k| (i + k) % self.n)
                    .find(|&j| self.mutex_waiters & (1 << j) != 0);
                self.mutex_owner = next;
                if let Some(j) = next {
                    self.mutex_waiters &= !(1 << j);
                    self.mutex_granted |= 1 << j;
                    self.wake(j, t);
                }
            }
            TEAM_CONFIG => self.team = v & self.all,
            DISPATCH_PUSH => {
                let team = self.team;
                let targets = (0..self.n).filter(|j| team & (1 << j) != 0);
                if targets
                    .clone()
                    .any(|j| self.fifo[j].len() >= DISPATCH_DEPTH)
                {
                    self.sleep[i] = Some(Sleep::Push);
                    return Err(Eu::Sleep);
                }
                for j in targets {
                    self.fifo[j].push_back(v);
                    if self.sleep[j] == Some(Sleep::Pop) {
                        self.wake(j, t);
                    }
                }
            }
            _ => return Err(Eu::Fault),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barrier_releases_the_others_at_the_last_arrival() {
        let mut eu = EventUnit::new(3, Picos(10));
        assert_eq!(eu.read(0, BARRIER_WAIT, Picos(100)), Err(Eu::Sleep));
        assert_eq!(eu.read(2, BARRIER_WAIT, Picos(150)), Err(Eu::Sleep));
        assert_eq!(eu.read(1, BARRIER_WAIT, Picos(300)), Ok(0));
        assert_eq!(eu.take_wake(0), Some(Picos(320)));
        assert_eq!(eu.take_wake(2), Some(Picos(320)));
        // The retries complete without arriving again.
        assert_eq!(eu.read(0, BARRIER_WAIT, Picos(320)), Ok(0));
        assert_eq!(eu.read(2, BARRIER_WAIT, Picos(320)), Ok(0));
        assert_eq!(eu.read(0, BARRIER_WAIT, Picos(400)), Err(Eu::Sleep));
    }

    #[test]
    fn mutex_is_handed_round_robin() {
        let mut eu = EventUnit::new(4, Picos(1));
        assert_eq!(eu.read(1, MUTEX_LOCK, Picos(0)), Ok(0));
        assert_eq!(eu.read(0, MUTEX_LOCK, Picos(1)), Err(Eu::Sleep));
        assert_eq!(eu.read(3, MUTEX_LOCK, Picos(1)), Err(Eu::Sleep));
        eu.write(1, MUTEX_UNLOCK, 0, Picos(5)).unwrap();
        assert_eq!(eu.take_wake(3), Some(Picos(7)));
        assert_eq!(eu.take_wake(0), None);
        assert_eq!(eu.read(3, MUTEX_LOCK, Picos(7)), Ok(0));
    }
}
