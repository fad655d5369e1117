//! The block executor: runs cached blocks (`block.rs`) as threaded code.
//!
//! Every op has its own small handler function; a handler does its
//! instruction and then calls the next instruction's handler itself, as its
//! last act (a tail call, which the optimiser turns into a jump). So each
//! handler ends in its own indirect jump, and the host's branch predictor
//! learns per op what tends to follow it: on the CPU-bound benchmark this
//! predicts far better than one shared `match` in a loop (measured: see the
//! ISS notes in `docs/ARCHITECTURE.md`). Everything that changes per
//! instruction travels in argument registers (`regs`, the instruction
//! pointer, `cycles`, `deadline`); the rest sits in [`Run`], touched only on
//! control transfers and exits.
//!
//! The tail calls stay within one block (at most
//! [`MAX_BLOCK_INSTS`](super::block::MAX_BLOCK_INSTS) deep even if a build
//! did not optimise them); going on to the next block returns to the
//! trampoline in [`run`].

use super::block::Inst;
use super::code::Starts;
use super::decode::op;
use super::l1::BankArbiter;
use super::mem::{ram_load, ram_store_data, AccessSize, MemTiming, Region};
use super::timing;
use super::xcv::mem::{address, Mode};

/// What one [`run`] leaves for the core.
pub(super) struct Run<'a> {
    pub regions: &'a mut [Region],
    /// All cached instructions (blocks are slices of it).
    pub all: &'a [Inst],
    /// The code region's block index (`Starts::at`), so blocks there
    /// chain without the core: `(base, size in bytes, entries)`.
    code_base: u32,
    code_size: u32,
    block_at: *const u32,
    /// Stores here (8 bytes) go to the core's general path.
    pub tohost: Option<u32>,
    /// The idle detector wants to see taken backward branches.
    pub poll_armed: bool,
    /// The cycle count on entering the running block (before any entry
    /// stall).
    entry: u64,
    /// Blocks entered by a direct tail call since the trampoline last ran.
    chains: u32,
    /// Instructions retired and jumps taken so far.
    pub retired: u64,
    pub jumps: u64,
    /// Where the core stands on the way out.
    pub cycles: u64,
    pub pc: u32,
    /// The load-use state to leave (`None`: keep the core's).
    pub load_mask: Option<u32>,
    /// For [`Flow::General`]: the instruction to do on the general path.
    pub general: Option<Inst>,
    /// For [`Flow::Poll`]: the branch's address.
    pub poll_from: u32,
    /// For [`Flow::Chain`]: the next block's first instruction.
    chain: *const Inst,
    /// The RAM region the code runs from, where most data lives too.
    fast: FastRam,
    /// The core's view of memory (extra cycles, L1 banks); the default
    /// costs nothing.
    timing: MemTiming,
    arbiter: Option<&'a mut (dyn BankArbiter + 'static)>,
    /// Device registers that read like memory (`Mmio::plain_window`):
    /// their base, their bytes, and the MMIO latency a read of them costs.
    window: (u32, &'a [u8]),
    window_latency: u64,
}

/// Direct access to one RAM region, for the loads and stores of the hot
/// path (the others search every region). The buffer is never reallocated
/// while a [`Run`] exists (regions are fixed in size), and while it exists
/// all accesses to it go through this pointer or through `Run::regions`
/// one at a time.
#[derive(Clone, Copy)]
struct FastRam {
    ptr: *mut u8,
    base: u32,
    /// Size in bytes (0: no region).
    size: u32,
    /// Byte offsets `[code_lo, code_hi)` holding cached code: stores there
    /// take the general path, which keeps the block cache coherent.
    code_lo: u32,
    code_hi: u32,
    /// Extra cycles of every access (a cluster core's L2 latency).
    extra: u64,
}

impl FastRam {
    /// Offset of an `n`-byte access at `addr`, if inside.
    #[inline(always)]
    fn offset(&self, addr: u32, n: u32) -> Option<usize> {
        let off = addr.wrapping_sub(self.base);
        ((off as u64) + (n as u64) <= self.size as u64).then_some(off as usize)
    }
}

