//! Instruction decoding: RV32IMC + Zicsr + Zifencei + the privileged
//! instructions we implement, into [`Decoded`], which the block cache
//! (`block.rs`) turns into the core's pre-decoded blocks.
//!
//! Compressed instructions are first expanded to the 32-bit instruction they
//! stand for ([`expand_compressed`]) and then decoded like any other, so the
//! two forms cannot disagree; only the length differs.
//!
//! The immediate is sign-extended; for CSR instructions it holds the CSR
//! number in bits 0..12 and the 5-bit immediate above it; for illegal
//! instructions the raw bits, which become `mtval`. Fields an instruction
//! does not read are 0, so the load-use stall check can compare rs1/rs2
//! blindly.

/// Operation codes (never 0). A plain `u8` namespace instead of an enum so
/// the core's dispatch is a jump table on a byte without a conversion.
pub mod op {
    macro_rules! ops {
        ($($name:ident),* $(,)?) => {
            ops!(@count 1u8; $($name),*);
            /// Mnemonic of each op (index = op code), for traces and tests.
            pub const NAMES: &[&str] = &["<none>", $(stringify!($name)),*];
        };
        (@count $n:expr; $first:ident $(, $rest:ident)*) => {
            pub const $first: u8 = $n;
            ops!(@count $n + 1; $($rest),*);
        };
        (@count $n:expr;) => {
            /// Number of op codes including the 0 "not decoded" marker.
            pub const COUNT: usize = $n as usize;
        };
    }
    ops! {
        LUI, AUIPC, JAL, JALR, BEQ, BNE, BLT, BGE, BLTU, BGEU, LB, LH, LW, LBU, LHU, SB, SH, SW,
        ADDI, SLTI, SLTIU, XORI, ORI, ANDI, SLLI, SRLI, SRAI, ADD, SUB, SLL, SLT, SLTU, XOR, SRL,
        SRA, OR, AND, FENCE, FENCE_I, ECALL, EBREAK, MRET, WFI, CSRRW, CSRRS, CSRRC, CSRRWI,
        CSRRSI, CSRRCI, MUL, MULH, MULHSU, MULHU, DIV, DIVU, REM, REMU, ILLEGAL,
        // Forms only the block cache produces (`block.rs`), never `decode`:
        // a computation whose result goes to x0, the end of a block that
        // has no control transfer, a `jal` the block follows.
        NOP, END, JUMP,
        // CORE-V XCV (`xcv/`): post-increment loads (immediate, register)
        // and register-offset loads; the same for stores (the third
        // register, `rs3`, sits in `rd`).
        CV_LB_PI, CV_LH_PI, CV_LW_PI, CV_LBU_PI, CV_LHU_PI,
        CV_LB_PR, CV_LH_PR, CV_LW_PR, CV_LBU_PR, CV_LHU_PR,
        CV_LB_RR, CV_LH_RR, CV_LW_RR, CV_LBU_RR, CV_LHU_RR,
        CV_SB_PI, CV_SH_PI, CV_SW_PI, CV_SB_PR, CV_SH_PR, CV_SW_PR, CV_SB_RR, CV_SH_RR, CV_SW_RR,
        // Immediate branches: `rd` holds the 5-bit immediate.
        CV_BEQIMM, CV_BNEIMM,
        // Computations: `imm` holds the function and its immediates
        // (`xcv::alu`, `xcv::mac`, `xcv::simd`); the `_RD` forms also
        // read rd.
        CV_ALU, CV_ALU_RD, CV_MAC, CV_MSU, CV_MULN, CV_MACN, CV_SIMD, CV_SIMD_RD,
        // The dot products of the NN inner loops, with their own handlers.
        CV_SDOTSP_B, CV_SDOTSP_H, CV_SDOTUSP_B, CV_SDOTUP_B, CV_DOTSP_B,
    }
}

/// A decoded instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decoded {
    pub op: u8,
    pub rd: u8,
    pub rs1: u8,
    pub rs2: u8,
    pub imm: i32,
    pub compressed: bool,
}

impl Decoded {
    /// Length of the instruction in bytes.
    #[allow(clippy::len_without_is_empty)] // an instruction is never empty
    pub const fn len(self) -> u32 {
        if self.compressed {
            2
        } else {
            4
        }
    }

