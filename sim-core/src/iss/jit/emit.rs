//! The templates: one decoded block (`block.rs`) to x86-64.
//!
//! A block's code does exactly what the interpreter's handlers do for the
//! same instructions, in the same order, on the same register file and
//! RAM; cycles are added once per exit from the block's static costs (the
//! costs `block.rs` computed, load-use stalls between its instructions
//! included) plus the dynamic parts where they arise (division, a split
//! access, a cluster core's access extra, a taken branch). The block is
//! only entered when its worst case ends before the deadline, so the
//! interpreter's per-instruction deadline check could never have fired
//! inside it (`mod.rs`).
//!
//! What it does not cover ends it: the core leaves, just before that
//! instruction, with the state the interpreter's `leave` gives, and the
//! interpreter does that instruction (system instructions, accesses
//! outside the fast RAM region and the cluster's L1, or near code or
//! `tohost`). L1 accesses grant their bank as the arbiter does (`iss::l1`), at the
//! interpreter's issue cycle (`grant`).

use dynasmrt::x64::X64Relocation;
use dynasmrt::{dynasm, DynamicLabel, DynasmApi, DynasmLabelApi, VecAssembler};

use super::super::block::Inst;
use super::super::cpu::MAX_POLL_LOOP_BYTES;
use super::super::decode::op;
use super::super::timing::BRANCH_TAKEN_EXTRA;
use super::super::xcv::alu;
use super::super::xcv::mem::base_op;
use super::ctx::*;
use super::helpers::{helper, is_div, MAX_DIV_EXTRA};
use mem::{is_store, mem_op, out_of_line, plain_out_of_line, L1Site};

mod mem;

type Asm = VecAssembler<X64Relocation>;

/// Host addresses of the shared stubs (`mod.rs`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stubs {
    /// Store `r13`/`r15` in the context and return to Rust.
    pub exit: usize,
    /// `eax` = a target pc: chain to its block if translated (whose
    /// checked entry tests the deadline), else leave there.
    pub dispatch: usize,
    /// `eax` = a target pc: leave there (after a transfer).
    pub leave: usize,
}

/// Whether the translator does this op (the rest end a block).
pub(crate) fn covered(o: u8) -> bool {
    matches!(
        o,
        op::LUI | op::NOP | op::FENCE | op::FENCE_I | op::JUMP | op::END
    ) || (op::ADDI..=op::AND).contains(&o)
        || (op::MUL..=op::REMU).contains(&o)
        || (op::BEQ..=op::BGEU).contains(&o)
        || matches!(o, op::JAL | op::JALR | op::CV_BEQIMM | op::CV_BNEIMM)
        || is_mem(o)
        || helper(o).is_some()
}

fn is_mem(o: u8) -> bool {
    (op::LB..=op::SW).contains(&o) || base_op(o).is_some()
}

/// Offset of guest register `r` in the register file.
fn reg(r: u8) -> i32 {
    4 * (r & 31) as i32
}

/// A translated block, before it is placed.
pub(crate) struct Translation {
    pub code: Vec<u8>,
    pub worst: u32,
    pub nmem: u16,
    pub careful: u16,
    /// Jumps to the dispatcher for a static target not translated yet:
    /// `(target pc, offset of the jump's rel32 in code)`, to be pointed at
    /// the target's code once it exists.
    pub patches: Vec<(u32, usize)>,
}

