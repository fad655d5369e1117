//! The fast path's block with AVX-512: the 64 bytes of a block are one
//! register, each byte class is one compare into a mask register (the `u64`
//! masks the block loop checks, with no `movemask` per 16 bytes), and the
//! numbers are packed to the front by one `vpcompressb` (VBMI2) instead of
//! eight `pshufb` steps with a table.
//!
//! The arithmetic is the SSE2 classifier's, lane for lane (the value of the
//! up to 3 digits before each byte from loads shifted by 1, 2 and 3 bytes),
//! so both give the same [`Masks`] and values (checked in the tests of
//! [`super::super`]).

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use super::{parse_blocks, Fast, Masks, Window, BLOCK, LOOKBACK};

/// Whether this CPU has what [`parse_compact`] needs (cached by `std`).
pub(in crate::image) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512vbmi2")
        && std::arch::is_x86_feature_detected!("popcnt")
}

/// [`super::parse_compact_array`] with AVX-512 blocks.
///
/// # Safety
/// The CPU must have the features of [`available`].
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi2,popcnt")]
pub(in crate::image) unsafe fn parse_compact(s: &[u8], open: usize) -> Fast {
    // Closures inherit this function's target features, so both calls
    // are inlined into the loop.
    parse_blocks(
        s,
        open,
        |win| classify(win),
        |value, term, out| compress(*value, term, out),
    )
}

/// The masks of a block and, per byte, the value of the number before it
/// (as [`super::classify`]).
#[target_feature(enable = "avx512f,avx512bw")]
#[inline]
pub(in crate::image) fn classify(win: &Window) -> (Masks, __m512i) {
    // 64 window bytes from `at` (LOOKBACK − 3 ≤ at ≤ LOOKBACK).
    let load = |at: usize| {
        let bytes: &[u8; BLOCK] = win[at..at + BLOCK].try_into().expect("64 bytes");
        // SAFETY: reads the 64 bytes of `bytes` (unaligned load).
        unsafe { _mm512_loadu_si512(bytes.as_ptr().cast()) }
    };
    let (v, v1, v2, v3) = (
        load(LOOKBACK),
        load(LOOKBACK - 1),
        load(LOOKBACK - 2),
        load(LOOKBACK - 3),
    );
    let zero = _mm512_set1_epi8(b'0' as i8);
    let ten = _mm512_set1_epi8(10);
    // Digit value (garbage elsewhere) and where the byte is a digit.
    let digit = |v: __m512i| {
        let d = _mm512_sub_epi8(v, zero);
        (d, _mm512_cmplt_epu8_mask(d, ten))
    };
    let (_, is_digit) = digit(v);
    // Units, tens, hundreds: the digits before, while they last.
    let (d1, m1) = digit(v1);
    let (d2, m2) = digit(v2);
    let (d3, m3) = digit(v3);
    let m2 = m1 & m2;
    let m3 = m2 & m3;
    let u = _mm512_maskz_mov_epi8(m1, d1);
    let t = _mm512_maskz_mov_epi8(m2, d2);
    let h = _mm512_maskz_mov_epi8(m3, d3);
    let t2 = _mm512_add_epi8(t, t);
    let t8 = _mm512_add_epi8(_mm512_add_epi8(t2, t2), _mm512_add_epi8(t2, t2));
    let tu = _mm512_add_epi8(_mm512_add_epi8(t8, t2), u); // ≤ 99
    let h1 = _mm512_cmpeq_epi8_mask(h, _mm512_set1_epi8(1));
    let h2 = _mm512_cmpeq_epi8_mask(h, _mm512_set1_epi8(2));
    let h100 = _mm512_mask_mov_epi8(
        _mm512_maskz_mov_epi8(h1, _mm512_set1_epi8(100)),
        h2,
        _mm512_set1_epi8(200u8 as i8),
    );
    let value = _mm512_add_epi8(h100, tu);
    let big = _mm512_cmpgt_epu8_mask(h, _mm512_set1_epi8(2))
        | (h2 & _mm512_cmpgt_epu8_mask(tu, _mm512_set1_epi8(55)));
    let masks = Masks {
        comma: _mm512_cmpeq_epi8_mask(v, _mm512_set1_epi8(b',' as i8)),
        close: _mm512_cmpeq_epi8_mask(v, _mm512_set1_epi8(b']' as i8)),
        digit: is_digit,
        zero: _mm512_cmpeq_epi8_mask(v, zero),
        big,
    };
    (masks, value)
}

/// Writes the bytes of `value` at the set bits of `term`, in order, to the
/// front of `out` and returns how many (the rest of `out` is scratch).
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi2,popcnt")]
#[inline]
pub(in crate::image) fn compress(
    value: __m512i,
    term: u64,
    out: &mut [MaybeUninit<u8>; BLOCK],
) -> usize {
    let packed = _mm512_maskz_compress_epi8(term, value);
    // SAFETY: writes the 64 bytes of `out` (unaligned store).
    unsafe { _mm512_storeu_si512(out.as_mut_ptr().cast(), packed) };
    term.count_ones() as usize
}

/// The value lanes as bytes (for the tests).
#[cfg(test)]
#[target_feature(enable = "avx512f")]
pub(in crate::image) fn to_bytes(v: __m512i) -> [u8; BLOCK] {
    let mut b = [0u8; BLOCK];
    // SAFETY: writes the 64 bytes of `b`.
    unsafe { _mm512_storeu_si512(b.as_mut_ptr().cast(), v) };
    b
}
