//! Traces (DESIGN.md §2): one JSON line per frame,
//! `{"seq":N,"dir":"to_world"|"to_platform","len":L,"msg":{…},"world_ms":T}`
//! (or `"platform_ps"`, whichever binary writes it). `msg` is the frame body
//! itself — the bytes that crossed the socket, not a re-serialisation — so the
//! two traces of one run hold identical messages; only an image's `data` is
//! replaced by `"sha256"` of the pixels unless images are kept.
//!
//! The writer is buffered; every record is one complete line handed to the
//! buffer at once, and [`TraceWriter::flush`] pushes it out. A crash can
//! leave at most a partial last line, which [`TraceReader`] reports and skips.
//!
//! A trace file is stored as a run's series are ([`crate::series`]): plain
//! (`world.trace`) or zstd-compressed (`world.trace.zst`, the default of a
//! `cosim` run: the race's two traces are 14 MB plain, 2.3 MB compressed),
//! chosen by the path's extension; [`TraceReader::open`] reads either form,
//! given either name.

use std::collections::VecDeque;
use std::io::{self, BufRead, Write};
use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::dump::{write_key, write_object, write_str, write_u64, Val};
use crate::image::{sha256_hex, Image};
use crate::series::SeriesWriter;

/// Direction of a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Platform → world (requests).
    ToWorld,
    /// World → platform (replies).
    ToPlatform,
}

impl Direction {
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::ToWorld => "to_world",
            Direction::ToPlatform => "to_platform",
        }
    }

    pub fn reverse(self) -> Direction {
        match self {
            Direction::ToWorld => Direction::ToPlatform,
            Direction::ToPlatform => Direction::ToWorld,
        }
    }
}

/// A frame as the transports show it to an observer.
#[derive(Clone, Copy, Debug)]
pub struct FrameEvent<'a> {
    pub dir: Direction,
    /// The frame body (no length prefix), exactly as on the wire.
    pub bytes: &'a [u8],
    /// The decoded image when the frame is a `GET_IMAGE` reply (so tracing
    /// can hash the pixels without decoding again).
    pub image: Option<&'a Image>,
    /// False when a received frame failed to decode (it is still traced).
    pub valid: bool,
}

/// What transports call for every frame; an error aborts the operation.
pub type Observer = Box<dyn FnMut(&FrameEvent<'_>) -> io::Result<()> + Send>;

/// Whose clock a trace records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceClock {
    /// The world's time in ms (`"world_ms"`).
    WorldMs,
    /// The platform's time in ps (`"platform_ps"`).
    PlatformPs,
}

impl TraceClock {
    fn key(self) -> &'static str {
        match self {
            TraceClock::WorldMs => "world_ms",
            TraceClock::PlatformPs => "platform_ps",
        }
    }
}

/// Writes a trace.
pub struct TraceWriter<W: Write = SeriesWriter> {
    out: W,
    clock: TraceClock,
    keep_images: bool,
    seq: u64,
    line: Vec<u8>,
}

impl TraceWriter<SeriesWriter> {
    /// Creates (truncates) `path`, compressed if it ends in `.zst`
    /// ([`SeriesWriter`]: same records, same bytes).
    pub fn create(path: &Path, clock: TraceClock, keep_images: bool) -> io::Result<Self> {
        let f = SeriesWriter::create(path).map_err(|e| {
            io::Error::new(
                e.kind(),
                format!("cannot create trace {}: {e}", path.display()),
            )
        })?;
        Ok(Self::new(f, clock, keep_images))
    }

    /// Writes what is buffered and ends the file (a compressed trace's
    /// frame); later records fail. Dropping the writer also ends it, without
    /// reporting an error.
    pub fn finish(&mut self) -> io::Result<()> {
        self.out.finish()
    }
}

impl<W: Write> TraceWriter<W> {
    pub fn new(out: W, clock: TraceClock, keep_images: bool) -> Self {
        TraceWriter {
            out,
            clock,
            keep_images,
            seq: 0,
            line: Vec::new(),
        }
    }

    /// Appends one record; `now` is the writer's clock (ms or ps).
    pub fn record(&mut self, ev: &FrameEvent<'_>, now: u64) -> io::Result<()> {
        self.record_for(ev, now, None)
    }

