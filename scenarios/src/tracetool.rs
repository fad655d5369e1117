//! Reading traces (DESIGN.md §2): `cosim trace show` (a readable listing)
//! and `cosim trace-check` (a trace's requests sent to a live world server,
//! its replies compared with the recorded ones).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use protocol::blocking::{Client, Options};
use protocol::trace::{Direction, TraceReader, TraceRecord};
use protocol::{decode_reply, sha256_hex, Endpoint, Reply};
use serde_json::Value;

pub use world_server::replay::diff_json;

/// Why a trace could not be shown or checked.
#[derive(Debug, thiserror::Error)]
pub enum TraceToolError {
    #[error("{0}")]
    Io(String),
    #[error("{path}: {message}")]
    Trace { path: PathBuf, message: String },
    #[error("world server: {0}")]
    World(String),
}

/// Reads every record of a trace (a partial last line is reported, not fatal).
pub fn read_trace(path: &Path) -> Result<Vec<TraceRecord>, TraceToolError> {
    let terr = |message: String| TraceToolError::Trace {
        path: path.to_path_buf(),
        message,
    };
    let mut reader = TraceReader::open(path).map_err(|e| TraceToolError::Io(e.to_string()))?;
    let mut out = Vec::new();
    for r in reader.by_ref() {
        out.push(r.map_err(|e| terr(e.to_string()))?);
    }
    if let Some(t) = reader.truncated() {
        tracing::warn!(
            "{}: line {} is cut short ({} bytes), ignored",
            path.display(),
            t.line,
            t.bytes
        );
    }
    Ok(out)
}

fn short_value(v: &Value) -> String {
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(f) if n.is_f64() => format!("{f:.6}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string(),
            _ => n.to_string(),
        },
        Value::String(s) if s.len() > 24 => format!("{}…", &s[..16]),
        Value::String(s) => s.clone(),
        Value::Array(a) => format!("[{} items]", a.len()),
        Value::Object(o) => {
            let inner: Vec<String> = o
                .iter()
                .map(|(k, v)| format!("{k}={}", short_value(v)))
                .collect();
            format!("{{{}}}", inner.join(" "))
        }
        other => other.to_string(),
    }
}

/// One record as a line: sequence, clock, direction, command, fields.
pub fn format_record(r: &TraceRecord, full: bool) -> String {
    let clock = match (r.world_ms, r.platform_ps) {
        (Some(ms), _) => format!("{:>10.3} s", ms as f64 / 1000.0),
        (None, Some(ps)) => format!("{:>10.6} s", ps as f64 / 1e12),
        _ => " ".repeat(12),
    };
    let arrow = match r.dir {
        Direction::ToWorld => "→ world   ",
        Direction::ToPlatform => "← platform",
    };
    let cmd = r.command().unwrap_or("?");
    let fields = if full {
        r.msg.to_string()
    } else {
        match &r.msg {
            Value::Object(o) => o
                .iter()
                .filter(|(k, _)| k.as_str() != "command")
                .map(|(k, v)| format!("{k}={}", short_value(v)))
                .collect::<Vec<_>>()
                .join(" "),
            other => short_value(other),
        }
    };
    // A world with several drones marks every line with its drone.
    let drone = r
        .drone
        .as_deref()
        .map_or(String::new(), |d| format!("[{d}] "));
    format!(
        "{:>7} {clock} {arrow} {drone}{cmd:<13} {:>7} B  {fields}",
        r.seq, r.len
    )
}

/// The records of one drone (a world trace of several drones has a
/// `"drone"` on every line; a platform's trace has none and is kept whole).
pub fn only_drone(records: Vec<TraceRecord>, drone: &str) -> Vec<TraceRecord> {
    if records.iter().all(|r| r.drone.is_none()) {
        return records;
    }
    records
        .into_iter()
        .filter(|r| r.drone.as_deref() == Some(drone))
        .collect()
}

/// The drones of a trace, in order of first appearance (empty for a trace
/// of one drone).
pub fn trace_drones(records: &[TraceRecord]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in records {
        if let Some(d) = &r.drone {
            if !out.contains(d) {
                out.push(d.clone());
            }
        }
    }
    out
}

