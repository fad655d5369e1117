//! What translated code and the core share during one run: a `#[repr(C)]`
//! record whose field offsets the templates (`emit.rs`) use directly.
//!
//! Host registers while translated code runs (all callee-saved in the
//! System V ABI, so calls to Rust helpers keep them):
//! - `rbx`: this [`Ctx`],
//! - `r12`: the guest register file (`[u32; 32]` in the `Cpu`),
//! - `r13`: the core's cycle count,
//! - `r14`: the host address of the fast RAM region's first byte,
//! - `r15`: instructions retired since the run began,
//! - `rbp`: [`Ctx::extra`], the extra cycles of every fast-region access.

use super::super::l1::PortStats;

use std::mem::offset_of;

/// A translated block as the dispatcher sees it (16 bytes, one per
/// halfword of a RAM region; `code == 0`: none).
///
/// The layout is the table's (`mod.rs`'s `pack`): `code`, then `worst`,
/// `nmem` and `careful` in one little-endian word.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C)]
pub(crate) struct Entry {
    /// Host address of its code.
    pub code: u64,
    /// Its worst-case cycles apart from the memory extras: the sum of its
    /// instruction costs, a taken branch and the longest divisions, one
    /// split cycle per access.
    pub worst: u32,
    /// Loads and stores in it, each of which may cost more than its cycle
    /// ([`Entry::worst_case`]; an L1 bank's stall aside: translated code
    /// checks the deadline again after each L1 access).
    pub nmem: u16,
    /// Offset from `code` of the careful variant's entry past its first
    /// deadline test (0: none), for a core whose deadline is nearer than
    /// the block's worst case: the block's instructions, each preceded by
    /// the interpreter's own test (`cycles >= deadline`: leave before it),
    /// so translated code runs right up to a cluster quantum's end instead
    /// of handing its last blocks to the interpreter (`emit::translate`).
    /// The core enters there only when its cycles are below the deadline,
    /// which is the interpreter's test for a block's first instruction.
    pub careful: u16,
}

impl Entry {
    /// The most cycles the block can take (apart from an L1 bank's stall)
    /// when each of its loads and stores costs at most `per` more: for a
    /// cluster core's translation (`jit::Flavour::L1`) the cheaper
    /// region's extra, [`Ctx::worst_extra`], since it checks again after
    /// every access; for the FC's, every access's.
    pub fn worst_case(&self, per: u64) -> u64 {
        self.worst as u64 + self.nmem as u64 * per
    }
}

