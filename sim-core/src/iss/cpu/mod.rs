//! The core: architectural state, CSRs, traps, the timed interpreter loop and
//! exact idle skipping.

use std::io::Write;

use thiserror::Error;

use crate::units::{Cycles, Hertz, Picos};

use super::block::{FetchFault, Inst};
use super::decode::{self, op, Decoded};
use super::exec;
use super::mem::{AccessSize, MemTiming, Memory, Mmio, MmioError};
use super::semihost::{self, Semihost};
use super::timing::{self, BASE_CYCLES};
use super::xcv;

/// The machine timer, a CLINT at its customary address (the GAP8 map has
/// nothing there, DESIGN.md §4). `mtime` counts core clock cycles.
pub const CLINT_BASE: u32 = 0x0200_0000;
pub const CLINT_SIZE: u32 = 0x0001_0000;
const CLINT_MSIP: u32 = 0x0000;
const CLINT_MTIMECMP: u32 = 0x4000;
const CLINT_MTIME: u32 = 0xbff8;

/// Longest loop body (bytes from the branch target to the branch) the idle
/// detector looks at; the thesis's polling loops are 2–4 instructions.
pub const MAX_POLL_LOOP_BYTES: u32 = 64;

/// How many MMIO reads one polling iteration may make.
const MAX_POLL_READS: usize = 4;

// mstatus bits.
const MSTATUS_MIE: u32 = 1 << 3;
const MSTATUS_MPIE: u32 = 1 << 7;
const MSTATUS_MPP: u32 = 3 << 11;
const MSTATUS_MPRV: u32 = 1 << 17;
const MSTATUS_TW: u32 = 1 << 21;
const MSTATUS_WRITABLE: u32 = MSTATUS_MIE | MSTATUS_MPIE | MSTATUS_MPP | MSTATUS_MPRV | MSTATUS_TW;

// Interrupt bits in mip/mie, and their cause codes.
const IRQ_MSI: u32 = 3;
const IRQ_MTI: u32 = 7;
const IRQ_MEI: u32 = 11;
const MIE_WRITABLE: u32 = 1 << IRQ_MSI | 1 << IRQ_MTI | 1 << IRQ_MEI;

/// misa: MXL = 1 (32-bit), extensions C, I, M, U.
pub const MISA: u32 = 1 << 30 | 1 << 2 | 1 << 8 | 1 << 12 | 1 << 20;

/// Exception causes (mcause values without the interrupt bit).
pub mod cause {
    pub const MISALIGNED_FETCH: u32 = 0;
    pub const FETCH_ACCESS: u32 = 1;
    pub const ILLEGAL_INSTRUCTION: u32 = 2;
    pub const BREAKPOINT: u32 = 3;
    pub const LOAD_ACCESS: u32 = 5;
    pub const STORE_ACCESS: u32 = 7;
    pub const ECALL_U: u32 = 8;
    pub const ECALL_M: u32 = 11;
    pub const INTERRUPT: u32 = 1 << 31;
}

/// Privilege level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Privilege {
    User = 0,
    Machine = 3,
}

/// Core parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CpuConfig {
    /// Core clock (platform file `core.frequency`; default 250 MHz).
    pub clock: Hertz,
    /// Extra cycles of every access to an MMIO window; the device sees the
    /// access at `(issue cycle + latency) × period` (see `mem.rs`).
    pub mmio_latency: Cycles,
    /// Exact idle skipping of polling loops and `wfi` sleeps.
    pub idle_skip: bool,
    /// A plain (non-semihosting) `ebreak` stops the run with
    /// [`StopReason::Breakpoint`] instead of trapping, like a debugger.
    pub ebreak_stops: bool,
    pub hart_id: u32,
    /// What runs the cached blocks: the interpreter or the translator
    /// (identical results; `--iss`, `--set iss=`).
    pub iss: Backend,
}

/// The ISS back end (DESIGN.md §14). Both give bit-identical state,
/// cycles and device-visible times; the translator is faster.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// The threaded interpreter (`exec.rs`), on every host; the reference.
    Interp,
    /// The block translator (`jit/`) in front of the interpreter; x86-64
    /// only (elsewhere it runs as the interpreter).
    Jit,
}

impl Backend {
    /// The translator on x86-64, the interpreter elsewhere.
    pub const DEFAULT: Backend = if cfg!(target_arch = "x86_64") {
        Backend::Jit
    } else {
        Backend::Interp
    };

    pub fn name(self) -> &'static str {
        match self {
            Backend::Interp => "interp",
            Backend::Jit => "jit",
        }
    }
}

impl Default for Backend {
    fn default() -> Self {
        Backend::DEFAULT
    }
}

impl std::str::FromStr for Backend {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "interp" => Ok(Backend::Interp),
            "jit" => Ok(Backend::Jit),
            _ => Err(format!(
                "unknown ISS back end {s:?} (expected interp or jit)"
            )),
        }
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Default for CpuConfig {
    fn default() -> Self {
        CpuConfig {
            clock: Hertz(250_000_000),
            mmio_latency: Cycles(0),
            idle_skip: true,
            ebreak_stops: false,
            hart_id: 0,
            iss: Backend::DEFAULT,
        }
    }
}

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
    /// An error of one of the cluster's cores (`crate::cluster`).
    #[error("cluster core {core}: {source}")]
    ClusterCore { core: usize, source: Box<IssError> },
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

