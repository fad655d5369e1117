//! The core's side of the block translator (`iss/jit`): enter translated
//! code when the block's worst case fits before the deadline, and take
//! back the state it leaves, exactly as the interpreter's `exec_block`
//! would have left it.

use super::*;
use crate::iss::code::Blocks;
use crate::iss::jit::ctx::{Bounds, Ctx, NO_TOHOST};
use crate::iss::jit::{Flavour, JitCache};

/// Cycles the interpreter runs, having started on a block the translator
/// does not take, before it hands back (a Rust round trip costs about a
/// hundred host cycles; 2048 guest cycles interpreted cost ~5 µs). Handing
/// back after every block made cluster cores, whose L1 accesses the
/// translator leaves to the interpreter, 2x slower (`cosim bench iss`).
pub(super) const RETURN_BUDGET: u64 = 2048;

/// What [`Cpu::run_translated`] did.
pub(super) enum Translated {
    /// Translated code ran; the core is on an instruction boundary.
    Ran,
    /// It ran and ended with a short backward branch from `from` to `to`
    /// that the idle detector wants to see (`Cpu::poll_slow`).
    Poll { from: u32, to: u32 },
    /// The block's first instruction is not translated: the interpreter
    /// does this block (and only this one).
    Uncovered,
    /// The block might reach the deadline (or the translator is not
    /// available): the interpreter runs on to it.
    TooLong,
}