/// Translate the block `b` (its instructions up to and including its last),
/// to be placed at host address `at`. `known` gives the translated block
/// at a guest pc, for direct jumps, and `first_reads` the registers the
/// first instruction of the cached block at a pc reads; `l1`: the memory has a cluster L1,
/// whose accesses get a path of their own (`mem::mem_op`; the cluster cores'
/// flavour, `jit::Flavour`). `None` when its first
/// instruction is not covered.
///
/// The code starts with its checked entry: it goes on only if the block's
/// worst case ends before the deadline, else it leaves at the block's pc.
pub(crate) fn translate(
    b: &[Inst],
    at: usize,
    stubs: Stubs,
    known: &dyn Fn(u32) -> Option<Entry>,
    first_reads: &dyn Fn(u32) -> Option<u32>,
    l1: bool,
) -> Option<Translation> {
    let n = b
        .iter()
        .take_while(|i| covered(i.op) && !i.is_self_loop())
        .count();
    if n == 0 {
        return None;
    }
    // Static bookkeeping: cycles and jumps before each instruction.
    let mut prefix = vec![0u64; n + 1];
    let mut jumps = vec![0u64; n + 1];
    // With the L1 path, the loads and stores before each instruction: the
    // L1 grants an exit there counts in `r15` (`account`), the accesses
    // that went to another region having taken theirs back.
    let mut grants = vec![0u64; n + 1];
    for (k, i) in b[..n].iter().enumerate() {
        prefix[k + 1] = prefix[k] + i.cost as u64;
        jumps[k + 1] = jumps[k] + (i.op == op::JUMP) as u64;
        grants[k + 1] = grants[k] + (l1 && is_mem(i.op)) as u64;
    }
    // The worst case of instructions k.. (from the block's entry cycle:
    // all static costs, a taken branch, and the longest divisions and a
    // split cycle from k on), and their loads and stores.
    let mut rest = vec![(prefix[n] + BRANCH_TAKEN_EXTRA, 0u32); n + 1];
    for (k, i) in b[..n].iter().enumerate().rev() {
        let (mut w, mut m) = rest[k + 1];
        if is_div(i.op) {
            w += MAX_DIV_EXTRA as u64;
        }
        if is_mem(i.op) {
            m += 1;
            w += 1; // a split access
        }
        rest[k] = (w, m);
    }
    let (worst, nmem) = rest[0];
    let worst = u32::try_from(worst).ok()?;

    // The byte dot products inline need SSE4.1 (`pmovsxbd`, `pmulld`);
    // without, the helpers do them.
    let sse41 = std::arch::is_x86_feature_detected!("sse4.1");
    let nmem = u16::try_from(nmem).ok()?;
    let mut a = Asm::new(at);
    let start = a.new_dynamic_label();
    // A cluster core's translation has a careful variant (`Entry::careful`):
    // its label before each instruction's deadline test, and the core's
    // entry past the first.
    let careful = l1.then(|| {
        let labels: Vec<_> = (0..n).map(|_| a.new_dynamic_label()).collect();
        (labels, a.new_dynamic_label())
    });
    let mut blk = Block {
        b,
        xmm2: None,
        xmm2_both: false,
        eax: None,
        paired: false,
        n,
        at,
        stubs,
        known,
        first_reads,
        l1,
        sse41,
        start,
        exits: (0..=n).map(|_| a.new_dynamic_label()).collect(),
        used: vec![false; n + 1],
        prefix,
        jumps,
        grants,
        rest,
        careful_at: careful.as_ref().map(|c| c.0.clone()),
        careful_go: careful.as_ref().map(|c| c.1),
        taken: vec![None; n],
        tail: None,
        patches: Vec::new(),
    };
    // The checked entry: enter only if the worst case ends before the
    // deadline; else run the careful variant when there is one (which
    // leaves at once at the deadline), or leave at the block's start
    // (reached by a transfer: nothing in the load shadow).
    let fail = match &blk.careful_at {
        Some(c) => c[0],
        None => a.new_dynamic_label(),
    };
    dynasm!(a ; .arch x64 ; =>start ; lea rcx, [r13 + worst as i32]);
    if l1 {
        fits(&mut a, nmem as u32, fail);
    } else if nmem != 0 {
        // Without the L1 path only fast-region accesses stay (`rbp` each).
        dynasm!(a ; .arch x64 ; imul rdx, rbp, nmem as i32 ; add rcx, rdx);
        dynasm!(a ; .arch x64 ; cmp rcx, [rbx + DEADLINE] ; jae =>fail);
    } else {
        dynasm!(a ; .arch x64 ; cmp rcx, [rbx + DEADLINE] ; jae =>fail);
    }
    blk.body(&mut a, false);
    if blk.careful_at.is_some() {
        blk.body(&mut a, true);
    } else {
        dynasm!(a ; .arch x64 ; =>fail ; mov eax, b[0].pc as i32);
        jmp_abs(&mut a, at, stubs.leave);
    }
    // Exits just before instruction k (the interpreter's `leave`): the
    // load-use state is that of the instruction before, or none after a
    // transfer (the core fixes the entry block's k = 0 case).
    for (k, l) in blk.exits.iter().enumerate().filter(|&(k, _)| blk.used[k]) {
        dynasm!(a ; =>*l);
        account(&mut a, blk.prefix[k], blk.retired(k), blk.jumps[k]);
        let mask = if k > 0 { b[k - 1].load_mask() } else { 0 };
        let pc = b.get(k).map_or(0, |i| i.pc);
        dynasm!(a
            ; mov DWORD [rbx + EXIT_PC], pc as i32
            ; mov DWORD [rbx + EXIT_PC + 4], 0
            ; mov DWORD [rbx + LOAD_MASK], mask as i32
            ; mov DWORD [rbx + LOAD_MASK + 4], 0
        );
        jmp_abs(&mut a, at, stubs.exit);
    }
    // The careful entry's offset (0, none, if it does not fit the table's
    // 16 bits: then the core interprets near the deadline, as before).
    let careful = blk.careful_go.map_or(0, |go| {
        let off = a
            .labels()
            .resolve_dynamic(go)
            .expect("careful entry placed")
            .0;
        u16::try_from(off).unwrap_or(0)
    });
    let code = a.finalize().ok()?;
    Some(Translation {
        code,
        worst,
        nmem,
        careful,
        patches: blk.patches,
    })
}

