//! The pre-decoded code cache: basic blocks of unpacked instructions.
//!
//! A block is the run of instructions the core executes from some pc if no
//! conditional branch is taken, up to and including the first indirect jump
//! (`jalr`) or system instruction (CSR access, `ecall`, `ebreak`, `mret`,
//! `wfi`, an illegal encoding), at most [`MAX_BLOCK_INSTS`] long: a
//! conditional branch is a side exit, taken or not, and a `jal` is followed
//! to its target (a superblock, in the literature's terms), so the core
//! leaves a block only when control really goes elsewhere. It is decoded once, into
//! [`Inst`]s whose operands are already unpacked and whose costs already hold
//! the CV32E40P table cycles plus every load-use stall between two
//! instructions of the same block, so the executor's handlers (`exec.rs`)
//! do no fetch lookup, no decoding, no stall logic and
//! no per-instruction bookkeeping beyond the instruction itself. Only the
//! stall on a block's first instruction (it depends on how the core got
//! there) and data-dependent costs (taken branch, division, split access)
//! are added while running.
//!
//! Blocks live in the [`CodeCache`] beside the memory they were decoded
//! from (a block describes bytes, not a core): per RAM region, the index
//! of the block that starts at each halfword, while the memory marks the
//! halfwords any decoded instruction occupies. A write to one of those
//! halfwords (a store, [`Memory::write_bytes`]) starts a new code epoch,
//! and the cache drops every block before its next use (see `code.rs`).

use super::code::CodeCache;
use super::decode::{self, op, Decoded};
use super::exec::{self, handler, Handler};
use super::mem::{Memory, Region};
use super::timing::BASE_CYCLES;
use super::xcv;

/// Longest block. Long enough that the per-block entry cost is noise,
/// short enough that a block built past a rarely taken exit wastes little.
pub const MAX_BLOCK_INSTS: usize = 64;

/// More cached instructions than this and the cache is dropped before the
/// next block is built (bounds memory for programs that generate code).
const MAX_CACHED_INSTS: usize = 1 << 20;

/// One instruction of a block, unpacked (24 bytes, a dense array the
/// executor walks).
///
/// Forms that differ from [`Decoded`]: `auipc` becomes `lui` of its result
/// (the pc is known), branches and `jal` hold their absolute target in
/// `imm`, a `jal` whose target follows it in the block becomes
/// [`op::JUMP`], a computation writing `x0` becomes [`op::NOP`] (keeping its
/// cost), and a block that ends without a control transfer ends with an
/// [`op::END`] whose `imm` is the next pc (cost 0, not an instruction).
#[derive(Debug, Clone, Copy)]
#[repr(C)]
pub(crate) struct Inst {
    /// The executor's handler for `op` (`exec.rs`), looked up once here so
    /// the dispatch is a single load.
    pub(super) handler: Handler,
    pub op: u8,
    pub rd: u8,
    pub rs1: u8,
    pub rs2: u8,
    pub imm: u32,
    pub pc: u32,
    /// Table cycles plus the load-use stall behind the previous instruction
    /// of the same block.
    pub cost: u8,
    /// Length in bytes (2 or 4).
    pub len: u8,
    /// Position in its block.
    pub idx: u8,
}

impl Inst {
    /// Registers read (one-hot mask; unused fields are x0).
    #[inline(always)]
    pub fn reads(&self) -> u32 {
        (1u32 << (self.rs1 & 31))
            | (1u32 << (self.rs2 & 31))
            | ((READS_RD[self.op as usize] as u32) << (self.rd & 31))
    }

    /// One-hot mask of the register this instruction loads (0 if it is not
    /// a load or loads x0): the next instruction's load-use hazard.
    #[inline(always)]
    pub fn load_mask(&self) -> u32 {
        if is_load(self.op) {
            (1u32 << (self.rd & 31)) & !1
        } else {
            0
        }
    }

