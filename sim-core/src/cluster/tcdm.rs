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
//! The arbiter keeps, per bank, one bit per cycle of a sliding window:
//! "granted in this cycle" (slices of 64 cycles tagged with their number,
//! so a slot from a window ago reads as free without being cleared). An
//! access at cycle `c` takes the first free cycle `g >= c` of its bank and
//! stalls `g - c`. The cluster scheduler (`mod.rs`) runs the cores one
//! after another in quanta (at most [`super::QUANTUM_CYCLES`] ahead of the
//! slowest runnable one, in a fixed order), so the window ([`WINDOW`]
//! cycles, four quanta) always holds every cycle a core may still reach.
//! What the quantum decides is only *which* of two cores that ask for one
//! bank in one cycle wins: the one the scheduler runs first in that
//! quantum, and the scheduler rotates that order every quantum (round
//! robin per quantum rather than per cycle). The number of stalled cycles
//! of a saturated bank, and everything else, is the same on every host.

/// Banks of the L1 (GAP8: 16, one 32-bit word per bank in turn).
pub const BANKS: usize = 16;
/// L1 base address and size (DESIGN.md §12, docs/CLUSTER.md).
pub const L1_BASE: u32 = 0x1000_0000;
pub const L1_SIZE: u32 = 64 * 1024;
/// Cycles the arbiter remembers; must exceed the spread between the
/// fastest and the slowest runnable core (quantum plus one instruction's
/// overshoot), see `mod.rs`.
pub const WINDOW: u64 = 4096;
/// Slices per bank.
pub(crate) const WORDS: usize = (WINDOW / 64) as usize;
const _: () = assert!(WORDS.is_power_of_two() && BANKS.is_power_of_two());

/// Ports of the arbiter: cluster cores 0..8 (statistics are per port).
pub const PORTS: usize = 8;

/// Per-port counts of the L1 (for `--stats` and the power model).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PortStats {
    pub accesses: u64,
    pub stall_cycles: u64,
}

/// One 64-cycle slice of a bank's grants: which cycles of slice `tag`
/// (cycle / 64) are taken. A slot holding another slice is stale (older
/// than the window) and reads as free, so nothing ever has to be cleared.
/// `repr(C)`: the block translator reads and sets it in place
/// ([`Tcdm::raw_parts`]).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C)]
struct Slice {
    tag: u64,
    bits: u64,
}

/// The bank arbiter.
#[derive(Debug, Clone)]
pub struct Tcdm {
    /// Per bank, the slices of the last [`WINDOW`] cycles, slice `k` at
    /// `k % (WINDOW / 64)`.
    granted: Box<[[Slice; WORDS]; BANKS]>,
    pub stats: [PortStats; PORTS],
}

impl Default for Tcdm {
    fn default() -> Self {
        Tcdm {
            granted: Box::new([[Slice::default(); WORDS]; BANKS]),
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

    /// For the block translator's inline grant (`iss/jit/emit.rs`): the
    /// slices, `BANKS × WINDOW/64` [`Slice`]s of `{tag: u64, bits: u64}`,
    /// bank-major, and `port`'s counts, to which the core adds what the
    /// run granted and stalled. Translated code does in the slices exactly
    /// what [`Tcdm::access`] does (and calls `access` when a conflict's
    /// search leaves the slice).
    pub(crate) fn raw_parts(&mut self, port: u8) -> (*mut u64, *mut PortStats) {
        (
            self.granted.as_mut_ptr() as *mut u64,
            &mut self.stats[port as usize % PORTS],
        )
    }

    /// An access by `port` to `addr` issued at cluster cycle `cycle`: the
    /// stall cycles until its bank grants it.
    #[inline]
    pub fn access(&mut self, port: u8, addr: u32, cycle: u64) -> u64 {
        let bank = &mut self.granted[Self::bank(addr)];
        let mut g = cycle;
        loop {
            let tag = g / 64;
            let slot = &mut bank[(tag % WORDS as u64) as usize];
            if slot.tag != tag {
                // A stale slice: older than the window, free.
                *slot = Slice { tag, bits: 0 };
            }
            let bit = 1u64 << (g % 64);
            if slot.bits & bit == 0 {
                slot.bits |= bit;
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
        // A cycle a window later reuses the slot: free again.
        assert_eq!(t.access(4, L1_BASE, 10 + WINDOW), 0);
        assert_eq!(t.access(5, L1_BASE, 10 + WINDOW), 1);
    }
}