/// One block being translated: what both of its variants share.
struct Block<'a> {
    b: &'a [Inst],
    /// The guest register whose widened bytes `xmm2` holds (and whether
    /// zero-extended), for a run of byte dot products sharing their first
    /// operand (`dot_b`); only in the checked variant, which is entered
    /// at its start alone.
    xmm2: Option<(u8, bool)>,
    /// `xmm2` holds those bytes in both halves (a pair left them so).
    xmm2_both: bool,
    /// The guest register whose value `eax` still holds after the
    /// previous instruction's template stored it (an ALU result), so the
    /// next one need not load it back: a load of what was just stored
    /// waits for the store to forward (~5 host cycles) on the chain it is
    /// on. Checked variant only (its instructions are entered only in
    /// sequence; the careful variant's can be entered at each one).
    eax: Option<u8>,
    /// The dot product just emitted did the next instruction too
    /// (`dot_b_pair`): the body skips it.
    paired: bool,
    /// Its covered instructions.
    n: usize,
    at: usize,
    stubs: Stubs,
    known: &'a dyn Fn(u32) -> Option<Entry>,
    first_reads: &'a dyn Fn(u32) -> Option<u32>,
    l1: bool,
    sse41: bool,
    /// The checked entry (for loops to itself).
    start: DynamicLabel,
    /// The exits just before each instruction (and after the last), and
    /// which of them something jumps to (only those are emitted: unused
    /// stubs would only dilute the host's instruction cache).
    exits: Vec<DynamicLabel>,
    used: Vec<bool>,
    /// Static cycles and jumps before each instruction; the worst case of
    /// instructions k.. and their loads and stores.
    prefix: Vec<u64>,
    jumps: Vec<u64>,
    grants: Vec<u64>,
    rest: Vec<(u64, u32)>,
    /// The careful variant: before each instruction's deadline test, and
    /// past the first one (the core's entry).
    careful_at: Option<Vec<DynamicLabel>>,
    careful_go: Option<DynamicLabel>,
    /// The taken side of the branch at k, shared by both variants (the
    /// same accounting and chaining).
    taken: Vec<Option<DynamicLabel>>,
    /// The block's closing transfer (jal, jalr, or running out into the
    /// next block) in the checked variant, which the careful one jumps to
    /// after its deadline test: `(k, label before its template)`.
    tail: Option<(usize, DynamicLabel)>,
    patches: Vec<(u32, usize)>,
}