    /// A branch or `jal` to itself: once taken it is taken forever, since
    /// nothing but the core could change its operands (registers are
    /// private) and it changes none; only an interrupt can end it. The
    /// block builder sends it to the general path
    /// ([`exec::general_handler`]), which decides whether the core can
    /// still progress, and the translator stops before it; a loop with
    /// anything else in it (a load of a device or of memory another agent
    /// writes) is not one. Wherever it sits in its block: one that only
    /// starting a block were caught would run once more when reached
    /// inside a block than when single-stepped (the two must agree to the
    /// cycle).
    #[inline]
    pub fn is_self_loop(&self) -> bool {
        self.imm == self.pc && is_direct_transfer(self.op)
    }

    /// The decoded instruction (for the general path, which only ever
    /// receives loads, stores, system instructions and self-loops
    /// ([`Inst::is_self_loop`]), kept in their decoded form).
    pub fn decoded(&self) -> Decoded {
        Decoded {
            op: self.op,
            rd: self.rd,
            rs1: self.rs1,
            rs2: self.rs2,
            imm: self.imm as i32,
            compressed: self.len == 2,
        }
    }
}

/// Branches and `jal`: the transfers whose target `imm` holds, absolute.
pub(crate) fn is_direct_transfer(o: u8) -> bool {
    (op::BEQ..=op::BGEU).contains(&o) || matches!(o, op::JAL | op::CV_BEQIMM | op::CV_BNEIMM)
}

pub(crate) fn is_load(o: u8) -> bool {
    (op::LB..=op::LHU).contains(&o) || xcv::is_load(o)
}

/// Ops that read rd as a source (XCV accumulators, inserts, the rs3 of
/// stores; `xcv::reads_rd`), indexed by op.
static READS_RD: [bool; 256] = {
    let mut t = [false; 256];
    let mut o = 0;
    while o < 256 {
        t[o] = xcv::reads_rd(o as u8);
        o += 1;
    }
    t
};

/// Instructions after which a block ends.
fn ends_block(o: u8) -> bool {
    matches!(o, op::JAL | op::JALR) || (op::ECALL..=op::CSRRCI).contains(&o) || o == op::ILLEGAL
}

/// Length of the block whose instructions start `insts` (up to and
/// including its last: a control transfer, a system instruction or `END`).
pub(super) fn block_len(insts: &[Inst]) -> usize {
    insts
        .iter()
        .position(|i| i.op == op::END || ends_block(i.op))
        .map_or(insts.len(), |k| k + 1)
}

/// Computations without side effects: writing x0 makes them no-ops.
fn pure(o: u8) -> bool {
    matches!(o, op::LUI | op::AUIPC)
        || (op::ADDI..=op::AND).contains(&o)
        || (op::MUL..=op::MULHU).contains(&o)
        || xcv::pure(o)
}

/// The first instruction at `pc` cannot be fetched; the address that faulted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FetchFault(pub u32);

/// The halfword at `off` of a region, if inside it.
fn half(r: &Region, off: usize) -> Option<u16> {
    let b = r.data.get(off..off + 2)?;
    Some(u16::from_le_bytes([b[0], b[1]]))
}

impl CodeCache {
    /// The block starting at `pc` in `mem`: `(region index, index of its
    /// first instruction in [`CodeCache::insts`])`, decoding it if needed.
    pub(crate) fn block(
        &mut self,
        mem: &mut Memory,
        pc: u32,
    ) -> Result<(usize, usize), FetchFault> {
        self.sync(mem);
        let (idx, off) = mem.region_index(pc, 2).ok_or(FetchFault(pc))?;
        let cached = self.start(idx, off);
        if cached != 0 {
            return Ok((idx, cached as usize - 1));
        }
        if self.insts.len() >= MAX_CACHED_INSTS {
            self.flush(mem);
        }
        self.starts_of(mem, idx);
        self.build(&mut mem.regions[idx], idx, pc, off)
            .map(|first| (idx, first))
    }