impl Cpu {
    /// Run the block at `self.pc` (`code.insts[first]` its first
    /// instruction) and the translated blocks it chains to.
    ///
    /// `window`: the device registers that read like memory
    /// (`Mmio::plain_window`), which the FC's translations read as the
    /// interpreter does (`emit::mem::plain_out_of_line`).
    pub(super) fn run_translated(
        &mut self,
        mem: &mut Memory,
        code: &mut CodeCache,
        first: usize,
        window: Option<(u32, &[u8])>,
    ) -> Translated {
        // `lookup` has just put the pc's region in the code window.
        let off = self.pc.wrapping_sub(self.code_base);
        if off >= self.code_size {
            return Translated::TooLong;
        }
        let region = self.code_idx;
        if code.jit.is_none() {
            match JitCache::new() {
                Ok(j) => code.jit = Some(Box::new(j)),
                Err(e) => {
                    tracing::warn!("no executable memory for the translator ({e}); interpreting");
                    self.cfg.iss = Backend::Interp;
                    return Translated::TooLong;
                }
            }
        }
        let t = self.mem_timing;
        // A cluster core's translations have an L1 path and check the
        // deadline after every access (`emit::mem_op`); the FC's do not.
        // Each has its own translation of a block they share
        // (`jit::Flavour`), whose checked entry counts accesses its way.
        let has_l1 = mem.l1_arbiter.is_some() && t.l1.1 != 0;
        let CodeCache {
            jit, insts, starts, ..
        } = code;
        let jit = jit.as_mut().expect("made above");
        let l1 = t.l1_port.is_some() && mem.l1_arbiter.is_some();
        if l1 && t.l1_extra != 0 {
            // The inline grant charges an arbitrated access nothing beyond
            // the cycle it costs anyway (`emit::mem::grant`), as every
            // cluster core has it (`Cluster::new`); another timing runs
            // interpreted.
            return Translated::Uncovered;
        }
        // The FC and the cores each run their own flavour of a block they
        // share (`jit::Flavour`).
        let flavour = Flavour::of(l1);
        let Some(e) = jit.entry(
            &mem.regions,
            Blocks { insts, starts },
            region,
            off as usize,
            first,
            flavour,
        ) else {
            return Translated::Uncovered;
        };
        // The L1 (the cluster's TCDM): its data, bounds and cached code,
        // and the bank arbiter if this core has a port on it.
        let (l1_ptr, l1_size, l1_code) = match mem
            .regions
            .iter_mut()
            .find(|r| has_l1 && r.base == t.l1.0 && r.size == t.l1.1)
        {
            Some(r) => (r.data.as_mut_ptr(), r.size as u64, (r.code_lo, r.code_hi)),
            None => (std::ptr::null_mut(), 0, (0, 0)),
        };
        let (l1_granted, l1_port_stats) = match (t.l1_port, mem.l1_arbiter.as_mut()) {
            (Some(port), Some(a)) => {
                let w = a.grant_window(port);
                (w.masks, w.port)
            }
            _ => (std::ptr::null_mut(), std::ptr::null_mut()),
        };
        let r = &mut mem.regions[region];
        // The fast region is the code's, as in `exec::Run::set_code_region`
        // (L1 code under the bank arbiter has none).
        let banked = t.l1_port.is_some() && r.base == t.l1.0;
        let extra = t.extra(None, r.base, 0);
        // What the checked entries of translations with the L1 path count
        // per access: the cheaper region's (every access re-checks after
        // itself).
        let worst_extra = if mem.l1_arbiter.is_some() {
            extra.min(t.l1_extra)
        } else {
            extra
        };
        // A window load costs the device latency (no extra, no split
        // cycle): without the L1 path every access is counted at no less
        // (`emit::mem::plain_out_of_line`).
        let (win, win_latency) = match window {
            Some((base, bytes)) if !l1 => (
                (Bounds::new(base, bytes.len() as u64), bytes.as_ptr()),
                self.latency,
            ),
            _ => ((Bounds::new(0, 0), std::ptr::null()), 0),
        };
        let (per_access, worst_extra) = if l1 {
            (worst_extra, worst_extra)
        } else {
            (extra.max(win_latency), worst_extra.max(win_latency))
        };
        let stall = self.entry_stall(insts, first);
        let entry = self.cycles;
        let cycles = entry + stall * timing::LOAD_USE_STALL;
        // Where the worst case does not fit, the careful variant (a
        // cluster core's translation) runs to the deadline itself: the
        // interpreter's test for this first instruction, `entry <
        // deadline`, is `run_block`'s loop condition.
        let code = if cycles.saturating_add(e.worst_case(per_access)) < self.deadline {
            e.code
        } else if e.careful != 0 {
            debug_assert!(entry < self.deadline);
            e.code + e.careful as u64
        } else {
            return Translated::TooLong;
        };
        let fast = Bounds::new(r.base, if banked { 0 } else { r.size as u64 });
        let l1 = Bounds::new(t.l1.0, l1_size);
        let mut ctx = Ctx {
            regs: self.regs.as_mut_ptr(),
            fast_ptr: r.data.as_mut_ptr(),
            fast_base: fast.base,
            fast_size: fast.size,
            fast_last: fast.last,
            code_lo: r.code_lo as u64,
            code_hi: r.code_hi as u64,
            tohost: self.tohost.map_or(NO_TOHOST, |t| t as u64),
            deadline: self.deadline,
            extra,
            worst_extra,
            l1_ptr,
            l1_base: l1.base,
            l1_size: l1.size,
            l1_last: l1.last,
            l1_code_lo: l1_code.0 as u64,
            l1_code_hi: l1_code.1 as u64,
            win_ptr: win.1,
            win_base: win.0.base,
            win_last: win.0.last,
            win_latency,
            l1_granted,
            l1_port_stats,
            l1_stalls: 0,
            poll_armed: self.poll.touched as u64,
            poll_from: 0,
            jumps: 0,
            exit_pc: 0,
            load_mask: 0,
            code_base: r.base as u64,
            code_size: r.size as u64,
            table: jit.table(region, flavour),
            cycles: 0,
            retired: 0,
        };
        // SAFETY: the register file, the region's and the L1's buffers and
        // the arbiter outlive the call and nothing else touches them
        // meanwhile (`&mut self`, `&mut mem`); the table is the cache's own, not resized during a run;
        // `e.code` was just returned by this cache.
        unsafe { jit.run(&mut ctx, code, cycles) };
        let (retired, grants) = ctx.retired_grants();
        if !ctx.l1_port_stats.is_null() {
            // SAFETY: the port's counts (`Tcdm::raw_parts`), which `mem`
            // still holds, unaliased (`&mut mem`).
            let s = unsafe { &mut *ctx.l1_port_stats };
            s.accesses += grants;
            s.stall_cycles += ctx.l1_stalls;
        }
        self.cycles = ctx.cycles;
        self.pc = ctx.exit_pc as u32;
        self.instret += retired;
        self.translated += retired;
        self.jumps += ctx.jumps;
        if retired == 0 {
            // Left before the block's first instruction (an access the
            // fast path does not do): nothing happened, the interpreter
            // does this block.
            self.cycles = entry;
            jit.demote(region, off as usize, flavour);
            return Translated::Uncovered;
        }
        self.load_mask = ctx.load_mask as u32;
        if ctx.poll_from != 0 {
            return Translated::Poll {
                from: ctx.poll_from as u32,
                to: self.pc,
            };
        }
        Translated::Ran
    }
}
