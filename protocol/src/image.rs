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

mod compact;

use compact::{parse_compact_array, Fast};

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
    use super::compact::*;
    use super::*;

    /// Every compiled path of the fast parser on this CPU: portable,
    /// SSSE3, AVX-512 (the last two where the CPU has them).
    fn fast_paths(s: &[u8], open: usize) -> Vec<(&'static str, Fast)> {
        let mut paths = vec![("portable", parse_compact_impl(s, open, false))];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("ssse3") {
                paths.push(("ssse3", parse_compact_impl(s, open, true)));
            }
            if avx512::available() {
                // SAFETY: the features were just detected.
                paths.push(("avx512", unsafe { avx512::parse_compact(s, open) }));
            }
        }
        paths
    }

    /// All paths of [`fast_paths`] give the same answer; returns it.
    fn fast_paths_agree(s: &[u8], open: usize) -> Fast {
        let mut paths = fast_paths(s, open).into_iter();
        let (_, first) = paths.next().expect("the portable path");
        for (name, other) in paths {
            assert_eq!(
                other,
                first,
                "{name} vs portable on {:?}",
                String::from_utf8_lossy(s)
            );
        }
        first
    }

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
        assert_eq!(fast_paths_agree(&text, open), fast);
        #[cfg(target_arch = "x86_64")]
        if avx512::available() {
            assert!(
                fast_paths(&text, open).len() == 3,
                "AVX-512 path not compared"
            );
        }
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
            #[cfg(target_arch = "x86_64")]
            if avx512::available() {
                // SAFETY: the features were just detected.
                let (masks, value) = unsafe { avx512::classify(&win) };
                let scalar = classify_scalar(&win);
                assert_eq!(masks, scalar.masks, "{win:?}");
                // SAFETY: as above.
                assert_eq!(unsafe { avx512::to_bytes(value) }, scalar.value, "{win:?}");
            }
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
            proptest::prop_assert_eq!(fast_paths_agree(&s, open), Fast::Done(data.clone(), end));
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
            fast_paths_agree(&s, open);
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