    /// [`TraceWriter::record`] with the `"drone"` field of a world serving
    /// several drones (DESIGN.md §7), written last on the line.
    pub fn record_for(
        &mut self,
        ev: &FrameEvent<'_>,
        now: u64,
        drone: Option<&str>,
    ) -> io::Result<()> {
        match ev.image {
            Some(img) if !self.keep_images => {
                let hash = sha256_hex(&img.data);
                let camera = Camera {
                    width: img.width,
                    height: img.height,
                    sha256: &hash,
                };
                self.write_line(ev.dir, ev.bytes.len(), Msg::Camera(camera), now, drone)
            }
            _ => self.write_line(ev.dir, ev.bytes.len(), Msg::Frame(ev), now, drone),
        }
    }

    /// One line: `len` is the frame body's length, `msg` what stands for it.
    fn write_line(
        &mut self,
        dir: Direction,
        len: usize,
        msg: Msg<'_>,
        now: u64,
        drone: Option<&str>,
    ) -> io::Result<()> {
        let l = &mut self.line;
        l.clear();
        l.push(b'{');
        write_key(l, "seq");
        write_u64(l, self.seq);
        l.push(b',');
        write_key(l, "dir");
        write_str(l, dir.as_str());
        l.push(b',');
        write_key(l, "len");
        write_u64(l, len as u64);
        l.push(b',');
        write_key(l, "msg");
        match msg {
            Msg::Camera(c) => {
                l.extend_from_slice(b"{\"camera\":");
                write_object(
                    l,
                    &[
                        ("height", Val::U64(c.height.into())),
                        ("sha256", Val::Str(c.sha256)),
                        ("width", Val::U64(c.width.into())),
                    ],
                );
                l.extend_from_slice(b",\"command\":\"GET_IMAGE\"}");
            }
            Msg::Frame(ev) => write_msg(l, ev),
        }
        l.push(b',');
        write_key(l, self.clock.key());
        write_u64(l, now);
        if let Some(d) = drone {
            l.push(b',');
            write_key(l, "drone");
            write_str(l, d);
        }
        l.extend_from_slice(b"}\n");
        self.out.write_all(l)?;
        self.seq += 1;
        Ok(())
    }

    /// Pushes buffered lines to the file.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// Records written so far.
    pub fn records(&self) -> u64 {
        self.seq
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

/// What a line's `msg` holds.
enum Msg<'a> {
    /// An image reply's size and the SHA-256 of its pixels.
    Camera(Camera<'a>),
    /// The frame body ([`write_msg`]).
    Frame(&'a FrameEvent<'a>),
}

struct Camera<'a> {
    width: u32,
    height: u32,
    sha256: &'a str,
}

/// A record kept by a [`TraceQueue`] until its line is written.
enum Queued {
    /// The frame's body, written as [`TraceWriter::record`] would.
    Frame {
        dir: Direction,
        body: Vec<u8>,
        valid: bool,
        now: u64,
        drone: Option<String>,
    },
    /// An image reply whose line holds the SHA-256 of its pixels, hashed
    /// [`HASH_SLICE`] bytes per slice of work.
    Image {
        dir: Direction,
        len: usize,
        width: u32,
        height: u32,
        pixels: Vec<u8>,
        hasher: sha2::Sha256,
        hashed: usize,
        now: u64,
        drone: Option<String>,
    },
}

/// Images queued before [`TraceQueue::push`] hashes them itself (a peer
/// that never leaves time to wait): four 320×320 frames, 400 KB.
const MAX_IMAGES: usize = 4;

/// Bytes hashed per slice of [`TraceQueue::work`]: 16 KB, ~10 µs.
const HASH_SLICE: usize = 16 * 1024;

/// A trace whose lines are written later, as idle work
/// (`busy_poll::IdleWork`): the platform hashes each image's pixels for
/// its trace (a 320×320 frame, ~50 µs), and with a queue that hashing and
/// the writing happen while the platform waits for the world instead of
/// before its next request (docs/COSIM.md "Performance"). The lines are
/// those of a [`TraceWriter`] recording the same events, in the same
/// order; a line that needs no hash is written at once when nothing is
/// queued before it. [`TraceQueue::flush`] and drop write what is queued.
pub struct TraceQueue<W: Write = SeriesWriter> {
    writer: TraceWriter<W>,
    queue: VecDeque<Queued>,
    /// How many of the queued records are images.
    images: usize,
    /// The first write error of [`TraceQueue::work`], returned by the next
    /// `push` or `flush`.
    error: Option<io::ErrorKind>,
}

impl<W: Write> TraceQueue<W> {
    pub fn new(writer: TraceWriter<W>) -> Self {
        TraceQueue {
            writer,
            queue: VecDeque::new(),
            images: 0,
            error: None,
        }
    }