    pub fn name(self) -> &'static str {
        op::NAMES.get(self.op as usize).copied().unwrap_or("?")
    }
}

const fn illegal(raw: u32) -> Decoded {
    Decoded {
        op: op::ILLEGAL,
        rd: 0,
        rs1: 0,
        rs2: 0,
        imm: raw as i32,
        compressed: false,
    }
}

#[inline]
pub(super) fn bits(x: u32, hi: u32, lo: u32) -> u32 {
    (x >> lo) & ((1u32 << (hi - lo + 1)) - 1)
}

/// The S-type immediate (stores, and the XCV stores that use its layout).
pub(super) fn imm_s(inst: u32) -> i32 {
    sext(bits(inst, 31, 25) << 5 | bits(inst, 11, 7), 12)
}

/// The B-type immediate (branches, and XCV's `cv.beqimm`/`cv.bneimm`).
pub(super) fn imm_b(inst: u32) -> i32 {
    sext(
        bits(inst, 31, 31) << 12
            | bits(inst, 7, 7) << 11
            | bits(inst, 30, 25) << 5
            | bits(inst, 11, 8) << 1,
        13,
    )
}

pub(super) fn sext(x: u32, width: u32) -> i32 {
    let s = 32 - width;
    ((x << s) as i32) >> s
}

/// Decode a 32-bit instruction.
pub fn decode32(inst: u32) -> Decoded {
    let rd = bits(inst, 11, 7) as u8;
    let rs1 = bits(inst, 19, 15) as u8;
    let rs2 = bits(inst, 24, 20) as u8;
    let f3 = bits(inst, 14, 12);
    let f7 = bits(inst, 31, 25);
    let imm_i = (inst as i32) >> 20;
    let imm_s = imm_s(inst);
    let imm_b = imm_b(inst);
    let imm_j = sext(
        bits(inst, 31, 31) << 20
            | bits(inst, 19, 12) << 12
            | bits(inst, 20, 20) << 11
            | bits(inst, 30, 21) << 1,
        21,
    );
    let d = |op, rd, rs1, rs2, imm| Decoded {
        op,
        rd,
        rs1,
        rs2,
        imm,
        compressed: false,
    };
    if inst & 3 != 3 {
        return illegal(inst);
    }
    match inst & 0x7f {
        0x37 => d(op::LUI, rd, 0, 0, (inst & 0xffff_f000) as i32),
        0x17 => d(op::AUIPC, rd, 0, 0, (inst & 0xffff_f000) as i32),
        0x6f => d(op::JAL, rd, 0, 0, imm_j),
        0x67 if f3 == 0 => d(op::JALR, rd, rs1, 0, imm_i),
        0x63 => {
            let o = match f3 {
                0 => op::BEQ,
                1 => op::BNE,
                4 => op::BLT,
                5 => op::BGE,
                6 => op::BLTU,
                7 => op::BGEU,
                _ => return illegal(inst),
            };
            d(o, 0, rs1, rs2, imm_b)
        }
        0x03 => {
            let o = match f3 {
                0 => op::LB,
                1 => op::LH,
                2 => op::LW,
                4 => op::LBU,
                5 => op::LHU,
                _ => return illegal(inst),
            };
            d(o, rd, rs1, 0, imm_i)
        }
        0x23 => {
            let o = match f3 {
                0 => op::SB,
                1 => op::SH,
                2 => op::SW,
                _ => return illegal(inst),
            };
            d(o, 0, rs1, rs2, imm_s)
        }
        0x13 => {
            let shamt = rs2 as i32;
            match (f3, f7) {
                (0, _) => d(op::ADDI, rd, rs1, 0, imm_i),
                (2, _) => d(op::SLTI, rd, rs1, 0, imm_i),
                (3, _) => d(op::SLTIU, rd, rs1, 0, imm_i),
                (4, _) => d(op::XORI, rd, rs1, 0, imm_i),
                (6, _) => d(op::ORI, rd, rs1, 0, imm_i),
                (7, _) => d(op::ANDI, rd, rs1, 0, imm_i),
                (1, 0) => d(op::SLLI, rd, rs1, 0, shamt),
                (5, 0) => d(op::SRLI, rd, rs1, 0, shamt),
                (5, 0x20) => d(op::SRAI, rd, rs1, 0, shamt),
                _ => illegal(inst),
            }
        }
        0x33 => {
            let o = match (f7, f3) {
                (0, 0) => op::ADD,
                (0x20, 0) => op::SUB,
                (0, 1) => op::SLL,
                (0, 2) => op::SLT,
                (0, 3) => op::SLTU,
                (0, 4) => op::XOR,
                (0, 5) => op::SRL,
                (0x20, 5) => op::SRA,
                (0, 6) => op::OR,
                (0, 7) => op::AND,
                (1, 0) => op::MUL,
                (1, 1) => op::MULH,
                (1, 2) => op::MULHSU,
                (1, 3) => op::MULHU,
                (1, 4) => op::DIV,
                (1, 5) => op::DIVU,
                (1, 6) => op::REM,
                (1, 7) => op::REMU,
                _ => return illegal(inst),
            };
            d(o, rd, rs1, rs2, 0)
        }
        // The unused fields of FENCE and FENCE.I are ignored, as the ISA
        // manual asks of base implementations.
        0x0f if f3 == 0 => d(op::FENCE, 0, 0, 0, 0),
        0x0f if f3 == 1 => d(op::FENCE_I, 0, 0, 0, 0),
        0x73 => {
            let csr = bits(inst, 31, 20) as i32;
            match f3 {
                0 => match inst {
                    0x0000_0073 => d(op::ECALL, 0, 0, 0, 0),
                    0x0010_0073 => d(op::EBREAK, 0, 0, 0, 0),
                    0x3020_0073 => d(op::MRET, 0, 0, 0, 0),
                    0x1050_0073 => d(op::WFI, 0, 0, 0, 0),
                    _ => illegal(inst),
                },
                1 => d(op::CSRRW, rd, rs1, 0, csr),
                2 => d(op::CSRRS, rd, rs1, 0, csr),
                3 => d(op::CSRRC, rd, rs1, 0, csr),
                5 => d(op::CSRRWI, rd, 0, 0, csr | (rs1 as i32) << 12),
                6 => d(op::CSRRSI, rd, 0, 0, csr | (rs1 as i32) << 12),
                7 => d(op::CSRRCI, rd, 0, 0, csr | (rs1 as i32) << 12),
                _ => illegal(inst),
            }
        }
        0x0b | 0x2b | 0x5b | 0x7b => super::xcv::decode(inst).unwrap_or(illegal(inst)),
        _ => illegal(inst),
    }
}

