//! `xcvsimd` (CV32E40P manual, "SIMD": packed 16-bit (.h) and 8-bit (.b)
//! lanes; ALU, bit manipulation, dot products, shuffle and pack,
//! comparisons, complex numbers). One cycle each: the ALU ops are
//! "Integer Computational", the dot products and complex multiplies run on
//! the single-cycle multiplier ("Multiplication: 1", pipeline.rst).
//!
//! Operand modes (manual, "SIMD operations"): vector (rs2's lanes), `.sc`
//! (rs2's lowest lane replicated), `.sci` (the 6-bit immediate replicated,
//! sign-extended except for the unsigned operations, shifts and shuffles).
//! Lane 0 is the lowest halfword / byte.
//!
//! `imm` of [`op::CV_SIMD`] and friends: the function ([`F`] << 5 |
//! funct5) in bits 16..22, funct1 in bit 11, funct3 in bits 8..11, Imm6
//! in bits 0..6.

use super::super::decode::{bits, op, sext};

/// The F bit (26): comparisons and complex-number operations.
const F: u32 = 32;

const ADD: u32 = 0;
const SUB: u32 = 1;
const AVG: u32 = 2;
const AVGU: u32 = 3;
const MIN: u32 = 4;
const MINU: u32 = 5;
const MAX: u32 = 6;
const MAXU: u32 = 7;
const SRL: u32 = 8;
const SRA: u32 = 9;
const SLL: u32 = 10;
const OR: u32 = 11;
const XOR: u32 = 12;
const AND: u32 = 13;
const ABS: u32 = 14;
const DOTUP: u32 = 16;
const DOTUSP: u32 = 17;
const DOTSP: u32 = 18;
const SDOTUP: u32 = 19;
const SDOTUSP: u32 = 20;
const SDOTSP: u32 = 21;
const EXTRACT: u32 = 23;
const SHUFFLE: u32 = 24;
const SHUFFLEI3: u32 = 27;
const SHUFFLE2: u32 = 28;
const PACK: u32 = 30;
const PACK_B: u32 = 31;
const CMPEQ: u32 = F;
const CMPNE: u32 = F + 1;
const CMPGT: u32 = F + 2;
const CMPGE: u32 = F + 3;
const CMPLT: u32 = F + 4;
const CMPLE: u32 = F + 5;
const CMPGTU: u32 = F + 6;
const CMPGEU: u32 = F + 7;
const CMPLTU: u32 = F + 8;
const CMPLEU: u32 = F + 9;
const CPLXMUL: u32 = F + 10;
const CPLXCONJ: u32 = F + 11;
const SUBROTMJ: u32 = F + 12;
const ADD_DIV: u32 = F + 13;
const SUB_DIV: u32 = F + 14;

/// Functions with the six operand forms (.h, .b, .sc.h, .sc.b, .sci.h,
/// .sci.b).
fn binary(f: u32) -> bool {
    matches!(f, ADD..=AND | DOTUP..=SDOTSP | CMPEQ..=CMPLEU)
}

/// Whether `.sci` zero-extends the immediate (unsigned operations and
/// shifts; the manual's notes per instruction).
fn unsigned_imm(f: u32) -> bool {
    matches!(
        f,
        AVGU | MINU | MAXU | SRL | SRA | SLL | DOTUP | SDOTUP | CMPGTU..=CMPLEU
    )
}

