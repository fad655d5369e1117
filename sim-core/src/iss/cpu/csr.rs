//! The machine-mode CSRs: what reads and writes them does (the counters
//! on the gated clock, mstatus' WARL fields, the read-only ID registers).
//! The CSR instructions themselves are in `system.rs`; the debug trigger's
//! registers in `trigger.rs`.

use super::*;

pub(super) const CSR_MSTATUS: u16 = 0x300;
pub(super) const CSR_MISA: u16 = 0x301;
pub(super) const CSR_MIE: u16 = 0x304;
pub(super) const CSR_MTVEC: u16 = 0x305;
pub(super) const CSR_MCOUNTEREN: u16 = 0x306;
pub(super) const CSR_MSTATUSH: u16 = 0x310;
pub(super) const CSR_MSCRATCH: u16 = 0x340;
pub(super) const CSR_MEPC: u16 = 0x341;
pub(super) const CSR_MCAUSE: u16 = 0x342;
pub(super) const CSR_MTVAL: u16 = 0x343;
pub(super) const CSR_MIP: u16 = 0x344;
pub(super) const CSR_MCYCLE: u16 = 0xb00;
pub(super) const CSR_MINSTRET: u16 = 0xb02;
pub(super) const CSR_MCYCLEH: u16 = 0xb80;
pub(super) const CSR_MINSTRETH: u16 = 0xb82;
pub(super) const CSR_CYCLE: u16 = 0xc00;
pub(super) const CSR_TIME: u16 = 0xc01;
pub(super) const CSR_INSTRET: u16 = 0xc02;
pub(super) const CSR_CYCLEH: u16 = 0xc80;
pub(super) const CSR_TIMEH: u16 = 0xc81;
pub(super) const CSR_INSTRETH: u16 = 0xc82;
pub(super) const CSR_MVENDORID: u16 = 0xf11;
pub(super) const CSR_MARCHID: u16 = 0xf12;
pub(super) const CSR_MIMPID: u16 = 0xf13;
pub(super) const CSR_MHARTID: u16 = 0xf14;

impl Cpu {
    /// mcycle counts only cycles the core is awake: CV32E40P's counters run
    /// on the gated clock, which `wfi` stops (manual, "Performance
    /// Counters").
    pub(super) fn mcycle(&self) -> u64 {
        (self.cycles - self.stats.sleep_cycles).wrapping_add(self.mcycle_off)
    }

    pub(super) fn minstret(&self) -> u64 {
        self.instret.wrapping_add(self.minstret_off)
    }

    pub(super) fn csr_read(&self, csr: u16) -> Option<u32> {
        Some(match csr {
            CSR_MSTATUS => self.mstatus,
            CSR_MISA => MISA,
            CSR_MIE => self.mie,
            CSR_MTVEC => self.mtvec,
            CSR_MCOUNTEREN => self.mcounteren,
            CSR_MSTATUSH => 0,
            CSR_MSCRATCH => self.mscratch,
            CSR_MEPC => self.mepc,
            CSR_MCAUSE => self.mcause,
            CSR_MTVAL => self.mtval,
            CSR_MIP => self.mip(),
            CSR_MCYCLE | CSR_CYCLE => self.mcycle() as u32,
            CSR_MCYCLEH | CSR_CYCLEH => (self.mcycle() >> 32) as u32,
            CSR_MINSTRET | CSR_INSTRET => self.minstret() as u32,
            CSR_MINSTRETH | CSR_INSTRETH => (self.minstret() >> 32) as u32,
            CSR_TIME => self.mtime() as u32,
            CSR_TIMEH => (self.mtime() >> 32) as u32,
            CSR_MVENDORID | CSR_MARCHID | CSR_MIMPID => 0,
            CSR_MHARTID => self.cfg.hart_id,
            _ => return trigger::read(csr),
        })
    }

    pub(super) fn csr_write(&mut self, csr: u16, v: u32) {
        // Writes that may enable an interrupt end the block so the run loop
        // re-evaluates pending interrupts and the timer deadline.
        self.break_block();
        match csr {
            CSR_MSTATUS => {
                let mut new = (self.mstatus & !MSTATUS_WRITABLE) | (v & MSTATUS_WRITABLE);
                // MPP is WARL with legal values U (0) and M (3); keep the
                // old value on anything else.
                let mpp = (new & MSTATUS_MPP) >> 11;
                if mpp != 0 && mpp != 3 {
                    new = (new & !MSTATUS_MPP) | (self.mstatus & MSTATUS_MPP);
                }
                self.mstatus = new;
            }
            CSR_MIE => self.mie = v & MIE_WRITABLE,
            // Modes 0 (direct) and 1 (vectored); reserved modes read as 0.
            CSR_MTVEC => self.mtvec = if v & 3 >= 2 { v & !3 } else { v },
            CSR_MCOUNTEREN => self.mcounteren = v & 7,
            CSR_MSCRATCH => self.mscratch = v,
            CSR_MEPC => self.mepc = v & !1,
            CSR_MCAUSE => self.mcause = v,
            CSR_MTVAL => self.mtval = v,
            CSR_MCYCLE => {
                let new = (self.mcycle() & !0xffff_ffff) | v as u64;
                self.mcycle_off = new.wrapping_sub(self.cycles - self.stats.sleep_cycles);
            }
            CSR_MCYCLEH => {
                let new = (self.mcycle() & 0xffff_ffff) | (v as u64) << 32;
                self.mcycle_off = new.wrapping_sub(self.cycles - self.stats.sleep_cycles);
            }
            // minstret is written by an instruction that itself retires
            // afterwards; the value written is what the next instruction
            // reads, so compensate for that increment.
            CSR_MINSTRET => {
                let new = (self.minstret() & !0xffff_ffff) | v as u64;
                self.minstret_off = new.wrapping_sub(self.instret + 1);
            }
            CSR_MINSTRETH => {
                let new = (self.minstret() & 0xffff_ffff) | (v as u64) << 32;
                self.minstret_off = new.wrapping_sub(self.instret + 1);
            }
            // misa, mstatush, mip, the ID registers and the trigger CSRs
            // (trigger.rs) ignore writes.
            _ => {}
        }
    }
}
