//! The RV32IMC instruction-set simulator: GVSoC's fabric controller in the
//! thesis (§2.1.2, §3.1.1, Appendix D; contract in DESIGN.md §4).
//!
//! - [`Cpu`]: RV32I + M + C + Zicsr + Zifencei and the CORE-V XCV
//!   extensions ([`xcv`]: xcvalu, xcvmac, xcvmem, xcvsimd, xcvbi,
//!   xcvbitmanip, DESIGN.md §12), machine and user mode,
//!   traps, `mret`, `wfi`, a CLINT machine timer, one external interrupt
//!   line, CV32E40P cycle timing ([`timing`]) and exact idle skipping.
//! - [`Memory`] / [`Mmio`]: RAM regions owned by the ISS and the device
//!   window(s) the platform implements (see [`mem`] for the access-time and
//!   idle-skip contracts).
//! - [`CodeCache`]: what the cores make of the code in that RAM, kept
//!   apart from it: pre-decoded basic blocks (`block.rs`) and their
//!   translation to host code (`jit`). Whoever owns a [`Memory`] keeps
//!   one beside it and hands both to the cores; memory tells it when code
//!   is overwritten (`code.rs`).
//! - [`MemTiming`]: extra cycles of RAM accesses and the L1 bank arbiter
//!   ([`Memory::l1_arbiter`], the [`l1::BankArbiter`] interface the
//!   platform's cluster implements) for the cluster's cores and the FC
//!   beside them; the default costs nothing. A device may answer
//!   [`MmioError::Wait`]: the instruction is undone and the core stops with
//!   [`StopReason::Wait`], to retry it later (the cluster's synchronising
//!   and sleeping accesses).
//! - [`elf`]: ELF loading with the `object` crate (segments at their
//!   physical addresses, symbols for `tohost` and the signature).
//! - [`semihost`]: the semihosting calls picolibc uses; output goes to a
//!   sink the platform chooses ([`Cpu::set_console`]).
//!
//! The ISS is the bottom layer: it knows nothing of the cluster (whose
//! bank arbiter it sees through [`l1::BankArbiter`]); the machines built
//! on it, and `sim-core run-elf`, are in `crate::machine`.
//!
//! # How the platform drives the core
//!
//! ```text
//! loop {
//!     let t = kernel.next_event_time();
//!     match cpu.run_until(&mut memory, &mut code, &mut peripherals, t) {
//!         StopReason::Limit | StopReason::Event => kernel.process_due_events(),
//!         StopReason::DeviceRequest => kernel.handle_request(),
//!         StopReason::Exit { code } => break,
//!         ...
//!     }
//! }
//! ```
//! `run_until` stops at the first instruction boundary at or after the limit
//! (an instruction is never split), so the core may overshoot by the length
//! of one instruction. Splitting a run into more or fewer `run_until` calls
//! never changes its outcome (tested).
//!
//! # Time
//!
//! Simulated time is `cycles × period` (250 MHz → 4000 ps per cycle), always
//! on a cycle boundary: a device event at a time between two edges is seen
//! at the next edge. `cycles` counts every clock cycle, asleep or not; the
//! `mcycle` CSR counts only awake cycles (CV32E40P's counters run on the
//! gated clock that `wfi` stops); `mtime` (CLINT at [`cpu::CLINT_BASE`])
//! counts core cycles. An MMIO access issued at cycle `c` happens at
//! `(c + latency) × period` ([`CpuConfig::mmio_latency`], default 0).
//!
//! # Idle skipping
//!
//! A loop is a polling loop when its body, from a backward branch's target
//! to the branch (at most [`cpu::MAX_POLL_LOOP_BYTES`]), holds only loads,
//! computations and conditional branches (no store, jump, CSR or system
//! instruction), and one whole iteration ran it straight through (none of
//! its branches taken but the closing one — the others are typically exits,
//! `if (status == BATTERY_LOW) break;`), read at least one MMIO register and
//! ended with exactly the register file it started with. With the same
//! registers and unchanged device values, the next iteration takes the
//! same path in the same cycles. Each such iteration counts as polling in [`CoreStats`]; with
//! skipping on, the core then jumps over as many whole iterations as fit
//! before the run's deadline and before [`Mmio::stable_until`] of every
//! register the iteration read, adding their exact cycles and instructions.
//! `wfi` with no enabled interrupt pending sleeps to the next deadline (the
//! limit, a device event or the timer) in one step, or cycle by cycle with
//! skipping off. Both modes give identical architectural state, counters,
//! statistics (except `skipped_instructions`) and device-visible access
//! times; `tests/iss_idle.rs` compares them. One difference by design: a
//! loop polling a register that never changes, with nothing scheduled, ends
//! the run with [`StopReason::Idle`] when skipping is on (a step-by-step run
//! would spin forever).
//!
//! # Decisions where the contract leaves room
//!
//! - Misaligned loads and stores are done in hardware; those that cross a
//!   word boundary cost one extra cycle (two bus transactions, as RI5CY).
//!   With C always enabled, a misaligned instruction fetch cannot happen
//!   (jump targets have bit 0 cleared), so that trap is never raised.
//! - A trap whose handler address is not in RAM (e.g. `mtvec` still 0 when
//!   the first fetch faults) ends the run with [`IssError::UnhandledTrap`]
//!   instead of looping.
//! - `wfi` in user mode raises an illegal-instruction trap (the spec's
//!   implementation-defined time limit is zero here); `mcounteren` gates
//!   user access to `cycle`/`time`/`instret`.
//! - A core that can never progress ends the run with
//!   [`IssError::NeverProgress`] (hart, pc, why) instead of spinning
//!   silently: a branch or `jal` to itself, taken, when no interrupt could
//!   ever be taken (machine mode with `mstatus.MIE` clear, or none enabled
//!   that could fire; registers and CSRs are the core's own, so nothing
//!   else can change its operands), and `wfi` with `mie` zero. The block
//!   builder marks a block that starts with such a transfer and sends it
//!   to the general path, which decides; the translator leaves it alone,
//!   so other code pays nothing. A loop with any other instruction in it
//!   (a load of a device or of memory another agent writes, a countdown)
//!   is not one; polling is the idle detector's.
//! - The code cache is kept coherent by every store (and by
//!   [`Memory::write_bytes`]), so `fence.i` only costs its 2 cycles.
//! - Semihosting times (`SYS_CLOCK`, `SYS_TIME`, `SYS_ELAPSED`) are
//!   simulated time, never the wall clock.

mod block;
mod code;
pub mod cpu;
pub mod decode;
pub mod elf;
mod exec;
#[cfg(target_arch = "x86_64")]
mod jit;
#[cfg(target_arch = "x86_64")]
pub use jit::JitStats;
pub mod l1;
pub mod mem;
pub mod semihost;
pub mod timing;
pub mod xcv;

pub use code::CodeCache;
pub use cpu::{cause, Backend, CoreStats, Cpu, CpuConfig, IssError, Privilege, StopReason, Stuck};
pub use elf::{load_elf, ElfError, LoadedElf, Segment};
pub use mem::{AccessSize, MemError, MemTiming, Memory, Mmio, MmioError, NoDevices};

/// The GAP8-like memory map (DESIGN.md §4).
pub mod map {
    /// L2 RAM, where firmware is linked.
    pub const L2_BASE: u32 = 0x1c00_0000;
    pub const L2_SIZE: u32 = 512 * 1024;
    /// The peripheral window (sensors laid out one after another as MESSY
    /// does; the thesis's offsets reach +102427). 1 MiB reserved.
    pub const PERIPH_BASE: u32 = 0x2000_0000;
    pub const PERIPH_SIZE: u32 = 0x0010_0000;
}
