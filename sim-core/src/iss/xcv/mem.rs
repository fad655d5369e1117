//! `xcvmem` (CV32E40P manual, "Post-Incrementing Load & Store Instructions
//! and Register-Register Load & Store Instructions"): loads and stores
//! whose address is rs1 and which then add an immediate or a register to
//! rs1 (post-increment), or whose address is rs1 + a register. Timing as
//! any load or store ("Load/Store: 1", pipeline.rst): the written-back
//! address comes out of the ALU in EX and is forwarded (no stall), the
//! loaded register follows the load-use rule.
//!
//! If a post-increment load names the same register as destination and
//! base, the loaded value wins (it is written back in WB, after the
//! address update in EX).

use super::super::decode::op;

/// How an XCV memory op forms its address.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Address rs1 + imm (the RV32I loads and stores).
    Offset,
    /// Address rs1, then rs1 += imm.
    PostImm,
    /// Address rs1, then rs1 += a register (rs2 for loads, rs3 for stores).
    PostReg,
    /// Address rs1 + a register, rs1 unchanged.
    RegReg,
}

/// The RV32I load or store with the same size and extension.
pub fn base_op(o: u8) -> Option<u8> {
    const LOADS: [u8; 5] = [op::LB, op::LH, op::LW, op::LBU, op::LHU];
    const STORES: [u8; 3] = [op::SB, op::SH, op::SW];
    match o {
        op::CV_LB_PI..=op::CV_LHU_RR => Some(LOADS[((o - op::CV_LB_PI) % 5) as usize]),
        op::CV_SB_PI..=op::CV_SW_RR => Some(STORES[((o - op::CV_SB_PI) % 3) as usize]),
        _ => None,
    }
}

/// The addressing mode of a load or store op (RV32I or XCV).
pub fn mode(o: u8) -> Mode {
    let k = match o {
        op::CV_LB_PI..=op::CV_LHU_RR => (o - op::CV_LB_PI) / 5,
        op::CV_SB_PI..=op::CV_SW_RR => (o - op::CV_SB_PI) / 3,
        _ => return Mode::Offset,
    };
    [Mode::PostImm, Mode::PostReg, Mode::RegReg][k as usize]
}

/// Address and new base (`None`: unchanged) of an access in `mode`, with
/// base `rs1`, the mode's register operand `reg` and the immediate `imm`.
#[inline(always)]
pub fn address(mode: Mode, rs1: u32, reg: u32, imm: u32) -> (u32, Option<u32>) {
    match mode {
        Mode::Offset => (rs1.wrapping_add(imm), None),
        Mode::PostImm => (rs1, Some(rs1.wrapping_add(imm))),
        Mode::PostReg => (rs1, Some(rs1.wrapping_add(reg))),
        Mode::RegReg => (rs1.wrapping_add(reg), None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_memory_op_has_a_base_and_a_mode() {
        assert_eq!(base_op(op::CV_LBU_RR), Some(op::LBU));
        assert_eq!(base_op(op::CV_LW_PR), Some(op::LW));
        assert_eq!(base_op(op::CV_SH_PI), Some(op::SH));
        assert_eq!(base_op(op::CV_SW_RR), Some(op::SW));
        assert_eq!(base_op(op::CV_ALU), None);
        assert_eq!(mode(op::CV_LHU_PI), Mode::PostImm);
        assert_eq!(mode(op::CV_LB_PR), Mode::PostReg);
        assert_eq!(mode(op::CV_SB_RR), Mode::RegReg);
        assert_eq!(mode(op::CV_SW_PR), Mode::PostReg);
        assert_eq!(mode(op::LW), Mode::Offset);
        assert_eq!(
            address(Mode::PostImm, 100, 0, -4i32 as u32),
            (100, Some(96))
        );
        assert_eq!(address(Mode::RegReg, 100, 8, 0), (108, None));
    }
}
