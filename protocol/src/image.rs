//! The camera image and its two wire spellings.
//!
//! The thesis sends `"data"` as a JSON array of 0–255 numbers (nlohmann
//! serialises a `std::vector<unsigned char>` that way); base64 is our
//! negotiated alternative (about 2.8× smaller). A 320×320 image is ~380 KB of
//! JSON and a 32 ms race sends ~4,200 of them, so both directions have
//! hand-written fast paths here instead of going through serde_json (which
//! would build or visit one value per pixel): a lookup table of the 256
//! decimal spellings for encoding and a byte-level digit parser for decoding.
//! The parser accepts every valid JSON spelling of the array (any whitespace,
//! `1.0e2`-style numbers with an integral value) and rejects everything else.

use std::mem::MaybeUninit;
use std::sync::OnceLock;

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine as _;
use serde::{Deserialize, Serialize};

/// A grey camera frame, row-major, one byte per pixel.
#[derive(Clone, PartialEq, Eq, Default)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
}

impl std::fmt::Debug for Image {
    // 102,400 numbers in a test failure message help nobody.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Image")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("data.len", &self.data.len())
            .finish()
    }
}

/// How `"data"` of a `GET_IMAGE` reply is spelled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageEncoding {
    /// `[0,255,...]` — the thesis's format and the default.
    #[default]
    Array,
    /// `"AAD/..."` (standard alphabet, padded) plus `"encoding":"base64"`.
    Base64,
    /// The pixels in a shared-memory file, the reply naming it
    /// ([`crate::shm`]): for a platform and a world on one host.
    Shm,
}

impl ImageEncoding {
    pub fn as_str(self) -> &'static str {
        match self {
            ImageEncoding::Array => "array",
            ImageEncoding::Base64 => "base64",
            ImageEncoding::Shm => "shm",
        }
    }
}

impl std::str::FromStr for ImageEncoding {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "array" => Ok(ImageEncoding::Array),
            "base64" => Ok(ImageEncoding::Base64),
            "shm" => Ok(ImageEncoding::Shm),
            _ => Err(format!("unknown image encoding {s:?} (array|base64|shm)")),
        }
    }
}

impl std::fmt::Display for ImageEncoding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Standard alphabet; padding written, and accepted present or absent (a
/// foreign world may strip it).
fn b64() -> &'static GeneralPurpose {
    static E: OnceLock<GeneralPurpose> = OnceLock::new();
    E.get_or_init(|| {
        GeneralPurpose::new(
            &base64::alphabet::STANDARD,
            GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
        )
    })
}

/// Entry `v`: the decimal spelling of `v` followed by a comma, left-aligned in
/// 4 bytes, and its length. Copying all 4 bytes and advancing by the length
/// makes the encoder branch-free per pixel.
const SPELLINGS: [([u8; 4], u8); 256] = {
    let mut t = [([0u8; 4], 0u8); 256];
    let mut v = 0;
    while v < 256 {
        let (h, d, u) = ((v / 100) as u8, ((v / 10) % 10) as u8, (v % 10) as u8);
        t[v] = if v >= 100 {
            ([b'0' + h, b'0' + d, b'0' + u, b','], 4)
        } else if v >= 10 {
            ([b'0' + d, b'0' + u, b',', 0], 3)
        } else {
            ([b'0' + u, b',', 0, 0], 2)
        };
        v += 1;
    }
    t
};

/// Appends the `"data"` value: `[..]` or a quoted base64 string.
pub(crate) fn write_image_data(out: &mut Vec<u8>, data: &[u8], encoding: ImageEncoding) {
    match encoding {
        // A frame in shared memory is written by the connection that owns
        // the file ([`crate::shm::ShmWriter`]); a pure encoder given an image
        // falls back to the thesis's array, which every platform decodes.
        ImageEncoding::Array | ImageEncoding::Shm => write_pixel_array(out, data),
        ImageEncoding::Base64 => {
            out.push(b'"');
            let start = out.len();
            let n = base64::encoded_len(data.len(), true).expect("image size fits in usize");
            out.resize(start + n, 0);
            let written = b64()
                .encode_slice(data, &mut out[start..])
                .expect("buffer sized by encoded_len");
            debug_assert_eq!(written, n);
            out.push(b'"');
        }
    }
}

