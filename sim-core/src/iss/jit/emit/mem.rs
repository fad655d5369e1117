//! The load and store templates (RV32I and XCV addressing): the fast
//! region inline, the cluster's L1 out of line with its bank grant
//! (`iss::l1`, the arbiter's own masks) at the interpreter's issue cycle.

use dynasmrt::{dynasm, DynasmApi, DynasmLabelApi};

use super::super::super::block::Inst;
use super::super::super::decode::op;
use super::super::super::l1::{BANKS, WINDOW};
use super::super::super::xcv::mem::{base_op, mode, Mode};
use super::super::ctx::*;
use super::{fits, reg, Asm};

/// A load or store's labels and static facts (`mem_op`).
#[derive(Clone, Copy)]
pub(super) struct L1Site {
    /// The other region's path (out of line, after the block, on a
    /// memory with an L1; else the exit before the access), the L1 access
    /// done out of line after a grant that stalled, with the deadline test
    /// after it (`ool`, in the checked variant), and where both rejoin the
    /// block (`back`).
    pub other: dynasmrt::DynamicLabel,
    pub ool: dynasmrt::DynamicLabel,
    /// The bank grant's out-of-line search for a free cycle (`busy`), and
    /// where it rejoins in the careful variant (`join`).
    pub busy: dynasmrt::DynamicLabel,
    /// A word access's split cycle, out of line (misaligned words are
    /// rare), and where it rejoins.
    pub split: dynasmrt::DynamicLabel,
    pub split_back: dynasmrt::DynamicLabel,
    pub join: dynasmrt::DynamicLabel,
    pub back: dynasmrt::DynamicLabel,
    /// The access's issue cycle, relative to `r13` before it: the last
    /// cycle of its cost, as the interpreter's `Run::extra` and the
    /// general path's `Cpu::issue_cycle` have it.
    pub issue: u64,
    /// The worst case of the instructions after it (`translate`'s `rest`).
    pub rest: (u64, u32),
    /// Test the deadline again after the access when it may have cost
    /// more than the checked entry counted (the checked variant on a
    /// memory with an L1; the careful variant tests before every
    /// instruction anyway).
    pub recheck: bool,
    /// Exits just before it, and where the checked variant goes on when
    /// the rest might not fit after it (the careful variant just after
    /// it, or the exit there).
    pub exit: dynasmrt::DynamicLabel,
    pub after: dynasmrt::DynamicLabel,
}

/// Whether `o` (an RV32I or XCV load or store) is a store.
pub(super) fn is_store(o: u8) -> bool {
    (op::SB..=op::SW).contains(&base_op(o).unwrap_or(o))
}

/// What a load or store does: its base op, size in bytes, whether a store,
/// its addressing mode and the field of its register operand (rs2 for
/// loads, rs3 = the rd field for stores).
fn shape(i: &Inst) -> (u8, i32, bool, Mode, i32) {
    let o = base_op(i.op).unwrap_or(i.op);
    let store = is_store(o);
    let n: i32 = match o {
        op::LB | op::LBU | op::SB => 1,
        op::LH | op::LHU | op::SH => 2,
        _ => 4,
    };
    let opnd = if store { reg(i.rd) } else { reg(i.rs2) };
    (o, n, store, mode(i.op), opnd)
}

/// A load or store (RV32I or XCV addressing). Without an L1 (`l1`
/// false): on the fast region, leaving at `site.other` (= `site.exit`,
/// just before it) elsewhere or near code or `tohost`. With one (a
/// cluster core's translation, whose data is mostly in the L1 while its
/// code, the fast region, is in L2): the L1 inline, the fast region out of
/// line at `site.other` (`out_of_line`), which rejoins at `site.back`.
///
/// With an L1 the checked entry counts each access at the cheaper of the
/// two regions' extras ([`Ctx::worst_extra`]): a cluster core's L2
/// accesses cost 10 cycles more than its L1 ones, and counting every
/// access of an unrolled kernel at 10 left most of a 1024-cycle quantum
/// to the interpreter. So an access that cost more (an L2 one, or an L1
/// one that stalled on its bank) tests the deadline again for the rest of
/// the block (`recheck`).
///
/// `eax_is_rs1`: the previous template left the base register's value in
/// `eax` (`Block::eax`).
pub(super) fn mem_op(a: &mut Asm, i: &Inst, site: &L1Site, l1: bool, eax_is_rs1: bool) {
    let (_, _, _, m, opnd) = shape(i);
    let rs1 = reg(i.rs1);
    let imm = i.imm as i32;
    // eax = address.
    if !eax_is_rs1 {
        dynasm!(a ; .arch x64 ; mov eax, [r12 + rs1]);
    }
    match m {
        Mode::Offset if imm != 0 => dynasm!(a ; .arch x64 ; add eax, imm),
        Mode::RegReg => dynasm!(a ; .arch x64 ; add eax, [r12 + opnd]),
        _ => {}
    }
    if !l1 {
        fast_access(a, i, site, Split::OutOfLine(site));
        return;
    }
    in_region(
        a,
        i,
        site,
        (L1_BASE, L1_SIZE, L1_LAST, L1_CODE_LO, L1_CODE_HI),
    );
    grant(a, site);
    dynasm!(a ; .arch x64 ; mov r8, [rbx + L1_PTR]);
    access(a, i, 8, Split::OutOfLine(site));
}

