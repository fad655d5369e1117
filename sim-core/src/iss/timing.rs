//! Cycle costs per instruction class, from the CV32E40P user manual's table
//! "Cycle counts per instruction type" (docs/source/pipeline.rst of
//! openhwgroup/cv32e40p), which is the core GAP8's fabric controller is
//! built on (RI5CY; thesis §2.1.2, DESIGN.md §4).
//!
//! Costs that depend on data are added by the core on top of the table:
//! - taken branch: +[`BRANCH_TAKEN_EXTRA`] (3 in total),
//! - division/remainder: 3 + leading zeros of the divisor (3..35),
//! - a load or store that crosses a word boundary: +[`SPLIT_ACCESS_EXTRA`]
//!   (two bus transactions),
//! - a load whose result the next instruction reads: +[`LOAD_USE_STALL`],
//! - an access to an MMIO window: + the configured peripheral latency.
//!
//! Not modelled (documented simplifications): the extra cycle of a jump or
//! taken branch to a non-word-aligned 32-bit instruction, the jalr
//! register hazard, and instruction-fetch stalls (zero-wait L2, as the
//! manual's table assumes).

use super::decode::op;
use super::mem::AccessSize;

/// Extra cycles of a taken branch (3 in total, "Branch (Taken)").
pub const BRANCH_TAKEN_EXTRA: u64 = 2;
/// Extra cycle of a misaligned access that needs two bus transactions.
pub const SPLIT_ACCESS_EXTRA: u64 = 1;
/// Load-use hazard penalty.
pub const LOAD_USE_STALL: u64 = 1;
/// Cost of a CSR access to mstatus, mepc, mtvec, mcause, mcycle(h),
/// minstret(h) (4 in the manual), on top of the table's 1.
pub const SLOW_CSR_EXTRA: u64 = 3;
/// Entering a trap handler flushes the pipeline like a jump; the manual has
/// no row for it, so we charge a jump's 2 cycles (assumption).
pub const TRAP_ENTRY: u64 = 2;

/// Base cycles of every op (index = op code; 256 entries so that indexing
/// with a `u8` needs no bounds check).
pub const BASE_CYCLES: [u8; 256] = {
    let mut t = [1u8; 256];
    t[op::JAL as usize] = 2;
    t[op::JALR as usize] = 2;
    t[op::MULH as usize] = 5;
    t[op::MULHSU as usize] = 5;
    t[op::MULHU as usize] = 5;
    // Division: the table's 3 is the minimum; the core adds clz(divisor).
    t[op::DIV as usize] = 3;
    t[op::DIVU as usize] = 3;
    t[op::REM as usize] = 3;
    t[op::REMU as usize] = 3;
    // "Internally it is implemented as a jump to the instruction following
    // the fence."
    t[op::FENCE_I as usize] = 2;
    // mret is a jump to mepc (assumption: jump cost).
    t[op::MRET as usize] = 2;
    // Traps charge TRAP_ENTRY themselves. ebreak keeps its 1 cycle because
    // as a semihosting call it retires (every retiring step costs >= 1).
    t[op::ECALL as usize] = 0;
    t[op::ILLEGAL as usize] = 0;
    t
};

/// Cycles of a division whose divisor magnitude is `b`.
#[inline(always)]
pub fn div_cycles(b: u32) -> u64 {
    3 + b.leading_zeros() as u64
}

/// Extra cycles of an access at `addr` that crosses a word boundary (two
/// bus transactions).
#[inline(always)]
pub fn split_cost(addr: u32, size: AccessSize) -> u64 {
    ((addr & 3) + size.bytes() > 4) as u64 * SPLIT_ACCESS_EXTRA
}

/// Whether a CSR is in the manual's 4-cycle group.
pub fn slow_csr(csr: u16) -> bool {
    matches!(
        csr,
        0x300 | 0x341 | 0x305 | 0x342 | 0xB00 | 0xB02 | 0xB80 | 0xB82
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn division_range_matches_manual() {
        // "3 when the divider has zero leading bits at 0 (e.g. 0x80000000),
        // 35 when the divider is 0".
        assert_eq!(div_cycles(0x8000_0000), 3);
        assert_eq!(div_cycles(0), 35);
        assert_eq!(div_cycles(1), 34);
    }
}