fn write_pixel_array(out: &mut Vec<u8>, data: &[u8]) {
    out.push(b'[');
    if data.is_empty() {
        out.push(b']');
        return;
    }
    let start = out.len();
    // Worst case 4 bytes per pixel ("255,"); the extra 4 let the last
    // unconditional 4-byte copy stay in bounds.
    out.resize(start + 4 * data.len() + 4, 0);
    let buf = &mut out[start..];
    let mut pos = 0;
    for &p in data {
        let (bytes, len) = SPELLINGS[p as usize];
        buf[pos..pos + 4].copy_from_slice(&bytes);
        pos += len as usize;
    }
    // Replace the trailing comma by the closing bracket.
    buf[pos - 1] = b']';
    out.truncate(start + pos);
}

/// Why a pixel array or base64 string was refused (becomes a
/// `ProtocolError::BadField` for `GET_IMAGE`).
pub(crate) type PixelError = String;

/// Parses a JSON array of integers 0–255 starting at `s[pos] == b'['`.
/// Returns the pixels and the position after `]`.
pub(crate) fn parse_pixel_array(s: &[u8], pos: usize) -> Result<(Vec<u8>, usize), PixelError> {
    debug_assert_eq!(s[pos], b'[');
    match parse_compact_array(s, pos) {
        Fast::Done(out, end) => Ok((out, end)),
        Fast::Resume(out, after_comma) => parse_rest(s, skip_ws(s, after_comma), out),
        Fast::Restart => parse_any_array(s, pos),
    }
}

/// How far the fast path got.
#[derive(Debug, PartialEq)]
enum Fast {
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
const BLOCK: usize = 64;
/// Bytes before a block that its window also holds: a number ending at the
/// block's first byte may have started up to 3 bytes earlier.
const LOOKBACK: usize = 4;

/// What one block holds, bit `i` / entry `i` for byte `i` of the block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Classes {
    comma: u64,
    close: u64,
    digit: u64,
    zero: u64,
    /// The number made of the (up to 3) digits right before byte `i`:
    /// `100·h + 10·t + u`, with `100·h` taken as 0 for `h` ≥ 3 (`big` then).
    value: [u8; BLOCK],
    /// Where that number is above 255.
    big: u64,
}

/// SSE2 (part of the x86_64 baseline, so no run-time detection): 16 bytes
/// per step, compares and a `movemask` per class, and the value of the
/// number before every byte from three shifted loads of the window.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn classify(win: &[u8; LOOKBACK + BLOCK]) -> Classes {
    use std::arch::x86_64::*;
    let mut c = Classes {
        comma: 0,
        close: 0,
        digit: 0,
        zero: 0,
        value: [0; BLOCK],
        big: 0,
    };
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
            c.comma |= bits(_mm_cmpeq_epi8(v, _mm_set1_epi8(b',' as i8)));
            c.close |= bits(_mm_cmpeq_epi8(v, _mm_set1_epi8(b']' as i8)));
            c.digit |= bits(is_digit);
            c.zero |= bits(_mm_cmpeq_epi8(v, zero));
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
            c.big |= bits(big);
            let mut lanes = [0u8; 16];
            _mm_storeu_si128(lanes.as_mut_ptr().cast(), value);
            c.value[16 * i..16 * i + 16].copy_from_slice(&lanes);
        }
    }
    c
}