/// Why [`run`] returned. A bare byte, so handlers return it in a register
/// and their calls to the next handler can be tail calls; the details are
/// in [`Run`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(super) enum Flow {
    /// At an instruction boundary: the deadline passed, the block ran out,
    /// or the next block is not cached.
    Paused,
    /// A taken backward branch from `Run::poll_from` to `Run::pc` closes a
    /// loop the idle detector wants to see.
    Poll,
    /// `Run::general` needs the general path; the core is just before it.
    General,
    /// Go on at `Run::chain` (internal: [`run`]'s trampoline).
    Chain,
}

/// Runs the instruction at the pointer (and, by tail calls, the ones after
/// it): `(run, registers, instruction, cycles, deadline)`.
pub(super) type Handler = fn(&mut Run, &mut [u32; 32], *const Inst, u64, u64) -> Flow;

/// Blocks entered in a row by tail calls before going through the
/// trampoline (see [`transfer`]).
const MAX_DIRECT_CHAINS: u32 = 16;

/// The handler of an op code.
pub(super) fn handler(op: u8) -> Handler {
    HANDLERS[op as usize]
}

impl<'a> Run<'a> {
    pub fn new(regions: &'a mut [Region], all: &'a [Inst]) -> Run<'a> {
        Run {
            regions,
            all,
            code_base: 0,
            code_size: 0,
            block_at: std::ptr::null(),
            tohost: None,
            poll_armed: false,
            entry: 0,
            chains: 0,
            retired: 0,
            jumps: 0,
            cycles: 0,
            pc: 0,
            load_mask: None,
            general: None,
            poll_from: 0,
            chain: std::ptr::null(),
            fast: FastRam {
                ptr: std::ptr::null_mut(),
                base: 0,
                size: 0,
                code_lo: 0,
                code_hi: 0,
                extra: 0,
            },
            timing: MemTiming::default(),
            arbiter: None,
            window: (0, &[]),
            window_latency: 0,
        }
    }

    /// Loads from these device registers run here rather than on the
    /// general path: `latency` cycles each, as `Cpu::mmio_access` charges,
    /// and, as there, no split cost (`Mmio::plain_window`).
    pub fn set_window(&mut self, base: u32, bytes: &'a [u8], latency: u64) {
        self.window = (base, bytes);
        self.window_latency = latency;
    }

    /// A load of `n` bytes from the plain device window, if inside it.
    #[inline(always)]
    fn window_load(&self, addr: u32, n: u32) -> Option<u32> {
        let off = addr.wrapping_sub(self.window.0) as usize;
        let bytes = self.window.1.get(off..off.checked_add(n as usize)?)?;
        Some(bytes.iter().rev().fold(0, |v, &b| (v << 8) | u32::from(b)))
    }

    /// The core's memory timing and the L1 arbiter (cluster cores).
    pub fn set_timing(
        &mut self,
        timing: MemTiming,
        arbiter: Option<&'a mut (dyn BankArbiter + 'static)>,
    ) {
        self.timing = timing;
        self.arbiter = arbiter;
    }

    /// Extra cycles of a RAM access at `addr` by an instruction whose cost
    /// (load-use stall included) is already in `cycles`: the access issues
    /// in its last cycle, `cycles − 1`, as `Cpu::issue_cycle` says on the
    /// general path, so both paths arbitrate an L1 bank at the same cycle
    /// wherever a block happens to start.
    #[inline(always)]
    fn extra(&mut self, addr: u32, cycles: u64) -> u64 {
        if self.timing.is_plain() {
            return 0;
        }
        self.timing
            .extra(self.arbiter.as_deref_mut(), addr, cycles - 1)
    }

    /// Region `idx` holds the code: chain its blocks directly (`starts`:
    /// where the cached blocks start, per region, `CodeCache::starts`,
    /// borrowed as long as the run), and give the hot path direct access
    /// to its bytes.
    pub fn set_code_region(&mut self, idx: usize, starts: &'a [Starts]) {
        if let Some(reg) = self.regions.get_mut(idx) {
            // The region's start table has one entry per halfword, `size /
            // 2` entries, once allocated; chain only through one that is.
            if let Some(s) = starts
                .get(idx)
                .filter(|s| s.at.len() == reg.size as usize / 2)
            {
                self.code_base = reg.base;
                self.code_size = reg.size;
                self.block_at = s.at.as_ptr();
            }
            // L1 code would bypass the bank arbiter: its data then takes
            // the other-region path (a cluster core normally runs from L2).
            let banked = self.timing.l1_port.is_some() && reg.base == self.timing.l1.0;
            self.fast = FastRam {
                ptr: reg.data.as_mut_ptr(),
                base: reg.base,
                size: if banked { 0 } else { reg.size },
                code_lo: reg.code_lo.min(u32::MAX as usize) as u32,
                code_hi: reg.code_hi as u32,
                extra: self.timing.extra(None, reg.base, 0),
            };
        }
    }

    /// Index of `p` in the running block.
    #[inline(always)]
    fn index(&self, p: *const Inst) -> usize {
        // SAFETY: `p` points into the running block.
        unsafe { (*p).idx as usize }
    }

    /// Leave just before the instruction at `p`, at `cycles`.
    #[cold]
    fn leave(&mut self, p: *const Inst, cycles: u64) -> Flow {
        let i = self.index(p);
        self.cycles = cycles;
        self.retired += i as u64;
        // SAFETY: `p` is within the running block (see `run`).
        self.pc = unsafe { (*p).pc };
        self.load_mask = if i > 0 {
            // SAFETY: `p - 1` is in the block too.
            Some(unsafe { (*p.sub(1)).load_mask() })
        } else if self.retired > 0 {
            Some(0) // a chained block: entered by a control transfer
        } else {
            None
        };
        Flow::Paused
    }
}

