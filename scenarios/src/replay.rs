//! A world server that answers from a recorded trace (`cosim replay`, meant
//! to back `world-server --replay TRACE`): the platform gets the recorded
//! reply bytes, in order, and the first request that differs from the
//! recording is reported.
//!
//! Replies are sent byte for byte as recorded (the trace's `msg` is the
//! frame body itself). A trace made without `--trace-images` holds only the
//! SHA-256 of each camera frame: the pixels are then taken from the PNGs the
//! world wrote with `--frames-dir` (the n-th image of the trace is the n-th
//! file by name), checked against the hash, and encoded as negotiated.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

use protocol::blocking::{Options, Server};
use protocol::trace::Direction;
use protocol::{encode_reply, sha256_hex, Endpoint, Image, ImageEncoding, Reply};
use serde::Deserialize;
use serde_json::value::RawValue;
use serde_json::Value;

use crate::tracetool::diff_json;

/// Why a replay could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("cannot read trace {path}: {message}")]
    Trace { path: PathBuf, message: String },
    #[error("frames: {0}")]
    Frames(String),
    #[error("socket: {0}")]
    Socket(String),
}

/// One recorded request and the reply the world gave (none for
/// SET_VELOCITY and ADVANCE_TIME).
#[derive(Debug, Clone)]
pub struct Exchange {
    pub seq: u64,
    pub request: Value,
    pub reply: Option<RecordedReply>,
}

/// A recorded reply.
#[derive(Debug, Clone)]
pub enum RecordedReply {
    /// The frame body, verbatim.
    Bytes(Vec<u8>),
    /// An image kept only as its hash: the n-th image of the trace.
    HashedImage {
        index: usize,
        width: u32,
        height: u32,
        sha256: String,
        len: u64,
    },
}

#[derive(Deserialize)]
struct RawRecord<'a> {
    seq: u64,
    dir: Direction,
    len: u64,
    #[serde(borrow)]
    msg: &'a RawValue,
}

/// Reads a trace into request/reply pairs.
pub fn load_trace(path: &Path) -> Result<Vec<Exchange>, ReplayError> {
    let bad = |message: String| ReplayError::Trace {
        path: path.to_path_buf(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let mut out: Vec<Exchange> = Vec::new();
    let mut images = 0usize;
    for (n, line) in BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| bad(e.to_string()))?;
        if line.trim().is_empty() {
            continue;
        }
        let rec: RawRecord<'_> =
            serde_json::from_str(&line).map_err(|e| bad(format!("line {}: {e}", n + 1)))?;
        let text = rec.msg.get();
        match rec.dir {
            Direction::ToWorld => out.push(Exchange {
                seq: rec.seq,
                request: serde_json::from_str(text)
                    .map_err(|e| bad(format!("line {}: {e}", n + 1)))?,
                reply: None,
            }),
            Direction::ToPlatform => {
                let Some(last) = out.last_mut().filter(|e| e.reply.is_none()) else {
                    return Err(bad(format!("line {}: a reply without a request", n + 1)));
                };
                let msg: Value =
                    serde_json::from_str(text).map_err(|e| bad(format!("line {}: {e}", n + 1)))?;
                let hashed = msg
                    .get("camera")
                    .and_then(|c| Some((c.get("sha256")?.as_str()?, c)));
                last.reply = Some(match hashed {
                    Some((sha, cam)) => {
                        let dim = |k: &str| cam.get(k).and_then(Value::as_u64).unwrap_or(0) as u32;
                        images += 1;
                        RecordedReply::HashedImage {
                            index: images - 1,
                            width: dim("width"),
                            height: dim("height"),
                            sha256: sha.to_string(),
                            len: rec.len,
                        }
                    }
                    None => {
                        if msg.get("camera").is_some() {
                            images += 1;
                        }
                        if text.len() as u64 != rec.len {
                            return Err(bad(format!(
                                "line {}: the message is {} bytes, the frame was {} (not a verbatim trace)",
                                n + 1,
                                text.len(),
                                rec.len
                            )));
                        }
                        RecordedReply::Bytes(text.as_bytes().to_vec())
                    }
                });
            }
        }
    }
    Ok(out)
}

/// The camera frames a world wrote with `--frames-dir`, in order.
pub fn frame_files(dir: &Path) -> Result<Vec<PathBuf>, ReplayError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| ReplayError::Frames(format!("{}: {e}", dir.display())))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    files.sort();
    Ok(files)
}

/// Reads an 8-bit greyscale PNG.
fn read_grey_png(path: &Path) -> Result<Image, ReplayError> {
    let bad = |m: String| ReplayError::Frames(format!("{}: {m}", path.display()));
    let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad(e.to_string()))?;
    let mut data = vec![
        0;
        reader
            .output_buffer_size()
            .ok_or_else(|| bad("image too large".into()))?
    ];
    let info = reader
        .next_frame(&mut data)
        .map_err(|e| bad(e.to_string()))?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Eight {
        return Err(bad("not an 8-bit greyscale PNG".into()));
    }
    data.truncate(info.buffer_size());
    Ok(Image {
        width: info.width,
        height: info.height,
        data,
    })
}

