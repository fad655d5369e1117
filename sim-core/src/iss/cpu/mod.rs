//! The core: architectural state, traps, the timed interpreter loop and
//! exact idle skipping. Beside it, by concept: `config.rs` (what a core is
//! built with), `outcome.rs` (counters, stop reasons, errors), `csr.rs`
//! and `trigger.rs` (the CSRs), `system.rs` (the system instructions),
//! `access.rs` (loads and stores off the fast path, the CLINT), `poll.rs`
//! (idle detection), `jit_run.rs` (the translator's side of the run loop).

use std::io::Write;

use crate::units::{Cycles, Hertz, Picos};

use super::block::{FetchFault, Inst};
use super::code::CodeCache;
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
    /// Instructions retired in translated code (`jit_run.rs`); the rest of
    /// `instret` the interpreter retired or idle skipping jumped over.
    translated: u64,
    stats: CoreStats,
    /// One-hot mask of the register the previous instruction loaded (0 if
    /// it was not a load or loaded x0): the load-use stall check.
    load_mask: u32,
    sleeping: bool,
    /// `wfi` ends the run slice ([`Cpu::set_stop_on_sleep`]).
    stop_on_sleep: bool,
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
            translated: 0,
            stats: CoreStats::default(),
            load_mask: 0,
            sleeping: false,
            stop_on_sleep: false,
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

    /// Instructions retired in translated code so far (0 under the
    /// interpreter): how much of a run the translator took, for tests and
    /// profiling. Not part of [`CoreStats`], which both back ends give
    /// alike.
    pub fn translated_instructions(&self) -> u64 {
        self.translated
    }

    /// Whether the core is asleep in `wfi`.
    pub fn is_sleeping(&self) -> bool {
        self.sleeping
    }

    /// The level of the external interrupt line (mip.MEIP).
    pub fn set_external_irq(&mut self, level: bool) {
        self.meip = level;
    }

    /// The level [`Cpu::set_external_irq`] last set.
    pub fn external_irq(&self) -> bool {
        self.meip
    }

    /// With `true`, a `wfi` that puts the core to sleep ends the current
    /// run slice ([`StopReason::Wait`]) instead of sleeping to its end: the
    /// cluster's scheduler then decides how far the FC may sleep, since a
    /// cluster core may wake it (docs/CLUSTER.md, `FC_IRQ`).
    pub fn set_stop_on_sleep(&mut self, on: bool) {
        self.stop_on_sleep = on;
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
    /// `step_until` as MESSY's core adapter uses it. `code` is the code
    /// cache kept beside `mem` (shared by every core on it).
    pub fn run_until(
        &mut self,
        mem: &mut Memory,
        code: &mut CodeCache,
        dev: &mut dyn Mmio,
        limit: Picos,
    ) -> StopReason {
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
            self.run_block(mem, code, dev);
        }
    }

    /// Run blocks until the deadline (or a break). Each block runs in
    /// [`Cpu::exec_block`]; what it cannot do (device and code accesses,
    /// system instructions) is done by [`Cpu::step`].
    fn run_block(&mut self, mem: &mut Memory, code: &mut CodeCache, dev: &mut dyn Mmio) {
        // Every instruction costs at least one cycle and retires at most one
        // instruction, so bounding cycles by the remaining instruction budget
        // stops no later than the instruction limit, with the single
        // per-instruction comparison the deadline needs anyway; the run loop
        // checks the limit itself.
        let budget = self.instr_deadline - self.instret;
        self.deadline = self.deadline.min(self.cycles.saturating_add(budget));
        while self.cycles < self.deadline {
            let Some(first) = self.lookup(mem, code) else {
                continue; // the fetch trapped (and ended the run slice)
            };
            match self.exec_block(mem, code, dev, first) {
                Exit::Poll { from, to } => self.poll_slow(mem, dev, from, to),
                Exit::General(inst) => self.step(mem, dev, inst),
                Exit::Paused => {}
            }
        }
    }

    /// The block at `pc` (index of its first instruction in `code.insts`),
    /// through the cached code region when it holds one; `None` when the
    /// fetch faults (the trap has been taken). The cache is brought up to
    /// date with memory first: the general path may just have stored into
    /// code.
    #[inline(always)]
    fn lookup(&mut self, mem: &mut Memory, code: &mut CodeCache) -> Option<usize> {
        code.sync(mem);
        let off = self.pc.wrapping_sub(self.code_base);
        if off < self.code_size {
            // `code_size != 0` only while `code_idx` names a region of this
            // `mem` with these bounds (checked on entry to `run_until`).
            let id = code.start(self.code_idx, off as usize);
            if id != 0 {
                return Some(id as usize - 1);
            }
        }
        match code.block(mem, self.pc) {
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

    /// Run the block whose first instruction is `code.insts[first]`, from
    /// `self.pc` = its start, and the blocks it leads to, until the deadline
    /// (checked after every instruction, so the run stops on the same
    /// instruction boundary as a one-by-one run), a block not cached yet, a
    /// loop the idle detector wants to see, or an instruction that needs the
    /// general path: a load or store outside RAM, a store near cached code
    /// or to `tohost`, a system instruction. That one is handed back
    /// unexecuted, with the core's state as it was just before it.
    fn exec_block(
        &mut self,
        mem: &mut Memory,
        code: &mut CodeCache,
        dev: &mut dyn Mmio,
        first: usize,
    ) -> Exit {
        // The translator first (`jit_run.rs`), except in a loop the idle
        // detector is measuring (after a device read it runs too, and
        // reports short backward branches as the interpreter does).
        #[cfg(target_arch = "x86_64")]
        let deadline = if self.cfg.iss == Backend::Jit && !self.poll.active {
            // The FC's translations read the device window (a core has none).
            let window = if self.mem_timing.l1_port.is_none() {
                dev.plain_window()
            } else {
                None
            };
            match self.run_translated(mem, code, first, window) {
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
        let mut run = exec::Run::new(&mut mem.regions, &code.insts);
        run.set_timing(self.mem_timing, mem.l1_arbiter.as_deref_mut());
        if self.code_size != 0 {
            run.set_code_region(self.code_idx, &code.starts);
        }
        if let Some((base, bytes)) = dev.plain_window() {
            run.set_window(base, bytes, self.latency);
        }
        run.tohost = self.tohost;
        run.poll_armed = self.poll.touched || self.poll.active;
        // The one load-use stall a block cannot know: behind whatever
        // instruction ran before it.
        let stall = self.entry_stall(&code.insts, first);
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
            // Only a self-loop comes here (`Inst::is_self_loop`).
            op::BEQ..=op::BGEU | op::JAL | op::CV_BEQIMM | op::CV_BNEIMM => {
                match self.step_self_loop(inst, a, b) {
                    Some(to) => next = to,
                    None => return,
                }
            }
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

mod access;
mod config;
mod csr;
#[cfg(target_arch = "x86_64")]
mod jit_run;
mod outcome;
mod poll;
mod system;
mod trigger;
use poll::PollTracker;

pub use config::{Backend, CpuConfig};
pub use outcome::{cause_name, CoreStats, IssError, StopReason, Stuck};
