//! The CORE-V CV32E40P v2 instruction-set extensions (the GAP8's Xpulp in
//! the CORE-V encodings) that Debian's clang-19 knows: `xcvalu`, `xcvmac`,
//! `xcvmem`, `xcvsimd`, `xcvbi`, `xcvbitmanip` (DESIGN.md §12). Encodings
//! from LLVM's `RISCVInstrInfoXCV.td`, semantics from the CV32E40P user
//! manual (openhwgroup/cv32e40p `docs/source/instruction_set_extensions.rst`,
//! section per group in each file), timing from its table "Cycle counts per
//! instruction type" (`docs/source/pipeline.rst`): every XCV instruction is
//! an "Integer Computational" (1 cycle, results forwarded, no penalty), a
//! "Multiplication" on the single-cycle multiplier (1 cycle: MACs, 16-bit
//! multiplies, dot products) or a "Load/Store" (1 cycle, +1 for a
//! misaligned transfer, +1 load-use stall when the next instruction reads
//! the loaded register; the post-incremented address register comes from
//! the ALU in EX and is forwarded like any result, so it never stalls).
//!
//! - [`decode`]: the 32-bit encodings under the custom opcodes 0x0b, 0x2b,
//!   0x5b and 0x7b; reserved fields (register fields of unary operations,
//!   unused immediate bits the manual says "must be set to 0", undefined
//!   function codes) make the instruction illegal.
//! - [`alu`], [`bitmanip`], [`mac`], [`simd`]: the semantic functions;
//!   [`mem`]: the addressing of the loads and stores. The block executor's
//!   handlers (`exec/xcv.rs`) call them; the general path (`cpu/mod.rs`) uses
//!   [`mem`] for loads and stores outside the fast RAM.
//!
//! Not implemented: hardware loops (`xcvhwlp`: Debian's clang-19 does not
//! know the extension, so nothing we build can contain them) and the
//! cluster's event load `cv.elw` (`xcvelw`, not in the contract's list);
//! both decode as illegal instructions.

pub mod alu;
pub mod bitmanip;
pub mod mac;
pub mod mem;
pub mod simd;

use super::decode::{bits, imm_b, imm_s, op, Decoded};

/// Numbers a list of names from 0 and lists their names (for tests and
/// traces): the function codes of [`alu`] and [`simd`].
macro_rules! numbered {
    ($ty:ty; $($name:ident),* $(,)?) => {
        $crate::iss::xcv::numbered!(@n $ty; 0; $($name),*);
        /// Names, index = code.
        #[allow(dead_code)]
        pub const NAMES: &[&str] = &[$(stringify!($name)),*];
    };
    (@n $ty:ty; $n:expr; $first:ident $(, $rest:ident)*) => {
        pub const $first: $ty = $n;
        $crate::iss::xcv::numbered!(@n $ty; $n + 1; $($rest),*);
    };
    (@n $ty:ty; $n:expr;) => {};
}
pub(crate) use numbered;

/// `imm` of [`op::CV_ALU`]/[`op::CV_ALU_RD`]: function in bits 16.., its
/// immediate below.
pub const fn alu_imm(f: u32, small: u32) -> i32 {
    (f << 16 | small) as i32
}

/// Whether an op reads rd as a source (accumulators, inserts, the third
/// register of stores): the load-use hazard check includes it.
pub const fn reads_rd(o: u8) -> bool {
    matches!(
        o,
        op::CV_SB_PR
            | op::CV_SH_PR
            | op::CV_SW_PR
            | op::CV_SB_RR
            | op::CV_SH_RR
            | op::CV_SW_RR
            | op::CV_ALU_RD
            | op::CV_MAC
            | op::CV_MSU
            | op::CV_MACN
            | op::CV_SIMD_RD
            | op::CV_SDOTSP_B
            | op::CV_SDOTSP_H
            | op::CV_SDOTUSP_B
            | op::CV_SDOTUP_B
    )
}

/// Ops whose only effect is writing rd (so writing x0 makes them no-ops).
pub const fn pure(o: u8) -> bool {
    o >= op::CV_ALU && o <= op::CV_DOTSP_B
}

/// Loads (their rd is subject to the load-use stall).
pub const fn is_load(o: u8) -> bool {
    o >= op::CV_LB_PI && o <= op::CV_LHU_RR
}