impl Block<'_> {
    /// What an exit before instruction `k` adds to `r15`: the instructions
    /// retired, and with the L1 path the grants in the bits from
    /// [`GRANT_SHIFT`] (`ctx::Ctx::retired_grants`).
    fn retired(&self, k: usize) -> u64 {
        k as u64 + (self.grants[k] << GRANT_SHIFT)
    }

    /// One variant of the block's instructions: the checked one (entered
    /// when the worst case fits; L1 accesses test the deadline again after
    /// themselves, going on in the careful variant when the rest might not
    /// fit), or the careful one (`careful`: the interpreter's test before
    /// every instruction, `cycles >= deadline` leaving just before it,
    /// where `cycles` = `r13` + the static prefix is exact: every dynamic
    /// cost is in `r13` by then).
    fn body(&mut self, a: &mut Asm, careful: bool) {
        let (b, n) = (self.b, self.n);
        // The loads and stores' other-region paths, emitted after the body.
        let mut l1_sites: Vec<(Inst, L1Site)> = Vec::new();
        self.xmm2 = None;
        let mut skip = false;
        for (k, i) in b[..n].iter().enumerate() {
            if std::mem::take(&mut skip) {
                // Done with the dot product before it (`dot_b_pair`).
                if k + 1 == n {
                    self.used[n] = true;
                    dynasm!(a ; jmp =>self.exits[n]);
                }
                continue;
            }
            // Only consecutive dot products share `xmm2` (anything else may
            // write the register or call a helper, which clobbers it).
            let dot = self.sse41 && is_dot_b(i.op);
            if careful || !dot {
                self.xmm2 = None;
            }
            if careful {
                let here = self.careful_at.as_ref().expect("careful variant")[k];
                dynasm!(a ; .arch x64 ; =>here);
                self.used[k] = true;
                if k == 0 {
                    // After a transfer (the core enters past this test,
                    // having made it itself before any entry stall).
                    dynasm!(a ; .arch x64 ; cmp r13, [rbx + DEADLINE] ; jae =>self.exits[0]);
                    let go = self.careful_go.expect("careful entry");
                    dynasm!(a ; .arch x64 ; =>go);
                } else {
                    dynasm!(a ; .arch x64
                        ; lea rcx, [r13 + self.prefix[k] as i32]
                        ; cmp rcx, [rbx + DEADLINE]
                        ; jae =>self.exits[k]
                    );
                }
                if let Some((t, l)) = self.tail.filter(|&(t, _)| t == k) {
                    // The closing transfer, as the checked variant has it.
                    debug_assert_eq!(t + 1, n);
                    dynasm!(a ; .arch x64 ; jmp =>l);
                    break;
                }
            }
            if self.inst(a, k, i, careful, &mut l1_sites) {
                break;
            }
            skip = std::mem::take(&mut self.paired);
            if !skip && k + 1 == n {
                // The next instruction is not covered: leave before it.
                self.used[n] = true;
                dynasm!(a ; jmp =>self.exits[n]);
            }
        }
        if !careful {
            self.taken_sides(a);
        }
        for (i, site) in &l1_sites {
            if self.l1 {
                out_of_line(a, i, site);
            } else {
                plain_out_of_line(a, i, site);
            }
        }
    }

    /// Instruction k's template; true when it closes the block.
    fn inst(
        &mut self,
        a: &mut Asm,
        k: usize,
        i: &Inst,
        careful: bool,
        l1_sites: &mut Vec<(Inst, L1Site)>,
    ) -> bool {
        let (rd, rs1, rs2) = (reg(i.rd), reg(i.rs1), reg(i.rs2));
        let imm = i.imm as i32;
        let (at, stubs) = (self.at, self.stubs);
        // What eax holds on entry, and whether this template leaves rd's
        // new value there (`Block::eax`).
        let eax = std::mem::take(&mut self.eax).filter(|_| !careful);
        let keeps = !careful && i.rd != 0;
        let load_rs1 = |a: &mut Asm| {
            if eax != Some(i.rs1) || i.rs1 == 0 {
                dynasm!(a ; .arch x64 ; mov eax, [r12 + rs1]);
            }
        };
        match i.op {
            op::NOP | op::FENCE | op::FENCE_I => {}
            op::LUI => dynasm!(a ; mov DWORD [r12 + rd], imm),
            // `li` and `mv`: one store, or a copy.
            op::ADDI if i.rs1 == 0 => dynasm!(a ; mov DWORD [r12 + rd], imm),
            op::ADDI if imm == 0 => {
                load_rs1(a);
                dynasm!(a ; mov [r12 + rd], eax);
                self.eax = keeps.then_some(i.rd);
            }
            op::ADDI | op::XORI | op::ORI | op::ANDI | op::SLLI | op::SRLI | op::SRAI => {
                load_rs1(a);
                self.eax = keeps.then_some(i.rd);
                match i.op {
                    op::ADDI => dynasm!(a ; add eax, imm),
                    op::XORI => dynasm!(a ; xor eax, imm),
                    op::ORI => dynasm!(a ; or eax, imm),
                    op::ANDI => dynasm!(a ; and eax, imm),
                    op::SLLI => dynasm!(a ; shl eax, (imm & 31) as i8),
                    op::SRLI => dynasm!(a ; shr eax, (imm & 31) as i8),
                    _ => dynasm!(a ; sar eax, (imm & 31) as i8),
                }
                dynasm!(a ; mov [r12 + rd], eax);
            }
            op::SLTI | op::SLTIU => {
                dynasm!(a ; xor eax, eax ; cmp DWORD [r12 + rs1], imm);
                if i.op == op::SLTI {
                    dynasm!(a ; setl al);
                } else {
                    dynasm!(a ; setb al);
                }
                dynasm!(a ; mov [r12 + rd], eax);
            }
            op::ADD | op::SUB | op::XOR | op::OR | op::AND | op::MUL => {
                load_rs1(a);
                self.eax = keeps.then_some(i.rd);
                match i.op {
                    op::ADD => dynasm!(a ; add eax, [r12 + rs2]),
                    op::SUB => dynasm!(a ; sub eax, [r12 + rs2]),
                    op::XOR => dynasm!(a ; xor eax, [r12 + rs2]),
                    op::OR => dynasm!(a ; or eax, [r12 + rs2]),
                    op::AND => dynasm!(a ; and eax, [r12 + rs2]),
                    _ => dynasm!(a ; imul eax, [r12 + rs2]),
                }
                dynasm!(a ; mov [r12 + rd], eax);
            }
            op::SLL | op::SRL | op::SRA => {
                // x86 masks 32-bit shift counts to 5 bits, as RISC-V does.
                dynasm!(a ; mov eax, [r12 + rs1] ; mov ecx, [r12 + rs2]);
                match i.op {
                    op::SLL => dynasm!(a ; shl eax, cl),
                    op::SRL => dynasm!(a ; shr eax, cl),
                    _ => dynasm!(a ; sar eax, cl),
                }
                dynasm!(a ; mov [r12 + rd], eax);
            }
            op::SLT | op::SLTU => {
                dynasm!(a ; mov ecx, [r12 + rs1] ; xor eax, eax ; cmp ecx, [r12 + rs2]);
                if i.op == op::SLT {
                    dynasm!(a ; setl al);
                } else {
                    dynasm!(a ; setb al);
                }
                dynasm!(a ; mov [r12 + rd], eax);
            }
            op::MULH | op::MULHSU | op::MULHU => {
                // The 64-bit product of the extended operands; for mulhsu
                // |a·b| < 2^63, for mulhu the low 64 bits are exact.
                match i.op {
                    op::MULH => {
                        dynasm!(a ; movsxd rax, DWORD [r12 + rs1] ; movsxd rcx, DWORD [r12 + rs2])
                    }
                    op::MULHSU => dynasm!(a ; movsxd rax, DWORD [r12 + rs1] ; mov ecx, [r12 + rs2]),
                    _ => dynasm!(a ; mov eax, [r12 + rs1] ; mov ecx, [r12 + rs2]),
                }
                dynasm!(a ; imul rax, rcx ; shr rax, 32 ; mov [r12 + rd], eax);
            }
            o if self.sse41 && is_dot_b(o) => {
                let first = (i.rs1, matches!(o, op::CV_SDOTUP_B | op::CV_SDOTUSP_B));
                let cached = self.xmm2 == Some(first);
                // The next instruction, done with this one when it is the
                // same dot product of the same first operand and reads
                // nothing this one writes (checked variant only: the
                // careful one may leave between the two).
                let next = self.b[..self.n].get(k + 1).filter(|j| {
                    !careful
                        && j.op == i.op
                        && j.rs1 == i.rs1
                        && i.rd != i.rs1
                        && (i.rd == 0 || j.rs2 != i.rd)
                });
                match next {
                    Some(j) => {
                        dot_b_pair(a, i, j, cached, cached && self.xmm2_both);
                        self.paired = true;
                        self.xmm2 = (j.rd != j.rs1).then_some(first);
                        self.xmm2_both = true;
                    }
                    None => {
                        dot_b(a, i, cached);
                        self.xmm2_both &= cached;
                        // The next one may reuse it, unless this one wrote it.
                        self.xmm2 = (!careful && i.rd != i.rs1).then_some(first);
                    }
                }
            }
            // `cv.min`, `cv.max` and their unsigned forms inline (the
            // network's requantization clamps with them; `xcv::alu::exec`
            // through the helper otherwise): rs2 where it wins.
            op::CV_ALU if min_max(i.imm).is_some() => {
                dynasm!(a ; mov eax, [r12 + rs1] ; mov ecx, [r12 + rs2] ; cmp eax, ecx);
                match min_max(i.imm).expect("guarded") {
                    alu::MIN => dynasm!(a ; cmovg eax, ecx),
                    alu::MAX => dynasm!(a ; cmovl eax, ecx),
                    alu::MINU => dynasm!(a ; cmova eax, ecx),
                    _ => dynasm!(a ; cmovb eax, ecx),
                }
                if i.rd != 0 {
                    dynasm!(a ; mov [r12 + rd], eax);
                }
            }
            o if helper(o).is_some() => {
                let f = helper(o).expect("helper") as usize as i64;
                dynasm!(a
                    ; mov edi, [r12 + rs1]
                    ; mov esi, [r12 + rs2]
                    ; mov edx, [r12 + rd]
                    ; mov ecx, imm
                    ; mov rax, QWORD f
                    ; call rax
                );
                if i.rd != 0 {
                    dynasm!(a ; mov [r12 + rd], eax);
                }
                if is_div(o) {
                    dynasm!(a ; shr rax, 32 ; add r13, rax);
                }
            }
            o if is_mem(o) => {
                self.used[k] = true;
                // The checked variant, on a memory with an L1, tests the
                // deadline again after the access (`recheck`) and goes on
                // in the careful variant (or leaves) when the rest might
                // not fit; the careful variant tests before every
                // instruction anyway.
                let recheck = self.l1 && !careful;
                let after = match &self.careful_at {
                    Some(c) if k + 1 < self.n => c[k + 1],
                    _ => {
                        self.used[k + 1] |= recheck;
                        self.exits[k + 1]
                    }
                };
                let back = a.new_dynamic_label();
                // Without the L1 path a load may still read the device
                // window out of line (`mem::plain_out_of_line`); a store leaves.
                let out = self.l1 || !is_store(o);
                let site = L1Site {
                    other: if out {
                        a.new_dynamic_label()
                    } else {
                        self.exits[k]
                    },
                    ool: a.new_dynamic_label(),
                    busy: a.new_dynamic_label(),
                    split: a.new_dynamic_label(),
                    split_back: a.new_dynamic_label(),
                    join: a.new_dynamic_label(),
                    back,
                    issue: self.prefix[k + 1] - 1,
                    rest: self.rest[k + 1],
                    recheck,
                    exit: self.exits[k],
                    after,
                };
                mem_op(a, i, &site, self.l1, eax == Some(i.rs1) && i.rs1 != 0);
                dynasm!(a ; .arch x64 ; =>back);
                // Every access has out-of-line parts: the L1 path's, or
                // without it the window and a word's split cycle.
                l1_sites.push((*i, site));
            }
            op::BEQ | op::BNE | op::BLT | op::BGE | op::BLTU | op::BGEU => {
                let l = self.taken_label(a, k);
                let in_eax = eax == Some(i.rs1) && i.rs1 != 0;
                match (i.rs2 == 0, in_eax) {
                    // `test` sets the flags `cmp` with 0 would (CF = OF = 0).
                    (true, true) => dynasm!(a ; test eax, eax),
                    (true, false) => dynasm!(a ; cmp DWORD [r12 + rs1], 0),
                    (false, true) => dynasm!(a ; cmp eax, [r12 + rs2]),
                    (false, false) => dynasm!(a ; mov eax, [r12 + rs1] ; cmp eax, [r12 + rs2]),
                }
                match i.op {
                    op::BEQ => dynasm!(a ; je =>l),
                    op::BNE => dynasm!(a ; jne =>l),
                    op::BLT => dynasm!(a ; jl =>l),
                    op::BGE => dynasm!(a ; jge =>l),
                    op::BLTU => dynasm!(a ; jb =>l),
                    _ => dynasm!(a ; jae =>l),
                }
            }
            op::CV_BEQIMM | op::CV_BNEIMM => {
                let l = self.taken_label(a, k);
                let imm5 = ((i.rd as i32) << 27) >> 27;
                dynasm!(a ; cmp DWORD [r12 + rs1], imm5);
                if i.op == op::CV_BEQIMM {
                    dynasm!(a ; je =>l);
                } else {
                    dynasm!(a ; jne =>l);
                }
            }
            op::JUMP => {
                if i.rd != 0 {
                    let link = i.pc.wrapping_add(i.len as u32) as i32;
                    dynasm!(a ; mov DWORD [r12 + rd], link);
                }
            }
            op::JAL | op::JALR => {
                self.mark_tail(a, k);
                if i.op == op::JALR {
                    dynasm!(a ; mov eax, [r12 + rs1] ; add eax, imm ; and eax, -2);
                }
                if i.rd != 0 {
                    let link = i.pc.wrapping_add(i.len as u32) as i32;
                    dynasm!(a ; mov DWORD [r12 + rd], link);
                }
                account(
                    a,
                    self.prefix[k + 1],
                    self.retired(k + 1),
                    self.jumps[k] + 1,
                );
                if i.op == op::JAL {
                    self.chain(a, i.imm);
                } else {
                    jmp_abs(a, at, stubs.dispatch);
                }
                return true;
            }
            op::END => {
                self.mark_tail(a, k);
                // The block ran out (`imm` = the next pc): go on into the
                // next block as the core would, when the next block's
                // first instruction is known not to stall on the last
                // one's load (the entry stall the core would add), else
                // leave and let the core do it. Not a transfer: no jump.
                let b = self.b;
                let stall = k == 0 || {
                    let m = b[k - 1].load_mask();
                    m != 0 && (self.first_reads)(i.imm).is_none_or(|r| r & m != 0)
                };
                if stall {
                    self.used[k] = true;
                    dynasm!(a ; jmp =>self.exits[k]);
                } else {
                    account(a, self.prefix[k], self.retired(k), self.jumps[k]);
                    self.chain(a, i.imm);
                }
                return true;
            }
            _ => unreachable!("covered op without a template"),
        }
        false
    }

    /// The label of the branch at k's taken side (made once, shared by the
    /// variants).
    fn taken_label(&mut self, a: &mut Asm, k: usize) -> DynamicLabel {
        *self.taken[k].get_or_insert_with(|| a.new_dynamic_label())
    }

    /// Mark the checked variant's closing transfer at k (the careful
    /// variant jumps there).
    fn mark_tail(&mut self, a: &mut Asm, k: usize) {
        if self.tail.is_none() {
            let l = a.new_dynamic_label();
            dynasm!(a ; .arch x64 ; =>l);
            self.tail = Some((k, l));
        }
    }

    /// Taken branches: their cost plus the taken extra, then chain.
    fn taken_sides(&mut self, a: &mut Asm) {
        let b = self.b;
        let taken: Vec<_> = self
            .taken
            .iter()
            .enumerate()
            .filter_map(|(k, l)| Some((k, (*l)?)))
            .collect();
        for (k, l) in taken {
            dynasm!(a ; =>l);
            account(
                a,
                self.prefix[k + 1] + BRANCH_TAKEN_EXTRA,
                self.retired(k + 1),
                self.jumps[k] + 1,
            );
            // A short backward branch closes a loop the idle detector wants
            // to see after a device read (`exec::transfer`,
            // `Cpu::poll_slow`): leave at its target, telling the core
            // where it came from.
            let (from, to) = (b[k].pc, b[k].imm);
            if to < from && from - to <= MAX_POLL_LOOP_BYTES {
                let go = a.new_dynamic_label();
                dynasm!(a ; .arch x64
                    ; cmp BYTE [rbx + POLL_ARMED], 0
                    ; je =>go
                    ; mov DWORD [rbx + POLL_FROM], from as i32
                    ; mov eax, to as i32
                );
                jmp_abs(a, self.at, self.stubs.leave);
                dynasm!(a ; .arch x64 ; =>go);
            }
            self.chain(a, b[k].imm);
        }
    }

    /// Go on at the static target `to`: straight into its translation's
    /// checked entry when it is known (or this block's, for loops to
    /// itself), else through the dispatcher, a jump `patches` records so
    /// it can go straight there once the target is translated.
    fn chain(&mut self, a: &mut Asm, to: u32) {
        if to == self.b[0].pc {
            dynasm!(a ; .arch x64 ; jmp =>self.start);
            return;
        }
        dynasm!(a ; .arch x64 ; mov eax, to as i32);
        match (self.known)(to) {
            Some(e) => jmp_abs(a, self.at, e.code as usize),
            None => {
                self.patches.push((to, a.offset().0 + 1));
                jmp_abs(a, self.at, self.stubs.dispatch);
            }
        }
    }
}