/// The RV32IMC core.
pub struct Cpu {
    regs: [u32; 32],
    pc: u32,
    privilege: Privilege,
    // CSRs.
    mstatus: u32,
    mie: u32,
    mtvec: u32,
    mscratch: u32,
    mepc: u32,
    mcause: u32,
    mtval: u32,
    mcounteren: u32,
    mcycle_off: u64,
    minstret_off: u64,
    meip: bool,
    msip: bool,
    mtimecmp: u64,
    mtime_off: u64,
    // Counters.
    cycles: u64,
    instret: u64,
    /// Taken branches and jumps (including `mret`) so far. The idle
    /// detector uses it to prove that an iteration ran its body straight
    /// through, none of the body's own branches taken. Counted in memory,
    /// not in `Hot`: it changes only on taken transfers, and the hot loop
    /// is short of host registers already.
    jumps: u64,
    stats: CoreStats,
    /// One-hot mask of the register the previous instruction loaded (0 if
    /// it was not a load or loaded x0): the load-use stall check.
    load_mask: u32,
    sleeping: bool,
    // Run control.
    deadline: u64,
    instr_deadline: u64,
    event_cycle: u64,
    pending_stop: Option<StopReason>,
    // Code cache window (a RAM region index and its bounds).
    code_idx: usize,
    code_base: u32,
    code_size: u32,
    period: u64,
    latency: u64,
    cfg: CpuConfig,
    tohost: Option<u32>,
    semihost: Semihost,
    poll: PollTracker,
    /// Extra cycles and L1 arbitration of RAM accesses (cluster, §12).
    mem_timing: MemTiming,
    /// The current general-path instruction met [`MmioError::Wait`]: undo
    /// its cycles (see [`Cpu::step`]).
    waited: bool,
}

impl std::fmt::Debug for Cpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cpu")
            .field("pc", &format_args!("{:#010x}", self.pc))
            .field("privilege", &self.privilege)
            .field("cycles", &self.cycles)
            .field("instret", &self.instret)
            .finish_non_exhaustive()
    }
}

#[inline(always)]
fn div_ceil(a: u64, b: u64) -> u64 {
    a.div_ceil(b)
}

impl Cpu {
    /// A core in machine mode at pc 0 with all registers zero. The
    /// semihosting console defaults to stdout; see [`Cpu::set_console`].
    pub fn new(cfg: CpuConfig) -> Cpu {
        Cpu {
            regs: [0; 32],
            pc: 0,
            privilege: Privilege::Machine,
            mstatus: 0,
            mie: 0,
            mtvec: 0,
            mscratch: 0,
            mepc: 0,
            mcause: 0,
            mtval: 0,
            mcounteren: 0,
            mcycle_off: 0,
            minstret_off: 0,
            meip: false,
            msip: false,
            mtimecmp: u64::MAX,
            mtime_off: 0,
            cycles: 0,
            instret: 0,
            jumps: 0,
            stats: CoreStats::default(),
            load_mask: 0,
            sleeping: false,
            deadline: 0,
            instr_deadline: u64::MAX,
            event_cycle: u64::MAX,
            pending_stop: None,
            code_idx: 0,
            code_base: 0,
            code_size: 0,
            period: cfg.clock.period().0.max(1),
            latency: cfg.mmio_latency.0,
            cfg,
            tohost: None,
            semihost: Semihost::new(Box::new(std::io::stdout())),
            poll: PollTracker::default(),
            mem_timing: MemTiming::default(),
            waited: false,
        }
    }

    /// How this core's RAM accesses are timed (a cluster core's L2 latency
    /// and L1 banks, the FC's view of L1; DESIGN.md §12).
    pub fn set_mem_timing(&mut self, timing: MemTiming) {
        self.mem_timing = timing;
    }

    /// Clock-gate the core until simulated time `t` (a cluster core asleep
    /// in the event unit, or not started yet): its cycle count jumps to the
    /// first edge at or after `t`, the cycles count as sleeping (not in
    /// `mcycle`, no instruction). Nothing happens if the core is past `t`.
    pub fn gate_until(&mut self, t: Picos) {
        let c = self.cycle_of(t);
        if c > self.cycles {
            self.stats.sleep_cycles += c - self.cycles;
            self.cycles = c;
        }
    }

    /// Restart at `pc` with every register zero and no pending sleep or
    /// load-use state (the cluster's FETCH_EN, docs/CLUSTER.md).
    pub fn restart(&mut self, pc: u32) {
        self.regs = [0; 32];
        self.load_mask = 0;
        self.privilege = Privilege::Machine;
        self.set_pc(pc);
    }

    pub fn config(&self) -> &CpuConfig {
        &self.cfg
    }

    /// Turn idle skipping on or off (e.g. for a comparison run).
    pub fn set_idle_skip(&mut self, on: bool) {
        self.cfg.idle_skip = on;
    }

    /// Where semihosting console output goes (the platform tees it to
    /// `console.log` and stdout).
    pub fn set_console(&mut self, console: Box<dyn Write + Send>) {
        self.semihost.set_console(console);
    }

    /// Flush the console sink.
    pub fn flush_console(&mut self) -> std::io::Result<()> {
        self.semihost.flush()
    }

    /// Address of the `tohost` word (riscv-tests convention), if any.
    pub fn set_tohost(&mut self, addr: Option<u32>) {
        self.tohost = addr;
    }

    /// Stop with [`StopReason::InstructionLimit`] once this many instructions
    /// have retired in total (skipped polling iterations included).
    pub fn set_instruction_limit(&mut self, limit: Option<u64>) {
        self.instr_deadline = limit.unwrap_or(u64::MAX);
    }

