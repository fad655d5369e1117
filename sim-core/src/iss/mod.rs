//! The RV32IMC instruction-set simulator: GVSoC's fabric controller in the
//! thesis (§2.1.2, §3.1.1, Appendix D; contract in DESIGN.md §4).
//!
//! - [`Cpu`]: RV32I + M + C + Zicsr + Zifencei, machine and user mode,
//!   traps, `mret`, `wfi`, a CLINT machine timer, one external interrupt
//!   line, CV32E40P cycle timing ([`timing`]), a pre-decoded instruction
//!   cache and exact idle skipping.
//! - [`Memory`] / [`Mmio`]: RAM regions owned by the ISS and the device
//!   window(s) the platform implements (see [`mem`] for the access-time and
//!   idle-skip contracts).
//! - [`elf`]: ELF loading with the `object` crate.
//! - [`run_elf`]: the `sim-core run-elf` driver (riscv-tests `tohost`,
//!   semihosting, RISCOF signatures).
//!
//! # How the platform drives the core
//!
//! ```text
//! loop {
//!     let t = kernel.next_event_time();
//!     match cpu.run_until(&mut memory, &mut peripherals, t) {
//!         StopReason::Limit | StopReason::Event => kernel.process_due_events(),
//!         StopReason::DeviceRequest => kernel.handle_request(),
//!         StopReason::Exit { code } => break,
//!         ...
//!     }
//! }
//! ```
//! `run_until` stops at the first instruction boundary at or after the limit
//! (an instruction is never split), so the core may overshoot by the length
//! of one instruction.

pub mod cpu;
pub mod decode;
pub mod elf;
pub mod mem;
pub mod run_elf;
pub mod semihost;
pub mod timing;

pub use cpu::{cause, CoreStats, Cpu, CpuConfig, IssError, Privilege, StopReason};
pub use elf::{load_elf, ElfError, LoadedElf, Segment};
pub use mem::{AccessSize, MemError, Memory, Mmio, MmioError, NoDevices};

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