/// Decode a custom-3 instruction: (op, imm, whether rs2 is a register
/// operand), or `None` if reserved.
pub fn decode(inst: u32) -> Option<(u8, i32, bool)> {
    let funct5 = bits(inst, 31, 27);
    let f = bits(inst, 26, 26) << 5 | funct5;
    let funct1 = bits(inst, 25, 25);
    let f3 = bits(inst, 14, 12);
    let rs2 = bits(inst, 24, 20);
    let imm6 = funct1 | rs2 << 1;
    let imm = (f << 16 | funct1 << 11 | f3 << 8 | imm6) as i32;
    let rr = funct1 == 0; // register forms: bit 25 is reserved
    let scaled = matches!(f3, 0 | 2 | 4 | 6); // the .div2/.div4/.div8 family
    let accumulates =
        matches!(f, SDOTUP..=SDOTSP | SHUFFLE2 | PACK_B | CPLXMUL) || (f == EXTRACT && f3 >= 4);
    let simd = if accumulates {
        op::CV_SIMD_RD
    } else {
        op::CV_SIMD
    };
    let ok = match f {
        _ if binary(f) => {
            let sci = f3 >= 6;
            let width_bits = if f3 & 1 == 0 { 4 } else { 3 };
            let shift_imm_ok = !matches!(f, SRL..=SLL) || imm6 >> width_bits == 0;
            !matches!(f3, 2 | 3) && (sci || rr) && (!sci || shift_imm_ok)
        }
        ABS => f3 <= 1 && rr && rs2 == 0,
        // Unused Imm6 bits must be 0: .h uses Imm6[0], .b Imm6[1:0].
        EXTRACT => f3 <= 5 && imm6 >> (1 + (f3 & 1)) == 0,
        SHUFFLE => match f3 {
            0 | 1 => rr,
            6 => imm6 >> 2 == 0,
            7 => true,
            _ => false,
        },
        25..=SHUFFLEI3 => f3 == 7,
        SHUFFLE2 => f3 <= 1 && rr,
        PACK => f3 == 0,
        PACK_B => f3 == 1,
        CPLXMUL => scaled,
        CPLXCONJ => f3 == 0 && rr && rs2 == 0,
        SUBROTMJ => scaled && rr,
        ADD_DIV | SUB_DIV => scaled && f3 != 0 && rr,
        _ => false,
    };
    if !ok {
        return None;
    }
    let uses_rs2 = match f {
        _ if binary(f) => f3 < 6,
        SHUFFLE => f3 <= 1,
        ABS | EXTRACT | 25..=SHUFFLEI3 | CPLXCONJ => false,
        _ => true,
    };
    let o = match (f, f3) {
        (SDOTSP, 1) => op::CV_SDOTSP_B,
        (SDOTSP, 0) => op::CV_SDOTSP_H,
        (SDOTUSP, 1) => op::CV_SDOTUSP_B,
        (SDOTUP, 1) => op::CV_SDOTUP_B,
        (DOTSP, 1) => op::CV_DOTSP_B,
        _ => simd,
    };
    Some((o, imm, uses_rs2))
}

/// Lane `i` of width `w` bits (zero-extended).
#[inline(always)]
fn lane(v: u32, i: u32, w: u32) -> u32 {
    (v >> (i * w)) & ((1u32 << w) - 1)
}

/// Replicate the lowest lane over the register.
#[inline(always)]
fn splat(v: u32, w: u32) -> u32 {
    if w == 8 {
        (v & 0xff) * 0x0101_0101
    } else {
        (v & 0xffff) * 0x0001_0001
    }
}

/// Apply `g` lane by lane.
#[inline(always)]
fn map(a: u32, b: u32, w: u32, g: impl Fn(u32, u32) -> u32) -> u32 {
    let mask = (1u32 << w) - 1;
    (0..32 / w).fold(0, |acc, i| {
        acc | (g(lane(a, i, w), lane(b, i, w)) & mask) << (i * w)
    })
}

/// `cv.sdotsp.b`: d + the four signed byte products (the NN inner loop).
#[inline(always)]
pub fn sdotsp_b(d: u32, a: u32, b: u32) -> u32 {
    let p = |k: u32| ((a >> k) as i8 as i32) * ((b >> k) as i8 as i32);
    // Each product is in [-16256, 16384]: the sum of four fits in i32.
    d.wrapping_add((p(0) + p(8) + p(16) + p(24)) as u32)
}

/// `cv.sdotsp.h`: d + the two signed halfword products (modulo 2^32).
#[inline(always)]
pub fn sdotsp_h(d: u32, a: u32, b: u32) -> u32 {
    let p = |k: u32| ((a >> k) as i16 as i32).wrapping_mul((b >> k) as i16 as i32);
    d.wrapping_add(p(0) as u32).wrapping_add(p(16) as u32)
}

/// `cv.sdotusp.b`: d + unsigned bytes of a times signed bytes of b.
#[inline(always)]
pub fn sdotusp_b(d: u32, a: u32, b: u32) -> u32 {
    let p = |k: u32| ((a >> k) as u8 as i32) * ((b >> k) as i8 as i32);
    d.wrapping_add((p(0) + p(8) + p(16) + p(24)) as u32)
}

/// `cv.sdotup.b`: d + the four unsigned byte products.
#[inline(always)]
pub fn sdotup_b(d: u32, a: u32, b: u32) -> u32 {
    let p = |k: u32| ((a >> k) & 0xff) * ((b >> k) & 0xff);
    d.wrapping_add(p(0) + p(8) + p(16) + p(24))
}