    pub fn pc(&self) -> u32 {
        self.pc
    }

    /// Jump to `pc` (reset vector, ELF entry). Clears any sleep.
    pub fn set_pc(&mut self, pc: u32) {
        self.pc = pc & !1;
        self.sleeping = false;
        self.poll.active = false;
    }

    pub fn reg(&self, i: usize) -> u32 {
        self.regs[i & 31]
    }

    pub fn set_reg(&mut self, i: usize, v: u32) {
        if i & 31 != 0 {
            self.regs[i & 31] = v;
        }
    }

    pub fn regs(&self) -> &[u32; 32] {
        &self.regs
    }

    pub fn privilege(&self) -> Privilege {
        self.privilege
    }

    /// Elapsed core clock cycles (including cycles asleep), the time base.
    pub fn cycles(&self) -> Cycles {
        Cycles(self.cycles)
    }

    /// Retired instructions.
    pub fn instret(&self) -> u64 {
        self.instret
    }

    /// Simulated time of the core: cycles × clock period.
    pub fn now(&self) -> Picos {
        Picos(self.cycles.saturating_mul(self.period))
    }

    pub fn stats(&self) -> CoreStats {
        CoreStats {
            instructions: self.instret,
            cycles: self.cycles,
            ..self.stats
        }
    }

    /// Whether the core is asleep in `wfi`.
    pub fn is_sleeping(&self) -> bool {
        self.sleeping
    }

    /// The level of the external interrupt line (mip.MEIP).
    pub fn set_external_irq(&mut self, level: bool) {
        self.meip = level;
    }

    /// Read a CSR as machine mode would (tests, debugging).
    pub fn csr(&self, csr: u16) -> Option<u32> {
        self.csr_read(csr)
    }

    fn mtime(&self) -> u64 {
        self.cycles.wrapping_add(self.mtime_off)
    }

    fn mip(&self) -> u32 {
        (self.msip as u32) << IRQ_MSI
            | ((self.mtime() >= self.mtimecmp) as u32) << IRQ_MTI
            | (self.meip as u32) << IRQ_MEI
    }

    /// First cycle at which the timer interrupt becomes pending, if it is
    /// enabled and not pending yet.
    fn timer_deadline(&self) -> u64 {
        if self.mie & (1 << IRQ_MTI) == 0 || self.mtime() >= self.mtimecmp {
            u64::MAX
        } else {
            self.mtimecmp.wrapping_sub(self.mtime_off)
        }
    }

    fn cycle_of(&self, t: Picos) -> u64 {
        if t == Picos::MAX {
            u64::MAX
        } else {
            div_ceil(t.0, self.period)
        }
    }

    fn refresh_event(&mut self, dev: &dyn Mmio) {
        self.event_cycle = dev.next_event().map_or(u64::MAX, |t| self.cycle_of(t));
        self.deadline = self.deadline.min(self.event_cycle);
    }

    /// Run until simulated time reaches `limit` (the first instruction
    /// boundary at or after it), or another [`StopReason`]. Like GVSoC's
    /// `step_until` as MESSY's core adapter uses it.
    pub fn run_until(&mut self, mem: &mut Memory, dev: &mut dyn Mmio, limit: Picos) -> StopReason {
        let limit_cycle = self.cycle_of(limit);
        // The cached code window may point into another Memory than this one.
        let window_ok = mem
            .regions
            .get(self.code_idx)
            .is_some_and(|r| r.base == self.code_base && r.size == self.code_size);
        if !window_ok {
            self.code_size = 0;
        }
        self.refresh_event(dev);
        loop {
            if let Some(r) = self.pending_stop.take() {
                return r;
            }
            let pending = self.mip() & self.mie;
            if pending != 0 {
                self.sleeping = false;
                if self.privilege == Privilege::User || self.mstatus & MSTATUS_MIE != 0 {
                    let code = [IRQ_MEI, IRQ_MSI, IRQ_MTI]
                        .into_iter()
                        .find(|&b| pending & (1 << b) != 0)
                        .unwrap_or(IRQ_MTI);
                    self.trap(mem, cause::INTERRUPT | code, 0, self.pc);
                    continue;
                }
            }
            if self.event_cycle <= self.cycles {
                return StopReason::Event;
            }
            if self.cycles >= limit_cycle {
                return StopReason::Limit;
            }
            if self.instret >= self.instr_deadline {
                return StopReason::InstructionLimit;
            }
            let deadline = limit_cycle.min(self.event_cycle).min(self.timer_deadline());
            if self.sleeping {
                if deadline == u64::MAX {
                    return StopReason::Idle;
                }
                let step = if self.cfg.idle_skip {
                    deadline - self.cycles
                } else {
                    1
                };
                self.cycles += step;
                self.stats.sleep_cycles += step;
                continue;
            }
            self.deadline = deadline;
            self.run_block(mem, dev);
        }
    }

    /// Run blocks until the deadline (or a break). Each block runs in
    /// [`Cpu::exec_block`]; what it cannot do (device and code accesses,
    /// system instructions) is done by [`Cpu::step`].
    fn run_block(&mut self, mem: &mut Memory, dev: &mut dyn Mmio) {
        // Every instruction costs at least one cycle and retires at most one
        // instruction, so bounding cycles by the remaining instruction budget
        // stops no later than the instruction limit, with the single
        // per-instruction comparison the deadline needs anyway; the run loop
        // checks the limit itself.
        let budget = self.instr_deadline - self.instret;
        self.deadline = self.deadline.min(self.cycles.saturating_add(budget));
        while self.cycles < self.deadline {
            let Some(first) = self.lookup(mem) else {
                continue; // the fetch trapped (and ended the run slice)
            };
            match self.exec_block(mem, first) {
                Exit::Poll { from, to } => self.poll_slow(mem, dev, from, to),
                Exit::General(inst) => self.step(mem, dev, inst),
                Exit::Paused => {}
            }
        }
    }