/// Run from the block whose first instruction is `all[first]`, at `cycles`
/// (`entry` = the core's cycle count before the block's entry stall), until
/// `deadline` or an exit (see [`Flow`]).
pub(super) fn run(
    r: &mut Run,
    regs: &mut [u32; 32],
    first: usize,
    entry: u64,
    mut cycles: u64,
    deadline: u64,
) -> Flow {
    let mut p: *const Inst = &r.all[first];
    r.entry = entry;
    loop {
        r.chains = 0;
        // SAFETY: `p` is the first instruction of a block of `all`.
        let h = unsafe { (*p).handler };
        match h(r, regs, p, cycles, deadline) {
            Flow::Chain => {
                p = r.chain;
                cycles = r.cycles;
            }
            flow => return flow,
        }
    }
}

/// Go on with the instruction after `p` (the tail of every handler that
/// does not leave).
#[inline(always)]
fn next(r: &mut Run, regs: &mut [u32; 32], p: *const Inst, cycles: u64, deadline: u64) -> Flow {
    // SAFETY: a handler that does not leave is never the last of its block
    // (every block ends with a jump, a system instruction or `END`, which
    // leave; `block.rs` builds them so), so `p + 1` is in the block.
    let p = unsafe { p.add(1) };
    if cycles >= deadline {
        return r.leave(p, cycles);
    }
    // SAFETY: as above.
    let h = unsafe { (*p).handler };
    h(r, regs, p, cycles, deadline)
}

/// The register file, unchecked: register fields are below 32 (`decode`
/// extracts 5-bit fields; `block.rs` asserts it in debug builds).
macro_rules! reg {
    ($regs:ident, $k:expr) => {
        // SAFETY: register fields are below 32, see above.
        *unsafe { $regs.get_unchecked_mut($k as usize) }
    };
}

/// A handler: `|r, regs, inst, cycles, p, deadline| body`; the body runs
/// after the instruction's static cost is added and may `return` a flow;
/// otherwise the handler goes on with the next instruction.
macro_rules! handler {
    ($name:ident, |$r:ident, $regs:ident, $inst:ident, $cycles:ident, $p:ident, $deadline:ident| $body:block) => {
        #[allow(unused_variables, unused_mut, unreachable_code)]
        fn $name(
            $r: &mut Run,
            $regs: &mut [u32; 32],
            $p: *const Inst,
            mut $cycles: u64,
            $deadline: u64,
        ) -> Flow {
            // SAFETY: `p` points into the running block (see `next`, `run`).
            let $inst = unsafe { &*$p };
            $cycles += $inst.cost as u64;
            $body
            next($r, $regs, $p, $cycles, $deadline)
        }
    };
}

