//! The block translator (DESIGN.md §14): decoded blocks (`block.rs`) to
//! x86-64 with dynasm-rs templates, run in front of the interpreter with
//! the interpreter's exact cycles.
//!
//! - `emit.rs`: the templates, one block at a time;
//! - `ctx.rs`: the record translated code and the core share, and the
//!   host registers it lives in;
//! - `helpers.rs`: the Rust functions it calls (division, XCV
//!   computations);
//! - `buffer.rs`: the executable memory.
//!
//! # Contract with the core (`cpu/jit_run.rs`)
//!
//! The core enters translated code only at a block whose worst case
//! (every instruction's cost, the longest divisions, a split cycle and the
//! access extra per load or store, one taken branch) ends before the
//! deadline; a block jumps on into the next one under the same condition
//! (directly when the target was translated before, else through the
//! dispatcher stub, which looks it up in the region's table). So the
//! interpreter's per-instruction deadline check could never have fired
//! inside a translated block, and every run stops on the instruction
//! boundary the interpreter would stop on. On a memory with a cluster the
//! access extra counted is the cheaper region's, and the code checks again
//! after every access (an L1 bank's stall has no bound), leaving just
//! after it when the rest might not fit (`emit::mem_op`). Everything else (a block that
//! does not fit, polling loops the idle detector watches, what the
//! templates do not cover) runs on the interpreter.
//!
//! The cache lives in the [`CodeCache`](super::CodeCache) beside the
//! blocks it was translated from, so the cluster's cores share it, and it
//! is dropped with them: any write into decoded code (stores leave
//! translated code before they could do one) and a full block cache flush
//! both empty it.

mod buffer;
pub(crate) mod ctx;
mod emit;
mod helpers;

use dynasmrt::x64::X64Relocation;
use dynasmrt::{dynasm, DynasmApi, DynasmLabelApi, VecAssembler};

use super::code::Blocks;
use super::mem::Region;
use buffer::{CodeBuffer, CODE_BYTES};
use ctx::*;
use emit::{translate, Stubs};

/// Marks a block start the translator could not take (its first
/// instruction is not covered), so it is not tried again.
const UNCOVERED: Entry = Entry {
    code: 0,
    worst: u32::MAX,
    nmem: 0,
    careful: 0,
};

/// The translator's counters (`sim-core run-elf --stats`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct JitStats {
    /// Blocks translated (again after each flush).
    pub translated: u64,
    /// Bytes of x86-64 code in the buffer now.
    pub code_bytes: u64,
    /// Times the cache was emptied (code overwritten, block cache full).
    pub flushes: u64,
}

/// An [`Entry`] as the table stores it (the `#[repr(C)]` layout on a
/// little-endian host: code, then worst, nmem and careful in one word).
fn pack(e: Entry) -> [u64; 2] {
    [
        e.code,
        e.worst as u64 | (e.nmem as u64) << 32 | (e.careful as u64) << 48,
    ]
}

fn unpack(w: [u64; 2]) -> Entry {
    Entry {
        code: w[0],
        worst: w[1] as u32,
        nmem: (w[1] >> 32) as u16,
        careful: (w[1] >> 48) as u16,
    }
}

/// The translated code of one [`CodeCache`](super::CodeCache).
pub(crate) struct JitCache {
    buf: CodeBuffer,
    stubs: Stubs,
    enter: usize,
    /// Bytes of the stubs at the buffer's start (kept on a flush).
    stub_bytes: usize,
    /// Per flavour ([`Flavour`]), per RAM region, one [`Entry`] per
    /// halfword (empty until used), stored as its two little-endian words
    /// so the allocation is a zeroed one (`calloc`: the OS backs only the
    /// pages that get code).
    tables: [Vec<Vec<[u64; 2]>>; 2],
    /// Per flavour, jumps waiting for a target to be translated: target
    /// pc → host addresses of their rel32 fields.
    pending: [std::collections::HashMap<u32, Vec<usize>>; 2],
    /// `COSIM_PERF_MAP` set: every translation is listed in
    /// `/tmp/perf-PID.map` (the format `perf report` reads for JIT code),
    /// named by its guest pc, so a profile shows which guest code the
    /// translated samples ran.
    perf_map: Option<std::io::LineWriter<std::fs::File>>,
    dump_code: bool,
    /// Blocks translated and cache flushes so far (statistics).
    pub translated: u64,
    pub flushes: u64,
}

impl std::fmt::Debug for JitCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JitCache")
            .field("buf", &self.buf)
            .field("translated", &self.translated)
            .finish_non_exhaustive()
    }
}

/// Which of a block's two translations: with an L1 path (a cluster core's,
/// its loads and stores granted by the bank arbiter inline) or without
/// (the FC's, whose L1 accesses are another region's). Code the FC and
/// the cores share (`memset`, `memcpy`) gets both: with one table, the
/// flavour translated first served the other badly (a core's `memset`
/// into L1 left the FC's translation at its first store, was demoted and
/// ran interpreted from then on).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Flavour {
    Plain = 0,
    L1 = 1,
}

