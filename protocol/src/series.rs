//! A run's series files (DESIGN.md §6, §19): CSV, stored either plain
//! (`power.csv`) or zstd-compressed (`power.csv.zst`, one zstd frame, which
//! pandas, polars and the `zstd` tool read directly). Every writer of a
//! series goes through [`SeriesWriter`] and every reader through [`read`]
//! (or [`open`]), given the series' CSV name (`out/power.csv`) whatever
//! its form, so the choice of form lives here only.
//!
//! - Same input, same bytes: single-threaded zstd at a fixed level, and the
//!   frame is flushed only where the writer says so (the end of a run, a
//!   battery that empties), never on a timer.
//! - A file whose writer died (`kill -9`) is still read: [`read`] keeps the
//!   valid prefix (every whole line; for a compressed file, every block that
//!   reached the disk) and says what it dropped ([`Torn`]).

use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// The extension a compressed series adds to its CSV name.
pub const ZST_EXT: &str = "zst";

/// zstd's level for series: 1, the fastest of the standard levels and, on
/// these logs, also the smallest (the race's power.csv: 5.2 MB at level 1,
/// 6.0 MB at 3, 5.6 MB at 7; docs/COSIM.md "Outputs").
pub const ZSTD_LEVEL: i32 = 1;

/// Bytes of CSV after which a compressed series ends its current block
/// and hands it to the file, so that a writer killed mid-run leaves at most
/// this much unwritten, as a plain file's 64 KiB buffer does. The points
/// are offsets into the text, whatever the writes' sizes: same text, same
/// bytes.
const ZSTD_FLUSH_EVERY: usize = 64 * 1024;

/// How a run stores its series.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SeriesFormat {
    /// `NAME.csv.zst`.
    #[default]
    Zstd,
    /// `NAME.csv`, as before compression existed.
    Plain,
}

impl SeriesFormat {
    /// The file name of the series `csv_name` (`power.csv`) in this form.
    pub fn file_name(self, csv_name: &str) -> String {
        match self {
            SeriesFormat::Zstd => format!("{csv_name}.{ZST_EXT}"),
            SeriesFormat::Plain => csv_name.to_string(),
        }
    }

    /// The form a path names (by its extension).
    pub fn of_path(path: &Path) -> SeriesFormat {
        if path.extension().is_some_and(|e| e == ZST_EXT) {
            SeriesFormat::Zstd
        } else {
            SeriesFormat::Plain
        }
    }
}

/// The first bytes of a zstd frame.
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// The other form's path of a series file (`a.csv` <-> `a.csv.zst`).
fn sibling(path: &Path) -> PathBuf {
    match SeriesFormat::of_path(path) {
        SeriesFormat::Zstd => path.with_extension(""),
        SeriesFormat::Plain => {
            let mut s = path.as_os_str().to_owned();
            s.push(".");
            s.push(ZST_EXT);
            PathBuf::from(s)
        }
    }
}

/// The file that holds the series a path names in either form
/// (`out/power.csv` finds `out/power.csv.zst`): the path itself if it
/// exists, else its other form if that exists, else the path.
pub fn resolve(path: &Path) -> PathBuf {
    if path.exists() {
        return path.to_path_buf();
    }
    let other = sibling(path);
    if other.is_file() {
        other
    } else {
        path.to_path_buf()
    }
}

/// Whether the series a path names exists, in either form.
pub fn exists(path: &Path) -> bool {
    resolve(path).is_file()
}

/// A stream of the series a path names (either form, [`resolve`]), for a
/// reader that needs only its beginning; [`read`] takes a whole file and
/// copes with a torn one.
pub fn open(path: &Path) -> Result<Box<dyn io::BufRead>, SeriesError> {
    let path = resolve(path);
    let err = |source| SeriesError {
        path: path.clone(),
        source,
    };
    let file = File::open(&path).map_err(err)?;
    Ok(match SeriesFormat::of_path(&path) {
        SeriesFormat::Plain => Box::new(io::BufReader::new(file)),
        SeriesFormat::Zstd => Box::new(io::BufReader::new(
            zstd::stream::read::Decoder::new(file).map_err(err)?,
        )),
    })
}