/// `rd = f(rs1, imm)` and `rd = f(rs1, rs2)` handlers.
macro_rules! alu {
    ($($name:ident: |$a:ident, $b:ident| $e:expr;)*) => {$(
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let $a = reg!(regs, inst.rs1);
            let $b = reg!(regs, inst.rs2);
            reg!(regs, inst.rd) = $e;
        });
    )*};
}
macro_rules! alu_imm {
    ($($name:ident: |$a:ident, $b:ident| $e:expr;)*) => {$(
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let $a = reg!(regs, inst.rs1);
            let $b = inst.imm;
            reg!(regs, inst.rd) = $e;
        });
    )*};
}

alu_imm! {
    h_addi: |a, b| a.wrapping_add(b);
    h_slti: |a, b| ((a as i32) < (b as i32)) as u32;
    h_sltiu: |a, b| (a < b) as u32;
    h_xori: |a, b| a ^ b;
    h_ori: |a, b| a | b;
    h_andi: |a, b| a & b;
    h_slli: |a, b| a << (b & 31);
    h_srli: |a, b| a >> (b & 31);
    h_srai: |a, b| ((a as i32) >> (b & 31)) as u32;
    // `auipc` arrives as `lui` of its result.
    h_lui: |a, b| b;
}
alu! {
    h_add: |a, b| a.wrapping_add(b);
    h_sub: |a, b| a.wrapping_sub(b);
    h_sll: |a, b| a << (b & 31);
    h_slt: |a, b| ((a as i32) < (b as i32)) as u32;
    h_sltu: |a, b| (a < b) as u32;
    h_xor: |a, b| a ^ b;
    h_srl: |a, b| a >> (b & 31);
    h_sra: |a, b| ((a as i32) >> (b & 31)) as u32;
    h_or: |a, b| a | b;
    h_and: |a, b| a & b;
    h_mul: |a, b| a.wrapping_mul(b);
    h_mulh: |a, b| ((a as i32 as i64 * b as i32 as i64) >> 32) as u32;
    h_mulhsu: |a, b| ((a as i32 as i64 * b as i64) >> 32) as u32;
    h_mulhu: |a, b| ((a as u64 * b as u64) >> 32) as u32;
}

handler!(h_nop, |r, regs, inst, cycles, p, deadline| {});

// Division: 3 + leading zeros of the divisor's magnitude (the table's 3 is
// in the static cost). The result may go to x0, so x0 is re-zeroed.
handler!(h_div, |r, regs, inst, cycles, p, deadline| {
    let (a, b) = (reg!(regs, inst.rs1), reg!(regs, inst.rs2));
    cycles += (b as i32).unsigned_abs().leading_zeros() as u64;
    let (x, y) = (a as i32, b as i32);
    reg!(regs, inst.rd) = match (inst.op == op::DIV, y) {
        (true, 0) => u32::MAX,
        (false, 0) => a,
        (true, _) => x.wrapping_div(y) as u32,
        (false, _) => x.wrapping_rem(y) as u32,
    };
    regs[0] = 0;
});
handler!(h_divu, |r, regs, inst, cycles, p, deadline| {
    let (a, b) = (reg!(regs, inst.rs1), reg!(regs, inst.rs2));
    cycles += b.leading_zeros() as u64;
    reg!(regs, inst.rd) = match (inst.op == op::DIVU, b) {
        (true, 0) => u32::MAX,
        (false, 0) => a,
        (true, _) => a / b,
        (false, _) => a % b,
    };
    regs[0] = 0;
});

/// Leave before the instruction at `p` for the general path.
#[cold]
fn general(r: &mut Run, p: *const Inst, cycles: u64) -> Flow {
    // SAFETY: `p` is in the running block.
    let inst = unsafe { *p };
    let before = if r.index(p) == 0 {
        r.entry
    } else {
        cycles - inst.cost as u64
    };
    r.leave(p, before);
    r.general = Some(inst);
    Flow::General
}

