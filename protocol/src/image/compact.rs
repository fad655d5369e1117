//! The fast path of the pixel-array parser: the compact spelling
//! (`[d,dd,ddd,...]`, digits and commas only — what nlohmann and our encoder
//! write), 64 bytes at a time with SIMD; anything else is left to the
//! general parser in [`super`].

use std::mem::MaybeUninit;

#[cfg(target_arch = "x86_64")]
pub(super) mod avx512;

/// How far the fast path got.
#[derive(Debug, PartialEq)]
pub(super) enum Fast {
    /// The whole array, and the position after `]`.
    Done(Vec<u8>, usize),
    /// The pixels up to a comma that ends a stretch of the compact spelling,
    /// and the position after that comma: the general parser goes on from
    /// there (and decides about the rest).
    Resume(Vec<u8>, usize),
    /// Not even the first pixel was taken: the general parser starts over.
    Restart,
}

/// Bytes per block of the fast path (one bit per byte in a `u64` mask).
pub(super) const BLOCK: usize = 64;
/// Bytes before a block that its window also holds: a number ending at the
/// block's first byte may have started up to 3 bytes earlier.
pub(super) const LOOKBACK: usize = 4;

/// A block and the bytes before it.
pub(super) type Window = [u8; LOOKBACK + BLOCK];

/// The bit masks of a block, bit `i` for byte `i`: what the block loop
/// checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Masks {
    pub(super) comma: u64,
    pub(super) close: u64,
    pub(super) digit: u64,
    pub(super) zero: u64,
    /// Where the number before the byte (see [`Classes::value`]) is above
    /// 255.
    pub(super) big: u64,
}

/// What one block holds, bit `i` / entry `i` for byte `i` of the block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Classes {
    pub(super) masks: Masks,
    /// The number made of the (up to 3) digits right before byte `i`:
    /// `100·h + 10·t + u`, with `100·h` taken as 0 for `h` ≥ 3 (`big` then).
    pub(super) value: [u8; BLOCK],
}

impl Classes {
    /// Nothing found (what the classifiers start from).
    const EMPTY: Classes = Classes {
        masks: Masks {
            comma: 0,
            close: 0,
            digit: 0,
            zero: 0,
            big: 0,
        },
        value: [0; BLOCK],
    };
}

/// SSE2 (part of the x86_64 baseline, so no run-time detection): 16 bytes
/// per step, compares and a `movemask` per class, and the value of the
/// number before every byte from three shifted loads of the window.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn classify(win: &Window) -> Classes {
    use std::arch::x86_64::*;
    let mut c = Classes::EMPTY;
    // 16 window bytes from `at`, as one register.
    let load = |at: usize| {
        let half = |j: usize| {
            i64::from_le_bytes(win[at + 8 * j..at + 8 * j + 8].try_into().expect("8 bytes"))
        };
        // SAFETY: register-only SSE2 intrinsic; SSE2 is x86_64 baseline.
        // (Two 8-byte halves: LLVM makes this one unaligned 16-byte load.)
        unsafe { _mm_set_epi64x(half(1), half(0)) }
    };
    for i in 0..BLOCK / 16 {
        let at = LOOKBACK + 16 * i;
        let (v, v1, v2, v3) = (load(at), load(at - 1), load(at - 2), load(at - 3));
        // SAFETY: SSE2 intrinsics on registers only (no pointers), and SSE2
        // is part of the x86_64 baseline, so always available.
        unsafe {
            let zero = _mm_set1_epi8(b'0' as i8);
            let nine = _mm_set1_epi8(9);
            // Digit value where the byte is a digit, and that mask.
            let digit = |v: __m128i| {
                let d = _mm_sub_epi8(v, zero);
                (d, _mm_cmpeq_epi8(_mm_min_epu8(d, nine), d))
            };
            let (_, is_digit) = digit(v);
            let bits = |m: __m128i| u64::from(_mm_movemask_epi8(m) as u16) << (16 * i);
            c.masks.comma |= bits(_mm_cmpeq_epi8(v, _mm_set1_epi8(b',' as i8)));
            c.masks.close |= bits(_mm_cmpeq_epi8(v, _mm_set1_epi8(b']' as i8)));
            c.masks.digit |= bits(is_digit);
            c.masks.zero |= bits(_mm_cmpeq_epi8(v, zero));
            // Units, tens, hundreds: the digits before, while they last.
            let (d1, m1) = digit(v1);
            let (d2, m2) = digit(v2);
            let (d3, m3) = digit(v3);
            let m2 = _mm_and_si128(m1, m2);
            let m3 = _mm_and_si128(m2, m3);
            let u = _mm_and_si128(d1, m1);
            let t = _mm_and_si128(d2, m2);
            let h = _mm_and_si128(d3, m3);
            let t2 = _mm_add_epi8(t, t);
            let t8 = _mm_add_epi8(_mm_add_epi8(t2, t2), _mm_add_epi8(t2, t2));
            let tu = _mm_add_epi8(_mm_add_epi8(t8, t2), u); // ≤ 99
            let is = |k: i8| _mm_cmpeq_epi8(h, _mm_set1_epi8(k));
            let h100 = _mm_or_si128(
                _mm_and_si128(is(1), _mm_set1_epi8(100)),
                _mm_and_si128(is(2), _mm_set1_epi8(200u8 as i8)),
            );
            let value = _mm_add_epi8(h100, tu);
            // All lanes are ≤ 99 as signed bytes here.
            let big = _mm_or_si128(
                _mm_cmpgt_epi8(h, _mm_set1_epi8(2)),
                _mm_and_si128(is(2), _mm_cmpgt_epi8(tu, _mm_set1_epi8(55))),
            );
            c.masks.big |= bits(big);
            let mut lanes = [0u8; 16];
            _mm_storeu_si128(lanes.as_mut_ptr().cast(), value);
            c.value[16 * i..16 * i + 16].copy_from_slice(&lanes);
        }
    }
    c
}

