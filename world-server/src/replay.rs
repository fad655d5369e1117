//! A world server that answers from a recorded trace (`world-server --replay
//! TRACE`, also `cosim replay`): the platform gets the recorded reply bytes,
//! in order, and the first request that differs from the recording is
//! reported.
//!
//! Replies are sent byte for byte as recorded (the trace's `msg` is the
//! frame body itself). A trace made without `--trace-images` holds only the
//! SHA-256 of each camera frame: the pixels are then taken from the PNGs the
//! world wrote with `--frames-dir` (the n-th image of the trace is the n-th
//! file by name), checked against the hash, and encoded as negotiated.
//!

use std::io::BufRead;
use std::path::{Path, PathBuf};

use protocol::blocking::{Options, Server};
use protocol::trace::Direction;
use protocol::{encode_reply, sha256_hex, Endpoint, Image, ImageEncoding, Reply};
use serde::Deserialize;
use serde_json::value::RawValue;
use serde_json::Value;

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
    // Either form (`world.trace` or `world.trace.zst`); of a trace whose
    // writer died, the whole lines that reached the disk.
    let text = protocol::series::read(path).map_err(|e| bad(e.to_string()))?;
    if let Some(w) = text.warning() {
        tracing::warn!("{w}");
    }
    let mut out: Vec<Exchange> = Vec::new();
    let mut images = 0usize;
    for (n, line) in std::io::Cursor::new(text.bytes).lines().enumerate() {
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

/// Loads `trace`, serves one platform on `endpoint` from it and prints the
/// outcome on stderr. `Ok(true)` when the whole recording was served and
/// every request matched it; `Ok(false)` when the platform left early or a
/// request differed (the first difference is printed).
pub fn replay_and_report(
    trace: &Path,
    endpoint: &Endpoint,
    opts: &ReplayOptions,
) -> Result<bool, ReplayError> {
    let exchanges = load_trace(trace)?;
    let report = serve(endpoint, &exchanges, opts)?;
    Ok(match &report.first_difference {
        None if report.complete => {
            eprintln!("replay: {} requests, all as recorded", report.requests);
            true
        }
        None => {
            eprintln!(
                "replay: the platform left after {} of {} requests",
                report.requests,
                exchanges.len()
            );
            false
        }
        Some((seq, d)) => {
            eprintln!("replay: first request that differs: #{seq}: {d}");
            false
        }
    })
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

/// The first place where two JSON values differ beyond `tol` (numbers:
/// |a − b| ≤ tol·max(1, |a|)), as `path: expected X, got Y`.
pub fn diff_json(expected: &Value, got: &Value, tol: f64) -> Option<String> {
    fn walk(path: &str, a: &Value, b: &Value, tol: f64) -> Option<String> {
        match (a, b) {
            (Value::Number(x), Value::Number(y)) => {
                let (x, y) = (x.as_f64()?, y.as_f64()?);
                let ok = (x - y).abs() <= tol * x.abs().max(1.0);
                (!ok).then(|| format!("{path}: expected {x}, got {y}"))
            }
            (Value::Object(x), Value::Object(y)) => {
                for (k, va) in x {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    match y.get(k) {
                        Some(vb) => {
                            if let Some(d) = walk(&p, va, vb, tol) {
                                return Some(d);
                            }
                        }
                        None => return Some(format!("{p}: missing")),
                    }
                }
                y.keys().find(|k| !x.contains_key(*k)).map(|k| {
                    format!(
                        "{path}{}{k}: not in the recording",
                        if path.is_empty() { "" } else { "." }
                    )
                })
            }
            (Value::Array(x), Value::Array(y)) => {
                if x.len() != y.len() {
                    return Some(format!(
                        "{path}: {} items expected, got {}",
                        x.len(),
                        y.len()
                    ));
                }
                x.iter()
                    .zip(y)
                    .enumerate()
                    .find_map(|(i, (va, vb))| walk(&format!("{path}[{i}]"), va, vb, tol))
            }
            _ => (a != b).then(|| format!("{path}: expected {a}, got {b}")),
        }
    }
    walk("", expected, got, tol)
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::blocking::Client;
    use std::time::Duration;

    const STOP: &str = r#"{"STOP_TIME":64,"TIME":3.5,"command":"STOP"}"#;

    fn trace(dir: &Path) -> PathBuf {
        let lines = [
            r#"{"seq":0,"dir":"to_world","len":36,"msg":{"command":"ADVANCE_TIME","time":32},"world_ms":2000}"#.to_string(),
            r#"{"seq":1,"dir":"to_world","len":18,"msg":{"command":"STOP"},"world_ms":2032}"#.to_string(),
            format!(r#"{{"seq":2,"dir":"to_platform","len":{},"msg":{STOP},"world_ms":2096}}"#, STOP.len()),
        ];
        let p = dir.join("t.trace");
        std::fs::write(&p, lines.join("\n") + "\n").unwrap();
        p
    }

    fn run(requests: &[&str]) -> (ReplayReport, Vec<Vec<u8>>) {
        let dir = tempfile::tempdir().unwrap();
        let ex = load_trace(&trace(dir.path())).unwrap();
        assert_eq!(ex.len(), 2);
        assert!(ex[0].reply.is_none());
        let ep = Endpoint::Unix(dir.path().join("r.sock"));
        let ep2 = ep.clone();
        let server = std::thread::spawn(move || serve(&ep2, &ex, &ReplayOptions::default()));
        let mut c = Client::connect_retry(&ep, Options::default(), Duration::from_secs(5)).unwrap();
        let mut replies = Vec::new();
        for r in requests {
            c.send_raw(r.as_bytes()).unwrap();
            if r.contains("STOP") {
                replies.push(c.recv_raw().unwrap().unwrap().to_vec());
            }
        }
        drop(c);
        (server.join().unwrap().unwrap(), replies)
    }

    #[test]
    fn replies_are_the_recorded_bytes() {
        let (report, replies) = run(&[
            r#"{"command":"ADVANCE_TIME","time":32}"#,
            r#"{"command":"STOP"}"#,
        ]);
        assert_eq!(replies, [STOP.as_bytes().to_vec()]);
        assert_eq!(
            report,
            ReplayReport {
                requests: 2,
                first_difference: None,
                complete: true
            }
        );
    }

    #[test]
    fn the_first_differing_request_is_reported() {
        let (report, replies) = run(&[
            r#"{"command":"ADVANCE_TIME","time":64}"#,
            r#"{"command":"STOP"}"#,
        ]);
        assert_eq!(replies.len(), 1);
        assert_eq!(
            report.first_difference,
            Some((0, "time: expected 32, got 64".into()))
        );
    }

    #[test]
    fn a_verbatim_trace_is_required() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.trace");
        std::fs::write(&p, "{\"seq\":0,\"dir\":\"to_world\",\"len\":18,\"msg\":{\"command\":\"STOP\"}}\n{\"seq\":1,\"dir\":\"to_platform\",\"len\":5,\"msg\":{\"command\":\"STOP\"}}\n").unwrap();
        let e = load_trace(&p).unwrap_err().to_string();
        assert!(e.contains("not a verbatim trace"), "{e}");
    }
}
