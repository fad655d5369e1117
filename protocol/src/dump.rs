//! JSON output that matches nlohmann::json's `dump()` byte for byte, so a
//! frame we write equals the frame the thesis's VirtualConnector writes for
//! the same object (Appendix B: `json_string = data.dump()`).
//!
//! What `dump()` does with no arguments, and what we reproduce:
//! - objects are `std::map`s: keys in byte order, no spaces: `{"a":1,"b":2}`;
//! - integers print as integers;
//! - doubles print the digits of a shortest round-trip representation laid out
//!   by nlohmann's `format_buffer` rules (kMinExp = -4, kMaxExp = 15):
//!   `2.0`, `0.001`, `1e-05`, `123456789012345.0`, `1e+16`, `1.5e+300`,
//!   `-0.0`; NaN and infinities print as `null`;
//! - strings escape `"`, `\`, and control characters (`\b \f \n \r \t`,
//!   others as `\u00xx`); everything else, including non-ASCII, is raw UTF-8
//!   (`ensure_ascii = false`), which is exactly what serde_json writes for a
//!   string, so strings go through serde_json.
//!
//! The digits come from `ryu` (shortest, correctly rounded). nlohmann gets its
//! digits from Grisu2, which round-trips but is not always the shortest; for
//! the rare doubles where Grisu2 emits a longer digit string our frame is
//! shorter than nlohmann's (both parse back to the same double). This is the
//! only known source of byte differences; tests/golden.rs pins the layout
//! rules on values where both agree.

use std::io::Write as _;

/// Appends `v` spelled as nlohmann's `dump()` spells a double.
pub fn write_f64(out: &mut Vec<u8>, v: f64) {
    if !v.is_finite() {
        out.extend_from_slice(b"null");
        return;
    }
    if v.is_sign_negative() {
        out.push(b'-');
    }
    let a = v.abs();
    if a == 0.0 {
        out.extend_from_slice(b"0.0");
        return;
    }
    let mut buf = ryu::Buffer::new();
    let s = buf.format_finite(a).as_bytes();
    // ryu writes either `ddd.ddd`, `0.000ddd`, `ddd.0`, `d.ddde±x` or `de±x`:
    // recover the significant digits and the decimal exponent, then lay them
    // out the nlohmann way.
    let (mantissa, exp10) = match s.iter().position(|&c| c == b'e') {
        Some(i) => (&s[..i], parse_exp(&s[i + 1..])),
        None => (s, 0),
    };
    let mut digits = [0u8; 24];
    let mut k = 0usize; // number of significant digits
    let mut point = None; // digits before the decimal point in `mantissa`
    let mut seen_nonzero = false;
    let mut leading_frac_zeros = 0i32;
    for &c in mantissa {
        if c == b'.' {
            point = Some(k as i32);
            continue;
        }
        if !seen_nonzero && c == b'0' {
            if point.is_some() {
                leading_frac_zeros += 1;
            }
            continue;
        }
        seen_nonzero = true;
        digits[k] = c;
        k += 1;
    }
    // Strip trailing zeros (ryu writes `100.0` for 1e2).
    while k > 1 && digits[k - 1] == b'0' {
        k -= 1;
    }
    let int_digits = match point {
        Some(p) if p > 0 => p,
        Some(_) => -leading_frac_zeros,
        None => {
            // No point: every digit of the mantissa is integral.
            mantissa.iter().filter(|c| c.is_ascii_digit()).count() as i32
                - mantissa.iter().take_while(|&&c| c == b'0').count() as i32
        }
    };
    // value = 0.d1d2...dk * 10^n
    let n = int_digits + exp10;
    format_nlohmann(out, &digits[..k], n);
}

fn parse_exp(s: &[u8]) -> i32 {
    let (neg, d) = match s.first() {
        Some(b'-') => (true, &s[1..]),
        Some(b'+') => (false, &s[1..]),
        _ => (false, s),
    };
    let v = d.iter().fold(0i32, |a, &c| a * 10 + (c - b'0') as i32);
    if neg {
        -v
    } else {
        v
    }
}

/// nlohmann's layout: `digits` are d1..dk, the value is 0.d1..dk × 10^n.
fn format_nlohmann(out: &mut Vec<u8>, digits: &[u8], n: i32) {
    const MIN_EXP: i32 = -4;
    const MAX_EXP: i32 = 15; // std::numeric_limits<double>::digits10
    let k = digits.len() as i32;
    if k <= n && n <= MAX_EXP {
        // digits[000].0
        out.extend_from_slice(digits);
        out.extend(std::iter::repeat_n(b'0', (n - k) as usize));
        out.extend_from_slice(b".0");
    } else if 0 < n && n <= MAX_EXP {
        // dig.its
        out.extend_from_slice(&digits[..n as usize]);
        out.push(b'.');
        out.extend_from_slice(&digits[n as usize..]);
    } else if MIN_EXP < n && n <= 0 {
        // 0.[000]digits
        out.extend_from_slice(b"0.");
        out.extend(std::iter::repeat_n(b'0', (-n) as usize));
        out.extend_from_slice(digits);
    } else {
        // d[.igits]e±XX (at least two exponent digits, like printf's %g)
        out.push(digits[0]);
        if k > 1 {
            out.push(b'.');
            out.extend_from_slice(&digits[1..]);
        }
        let e = n - 1;
        out.push(b'e');
        out.push(if e < 0 { b'-' } else { b'+' });
        let _ = write!(out, "{:02}", e.unsigned_abs());
    }
}