/// Writes the lines of `path` that belong to `drone` into `dest`, byte for
/// byte (what `cosim replay --drone` serves to one platform). Returns how
/// many lines were kept.
pub fn extract_drone(path: &Path, drone: &str, dest: &Path) -> Result<usize, TraceToolError> {
    // Either form (`world.trace` or `world.trace.zst`).
    let text = protocol::series::read(path)
        .map_err(|e| TraceToolError::Io(e.to_string()))
        .and_then(|t| {
            String::from_utf8(t.bytes)
                .map_err(|e| TraceToolError::Io(format!("{}: {e}", path.display())))
        })?;
    let mut kept = String::new();
    let mut n = 0;
    for (i, line) in text.lines().enumerate() {
        let r: TraceRecord = match serde_json::from_str(line) {
            Ok(r) => r,
            // A cut last line (a writer that crashed) is left out, as the
            // reader does.
            Err(_) if i + 1 == text.lines().count() => break,
            Err(e) => {
                return Err(TraceToolError::Trace {
                    path: path.to_path_buf(),
                    message: format!("line {}: {e}", i + 1),
                })
            }
        };
        if r.drone.as_deref() == Some(drone) {
            kept.push_str(line);
            kept.push('\n');
            n += 1;
        }
    }
    std::fs::write(dest, kept)
        .map_err(|e| TraceToolError::Io(format!("{}: {e}", dest.display())))?;
    Ok(n)
}

/// `cosim trace show`: the listing, filtered by command, then totals.
pub fn show(
    records: &[TraceRecord],
    command: Option<&str>,
    drone: Option<&str>,
    limit: Option<usize>,
    full: bool,
) -> String {
    let mut out = String::new();
    let mut shown = 0usize;
    let mut per_command: BTreeMap<(String, &'static str), (u64, u64)> = BTreeMap::new();
    for r in records {
        let cmd = r.command().unwrap_or("?").to_string();
        if let (Some(want), Some(d)) = (drone, &r.drone) {
            if want != d {
                continue;
            }
        }
        let e = per_command
            .entry((cmd.clone(), r.dir.as_str()))
            .or_default();
        e.0 += 1;
        e.1 += r.len;
        if command.is_some_and(|c| !c.eq_ignore_ascii_case(&cmd)) {
            continue;
        }
        if limit.is_some_and(|l| shown >= l) {
            continue;
        }
        shown += 1;
        out += &format_record(r, full);
        out.push('\n');
    }
    let _ = writeln!(
        out,
        "-- {} frames; per command and direction:",
        records.len()
    );
    for ((cmd, dir), (n, bytes)) in per_command {
        let _ = writeln!(
            out,
            "   {cmd:<14} {dir:<12} {n:>8} frames {bytes:>12} bytes"
        );
    }
    out
}

/// Compares a live reply with a recorded one. Images are compared by the
/// SHA-256 of their pixels (the recording keeps only the hash unless it
/// was made with `--trace-images`).
pub fn compare_reply(recorded: &Value, body: &[u8], tol: f64) -> Option<String> {
    let got: Value = match serde_json::from_slice(body) {
        Ok(v) => v,
        Err(e) => return Some(format!("the reply is not JSON: {e}")),
    };
    if let Some(cam) = recorded.get("camera") {
        let expected_sha = match cam.get("sha256").and_then(Value::as_str) {
            Some(s) => s.to_string(),
            None => match decode_reply(recorded.to_string().as_bytes()) {
                Ok(Reply::Image(img)) => sha256_hex(&img.data),
                _ => return Some("the recorded image cannot be decoded".into()),
            },
        };
        return match decode_reply(body) {
            Ok(Reply::Image(img)) => {
                let w = cam.get("width").and_then(Value::as_u64);
                let h = cam.get("height").and_then(Value::as_u64);
                if w != Some(img.width.into()) || h != Some(img.height.into()) {
                    Some(format!(
                        "camera: expected {w:?}x{h:?}, got {}x{}",
                        img.width, img.height
                    ))
                } else if sha256_hex(&img.data) != expected_sha {
                    Some("camera.data: the pixels differ (SHA-256)".into())
                } else {
                    None
                }
            }
            Ok(other) => Some(format!(
                "command: expected GET_IMAGE, got {}",
                other.command()
            )),
            Err(e) => Some(format!("the image reply does not decode: {e}")),
        };
    }
    diff_json(recorded, &got, tol)
}

/// The result of `trace-check`.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// Requests sent.
    pub requests: usize,
    /// Replies compared.
    pub replies: usize,
    /// The first difference: (sequence number of the recorded reply,
    /// command, what differs).
    pub first_difference: Option<(u64, String, String)>,
}