/// Decode an instruction under one of the four custom opcodes; `None` for
/// reserved or unknown encodings.
pub fn decode(inst: u32) -> Option<Decoded> {
    let rd = bits(inst, 11, 7) as u8;
    let rs1 = bits(inst, 19, 15) as u8;
    let rs2 = bits(inst, 24, 20) as u8;
    let f3 = bits(inst, 14, 12);
    let f7 = bits(inst, 31, 25);
    let d = some;
    match inst & 0x7f {
        // custom-0: post-increment loads (immediate), immediate branches.
        0x0b => {
            let imm_i = (inst as i32) >> 20;
            let o = match f3 {
                0 => op::CV_LB_PI,
                1 => op::CV_LH_PI,
                2 => op::CV_LW_PI,
                4 => op::CV_LBU_PI,
                5 => op::CV_LHU_PI,
                6 | 7 => {
                    let imm_b = imm_b(inst);
                    let o = if f3 == 6 {
                        op::CV_BEQIMM
                    } else {
                        op::CV_BNEIMM
                    };
                    return d(o, rs2, rs1, 0, imm_b);
                }
                _ => return None, // 3: cv.elw (xcvelw)
            };
            d(o, rd, rs1, 0, imm_i)
        }
        // custom-1: post-increment stores (immediate); funct3 011: the
        // register forms of loads and stores, ALU, bit manipulation, MAC.
        0x2b => match f3 {
            0..=2 => {
                let imm_s = imm_s(inst);
                let o = [op::CV_SB_PI, op::CV_SH_PI, op::CV_SW_PI][f3 as usize];
                d(o, 0, rs1, rs2, imm_s)
            }
            3 => decode_custom1_rr(f7, rd, rs1, rs2),
            _ => None, // 4..: hardware loops (xcvhwlp)
        },
        // custom-2: immediate bit manipulation, addN/subN, 16-bit
        // multiplies and MACs with a normalisation shift.
        0x5b => {
            let f2 = bits(inst, 31, 30);
            let is3 = bits(inst, 29, 25);
            let is2 = rs2 as u32;
            let both = is3 << 5 | is2;
            match f3 {
                0 => {
                    let f = [alu::EXTRACT, alu::EXTRACTU, alu::INSERT, u32::MAX][f2 as usize];
                    match f {
                        alu::INSERT => d(op::CV_ALU_RD, rd, rs1, 0, alu_imm(f, both)),
                        u32::MAX => None,
                        _ => d(op::CV_ALU, rd, rs1, 0, alu_imm(f, both)),
                    }
                }
                1 => match f2 {
                    0 => d(op::CV_ALU, rd, rs1, 0, alu_imm(alu::BCLR, both)),
                    1 => d(op::CV_ALU, rd, rs1, 0, alu_imm(alu::BSET, both)),
                    // cv.bitrev: Is3 is a 2-bit field ("000, Luimm2").
                    3 if is3 < 4 => d(op::CV_ALU, rd, rs1, 0, alu_imm(alu::BITREV, both)),
                    _ => None,
                },
                2 | 3 => {
                    let f = if f3 == 2 { alu::ADDN } else { alu::SUBN } + f2;
                    d(op::CV_ALU, rd, rs1, rs2, alu_imm(f, is3))
                }
                _ => {
                    // 100 muls, 101 mulu, 110 macs, 111 macu; f2 = hh | round.
                    let signed = f3 & 1 == 0;
                    let kind = mac::kind(f2 & 1 != 0, f2 & 2 != 0, signed);
                    let o = if f3 >= 6 { op::CV_MACN } else { op::CV_MULN };
                    d(o, rd, rs1, rs2, alu_imm(kind, is3))
                }
            }
        }
        0x7b => simd::decode(inst)
            .and_then(|(o, imm, uses_rs2)| d(o, rd, rs1, if uses_rs2 { rs2 } else { 0 }, imm)),
        _ => None,
    }
}

/// A 32-bit decoded instruction.
fn some(op: u8, rd: u8, rs1: u8, rs2: u8, imm: i32) -> Option<Decoded> {
    Some(Decoded {
        op,
        rd,
        rs1,
        rs2,
        imm,
        compressed: false,
    })
}