/// The fast region's access (`eax` = address; `rcx` = its offset there):
/// outside it, on to `site.other`; a store near code or `tohost` leaves at
/// `site.exit`. `split`: out of line in the FC's translations
/// (`plain_out_of_line`), inline in the L1 path's out-of-line code.
fn fast_access(a: &mut Asm, i: &Inst, site: &L1Site, split: Split) {
    in_region(
        a,
        i,
        site,
        (FAST_BASE, FAST_SIZE, FAST_LAST, CODE_LO, CODE_HI),
    );
    access(a, i, 14, split);
    dynasm!(a ; .arch x64 ; add r13, rbp);
}

/// Whether the access at `eax` is inside the region whose base, size,
/// last offsets ([`Bounds`]) and cached-code bounds are the [`Ctx`] fields
/// at `fields`: `rcx` = its offset there (and for a store `rdx` = its
/// end); outside, on to `site.other`; a store near the region's code or on
/// `tohost` leaves at `site.exit`.
fn in_region(a: &mut Asm, i: &Inst, site: &L1Site, fields: (i32, i32, i32, i32, i32)) {
    let (_, n, store, _, _) = shape(i);
    let (base, size, last, code_lo, code_hi) = fields;
    dynasm!(a ; .arch x64 ; mov ecx, eax ; sub rcx, [rbx + base]);
    if store {
        dynasm!(a ; .arch x64
            ; lea rdx, [rcx + n]
            ; cmp rdx, [rbx + size]
            ; ja =>site.other
        );
        watched(a, code_lo, code_hi, site.exit);
    } else {
        let last = last + 8 * Bounds::index(n);
        dynasm!(a ; .arch x64 ; cmp rcx, [rbx + last] ; ja =>site.other);
    }
}

/// After an access that may have cost more than [`Ctx::worst_extra`]: go
/// on only if the rest of the block still fits before the deadline, else
/// go on at `site.after` (the careful variant, or an exit just after the
/// access: a pause at an instruction boundary, which changes nothing).
fn recheck(a: &mut Asm, site: &L1Site) {
    let (w, nmem) = site.rest;
    dynasm!(a ; .arch x64 ; lea rcx, [r13 + w as i32]);
    fits(a, nmem, site.after);
}

/// The out-of-line parts of an L1-path access (after the block): the
/// grant's stall (`busy`), which with `site.recheck` goes on at
/// `site.ool`: the access there, then the deadline test (the stall may
/// have cost more than the checked entry counted); a misaligned word's
/// split cycle; at `site.other` the fast region's access (else leave just
/// before it); all rejoin at `site.back`.
pub(super) fn out_of_line(a: &mut Asm, i: &Inst, site: &L1Site) {
    busy(a, site);
    if site.recheck {
        dynasm!(a ; .arch x64
            ; =>site.ool
            ; mov r8, [rbx + L1_PTR]
        );
        access(a, i, 8, Split::Inline);
        recheck(a, site);
        dynasm!(a ; .arch x64 ; jmp =>site.back);
    }
    if shape(i).1 == 4 {
        dynasm!(a ; .arch x64 ; =>site.split ; add r13, 1 ; jmp =>site.split_back);
    }
    dynasm!(a ; .arch x64 ; =>site.other);
    let fast = L1Site {
        other: site.exit,
        ..*site
    };
    fast_access(a, i, &fast, Split::Inline);
    // Not an L1 access: no grant (the block's exits count one per load or
    // store, `emit::Block::retired`).
    dynasm!(a ; .arch x64 ; sub r15, GRANT_ONE);
    if site.recheck {
        // Only a core whose fast-region accesses cost extra (a cluster
        // core's L2) can exceed the count: the FC's cost nothing more.
        dynasm!(a ; .arch x64 ; test rbp, rbp ; jz =>site.back);
        recheck(a, site);
    }
    dynasm!(a ; .arch x64 ; jmp =>site.back);
}

/// A load outside the fast region in a translation without the L1 path
/// (the FC's), out of line at `site.other`: from the device registers that
/// read like memory (`Mmio::plain_window`: the camera's image, which the
/// race firmware copies a word at a time) as `exec::Run::window_load`
/// reads them: [`Ctx::win_latency`] cycles, no split cycle; elsewhere
/// leave just before it. The checked entry counts every access at no less
/// than the window's latency (`Cpu::run_translated`), so the block still
/// fits. Rejoins at `site.back`.
///
/// Also, for a word access, its split cycle (misaligned words are rare).
pub(super) fn plain_out_of_line(a: &mut Asm, i: &Inst, site: &L1Site) {
    let (_, n, store, _, _) = shape(i);
    if n == 4 {
        dynasm!(a ; .arch x64 ; =>site.split ; add r13, 1 ; jmp =>site.split_back);
    }
    if store {
        return;
    }
    let last = WIN_LAST + 8 * Bounds::index(n);
    dynasm!(a ; .arch x64
        ; =>site.other
        ; mov ecx, eax
        ; sub rcx, [rbx + WIN_BASE]
        ; cmp rcx, [rbx + last]
        ; ja =>site.exit
        ; mov r8, [rbx + WIN_PTR]
    );
    access(a, i, 8, Split::No);
    dynasm!(a ; .arch x64 ; add r13, [rbx + WIN_LATENCY] ; jmp =>site.back);
}