/// A world server started for a check, killed when dropped.
pub struct WorldProcess {
    child: Child,
    _dir: tempfile::TempDir,
    pub endpoint: Endpoint,
}

impl Drop for WorldProcess {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Starts `command` through `sh -c` on a fresh private socket; `{socket}`
/// in the command is replaced by the socket path (also in `COSIM_SOCKET`).
pub fn start_world(command: &str) -> Result<WorldProcess, TraceToolError> {
    let dir = tempfile::Builder::new()
        .prefix("cosim-check-")
        .tempdir()
        .map_err(|e| TraceToolError::Io(format!("cannot create a socket directory: {e}")))?;
    let socket = dir.path().join("world.sock");
    let cmd = command.replace("{socket}", &socket.display().to_string());
    // `exec`: the shell becomes the world server, so killing the child
    // kills the server and not just a shell that started it.
    let child = Command::new("sh")
        .arg("-c")
        .arg(format!("exec {cmd}"))
        .env("COSIM_SOCKET", &socket)
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| TraceToolError::World(format!("cannot start `{cmd}`: {e}")))?;
    Ok(WorldProcess {
        child,
        _dir: dir,
        endpoint: Endpoint::Unix(socket),
    })
}

/// The basicTimeStep a trace was recorded with (its GET_INIT_DATA reply).
pub fn trace_timestep(records: &[TraceRecord]) -> Option<u64> {
    records
        .iter()
        .find(|r| r.dir == Direction::ToPlatform && r.command() == Some("GET_INIT_DATA"))
        .and_then(|r| r.msg.get("TIMESTEP"))
        .and_then(Value::as_u64)
}

/// [`check`] for a trace of several drones: one connection per drone, each
/// sending its drone's requests in order from its own thread (the world's
/// lockstep orders them as in the recording, docs/SWARM.md §2). The first
/// difference is the one with the smallest sequence number: once a drone
/// differs, the others see the world's ERROR after it.
pub fn check_drones(
    records: &[TraceRecord],
    endpoint: &Endpoint,
    tol: f64,
    patience: Duration,
) -> Result<CheckReport, TraceToolError> {
    let drones = trace_drones(records);
    if drones.is_empty() {
        return check(records, endpoint, tol, patience);
    }
    let per: Vec<Vec<TraceRecord>> = drones
        .iter()
        .map(|d| only_drone(records.to_vec(), d))
        .collect();
    let results: Vec<Result<CheckReport, TraceToolError>> = std::thread::scope(|scope| {
        let handles: Vec<_> = per
            .iter()
            .map(|recs| scope.spawn(move || check(recs, endpoint, tol, patience)))
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(TraceToolError::World("a check thread panicked".into()))
                })
            })
            .collect()
    });
    let mut total = CheckReport {
        requests: 0,
        replies: 0,
        first_difference: None,
    };
    let mut first_error = None;
    for (d, r) in drones.iter().zip(results) {
        match r {
            Ok(r) => {
                total.requests += r.requests;
                total.replies += r.replies;
                if let Some((seq, cmd, what)) = r.first_difference {
                    if total.first_difference.as_ref().is_none_or(|f| seq < f.0) {
                        total.first_difference = Some((seq, format!("{cmd} of {d}"), what));
                    }
                }
            }
            Err(e) => {
                first_error.get_or_insert(TraceToolError::World(format!("drone {d}: {e}")));
            }
        }
    }
    match (first_error, &total.first_difference) {
        // A difference explains why another drone's connection broke.
        (Some(e), None) => Err(e),
        _ => Ok(total),
    }
}