/// The hot load and store handlers only touch the fast region; everything
/// else continues in a cold twin with the same signature, entered by a tail
/// call, so the hot handler needs no stack frame. `$mode` is the addressing
/// mode (`xcv::mem`; a constant, so the RV32I forms compile to `rs1 + imm`
/// with no write-back) and `$reg` the field of its register operand.
macro_rules! loads {
    ($($name:ident, $slow:ident: $size:expr, $conv:expr, $mode:expr, $reg:ident;)*) => {$(
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let (addr, wb) = address($mode, reg!(regs, inst.rs1), reg!(regs, inst.$reg), inst.imm);
            const N: u32 = $size.bytes();
            let Some(off) = r.fast.offset(addr, N) else {
                return $slow(r, regs, p, cycles, deadline);
            };
            let mut b = [0u8; 4];
            // SAFETY: `off + N` is within the fast region's buffer (see
            // `FastRam`).
            unsafe { std::ptr::copy_nonoverlapping(r.fast.ptr.add(off), b.as_mut_ptr(), N as usize) };
            cycles += timing::split_cost(addr, $size) + r.fast.extra;
            if let Some(v) = wb {
                reg!(regs, inst.rs1) = v;
            }
            reg!(regs, inst.rd) = $conv(u32::from_le_bytes(b));
            regs[0] = 0;
        });

        /// The load outside the fast region (`cycles` include the cost).
        #[cold]
        #[inline(never)]
        fn $slow(r: &mut Run, regs: &mut [u32; 32], p: *const Inst, mut cycles: u64, deadline: u64) -> Flow {
            // SAFETY: `p` points into the running block.
            let inst = unsafe { &*p };
            let (addr, wb) = address($mode, reg!(regs, inst.rs1), reg!(regs, inst.$reg), inst.imm);
            match ram_load(r.regions, addr, $size) {
                Some(v) => {
                    cycles += timing::split_cost(addr, $size) + r.extra(addr, cycles);
                    if let Some(v) = wb {
                        reg!(regs, inst.rs1) = v;
                    }
                    reg!(regs, inst.rd) = $conv(v);
                    regs[0] = 0;
                    next(r, regs, p, cycles, deadline)
                }
                None => match r.window_load(addr, $size.bytes()) {
                    Some(v) => {
                        cycles += r.window_latency;
                        if let Some(v) = wb {
                            reg!(regs, inst.rs1) = v;
                        }
                        reg!(regs, inst.rd) = $conv(v);
                        regs[0] = 0;
                        next(r, regs, p, cycles, deadline)
                    }
                    None => general(r, p, cycles),
                },
            }
        }
    )*};
}
loads! {
    h_lb, h_lb_other: AccessSize::Byte, sext8, Mode::Offset, rs2;
    h_lh, h_lh_other: AccessSize::Half, sext16, Mode::Offset, rs2;
    h_lw, h_lw_other: AccessSize::Word, same, Mode::Offset, rs2;
    h_lbu, h_lbu_other: AccessSize::Byte, same, Mode::Offset, rs2;
    h_lhu, h_lhu_other: AccessSize::Half, same, Mode::Offset, rs2;
}

/// Load conversions.
#[inline(always)]
fn sext8(v: u32) -> u32 {
    v as u8 as i8 as i32 as u32
}
#[inline(always)]
fn sext16(v: u32) -> u32 {
    v as u16 as i16 as i32 as u32
}
#[inline(always)]
fn same(v: u32) -> u32 {
    v
}