    fn failed(&self) -> io::Result<()> {
        match self.error {
            Some(kind) => Err(io::Error::new(
                kind,
                "an earlier trace line could not be written",
            )),
            None => Ok(()),
        }
    }

    /// Records `ev` (now or later).
    pub fn push(&mut self, ev: &FrameEvent<'_>, now: u64) -> io::Result<()> {
        self.push_for(ev, now, None)
    }

    /// [`TraceWriter::record_for`], now or later.
    pub fn push_for(
        &mut self,
        ev: &FrameEvent<'_>,
        now: u64,
        drone: Option<&str>,
    ) -> io::Result<()> {
        self.failed()?;
        match ev.image {
            Some(img) if !self.writer.keep_images => {
                while self.images >= MAX_IMAGES && self.work() {}
                self.failed()?;
                self.images += 1;
                self.queue.push_back(Queued::Image {
                    dir: ev.dir,
                    len: ev.bytes.len(),
                    width: img.width,
                    height: img.height,
                    pixels: img.data.clone(),
                    hasher: Default::default(),
                    hashed: 0,
                    now,
                    drone: drone.map(str::to_string),
                });
                Ok(())
            }
            _ if self.queue.is_empty() => self.writer.record_for(ev, now, drone),
            _ => {
                self.queue.push_back(Queued::Frame {
                    dir: ev.dir,
                    body: ev.bytes.to_vec(),
                    valid: ev.valid,
                    now,
                    drone: drone.map(str::to_string),
                });
                Ok(())
            }
        }
    }

    /// One slice of work: hashes up to [`HASH_SLICE`] bytes of the first
    /// queued image, or writes the lines up to the next image. Returns
    /// whether anything is still queued. A write error is kept for the next
    /// `push` or `flush` (and the queue dropped).
    pub fn work(&mut self) -> bool {
        if let Err(e) = self.step() {
            self.error.get_or_insert(e.kind());
            self.queue.clear();
            self.images = 0;
        }
        !self.queue.is_empty()
    }

    fn step(&mut self) -> io::Result<()> {
        use sha2::Digest as _;
        while let Some(front) = self.queue.front_mut() {
            match front {
                Queued::Image {
                    pixels,
                    hasher,
                    hashed,
                    ..
                } if *hashed < pixels.len() => {
                    let end = (*hashed + HASH_SLICE).min(pixels.len());
                    hasher.update(&pixels[*hashed..end]);
                    *hashed = end;
                    return Ok(());
                }
                _ => {}
            }
            match self.queue.pop_front().expect("front exists") {
                Queued::Image {
                    dir,
                    len,
                    width,
                    height,
                    hasher,
                    now,
                    drone,
                    ..
                } => {
                    self.images -= 1;
                    let hash = hex::encode(hasher.finalize());
                    let camera = Camera {
                        width,
                        height,
                        sha256: &hash,
                    };
                    self.writer
                        .write_line(dir, len, Msg::Camera(camera), now, drone.as_deref())?;
                }
                Queued::Frame {
                    dir,
                    body,
                    valid,
                    now,
                    drone,
                } => {
                    let ev = FrameEvent {
                        dir,
                        bytes: &body,
                        image: None,
                        valid,
                    };
                    self.writer.record_for(&ev, now, drone.as_deref())?;
                }
            }
        }
        Ok(())
    }

    /// Writes every queued line and flushes the file.
    pub fn flush(&mut self) -> io::Result<()> {
        while self.work() {}
        self.failed()?;
        self.writer.flush()
    }

    /// Records written or queued so far.
    pub fn records(&self) -> u64 {
        self.writer.records() + self.queue.len() as u64
    }
}

impl TraceQueue<SeriesWriter> {
    /// Writes every queued line and ends the file ([`TraceWriter::finish`]).
    pub fn finish(&mut self) -> io::Result<()> {
        while self.work() {}
        self.failed()?;
        self.writer.finish()
    }
}

impl<W: Write> Drop for TraceQueue<W> {
    fn drop(&mut self) {
        // Best effort (the normal path flushes and sees the errors).
        let _ = self.flush();
    }
}

/// The frame body as the `msg` value: verbatim when it is a valid message
/// on one line (our own frames always are); re-serialised compactly if a
/// foreign peer sent JSON with newlines; a JSON string of the (lossy) text
/// for a frame that failed to decode, so the line stays valid JSON.
fn write_msg(l: &mut Vec<u8>, ev: &FrameEvent<'_>) {
    if ev.valid {
        if !ev.bytes.iter().any(|&b| b == b'\n' || b == b'\r') {
            l.extend_from_slice(ev.bytes);
            return;
        }
        if let Ok(v) = serde_json::from_slice::<Value>(ev.bytes) {
            serde_json::to_writer(&mut *l, &v).expect("writing to a Vec cannot fail");
            return;
        }
    }
    l.extend_from_slice(b"{\"invalid_frame\":");
    write_str(l, &String::from_utf8_lossy(ev.bytes));
    l.push(b'}');
}

/// One trace line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TraceRecord {
    pub seq: u64,
    pub dir: Direction,
    pub len: u64,
    pub msg: Value,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub world_ms: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform_ps: Option<u64>,
    /// The drone a frame belongs to, in a world with several drones.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drone: Option<String>,
}

