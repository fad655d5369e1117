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
}

impl ImageEncoding {
    pub fn as_str(self) -> &'static str {
        match self {
            ImageEncoding::Array => "array",
            ImageEncoding::Base64 => "base64",
        }
    }
}

impl std::str::FromStr for ImageEncoding {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "array" => Ok(ImageEncoding::Array),
            "base64" => Ok(ImageEncoding::Base64),
            _ => Err(format!("unknown image encoding {s:?} (array|base64)")),
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
        ImageEncoding::Array => write_pixel_array(out, data),
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
        Some(done) => Ok(done),
        None => parse_any_array(s, pos),
    }
}

/// The fast path, for the compact spelling (`[d,dd,ddd,...]`, digits and
/// commas only — what nlohmann and our encoder write). `None` means "not
/// that spelling, or invalid": the general parser then decides and names
/// the problem.
///
/// Each step loads 8 bytes and takes two numbers out of them at once
/// ("ddd,ddd," fits in 8 bytes), branch-free in the numbers' lengths: with
/// random pixel values a per-digit branch would mispredict about every
/// other pixel. (Measured alternatives on the dev box, 320×320 random
/// pixels: per-digit branches 0.31 GB/s, one number per load 0.54 GB/s,
/// two per load 0.66 GB/s; interleaving several cursors was slower.)
#[inline(never)] // own register allocation: inlined into the caller it spills
fn parse_compact_array(s: &[u8], open: usize) -> Option<(Vec<u8>, usize)> {
    let start = open + 1;
    let close = start + memchr::memchr(b']', &s[start..])?;
    let body = &s[start..close];
    // Only digits and commas? (Branch-free fold: vectorises.)
    let odd = body.iter().fold(0u8, |acc, &b| {
        acc | u8::from((b.wrapping_sub(b'0') > 9) & (b != b','))
    });
    // The 8-byte loads need 8 readable bytes from any number's start; the
    // frame goes on after ']' (at least `,"height":…}}`), and an image too
    // small for that does not need this path.
    if odd != 0 || body.is_empty() || close + 8 > s.len() {
        return None;
    }
    let mut out = Vec::with_capacity(body.len() / 2 + 1);
    let mut bad = false;
    let mut p = start;
    // Two numbers per load while the window cannot reach past ']'.
    while p + 8 <= close {
        let (v1, v2, adv, ok) = swar_two_numbers(s, p);
        bad |= !ok;
        out.push(v1);
        out.push(v2);
        p += adv;
    }
    // The last few, one at a time.
    while p <= close {
        let (v, n, ok) = swar_number(s, p);
        bad |= !ok;
        out.push(v);
        p += n + 1;
    }
    // The last number must end exactly at ']'.
    if bad || p != close + 1 {
        return None;
    }
    Some((out, close + 1))
}

const LANES: u64 = 0x0101_0101_0101_0101;

/// The 8 bytes at `pos` as digit lanes (0–9 where the byte is an ASCII
/// digit) and a mask with the high bit of every non-digit lane set.
#[inline(always)]
fn digit_lanes(s: &[u8], pos: usize) -> (u64, u64) {
    let w = u64::from_le_bytes(s[pos..pos + 8].try_into().expect("8 bytes"));
    let x = w ^ (0x30 * LANES);
    // Lane ≥ 10 ⇔ high bit after adding 0x76 to its low 7 bits (no carry
    // crosses lanes) or its own high bit set.
    let non_digit = (((x & (0x7F * LANES)) + (0x76 * LANES)) | x) & (0x80 * LANES);
    (x, non_digit)
}

/// The number made of the first `n` digit lanes of `x`, and whether it is a
/// valid pixel: 1–3 digits, no leading zero, ≤ 255. Branch-free.
#[inline(always)]
fn lanes_value(x: u64, n: usize) -> (u8, bool) {
    let nn = n.clamp(1, 3);
    // Right-align the digits in 3 lanes, most significant first.
    let a = (x << (8 * (3 - nn))) & 0xFF_FFFF;
    let v = (a & 0xFF) * 100 + ((a >> 8) & 0xFF) * 10 + (a >> 16);
    let ok = (n.wrapping_sub(1) < 3) & ((n == 1) | (x & 0xFF != 0)) & (v <= 255);
    (v as u8, ok)
}

/// One number at `pos` (8 readable bytes guaranteed by the caller): value,
/// digit count (the caller advances by count + 1, so even a bad "number"
/// moves the cursor) and validity.
#[inline(always)]
fn swar_number(s: &[u8], pos: usize) -> (u8, usize, bool) {
    let (x, non_digit) = digit_lanes(s, pos);
    let n = (non_digit.trailing_zeros() / 8) as usize;
    let (v, ok) = lanes_value(x, n);
    (v, n, ok)
}

/// Two numbers at `pos`: "ddd,ddd," is at most 8 bytes, so one load holds
/// both. Returns both values, the advance past the second comma, and
/// validity (both numbers valid, each followed by a comma).
#[inline(always)]
fn swar_two_numbers(s: &[u8], pos: usize) -> (u8, u8, usize, bool) {
    let (x, non_digit) = digit_lanes(s, pos);
    let n1 = (non_digit.trailing_zeros() / 8) as usize;
    let second = non_digit & non_digit.wrapping_sub(1);
    let end2 = (second.trailing_zeros() / 8) as usize; // 8 if absent
    let (v1, ok1) = lanes_value(x, n1);
    let (v2, ok2) = lanes_value(
        x.wrapping_shr(8 * (n1 as u32 + 1)),
        end2.wrapping_sub(n1 + 1),
    );
    // Only digits and commas reach here, so a non-digit lane is a comma.
    (v1, v2, end2 + 1, ok1 & ok2 & (end2 < 8))
}

/// The general parser: any valid JSON spelling of the array, precise errors.
fn parse_any_array(s: &[u8], mut pos: usize) -> Result<(Vec<u8>, usize), PixelError> {
    let mut out = Vec::new();
    let at = |i: usize| -> u8 { s.get(i).copied().unwrap_or(0) };
    pos = skip_ws(s, pos + 1);
    if at(pos) == b']' {
        return Ok((out, pos + 1));
    }
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