// Encoders for the expansion of compressed instructions.
fn enc_i(opcode: u32, rd: u32, f3: u32, rs1: u32, imm: i32) -> u32 {
    ((imm as u32) & 0xfff) << 20 | rs1 << 15 | f3 << 12 | rd << 7 | opcode
}
fn enc_s(opcode: u32, f3: u32, rs1: u32, rs2: u32, imm: i32) -> u32 {
    let imm = imm as u32;
    bits(imm, 11, 5) << 25 | rs2 << 20 | rs1 << 15 | f3 << 12 | bits(imm, 4, 0) << 7 | opcode
}
fn enc_r(f7: u32, rs2: u32, rs1: u32, f3: u32, rd: u32) -> u32 {
    f7 << 25 | rs2 << 20 | rs1 << 15 | f3 << 12 | rd << 7 | 0x33
}
fn enc_b(f3: u32, rs1: u32, rs2: u32, imm: i32) -> u32 {
    let imm = imm as u32;
    bits(imm, 12, 12) << 31
        | bits(imm, 10, 5) << 25
        | rs2 << 20
        | rs1 << 15
        | f3 << 12
        | bits(imm, 4, 1) << 8
        | bits(imm, 11, 11) << 7
        | 0x63
}
fn enc_j(rd: u32, imm: i32) -> u32 {
    let imm = imm as u32;
    bits(imm, 20, 20) << 31
        | bits(imm, 10, 1) << 21
        | bits(imm, 11, 11) << 20
        | bits(imm, 19, 12) << 12
        | rd << 7
        | 0x6f
}