/// The shared record.
#[derive(Debug)]
#[repr(C)]
pub(crate) struct Ctx {
    pub regs: *mut u32,
    /// Host address of the fast region's data.
    pub fast_ptr: *mut u8,
    /// Guest address and size of the fast region (size 0: none, and then
    /// the base [`NO_REGION`]), and the last offset at which a load of 1,
    /// 2 and 4 bytes fits in it ([`Bounds`]).
    pub fast_base: u64,
    pub fast_size: u64,
    pub fast_last: [u64; 3],
    /// Byte offsets `[code_lo, code_hi)` in the fast region that hold
    /// cached code: stores there leave translated code.
    pub code_lo: u64,
    pub code_hi: u64,
    /// Address of `tohost` (stores to its 8 bytes leave translated code);
    /// [`NO_TOHOST`] when there is none.
    pub tohost: u64,
    /// Translated code never starts a block that could reach this cycle.
    pub deadline: u64,
    /// Extra cycles of every fast-region access (a cluster core's L2).
    pub extra: u64,
    /// What the checked entries of L1-path translations count per load or
    /// store: the cheaper of the fast region's extra cycles and the L1's
    /// (none, for the cores that run them); an access that costs more (an
    /// L2 one, or an L1 one that stalled on its bank) tests the deadline
    /// again.
    pub worst_extra: u64,
    /// The L1 (`MemTiming::l1`, the cluster's TCDM) when it is not the
    /// fast region: host address of its data, guest base and size (size
    /// 0: none), and the byte offsets `[l1_code_lo, l1_code_hi)` of cached
    /// code in it.
    pub l1_ptr: *mut u8,
    pub l1_base: u64,
    pub l1_size: u64,
    pub l1_last: [u64; 3],
    pub l1_code_lo: u64,
    pub l1_code_hi: u64,
    /// The device registers that read like memory (`Mmio::plain_window`,
    /// the camera's image): host address of their bytes, guest base and
    /// last offsets ([`Bounds`]; base [`NO_REGION`]: none), and what a
    /// load there costs beyond its cycle (`Cpu::latency`, as
    /// `exec::Run::window_load` charges). Only the FC's translations read
    /// it (`emit::mem::plain_out_of_line`).
    pub win_ptr: *const u8,
    pub win_base: u64,
    pub win_last: [u64; 3],
    pub win_latency: u64,
    /// The bank arbiter's masks and this core's port's counts
    /// ([`BankArbiter::grant_window`](super::super::l1::BankArbiter::grant_window)), for
    /// the inline grant (null: no arbitration, the FC's view of L1).
    pub l1_granted: *mut u16,
    pub l1_port_stats: *mut PortStats,
    /// Stall cycles of the conflicts translated code resolved itself
    /// (`emit::mem::busy`), which the core adds to the port's count
    /// afterwards, as it does with the grants in `r15`.
    pub l1_stalls: u64,
    /// The idle detector wants to see short backward branches (a device
    /// was read since the last one, `PollTracker::touched`): a taken one
    /// leaves at its target with its pc in [`Ctx::poll_from`] (else 0).
    pub poll_armed: u64,
    pub poll_from: u64,
    /// Taken jumps so far (`Cpu::jumps`).
    pub jumps: u64,
    /// Where the run stopped: the pc of the next instruction.
    pub exit_pc: u64,
    /// The load-use state at the exit (one-hot loaded register).
    pub load_mask: u64,
    /// The code region whose blocks chain through [`Ctx::table`].
    pub code_base: u64,
    pub code_size: u64,
    pub table: *const Entry,
    /// Cycles at the exit, and `r15`: the instructions retired, and with
    /// an arbiter ([`Ctx::l1_granted`] not null) the L1 accesses granted
    /// inline in its bits from [`GRANT_SHIFT`] up ([`Ctx::retired_grants`]).
    pub cycles: u64,
    pub retired: u64,
}

/// Where `r15` counts the inline L1 grants of a cluster core's run: a
/// counter in a register rather than in memory (a read-modify-write per
/// access, measured 5–8 % of `cosim nn eval`). The instructions retired
/// stay below: a core with an arbiter port runs at most a quantum per
/// call (the cluster scheduler's, 1024 cycles, one instruction per cycle
/// at most), far below 2^24; the FC, with no arbiter, grants nothing and may use all 64
/// bits.
pub(crate) const GRANT_SHIFT: u32 = 24;
/// One grant (an `imm32` for `add r15`).
pub(crate) const GRANT_ONE: i32 = 1 << GRANT_SHIFT;

impl Ctx {
    /// `(instructions retired, L1 accesses granted inline)` at the exit.
    pub fn retired_grants(&self) -> (u64, u64) {
        if self.l1_granted.is_null() {
            (self.retired, 0)
        } else {
            let mask = (1u64 << GRANT_SHIFT) - 1;
            debug_assert!(
                self.retired & mask < mask,
                "a cluster core's run retired 2^24 instructions"
            );
            (self.retired & mask, self.retired >> GRANT_SHIFT)
        }
    }
}

/// `tohost` when there is none: far above any 32-bit address, so
/// `addr - NO_TOHOST` (wrapping, 64-bit) is never below 8.
pub(crate) const NO_TOHOST: u64 = 1 << 40;

/// A region's base, size and last offsets as [`Ctx`] holds them: a load
/// of `n` bytes at offset `off = addr - base` (64-bit, wrapping) is inside
/// when `off <= last[n]`, one comparison; without a region (size 0) the
/// base is [`NO_REGION`], so no 32-bit address is at an offset as small as
/// a `last`, which is then 0.
pub(crate) struct Bounds {
    pub base: u64,
    pub size: u64,
    pub last: [u64; 3],
}

/// The base of no region: far above any 32-bit address.
pub(crate) const NO_REGION: u64 = 1 << 40;