/// The L1's extra cycles of an access at `eax` issued at `r13 + issue`
/// (keeps `rax`, `rcx`): inline, what `Tcdm::access` does: the cycle's
/// mask of granted banks (`Tcdm::raw_parts`, one `u16` per cycle of the
/// window) gets the access's bank; when the bank is taken in that cycle,
/// the next free cycle is found out of line (`busy`). The port's count is
/// the block's (its exits count one grant per load or store,
/// `emit::Block::retired`). Only cores with a port on the arbiter run these
/// translations, and they have no L1 latency beyond the cycle the load or
/// store costs anyway, which the checked entry counts
/// (`Cpu::run_translated` makes sure of both): only a stall can make an
/// access cost more than counted, and with `site.recheck` the access then
/// goes on out of line (`site.ool`), where the deadline is tested again
/// after it.
fn grant(a: &mut Asm, site: &L1Site) {
    const SLOT_MASK: i32 = WINDOW as i32 - 1;
    dynasm!(a ; .arch x64
        ; mov r9, [rbx + L1_GRANTED]
        // edx = the cycle's slot (its low bits suffice), si = the word's
        // index, whose low four bits are the bank: a 16-bit `bts` takes
        // its bit offset modulo 16, and leaves the old bit in CF (taken:
        // `busy`).
        ; lea edx, [r13 + site.issue as i32]
        ; and edx, SLOT_MASK
        ; mov esi, eax
        ; shr esi, 2
        ; movzx r11d, WORD [r9 + rdx * 2]
        ; bts r11w, si
        ; jc =>site.busy
        ; mov [r9 + rdx * 2], r11w
        ; =>site.join
    );
    const _: () = assert!(BANKS == 16, "the grant's 16-bit bts is the bank");
}

/// The grant's taken-cycle case, out of line: the next cycle whose mask
/// lacks the bank (`si`; `edx`, the cycle's slot; `r9`, the masks), as
/// `Tcdm::access` finds it: the grant set, the stall added to the cycles
/// and counted in [`Ctx::l1_stalls`]. On at
/// `site.ool` (the access and the deadline test) or, in the careful
/// variant, back at `site.join`. Conflicts are about 2 % of the network's
/// L1 accesses.
fn busy(a: &mut Asm, site: &L1Site) {
    const SLOT_MASK: i32 = WINDOW as i32 - 1;
    let next = a.new_dynamic_label();
    dynasm!(a ; .arch x64
        ; =>site.busy
        ; mov edi, edx
        ; =>next
        ; add edi, 1
        ; and edi, SLOT_MASK
        ; movzx r11d, WORD [r9 + rdi * 2]
        ; bts r11w, si
        ; jc =>next
        ; mov [r9 + rdi * 2], r11w
        // The stall: the slots between, modulo the window.
        ; sub edi, edx
        ; and edi, SLOT_MASK
        ; add r13, rdi
        ; add [rbx + L1_STALLS], rdi
    );
    // A stall: the rest of the block may no longer fit (`site.ool`).
    let to = if site.recheck { site.ool } else { site.join };
    dynasm!(a ; .arch x64 ; jmp =>to);
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

/// How an access charges a split cycle (one crossing a word boundary).
#[derive(Clone, Copy)]
enum Split<'a> {
    /// Not at all: a device window read (`exec::Run::window_load`).
    No,
    /// Computed inline.
    Inline,
    /// A word's out of line at the site's `split` (misaligned words are
    /// rare); other sizes inline.
    OutOfLine(&'a L1Site),
}

/// The access itself at host address `base + rcx` (`eax` = the guest
/// address), the base register's write-back, the loaded value and the
/// split cycle.
fn access(a: &mut Asm, i: &Inst, base: u8, split: Split) {
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
    // A split access (crosses a word boundary) costs one more cycle: for a
    // word, any misaligned one (out of line at `site.split` where there
    // is one); else ((addr & 3) + n + 3) >> 3 is 1 exactly when
    // (addr & 3) + n > 4.
    match (split, n) {
        (Split::No, _) | (_, 1) => {}
        (Split::OutOfLine(site), 4) => {
            dynasm!(a ; .arch x64 ; test al, 3 ; jnz =>site.split ; =>site.split_back)
        }
        _ => dynasm!(a ; .arch x64
            ; and eax, 3
            ; add eax, n + 3
            ; shr eax, 3
            ; add r13, rax
        ),
    }
}