/// The portable classifier (other targets; also the reference in tests).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
pub(super) fn classify_scalar(win: &Window) -> Classes {
    let mut c = Classes::EMPTY;
    let digit = |b: u8| b.is_ascii_digit().then(|| b - b'0');
    for i in 0..BLOCK {
        let b = win[LOOKBACK + i];
        c.masks.comma |= u64::from(b == b',') << i;
        c.masks.close |= u64::from(b == b']') << i;
        c.masks.digit |= u64::from(b.is_ascii_digit()) << i;
        c.masks.zero |= u64::from(b == b'0') << i;
        let (u, t, h) = match (digit(win[i + 3]), digit(win[i + 2]), digit(win[i + 1])) {
            (Some(u), Some(t), Some(h)) => (u, t, h),
            (Some(u), Some(t), None) => (u, t, 0),
            (Some(u), _, _) => (u, 0, 0),
            _ => (0, 0, 0),
        };
        let tu = 10 * t + u;
        c.value[i] = tu.wrapping_add(match h {
            1 => 100,
            2 => 200,
            _ => 0,
        });
        c.masks.big |= u64::from(h > 2 || (h == 2 && tu > 55)) << i;
    }
    c
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(super) fn classify(win: &Window) -> Classes {
    classify_scalar(win)
}

/// `m` shifted up by `n` (1–3) bits, the previous block's top bits coming in.
#[inline(always)]
fn shifted(m: u64, prev: u64, n: u32) -> u64 {
    (m << n) | (prev >> (64 - n))
}

/// Writes `value[i]` for every set bit `i` of `term`, in order, to
/// `out[..k]` and returns `k` (the popcount). With SSSE3: 8 bytes at a time,
/// a `pshufb` with a table entry per mask byte (no branch per pixel).
#[inline(always)]
fn gather(
    value: &[u8; BLOCK],
    term: u64,
    out: &mut [MaybeUninit<u8>; BLOCK],
    ssse3: bool,
) -> usize {
    #[cfg(target_arch = "x86_64")]
    if ssse3 {
        // SAFETY: `ssse3` is only true in `parse_compact_ssse3`, called
        // once SSSE3 was detected at run time.
        return unsafe { gather_ssse3(value, term, out) };
    }
    let _ = ssse3;
    let mut k = 0;
    let mut w = term;
    while w != 0 {
        let e = w.trailing_zeros() as usize & (BLOCK - 1);
        w &= w - 1;
        out[k & (BLOCK - 1)].write(value[e]); // k < popcount ≤ 64
        k += 1;
    }
    k
}

/// For every byte `m`: the positions of its set bits, in order, then zeros
/// (the `pshufb` indices that pack those bytes of 8 to the front).
#[cfg(target_arch = "x86_64")]
static PACK: [[u8; 8]; 256] = {
    let mut t = [[0u8; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut i, mut k) = (0, 0);
        while i < 8 {
            if m & (1 << i) != 0 {
                t[m][k] = i as u8;
                k += 1;
            }
            i += 1;
        }
        m += 1;
    }
    t
};

/// [`gather`] with SSSE3.
///
/// # Safety
/// The CPU must support SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
unsafe fn gather_ssse3(
    value: &[u8; BLOCK],
    term: u64,
    out: &mut [MaybeUninit<u8>; BLOCK],
) -> usize {
    use std::arch::x86_64::*;
    let mut k = 0;
    for j in 0..BLOCK / 8 {
        let m = (term >> (8 * j)) as u8;
        // SAFETY: the loads read 8 bytes of `value[8j..8j+8]` and of a
        // `PACK` entry, both in bounds; the store writes 8 bytes at
        // `out[k..k+8]`, in bounds as k ≤ 8j (at most 8 per earlier step),
        // so k + 8 ≤ 64. Bytes past the packed ones are scratch, overwritten
        // by later steps or left beyond the returned count.
        unsafe {
            let v = _mm_loadl_epi64(value.as_ptr().add(8 * j).cast());
            let idx = _mm_loadl_epi64(PACK[m as usize].as_ptr().cast());
            _mm_storel_epi64(out.as_mut_ptr().add(k).cast(), _mm_shuffle_epi8(v, idx));
        }
        k += m.count_ones() as usize;
    }
    k
}

/// The fast path, for the compact spelling (`[d,dd,ddd,...]`, digits and
/// commas only — what nlohmann and our encoder write).
///
/// Works in 64-byte blocks. Per block, all with SIMD compares and adds on
/// 16 bytes at a time: the byte classes as bit masks, and before every byte
/// the value of the (up to 3) digits preceding it (three loads of the
/// window shifted by 1, 2 and 3 bytes give units, tens and hundreds). The
/// spelling's rules are then checked on the masks all at once (no empty
/// number, no 4 digits in a row, no leading zero, none above 255, nothing but
/// digits, commas and the final `]`), and the numbers are the values at the
/// terminators, gathered by walking the set bits: about 6 instructions per
/// pixel. A number is stored in the block holding its comma, and everything
/// wrong with it shows by then, so a bad block is dropped whole and the
/// general parser resumes after the last comma of the blocks before.
/// (Measured on the dev box, 320×320 random pixels, CPU time of the whole
/// `decode_reply`: the previous two-numbers-per-8-byte-load SWAR loop
/// 0.57 GB/s, one scalar step per number from the comma mask 0.96 GB/s;
/// this with the bit walk 1.1 GB/s, with SSSE3 `pshufb` packing 8 bytes at a
/// time and the whole loop compiled for SSSE3 1.9 GB/s.)
///
/// With AVX-512 (BW and VBMI2) a block is one register: the classes are
/// compares straight into mask registers and the numbers are packed by one
/// `vpcompressb` ([`avx512`]). `cargo bench -p protocol -- image_array/decode`
/// on the 2026-11-23 host (a Xeon with AVX-512 VBMI2): SSSE3 2.70 GB/s,
/// AVX-512 7.40 GB/s of CPU time.
#[inline(never)] // own register allocation: inlined into the caller it spills
pub(super) fn parse_compact_array(s: &[u8], open: usize) -> Fast {
    #[cfg(target_arch = "x86_64")]
    if avx512::available() {
        // SAFETY: the features it needs were just detected at run time.
        return unsafe { avx512::parse_compact(s, open) };
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("ssse3") && std::arch::is_x86_feature_detected!("popcnt")
    {
        // SAFETY: both features were just detected at run time.
        return unsafe { parse_compact_ssse3(s, open) };
    }
    parse_compact_impl(s, open, false)
}

/// [`parse_compact_array`] compiled with SSSE3 and POPCNT.
///
/// # Safety
/// The CPU must support SSSE3 and POPCNT.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3,popcnt")]
unsafe fn parse_compact_ssse3(s: &[u8], open: usize) -> Fast {
    parse_compact_impl(s, open, true)
}

/// The body of [`parse_compact_array`]; `ssse3` says SSSE3 is available.
#[inline(always)]
pub(super) fn parse_compact_impl(s: &[u8], open: usize, ssse3: bool) -> Fast {
    parse_blocks(
        s,
        open,
        |win| {
            let c = classify(win);
            (c.masks, c.value)
        },
        |value, term, out| gather(value, term, out, ssse3),
    )
}

/// The block loop of the fast path: `classify` gives a block's masks and
/// the value of the number before each byte (in whatever form `gather`
/// takes), `gather` writes the values at the set bits of `term`, in order,
/// to the front of its 64 slots and returns how many.
#[inline(always)]
pub(super) fn parse_blocks<V>(
    s: &[u8],
    open: usize,
    classify: impl Fn(&Window) -> (Masks, V),
    gather: impl Fn(&V, u64, &mut [MaybeUninit<u8>; BLOCK]) -> usize,
) -> Fast {
    // Every pixel takes at least 2 bytes; 64 spare slots for a block's
    // stores (`reserve` below keeps that true for odd inputs).
    let mut out = Vec::with_capacity((s.len() - open) / 2 + BLOCK);
    let mut base = open + 1; // first byte of the block
                             // The previous block's masks (the '[' counts as a terminator).
    let (mut p_term, mut p_digit, mut p_zero) = (1u64 << 63, 0u64, 0u64);
    let mut copy: Window = [0u8; LOOKBACK + BLOCK];
    loop {
        let win: &Window = match s.get(base.wrapping_sub(LOOKBACK)..base + BLOCK) {
            Some(w) if base >= LOOKBACK => w.try_into().expect("window size"),
            _ => {
                // Near either end of `s`: a copy, zeros (not a valid byte
                // in the array) for what is not there.
                for (i, b) in copy.iter_mut().enumerate() {
                    let p = (base + i).wrapping_sub(LOOKBACK);
                    *b = s.get(p).copied().unwrap_or(0);
                }
                &copy
            }
        };
        let (c, value) = classify(win);
        let close = c.close & c.close.wrapping_neg(); // the first ']', if any
        let upto = if close != 0 { close | (close - 1) } else { !0 };
        let term = (c.comma & upto) | close;
        let digit = c.digit & upto;
        let zero = c.zero & upto;
        let bad = (!(c.digit | c.comma | c.close) & upto) // other bytes
            | (term & shifted(term, p_term, 1)) // empty number
            | (digit & shifted(digit, p_digit, 1) & shifted(digit, p_digit, 2)
                & shifted(digit, p_digit, 3)) // 4 digits
            | (digit & shifted(zero, p_zero, 1) & shifted(term, p_term, 2)) // leading 0
            | (term & c.big); // above 255
        let len0 = out.len();
        out.reserve(BLOCK);
        let spare = &mut out.spare_capacity_mut()[..BLOCK];
        // The numbers, in order: the value before each terminator.
        let k = gather(&value, term, spare.try_into().expect("64 slots"));
        if bad != 0 {
            return if len0 == 0 {
                Fast::Restart
            } else {
                // Resume after the previous block's last comma.
                let last = 63 - p_term.leading_zeros() as usize;
                Fast::Resume(out, base - BLOCK + last + 1)
            };
        }
        // SAFETY: `gather` initialised spare[..k], the k slots after len0
        // (k ≤ 64 ≤ the spare capacity reserved).
        unsafe { out.set_len(len0 + k) };
        if close != 0 {
            return Fast::Done(out, base + close.trailing_zeros() as usize + 1);
        }
        (p_term, p_digit, p_zero) = (term, digit, zero);
        base += BLOCK;
    }
}
