//! The block executor's handlers of the CORE-V XCV instructions
//! (`iss/xcv/`): the same threaded handlers as the RV32I ones, so hot loops
//! of post-increment loads and dot products never leave the block
//! executor. Loads and stores use the RV32I macros with their addressing
//! mode (RAM through the fast pointer, the rest on the general path);
//! computations call the semantic functions of `iss/xcv/`.

use super::super::decode::op;
use super::super::xcv::{alu, mac, simd};
use super::*;

loads! {
    h_cv_lb_pi, h_cv_lb_pi_other: AccessSize::Byte, sext8, Mode::PostImm, rs2;
    h_cv_lh_pi, h_cv_lh_pi_other: AccessSize::Half, sext16, Mode::PostImm, rs2;
    h_cv_lw_pi, h_cv_lw_pi_other: AccessSize::Word, same, Mode::PostImm, rs2;
    h_cv_lbu_pi, h_cv_lbu_pi_other: AccessSize::Byte, same, Mode::PostImm, rs2;
    h_cv_lhu_pi, h_cv_lhu_pi_other: AccessSize::Half, same, Mode::PostImm, rs2;
    h_cv_lb_pr, h_cv_lb_pr_other: AccessSize::Byte, sext8, Mode::PostReg, rs2;
    h_cv_lh_pr, h_cv_lh_pr_other: AccessSize::Half, sext16, Mode::PostReg, rs2;
    h_cv_lw_pr, h_cv_lw_pr_other: AccessSize::Word, same, Mode::PostReg, rs2;
    h_cv_lbu_pr, h_cv_lbu_pr_other: AccessSize::Byte, same, Mode::PostReg, rs2;
    h_cv_lhu_pr, h_cv_lhu_pr_other: AccessSize::Half, same, Mode::PostReg, rs2;
    h_cv_lb_rr, h_cv_lb_rr_other: AccessSize::Byte, sext8, Mode::RegReg, rs2;
    h_cv_lh_rr, h_cv_lh_rr_other: AccessSize::Half, sext16, Mode::RegReg, rs2;
    h_cv_lw_rr, h_cv_lw_rr_other: AccessSize::Word, same, Mode::RegReg, rs2;
    h_cv_lbu_rr, h_cv_lbu_rr_other: AccessSize::Byte, same, Mode::RegReg, rs2;
    h_cv_lhu_rr, h_cv_lhu_rr_other: AccessSize::Half, same, Mode::RegReg, rs2;
}
stores! {
    h_cv_sb_pi, h_cv_sb_pi_other: AccessSize::Byte, Mode::PostImm;
    h_cv_sh_pi, h_cv_sh_pi_other: AccessSize::Half, Mode::PostImm;
    h_cv_sw_pi, h_cv_sw_pi_other: AccessSize::Word, Mode::PostImm;
    h_cv_sb_pr, h_cv_sb_pr_other: AccessSize::Byte, Mode::PostReg;
    h_cv_sh_pr, h_cv_sh_pr_other: AccessSize::Half, Mode::PostReg;
    h_cv_sw_pr, h_cv_sw_pr_other: AccessSize::Word, Mode::PostReg;
    h_cv_sb_rr, h_cv_sb_rr_other: AccessSize::Byte, Mode::RegReg;
    h_cv_sh_rr, h_cv_sh_rr_other: AccessSize::Half, Mode::RegReg;
    h_cv_sw_rr, h_cv_sw_rr_other: AccessSize::Word, Mode::RegReg;
}

/// `rd = f(rs1, rs2, rd, imm)` handlers (rd = x0 never gets here: the
/// block cache turns those into `NOP`s).
macro_rules! compute {
    ($($name:ident: |$a:ident, $b:ident, $d:ident, $imm:ident| $e:expr;)*) => {$(
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let $a = reg!(regs, inst.rs1);
            let $b = reg!(regs, inst.rs2);
            let $d = reg!(regs, inst.rd);
            let $imm = inst.imm;
            reg!(regs, inst.rd) = $e;
        });
    )*};
}
compute! {
    h_cv_alu: |a, b, d, imm| alu::exec(imm, a, b, d);
    h_cv_mac: |a, b, d, imm| mac::mac(d, a, b);
    h_cv_msu: |a, b, d, imm| mac::msu(d, a, b);
    h_cv_muln: |a, b, d, imm| mac::mul_n(imm, a, b, 0);
    h_cv_macn: |a, b, d, imm| mac::mul_n(imm, a, b, d);
    h_cv_simd: |a, b, d, imm| simd::exec(imm, a, b, d);
    h_cv_sdotsp_b: |a, b, d, imm| simd::sdotsp_b(d, a, b);
    h_cv_sdotsp_h: |a, b, d, imm| simd::sdotsp_h(d, a, b);
    h_cv_sdotusp_b: |a, b, d, imm| simd::sdotusp_b(d, a, b);
    h_cv_sdotup_b: |a, b, d, imm| simd::sdotup_b(d, a, b);
    h_cv_dotsp_b: |a, b, d, imm| simd::sdotsp_b(0, a, b);
}