    /// The block at `pc` (index of its first instruction in `mem.insts`),
    /// through the cached code region when it holds one; `None` when the
    /// fetch faults (the trap has been taken).
    #[inline(always)]
    fn lookup(&mut self, mem: &mut Memory) -> Option<usize> {
        let off = self.pc.wrapping_sub(self.code_base);
        if off < self.code_size {
            // `code_size != 0` only while `code_idx` names a region of this
            // `mem` with these bounds (checked on entry to `run_until`).
            let id = mem.regions[self.code_idx].block_at[(off >> 1) as usize];
            if id != 0 {
                return Some(id as usize - 1);
            }
        }
        match mem.block(self.pc) {
            Ok((idx, first)) => {
                let r = &mem.regions[idx];
                self.code_idx = idx;
                self.code_base = r.base;
                self.code_size = r.size;
                Some(first)
            }
            Err(FetchFault(addr)) => {
                self.trap(mem, cause::FETCH_ACCESS, addr, self.pc);
                None
            }
        }
    }

    /// Whether the block at `insts[first]` starts with a load-use
    /// stall behind the instruction before it (1 or 0). Nothing in the
    /// load shadow (a transfer, a non-load) is the common case and needs
    /// no look at the block (a cache miss per cluster quantum otherwise).
    #[inline(always)]
    fn entry_stall(&self, insts: &[Inst], first: usize) -> u64 {
        (self.load_mask != 0 && insts[first].reads() & self.load_mask != 0) as u64
    }

    /// Stop the inner loop after the current instruction.
    #[inline(always)]
    fn break_block(&mut self) {
        self.deadline = 0;
    }

    fn stop(&mut self, r: StopReason) {
        if self.pending_stop.is_none() {
            self.pending_stop = Some(r);
        }
        self.break_block();
    }

    /// Run the block whose first instruction is `mem.insts[first]`, from
    /// `self.pc` = its start, and the blocks it leads to, until the deadline
    /// (checked after every instruction, so the run stops on the same
    /// instruction boundary as a one-by-one run), a block not cached yet, a
    /// loop the idle detector wants to see, or an instruction that needs the
    /// general path: a load or store outside RAM, a store near cached code
    /// or to `tohost`, a system instruction. That one is handed back
    /// unexecuted, with the core's state as it was just before it.
    fn exec_block(&mut self, mem: &mut Memory, first: usize) -> Exit {
        // The translator first (`jit_run.rs`), except in a loop the idle
        // detector is measuring (after a device read it runs too, and
        // reports short backward branches as the interpreter does).
        #[cfg(target_arch = "x86_64")]
        let deadline = if self.cfg.iss == Backend::Jit && !self.poll.active {
            match self.run_translated(mem, first) {
                jit_run::Translated::Ran => return Exit::Paused,
                jit_run::Translated::Poll { from, to } => return Exit::Poll { from, to },
                // The interpreter does what the translator does not take,
                // and a little more before handing back (a pause at an
                // instruction boundary, like the end of a run slice: it
                // changes nothing), so code the translator keeps leaving
                // does not bounce between the two at every block.
                jit_run::Translated::Uncovered => self
                    .deadline
                    .min(self.cycles.saturating_add(jit_run::RETURN_BUDGET)),
                jit_run::Translated::TooLong => self.deadline,
            }
        } else {
            self.deadline
        };
        #[cfg(not(target_arch = "x86_64"))]
        let deadline = self.deadline;
        let mut run = exec::Run::new(&mut mem.regions, &mem.insts);
        run.set_timing(self.mem_timing, mem.tcdm.as_mut());
        if self.code_size != 0 {
            run.set_code_region(self.code_idx);
        }
        run.tohost = self.tohost;
        run.poll_armed = self.poll.touched || self.poll.active;
        // The one load-use stall a block cannot know: behind whatever
        // instruction ran before it.
        let stall = self.entry_stall(&mem.insts, first);
        let entry = self.cycles;
        let cycles = entry + stall * timing::LOAD_USE_STALL;
        let flow = exec::run(&mut run, &mut self.regs, first, entry, cycles, deadline);
        self.cycles = run.cycles;
        self.pc = run.pc;
        self.instret += run.retired;
        self.jumps += run.jumps;
        if let Some(m) = run.load_mask {
            self.load_mask = m;
        }
        match flow {
            exec::Flow::Poll => Exit::Poll {
                from: run.poll_from,
                to: run.pc,
            },
            exec::Flow::General => Exit::General(run.general.expect("general path instruction")),
            exec::Flow::Paused | exec::Flow::Chain => Exit::Paused,
        }
    }