/// custom-1, funct3 011: register-register forms (funct7 selects).
fn decode_custom1_rr(f7: u32, rd: u8, rs1: u8, rs2: u8) -> Option<Decoded> {
    let d = some;
    // Unary operations: the rs2 field is reserved (0).
    let unary = |f| {
        if rs2 == 0 {
            d(op::CV_ALU, rd, rs1, 0, alu_imm(f, 0))
        } else {
            None
        }
    };
    let binary = |f| d(op::CV_ALU, rd, rs1, rs2, alu_imm(f, 0));
    let loads = [op::CV_LB_PR, op::CV_LH_PR, op::CV_LW_PR];
    match f7 {
        // Loads: bit 2 = register offset (no increment), bit 3 = unsigned.
        0b000_0000..=0b000_0010 => d(loads[f7 as usize], rd, rs1, rs2, 0),
        0b000_1000 => d(op::CV_LBU_PR, rd, rs1, rs2, 0),
        0b000_1001 => d(op::CV_LHU_PR, rd, rs1, rs2, 0),
        0b000_0100 => d(op::CV_LB_RR, rd, rs1, rs2, 0),
        0b000_0101 => d(op::CV_LH_RR, rd, rs1, rs2, 0),
        0b000_0110 => d(op::CV_LW_RR, rd, rs1, rs2, 0),
        0b000_1100 => d(op::CV_LBU_RR, rd, rs1, rs2, 0),
        0b000_1101 => d(op::CV_LHU_RR, rd, rs1, rs2, 0),
        // Stores: rs3 (the increment or offset) is in the rd field.
        0b001_0000 => d(op::CV_SB_PR, rd, rs1, rs2, 0),
        0b001_0001 => d(op::CV_SH_PR, rd, rs1, rs2, 0),
        0b001_0010 => d(op::CV_SW_PR, rd, rs1, rs2, 0),
        0b001_0100 => d(op::CV_SB_RR, rd, rs1, rs2, 0),
        0b001_0101 => d(op::CV_SH_RR, rd, rs1, rs2, 0),
        0b001_0110 => d(op::CV_SW_RR, rd, rs1, rs2, 0),
        // Bit manipulation, register forms.
        0b001_1000 => binary(alu::EXTRACTR),
        0b001_1001 => binary(alu::EXTRACTUR),
        0b001_1010 => d(op::CV_ALU_RD, rd, rs1, rs2, alu_imm(alu::INSERTR, 0)),
        0b001_1100 => binary(alu::BCLRR),
        0b001_1101 => binary(alu::BSETR),
        0b010_0000 => binary(alu::ROR),
        0b010_0001 => unary(alu::FF1),
        0b010_0010 => unary(alu::FL1),
        0b010_0011 => unary(alu::CLB),
        0b010_0100 => unary(alu::CNT),
        // General ALU operations.
        0b010_1000 => unary(alu::ABS),
        0b010_1001..=0b010_1110 => binary(alu::SLE + (f7 - 0b010_1001)),
        0b011_0000..=0b011_0011 => unary(alu::EXTHS + (f7 - 0b011_0000)),
        // cv.clip/cv.clipu: the rs2 field is the immediate Is2.
        0b011_1000 => d(op::CV_ALU, rd, rs1, 0, alu_imm(alu::CLIP, rs2 as u32)),
        0b011_1001 => d(op::CV_ALU, rd, rs1, 0, alu_imm(alu::CLIPU, rs2 as u32)),
        0b011_1010 => binary(alu::CLIPR),
        0b011_1011 => binary(alu::CLIPUR),
        0b100_0000..=0b100_0111 => d(
            op::CV_ALU_RD,
            rd,
            rs1,
            rs2,
            alu_imm(alu::ADDNR + (f7 - 0b100_0000), 0),
        ),
        0b100_1000 => d(op::CV_MAC, rd, rs1, rs2, 0),
        0b100_1001 => d(op::CV_MSU, rd, rs1, rs2, 0),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Encodings assembled by clang-19 (`llvm-objdump-19 -d` of the
    /// firmware's XCV ELFs), the independent reference.
    #[test]
    fn decodes_what_clang_assembles() {
        for (word, o, rd, rs1, rs2) in [
            (0x0015_070b, op::CV_LB_PI, 14, 10, 0), // cv.lb a4, (a0), 1
            (0x0045_270b, op::CV_LW_PI, 14, 10, 0), // cv.lw a4, (a0), 4
            (0x00e5_222b, op::CV_SW_PI, 0, 10, 14), // cv.sw a4, (a0), 4
            (0x56b5_352b, op::CV_ALU, 10, 10, 11),  // cv.min a0, a0, a1
            (0xa8f7_157b, op::CV_SDOTSP_B, 10, 14, 15), // cv.sdotsp.b a0, a4, a5
            (0x98c5_d77b, op::CV_SIMD_RD, 14, 11, 12), // cv.sdotup.sc.b a4, a1, a2
            (0x92c5_b72b, op::CV_MSU, 14, 11, 12),  // cv.msu a4, a1, a2
            (0x2105_e77b, op::CV_SIMD, 14, 11, 0),  // cv.min.sci.h a4, a1, -32
            (0x14c5_977b, op::CV_SIMD, 14, 11, 12), // cv.cmpgt.b a4, a1, a2
        ] {
            let d = decode(word).unwrap_or_else(|| panic!("{word:#010x}"));
            assert_eq!(
                (d.op, d.rd, d.rs1, d.rs2),
                (o, rd, rs1, rs2),
                "{word:#010x}"
            );
        }
        // cv.bneimm a3, 0, -14 (the benchmark's loop branch).
        let b = decode(0xfe06_f98b).unwrap();
        assert_eq!((b.op, b.rs1, b.rd, b.imm), (op::CV_BNEIMM, 13, 0, -14));
        // cv.min.sci.h: Imm6 = -32 (0b100000) sits in bit 25 and the rs2 field.
        let m = decode(0x2105_e77b).unwrap();
        assert_eq!(m.imm & 63, 0b10_0000);
    }

    proptest::proptest! {
        #[test]
        fn xcv_decoding_never_panics_and_fields_are_in_range(inst: u32, k in 0usize..4) {
            let inst = (inst & !0x7f) | [0x0b, 0x2b, 0x5b, 0x7b][k];
            if let Some(d) = decode(inst) {
                proptest::prop_assert!(d.op >= op::CV_LB_PI && (d.op as usize) < op::COUNT);
                proptest::prop_assert!(d.rd < 32 && d.rs1 < 32 && d.rs2 < 32);
            }
        }
    }
}