/// What a replay found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayReport {
    /// Requests received.
    pub requests: usize,
    /// The first request that differs from the recording: (recorded
    /// sequence number, what differs).
    pub first_difference: Option<(u64, String)>,
    /// True when the whole recording was served (up to STOP).
    pub complete: bool,
}

/// Replay options.
#[derive(Debug, Clone, Default)]
pub struct ReplayOptions {
    /// PNG frames for traces that hold only image hashes.
    pub frames: Option<PathBuf>,
    /// Relative tolerance for numbers in requests (0: exact).
    pub tolerance: f64,
}

fn image_reply(
    frames: &[PathBuf],
    index: usize,
    (width, height, sha256, len): (u32, u32, &str, u64),
    encoding: ImageEncoding,
) -> Result<Vec<u8>, String> {
    let Some(path) = frames.get(index) else {
        return Err(format!(
            "the trace holds only the SHA-256 of image {index}: record with --trace-images, or give the frames the world wrote (--frames DIR; {} found)",
            frames.len()
        ));
    };
    let img = read_grey_png(path).map_err(|e| e.to_string())?;
    if img.width != width || img.height != height || sha256_hex(&img.data) != sha256 {
        return Err(format!(
            "{} is not the recorded image {index}",
            path.display()
        ));
    }
    let mut body = Vec::new();
    encode_reply(&Reply::Image(img), encoding, &mut body);
    if body.len() as u64 != len {
        return Err(format!(
            "image {index} encodes to {} bytes, the recording has {len}",
            body.len()
        ));
    }
    Ok(body)
}

/// Serves one platform connection on `endpoint` from `exchanges`.
pub fn serve(
    endpoint: &Endpoint,
    exchanges: &[Exchange],
    opts: &ReplayOptions,
) -> Result<ReplayReport, ReplayError> {
    let frames = match &opts.frames {
        Some(dir) => frame_files(dir)?,
        None => Vec::new(),
    };
    let server = Server::bind_with(endpoint, Options::default())
        .map_err(|e| ReplayError::Socket(format!("cannot listen on {endpoint}: {e}")))?;
    tracing::info!(%endpoint, requests = exchanges.len(), "replaying");
    let mut conn = server
        .accept()
        .map_err(|e| ReplayError::Socket(e.to_string()))?;
    let mut report = ReplayReport::default();
    let mut encoding = ImageEncoding::Array;
    let fail = |conn: &mut protocol::blocking::Connection, msg: String| {
        tracing::error!("{msg}");
        let mut body = Vec::new();
        encode_reply(&Reply::error(msg), ImageEncoding::Array, &mut body);
        // The platform may already be gone; the report says what happened.
        let _ = conn.send_raw(&body);
    };
    for ex in exchanges {
        let body = match conn.recv_raw() {
            Ok(Some(b)) => b.to_vec(),
            Ok(None) => return Ok(report),
            Err(e) => return Err(ReplayError::Socket(e.to_string())),
        };
        report.requests += 1;
        let got: Value = match serde_json::from_slice(&body) {
            Ok(v) => v,
            Err(e) => {
                fail(
                    &mut conn,
                    format!("request {} is not JSON: {e}", report.requests),
                );
                return Ok(report);
            }
        };
        if let Some(d) = diff_json(&ex.request, &got, opts.tolerance) {
            if report.first_difference.is_none() {
                tracing::warn!("request #{} differs from the recording: {d}", ex.seq);
                report.first_difference = Some((ex.seq, d));
            }
            if ex.request.get("command") != got.get("command") {
                fail(
                    &mut conn,
                    format!("replay: request #{} is not the recorded command", ex.seq),
                );
                return Ok(report);
            }
        }
        let reply = match &ex.reply {
            None => continue,
            Some(RecordedReply::Bytes(b)) => b.clone(),
            Some(RecordedReply::HashedImage {
                index,
                width,
                height,
                sha256,
                len,
            }) => match image_reply(&frames, *index, (*width, *height, sha256, *len), encoding) {
                Ok(b) => b,
                Err(m) => {
                    fail(&mut conn, format!("replay: {m}"));
                    return Err(ReplayError::Frames(m));
                }
            },
        };
        if ex.request.get("command").and_then(Value::as_str) == Some("GET_INIT_DATA") {
            let recorded: Value = serde_json::from_slice(&reply).unwrap_or(Value::Null);
            encoding = match recorded.get("image_encoding").and_then(Value::as_str) {
                Some("base64") => ImageEncoding::Base64,
                _ => ImageEncoding::Array,
            };
        }
        conn.send_raw(&reply)
            .map_err(|e| ReplayError::Socket(e.to_string()))?;
    }
    report.complete = true;
    Ok(report)
}