impl Bounds {
    /// A region of `size` bytes at `base`; one of under 4 bytes (none of
    /// our RAMs) is taken as none, so that every offset has a `last`: its
    /// accesses are left to the interpreter.
    pub fn new(base: u32, size: u64) -> Bounds {
        if size < 4 {
            return Bounds {
                base: NO_REGION,
                size: 0,
                last: [0; 3],
            };
        }
        Bounds {
            base: base as u64,
            size,
            last: [size - 1, size - 2, size - 4],
        }
    }

    /// The index of an access size in `last` (1, 2 or 4 bytes).
    pub const fn index(n: i32) -> i32 {
        match n {
            1 => 0,
            2 => 1,
            _ => 2,
        }
    }
}

pub(crate) const REGS: i32 = offset_of!(Ctx, regs) as i32;
pub(crate) const FAST_PTR: i32 = offset_of!(Ctx, fast_ptr) as i32;
pub(crate) const FAST_BASE: i32 = offset_of!(Ctx, fast_base) as i32;
pub(crate) const FAST_SIZE: i32 = offset_of!(Ctx, fast_size) as i32;
pub(crate) const FAST_LAST: i32 = offset_of!(Ctx, fast_last) as i32;
pub(crate) const CODE_LO: i32 = offset_of!(Ctx, code_lo) as i32;
pub(crate) const CODE_HI: i32 = offset_of!(Ctx, code_hi) as i32;
pub(crate) const TOHOST: i32 = offset_of!(Ctx, tohost) as i32;
pub(crate) const DEADLINE: i32 = offset_of!(Ctx, deadline) as i32;
pub(crate) const EXTRA: i32 = offset_of!(Ctx, extra) as i32;
pub(crate) const WORST_EXTRA: i32 = offset_of!(Ctx, worst_extra) as i32;
pub(crate) const L1_PTR: i32 = offset_of!(Ctx, l1_ptr) as i32;
pub(crate) const L1_BASE: i32 = offset_of!(Ctx, l1_base) as i32;
pub(crate) const L1_SIZE: i32 = offset_of!(Ctx, l1_size) as i32;
pub(crate) const L1_LAST: i32 = offset_of!(Ctx, l1_last) as i32;
pub(crate) const L1_CODE_LO: i32 = offset_of!(Ctx, l1_code_lo) as i32;
pub(crate) const L1_CODE_HI: i32 = offset_of!(Ctx, l1_code_hi) as i32;
pub(crate) const WIN_PTR: i32 = offset_of!(Ctx, win_ptr) as i32;
pub(crate) const WIN_BASE: i32 = offset_of!(Ctx, win_base) as i32;
pub(crate) const WIN_LAST: i32 = offset_of!(Ctx, win_last) as i32;
pub(crate) const WIN_LATENCY: i32 = offset_of!(Ctx, win_latency) as i32;
pub(crate) const POLL_ARMED: i32 = offset_of!(Ctx, poll_armed) as i32;
pub(crate) const POLL_FROM: i32 = offset_of!(Ctx, poll_from) as i32;
pub(crate) const L1_GRANTED: i32 = offset_of!(Ctx, l1_granted) as i32;
pub(crate) const L1_STALLS: i32 = offset_of!(Ctx, l1_stalls) as i32;
pub(crate) const JUMPS: i32 = offset_of!(Ctx, jumps) as i32;
pub(crate) const EXIT_PC: i32 = offset_of!(Ctx, exit_pc) as i32;
pub(crate) const LOAD_MASK: i32 = offset_of!(Ctx, load_mask) as i32;
pub(crate) const CODE_BASE: i32 = offset_of!(Ctx, code_base) as i32;
pub(crate) const CODE_SIZE: i32 = offset_of!(Ctx, code_size) as i32;
pub(crate) const TABLE: i32 = offset_of!(Ctx, table) as i32;
pub(crate) const CYCLES: i32 = offset_of!(Ctx, cycles) as i32;
pub(crate) const RETIRED: i32 = offset_of!(Ctx, retired) as i32;

pub(crate) const ENTRY_CODE: i32 = offset_of!(Entry, code) as i32;
/// log2 of `size_of::<Entry>()` (the dispatcher scales by a shift).
pub(crate) const ENTRY_SHIFT: i8 = 4;
const _: () = assert!(std::mem::size_of::<Entry>() == 1 << ENTRY_SHIFT);