/// The function of a `cv.min`, `cv.max`, `cv.minu` or `cv.maxu` (an
/// [`op::CV_ALU`]'s `imm`, `xcv::alu`), else `None`.
fn min_max(imm: u32) -> Option<u32> {
    let f = imm >> 16;
    matches!(f, alu::MIN | alu::MAX | alu::MINU | alu::MAXU).then_some(f)
}

/// The byte dot products (`cv.sdotsp.b`, `cv.sdotusp.b`, `cv.sdotup.b`,
/// `cv.dotsp.b`) inline: the four bytes of each operand widened to 16 bits
/// (signed or not, as `xcv::simd` has them; 0..255 is a positive `i16`),
/// `pmaddwd` multiplies the lanes into 32-bit products and adds them in
/// pairs, the two pair sums are added, and the result is added to rd
/// (modulo 2^32) for the `sdot` forms. Every product and sum fits in 32
/// bits, so this is the interpreter's `i32` sum. (`pmaddwd` is one
/// micro-op where `pmulld` and two `phaddd` are eight.)
fn dot_b(a: &mut Asm, i: &Inst, cached: bool) {
    let (rd, rs1, rs2) = (reg(i.rd), reg(i.rs1), reg(i.rs2));
    // rs1 unsigned for sdotup and sdotusp, rs2 unsigned for sdotup only;
    // rs1's widened bytes stay in xmm2 for the next dot product (`cached`:
    // the previous one left them there).
    if !cached {
        widen(
            a,
            2,
            rs1,
            matches!(i.op, op::CV_SDOTUP_B | op::CV_SDOTUSP_B),
        );
    }
    widen(a, 1, rs2, i.op == op::CV_SDOTUP_B);
    dynasm!(a ; .arch x64
        ; pmaddwd xmm1, xmm2
        ; pshufd xmm0, xmm1, 1
        ; paddd xmm0, xmm1
        ; movd eax, xmm0
    );
    if i.op != op::CV_DOTSP_B {
        dynasm!(a ; .arch x64 ; add eax, [r12 + rd]);
    }
    if i.rd != 0 {
        dynasm!(a ; .arch x64 ; mov [r12 + rd], eax);
    }
}