/// The portable classifier (other targets; also the reference in tests).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn classify_scalar(win: &[u8; LOOKBACK + BLOCK]) -> Classes {
    let mut c = Classes {
        comma: 0,
        close: 0,
        digit: 0,
        zero: 0,
        value: [0; BLOCK],
        big: 0,
    };
    let digit = |b: u8| b.is_ascii_digit().then(|| b - b'0');
    for i in 0..BLOCK {
        let b = win[LOOKBACK + i];
        c.comma |= u64::from(b == b',') << i;
        c.close |= u64::from(b == b']') << i;
        c.digit |= u64::from(b.is_ascii_digit()) << i;
        c.zero |= u64::from(b == b'0') << i;
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
        c.big |= u64::from(h > 2 || (h == 2 && tu > 55)) << i;
    }
    c
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn classify(win: &[u8; LOOKBACK + BLOCK]) -> Classes {
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
#[inline(never)] // own register allocation: inlined into the caller it spills
fn parse_compact_array(s: &[u8], open: usize) -> Fast {
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
fn parse_compact_impl(s: &[u8], open: usize, ssse3: bool) -> Fast {
    // Every pixel takes at least 2 bytes; 64 spare slots for a block's
    // stores (`reserve` below keeps that true for odd inputs).
    let mut out = Vec::with_capacity((s.len() - open) / 2 + BLOCK);
    let mut base = open + 1; // first byte of the block
                             // The previous block's masks (the '[' counts as a terminator).
    let (mut p_term, mut p_digit, mut p_zero) = (1u64 << 63, 0u64, 0u64);
    let mut copy = [0u8; LOOKBACK + BLOCK];
    loop {
        let win: &[u8; LOOKBACK + BLOCK] = match s.get(base.wrapping_sub(LOOKBACK)..base + BLOCK) {
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
        let c = classify(win);
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
        let k = gather(&c.value, term, spare.try_into().expect("64 slots"), ssse3);
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

/// The general parser: any valid JSON spelling of the array, precise errors.
fn parse_any_array(s: &[u8], pos: usize) -> Result<(Vec<u8>, usize), PixelError> {
    let pos = skip_ws(s, pos + 1);
    if s.get(pos) == Some(&b']') {
        return Ok((Vec::new(), pos + 1));
    }
    parse_rest(s, pos, Vec::new())
}

/// The general parser from a pixel's first byte at `pos`, `out` holding the
/// pixels before it.
fn parse_rest(s: &[u8], mut pos: usize, mut out: Vec<u8>) -> Result<(Vec<u8>, usize), PixelError> {
    let at = |i: usize| -> u8 { s.get(i).copied().unwrap_or(0) };
    loop {
        let (v, end) = parse_general_number(s, pos)?;
        if v > 255 {
            return Err(format!("pixel {} is {v}, above 255", out.len()));
        }
        out.push(v as u8);
        pos = skip_ws(s, end);
        match at(pos) {
            b',' => pos = skip_ws(s, pos + 1),
            b']' => return Ok((out, pos + 1)),
            _ => {
                return Err(format!(
                    "expected ',' or ']' after pixel {} at byte {pos}",
                    out.len() - 1
                ))
            }
        }
    }
}

/// Any JSON number (RFC 8259 grammar, checked here) whose value is an integer
/// 0–255, e.g. `7`, `7.0`, `0.7e1`, `-0`. Returns the value (or 256 for "too
/// large") and the end position.
fn parse_general_number(s: &[u8], start: usize) -> Result<(u32, usize), PixelError> {
    let at = |i: usize| -> u8 { s.get(i).copied().unwrap_or(0) };
    let mut p = start;
    if at(p) == b'-' {
        p += 1;
    }
    match at(p) {
        b'0' => p += 1,
        b'1'..=b'9' => {
            while at(p).is_ascii_digit() {
                p += 1
            }
        }
        _ => return Err(format!("not a number at byte {start}")),
    }
    if at(p) == b'.' {
        p += 1;
        if !at(p).is_ascii_digit() {
            return Err(format!("bad number at byte {start}"));
        }
        while at(p).is_ascii_digit() {
            p += 1
        }
    }
    if matches!(at(p), b'e' | b'E') {
        p += 1;
        if matches!(at(p), b'+' | b'-') {
            p += 1;
        }
        if !at(p).is_ascii_digit() {
            return Err(format!("bad number at byte {start}"));
        }
        while at(p).is_ascii_digit() {
            p += 1
        }
    }
    let text = std::str::from_utf8(&s[start..p]).expect("ASCII digits");
    let f: f64 = text
        .parse()
        .map_err(|_| format!("bad number {text:?} at byte {start}"))?;
    if f.fract() != 0.0 || !(0.0..=255.0).contains(&f) {
        return Err(format!("pixel value {text} is not an integer 0–255"));
    }
    Ok((f as u32, p))
}

/// JSON whitespace only (space, tab, LF, CR).
pub(crate) fn skip_ws(s: &[u8], mut pos: usize) -> usize {
    while let Some(b' ' | b'\t' | b'\n' | b'\r') = s.get(pos) {
        pos += 1;
    }
    pos
}

/// Decodes base64 text (already unquoted and unescaped).
pub(crate) fn decode_base64(text: &[u8]) -> Result<Vec<u8>, PixelError> {
    b64()
        .decode(text)
        .map_err(|e| format!("bad base64 image data: {e}"))
}

/// SHA-256 of the pixels as lowercase hex (what traces record instead of the
/// data).
pub fn sha256_hex(data: &[u8]) -> String {
    use sha2::Digest as _;
    hex::encode(sha2::Sha256::digest(data))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arr(text: &str) -> Result<Vec<u8>, PixelError> {
        let s = text.as_bytes();
        let (v, end) = parse_pixel_array(s, 0)?;
        assert_eq!(end, s.len(), "consumed all of {text:?}");
        Ok(v)
    }

    #[test]
    fn table_spells_every_value() {
        for v in 0..=255u8 {
            let mut out = Vec::new();
            write_pixel_array(&mut out, &[v]);
            assert_eq!(String::from_utf8(out).unwrap(), format!("[{v}]"));
        }
    }

    #[test]
    fn array_spellings_accepted() {
        assert_eq!(arr("[]").unwrap(), Vec::<u8>::new());
        assert_eq!(arr("[ ]").unwrap(), Vec::<u8>::new());
        assert_eq!(arr("[0,1,255]").unwrap(), vec![0, 1, 255]);
        assert_eq!(arr("[ 0 ,\n1\t,\r255 ]").unwrap(), vec![0, 1, 255]);
        assert_eq!(
            arr("[7.0,0.7e1,70E-1,-0,2.55e+2]").unwrap(),
            vec![7, 7, 7, 0, 255]
        );
    }

    /// The compact spelling of `data`, `[..]`.
    fn compact(data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        write_pixel_array(&mut out, data);
        out
    }

    /// `text` inside a frame-like tail, as the decoder sees it.
    fn framed(text: &[u8]) -> Vec<u8> {
        let mut s = br#"{"camera":{"data":"#.to_vec();
        s.extend_from_slice(text);
        s.extend_from_slice(br#","height":1,"width":1}}"#);
        s
    }

    /// Both parsers on `s` (array at `open`): the fast-path one must say
    /// exactly what the general one says, values, end and error messages.
    fn same_as_general(s: &[u8], open: usize) -> Result<(Vec<u8>, usize), PixelError> {
        let fast = parse_pixel_array(s, open);
        let general = parse_any_array(s, open);
        assert_eq!(fast, general, "{:?}", String::from_utf8_lossy(s));
        fast
    }

    #[test]
    fn fast_path_takes_compact_arrays_whole() {
        let data: Vec<u8> = (0..=255).cycle().take(5000).collect();
        for open in [0, 1, 5, 18] {
            let mut s = vec![b' '; open];
            s.extend_from_slice(&compact(&data));
            let end = s.len();
            s.extend_from_slice(b",\"x\":1}");
            assert_eq!(parse_compact_array(&s, open), Fast::Done(data.clone(), end));
            // Array at the very end of the buffer.
            s.truncate(end);
            assert_eq!(parse_compact_array(&s, open), Fast::Done(data.clone(), end));
        }
        assert_eq!(parse_compact_array(b"[7]", 0), Fast::Done(vec![7], 3));
        assert_eq!(parse_compact_array(b"[]", 0), Fast::Restart);
    }

    #[test]
    fn fast_path_resumes_after_the_last_good_comma() {
        let data: Vec<u8> = (0..=255).cycle().take(1000).collect();
        let mut s = compact(&data);
        // A space late in the array: the blocks before it stay decoded.
        let at = s.len() - 10;
        let comma = at + s[at..].iter().position(|&b| b == b',').unwrap();
        s.insert(comma + 1, b' ');
        match parse_compact_array(&s, 0) {
            Fast::Resume(out, after) => {
                assert!(out.len() > 900, "{}", out.len());
                assert_eq!(s[after - 1], b',');
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(same_as_general(&s, 0).unwrap().0, data);
    }

    #[test]
    fn gather_paths_agree() {
        let data: Vec<u8> = (0..3000u32).map(|i| (i * 37 % 256) as u8).collect();
        let text = framed(&compact(&data));
        let open = text.iter().position(|&b| b == b'[').expect("[");
        let fast = parse_compact_array(&text, open);
        assert_eq!(parse_compact_impl(&text, open, false), fast);
        let Fast::Done(out, _) = fast else {
            panic!("not taken whole")
        };
        assert_eq!(out, data);
    }

    #[test]
    fn classifiers_agree() {
        let mut win = [0u8; LOOKBACK + BLOCK];
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..5000 {
            for b in win.iter_mut() {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // Mostly the interesting bytes, sometimes anything.
                *b = match x % 8 {
                    0 => (x >> 8) as u8,
                    1 => b',',
                    2 => b']',
                    3 => b'0',
                    _ => b'0' + ((x >> 8) % 10) as u8,
                };
            }
            assert_eq!(classify(&win), classify_scalar(&win), "{win:?}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(512))]

        /// Random compact arrays: the fast path alone decodes them.
        #[test]
        fn prop_compact_roundtrip(data in proptest::collection::vec(proptest::num::u8::ANY, 1..700)) {
            let s = framed(&compact(&data));
            let open = s.iter().position(|&b| b == b'[').unwrap();
            let end = open + compact(&data).len();
            proptest::prop_assert_eq!(parse_compact_array(&s, open), Fast::Done(data.clone(), end));
            proptest::prop_assert_eq!(same_as_general(&s, open).unwrap(), (data, end));
        }

        /// Random whitespace after random commas: same pixels.
        #[test]
        fn prop_spaced_arrays(
            data in proptest::collection::vec(proptest::num::u8::ANY, 1..400),
            spaces in proptest::collection::vec((proptest::num::usize::ANY, 0usize..4, 1usize..3), 0..6),
        ) {
            let text = String::from_utf8(compact(&data)).unwrap();
            let mut parts: Vec<String> = text.split(',').map(str::to_owned).collect();
            for (i, kind, n) in spaces {
                let i = i % parts.len();
                let ws = [" ", "\n", "\t", "\r\n"][kind].repeat(n);
                // Before or after the number (JSON allows both), inside
                // the brackets.
                let part = &mut parts[i];
                let at = match (i.is_multiple_of(2), part.strip_suffix(']')) {
                    (true, Some(num)) => num.len(),
                    (true, None) => part.len(),
                    (false, _) => usize::from(part.starts_with('[')),
                };
                part.insert_str(at, &ws);
            }
            let spaced = parts.join(",");
            let s = framed(spaced.as_bytes());
            let open = s.iter().position(|&b| b == b'[').unwrap();
            let (got, end) = same_as_general(&s, open).unwrap();
            proptest::prop_assert_eq!(got, data);
            proptest::prop_assert_eq!(end, open + spaced.len());
        }

        /// Random corruptions of a compact array: the same answer as the
        /// general parser (values or error message), and valid exactly when
        /// serde_json reads an array of integers 0–255.
        #[test]
        fn prop_corrupted_arrays(
            data in proptest::collection::vec(proptest::num::u8::ANY, 0..300),
            edits in proptest::collection::vec((proptest::num::usize::ANY, 0usize..4, proptest::sample::select(
                b",]0123456789 .e-+x[\"\x80".to_vec())), 1..4),
            bare in proptest::bool::ANY,
        ) {
            let mut text = compact(&data);
            for (i, op, b) in edits {
                let i = i % text.len();
                match op {
                    0 => text[i] = b,
                    1 => text.insert(i, b),
                    2 if text.len() > 1 && i > 0 => { text.remove(i); }
                    _ => text.insert(i, b'0'), // leading zeros, long numbers
                }
            }
            text[0] = b'[';
            let s = if bare { text.clone() } else { framed(&text) };
            let open = if bare { 0 } else { s.iter().position(|&b| b == b'[').unwrap() };
            let got = same_as_general(&s, open);
            // serde_json on the array alone (up to our end, if any).
            let reference = serde_json::Deserializer::from_slice(&s[open..])
                .into_iter::<serde_json::Value>()
                .next()
                .and_then(Result::ok)
                .and_then(|v| match v {
                    serde_json::Value::Array(items) => items
                        .iter()
                        .map(|v| v.as_f64().filter(|f| f.fract() == 0.0 && (0.0..=255.0).contains(f)).map(|f| f as u8))
                        .collect::<Option<Vec<u8>>>(),
                    _ => None,
                });
            proptest::prop_assert_eq!(got.ok().map(|(v, _)| v), reference);
        }
    }

    #[test]
    fn array_invalid_rejected() {
        for bad in [
            "[256]", "[1000]", "[-1]", "[01]", "[1.5]", "[1,]", "[,1]", "[1 2]", "[1", "[1,",
            "[\"1\"]", "[1.]", "[1e]", "[+1]", "[null]", "[1;2]", "[0x10]", "[2.56e2]",
        ] {
            assert!(arr(bad).is_err(), "{bad} must be rejected");
        }
    }
}