// `cv.beqimm` / `cv.bneimm rs1, Imm5, target` (manual, "Immediate
// Branching Operations"): the 5-bit immediate sits in `rd`, sign-extended
// here; timing as the RV32I branches (taken 3, not taken 1).
macro_rules! imm_branches {
    ($($name:ident: $taken_if_equal:expr;)*) => {$(
        handler!($name, |r, regs, inst, cycles, p, deadline| {
            let imm5 = (((inst.rd as i32) << 27) >> 27) as u32;
            if (reg!(regs, inst.rs1) == imm5) == $taken_if_equal {
                cycles += timing::BRANCH_TAKEN_EXTRA;
                return transfer(r, regs, p, inst.imm, cycles, deadline, true);
            }
        });
    )*};
}
imm_branches! {
    h_cv_beqimm: true;
    h_cv_bneimm: false;
}

/// Put the XCV handlers into the executor's table.
pub(super) const fn install(t: &mut [Handler; 256]) {
    let h: [(u8, Handler); 39] = [
        (op::CV_LB_PI, h_cv_lb_pi),
        (op::CV_LH_PI, h_cv_lh_pi),
        (op::CV_LW_PI, h_cv_lw_pi),
        (op::CV_LBU_PI, h_cv_lbu_pi),
        (op::CV_LHU_PI, h_cv_lhu_pi),
        (op::CV_LB_PR, h_cv_lb_pr),
        (op::CV_LH_PR, h_cv_lh_pr),
        (op::CV_LW_PR, h_cv_lw_pr),
        (op::CV_LBU_PR, h_cv_lbu_pr),
        (op::CV_LHU_PR, h_cv_lhu_pr),
        (op::CV_LB_RR, h_cv_lb_rr),
        (op::CV_LH_RR, h_cv_lh_rr),
        (op::CV_LW_RR, h_cv_lw_rr),
        (op::CV_LBU_RR, h_cv_lbu_rr),
        (op::CV_LHU_RR, h_cv_lhu_rr),
        (op::CV_SB_PI, h_cv_sb_pi),
        (op::CV_SH_PI, h_cv_sh_pi),
        (op::CV_SW_PI, h_cv_sw_pi),
        (op::CV_SB_PR, h_cv_sb_pr),
        (op::CV_SH_PR, h_cv_sh_pr),
        (op::CV_SW_PR, h_cv_sw_pr),
        (op::CV_SB_RR, h_cv_sb_rr),
        (op::CV_SH_RR, h_cv_sh_rr),
        (op::CV_SW_RR, h_cv_sw_rr),
        (op::CV_BEQIMM, h_cv_beqimm),
        (op::CV_BNEIMM, h_cv_bneimm),
        (op::CV_ALU, h_cv_alu),
        (op::CV_ALU_RD, h_cv_alu),
        (op::CV_MAC, h_cv_mac),
        (op::CV_MSU, h_cv_msu),
        (op::CV_MULN, h_cv_muln),
        (op::CV_MACN, h_cv_macn),
        (op::CV_SIMD, h_cv_simd),
        (op::CV_SIMD_RD, h_cv_simd),
        (op::CV_SDOTSP_B, h_cv_sdotsp_b),
        (op::CV_SDOTSP_H, h_cv_sdotsp_h),
        (op::CV_SDOTUSP_B, h_cv_sdotusp_b),
        (op::CV_SDOTUP_B, h_cv_sdotup_b),
        (op::CV_DOTSP_B, h_cv_dotsp_b),
    ];
    let mut k = 0;
    while k < h.len() {
        t[h[k].0 as usize] = h[k].1;
        k += 1;
    }
}