/// The dot products: (a signed, b signed) per function, accumulated for
/// the `sdot` forms; modulo 2^32.
fn dot(f: u32, w: u32, a: u32, b: u32, d: u32) -> u32 {
    let (sa, sb) = match f {
        DOTUP | SDOTUP => (false, false),
        DOTUSP | SDOTUSP => (false, true),
        _ => (true, true),
    };
    let ext = |v: u32, s: bool| if s { sext(v, w) as i64 } else { v as i64 };
    let sum: i64 = (0..32 / w)
        .map(|i| ext(lane(a, i, w), sa) * ext(lane(b, i, w), sb))
        .sum();
    let acc = if f >= SDOTUP { d } else { 0 };
    acc.wrapping_add(sum as u32)
}

/// One lane of the binary ALU and comparison functions.
#[inline(always)]
fn lane_op(f: u32, w: u32, x: u32, y: u32) -> u32 {
    let (sx_, sy) = (sext(x, w), sext(y, w));
    let mask = (1u32 << w) - 1;
    let sh = y & (w - 1);
    let all = |c: bool| if c { mask } else { 0 };
    match f {
        ADD => x.wrapping_add(y),
        SUB => x.wrapping_sub(y),
        // The lane sum (carry lost), then shifted by one.
        AVG => (sext(x.wrapping_add(y) & mask, w) >> 1) as u32,
        AVGU => (x.wrapping_add(y) & mask) >> 1,
        MIN => sx_.min(sy) as u32,
        MINU => x.min(y),
        MAX => sx_.max(sy) as u32,
        MAXU => x.max(y),
        SRL => x >> sh,
        SRA => (sx_ >> sh) as u32,
        SLL => x << sh,
        OR => x | y,
        XOR => x ^ y,
        AND => x & y,
        CMPEQ => all(x == y),
        CMPNE => all(x != y),
        CMPGT => all(sx_ > sy),
        CMPGE => all(sx_ >= sy),
        CMPLT => all(sx_ < sy),
        CMPLE => all(sx_ <= sy),
        CMPGTU => all(x > y),
        CMPGEU => all(x >= y),
        CMPLTU => all(x < y),
        _ => all(x <= y), // CMPLEU
    }
}

