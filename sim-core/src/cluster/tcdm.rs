//! The cluster's L1 (TCDM, DESIGN.md §12): 64 KiB at 0x1000_0000 in 16
//! word-interleaved banks (bank = `(addr >> 2) & 15`, as the PULP cluster's
//! logarithmic interconnect and gap_sdk `ARCHI_TCDM_NB_BANKS`... the GAP8
//! has 16 banks of 4 KiB). Each bank serves one access per cluster cycle;
//! a core asking for a bank already granted in that cycle waits one cycle
//! and asks again (the stall is added to its load or store).
//!
//! # Why the counts are exact and deterministic
//!
//! Every access carries its exact cluster cycle (the core's issue cycle).
//! The arbiter keeps, per bank, one bit per cycle of a sliding window:
//! "granted in this cycle". An access at cycle `c` takes the first free
//! cycle `g >= c` of its bank and stalls `g - c`. The cluster scheduler
//! (`mod.rs`) runs the cores one after another in quanta (at most
//! [`super::QUANTUM_CYCLES`] ahead of the slowest runnable one, in a fixed
//! order), so a bank's bits for a cycle are always filled before any later
//! core asks for it, and the window ([`WINDOW`] cycles, twice the quantum
//! plus margin) never drops a cycle a core may still reach. What the
//! quantum decides is only *which* of two cores that ask for one bank in
//! one cycle wins: the one the scheduler runs first in that quantum, and
//! the scheduler rotates that order every quantum (round robin per
//! quantum rather than per cycle). The number of stalled cycles of a
//! saturated bank, and everything else, is the same on every host.

/// Banks of the L1 (GAP8: 16 banks, gap_sdk `ARCHI_CLUSTER_NB_TCDM_BANKS`...
/// the interleaving is one 32-bit word per bank).
pub const BANKS: usize = 16;
/// L1 base address and size (DESIGN.md §12, docs/CLUSTER.md).
pub const L1_BASE: u32 = 0x1000_0000;
pub const L1_SIZE: u32 = 64 * 1024;
/// Cycles the arbiter remembers; must exceed the spread between the
/// fastest and the slowest runnable core (quantum plus one instruction's
/// overshoot), see `mod.rs`.
pub const WINDOW: u64 = 4096;
const WORDS: usize = (WINDOW / 64) as usize;

/// Ports of the arbiter: cluster cores 0..8 (statistics are per port).
pub const PORTS: usize = 8;

/// Per-port counts of the L1 (for `--stats` and the power model).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PortStats {
    pub accesses: u64,
    pub stall_cycles: u64,
}

/// The bank arbiter.
#[derive(Debug, Clone)]
pub struct Tcdm {
    /// Per bank, one bit per cycle `c` at `c % WINDOW`, for cycles in
    /// `[floor, floor + WINDOW)`.
    granted: Box<[[u64; WORDS]; BANKS]>,
    /// Cycles below are forgotten (every future access is at or after it).
    floor: u64,
    pub stats: [PortStats; PORTS],
}

impl Default for Tcdm {
    fn default() -> Self {
        Tcdm {
            granted: Box::new([[0; WORDS]; BANKS]),
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

    /// An access by `port` to `addr` issued at cluster cycle `cycle`: the
    /// stall cycles until its bank grants it.
    #[inline]
    pub fn access(&mut self, port: u8, addr: u32, cycle: u64) -> u64 {
        let bank = &mut self.granted[Self::bank(addr)];
        let mut g = cycle.max(self.floor);
        debug_assert!(
            cycle + WINDOW / 2 > self.floor,
            "access below the arbiter's floor"
        );
        while g < self.floor + WINDOW {
            let (w, b) = (((g % WINDOW) / 64) as usize, g % 64);
            if bank[w] & (1 << b) == 0 {
                bank[w] |= 1 << b;
                break;
            }
            g += 1;
        }
        let stall = g - cycle;
        let s = &mut self.stats[port as usize % PORTS];
        s.accesses += 1;
        s.stall_cycles += stall;
        stall
    }

    /// Forget the cycles below `floor` (no core can access before it).
    pub fn retire_below(&mut self, floor: u64) {
        if floor <= self.floor {
            return;
        }
        if floor - self.floor >= WINDOW {
            for bank in self.granted.iter_mut() {
                *bank = [0; WORDS];
            }
        } else {
            for c in self.floor..floor {
                let (w, b) = (((c % WINDOW) / 64) as usize, c % 64);
                for bank in self.granted.iter_mut() {
                    bank[w] &= !(1 << b);
                }
            }
        }
        self.floor = floor;
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
        t.retire_below(11);
        // Cycle 11 and 12 of bank 0 are still taken.
        assert_eq!(t.access(4, L1_BASE, 11), 2);
        t.retire_below(10_000);
        assert_eq!(t.access(4, L1_BASE, 10_000), 0);
    }
}