impl TraceRecord {
    /// The message's `"command"`, if any.
    pub fn command(&self) -> Option<&str> {
        self.msg.get("command").and_then(Value::as_str)
    }
}

/// Why a trace could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    #[error("trace I/O error: {0}")]
    Io(#[from] io::Error),
    #[error("trace line {line}: {detail}")]
    BadLine { line: usize, detail: String },
}

/// A partial last line (a writer that crashed mid-line).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TruncatedLine {
    /// 1-based line number.
    pub line: usize,
    /// Bytes in the partial line.
    pub bytes: usize,
}

/// Reads a trace: an iterator of records. A last line without its newline
/// that does not parse is not an error: iteration ends and
/// [`TraceReader::truncated`] reports it.
pub struct TraceReader<R> {
    r: R,
    buf: Vec<u8>,
    line: usize,
    truncated: Option<TruncatedLine>,
    /// What [`TraceReader::open`] already dropped from a file whose writer
    /// died (a compressed trace's unfinished frame), reported at the end.
    dropped: Option<TruncatedLine>,
    done: bool,
}

impl TraceReader<Box<dyn BufRead>> {
    /// Opens the trace a path names, in either form (`world.trace` finds
    /// `world.trace.zst`: [`crate::series::read`]). Of a file whose writer
    /// died, the whole lines that reached the disk: a compressed trace's
    /// unfinished frame ends the records as a plain file's partial last line
    /// does ([`TraceReader::truncated`]).
    pub fn open(path: &Path) -> io::Result<Self> {
        let text = crate::series::read(path)
            .map_err(|e| io::Error::new(e.source.kind(), format!("cannot open trace: {e}")))?;
        let dropped = text.torn.as_ref().map(|t| TruncatedLine {
            line: t.lines_kept + 1,
            bytes: t.partial_line_bytes,
        });
        let mut r = Self::new(Box::new(io::Cursor::new(text.bytes)) as Box<dyn BufRead>);
        r.dropped = dropped;
        Ok(r)
    }
}

impl<R: BufRead> TraceReader<R> {
    pub fn new(r: R) -> Self {
        TraceReader {
            r,
            buf: Vec::new(),
            line: 0,
            truncated: None,
            dropped: None,
            done: false,
        }
    }

    /// Set once iteration met a partial last line.
    pub fn truncated(&self) -> Option<TruncatedLine> {
        self.truncated
    }
}

impl<R: BufRead> Iterator for TraceReader<R> {
    type Item = Result<TraceRecord, TraceError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            self.buf.clear();
            let n = match self.r.read_until(b'\n', &mut self.buf) {
                Ok(n) => n,
                Err(e) => {
                    self.done = true;
                    return Some(Err(e.into()));
                }
            };
            if n == 0 {
                self.done = true;
                if let Some(t) = self.dropped.take() {
                    tracing::warn!(
                        line = t.line,
                        "trace ends mid-write (writer interrupted?); the rest is lost"
                    );
                    self.truncated = Some(t);
                }
                return None;
            }
            self.line += 1;
            let complete = self.buf.last() == Some(&b'\n');
            let text = self.buf.trim_ascii();
            if text.is_empty() {
                continue;
            }
            return match serde_json::from_slice::<TraceRecord>(text) {
                Ok(r) => Some(Ok(r)),
                Err(_) if !complete => {
                    self.done = true;
                    self.truncated = Some(TruncatedLine {
                        line: self.line,
                        bytes: self.buf.len(),
                    });
                    tracing::warn!(
                        line = self.line,
                        bytes = self.buf.len(),
                        "trace ends with a partial line (writer interrupted?); ignored"
                    );
                    None
                }
                Err(e) => {
                    self.done = true;
                    Some(Err(TraceError::BadLine {
                        line: self.line,
                        detail: e.to_string(),
                    }))
                }
            };
        }
    }
}