    /// Enter the trap handler. `epc` is the pc to save in mepc.
    fn trap(&mut self, mem: &mut Memory, mcause: u32, tval: u32, epc: u32) {
        self.mepc = epc & !1;
        self.mcause = mcause;
        self.mtval = tval;
        let mie = (self.mstatus & MSTATUS_MIE) != 0;
        self.mstatus &= !(MSTATUS_MIE | MSTATUS_MPIE | MSTATUS_MPP);
        self.mstatus |= ((mie as u32) * MSTATUS_MPIE) | ((self.privilege as u32) << 11);
        self.privilege = Privilege::Machine;
        let base = self.mtvec & !3;
        self.pc = if self.mtvec & 3 == 1 && mcause & cause::INTERRUPT != 0 {
            base.wrapping_add(4 * (mcause & 0x3ff))
        } else {
            base
        };
        self.cycles += timing::TRAP_ENTRY;
        self.load_mask = 0;
        self.poll.active = false;
        self.break_block();
        if !mem.is_ram(self.pc, 2) {
            self.stop(StopReason::Fatal(IssError::UnhandledTrap {
                cause: mcause,
                pc: epc,
                tval,
                handler: self.pc,
            }));
        }
        tracing::trace!(mcause, tval, epc, "trap");
    }

    /// The general path: execute one instruction the block loop handed
    /// back (a load, a store or a system instruction) with everything it
    /// may involve: device accesses at their simulated time, `tohost`,
    /// stores into code, CSRs, traps, semihosting.
    fn step(&mut self, mem: &mut Memory, dev: &mut dyn Mmio, inst: Inst) {
        let (cycles, load_mask) = (self.cycles, self.load_mask);
        self.step_inner(mem, dev, inst);
        if self.waited {
            // Not executed: it is retried with the same cost later.
            self.waited = false;
            self.cycles = cycles;
            self.load_mask = load_mask;
        }
    }

    fn step_inner(&mut self, mem: &mut Memory, dev: &mut dyn Mmio, inst: Inst) {
        let stall = (inst.reads() & self.load_mask != 0) as u64;
        self.cycles += BASE_CYCLES[inst.op as usize] as u64 + stall * timing::LOAD_USE_STALL;
        self.load_mask = 0;
        let pc = inst.pc;
        let rd = (inst.rd & 31) as usize;
        let a = self.regs[(inst.rs1 & 31) as usize];
        let b = self.regs[(inst.rs2 & 31) as usize];
        let mut next = pc.wrapping_add(inst.len as u32);
        // Address and base write-back of a load or store (RV32I: rs1 + imm;
        // the XCV forms: `xcv::mem`, register operand rs2 for loads, rs3 =
        // the rd field for stores).
        let (o, mode) = match xcv::mem::base_op(inst.op) {
            Some(base) => (base, xcv::mem::mode(inst.op)),
            None => (inst.op, xcv::mem::Mode::Offset),
        };
        let reg = if (op::SB..=op::SW).contains(&o) {
            self.regs[rd]
        } else {
            b
        };
        let (addr, wb) = xcv::mem::address(mode, a, reg, inst.imm);
        let rs1 = (inst.rs1 & 31) as usize;
        macro_rules! load {
            ($size:expr, $conv:expr) => {{
                let v = match mem.load_ram(addr, $size) {
                    Some(v) => {
                        // Arbitrated at the issue cycle, before a split's
                        // second transfer (as the block executor does).
                        self.cycles += self.ram_extra(mem, addr);
                        self.cycles += timing::split_cost(addr, $size);
                        v
                    }
                    None => match self.load_slow(mem, dev, addr, $size, pc) {
                        Some(v) => v,
                        None => return,
                    },
                };
                if let Some(w) = wb {
                    self.regs[rs1] = w;
                }
                self.regs[rd] = $conv(v);
                self.regs[0] = 0;
                self.load_mask = inst.load_mask();
            }};
        }
        macro_rules! store {
            ($size:expr) => {{
                let watched = self.tohost.is_some_and(|t| addr.wrapping_sub(t) < 8);
                if !watched && mem.store_ram(addr, $size, b) {
                    self.cycles += self.ram_extra(mem, addr);
                    self.cycles += timing::split_cost(addr, $size);
                } else if !self.store_slow(mem, dev, addr, $size, b, pc) {
                    return;
                }
                if let Some(w) = wb {
                    self.regs[rs1] = w;
                    self.regs[0] = 0;
                }
            }};
        }
        match o {
            op::LB => load!(AccessSize::Byte, |v: u32| v as u8 as i8 as i32 as u32),
            op::LH => load!(AccessSize::Half, |v: u32| v as u16 as i16 as i32 as u32),
            op::LW => load!(AccessSize::Word, |v: u32| v),
            op::LBU => load!(AccessSize::Byte, |v: u32| v),
            op::LHU => load!(AccessSize::Half, |v: u32| v),
            op::SB => store!(AccessSize::Byte),
            op::SH => store!(AccessSize::Half),
            op::SW => store!(AccessSize::Word),
            _ => match self.step_system(mem, dev, inst.decoded(), pc, a) {
                Sys::Trapped => return,
                Sys::Next(v) => {
                    if let Some(v) = v {
                        self.regs[rd] = v;
                        self.regs[0] = 0;
                    }
                }
                Sys::Jump(t) => {
                    next = t;
                    self.jumps += 1;
                }
            },
        }
        self.pc = next;
        self.instret += 1;
    }
}

/// How [`Cpu::exec_block`] left its block.
enum Exit {
    /// A taken backward branch from `from` to `to` retired and closes a
    /// loop the idle detector wants to see ([`Cpu::poll_slow`]).
    Poll { from: u32, to: u32 },
    /// At an instruction boundary: the deadline passed, or the next block
    /// is not cached yet.
    Paused,
    /// This instruction needs [`Cpu::step`]; the core is just before it.
    General(Inst),
}

/// Outcome of a system instruction.
enum Sys {
    /// It trapped (or stopped); the instruction does not retire.
    Trapped,
    /// It retired; write this value to rd if any.
    Next(Option<u32>),
    /// It retired and jumps to this pc (mret).
    Jump(u32),
}