/// The 32-bit instruction a 16-bit RVC instruction stands for (RV32C, no F/D),
/// or `None` for reserved and unsupported encodings (illegal instruction).
pub fn expand_compressed(c: u16) -> Option<u32> {
    let c = c as u32;
    let rd = bits(c, 11, 7);
    let rs2 = bits(c, 6, 2);
    let rdp = bits(c, 4, 2) + 8; // rd' / rs2'
    let rs1p = bits(c, 9, 7) + 8; // rs1' / rd'
    let f3 = bits(c, 15, 13);
    let imm6 = sext(bits(c, 12, 12) << 5 | bits(c, 6, 2), 6);
    let lw_off = (bits(c, 12, 10) << 3 | bits(c, 6, 6) << 2 | bits(c, 5, 5) << 6) as i32;
    let j_off = sext(
        bits(c, 12, 12) << 11
            | bits(c, 11, 11) << 4
            | bits(c, 10, 9) << 8
            | bits(c, 8, 8) << 10
            | bits(c, 7, 7) << 6
            | bits(c, 6, 6) << 7
            | bits(c, 5, 3) << 1
            | bits(c, 2, 2) << 5,
        12,
    );
    let b_off = sext(
        bits(c, 12, 12) << 8
            | bits(c, 11, 10) << 3
            | bits(c, 6, 5) << 6
            | bits(c, 4, 3) << 1
            | bits(c, 2, 2) << 5,
        9,
    );
    match (c & 3, f3) {
        (0, 0) => {
            let nzuimm = bits(c, 12, 11) << 4
                | bits(c, 10, 7) << 6
                | bits(c, 6, 6) << 2
                | bits(c, 5, 5) << 3;
            (nzuimm != 0).then(|| enc_i(0x13, rdp, 0, 2, nzuimm as i32))
        }
        (0, 2) => Some(enc_i(0x03, rdp, 2, rs1p, lw_off)),
        (0, 6) => Some(enc_s(0x23, 2, rs1p, rdp, lw_off)),
        (1, 0) => Some(enc_i(0x13, rd, 0, rd, imm6)),
        (1, 1) => Some(enc_j(1, j_off)),
        (1, 2) => Some(enc_i(0x13, rd, 0, 0, imm6)),
        (1, 3) if rd == 2 => {
            let nz = sext(
                bits(c, 12, 12) << 9
                    | bits(c, 6, 6) << 4
                    | bits(c, 5, 5) << 6
                    | bits(c, 4, 3) << 7
                    | bits(c, 2, 2) << 5,
                10,
            );
            (nz != 0).then(|| enc_i(0x13, 2, 0, 2, nz))
        }
        (1, 3) => (imm6 != 0).then_some(((imm6 as u32) << 12) | rd << 7 | 0x37),
        (1, 4) => {
            let shamt = bits(c, 6, 2);
            match bits(c, 11, 10) {
                0 if bits(c, 12, 12) == 0 => Some(enc_i(0x13, rs1p, 5, rs1p, shamt as i32)),
                1 if bits(c, 12, 12) == 0 => {
                    Some(enc_i(0x13, rs1p, 5, rs1p, (shamt | 0x400) as i32))
                }
                2 => Some(enc_i(0x13, rs1p, 7, rs1p, imm6)),
                3 if bits(c, 12, 12) == 0 => {
                    let (f7, f3) = match bits(c, 6, 5) {
                        0 => (0x20, 0),
                        1 => (0, 4),
                        2 => (0, 6),
                        _ => (0, 7),
                    };
                    Some(enc_r(f7, rdp, rs1p, f3, rs1p))
                }
                _ => None,
            }
        }
        (1, 5) => Some(enc_j(0, j_off)),
        (1, 6) => Some(enc_b(0, rs1p, 0, b_off)),
        (1, 7) => Some(enc_b(1, rs1p, 0, b_off)),
        (2, 0) => (bits(c, 12, 12) == 0).then(|| enc_i(0x13, rd, 1, rd, rs2 as i32)),
        (2, 2) if rd != 0 => {
            let off = bits(c, 12, 12) << 5 | bits(c, 6, 4) << 2 | bits(c, 3, 2) << 6;
            Some(enc_i(0x03, rd, 2, 2, off as i32))
        }
        (2, 4) => match (bits(c, 12, 12), rd, rs2) {
            (0, 0, 0) => None,
            (0, _, 0) => Some(enc_i(0x67, 0, 0, rd, 0)),
            (0, _, _) => Some(enc_r(0, rs2, 0, 0, rd)),
            (1, 0, 0) => Some(0x0010_0073),
            (1, _, 0) => Some(enc_i(0x67, 1, 0, rd, 0)),
            _ => Some(enc_r(0, rs2, rd, 0, rd)),
        },
        (2, 6) => {
            let off = bits(c, 12, 9) << 2 | bits(c, 8, 7) << 6;
            Some(enc_s(0x23, 2, 2, rs2, off as i32))
        }
        _ => None,
    }
}