/// Whether the file holding a series ends as its writer ends it (a whole
/// last line; for a compressed file, a whole frame), without decoding it:
/// the cheap test before [`read`] says what a torn file lost.
pub fn is_whole(path: &Path) -> Result<bool, SeriesError> {
    let path = resolve(path);
    let bytes = std::fs::read(&path).map_err(|source| SeriesError {
        path: path.clone(),
        source,
    })?;
    Ok(match SeriesFormat::of_path(&path) {
        SeriesFormat::Plain => bytes.last().is_none_or(|&b| b == b'\n'),
        SeriesFormat::Zstd => {
            zstd::zstd_safe::find_frame_compressed_size(&bytes) == Ok(bytes.len())
        }
    })
}

enum Inner {
    Plain(BufWriter<File>),
    // No buffer behind the encoder: it hands the file whole compressed
    // blocks, and a buffer would only hold back what a killed writer
    // leaves on the disk.
    Zstd(zstd::stream::write::Encoder<'static, File>),
}

/// A series file being written, in the form its path names (a `.zst` path
/// is compressed). Call [`SeriesWriter::finish`] at the end: it ends the
/// zstd frame (dropping the writer also does, without reporting an error).
pub struct SeriesWriter {
    inner: Inner,
    finished: bool,
    /// Bytes written since the last flush (compressed form).
    since_flush: usize,
}

impl SeriesWriter {
    /// Creates (truncates) `path`, and removes the series' file of the other
    /// form, left by an earlier run in the same directory, so that a reader
    /// never finds a stale copy.
    pub fn create(path: &Path) -> io::Result<SeriesWriter> {
        let file = File::create(path)?;
        match std::fs::remove_file(sibling(path)) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        let inner = match SeriesFormat::of_path(path) {
            SeriesFormat::Plain => Inner::Plain(BufWriter::with_capacity(1 << 16, file)),
            SeriesFormat::Zstd => {
                let mut enc = zstd::stream::write::Encoder::new(file, ZSTD_LEVEL)?;
                enc.include_checksum(true)?;
                Inner::Zstd(enc)
            }
        };
        Ok(SeriesWriter {
            inner,
            finished: false,
            since_flush: 0,
        })
    }

    /// Writes what is buffered and ends the zstd frame; later writes fail.
    pub fn finish(&mut self) -> io::Result<()> {
        if self.finished {
            return Ok(());
        }
        self.finished = true;
        match &mut self.inner {
            Inner::Plain(w) => w.flush(),
            Inner::Zstd(enc) => {
                enc.do_finish()?;
                enc.get_mut().flush()
            }
        }
    }
}

impl Write for SeriesWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.finished {
            return Err(io::Error::other("series file written after its end"));
        }
        match &mut self.inner {
            Inner::Plain(w) => w.write(buf),
            Inner::Zstd(enc) => {
                let room = ZSTD_FLUSH_EVERY - self.since_flush;
                let n = enc.write(&buf[..buf.len().min(room)])?;
                self.since_flush += n;
                if self.since_flush == ZSTD_FLUSH_EVERY {
                    enc.flush()?;
                    self.since_flush = 0;
                }
                Ok(n)
            }
        }
    }

    /// Makes every byte written so far readable from the file (for zstd:
    /// ends the current block; call it at points the simulation decides,
    /// so that the bytes stay the same run after run).
    fn flush(&mut self) -> io::Result<()> {
        if self.finished {
            return Ok(());
        }
        match &mut self.inner {
            Inner::Plain(w) => w.flush(),
            Inner::Zstd(enc) => {
                self.since_flush = 0;
                enc.flush()?;
                enc.get_mut().flush()
            }
        }
    }
}

impl Drop for SeriesWriter {
    fn drop(&mut self) {
        // Best effort on error and panic paths; the normal path calls
        // `finish` and sees its error.
        let _ = self.finish();
    }
}

/// What [`read`] left out of a file whose writer stopped mid-file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Torn {
    /// Whole lines kept, the header included.
    pub lines_kept: usize,
    /// Bytes of a last line without its end, dropped.
    pub partial_line_bytes: usize,
    /// The compressed stream ended (or broke) mid-frame: what the writer had
    /// not yet flushed to the disk is lost; the reason.
    pub frame_error: Option<String>,
}

impl fmt::Display for Torn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rows = self.lines_kept.saturating_sub(1);
        write!(f, "its writer stopped mid-file: kept {rows} rows")?;
        if self.partial_line_bytes > 0 {
            write!(
                f,
                ", dropped a torn last row ({} bytes)",
                self.partial_line_bytes
            )?;
        }
        if let Some(e) = &self.frame_error {
            write!(
                f,
                ", and the rows the writer had not yet compressed to the file ({e})"
            )?;
        }
        Ok(())
    }
}