const CSR_MSTATUS: u16 = 0x300;
const CSR_MISA: u16 = 0x301;
const CSR_MIE: u16 = 0x304;
const CSR_MTVEC: u16 = 0x305;
const CSR_MCOUNTEREN: u16 = 0x306;
const CSR_MSTATUSH: u16 = 0x310;
const CSR_MSCRATCH: u16 = 0x340;
const CSR_MEPC: u16 = 0x341;
const CSR_MCAUSE: u16 = 0x342;
const CSR_MTVAL: u16 = 0x343;
const CSR_MIP: u16 = 0x344;
const CSR_MCYCLE: u16 = 0xb00;
const CSR_MINSTRET: u16 = 0xb02;
const CSR_MCYCLEH: u16 = 0xb80;
const CSR_MINSTRETH: u16 = 0xb82;
const CSR_CYCLE: u16 = 0xc00;
const CSR_TIME: u16 = 0xc01;
const CSR_INSTRET: u16 = 0xc02;
const CSR_CYCLEH: u16 = 0xc80;
const CSR_TIMEH: u16 = 0xc81;
const CSR_INSTRETH: u16 = 0xc82;
const CSR_MVENDORID: u16 = 0xf11;
const CSR_MARCHID: u16 = 0xf12;
const CSR_MIMPID: u16 = 0xf13;
const CSR_MHARTID: u16 = 0xf14;

impl Cpu {
    /// mcycle counts only cycles the core is awake: CV32E40P's counters run
    /// on the gated clock, which `wfi` stops (manual, "Performance
    /// Counters").
    fn mcycle(&self) -> u64 {
        (self.cycles - self.stats.sleep_cycles).wrapping_add(self.mcycle_off)
    }

    fn minstret(&self) -> u64 {
        self.instret.wrapping_add(self.minstret_off)
    }

    fn csr_read(&self, csr: u16) -> Option<u32> {
        Some(match csr {
            CSR_MSTATUS => self.mstatus,
            CSR_MISA => MISA,
            CSR_MIE => self.mie,
            CSR_MTVEC => self.mtvec,
            CSR_MCOUNTEREN => self.mcounteren,
            CSR_MSTATUSH => 0,
            CSR_MSCRATCH => self.mscratch,
            CSR_MEPC => self.mepc,
            CSR_MCAUSE => self.mcause,
            CSR_MTVAL => self.mtval,
            CSR_MIP => self.mip(),
            CSR_MCYCLE | CSR_CYCLE => self.mcycle() as u32,
            CSR_MCYCLEH | CSR_CYCLEH => (self.mcycle() >> 32) as u32,
            CSR_MINSTRET | CSR_INSTRET => self.minstret() as u32,
            CSR_MINSTRETH | CSR_INSTRETH => (self.minstret() >> 32) as u32,
            CSR_TIME => self.mtime() as u32,
            CSR_TIMEH => (self.mtime() >> 32) as u32,
            CSR_MVENDORID | CSR_MARCHID | CSR_MIMPID => 0,
            CSR_MHARTID => self.cfg.hart_id,
            _ => return None,
        })
    }

    fn csr_write(&mut self, csr: u16, v: u32) {
        // Writes that may enable an interrupt end the block so the run loop
        // re-evaluates pending interrupts and the timer deadline.
        self.break_block();
        match csr {
            CSR_MSTATUS => {
                let mut new = (self.mstatus & !MSTATUS_WRITABLE) | (v & MSTATUS_WRITABLE);
                // MPP is WARL with legal values U (0) and M (3); keep the
                // old value on anything else.
                let mpp = (new & MSTATUS_MPP) >> 11;
                if mpp != 0 && mpp != 3 {
                    new = (new & !MSTATUS_MPP) | (self.mstatus & MSTATUS_MPP);
                }
                self.mstatus = new;
            }
            CSR_MIE => self.mie = v & MIE_WRITABLE,
            // Modes 0 (direct) and 1 (vectored); reserved modes read as 0.
            CSR_MTVEC => self.mtvec = if v & 3 >= 2 { v & !3 } else { v },
            CSR_MCOUNTEREN => self.mcounteren = v & 7,
            CSR_MSCRATCH => self.mscratch = v,
            CSR_MEPC => self.mepc = v & !1,
            CSR_MCAUSE => self.mcause = v,
            CSR_MTVAL => self.mtval = v,
            CSR_MCYCLE => {
                let new = (self.mcycle() & !0xffff_ffff) | v as u64;
                self.mcycle_off = new.wrapping_sub(self.cycles - self.stats.sleep_cycles);
            }
            CSR_MCYCLEH => {
                let new = (self.mcycle() & 0xffff_ffff) | (v as u64) << 32;
                self.mcycle_off = new.wrapping_sub(self.cycles - self.stats.sleep_cycles);
            }
            // minstret is written by an instruction that itself retires
            // afterwards; the value written is what the next instruction
            // reads, so compensate for that increment.
            CSR_MINSTRET => {
                let new = (self.minstret() & !0xffff_ffff) | v as u64;
                self.minstret_off = new.wrapping_sub(self.instret + 1);
            }
            CSR_MINSTRETH => {
                let new = (self.minstret() & 0xffff_ffff) | (v as u64) << 32;
                self.minstret_off = new.wrapping_sub(self.instret + 1);
            }
            // misa, mstatush, mip and the ID registers ignore writes.
            _ => {}
        }
    }