/// Decode the instruction whose first halfword is `lo` and, if it is a
/// 32-bit one, second halfword `hi` (only read when needed).
pub fn decode(lo: u16, hi: impl FnOnce() -> Option<u16>) -> Option<Decoded> {
    if lo & 3 == 3 {
        let hi = hi()?;
        Some(decode32(lo as u32 | (hi as u32) << 16))
    } else {
        Some(match expand_compressed(lo) {
            Some(inst) => {
                let mut d = decode32(inst);
                d.compressed = true;
                if d.op == op::ILLEGAL {
                    d.imm = lo as i32;
                }
                d
            }
            None => Decoded {
                compressed: true,
                ..illegal(lo as u32)
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn op_names_cover_every_op() {
        assert_eq!(op::NAMES.len(), op::COUNT);
        assert_eq!(op::NAMES[op::ILLEGAL as usize], "ILLEGAL");
    }

    // Encodings below were assembled by riscv64-unknown-elf-as
    // (-march=rv32imc), which is the independent reference.
    #[test]
    fn decodes_known_encodings() {
        let addi = decode32(0xfff0_0513); // addi a0, zero, -1
        assert_eq!(
            (addi.op, addi.rd, addi.rs1, addi.imm),
            (op::ADDI, 10, 0, -1)
        );
        let sw = decode32(0x00a1_2623); // sw a0, 12(sp)
        assert_eq!((sw.op, sw.rs1, sw.rs2, sw.imm), (op::SW, 2, 10, 12));
        let beq = decode32(0xfe05_8ee3); // beq a1, zero, -4
        assert_eq!((beq.op, beq.rs1, beq.rs2, beq.imm), (op::BEQ, 11, 0, -4));
        let jal = decode32(0x0080_00ef); // jal ra, +8
        assert_eq!((jal.op, jal.rd, jal.imm), (op::JAL, 1, 8));
        let csr = decode32(0x3400_5073); // csrwi mscratch, 0
        assert_eq!((csr.op, csr.imm & 0xfff), (op::CSRRWI, 0x340));
        assert_eq!(decode32(0x0000_0000).op, op::ILLEGAL);
        assert_eq!(decode32(0x3020_0073).op, op::MRET);
        assert_eq!(decode32(0x4000_d093).op, op::SRAI);
        assert_eq!(decode32(0x0200_0033).op, op::MUL);
    }

    /// (compressed, expanded) pairs assembled by GNU as (rv32imc, no
    /// relaxation): each 16-bit form next to its 32-bit equivalent.
    const RVC_PAIRS: &[(u16, u32)] = &[
        (0x0020, 0x00810413), // c.addi4spn s0, sp, 8
        (0x1ffc, 0x3fc10793), // c.addi4spn a5, sp, 1020
        (0x4188, 0x0005a503), // c.lw a0, 0(a1)
        (0x5fe4, 0x07c7a483), // c.lw s1, 124(a5)
        (0xc030, 0x04c42023), // c.sw a2, 64(s0)
        (0xc35c, 0x00f72223), // c.sw a5, 4(a4)
        (0x1501, 0xfe050513), // c.addi a0, -32
        (0x0ffd, 0x01ff8f93), // c.addi t6, 31
        (0x0001, 0x00000013), // c.nop
        (0x2ffd, 0x7fe000ef), // c.jal .+2046
        (0x3001, 0x801ff0ef), // c.jal .-2048
        (0x557d, 0xfff00513), // c.li a0, -1
        (0x42c5, 0x01100293), // c.li t0, 17
        (0x7101, 0xe0010113), // c.addi16sp sp, -512
        (0x617d, 0x1f010113), // c.addi16sp sp, 496
        (0x7501, 0xfffe0537), // c.lui a0, 0xfffe0
        (0x6dfd, 0x0001fdb7), // c.lui s11, 0x1f
        (0x817d, 0x01f55513), // c.srli a0, 31
        (0x8485, 0x4014d493), // c.srai s1, 1
        (0x9a81, 0xfe06f693), // c.andi a3, -32
        (0x8a9d, 0x0076f693), // c.andi a3, 7
        (0x8c1d, 0x40f40433), // c.sub s0, a5
        (0x8db1, 0x00c5c5b3), // c.xor a1, a2
        (0x8f45, 0x00976733), // c.or a4, s1
        (0x8fe9, 0x00a7f7b3), // c.and a5, a0
        (0xbffd, 0xfffff06f), // c.j .-2
        (0xa6e5, 0x3e80006f), // c.j .+1000
        (0xd101, 0xf00500e3), // c.beqz a0, .-256
        (0xccfd, 0x0e048f63), // c.beqz s1, .+254
        (0xeb81, 0x00079863), // c.bnez a5, .+16
        (0x02fe, 0x01f29293), // c.slli t0, 31
        (0x50fe, 0x0fc12083), // c.lwsp ra, 252(sp)
        (0x4502, 0x00012503), // c.lwsp a0, 0(sp)
        (0x8082, 0x00008067), // c.jr ra
        (0x8e02, 0x000e0067), // c.jr t3
        (0x854a, 0x01200533), // c.mv a0, s2
        (0x9002, 0x00100073), // c.ebreak
        (0x9782, 0x000780e7), // c.jalr a5
        (0x9346, 0x01130333), // c.add t1, a7
        (0xdfa2, 0x0e812e23), // c.swsp s0, 252(sp)
        (0xc402, 0x00012423), // c.swsp zero, 8(sp)
    ];

    #[test]
    fn compressed_expand_to_the_assemblers_32_bit_form() {
        for &(c, full) in RVC_PAIRS {
            assert_eq!(expand_compressed(c), Some(full), "{c:#06x}");
            let d = decode(c, || None).unwrap();
            let mut want = decode32(full);
            want.compressed = true;
            assert_eq!(d, want, "{c:#06x}");
            assert_eq!(d.len(), 2);
        }
    }

    #[test]
    fn reserved_compressed_encodings_are_illegal() {
        // All-zero halfword, c.addi16sp 0, c.lui x1 0, c.lwsp x0, c.jr x0,
        // RV32 c.srli with shamt[5], and the F/D loads and stores.
        for c in [
            0x0000u16, 0x6101, 0x6081, 0x4002, 0x8002, 0x9001, 0x2000, 0x6000, 0xe000, 0x2002,
        ] {
            assert_eq!(expand_compressed(c), None, "{c:#06x}");
            let d = decode(c, || None).unwrap();
            assert_eq!((d.op, d.imm as u32, d.len()), (op::ILLEGAL, c as u32, 2));
        }
    }

    #[test]
    fn every_halfword_expands_to_a_legal_32_bit_instruction_or_none() {
        for c in 0..=u16::MAX {
            if c & 3 == 3 {
                continue;
            }
            if let Some(full) = expand_compressed(c) {
                assert_eq!(full & 3, 3, "{c:#06x}");
                assert_ne!(decode32(full).op, op::ILLEGAL, "{c:#06x} -> {full:#010x}");
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn decoding_never_panics_and_fields_are_in_range(inst: u32) {
            let d = decode32(inst);
            proptest::prop_assert!(d.op != 0 && (d.op as usize) < op::COUNT);
            proptest::prop_assert!(d.rd < 32 && d.rs1 < 32 && d.rs2 < 32);
        }
    }
}