impl Flavour {
    pub fn of(l1: bool) -> Flavour {
        if l1 {
            Flavour::L1
        } else {
            Flavour::Plain
        }
    }
}

/// The entry stub's signature: `(ctx, code, cycles)`.
type EnterFn = unsafe extern "sysv64" fn(*mut Ctx, u64, u64);

impl JitCache {
    pub fn new() -> std::io::Result<JitCache> {
        let mut buf = CodeBuffer::new(CODE_BYTES)?;
        let at = buf.next_addr();
        let mut a = VecAssembler::<X64Relocation>::new(at);
        let (enter, exit, dispatch, leave) = (
            a.new_dynamic_label(),
            a.new_dynamic_label(),
            a.new_dynamic_label(),
            a.new_dynamic_label(),
        );
        dynasm!(a
            ; .arch x64
            // enter(ctx = rdi, code = rsi, cycles = rdx): save the
            // callee-saved registers (6 pushes + 8 keep rsp 16-aligned at
            // helper calls), load the pinned ones, jump into the block.
            ; =>enter
            ; push rbx ; push rbp ; push r12 ; push r13 ; push r14 ; push r15
            ; sub rsp, 8
            ; mov rbx, rdi
            ; mov r12, [rbx + REGS]
            ; mov r14, [rbx + FAST_PTR]
            ; mov rbp, [rbx + EXTRA]
            ; mov r13, rdx
            ; xor r15d, r15d
            ; jmp rsi
            // exit: hand the cycles and retired count back.
            ; =>exit
            ; mov [rbx + CYCLES], r13
            ; mov [rbx + RETIRED], r15
            ; add rsp, 8
            ; pop r15 ; pop r14 ; pop r13 ; pop r12 ; pop rbp ; pop rbx
            ; ret
            // dispatch(eax = target pc): its block in the code region's
            // table (whose checked entry tests the deadline) if translated,
            // else leave there.
            ; =>dispatch
            ; mov ecx, eax
            ; sub rcx, [rbx + CODE_BASE]
            ; cmp rcx, [rbx + CODE_SIZE]
            ; jae =>leave
            ; shr rcx, 1
            ; shl rcx, ENTRY_SHIFT
            ; add rcx, [rbx + TABLE]
            ; mov rsi, [rcx + ENTRY_CODE]
            ; test rsi, rsi
            ; jz =>leave
            ; jmp rsi
            // leave(eax = pc) after a transfer: nothing in the load shadow.
            ; =>leave
            ; mov [rbx + EXIT_PC], rax
            ; mov QWORD [rbx + LOAD_MASK], 0
            ; jmp =>exit
        );
        let labels = a.labels().clone();
        let addr = |l| at + labels.resolve_dynamic(l).expect("stub label defined").0;
        let (enter, exit, dispatch, leave) = (addr(enter), addr(exit), addr(dispatch), addr(leave));
        let code = a.finalize().expect("stubs assemble");
        buf.push(&code);
        Ok(JitCache {
            stub_bytes: buf.used(),
            buf,
            stubs: Stubs {
                exit,
                dispatch,
                leave,
            },
            enter,
            tables: Default::default(),
            pending: Default::default(),
            translated: 0,
            flushes: 0,
            dump_code: std::env::var_os("COSIM_PERF_MAP").is_some_and(|v| v == "code"),
            perf_map: std::env::var_os("COSIM_PERF_MAP").and_then(|_| {
                let path = format!("/tmp/perf-{}.map", std::process::id());
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(&path)
                    .map_err(|e| tracing::warn!("cannot open {path}: {e}"))
                    .ok()
                    .map(std::io::LineWriter::new)
            }),
        })
    }

    /// What the cache holds and has done.
    pub fn stats(&self) -> JitStats {
        JitStats {
            translated: self.translated,
            code_bytes: (self.buf.used() - self.stub_bytes) as u64,
            flushes: self.flushes,
        }
    }

    /// Drop every translation (the block cache was flushed).
    pub fn flush(&mut self) {
        for t in &mut self.tables {
            t.clear();
        }
        for p in &mut self.pending {
            p.clear();
        }
        self.buf.truncate(self.stub_bytes);
        self.flushes += 1;
    }

    /// The region table's base (for [`Ctx::table`]); null if unused yet.
    pub fn table(&self, region: usize, flavour: Flavour) -> *const Entry {
        self.tables[flavour as usize]
            .get(region)
            .filter(|t| !t.is_empty())
            .map_or(std::ptr::null(), |t| t.as_ptr() as *const Entry)
    }

