//! The polling-loop detector and exact idle skipping (see the module
//! docs of `iss` and `Cpu::poll_slow`).

use super::*;

/// One MMIO read made by the current loop iteration.
#[derive(Debug, Clone, Copy, Default)]
struct PollRead {
    addr: u32,
    size: u8,
    issue: u64,
}

/// State of the polling-loop detector (see `Cpu::poll_slow`).
#[derive(Debug, Clone, Default)]
pub(super) struct PollTracker {
    /// Some device register was read since the last backward branch.
    pub(super) touched: bool,
    /// A loop is armed: its next iteration is being measured.
    pub(super) active: bool,
    branch: u32,
    target: u32,
    body_len: u64,
    snapshot: [u32; 32],
    start_cycles: u64,
    start_instret: u64,
    /// `Cpu::jumps` at the start of the iteration: a verified iteration
    /// took exactly one control transfer, its closing backward branch.
    start_jumps: u64,
    /// This core's L1 accesses at the start of the iteration (its port's
    /// count in the bank arbiter; 0 without one): iterations that granted
    /// L1 banks are counted as polling but never skipped, since a skipped
    /// grant would leave the arbiter's state, and so the other cores'
    /// stalls, different.
    start_l1: u64,
    reads: [PollRead; MAX_POLL_READS],
    n_reads: usize,
    /// A read this iteration that idle skipping cannot reason about
    /// (too many reads, or the machine timer).
    pub(super) unskippable: bool,
    /// The last loop the static check rejected, so hot compute loops are
    /// checked only once.
    rejected: (u32, u32),
}

impl Cpu {
    pub(super) fn record_poll_read(&mut self, addr: u32, size: AccessSize, issue: u64) {
        let p = &mut self.poll;
        p.touched = true;
        if p.n_reads < MAX_POLL_READS {
            p.reads[p.n_reads] = PollRead {
                addr,
                size: size as u8,
                issue,
            };
            p.n_reads += 1;
        } else {
            p.unskippable = true;
        }
    }

    /// Called after a taken backward branch from `branch` to `target` has
    /// retired (pc = target). Detects loops whose iterations are fixed
    /// points — bodies without stores, jumps, CSR or system instructions,
    /// run straight through (none of their conditional branches, typically
    /// the loop's exits, taken), that read device registers and end with
    /// the same register file they started with — counts their cycles as
    /// polling and, with idle skipping on, jumps over as many whole
    /// iterations as the devices guarantee to be identical.
    ///
    /// Why that is exact: an iteration is a function of the register file
    /// it starts with, the RAM it loads (no store in the body, and nothing
    /// else writes RAM before the next device event, which bounds the skip)
    /// and the device values it reads (promised unchanged, without side
    /// effects, by `stable_until`). Same inputs, same path: every body
    /// branch falls through again, the closing branch is taken again, with
    /// the same cycles (the load-use state at the loop head is always that
    /// of a taken branch).
    #[cold]
    pub(super) fn poll_slow(&mut self, mem: &Memory, dev: &mut dyn Mmio, branch: u32, target: u32) {
        let p = &self.poll;
        let verified = p.active
            && p.branch == branch
            && p.target == target
            && self.instret - p.start_instret == p.body_len
            && self.jumps - p.start_jumps == 1
            && p.n_reads > 0
            && !p.unskippable
            && p.snapshot == self.regs;
        if verified {
            let iter_cycles = self.cycles - p.start_cycles;
            let body_len = p.body_len;
            self.stats.poll_cycles += iter_cycles;
            self.stats.poll_instructions += body_len;
            let l1 = self.l1_accesses(mem);
            if self.cfg.idle_skip && l1 == self.poll.start_l1 {
                self.skip_iterations(dev, iter_cycles, body_len);
            }
            let p = &mut self.poll;
            p.start_cycles = self.cycles;
            p.start_instret = self.instret;
            p.start_jumps = self.jumps;
            p.start_l1 = l1;
        } else {
            let arm = self.poll.touched
                && self.poll.rejected != (branch, target)
                && !self.poll.unskippable;
            let body = if arm {
                straight_line_body(mem, target, branch)
            } else {
                None
            };
            let l1 = self.l1_accesses(mem);
            let p = &mut self.poll;
            match body {
                Some(len) => {
                    p.active = true;
                    p.branch = branch;
                    p.target = target;
                    p.body_len = len;
                    p.snapshot = self.regs;
                    p.start_cycles = self.cycles;
                    p.start_instret = self.instret;
                    p.start_jumps = self.jumps;
                    p.start_l1 = l1;
                }
                None => {
                    if arm {
                        p.rejected = (branch, target);
                    }
                    p.active = false;
                }
            }
        }
        let p = &mut self.poll;
        p.touched = false;
        p.n_reads = 0;
        p.unskippable = false;
    }

