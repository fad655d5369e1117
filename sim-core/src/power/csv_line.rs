//! CSV rows written by hand, byte for byte as the `csv` crate writes them
//! from a serde row (what `power.csv` and the model files were written with
//! before): integers by `itoa`, floats in the shortest form that reads back
//! to the same `f64` (`csv` uses `ryu`), fields separated by `,`, rows ended
//! by `\n`. The fields are numbers and fixed identifiers (the power-model
//! names), which `csv` never quotes.
//!
//! Why: the power network logs one row per simulated millisecond into four
//! files (~10 floats each), about 5 % of a race's CPU through `csv`'s serde
//! path and `ryu` (docs/COSIM.md "Performance"). Floats are formatted by
//! `zmij`, about twice as fast as `ryu` and with the same digits; the two
//! differ only in the spelling of exponents (`1e+20` against `1e20`), so any
//! value `zmij` writes with an exponent — or a NaN or infinity — is written
//! by `ryu` instead. `tests` compare both with `csv` directly.

use std::io::{self, Write};

/// One row being built. Rows of one file have the same columns, so the
/// line remembers, per column, the last float it formatted: a value equal
/// (bit for bit) to the previous row's is copied, not formatted again (the
/// motor state changes once per PID iteration, every 8–32 rows).
#[derive(Debug, Default)]
pub struct CsvLine {
    buf: Vec<u8>,
    fields: usize,
    /// Per column: the last float's bits and its spelling.
    last: Vec<Option<(u64, Spelling)>>,
}

/// A float as written: at most 24 bytes (`-2.2250738585072014e-308`).
#[derive(Debug, Clone, Copy)]
struct Spelling {
    len: u8,
    bytes: [u8; 24],
}

impl Spelling {
    fn of(v: f64) -> Spelling {
        let mut z = zmij::Buffer::new();
        let mut r = ryu::Buffer::new();
        let s = match v.is_finite().then(|| z.format_finite(v)) {
            Some(s) if !s.as_bytes().contains(&b'e') => s,
            _ => r.format(v),
        };
        let mut bytes = [0u8; 24];
        bytes[..s.len()].copy_from_slice(s.as_bytes());
        Spelling {
            len: s.len() as u8,
            bytes,
        }
    }

    /// Appends the spelling to `buf`: all 24 bytes copied (a fixed-size
    /// copy, a few moves, where a `len`-byte one is a `memcpy` call: most
    /// of the cost of a copied field), then `buf` cut to its length.
    fn append_to(&self, buf: &mut Vec<u8>) {
        let start = buf.len();
        buf.reserve(self.bytes.len());
        // SAFETY: `reserve` made room for the 24 bytes written after
        // `start`, so they are initialised, and `len` ≤ 24 keeps the new
        // length within them.
        unsafe {
            std::ptr::copy_nonoverlapping(
                self.bytes.as_ptr(),
                buf.as_mut_ptr().add(start),
                self.bytes.len(),
            );
            buf.set_len(start + usize::from(self.len));
        }
    }
}

impl CsvLine {
    pub fn new() -> Self {
        CsvLine::default()
    }

    fn sep(&mut self) {
        if self.fields > 0 {
            self.buf.push(b',');
        }
        self.fields += 1;
    }

    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.sep();
        self.buf
            .extend_from_slice(itoa::Buffer::new().format(v).as_bytes());
        self
    }

    pub fn f64(&mut self, v: f64) -> &mut Self {
        let col = self.fields;
        self.sep();
        if self.last.len() <= col {
            self.last.resize(col + 1, None);
        }
        let bits = v.to_bits();
        let spelling = match self.last[col] {
            Some((b, sp)) if b == bits => sp,
            _ => {
                let sp = Spelling::of(v);
                self.last[col] = Some((bits, sp));
                sp
            }
        };
        spelling.append_to(&mut self.buf);
        self
    }

    /// A field that needs no quoting (an identifier).
    pub fn ident(&mut self, v: &str) -> &mut Self {
        debug_assert!(
            !v.is_empty() && !v.bytes().any(|b| matches!(b, b',' | b'"' | b'\n' | b'\r')),
            "{v:?} would need CSV quoting"
        );
        self.sep();
        self.buf.extend_from_slice(v.as_bytes());
        self
    }

    /// Ends the row, appends it to `out` and starts the next one.
    pub fn finish(&mut self, out: &mut impl Write) -> io::Result<()> {
        self.buf.push(b'\n');
        let r = out.write_all(&self.buf);
        self.buf.clear();
        self.fields = 0;
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64: a fixed, seeded sequence of bit patterns.
    struct Bits(u64);
    impl Bits {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// What `csv` writes for one row of these fields.
    fn by_csv(ints: u64, floats: &[f64], name: &str) -> Vec<u8> {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        w.serialize((ints, floats, name)).unwrap();
        w.into_inner().unwrap()
    }

    fn by_hand(ints: u64, floats: &[f64], name: &str) -> Vec<u8> {
        let mut l = CsvLine::new();
        l.u64(ints);
        for &f in floats {
            l.f64(f);
        }
        l.ident(name);
        let mut out = Vec::new();
        l.finish(&mut out).unwrap();
        out
    }

    #[test]
    fn rows_are_the_bytes_csv_writes() {
        let special = [
            0.0,
            -0.0,
            1.0,
            0.1,
            1e-7,
            1e-5,
            1e15,
            1e16,
            1e21,
            -1.5e300,
            5e-324,
            f64::MAX,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        assert_eq!(
            by_hand(7, &special, "empirical"),
            by_csv(7, &special, "empirical")
        );
        let mut rng = Bits(0x9E37_79B9_7F4A_7C15);
        for _ in 0..20_000 {
            let floats: Vec<f64> = (0..8)
                .map(|k| match k {
                    0 => f64::from_bits(rng.next()),
                    1 => rng.unit() * 10f64.powi((rng.next() % 60) as i32 - 30),
                    2 => (rng.unit() * 1e6).round() / 1e6,
                    _ => rng.unit() * 10.0 - 5.0,
                })
                .collect();
            let t = rng.next();
            assert_eq!(
                by_hand(t, &floats, "dandrea"),
                by_csv(t, &floats, "dandrea")
            );
        }
    }
}