macro_rules! stores {
    ($($name:ident, $slow:ident: $size:expr, $mode:expr;)*) => {$(
        // The register operand of the XCV forms (rs3) is in the rd field.
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let (addr, wb) = address($mode, reg!(regs, inst.rs1), reg!(regs, inst.rd), inst.imm);
            const N: u32 = $size.bytes();
            let watched = r.tohost.is_some_and(|t| addr.wrapping_sub(t) < 8);
            let off = match r.fast.offset(addr, N) {
                Some(off) if !watched && (off as u32 >= r.fast.code_hi || off as u32 + N <= r.fast.code_lo) => off,
                _ => return $slow(r, regs, p, cycles, deadline),
            };
            let b = reg!(regs, inst.rs2).to_le_bytes();
            // SAFETY: `off + N` is within the fast region's buffer (see
            // `FastRam`).
            unsafe { std::ptr::copy_nonoverlapping(b.as_ptr(), r.fast.ptr.add(off), N as usize) };
            cycles += timing::split_cost(addr, $size) + r.fast.extra;
            if let Some(v) = wb {
                reg!(regs, inst.rs1) = v;
                regs[0] = 0;
            }
        });

        /// The store outside the fast region, near code or to `tohost`
        /// (`cycles` include the cost).
        #[cold]
        #[inline(never)]
        fn $slow(r: &mut Run, regs: &mut [u32; 32], p: *const Inst, mut cycles: u64, deadline: u64) -> Flow {
            // SAFETY: `p` points into the running block.
            let inst = unsafe { &*p };
            let (addr, wb) = address($mode, reg!(regs, inst.rs1), reg!(regs, inst.rd), inst.imm);
            let watched = r.tohost.is_some_and(|t| addr.wrapping_sub(t) < 8);
            let in_fast = r.fast.offset(addr, $size.bytes()).is_some();
            if watched || in_fast || !ram_store_data(r.regions, addr, $size, reg!(regs, inst.rs2)) {
                return general(r, p, cycles);
            }
            cycles += timing::split_cost(addr, $size) + r.extra(addr, cycles);
            if let Some(v) = wb {
                reg!(regs, inst.rs1) = v;
                regs[0] = 0;
            }
            next(r, regs, p, cycles, deadline)
        }
    )*};
}
stores! {
    h_sb, h_sb_other: AccessSize::Byte, Mode::Offset;
    h_sh, h_sh_other: AccessSize::Half, Mode::Offset;
    h_sw, h_sw_other: AccessSize::Word, Mode::Offset;
}

/// A control transfer from the instruction at `p` to `to` retired: go on
/// with the block at `to` if it is cached and nothing needs the core, else
/// leave. After a transfer nothing is in the load-use shadow.
///
/// The next block is entered by a tail call (a jump, optimised) up to
/// [`MAX_DIRECT_CHAINS`] times in a row, then through the trampoline in
/// [`run`], which bounds the stack even where tail calls are not optimised.
#[inline(always)]
fn transfer(
    r: &mut Run,
    regs: &mut [u32; 32],
    p: *const Inst,
    to: u32,
    cycles: u64,
    deadline: u64,
    conditional: bool,
) -> Flow {
    // SAFETY: `p` is in the running block.
    let from = unsafe { (*p).pc };
    r.jumps += 1;
    r.retired += r.index(p) as u64 + 1;
    let poll =
        conditional && r.poll_armed && to < from && from - to <= super::cpu::MAX_POLL_LOOP_BYTES;
    let off = to.wrapping_sub(r.code_base);
    let next = if cycles < deadline && !poll && off < r.code_size {
        // SAFETY: `off < code_size`, and `block_at` has `code_size / 2`
        // entries (see `set_code_region`); nothing changes it during a run
        // (`set_code_region` borrows it for the run's lifetime).
        unsafe { *r.block_at.add((off >> 1) as usize) }
    } else {
        0
    };
    if next != 0 {
        let q: *const Inst = &r.all[next as usize - 1];
        r.entry = cycles;
        if r.chains < MAX_DIRECT_CHAINS {
            r.chains += 1;
            // SAFETY: `q` is the first instruction of a block of `all`.
            let h = unsafe { (*q).handler };
            return h(r, regs, q, cycles, deadline);
        }
        r.cycles = cycles;
        r.chain = q;
        return Flow::Chain;
    }
    r.cycles = cycles;
    r.pc = to;
    r.load_mask = Some(0);
    if poll {
        r.poll_from = from;
        Flow::Poll
    } else {
        Flow::Paused
    }
}

// A conditional branch: a side exit when taken, else the block goes on.
macro_rules! branches {
    ($($name:ident: |$a:ident, $b:ident| $cond:expr;)*) => {$(
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let ($a, $b) = (reg!(regs, inst.rs1), reg!(regs, inst.rs2));
            if $cond {
                cycles += timing::BRANCH_TAKEN_EXTRA;
                return transfer(r, regs, p, inst.imm, cycles, deadline, true);
            }
        });
    )*};
}
branches! {
    h_beq: |a, b| a == b;
    h_bne: |a, b| a != b;
    h_blt: |a, b| (a as i32) < (b as i32);
    h_bge: |a, b| (a as i32) >= (b as i32);
    h_bltu: |a, b| a < b;
    h_bgeu: |a, b| a >= b;
}

