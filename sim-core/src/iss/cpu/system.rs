//! The system instructions: ecall, ebreak (and semihosting), mret, wfi,
//! the CSR instructions and the illegal-instruction trap.

use super::csr::{CSR_CYCLE, CSR_INSTRETH};
use super::*;

impl Cpu {
    /// A self-loop ([`Inst::is_self_loop`]) with operands `a`, `b`: the
    /// next pc, or `None` when taking it would spin forever (the run then
    /// ends with [`IssError::NeverProgress`], the loop not retired).
    /// Otherwise it runs as the block executor would run it, so a loop an
    /// interrupt will end costs the same cycles either way.
    #[cold]
    pub(super) fn step_self_loop(&mut self, inst: Inst, a: u32, b: u32) -> Option<u32> {
        let imm5 = (((inst.rd as i32) << 27) >> 27) as u32;
        let taken = match inst.op {
            op::BEQ => a == b,
            op::BNE => a != b,
            op::BLT => (a as i32) < (b as i32),
            op::BGE => (a as i32) >= (b as i32),
            op::BLTU => a < b,
            op::BGEU => a >= b,
            op::CV_BEQIMM => a == imm5,
            op::CV_BNEIMM => a != imm5,
            _ => true, // jal
        };
        if !taken {
            return Some(inst.pc.wrapping_add(inst.len as u32));
        }
        if !self.interruptible() {
            self.stop(StopReason::Fatal(IssError::NeverProgress {
                hart: self.cfg.hart_id,
                pc: inst.pc,
                why: if self.privilege == Privilege::Machine && self.mstatus & MSTATUS_MIE == 0 {
                    Stuck::SpinsInterruptsOff
                } else {
                    Stuck::SpinsNoInterrupt
                },
            }));
            return None;
        }
        if inst.op == op::JAL {
            self.regs[(inst.rd & 31) as usize] = inst.pc.wrapping_add(inst.len as u32);
            self.regs[0] = 0;
        } else {
            self.cycles += timing::BRANCH_TAKEN_EXTRA;
        }
        self.jumps += 1;
        Some(inst.pc)
    }

    /// Whether an interrupt could ever be taken by a core that changes no
    /// CSR: only the core itself writes its `mstatus`, `mie` and `msip`;
    /// the timer fires unless `mtimecmp` is out of reach; the external
    /// line belongs to the platform (devices, the cluster), so an enabled
    /// one counts.
    fn interruptible(&self) -> bool {
        if self.privilege == Privilege::Machine && self.mstatus & MSTATUS_MIE == 0 {
            return false;
        }
        self.mie & (1 << IRQ_MEI) != 0
            || (self.mie & (1 << IRQ_MTI) != 0 && self.mtimecmp != u64::MAX)
            || self.mie & self.mip() != 0
    }

    pub(super) fn illegal(&mut self, mem: &mut Memory, raw: u32, pc: u32) -> Sys {
        self.trap(mem, cause::ILLEGAL_INSTRUCTION, raw, pc);
        Sys::Trapped
    }

    #[cold]
    pub(super) fn step_system(
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
                if self.mie == 0 {
                    // Only the core itself can enable an interrupt.
                    self.stop(StopReason::Fatal(IssError::NeverProgress {
                        hart: self.cfg.hart_id,
                        pc,
                        why: Stuck::Asleep,
                    }));
                    return Sys::Trapped;
                }
                if self.mip() & self.mie == 0 {
                    self.sleeping = true;
                    self.break_block();
                    if self.stop_on_sleep {
                        self.stop(StopReason::Wait);
                    }
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
    pub(super) fn raw_at(&self, mem: &Memory, pc: u32, d: Decoded) -> u32 {
        let mut b = [0u8; 4];
        let n = d.len() as usize;
        if mem.read_bytes(pc, &mut b[..n]).is_err() {
            return 0;
        }
        u32::from_le_bytes(b)
    }

    #[cold]
    pub(super) fn semihosting(&mut self, mem: &mut Memory) -> Sys {
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
}