    fn build(
        &mut self,
        r: &mut Region,
        idx: usize,
        pc: u32,
        off: usize,
    ) -> Result<usize, FetchFault> {
        let first = self.insts.len();
        let mut at = off;
        let mut prev_load = 0u32;
        loop {
            let n = self.insts.len() - first;
            let lo = half(r, at);
            let d = lo.and_then(|lo| decode::decode(lo, || half(r, at + 2)));
            let Some(d) = d else {
                if n == 0 {
                    // The first halfword, or the second half of a 32-bit
                    // instruction, is not in this region.
                    let bad = if lo.is_none() { pc } else { pc.wrapping_add(2) };
                    return Err(FetchFault(bad));
                }
                // Leave the fault to a block that starts there.
                self.insts.push(end(r.base.wrapping_add(at as u32), n));
                break;
            };
            let ipc = r.base.wrapping_add(at as u32);
            // The core indexes its register file with these unchecked.
            debug_assert!(d.rd < 32 && d.rs1 < 32 && d.rs2 < 32);
            let mut inst = Inst {
                op: d.op,
                rd: d.rd,
                rs1: d.rs1,
                rs2: d.rs2,
                imm: d.imm as u32,
                pc: ipc,
                cost: BASE_CYCLES[d.op as usize],
                len: d.len() as u8,
                handler: handler(0),
                idx: n as u8,
            };
            if n > 0 && inst.reads() & prev_load != 0 {
                inst.cost += super::timing::LOAD_USE_STALL as u8;
            }
            prev_load = inst.load_mask();
            match d.op {
                op::AUIPC => {
                    inst.op = op::LUI;
                    inst.imm = ipc.wrapping_add(inst.imm);
                }
                op::JAL => inst.imm = ipc.wrapping_add(inst.imm),
                o if (op::BEQ..=op::BGEU).contains(&o)
                    || o == op::CV_BEQIMM
                    || o == op::CV_BNEIMM =>
                {
                    inst.imm = ipc.wrapping_add(inst.imm)
                }
                _ => {}
            }
            if inst.rd == 0 && pure(inst.op) {
                inst.op = op::NOP;
            }
            // Where the block goes on: after the instruction, or at the
            // target of a `jal` (which becomes a `JUMP`), unless it jumps to
            // itself or out of this region.
            let next = match inst.op {
                op::JAL => match r.offset_of(inst.imm, 2) {
                    Some(t) if inst.imm != ipc => {
                        inst.op = op::JUMP;
                        Some(t)
                    }
                    _ => None,
                },
                o if ends_block(o) => None,
                _ => Some(at + d.len() as usize),
            };
            r.mark_code(at, d.len() as usize);
            inst.handler = if inst.is_self_loop() {
                exec::general_handler()
            } else {
                handler(inst.op)
            };
            self.insts.push(inst);
            let Some(next) = next else {
                break;
            };
            at = next;
            if n + 1 == MAX_BLOCK_INSTS {
                self.insts.push(end(r.base.wrapping_add(at as u32), n + 1));
                break;
            }
        }
        self.starts[idx].set(off >> 1, first);
        Ok(first)
    }
}