/// Two consecutive byte dot products `i` and `j` of the same kind and
/// first operand, `j` reading nothing `i` writes (`Block::inst` checks):
/// one `pmaddwd` for both. The first operand's widened bytes in both
/// halves of `xmm2`, the two second operands' bytes side by side in
/// `xmm1`, widened to eight lanes; `phaddd` adds each one's two pair
/// sums; then `i`'s result is written before `j`'s (which may accumulate
/// into the same register), as one after the other would. Every sum
/// fits in 32 bits, as in [`dot_b`]. The network's kernels do eight dot
/// products per pair of loaded rows, four per first operand: this halves
/// their widening and summing (`cosim nn eval`).
///
/// `both`: `xmm2` already holds the first operand in both halves (the
/// previous pair's).
fn dot_b_pair(a: &mut Asm, i: &Inst, j: &Inst, cached: bool, both: bool) {
    let (rs1, rs2a, rs2b) = (reg(i.rs1), reg(i.rs2), reg(j.rs2));
    if !cached {
        widen(
            a,
            2,
            rs1,
            matches!(i.op, op::CV_SDOTUP_B | op::CV_SDOTUSP_B),
        );
    }
    if !both {
        dynasm!(a ; .arch x64 ; punpcklqdq xmm2, xmm2);
    }
    dynasm!(a ; .arch x64
        ; movd xmm1, [r12 + rs2a]
        ; movd xmm3, [r12 + rs2b]
        ; punpckldq xmm1, xmm3
    );
    if i.op == op::CV_SDOTUP_B {
        dynasm!(a ; .arch x64 ; pmovzxbw xmm1, xmm1);
    } else {
        dynasm!(a ; .arch x64 ; pmovsxbw xmm1, xmm1);
    }
    dynasm!(a ; .arch x64
        ; pmaddwd xmm1, xmm2
        ; phaddd xmm1, xmm1
        ; movd eax, xmm1
    );
    for (k, d) in [(0, i.rd), (1, j.rd)] {
        if k == 1 {
            dynasm!(a ; .arch x64 ; pextrd eax, xmm1, 1);
        }
        if i.op != op::CV_DOTSP_B {
            dynasm!(a ; .arch x64 ; add eax, [r12 + reg(d)]);
        }
        if d != 0 {
            dynasm!(a ; .arch x64 ; mov [r12 + reg(d)], eax);
        }
    }
}