/// Appends an unsigned integer.
pub fn write_u64(out: &mut Vec<u8>, v: u64) {
    let mut b = itoa_buf(v);
    let (buf, start) = (&mut b.0, b.1);
    out.extend_from_slice(&buf[start..]);
}

fn itoa_buf(mut v: u64) -> ([u8; 20], usize) {
    let mut buf = [0u8; 20];
    let mut i = 20;
    loop {
        i -= 1;
        buf[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    (buf, i)
}

/// Appends a quoted, escaped JSON string (same escapes as nlohmann).
pub fn write_str(out: &mut Vec<u8>, s: &str) {
    // serde_json escapes exactly the set nlohmann escapes, with lowercase hex.
    serde_json::to_writer(&mut *out, s).expect("writing to a Vec cannot fail");
}

/// One key/value of an object being written.
pub enum Val<'a> {
    F64(f64),
    U64(u64),
    Str(&'a str),
    /// An already encoded JSON value (a nested object or array), copied as is.
    Raw(&'a [u8]),
}

/// Writes `{"k":v,...}`. Entries must already be in byte order of their keys,
/// as `std::map` iterates; checked in debug builds (so every test of every
/// message checks it).
pub fn write_object(out: &mut Vec<u8>, entries: &[(&str, Val<'_>)]) {
    debug_assert!(
        entries
            .windows(2)
            .all(|w| w[0].0.as_bytes() < w[1].0.as_bytes()),
        "object keys must be written in byte order: {:?}",
        entries.iter().map(|e| e.0).collect::<Vec<_>>()
    );
    out.push(b'{');
    for (i, (k, v)) in entries.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        write_key(out, k);
        match v {
            Val::F64(x) => write_f64(out, *x),
            Val::U64(x) => write_u64(out, *x),
            Val::Str(s) => write_str(out, s),
            Val::Raw(b) => out.extend_from_slice(b),
        }
    }
    out.push(b'}');
}

/// Writes `"key":` (keys are our own ASCII constants: no escaping needed,
/// checked in debug builds).
pub fn write_key(out: &mut Vec<u8>, k: &str) {
    debug_assert!(k
        .bytes()
        .all(|b| b.is_ascii_graphic() && b != b'"' && b != b'\\'));
    out.push(b'"');
    out.extend_from_slice(k.as_bytes());
    out.extend_from_slice(b"\":");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(v: f64) -> String {
        let mut o = Vec::new();
        write_f64(&mut o, v);
        String::from_utf8(o).unwrap()
    }

    /// Expected spellings are nlohmann 3.x `json(v).dump()` outputs, worked
    /// out from its documented rules (shortest digits; fixed notation for
    /// decimal exponents in (-4, 15]; otherwise d.ddde±XX with at least two
    /// exponent digits; ".0" appended to integral values).
    #[test]
    fn doubles_are_spelled_like_nlohmann() {
        let cases: &[(f64, &str)] = &[
            (2.0, "2.0"),
            (-2.0, "-2.0"),
            (0.0, "0.0"),
            (-0.0, "-0.0"),
            (0.5, "0.5"),
            (0.1, "0.1"),
            (1.0 / 3.0, "0.3333333333333333"),
            (123.456, "123.456"),
            (0.001, "0.001"),
            (0.0001, "0.0001"),
            (0.00001, "1e-05"),
            (1.5e-5, "1.5e-05"),
            (1e-7, "1e-07"),
            (1.25e-7, "1.25e-07"),
            (100.0, "100.0"),
            (1e14, "100000000000000.0"),
            (1e15, "1e+15"),
            (123456789012345.6, "123456789012345.6"),
            (1e16, "1e+16"),
            (1.2345678901234567e16, "1.2345678901234568e+16"),
            (1e21, "1e+21"),
            (1.5e300, "1.5e+300"),
            (5e-324, "5e-324"),
            (1.7976931348623157e308, "1.7976931348623157e+308"),
            (48.0, "48.0"),
            (-2.6, "-2.6"),
            (0.015, "0.015"),
            (f64::NAN, "null"),
            (f64::INFINITY, "null"),
        ];
        for &(v, want) in cases {
            assert_eq!(f(v), want, "spelling of {v:e}");
        }
    }

    #[test]
    fn doubles_round_trip() {
        let mut x = 1.234567e-300f64;
        while x < 1e300 {
            for v in [x, -x, x * 1.0000001, 1.0 / x] {
                assert_eq!(f(v).parse::<f64>().unwrap(), v);
            }
            x *= 7.3;
        }
    }

    #[test]
    fn integers_and_strings() {
        let mut o = Vec::new();
        write_u64(&mut o, 0);
        o.push(b' ');
        write_u64(&mut o, u64::MAX);
        o.push(b' ');
        write_str(&mut o, "a\"b\\c\n\u{1}é/");
        assert_eq!(
            String::from_utf8(o).unwrap(),
            "0 18446744073709551615 \"a\\\"b\\\\c\\n\\u0001é/\""
        );
    }
}