/// Sends the trace's requests to the world at `endpoint` in order and
/// compares every reply with the recorded one; stops at the first
/// difference (after it the two worlds are in different states anyway).
pub fn check(
    records: &[TraceRecord],
    endpoint: &Endpoint,
    tol: f64,
    patience: Duration,
) -> Result<CheckReport, TraceToolError> {
    let mut conn = Client::connect_retry(endpoint, Options::default(), patience)
        .map_err(|e| TraceToolError::World(format!("cannot connect to {endpoint}: {e}")))?;
    let mut report = CheckReport {
        requests: 0,
        replies: 0,
        first_difference: None,
    };
    let mut i = 0;
    while i < records.len() {
        let r = &records[i];
        i += 1;
        if r.dir != Direction::ToWorld {
            continue;
        }
        let body = serde_json::to_vec(&r.msg).expect("a JSON value serializes");
        conn.send_raw(&body)
            .map_err(|e| TraceToolError::World(format!("sending #{}: {e}", r.seq)))?;
        report.requests += 1;
        let Some(rec) = records.get(i).filter(|n| n.dir == Direction::ToPlatform) else {
            continue;
        };
        i += 1;
        let cmd = rec.command().unwrap_or("?").to_string();
        let reply = match conn.recv_raw() {
            Ok(Some(b)) => b.to_vec(),
            Ok(None) => {
                report.first_difference = Some((
                    rec.seq,
                    cmd,
                    "the world closed the connection instead of replying".into(),
                ));
                return Ok(report);
            }
            Err(e) => {
                return Err(TraceToolError::World(format!(
                    "reading the reply to #{}: {e}",
                    r.seq
                )))
            }
        };
        report.replies += 1;
        if let Some(d) = compare_reply(&rec.msg, &reply, tol) {
            report.first_difference = Some((rec.seq, cmd, d));
            return Ok(report);
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn numbers_within_the_tolerance_are_equal() {
        let a = json!({"command":"GET_SENSORS","TIME":2.0,"X":1.0});
        assert_eq!(
            diff_json(
                &a,
                &json!({"command":"GET_SENSORS","TIME":2.0,"X":1.0 + 1e-12}),
                1e-9
            ),
            None
        );
        let d = diff_json(
            &a,
            &json!({"command":"GET_SENSORS","TIME":2.0,"X":1.1}),
            1e-9,
        )
        .unwrap();
        assert!(d.starts_with("X: expected 1"), "{d}");
        let d = diff_json(&a, &json!({"command":"GET_SENSORS","TIME":2.0}), 1e-9).unwrap();
        assert_eq!(d, "X: missing");
        let d = diff_json(&a, &json!({"command":"STOP","TIME":2.0,"X":1.0}), 1e-9).unwrap();
        assert!(d.starts_with("command: expected"), "{d}");
    }

    #[test]
    fn a_drone_is_picked_out_of_a_world_trace_line_for_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("world.trace");
        let lines = [
            r#"{"seq":0,"dir":"to_world","len":2,"msg":{"command":"GET_INIT_DATA","drone":"A"},"world_ms":2000,"drone":"A"}"#,
            r#"{"seq":1,"dir":"to_world","len":2,"msg":{"command":"GET_INIT_DATA","drone":"B"},"world_ms":2000,"drone":"B"}"#,
            r#"{"seq":2,"dir":"to_platform","len":2,"msg":{"command":"GET_INIT_DATA","drone":"A"},"world_ms":2000,"drone":"A"}"#,
        ];
        std::fs::write(&p, lines.join("\n") + "\n").unwrap();
        let records = read_trace(&p).unwrap();
        assert_eq!(trace_drones(&records), ["A", "B"]);
        let a = only_drone(records.clone(), "A");
        assert_eq!(a.iter().map(|r| r.seq).collect::<Vec<_>>(), [0, 2]);
        let dest = dir.path().join("a.trace");
        assert_eq!(extract_drone(&p, "A", &dest).unwrap(), 2);
        assert_eq!(
            std::fs::read_to_string(&dest).unwrap(),
            format!("{}\n{}\n", lines[0], lines[2])
        );
        let listing = show(&records, None, Some("B"), None, false);
        assert!(
            listing.contains("[B] GET_INIT_DATA") && !listing.contains("[A]"),
            "{listing}"
        );
        assert!(listing.contains("-- 3 frames"), "{listing}");
    }

    #[test]
    fn images_compare_by_their_pixels() {
        let img = protocol::Image {
            width: 2,
            height: 1,
            data: vec![3, 4],
        };
        let mut body = Vec::new();
        protocol::encode_reply(
            &Reply::Image(img.clone()),
            protocol::ImageEncoding::Array,
            &mut body,
        );
        let rec = json!({"command":"GET_IMAGE","camera":{"width":2,"height":1,"sha256":sha256_hex(&[3, 4])}});
        assert_eq!(compare_reply(&rec, &body, 0.0), None);
        let rec = json!({"command":"GET_IMAGE","camera":{"width":2,"height":1,"sha256":sha256_hex(&[3, 5])}});
        assert!(compare_reply(&rec, &body, 0.0).unwrap().contains("pixels"));
    }
}