    fn illegal(&mut self, mem: &mut Memory, raw: u32, pc: u32) -> Sys {
        self.trap(mem, cause::ILLEGAL_INSTRUCTION, raw, pc);
        Sys::Trapped
    }

    #[cold]
    fn step_system(
        &mut self,
        mem: &mut Memory,
        _dev: &mut dyn Mmio,
        d: Decoded,
        pc: u32,
        a: u32,
    ) -> Sys {
        let machine = self.privilege == Privilege::Machine;
        match d.op {
            op::ECALL => {
                let c = if machine {
                    cause::ECALL_M
                } else {
                    cause::ECALL_U
                };
                self.trap(mem, c, 0, pc);
                Sys::Trapped
            }
            op::EBREAK => {
                let around = (
                    mem.read_u32(pc.wrapping_sub(4)),
                    mem.read_u32(pc.wrapping_add(4)),
                );
                if !d.compressed
                    && around == (Some(semihost::SEMIHOST_PRE), Some(semihost::SEMIHOST_POST))
                {
                    return self.semihosting(mem);
                }
                if self.cfg.ebreak_stops {
                    self.stop(StopReason::Breakpoint { pc });
                    return Sys::Trapped;
                }
                self.trap(mem, cause::BREAKPOINT, pc, pc);
                Sys::Trapped
            }
            op::MRET if machine => {
                let mpie = self.mstatus & MSTATUS_MPIE != 0;
                self.privilege = if self.mstatus & MSTATUS_MPP == MSTATUS_MPP {
                    Privilege::Machine
                } else {
                    Privilege::User
                };
                self.mstatus &= !(MSTATUS_MIE | MSTATUS_MPP);
                self.mstatus |= MSTATUS_MPIE | ((mpie as u32) * MSTATUS_MIE);
                // MPRV is cleared when returning to a less-privileged mode.
                if self.privilege == Privilege::User {
                    self.mstatus &= !MSTATUS_MPRV;
                }
                self.break_block();
                Sys::Jump(self.mepc)
            }
            // wfi in user mode traps at once: the spec allows an
            // implementation-defined time limit, ours is zero.
            op::WFI if machine => {
                if self.mip() & self.mie == 0 {
                    self.sleeping = true;
                    self.break_block();
                }
                Sys::Next(None)
            }
            op::CSRRW | op::CSRRS | op::CSRRC | op::CSRRWI | op::CSRRSI | op::CSRRCI => {
                let csr = (d.imm & 0xfff) as u16;
                let imm_form = d.op >= op::CSRRWI;
                let src = if imm_form {
                    (d.imm as u32 >> 12) & 31
                } else {
                    a
                };
                let writes = match d.op {
                    op::CSRRW | op::CSRRWI => true,
                    op::CSRRS | op::CSRRC => d.rs1 != 0,
                    _ => src != 0,
                };
                let raw = self.raw_at(mem, pc, d);
                let level = (csr >> 8) & 3;
                if level > self.privilege as u16 || (writes && csr >> 10 == 3) {
                    return self.illegal(mem, raw, pc);
                }
                // User access to the counters needs mcounteren.
                if !machine && (CSR_CYCLE..=CSR_INSTRETH).contains(&csr) {
                    let bit = (csr & 0x1f) as u32;
                    if bit > 2 || self.mcounteren & (1 << bit) == 0 {
                        return self.illegal(mem, raw, pc);
                    }
                }
                let Some(old) = self.csr_read(csr) else {
                    return self.illegal(mem, raw, pc);
                };
                if timing::slow_csr(csr) {
                    self.cycles += timing::SLOW_CSR_EXTRA;
                }
                if writes {
                    let new = match d.op {
                        op::CSRRW | op::CSRRWI => src,
                        op::CSRRS | op::CSRRSI => old | src,
                        _ => old & !src,
                    };
                    self.csr_write(csr, new);
                }
                Sys::Next(Some(old))
            }
            _ => {
                let raw = if d.op == op::ILLEGAL {
                    d.imm as u32
                } else {
                    self.raw_at(mem, pc, d)
                };
                self.illegal(mem, raw, pc)
            }
        }
    }

    /// The raw bits of the instruction at pc (for mtval on illegal
    /// instructions that decoded to a known op, e.g. mret in user mode).
    fn raw_at(&self, mem: &Memory, pc: u32, d: Decoded) -> u32 {
        let mut b = [0u8; 4];
        let n = d.len() as usize;
        if mem.read_bytes(pc, &mut b[..n]).is_err() {
            return 0;
        }
        u32::from_le_bytes(b)
    }

    #[cold]
    fn semihosting(&mut self, mem: &mut Memory) -> Sys {
        let clock = semihost::Clock {
            now: self.now(),
            cycles: self.cycles,
            hz: self.cfg.clock.0,
        };
        match self.semihost.call(self.regs[10], self.regs[11], mem, clock) {
            Ok(semihost::Outcome::Return(v)) => {
                self.regs[10] = v;
                Sys::Next(None)
            }
            Ok(semihost::Outcome::Exit(code)) => {
                self.stop(StopReason::Exit { code });
                Sys::Next(None)
            }
            Err(e) => {
                self.stop(StopReason::Fatal(IssError::Console(e.to_string())));
                Sys::Trapped
            }
        }
    }

    /// The cycle at which the current load/store issued: the table charges
    /// loads and stores 1 cycle, already added.
    fn issue_cycle(&self) -> u64 {
        self.cycles - 1
    }