/// The byte dot products [`dot_b`] does inline.
fn is_dot_b(o: u8) -> bool {
    matches!(
        o,
        op::CV_SDOTSP_B | op::CV_SDOTUSP_B | op::CV_SDOTUP_B | op::CV_DOTSP_B
    )
}

/// `xmm{x}`'s four low 16-bit lanes = the four bytes of the guest
/// register at `off`, sign- or zero-extended. Loaded with a 4-byte `movd`
/// first: an 8-byte load straight from the register file would span the
/// register and the next one, most often both just stored, which the
/// host cannot forward from its store buffer (measured: `xcv_bench.elf`
/// 3x slower, `cosim nn eval` no faster).
fn widen(a: &mut Asm, x: u8, off: i32, unsigned: bool) {
    dynasm!(a ; .arch x64 ; movd Rx(x), [r12 + off]);
    if unsigned {
        dynasm!(a ; .arch x64 ; pmovzxbw Rx(x), Rx(x));
    } else {
        dynasm!(a ; .arch x64 ; pmovsxbw Rx(x), Rx(x));
    }
}

/// `jmp rel32` to a host address (dynasm-rs has no absolute targets on
/// x64); `at` is where the assembler's code will be placed.
fn jmp_abs(a: &mut Asm, at: usize, target: usize) {
    let end = at + a.offset().0 + 5;
    a.push(0xe9);
    a.extend(rel32(end, target).to_le_bytes());
}

