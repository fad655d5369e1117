//! The cluster's L1 (TCDM, DESIGN.md §12): 64 KiB at 0x1000_0000 in 16
//! word-interleaved banks (bank = `(addr >> 2) & 15`: the PULP cluster's
//! logarithmic interconnect, 16 banks of 4 KiB on the GAP8). Each bank
//! serves one access per cluster cycle; a core asking for a bank already
//! granted in that cycle waits one cycle and asks again (the stall is
//! added to its load or store).
//!
//! # Why the counts are exact and deterministic
//!
//! Every access carries its exact cluster cycle (the core's issue cycle).
//! The arbiter keeps, for each cycle of a sliding window of [`WINDOW`]
//! cycles, which banks were granted in it: one 16-bit mask per cycle, at
//! `cycle % WINDOW`. An access at cycle `c` takes the first cycle `g >= c`
//! whose mask does not hold its bank and stalls `g - c`. The cluster
//! scheduler (`mod.rs`) runs the cores one after another in quanta (at
//! most [`super::QUANTUM_CYCLES`] ahead of the slowest runnable one, in a
//! fixed order) and tells the arbiter, before each core's turn, the
//! slowest runnable core's cycle ([`Tcdm::retire`]): no access is issued
//! below it any more, so the masks of the cycles before it are cleared
//! for the cycles a window later. The window (four quanta) therefore
//! always holds every cycle a core may still reach, and only those.
//! What the quantum decides is only *which* of two cores that ask for one
//! bank in one cycle wins: the one the scheduler runs first in that
//! quantum, and the scheduler rotates that order every quantum (round
//! robin per quantum rather than per cycle). The number of stalled cycles
//! of a saturated bank, and everything else, is the same on every host.
//!
//! A mask per cycle (rather than a bit per cycle per bank) makes a grant
//! one load, one bit test and one store at an index the cycle alone gives,
//! which the block translator emits inline (`iss/jit/emit/mem.rs`): the
//! network's inner loop makes six L1 accesses per eight dot products.

use crate::iss::l1::{BankArbiter, GrantWindow};
pub use crate::iss::l1::{PortStats, BANKS, WINDOW};

/// L1 base address and size (DESIGN.md §12, docs/CLUSTER.md).
pub const L1_BASE: u32 = 0x1000_0000;
pub const L1_SIZE: u32 = 64 * 1024;
// The cycles the arbiter remembers ([`WINDOW`]) must exceed the spread
// between the fastest and the slowest runnable core (quantum plus one
// instruction's overshoot), see `mod.rs`.
const _: () = assert!(WINDOW >= 4 * super::QUANTUM_CYCLES);

/// Ports of the arbiter: cluster cores 0..8 (statistics are per port).
pub const PORTS: usize = 8;

/// The bank arbiter.
#[derive(Debug, Clone)]
pub struct Tcdm {
    /// Per cycle of the window, at `cycle % WINDOW`, the banks granted in
    /// it (bit `b`: bank `b`).
    granted: Box<[u16; WINDOW as usize]>,
    /// No access is issued below this cycle any more ([`Tcdm::retire`]);
    /// the masks of the cycles before it are clear.
    floor: u64,
    pub stats: [PortStats; PORTS],
}

impl Default for Tcdm {
    fn default() -> Self {
        Tcdm {
            granted: Box::new([0; WINDOW as usize]),
            floor: 0,
            stats: [PortStats::default(); PORTS],
        }
    }
}

impl Tcdm {
    /// The bank of an L1 address.
    #[inline(always)]
    pub fn bank(addr: u32) -> usize {
        ((addr >> 2) as usize) & (BANKS - 1)
    }

    /// No access will be issued below cycle `floor` from now on (the
    /// scheduler's slowest runnable core): clear the masks of the cycles
    /// from the last floor to this one, which the cycles a window later
    /// reuse. A floor below the last one changes nothing.
    pub fn retire(&mut self, floor: u64) {
        if floor <= self.floor {
            return;
        }
        if floor - self.floor >= WINDOW {
            self.granted.fill(0);
        } else {
            let (a, b) = ((self.floor % WINDOW) as usize, (floor % WINDOW) as usize);
            if a < b {
                self.granted[a..b].fill(0);
            } else {
                self.granted[a..].fill(0);
                self.granted[..b].fill(0);
            }
        }
        self.floor = floor;
    }

    /// An access by `port` to `addr` issued at cluster cycle `cycle`: the
    /// stall cycles until its bank grants it.
    #[inline]
    pub fn access(&mut self, port: u8, addr: u32, cycle: u64) -> u64 {
        debug_assert!(
            cycle >= self.floor && cycle - self.floor < WINDOW,
            "an L1 access at cycle {cycle} outside the arbiter's window from {}",
            self.floor
        );
        let bank = 1u16 << Self::bank(addr);
        let mut g = cycle;
        while self.granted[(g % WINDOW) as usize] & bank != 0 {
            g += 1;
        }
        self.granted[(g % WINDOW) as usize] |= bank;
        let stall = g - cycle;
        let s = &mut self.stats[port as usize % PORTS];
        s.accesses += 1;
        s.stall_cycles += stall;
        stall
    }
}

/// The ISS's view of the arbiter (`iss::l1`).
impl BankArbiter for Tcdm {
    #[inline]
    fn access(&mut self, port: u8, addr: u32, cycle: u64) -> u64 {
        Tcdm::access(self, port, addr, cycle)
    }

    fn port_stats(&self, port: u8) -> PortStats {
        self.stats[port as usize % PORTS]
    }

    fn grant_window(&mut self, port: u8) -> GrantWindow {
        GrantWindow {
            masks: self.granted.as_mut_ptr(),
            port: &mut self.stats[port as usize % PORTS],
        }
    }

    fn retire(&mut self, floor: u64) {
        Tcdm::retire(self, floor);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_bank_same_cycle_waits_other_banks_do_not() {
        let mut t = Tcdm::default();
        assert_eq!(t.access(0, L1_BASE, 10), 0);
        assert_eq!(t.access(1, L1_BASE + 64, 10), 1); // bank 0 again
        assert_eq!(t.access(2, L1_BASE + 4, 10), 0); // bank 1
        assert_eq!(t.access(3, L1_BASE, 10), 2);
        assert_eq!(t.stats[3].stall_cycles, 2);
        // Cycles 11 and 12 of bank 0 are taken.
        assert_eq!(t.access(4, L1_BASE, 11), 2);
        // Once the scheduler retires cycles 0..12, a cycle a window later
        // reuses their slots: free again (cycles 12 and 13 stay taken).
        t.retire(12);
        assert_eq!(t.access(4, L1_BASE, 10 + WINDOW), 0);
        assert_eq!(t.access(5, L1_BASE, 10 + WINDOW), 1);
        assert_eq!(t.access(6, L1_BASE, 12), 2);
        t.retire(5 * WINDOW);
        assert_eq!(t.access(7, L1_BASE, 5 * WINDOW + 11), 0);
    }
}
