//! What a run reports: the core's counters, why `run_until` returned, the
//! errors that end a run.

use thiserror::Error;

use super::*;

/// Counters for reports and the power model. Cycles split into running,
/// sleeping (in `wfi`) and polling (iterations of a loop proven to only
/// re-read an unchanged device register, whether skipped or stepped; the
/// count is the same with idle skipping on and off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CoreStats {
    pub instructions: u64,
    pub cycles: u64,
    pub sleep_cycles: u64,
    pub poll_cycles: u64,
    pub poll_instructions: u64,
    /// Instructions not interpreted thanks to idle skipping (0 when off).
    pub skipped_instructions: u64,
}

impl CoreStats {
    /// Cycles neither sleeping nor polling.
    pub fn running_cycles(&self) -> u64 {
        self.cycles - self.sleep_cycles - self.poll_cycles
    }

    /// What happened between an `earlier` snapshot and this one (for a
    /// power model sampling the core every millisecond).
    pub fn since(&self, earlier: &CoreStats) -> CoreStats {
        CoreStats {
            instructions: self.instructions - earlier.instructions,
            cycles: self.cycles - earlier.cycles,
            sleep_cycles: self.sleep_cycles - earlier.sleep_cycles,
            poll_cycles: self.poll_cycles - earlier.poll_cycles,
            poll_instructions: self.poll_instructions - earlier.poll_instructions,
            skipped_instructions: self.skipped_instructions - earlier.skipped_instructions,
        }
    }
}

/// Why [`Cpu::run_until`] returned. In every case the core stopped on an
/// instruction boundary and can be resumed with another `run_until`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopReason {
    /// Simulated time reached the limit.
    Limit,
    /// Simulated time reached the device's [`Mmio::next_event`].
    Event,
    /// An MMIO access asked to stop ([`Mmio::take_stop_request`]).
    DeviceRequest,
    /// The program ended (semihosting exit, or a `tohost` write).
    Exit { code: i32 },
    /// The instruction limit was reached.
    InstructionLimit,
    /// A plain `ebreak` with [`CpuConfig::ebreak_stops`]; `pc` is the ebreak.
    Breakpoint { pc: u32 },
    /// The core sleeps (or, with idle skipping, spins on a device register
    /// that never changes) with nothing that could ever wake it.
    Idle,
    /// An MMIO access answered [`MmioError::Wait`]: the instruction did
    /// not execute (no cycle, no retirement), the pc is on it, and the next
    /// `run_until` retries it.
    Wait,
    /// The run cannot continue.
    Fatal(IssError),
}

/// Errors that end a run.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum IssError {
    #[error("{} at pc {pc:#010x} (mtval {tval:#010x}) and the trap handler at {handler:#010x} is not in RAM", cause_name(*.cause))]
    UnhandledTrap {
        cause: u32,
        pc: u32,
        tval: u32,
        handler: u32,
    },
    #[error(transparent)]
    Device(#[from] MmioError),
    #[error("console output failed: {0}")]
    Console(String),
    /// The core can never execute another instruction (DESIGN.md §19):
    /// nothing but the core itself could change what keeps it where it
    /// is. The pc stays on the instruction.
    #[error("hart {hart:#x} at {pc:#010x} {why}: it can never progress")]
    NeverProgress { hart: u32, pc: u32, why: Stuck },
    /// An error of one of the cluster's cores (`crate::cluster`).
    #[error("cluster core {core}: {source}")]
    ClusterCore { core: usize, source: Box<IssError> },
}

/// Why a core can never progress ([`IssError::NeverProgress`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum Stuck {
    /// A branch or jump to itself, taken, in machine mode with
    /// `mstatus.MIE` clear.
    #[error("spins on itself with interrupts off")]
    SpinsInterruptsOff,
    /// The same with interrupts on, but none enabled that could fire.
    #[error("spins on itself with no interrupt enabled that could fire")]
    SpinsNoInterrupt,
    /// `wfi` with `mie` zero: no interrupt can wake it.
    #[error("sleeps in wfi with no interrupt enabled")]
    Asleep,
}

/// Human name of an mcause value.
pub fn cause_name(c: u32) -> &'static str {
    match c {
        cause::MISALIGNED_FETCH => "misaligned instruction fetch",
        cause::FETCH_ACCESS => "instruction fetch from unmapped memory",
        cause::ILLEGAL_INSTRUCTION => "illegal instruction",
        cause::BREAKPOINT => "breakpoint",
        cause::LOAD_ACCESS => "load access fault",
        cause::STORE_ACCESS => "store access fault",
        cause::ECALL_U => "ecall from user mode",
        cause::ECALL_M => "ecall from machine mode",
        _ if c & cause::INTERRUPT != 0 => "interrupt",
        _ => "exception",
    }
}