/// The displacement from the end of a jump to its target (the code buffer
/// is one mapping of a few MiB, so it fits).
fn rel32(end: usize, target: usize) -> i32 {
    i32::try_from(target as i64 - end as i64).expect("jump within the code buffer")
}

/// Add the static cycles, retired instructions and jumps of an exit.
fn account(a: &mut Asm, cycles: u64, retired: u64, jumps: u64) {
    if cycles != 0 {
        dynasm!(a ; .arch x64 ; add r13, cycles as i32);
    }
    match i32::try_from(retired) {
        Ok(0) => {}
        Ok(r) => dynasm!(a ; .arch x64 ; add r15, r),
        // Over 127 grants (`retired`): through `rcx`, free at every exit.
        Err(_) => dynasm!(a ; .arch x64 ; mov rcx, QWORD retired as i64 ; add r15, rcx),
    }
    if jumps != 0 {
        dynasm!(a ; .arch x64 ; add QWORD [rbx + JUMPS], jumps as i32);
    }
}

/// Go on only if the worst case from here, `rcx` = the cycles before the
/// access extras, plus `nmem` accesses at [`Ctx::worst_extra`] each, ends
/// before the deadline; else jump to `fail`.
fn fits(a: &mut Asm, nmem: u32, fail: DynamicLabel) {
    if nmem != 0 {
        dynasm!(a ; .arch x64 ; imul rdx, [rbx + WORST_EXTRA], nmem as i32 ; add rcx, rdx);
    }
    dynasm!(a ; .arch x64 ; cmp rcx, [rbx + DEADLINE] ; jae =>fail);
}