    /// The translation of the block starting at byte `off` of region
    /// `region`, whose first instruction is `blocks.insts[first]`, translating it
    /// if needed (`l1`: with a path for L1 accesses, see `emit::translate`);
    /// `None` if the translator does not cover its first
    /// instruction.
    pub fn entry(
        &mut self,
        regions: &[Region],
        blocks: Blocks,
        region: usize,
        off: usize,
        first: usize,
        flavour: Flavour,
    ) -> Option<Entry> {
        let f = flavour as usize;
        if self.tables[f].len() <= region {
            self.tables[f].resize_with(regions.len().max(region + 1), Vec::new);
        }
        if self.tables[f][region].is_empty() {
            self.tables[f][region] = vec![[0u64; 2]; regions[region].size as usize / 2];
        }
        let e = unpack(self.tables[f][region][off >> 1]);
        if e.code != 0 {
            return Some(e);
        }
        if e.worst == UNCOVERED.worst {
            return None;
        }
        let Blocks { insts, starts } = blocks;
        let len = super::block::block_len(&insts[first..]);
        let b = &insts[first..first + len];
        // Room for the worst block (~100 host bytes per instruction, twice
        // with the careful variant).
        if !self.buf.fits(128 * 1024) {
            self.flush();
            return self.entry(regions, blocks, region, off, first, flavour);
        }
        let tables = &self.tables[f];
        let known = |pc: u32| {
            let r = regions.iter().position(|r| r.offset_of(pc, 2).is_some())?;
            let o = pc.wrapping_sub(regions[r].base) as usize;
            let e = unpack(*tables.get(r)?.get(o >> 1)?);
            (e.code != 0).then_some(e)
        };
        let first_reads = |pc: u32| {
            let k = regions.iter().position(|r| r.offset_of(pc, 2).is_some())?;
            let at = &starts.get(k)?.at;
            let id = *at.get((pc.wrapping_sub(regions[k].base) >> 1) as usize)?;
            (id != 0).then(|| insts[id as usize - 1].reads())
        };
        let Some(t) = translate(
            b,
            self.buf.next_addr(),
            self.stubs,
            &known,
            &first_reads,
            flavour == Flavour::L1,
        ) else {
            self.tables[f][region][off >> 1] = pack(UNCOVERED);
            return None;
        };
        let code = self.buf.push(&t.code);
        if let Some(m) = self.perf_map.as_mut() {
            use std::io::Write;
            let pc = regions[region].base.wrapping_add(off as u32);
            // A profiling aid only: a failed write loses a name, nothing else.
            let _ = writeln!(m, "{code:x} {:x} rv_{pc:08x}", t.code.len());
            if self.dump_code {
                // `COSIM_PERF_MAP=code`: the code itself beside the map, for
                // `objdump -D -b binary -mi386:x86-64 --adjust-vma=ADDR`
                // (`perf report` cannot annotate JIT code from a map alone).
                let dir = format!("/tmp/perf-{}.code", std::process::id());
                let _ = std::fs::create_dir_all(&dir)
                    .and_then(|_| std::fs::write(format!("{dir}/{pc:08x}-{code:x}.bin"), &t.code));
            }
        }
        for (to, off) in t.patches {
            self.pending[f].entry(to).or_default().push(code + off);
        }
        // Jumps that waited for this block now go straight to it.
        let pc = regions[region].base.wrapping_add(off as u32);
        for site in self.pending[f].remove(&pc).unwrap_or_default() {
            self.buf.patch_rel32(site, code);
        }
        let code = code as u64;
        let e = Entry {
            code,
            worst: t.worst,
            nmem: t.nmem,
            careful: t.careful,
        };
        self.tables[f][region][off >> 1] = pack(e);
        self.translated += 1;
        Some(e)
    }

    /// Hand the block at byte `off` of region `region` to the interpreter
    /// from now on: its first instruction is an access the fast path does
    /// not do (a device, another RAM region, cached code), which would
    /// otherwise leave translated code at once every time. Jumps already
    /// patched to it still enter it, and leave at once as before.
    pub fn demote(&mut self, region: usize, off: usize, flavour: Flavour) {
        if let Some(e) = self.tables[flavour as usize]
            .get_mut(region)
            .and_then(|t| t.get_mut(off >> 1))
        {
            *e = pack(UNCOVERED);
        }
    }

    /// Run translated code from `code` (an [`Entry::code`]) at `cycles`.
    ///
    /// # Safety
    /// `ctx` must describe live memory: its register file, fast region and
    /// table must stay valid and unaliased for the call, and `code` must
    /// come from this cache since its last flush.
    pub unsafe fn run(&self, ctx: &mut Ctx, code: u64, cycles: u64) {
        // SAFETY: `enter` is the entry stub assembled in `new` with this
        // signature; the caller guarantees the rest.
        unsafe {
            let f: EnterFn = std::mem::transmute(self.enter);
            f(ctx, code, cycles);
        }
    }
}