/// The pseudo-instruction that ends a block without a control transfer,
/// at position `idx`.
fn end(next: u32, idx: usize) -> Inst {
    Inst {
        op: op::END,
        rd: 0,
        rs1: 0,
        rs2: 0,
        imm: next,
        pc: next,
        cost: 0,
        len: 0,
        handler: handler(op::END),
        idx: idx as u8,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mem_with(words: &[u32]) -> Memory {
        let mut m = Memory::new();
        m.add_ram(0x1000, 0x1000).unwrap();
        for (k, w) in words.iter().enumerate() {
            m.write_bytes(0x1000 + 4 * k as u32, &w.to_le_bytes())
                .unwrap();
        }
        m
    }

    #[test]
    fn blocks_end_at_control_transfers_and_fold_static_stalls() {
        // lw x5,0(x6); addi x7,x5,1 (load-use: +1); auipc x8,1; addi x0,x1,1;
        // beq x0,x0,-16 (a side exit); jal x0,-20 (followed); jal x0,0
        let m = &mut mem_with(&[
            0x0003_2283,
            0x0012_8393,
            0x0000_1417,
            0x0010_8013,
            0xfe00_08e3,
            0xfedf_f06f,
            0x0000_006f,
        ]);
        let c = &mut CodeCache::new();
        let (_, first) = c.block(m, 0x1000).unwrap();
        let b = &c.insts[first..];
        assert_eq!(b[0].op, op::LW);
        assert_eq!((b[1].op, b[1].cost), (op::ADDI, 2));
        assert_eq!((b[2].op, b[2].imm), (op::LUI, 0x1008 + 0x1000));
        assert_eq!(b[3].op, op::NOP);
        assert_eq!((b[4].op, b[4].imm), (op::BEQ, 0x1010 - 16));
        assert_eq!((b[5].op, b[5].imm), (op::JUMP, 0x1000));
        // The jump's target starts again at the load, after a jump: no stall.
        assert_eq!((b[6].op, b[6].pc), (op::LW, 0x1000));
        assert_eq!((b[7].op, b[7].cost), (op::ADDI, 2));
        // It loops until the length limit.
        assert_eq!(c.insts.len(), first + MAX_BLOCK_INSTS + 1);
        assert_eq!(c.insts.last().unwrap().op, op::END);
        // Cached: the same block comes back.
        assert_eq!(c.block(m, 0x1000).unwrap().1, first);
    }

    #[test]
    fn writing_cached_code_drops_the_blocks_and_data_writes_do_not() {
        let m = &mut mem_with(&[0x0010_0093, 0x0000_006f]);
        let c = &mut CodeCache::new();
        let (_, first) = c.block(m, 0x1000).unwrap();
        m.write_bytes(0x1800, &[1, 2, 3, 4]).unwrap();
        c.sync(m);
        assert_eq!(c.insts.len(), first + 2);
        m.write_bytes(0x1006, &[0]).unwrap();
        // Memory forgets its code marks at once, the cache at its next use.
        assert!(!m.regions[0].near_code(0, 0x1000));
        c.sync(m);
        assert!(c.insts.is_empty());
        assert_eq!(c.start(0, 0), 0);
        // Decoded again on the next lookup.
        let (_, first) = c.block(m, 0x1000).unwrap();
        assert_eq!(c.insts[first].op, op::ADDI);
    }

    #[test]
    fn a_cache_handed_another_memory_decodes_that_memory() {
        // The same address, different code: addi x1,x0,1 / lui x1,1.
        let a = &mut mem_with(&[0x0010_0093, 0x0000_006f]);
        let b = &mut mem_with(&[0x0000_10b7, 0x0000_006f]);
        let c = &mut CodeCache::new();
        let (_, first) = c.block(a, 0x1000).unwrap();
        assert_eq!(c.insts[first].op, op::ADDI);
        let (_, first) = c.block(b, 0x1000).unwrap();
        assert_eq!(c.insts[first].op, op::LUI);
        // And back: memory A's epoch is not the cache's any more.
        let (_, first) = c.block(a, 0x1000).unwrap();
        assert_eq!(c.insts[first].op, op::ADDI);
    }

    #[test]
    fn a_fetch_outside_ram_faults_with_the_missing_address() {
        let mut m = Memory::new();
        let c = &mut CodeCache::new();
        m.add_ram(0x1000, 0x1000).unwrap();
        assert_eq!(c.block(&mut m, 0x4000), Err(FetchFault(0x4000)));
        // A 32-bit instruction whose second half is past the region.
        m.write_bytes(0x1ffe, &[0x93, 0x00]).unwrap();
        assert_eq!(c.block(&mut m, 0x1ffe), Err(FetchFault(0x2000)));
    }
}