    /// Extra cycles of a general-path RAM access (see [`MemTiming`]).
    fn ram_extra(&self, mem: &mut Memory, addr: u32) -> u64 {
        if self.mem_timing.is_plain() {
            return 0;
        }
        self.mem_timing
            .extra(mem.tcdm.as_mut(), addr, self.issue_cycle())
    }

    fn mmio_time(&self, issue: u64) -> Picos {
        Picos((issue + self.latency).saturating_mul(self.period))
    }

    /// One access to an MMIO window issued at cycle `issue`: charges the
    /// peripheral latency, performs it at its access time, then honours a
    /// stop request and picks up a newly scheduled event. `None`: the device
    /// answered with an access fault (the caller traps); `Some(Err(()))`: the
    /// device failed and the run stops.
    fn mmio_access(
        &mut self,
        dev: &mut dyn Mmio,
        issue: u64,
        access: impl FnOnce(&mut dyn Mmio, Picos) -> Result<u32, MmioError>,
    ) -> Option<Result<u32, ()>> {
        self.cycles += self.latency;
        let result = access(dev, self.mmio_time(issue));
        if dev.take_stop_request() {
            self.stop(StopReason::DeviceRequest);
        }
        self.refresh_event(dev);
        match result {
            Ok(v) => Some(Ok(v)),
            Err(MmioError::AccessFault { .. }) => None,
            Err(MmioError::Wait { .. }) => {
                self.waited = true;
                self.stop(StopReason::Wait);
                Some(Err(()))
            }
            Err(e) => {
                self.stop(StopReason::Fatal(e.into()));
                Some(Err(()))
            }
        }
    }

    #[cold]
    fn load_slow(
        &mut self,
        mem: &mut Memory,
        dev: &mut dyn Mmio,
        addr: u32,
        size: AccessSize,
        pc: u32,
    ) -> Option<u32> {
        let issue = self.issue_cycle();
        if addr.wrapping_sub(CLINT_BASE) < CLINT_SIZE {
            self.poll.touched = true;
            self.poll.unskippable = true;
            if let Some(v) = self.clint_read(addr - CLINT_BASE, size) {
                return Some(v);
            }
        } else if mem.is_mmio(addr) {
            match self.mmio_access(dev, issue, |d, now| d.read(addr, size, now)) {
                Some(Ok(v)) => {
                    self.record_poll_read(addr, size, issue);
                    return Some(v);
                }
                Some(Err(())) => return None,
                None => {}
            }
        }
        self.trap(mem, cause::LOAD_ACCESS, addr, pc);
        None
    }

    #[cold]
    fn store_slow(
        &mut self,
        mem: &mut Memory,
        dev: &mut dyn Mmio,
        addr: u32,
        size: AccessSize,
        value: u32,
        pc: u32,
    ) -> bool {
        let issue = self.issue_cycle();
        if mem.store_ram(addr, size, value) {
            self.cycles += self.ram_extra(mem, addr);
            self.cycles += timing::split_cost(addr, size);
            if let Some(th) = self.tohost {
                // riscv-tests: a non-zero tohost ends the test; 1 is a pass,
                // any other odd value v a failure of test v >> 1.
                match mem.read_u32(th) {
                    Some(0) | None => {}
                    Some(1) => self.stop(StopReason::Exit { code: 0 }),
                    Some(v) if v & 1 == 1 => self.stop(StopReason::Exit {
                        code: ((v >> 1) as i32).max(1),
                    }),
                    Some(v) => tracing::warn!(value = v, "even tohost value ignored"),
                }
            }
            return true;
        }
        if addr.wrapping_sub(CLINT_BASE) < CLINT_SIZE {
            if self.clint_write(addr - CLINT_BASE, size, value) {
                return true;
            }
        } else if mem.is_mmio(addr) {
            let write = |d: &mut dyn Mmio, now| d.write(addr, size, value, now).map(|()| 0);
            if let Some(r) = self.mmio_access(dev, issue, write) {
                return r.is_ok();
            }
        }
        self.trap(mem, cause::STORE_ACCESS, addr, pc);
        false
    }

    fn clint_read(&self, off: u32, size: AccessSize) -> Option<u32> {
        if size != AccessSize::Word {
            return None;
        }
        Some(match off {
            CLINT_MSIP => self.msip as u32,
            CLINT_MTIMECMP => self.mtimecmp as u32,
            o if o == CLINT_MTIMECMP + 4 => (self.mtimecmp >> 32) as u32,
            CLINT_MTIME => self.mtime() as u32,
            o if o == CLINT_MTIME + 4 => (self.mtime() >> 32) as u32,
            _ => return None,
        })
    }

    fn clint_write(&mut self, off: u32, size: AccessSize, v: u32) -> bool {
        if size != AccessSize::Word {
            return false;
        }
        let lo = |x: u64| (x & !0xffff_ffff) | v as u64;
        let hi = |x: u64| (x & 0xffff_ffff) | (v as u64) << 32;
        match off {
            CLINT_MSIP => self.msip = v & 1 != 0,
            CLINT_MTIMECMP => self.mtimecmp = lo(self.mtimecmp),
            o if o == CLINT_MTIMECMP + 4 => self.mtimecmp = hi(self.mtimecmp),
            CLINT_MTIME => self.mtime_off = lo(self.mtime()).wrapping_sub(self.cycles),
            o if o == CLINT_MTIME + 4 => {
                self.mtime_off = hi(self.mtime()).wrapping_sub(self.cycles)
            }
            _ => return false,
        }
        self.break_block();
        true
    }
}

#[cfg(target_arch = "x86_64")]
mod jit_run;
mod poll;
use poll::PollTracker;