/// The text of a series file: every whole line, and what was left out.
#[derive(Debug)]
pub struct SeriesText {
    pub path: PathBuf,
    /// Whole lines only (each ends with `\n`).
    pub bytes: Vec<u8>,
    /// `Some` when the file ends mid-line or mid-frame.
    pub torn: Option<Torn>,
}

impl SeriesText {
    /// The one warning line a reader prints for a torn file.
    pub fn warning(&self) -> Option<String> {
        self.torn
            .as_ref()
            .map(|t| format!("{}: {t}", self.path.display()))
    }
}

/// Why a series file could not be read at all.
#[derive(Debug, thiserror::Error)]
#[error("cannot read {}: {source}", path.display())]
pub struct SeriesError {
    pub path: PathBuf,
    #[source]
    pub source: io::Error,
}

/// Reads the series a path names, in either form ([`resolve`]), and keeps
/// its valid prefix: a compressed file is decoded up to where its frame
/// breaks off, and a last line without its newline is dropped.
pub fn read(path: &Path) -> Result<SeriesText, SeriesError> {
    let path = &resolve(path);
    let err = |source| SeriesError {
        path: path.to_path_buf(),
        source,
    };
    let raw = std::fs::read(path).map_err(err)?;
    let mut bytes = Vec::new();
    let mut frame_error = None;
    match SeriesFormat::of_path(path) {
        SeriesFormat::Plain => bytes = raw,
        SeriesFormat::Zstd => {
            let incomplete = || "the zstd frame is incomplete".to_string();
            let mut dec = zstd::stream::read::Decoder::new(&raw[..]).map_err(err)?;
            // On an error `read_to_end` keeps what it decoded before it.
            if let Err(e) = dec.read_to_end(&mut bytes) {
                // Not zstd at all is an error; a frame cut before its first
                // whole block is a writer that died early.
                let zstd_start = if raw.len() < ZSTD_MAGIC.len() {
                    ZSTD_MAGIC.starts_with(&raw)
                } else {
                    raw.starts_with(&ZSTD_MAGIC)
                };
                if bytes.is_empty() && !zstd_start {
                    return Err(err(e));
                }
                frame_error = Some(match e.kind() {
                    io::ErrorKind::UnexpectedEof => incomplete(),
                    _ => format!("zstd: {e}"),
                });
            } else if zstd::zstd_safe::find_frame_compressed_size(&raw) != Ok(raw.len()) {
                // Ended between blocks (or before the first): no error
                // from the decoder, but no frame end either.
                frame_error = Some(incomplete());
            }
        }
    }
    let whole = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    let partial_line_bytes = bytes.len() - whole;
    bytes.truncate(whole);
    let torn = (partial_line_bytes > 0 || frame_error.is_some()).then(|| Torn {
        lines_kept: bytes.iter().filter(|&&b| b == b'\n').count(),
        partial_line_bytes,
        frame_error,
    });
    Ok(SeriesText {
        path: path.to_path_buf(),
        bytes,
        torn,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::BufRead;

    const TEXT: &[u8] = b"t,x\n1,0.5\n2,0.25\n3,0.125\n";

    fn write_series(path: &Path, text: &[u8]) {
        let mut w = SeriesWriter::create(path).unwrap();
        w.write_all(text).unwrap();
        w.finish().unwrap();
    }

    #[test]
    fn both_forms_read_back_the_same_text() {
        let dir = tempfile::tempdir().unwrap();
        for form in [SeriesFormat::Plain, SeriesFormat::Zstd] {
            let path = dir.path().join(form.file_name("a.csv"));
            write_series(&path, TEXT);
            let got = read(&path).unwrap();
            assert_eq!(got.bytes, TEXT);
            assert!(got.torn.is_none());
            assert_eq!(resolve(&dir.path().join("a.csv")), path);
            assert_eq!(read(&dir.path().join("a.csv")).unwrap().bytes, TEXT);
            assert!(is_whole(&path).unwrap());
            let mut first = String::new();
            open(&path).unwrap().read_line(&mut first).unwrap();
            assert_eq!(first, "t,x\n");
        }
        // The zstd tool's framing: one frame that decodes to the text.
        let raw = std::fs::read(dir.path().join("a.csv.zst")).unwrap();
        assert_eq!(zstd::decode_all(&raw[..]).unwrap(), TEXT);
    }

    #[test]
    fn a_new_file_removes_the_other_form() {
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("a.csv");
        write_series(&plain, TEXT);
        write_series(&dir.path().join("a.csv.zst"), TEXT);
        assert!(!plain.exists());
        write_series(&plain, TEXT);
        assert!(!dir.path().join("a.csv.zst").exists());
    }

    #[test]
    fn same_text_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let big: Vec<u8> = (0..50_000)
            .flat_map(|i| format!("{i},{}\n", f64::from(i).sqrt()).into_bytes())
            .collect();
        let a = dir.path().join("a.csv.zst");
        let b = dir.path().join("b.csv.zst");
        write_series(&a, &big);
        // The same bytes handed over in other pieces (a row at a time, as
        // the loggers do): the same file.
        let mut w = SeriesWriter::create(&b).unwrap();
        for piece in big.chunks(37) {
            w.write_all(piece).unwrap();
        }
        w.finish().unwrap();
        assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    }

    #[test]
    fn a_torn_last_line_is_dropped_and_counted() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv");
        std::fs::write(&path, b"t,x\n1,0.5\n2,0.2").unwrap();
        assert!(!is_whole(&path).unwrap());
        let got = read(&path).unwrap();
        assert_eq!(got.bytes, b"t,x\n1,0.5\n");
        let torn = got.torn.unwrap();
        assert_eq!(torn.lines_kept, 2);
        assert_eq!(torn.partial_line_bytes, 5);
        assert_eq!(torn.frame_error, None);
        assert!(torn.to_string().contains("kept 1 rows"), "{torn}");
    }

    #[test]
    fn a_cut_zstd_frame_keeps_the_blocks_before_the_cut() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv.zst");
        let rows: Vec<String> = (0..100_000).map(|i| format!("{i},{}\n", i * 7)).collect();
        let text: Vec<u8> = std::iter::once("t,x\n".to_string())
            .chain(rows)
            .flat_map(String::into_bytes)
            .collect();
        // A writer that flushed mid-way (one block boundary) and then died.
        let mut w = SeriesWriter::create(&path).unwrap();
        w.write_all(&text[..text.len() / 2]).unwrap();
        w.flush().unwrap();
        let flushed = std::fs::metadata(&path).unwrap().len();
        w.write_all(&text[text.len() / 2..]).unwrap();
        w.finish().unwrap();
        let full = std::fs::read(&path).unwrap();
        std::fs::write(&path, &full[..flushed as usize + 10]).unwrap();
        assert!(!is_whole(&path).unwrap());
        let got = read(&path).unwrap();
        let torn = got.torn.expect("torn");
        assert!(torn.frame_error.is_some());
        assert!(
            got.bytes.len() >= text.len() / 2 - 20,
            "{}",
            got.bytes.len()
        );
        assert!(text.starts_with(&got.bytes));
        assert!(got.bytes.ends_with(b"\n"));
    }

    #[test]
    fn an_empty_zstd_file_is_a_writer_that_died_before_its_first_block() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv.zst");
        std::fs::write(&path, b"").unwrap();
        let got = read(&path).unwrap();
        assert!(got.bytes.is_empty());
        assert_eq!(got.torn.unwrap().lines_kept, 0);
    }

    #[test]
    fn a_frame_cut_inside_its_first_block_keeps_nothing_and_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv.zst");
        let text: Vec<u8> = (0..20_000)
            .flat_map(|i| format!("{i},{}\n", i * 7).into_bytes())
            .collect();
        write_series(&path, &text);
        let full = std::fs::read(&path).unwrap();
        std::fs::write(&path, &full[..20]).unwrap();
        let got = read(&path).unwrap();
        assert!(got.bytes.is_empty());
        assert!(got.torn.unwrap().frame_error.is_some());
    }

    #[test]
    fn a_long_series_reaches_the_file_every_64_kib() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv.zst");
        let mut w = SeriesWriter::create(&path).unwrap();
        let row = b"123456,0.123456789012345,-9.87654321098765\n";
        for _ in 0..(3 * ZSTD_FLUSH_EVERY / row.len()) {
            w.write_all(row).unwrap();
        }
        // Not finished (a writer killed now): two blocks are readable.
        let got = read(&path).unwrap();
        assert!(
            got.bytes.len() >= 2 * ZSTD_FLUSH_EVERY - row.len(),
            "{}",
            got.bytes.len()
        );
        drop(w);
    }

    #[test]
    fn not_zstd_at_all_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv.zst");
        std::fs::write(&path, b"t,x\n1,2\n").unwrap();
        let e = read(&path).unwrap_err();
        assert!(e.to_string().starts_with("cannot read"), "{e}");
    }
}