handler!(h_jal, |r, regs, inst, cycles, p, deadline| {
    reg!(regs, inst.rd) = inst.pc.wrapping_add(inst.len as u32);
    regs[0] = 0;
    return transfer(r, regs, p, inst.imm, cycles, deadline, false);
});
handler!(h_jalr, |r, regs, inst, cycles, p, deadline| {
    let to = reg!(regs, inst.rs1).wrapping_add(inst.imm) & !1;
    reg!(regs, inst.rd) = inst.pc.wrapping_add(inst.len as u32);
    regs[0] = 0;
    return transfer(r, regs, p, to, cycles, deadline, false);
});
// A `jal` whose target is the next instruction of the block.
handler!(h_jump, |r, regs, inst, cycles, p, deadline| {
    reg!(regs, inst.rd) = inst.pc.wrapping_add(inst.len as u32);
    regs[0] = 0;
    r.jumps += 1;
});
// Not an instruction: the block ran out without a jump (cost 0).
handler!(h_end, |r, regs, inst, cycles, p, deadline| {
    return r.leave(p, cycles);
});

/// System instructions (and anything unexpected) take the general path.
fn h_general(r: &mut Run, _: &mut [u32; 32], p: *const Inst, cycles: u64, _: u64) -> Flow {
    // `general` wants the cycles after this instruction's cost.
    // SAFETY: `p` is in the running block.
    general(r, p, cycles + unsafe { (*p).cost } as u64)
}

/// The handler that hands its instruction to the general path (a
/// self-loop's, [`Inst::is_self_loop`]).
pub(super) fn general_handler() -> Handler {
    h_general
}

/// Handler of every op code (256 entries, so a `u8` needs no check).
static HANDLERS: [Handler; 256] = {
    let mut t: [Handler; 256] = [h_general; 256];
    t[op::LUI as usize] = h_lui;
    t[op::ADDI as usize] = h_addi;
    t[op::SLTI as usize] = h_slti;
    t[op::SLTIU as usize] = h_sltiu;
    t[op::XORI as usize] = h_xori;
    t[op::ORI as usize] = h_ori;
    t[op::ANDI as usize] = h_andi;
    t[op::SLLI as usize] = h_slli;
    t[op::SRLI as usize] = h_srli;
    t[op::SRAI as usize] = h_srai;
    t[op::ADD as usize] = h_add;
    t[op::SUB as usize] = h_sub;
    t[op::SLL as usize] = h_sll;
    t[op::SLT as usize] = h_slt;
    t[op::SLTU as usize] = h_sltu;
    t[op::XOR as usize] = h_xor;
    t[op::SRL as usize] = h_srl;
    t[op::SRA as usize] = h_sra;
    t[op::OR as usize] = h_or;
    t[op::AND as usize] = h_and;
    t[op::MUL as usize] = h_mul;
    t[op::MULH as usize] = h_mulh;
    t[op::MULHSU as usize] = h_mulhsu;
    t[op::MULHU as usize] = h_mulhu;
    t[op::DIV as usize] = h_div;
    t[op::REM as usize] = h_div;
    t[op::DIVU as usize] = h_divu;
    t[op::REMU as usize] = h_divu;
    t[op::LB as usize] = h_lb;
    t[op::LH as usize] = h_lh;
    t[op::LW as usize] = h_lw;
    t[op::LBU as usize] = h_lbu;
    t[op::LHU as usize] = h_lhu;
    t[op::SB as usize] = h_sb;
    t[op::SH as usize] = h_sh;
    t[op::SW as usize] = h_sw;
    t[op::BEQ as usize] = h_beq;
    t[op::BNE as usize] = h_bne;
    t[op::BLT as usize] = h_blt;
    t[op::BGE as usize] = h_bge;
    t[op::BLTU as usize] = h_bltu;
    t[op::BGEU as usize] = h_bgeu;
    t[op::JAL as usize] = h_jal;
    t[op::JALR as usize] = h_jalr;
    t[op::JUMP as usize] = h_jump;
    t[op::NOP as usize] = h_nop;
    t[op::FENCE as usize] = h_nop;
    t[op::FENCE_I as usize] = h_nop;
    t[op::END as usize] = h_end;
    xcv::install(&mut t);
    t
};

mod xcv;