    /// This core's L1 accesses so far (its port's count in the bank
    /// arbiter; 0 for a core without one).
    fn l1_accesses(&self, mem: &Memory) -> u64 {
        match (self.mem_timing.l1_port, mem.l1_arbiter.as_ref()) {
            (Some(port), Some(a)) => a.port_stats(port).accesses,
            _ => 0,
        }
    }

    /// Skip whole iterations of a verified polling loop: as many as fit
    /// before the run's deadline and before any polled register may change.
    fn skip_iterations(&mut self, dev: &mut dyn Mmio, iter_cycles: u64, body_len: u64) {
        let c0 = self.cycles;
        let start = self.poll.start_cycles;
        let mut n = self.deadline.saturating_sub(c0) / iter_cycles;
        n = n.min((self.instr_deadline - self.instret) / body_len);
        let mut bounded = self.deadline != u64::MAX || self.instr_deadline != u64::MAX;
        for r in &self.poll.reads[..self.poll.n_reads] {
            let size = match r.size {
                1 => AccessSize::Byte,
                2 => AccessSize::Half,
                _ => AccessSize::Word,
            };
            let t = self.mmio_time(r.issue);
            let stable = dev.stable_until(r.addr, size, t);
            if stable <= t {
                return;
            }
            if stable == Picos::MAX {
                continue;
            }
            bounded = true;
            // Latest issue cycle whose access time is still before `stable`.
            let Some(c_max) = div_ceil(stable.0, self.period).checked_sub(1 + self.latency) else {
                return;
            };
            let first = c0 + (r.issue - start);
            if c_max < first {
                return;
            }
            n = n.min((c_max - first) / iter_cycles + 1);
        }
        if !bounded {
            // A step-by-step run would spin here forever.
            self.stop(StopReason::Idle);
            return;
        }
        if n == 0 {
            return;
        }
        self.cycles += n * iter_cycles;
        self.instret += n * body_len;
        self.stats.poll_cycles += n * iter_cycles;
        self.stats.poll_instructions += n * body_len;
        self.stats.skipped_instructions += n * body_len;
    }
}

/// If `[target, branch]` is a loop body that only computes, loads and
/// branches conditionally (no store, jump, CSR or system instruction) and
/// ends with the branch at `branch`, its length in instructions when run
/// straight through. Its other branches are typically exits (the race
/// firmware's `if (status == BATTERY_LOW) break;`); `Cpu::poll_slow` only
/// accepts an iteration that took none of them.
fn straight_line_body(mem: &Memory, target: u32, branch: u32) -> Option<u64> {
    let mut pc = target;
    let mut n = 0;
    loop {
        let lo = mem.load_ram(pc, AccessSize::Half)? as u16;
        let d = decode::decode(lo, || {
            mem.load_ram(pc.wrapping_add(2), AccessSize::Half)
                .map(|h| h as u16)
        })?;
        n += 1;
        // clang's XCV code polls with `cv.bneimm`/`cv.beqimm` and may read
        // or compute with the XCV forms (register-offset loads, ALU, SIMD);
        // post-increment loads change their base, so an iteration with one
        // never ends with its starting registers and is rejected later.
        let branch_op =
            (op::BEQ..=op::BGEU).contains(&d.op) || matches!(d.op, op::CV_BEQIMM | op::CV_BNEIMM);
        if pc == branch {
            return branch_op.then_some(n);
        }
        let pure = matches!(
            d.op,
            op::LUI | op::AUIPC | op::LB | op::LH | op::LW | op::LBU | op::LHU
        ) || (op::ADDI..=op::AND).contains(&d.op)
            || (op::MUL..=op::REMU).contains(&d.op)
            || branch_op
            || xcv::pure(d.op)
            || xcv::is_load(d.op);
        if !pure {
            return None;
        }
        pc = pc.wrapping_add(d.len());
        if pc > branch {
            return None;
        }
    }
}
