//! Rust functions translated code calls for what is not worth a template:
//! division (x86's `idiv` faults where RISC-V defines a result) and the
//! XCV computations, which call the very functions the interpreter's
//! handlers call (`iss/xcv/`), so both back ends cannot disagree.
//!
//! All take `(rs1, rs2, rd, imm)` values in the System V argument
//! registers (`edi`, `esi`, `edx`, `ecx`) and return the result in the low
//! 32 bits of `rax` and extra cycles in the high 32.

use super::super::decode::op;
use super::super::xcv::{alu, mac, simd};

/// A helper's signature.
pub(crate) type Helper = extern "sysv64" fn(u32, u32, u32, u32) -> u64;

/// Division and remainder: RISC-V results for a zero divisor and overflow,
/// and 3 + leading zeros of the divisor's magnitude (timing.rs; the 3 is
/// in the static cost, the rest returned as extra cycles).
extern "sysv64" fn div(a: u32, b: u32, _: u32, _: u32) -> u64 {
    let (x, y) = (a as i32, b as i32);
    let v = if y == 0 {
        u32::MAX
    } else {
        x.wrapping_div(y) as u32
    };
    v as u64 | ((y.unsigned_abs().leading_zeros() as u64) << 32)
}
extern "sysv64" fn rem(a: u32, b: u32, _: u32, _: u32) -> u64 {
    let (x, y) = (a as i32, b as i32);
    let v = if y == 0 { a } else { x.wrapping_rem(y) as u32 };
    v as u64 | ((y.unsigned_abs().leading_zeros() as u64) << 32)
}
extern "sysv64" fn divu(a: u32, b: u32, _: u32, _: u32) -> u64 {
    let v = a.checked_div(b).unwrap_or(u32::MAX);
    v as u64 | ((b.leading_zeros() as u64) << 32)
}
extern "sysv64" fn remu(a: u32, b: u32, _: u32, _: u32) -> u64 {
    let v = a.checked_rem(b).unwrap_or(a);
    v as u64 | ((b.leading_zeros() as u64) << 32)
}

extern "sysv64" fn cv_alu(a: u32, b: u32, d: u32, imm: u32) -> u64 {
    alu::exec(imm, a, b, d) as u64
}
extern "sysv64" fn cv_mac(a: u32, b: u32, d: u32, _: u32) -> u64 {
    mac::mac(d, a, b) as u64
}
extern "sysv64" fn cv_msu(a: u32, b: u32, d: u32, _: u32) -> u64 {
    mac::msu(d, a, b) as u64
}
extern "sysv64" fn cv_muln(a: u32, b: u32, _: u32, imm: u32) -> u64 {
    mac::mul_n(imm, a, b, 0) as u64
}
extern "sysv64" fn cv_macn(a: u32, b: u32, d: u32, imm: u32) -> u64 {
    mac::mul_n(imm, a, b, d) as u64
}
extern "sysv64" fn cv_simd(a: u32, b: u32, d: u32, imm: u32) -> u64 {
    simd::exec(imm, a, b, d) as u64
}
extern "sysv64" fn cv_sdotsp_b(a: u32, b: u32, d: u32, _: u32) -> u64 {
    simd::sdotsp_b(d, a, b) as u64
}
extern "sysv64" fn cv_sdotsp_h(a: u32, b: u32, d: u32, _: u32) -> u64 {
    simd::sdotsp_h(d, a, b) as u64
}
extern "sysv64" fn cv_sdotusp_b(a: u32, b: u32, d: u32, _: u32) -> u64 {
    simd::sdotusp_b(d, a, b) as u64
}
extern "sysv64" fn cv_sdotup_b(a: u32, b: u32, d: u32, _: u32) -> u64 {
    simd::sdotup_b(d, a, b) as u64
}
extern "sysv64" fn cv_dotsp_b(a: u32, b: u32, _: u32, _: u32) -> u64 {
    simd::sdotsp_b(0, a, b) as u64
}

/// The helper of an op done by a call, if it is one.
pub(crate) fn helper(o: u8) -> Option<Helper> {
    Some(match o {
        op::DIV => div,
        op::REM => rem,
        op::DIVU => divu,
        op::REMU => remu,
        op::CV_ALU | op::CV_ALU_RD => cv_alu,
        op::CV_MAC => cv_mac,
        op::CV_MSU => cv_msu,
        op::CV_MULN => cv_muln,
        op::CV_MACN => cv_macn,
        op::CV_SIMD | op::CV_SIMD_RD => cv_simd,
        op::CV_SDOTSP_B => cv_sdotsp_b,
        op::CV_SDOTSP_H => cv_sdotsp_h,
        op::CV_SDOTUSP_B => cv_sdotusp_b,
        op::CV_SDOTUP_B => cv_sdotup_b,
        op::CV_DOTSP_B => cv_dotsp_b,
        _ => return None,
    })
}

/// Whether an op's helper may return extra cycles (the divisions): the
/// block's worst case then counts [`MAX_DIV_EXTRA`].
pub(crate) fn is_div(o: u8) -> bool {
    (op::DIV..=op::REMU).contains(&o)
}

/// Most extra cycles of one division (a zero divisor: 32 leading zeros).
pub(crate) const MAX_DIV_EXTRA: u32 = 32;
