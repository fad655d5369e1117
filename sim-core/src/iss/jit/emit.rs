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
//! `tohost`). L1 accesses grant their bank as `cluster::tcdm` does, at the
//! interpreter's issue cycle (`grant`).

use dynasmrt::x64::X64Relocation;
use dynasmrt::{dynasm, DynasmApi, DynasmLabelApi, VecAssembler};

use super::super::block::Inst;
use super::super::cpu::MAX_POLL_LOOP_BYTES;
use super::super::decode::op;
use super::super::timing::BRANCH_TAKEN_EXTRA;
use super::super::xcv::mem::{base_op, mode, Mode};
use super::ctx::*;
use super::helpers::{helper, is_div, l1_access, MAX_DIV_EXTRA};
use crate::cluster::tcdm::{BANKS, WORDS};

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
    pub nmem: u32,
    /// Jumps to the dispatcher for a static target not translated yet:
    /// `(target pc, offset of the jump's rel32 in code)`, to be pointed at
    /// the target's code once it exists.
    pub patches: Vec<(u32, usize)>,
}

/// Translate the block `b` (its instructions up to and including its last),
/// to be placed at host address `at`. `known` gives the translated block
/// at a guest pc, for direct jumps, and `first_reads` the registers the
/// first instruction of the cached block at a pc reads; `l1`: the memory has a cluster L1,
/// whose accesses get a path of their own (`l1_op`; the cluster cores'
/// translations, marked [`L1_PATH`] in `nmem`). `None` when its first
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
    let n = b.iter().take_while(|i| covered(i.op)).count();
    if n == 0 {
        return None;
    }
    // Static bookkeeping: cycles and jumps before each instruction.
    let mut prefix = vec![0u64; n + 1];
    let mut jumps = vec![0u64; n + 1];
    for (k, i) in b[..n].iter().enumerate() {
        prefix[k + 1] = prefix[k] + i.cost as u64;
        jumps[k + 1] = jumps[k] + (i.op == op::JUMP) as u64;
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
    let mut a = Asm::new(at);
    let start = a.new_dynamic_label();
    let exits: Vec<_> = (0..=n).map(|_| a.new_dynamic_label()).collect();
    // Which exits something jumps to (only those are emitted: unused stubs
    // would only dilute the host's instruction cache).
    let mut used = vec![false; n + 1];
    let mut taken: Vec<(usize, dynasmrt::DynamicLabel)> = Vec::new();
    let mut patches = Vec::new();
    // The loads and stores' other-region paths, emitted after the block.
    let mut l1_sites: Vec<(Inst, L1Site)> = Vec::new();
    // The checked entry: enter only if the worst case ends before the
    // deadline, else leave at the block's start (reached by a transfer:
    // nothing in the load shadow).
    let fail = a.new_dynamic_label();
    dynasm!(a ; .arch x64 ; =>start ; lea rcx, [r13 + worst as i32]);
    if l1 {
        fits(&mut a, nmem, fail);
    } else if nmem != 0 {
        // Without the L1 path only fast-region accesses stay (`rbp` each).
        dynasm!(a ; .arch x64 ; imul rdx, rbp, nmem as i32 ; add rcx, rdx);
        dynasm!(a ; .arch x64 ; cmp rcx, [rbx + DEADLINE] ; jae =>fail);
    } else {
        dynasm!(a ; .arch x64 ; cmp rcx, [rbx + DEADLINE] ; jae =>fail);
    }

    for (k, i) in b[..n].iter().enumerate() {
        let (rd, rs1, rs2) = (reg(i.rd), reg(i.rs1), reg(i.rs2));
        let imm = i.imm as i32;
        match i.op {
            op::NOP | op::FENCE | op::FENCE_I => {}
            op::LUI => dynasm!(a ; mov DWORD [r12 + rd], imm),
            // `li` and `mv`: one store, or a copy.
            op::ADDI if i.rs1 == 0 => dynasm!(a ; mov DWORD [r12 + rd], imm),
            op::ADDI if imm == 0 => dynasm!(a ; mov eax, [r12 + rs1] ; mov [r12 + rd], eax),
            op::ADDI | op::XORI | op::ORI | op::ANDI | op::SLLI | op::SRLI | op::SRAI => {
                dynasm!(a ; mov eax, [r12 + rs1]);
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
                dynasm!(a ; mov eax, [r12 + rs1]);
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
            op::CV_SDOTSP_B | op::CV_SDOTUSP_B | op::CV_SDOTUP_B | op::CV_DOTSP_B if sse41 => {
                dot_b(&mut a, i)
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
                used[k] = true;
                used[k + 1] |= l1;
                let back = a.new_dynamic_label();
                let site = L1Site {
                    other: if l1 { a.new_dynamic_label() } else { exits[k] },
                    back,
                    issue: prefix[k + 1] - 1,
                    rest: rest[k + 1],
                    exit: exits[k],
                    after: exits[k + 1],
                };
                mem_op(&mut a, i, &site, l1);
                dynasm!(a ; .arch x64 ; =>back);
                if l1 {
                    l1_sites.push((*i, site));
                }
            }
            op::BEQ | op::BNE | op::BLT | op::BGE | op::BLTU | op::BGEU => {
                let l = a.new_dynamic_label();
                if i.rs2 == 0 {
                    dynasm!(a ; cmp DWORD [r12 + rs1], 0);
                } else {
                    dynasm!(a ; mov eax, [r12 + rs1] ; cmp eax, [r12 + rs2]);
                }
                match i.op {
                    op::BEQ => dynasm!(a ; je =>l),
                    op::BNE => dynasm!(a ; jne =>l),
                    op::BLT => dynasm!(a ; jl =>l),
                    op::BGE => dynasm!(a ; jge =>l),
                    op::BLTU => dynasm!(a ; jb =>l),
                    _ => dynasm!(a ; jae =>l),
                }
                taken.push((k, l));
            }
            op::CV_BEQIMM | op::CV_BNEIMM => {
                let l = a.new_dynamic_label();
                let imm5 = ((i.rd as i32) << 27) >> 27;
                dynasm!(a ; cmp DWORD [r12 + rs1], imm5);
                if i.op == op::CV_BEQIMM {
                    dynasm!(a ; je =>l);
                } else {
                    dynasm!(a ; jne =>l);
                }
                taken.push((k, l));
            }
            op::JUMP => {
                if i.rd != 0 {
                    let link = i.pc.wrapping_add(i.len as u32) as i32;
                    dynasm!(a ; mov DWORD [r12 + rd], link);
                }
            }
            op::JAL | op::JALR => {
                if i.op == op::JALR {
                    dynasm!(a ; mov eax, [r12 + rs1] ; add eax, imm ; and eax, -2);
                }
                if i.rd != 0 {
                    let link = i.pc.wrapping_add(i.len as u32) as i32;
                    dynasm!(a ; mov DWORD [r12 + rd], link);
                }
                account(&mut a, prefix[k + 1], k as u64 + 1, jumps[k] + 1);
                if i.op == op::JAL {
                    chain(
                        &mut a,
                        at,
                        i.imm,
                        stubs,
                        known,
                        (b[0].pc, start),
                        &mut patches,
                    );
                } else {
                    jmp_abs(&mut a, at, stubs.dispatch);
                }
                break;
            }
            op::END => {
                // The block ran out (`imm` = the next pc): go on into the
                // next block as the core would, when the next block's
                // first instruction is known not to stall on the last
                // one's load (the entry stall the core would add), else
                // leave and let the core do it. Not a transfer: no jump.
                let stall = k == 0 || {
                    let m = b[k - 1].load_mask();
                    m != 0 && first_reads(i.imm).is_none_or(|r| r & m != 0)
                };
                if stall {
                    used[k] = true;
                    dynasm!(a ; jmp =>exits[k]);
                } else {
                    account(&mut a, prefix[k], k as u64, jumps[k]);
                    chain(
                        &mut a,
                        at,
                        i.imm,
                        stubs,
                        known,
                        (b[0].pc, start),
                        &mut patches,
                    );
                }
                break;
            }
            _ => unreachable!("covered op without a template"),
        }
        if k + 1 == n {
            // The next instruction is not covered: leave before it.
            used[n] = true;
            dynasm!(a ; jmp =>exits[n]);
        }
    }

    // Taken branches: their cost plus the taken extra, then chain.
    for (k, l) in taken {
        dynasm!(a ; =>l);
        account(
            &mut a,
            prefix[k + 1] + BRANCH_TAKEN_EXTRA,
            k as u64 + 1,
            jumps[k] + 1,
        );
        // A short backward branch closes a loop the idle detector wants to
        // see after a device read (`exec::transfer`, `Cpu::poll_slow`):
        // leave at its target, telling the core where it came from.
        let (from, to) = (b[k].pc, b[k].imm);
        if to < from && from - to <= MAX_POLL_LOOP_BYTES {
            let go = a.new_dynamic_label();
            dynasm!(a ; .arch x64
                ; cmp BYTE [rbx + POLL_ARMED], 0
                ; je =>go
                ; mov DWORD [rbx + POLL_FROM], from as i32
                ; mov eax, to as i32
            );
            jmp_abs(&mut a, at, stubs.leave);
            dynasm!(a ; .arch x64 ; =>go);
        }
        chain(
            &mut a,
            at,
            b[k].imm,
            stubs,
            known,
            (b[0].pc, start),
            &mut patches,
        );
    }
    for (i, site) in &l1_sites {
        l1_op(&mut a, i, site);
    }
    dynasm!(a ; .arch x64 ; =>fail ; mov eax, b[0].pc as i32);
    jmp_abs(&mut a, at, stubs.leave);
    // Exits just before instruction k (the interpreter's `leave`): the
    // load-use state is that of the instruction before, or none after a
    // transfer (the core fixes the entry block's k = 0 case).
    for (k, l) in exits.iter().enumerate().filter(|&(k, _)| used[k]) {
        dynasm!(a ; =>*l);
        account(&mut a, prefix[k], k as u64, jumps[k]);
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
    let code = a.finalize().ok()?;
    Some(Translation {
        code,
        worst,
        nmem: nmem | if l1 { L1_PATH } else { 0 },
        patches,
    })
}

/// The byte dot products (`cv.sdotsp.b`, `cv.sdotusp.b`, `cv.sdotup.b`,
/// `cv.dotsp.b`) inline: the four bytes of each operand widened to 32 bits
/// (signed or not, as `xcv::simd` has them), multiplied lane by lane, the
/// lanes summed, added to rd (modulo 2^32) for the `sdot` forms. Each
/// product fits in 17 bits, so the 32-bit lanes are exact, as the
/// interpreter's `i32` sums are.
fn dot_b(a: &mut Asm, i: &Inst) {
    let (rd, rs1, rs2) = (reg(i.rd), reg(i.rs1), reg(i.rs2));
    match i.op {
        op::CV_SDOTUP_B => dynasm!(a ; .arch x64
            ; pmovzxbd xmm0, DWORD [r12 + rs1]
            ; pmovzxbd xmm1, DWORD [r12 + rs2]
        ),
        op::CV_SDOTUSP_B => dynasm!(a ; .arch x64
            ; pmovzxbd xmm0, DWORD [r12 + rs1]
            ; pmovsxbd xmm1, DWORD [r12 + rs2]
        ),
        _ => dynasm!(a ; .arch x64
            ; pmovsxbd xmm0, DWORD [r12 + rs1]
            ; pmovsxbd xmm1, DWORD [r12 + rs2]
        ),
    }
    dynasm!(a ; .arch x64
        ; pmulld xmm0, xmm1
        ; phaddd xmm0, xmm0
        ; phaddd xmm0, xmm0
        ; movd eax, xmm0
    );
    if i.op != op::CV_DOTSP_B {
        dynasm!(a ; .arch x64 ; add eax, [r12 + rd]);
    }
    if i.rd != 0 {
        dynasm!(a ; .arch x64 ; mov [r12 + rd], eax);
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
    if retired != 0 {
        dynasm!(a ; .arch x64 ; add r15, retired as i32);
    }
    if jumps != 0 {
        dynasm!(a ; .arch x64 ; add QWORD [rbx + JUMPS], jumps as i32);
    }
}

/// Go on at the static target `to`: straight into its translation's
/// checked entry when it is known (`me`: the block being translated, for
/// loops to itself), else through the dispatcher, a jump `patches` records
/// so it can go straight there once the target is translated.
fn chain(
    a: &mut Asm,
    at: usize,
    to: u32,
    stubs: Stubs,
    known: &dyn Fn(u32) -> Option<Entry>,
    me: (u32, dynasmrt::DynamicLabel),
    patches: &mut Vec<(u32, usize)>,
) {
    if to == me.0 {
        dynasm!(a ; .arch x64 ; jmp =>me.1);
        return;
    }
    dynasm!(a ; .arch x64 ; mov eax, to as i32);
    match known(to) {
        Some(e) => jmp_abs(a, at, e.code as usize),
        None => {
            patches.push((to, a.offset().0 + 1));
            jmp_abs(a, at, stubs.dispatch);
        }
    }
}

/// Go on only if the worst case from here, `rcx` = the cycles before the
/// access extras, plus `nmem` accesses at [`Ctx::worst_extra`] each, ends
/// before the deadline; else jump to `fail`.
fn fits(a: &mut Asm, nmem: u32, fail: dynasmrt::DynamicLabel) {
    if nmem != 0 {
        dynasm!(a ; .arch x64 ; imul rdx, [rbx + WORST_EXTRA], nmem as i32 ; add rcx, rdx);
    }
    dynasm!(a ; .arch x64 ; cmp rcx, [rbx + DEADLINE] ; jae =>fail);
}

/// Where a load or store continues when its address is outside the fast
/// region (the L1 of a cluster core, out of line after the block).
struct L1Site {
    /// The out-of-line path, and where it rejoins the block.
    other: dynasmrt::DynamicLabel,
    back: dynasmrt::DynamicLabel,
    /// The access's issue cycle, relative to `r13` before it: the last
    /// cycle of its cost, as the interpreter's `Run::extra` and the
    /// general path's `Cpu::issue_cycle` have it.
    issue: u64,
    /// The worst case of the instructions after it (`translate`'s `rest`).
    rest: (u64, u32),
    /// Exits just before it and just after it.
    exit: dynasmrt::DynamicLabel,
    after: dynasmrt::DynamicLabel,
}

/// What a load or store does: its base op, size in bytes, whether a store,
/// its addressing mode and the field of its register operand (rs2 for
/// loads, rs3 = the rd field for stores).
fn shape(i: &Inst) -> (u8, i32, bool, Mode, i32) {
    let o = base_op(i.op).unwrap_or(i.op);
    let store = (op::SB..=op::SW).contains(&o);
    let n: i32 = match o {
        op::LB | op::LBU | op::SB => 1,
        op::LH | op::LHU | op::SH => 2,
        _ => 4,
    };
    let opnd = if store { reg(i.rd) } else { reg(i.rs2) };
    (o, n, store, mode(i.op), opnd)
}

/// A load or store (RV32I or XCV addressing) on the fast region; outside
/// it, on to `site.other` (the L1 path, `l1_op`), which rejoins at
/// `site.back` or leaves; near code or `tohost`, leave at `site.exit`
/// (just before it).
///
/// With an L1 (`l1`) the checked entry counts each access at the cheaper of
/// the two regions' extras ([`Ctx::worst_extra`]): a cluster core's L2
/// accesses cost 10 cycles more than its L1 ones, and counting every
/// access of an unrolled kernel at 10 left most of a 1024-cycle quantum
/// to the interpreter. So the deadline is checked again after every access
/// on either path, for the rest of the block (`recheck`).
fn mem_op(a: &mut Asm, i: &Inst, site: &L1Site, l1: bool) {
    let (_, n, store, m, opnd) = shape(i);
    let rs1 = reg(i.rs1);
    let imm = i.imm as i32;
    // eax = address.
    dynasm!(a ; .arch x64 ; mov eax, [r12 + rs1]);
    match m {
        Mode::Offset if imm != 0 => dynasm!(a ; .arch x64 ; add eax, imm),
        Mode::RegReg => dynasm!(a ; .arch x64 ; add eax, [r12 + opnd]),
        _ => {}
    }
    // rcx = offset in the fast region, rdx = its end; inside or elsewhere.
    dynasm!(a ; .arch x64
        ; mov ecx, eax
        ; sub rcx, [rbx + FAST_BASE]
        ; lea rdx, [rcx + n]
        ; cmp rdx, [rbx + FAST_SIZE]
        ; ja =>site.other
    );
    if store {
        watched(a, CODE_LO, CODE_HI, site.exit);
    }
    access(a, i, 14);
    dynasm!(a ; .arch x64 ; add r13, rbp);
    if l1 {
        // Only a core whose fast-region accesses cost extra (a cluster
        // core's L2) can exceed the count: the FC's cost nothing more.
        let skip = a.new_dynamic_label();
        dynasm!(a ; .arch x64 ; test rbp, rbp ; jz =>skip);
        recheck(a, site);
        dynasm!(a ; .arch x64 ; =>skip);
    }
}

/// After an access that may have cost more than [`Ctx::worst_extra`]: go
/// on only if the rest of the block still fits before the deadline, else
/// leave just after the access (the core goes on from there: only a pause
/// at an instruction boundary, which changes nothing).
fn recheck(a: &mut Asm, site: &L1Site) {
    let (w, nmem) = site.rest;
    dynasm!(a ; .arch x64 ; lea rcx, [r13 + w as i32]);
    fits(a, nmem, site.after);
}

/// The out-of-line rest of a load or store outside the fast region
/// (`eax` = address): in the L1, the access with its extra cycles from
/// [`l1_access`] (the bank arbiter at the interpreter's issue cycle), and,
/// since a bank's stall has no bound, the deadline check again for the
/// rest of the block (`recheck`); anywhere else, leave just before it.
fn l1_op(a: &mut Asm, i: &Inst, site: &L1Site) {
    let (_, n, store, _, _) = shape(i);
    dynasm!(a ; .arch x64
        ; =>site.other
        ; mov ecx, eax
        ; sub rcx, [rbx + L1_BASE]
        ; lea rdx, [rcx + n]
        ; cmp rdx, [rbx + L1_SIZE]
        ; ja =>site.exit
    );
    if store {
        watched(a, L1_CODE_LO, L1_CODE_HI, site.exit);
    }
    grant(a, site.issue);
    dynasm!(a ; .arch x64 ; mov r8, [rbx + L1_PTR]);
    access(a, i, 8);
    recheck(a, site);
    dynasm!(a ; .arch x64 ; jmp =>site.back);
}

/// The L1's extra cycles of an access at `eax` issued at `r13 + issue`
/// (keeps `rax`, `rcx`): inline, what `Tcdm::access` does when the cycle
/// is free in the bank (the common case: the slice of the cycle's 64 is
/// set, or a stale one restarted, and the port's count goes up); when it
/// is taken, the arbiter itself through [`l1_access`], which finds the
/// stall; without arbitration (the FC), the L1's latency alone.
fn grant(a: &mut Asm, issue: u64) {
    const SLOT_MASK: i32 = WORDS as i32 - 1;
    const BANK_MASK: i32 = BANKS as i32 - 1;
    const SLOT_SHIFT: i8 = WORDS.trailing_zeros() as i8;
    let (no_arb, fresh, done, busy, join) = (
        a.new_dynamic_label(),
        a.new_dynamic_label(),
        a.new_dynamic_label(),
        a.new_dynamic_label(),
        a.new_dynamic_label(),
    );
    let f = l1_access as extern "sysv64" fn(*mut Ctx, u32, u64) -> u64 as usize as i64;
    dynasm!(a ; .arch x64
        ; mov r9, [rbx + L1_GRANTED]
        ; test r9, r9
        ; jz =>no_arb
        // rdx = cycle, r10 = its slice's tag, r11 = its bit.
        ; lea rdx, [r13 + issue as i32]
        ; mov r10, rdx
        ; shr r10, 6
        ; xor r11d, r11d
        ; bts r11, rdx
        // r9 += 16 · (bank · WORDS + tag % WORDS): the slice's slot.
        ; mov esi, eax
        ; shr esi, 2
        ; and esi, BANK_MASK
        ; shl esi, SLOT_SHIFT
        ; mov edi, r10d
        ; and edi, SLOT_MASK
        ; add esi, edi
        ; shl rsi, 4
        ; add r9, rsi
        ; cmp [r9], r10
        ; jne =>fresh
        ; test [r9 + 8], r11
        ; jnz =>busy
        ; or [r9 + 8], r11
        ; jmp =>done
        ; =>fresh
        ; mov [r9], r10
        ; mov [r9 + 8], r11
        ; =>done
        ; mov r9, [rbx + L1_ACCESSES]
        ; add QWORD [r9], 1
        ; =>no_arb
        ; add r13, [rbx + L1_EXTRA]
        ; jmp =>join
        // Two pushes keep `rsp` 16-aligned for the call.
        ; =>busy
        ; push rax
        ; push rcx
        ; mov rdi, rbx
        ; mov esi, eax
        ; mov rax, QWORD f
        ; call rax
        ; add r13, rax
        ; pop rcx
        ; pop rax
        ; =>join
    );
}

/// A store's checks besides the bounds (`rcx` = offset in the region, `rdx`
/// = its end): not near the region's cached code (off >= code_hi or end <=
/// code_lo) and not on `tohost`, the interpreter's fast-path conditions;
/// else leave at `exit`.
fn watched(a: &mut Asm, lo: i32, hi: i32, exit: dynasmrt::DynamicLabel) {
    let ok = a.new_dynamic_label();
    dynasm!(a ; .arch x64
        ; cmp rcx, [rbx + hi]
        ; jae =>ok
        ; cmp rdx, [rbx + lo]
        ; ja =>exit
        ; =>ok
        ; mov esi, eax
        ; sub rsi, [rbx + TOHOST]
        ; cmp rsi, 8
        ; jb =>exit
    );
}

/// The access itself at host address `base + rcx` (`eax` = the guest
/// address), the base register's write-back, the loaded value and the
/// split cycle.
fn access(a: &mut Asm, i: &Inst, base: u8) {
    let (o, n, store, m, opnd) = shape(i);
    let (rd, rs1, rs2) = (reg(i.rd), reg(i.rs1), reg(i.rs2));
    let imm = i.imm as i32;
    if store {
        dynasm!(a ; .arch x64 ; mov esi, [r12 + rs2]);
        match n {
            1 => dynasm!(a ; .arch x64 ; mov [Rq(base) + rcx], sil),
            2 => dynasm!(a ; .arch x64 ; mov [Rq(base) + rcx], si),
            _ => dynasm!(a ; .arch x64 ; mov [Rq(base) + rcx], esi),
        }
    } else {
        match o {
            op::LB => dynasm!(a ; .arch x64 ; movsx edx, BYTE [Rq(base) + rcx]),
            op::LBU => dynasm!(a ; .arch x64 ; movzx edx, BYTE [Rq(base) + rcx]),
            op::LH => dynasm!(a ; .arch x64 ; movsx edx, WORD [Rq(base) + rcx]),
            op::LHU => dynasm!(a ; .arch x64 ; movzx edx, WORD [Rq(base) + rcx]),
            _ => dynasm!(a ; .arch x64 ; mov edx, [Rq(base) + rcx]),
        }
    }
    // Base write-back (the loaded value wins if rd == rs1: written after).
    if i.rs1 != 0 {
        match m {
            Mode::PostImm => dynasm!(a ; .arch x64 ; lea esi, [rax + imm] ; mov [r12 + rs1], esi),
            Mode::PostReg => {
                dynasm!(a ; .arch x64 ; mov esi, eax ; add esi, [r12 + opnd] ; mov [r12 + rs1], esi)
            }
            _ => {}
        }
    }
    if !store && i.rd != 0 {
        dynasm!(a ; .arch x64 ; mov [r12 + rd], edx);
    }
    // A split access (crosses a word boundary) costs one more cycle:
    // ((addr & 3) + n + 3) >> 3 is 1 exactly when (addr & 3) + n > 4.
    if n > 1 {
        dynasm!(a ; .arch x64
            ; and eax, 3
            ; add eax, n + 3
            ; shr eax, 3
            ; add r13, rax
        );
    }
}