/// Execute a SIMD instruction: `a` = rs1, `b` = rs2, `d` = rd.
pub fn exec(imm: u32, a: u32, b: u32, d: u32) -> u32 {
    let f = (imm >> 16) & 63;
    let funct1 = (imm >> 11) & 1;
    let f3 = (imm >> 8) & 7;
    let imm6 = imm & 63;
    let w = if f3 & 1 == 1 { 8 } else { 16 };
    if binary(f) {
        let op2 = match f3 >> 1 {
            0 => b,
            2 => splat(b, w),
            _ if unsigned_imm(f) => splat(imm6, w),
            _ => splat(sext(imm6, 6) as u32, w),
        };
        return if (DOTUP..=SDOTSP).contains(&f) {
            dot(f, w, a, op2, d)
        } else {
            map(a, op2, w, |x, y| lane_op(f, w, x, y))
        };
    }
    let h = |v: u32, i: u32| lane(v, i, 16);
    // An arithmetic shift of a 16-bit lane.
    let sh16 = |v: u32, s: u32| ((sext(v & 0xffff, 16) >> s) as u32) & 0xffff;
    match f {
        ABS => map(a, 0, w, |x, _| sext(x, w).wrapping_abs() as u32),
        EXTRACT => {
            let i = imm6;
            match f3 {
                0 | 1 => sext(lane(a, i, w), w) as u32,
                2 | 3 => lane(a, i, w),
                _ => {
                    let m = ((1u32 << w) - 1) << (i * w);
                    (d & !m) | ((a << (i * w)) & m)
                }
            }
        }
        SHUFFLE..=SHUFFLEI3 => match f3 {
            0 => map(b, 0, 16, |s, _| h(a, s & 1)),
            1 => map(b, 0, 8, |s, _| lane(a, s & 3, 8)),
            6 => h(a, imm6 & 1) | h(a, (imm6 >> 1) & 1) << 16,
            _ => {
                // Lane 3's selector is the function's low bits
                // (shufflei0..3), lanes 0..2 come from Imm6.
                let sel = (f - SHUFFLE) << 6 | imm6;
                (0..4).fold(0, |acc, i| {
                    acc | lane(a, (sel >> (2 * i)) & 3, 8) << (8 * i)
                })
            }
        },
        SHUFFLE2 => {
            let (src_bit, idx) = if w == 16 { (2, 1) } else { (4, 3) };
            (0..32 / w).fold(0, |acc, i| {
                let s = lane(b, i, w);
                let src = if s & src_bit != 0 { a } else { d };
                acc | lane(src, s & idx, w) << (i * w)
            })
        }
        PACK => {
            if funct1 == 0 {
                (a & 0xffff) << 16 | (b & 0xffff)
            } else {
                (a & 0xffff_0000) | b >> 16
            }
        }
        PACK_B => {
            if funct1 == 1 {
                (a & 0xff) << 24 | (b & 0xff) << 16 | (d & 0xffff)
            } else {
                (d & 0xffff_0000) | (a & 0xff) << 8 | (b & 0xff)
            }
        }
        CPLXMUL => {
            let s = 15 + (f3 >> 1);
            let (a0, a1) = (sext(h(a, 0), 16) as i64, sext(h(a, 1), 16) as i64);
            let (b0, b1) = (sext(h(b, 0), 16) as i64, sext(h(b, 1), 16) as i64);
            if funct1 == 0 {
                let re = ((a0 * b0 - a1 * b1) >> s) as u32 & 0xffff;
                (d & 0xffff_0000) | re
            } else {
                let im = ((a0 * b1 + a1 * b0) >> s) as u32 & 0xffff;
                im << 16 | (d & 0xffff)
            }
        }
        CPLXCONJ => (a & 0xffff) | (h(a, 1).wrapping_neg() & 0xffff) << 16,
        SUBROTMJ => {
            let s = f3 >> 1;
            let im = sh16(h(b, 0).wrapping_sub(h(a, 0)), s);
            let re = sh16(h(a, 1).wrapping_sub(h(b, 1)), s);
            im << 16 | re
        }
        ADD_DIV => map(a, b, 16, |x, y| sh16(x.wrapping_add(y), f3 >> 1)),
        SUB_DIV => map(a, b, 16, |x, y| sh16(x.wrapping_sub(y), f3 >> 1)),
        _ => unreachable!("not a SIMD function: {f}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `imm` of function `f` with funct3 `f3`, funct1 and Imm6.
    fn imm(f: u32, f3: u32, funct1: u32, imm6: u32) -> u32 {
        f << 16 | funct1 << 11 | f3 << 8 | imm6
    }

    fn bytes(v: [i8; 4]) -> u32 {
        u32::from_le_bytes(v.map(|x| x as u8))
    }

    #[test]
    fn dot_products_at_the_edges() {
        // -128 * -128 four times = 65536.
        let m = bytes([-128; 4]);
        assert_eq!(sdotsp_b(0, m, m), 65536);
        assert_eq!(exec(imm(DOTSP, 1, 0, 0), m, m, 123), 65536);
        // Unsigned bytes: 255 * 255 * 4.
        assert_eq!(sdotup_b(1, u32::MAX, u32::MAX), 4 * 65025 + 1);
        // Unsigned times signed: 255 * -1 * 4.
        assert_eq!(sdotusp_b(0, u32::MAX, u32::MAX), (-1020i32) as u32);
        // Halfwords: 2 * (-32768)^2 = 2^31 wraps to i32::MIN.
        assert_eq!(sdotsp_h(0, 0x8000_8000, 0x8000_8000), 0x8000_0000);
        // The accumulator wraps.
        assert_eq!(
            sdotsp_b(i32::MAX as u32, m, m),
            (i32::MAX as u32).wrapping_add(65536)
        );
        // .sci.b: Imm6 = -1 (sign-extended) replicated.
        assert_eq!(exec(imm(SDOTSP, 7, 1, 0x3f), bytes([1, 2, 3, 4]), 0, 10), 0);
        // .sc.h: rs2's low halfword replicated.
        assert_eq!(exec(imm(DOTUP, 4, 0, 0), 0x0002_0003, 0xdead_0010, 0), 80);
    }

    #[test]
    fn lane_ops() {
        assert_eq!(
            exec(imm(ADD, 0, 0, 0), 0xffff_0001, 0x0001_0001, 0),
            0x0000_0002
        );
        assert_eq!(
            exec(
                imm(AVG, 1, 0, 0),
                bytes([-4, 100, 0, 1]),
                bytes([2, 100, 0, 1]),
                0
            ),
            bytes([-1, -28, 0, 1])
        );
        assert_eq!(exec(imm(SRA, 6, 0, 1 << 1), 0x8000_0010, 0, 0), 0xe000_0004);
        assert_eq!(
            exec(imm(CMPLT, 5, 0, 0), bytes([-1, 5, 0, 7]), 5, 0),
            bytes([-1, 0, -1, 0])
        );
        assert_eq!(exec(imm(MAXU, 7, 1, 0x3f), 0x0040_0001, 0, 0), 0x3f40_3f3f);
        assert_eq!(exec(imm(ABS, 0, 0, 0), 0x8000_ffff, 0, 0), 0x8000_0001);
    }

    #[test]
    fn shuffles_and_packs() {
        let a = 0x4433_2211;
        assert_eq!(exec(imm(SHUFFLE, 1, 0, 0), a, 0x0001_0203, 0), 0x1122_3344);
        assert_eq!(exec(imm(SHUFFLE, 6, 0, 0b01), a, 0, 0), 0x2211_4433);
        // shufflei2.sci.b: lane 3 = a[2]; lanes 2..0 = a[0], a[1], a[3].
        assert_eq!(exec(imm(26, 7, 1, 0b00_01_11), a, 0, 0), 0x3311_2244);
        assert_eq!(
            exec(
                imm(SHUFFLE2, 0, 0, 0),
                0xaaaa_bbbb,
                0x0002_0001,
                0xcccc_dddd
            ),
            0xbbbb_cccc
        );
        assert_eq!(
            exec(imm(PACK, 0, 1, 0), 0x1234_5678, 0x9abc_def0, 0),
            0x1234_9abc
        );
        assert_eq!(
            exec(imm(PACK_B, 1, 1, 0), 0x11, 0x22, 0x3333_4444),
            0x1122_4444
        );
        assert_eq!(exec(imm(EXTRACT, 1, 0, 3), 0x80ff_ffff, 0, 0), 0xffff_ff80);
        assert_eq!(
            exec(imm(EXTRACT, 5, 0, 2), 0xab, 0, 0xffff_ffff),
            0xffab_ffff
        );
    }

    #[test]
    fn complex_numbers() {
        // (0.5 + 0.5j)(0.5 - 0.5j) = 0.5 in Q15.
        let a = 0x4000_4000;
        let b = 0xc000_4000;
        assert_eq!(exec(imm(CPLXMUL, 0, 0, 0), a, b, 0xffff_0000), 0xffff_4000);
        assert_eq!(exec(imm(CPLXMUL, 0, 1, 0), a, b, 0x0000_1234), 0x0000_1234);
        assert_eq!(exec(imm(CPLXCONJ, 0, 0, 0), 0x0001_0002, 0, 0), 0xffff_0002);
        // (rs1 - rs2) * -j: re = a1 - b1 = 3, im = b0 - a0 = -2, /2.
        assert_eq!(
            exec(imm(SUBROTMJ, 2, 0, 0), 0x0005_0004, 0x0002_0002, 0),
            0xffff_0001
        );
        assert_eq!(
            exec(imm(ADD_DIV, 4, 0, 0), 0x0010_fff0, 0x0010_0000, 0),
            0x0008_fffc
        );
    }

    proptest::proptest! {
        #[test]
        fn dot_products_match_wide_sums(a: u32, b: u32, d: u32) {
            let sb = |v: u32, k: u32| (v >> (8 * k)) as u8 as i8 as i64;
            let ub = |v: u32, k: u32| ((v >> (8 * k)) & 0xff) as i64;
            let sum = |f: &dyn Fn(u32) -> i64| (0..4).map(f).sum::<i64>();
            let s = sum(&|k| sb(a, k) * sb(b, k));
            proptest::prop_assert_eq!(sdotsp_b(d, a, b), (d as i64 + s) as u32);
            proptest::prop_assert_eq!(exec(imm(SDOTSP, 1, 0, 0), a, b, d), (d as i64 + s) as u32);
            let us = sum(&|k| ub(a, k) * sb(b, k));
            proptest::prop_assert_eq!(sdotusp_b(d, a, b), (d as i64 + us) as u32);
            proptest::prop_assert_eq!(exec(imm(SDOTUSP, 1, 0, 0), a, b, d), (d as i64 + us) as u32);
            let uu = sum(&|k| ub(a, k) * ub(b, k));
            proptest::prop_assert_eq!(sdotup_b(d, a, b), (d as i64 + uu) as u32);
            let sh = |v: u32, k: u32| (v >> (16 * k)) as u16 as i16 as i64;
            let hs = (0..2).map(|k| sh(a, k) * sh(b, k)).sum::<i64>();
            proptest::prop_assert_eq!(sdotsp_h(d, a, b), (d as i64 + hs) as u32);
            proptest::prop_assert_eq!(exec(imm(SDOTSP, 0, 0, 0), a, b, d), (d as i64 + hs) as u32);
        }
    }
}
