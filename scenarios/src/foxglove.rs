//! `run.mcap`: a run for Foxglove (DESIGN.md §15, docs/FOXGLOVE.md).
//!
//! The world writes what it sees live (`world-server --mcap`, into
//! `world.mcap`: transforms, scene, camera frames, motors, radio; see
//! `world_server::foxglove`); the platforms write their power log
//! (`power.csv`, 1 ms rows) as they always did, and a mapping run's map is
//! known only at its end (`map.csv`). After the run, [`write_run_mcap`]
//! merges the three into one `run.mcap` sorted by log time (world time in
//! ns; ties keep the world's messages first, then the drones' in
//! `[[platform]]` order) and removes `world.mcap`. A world that died
//! leaves a truncated `world.mcap`: its messages up to the break are kept
//! and the result is a complete file with a summary.

use std::borrow::Cow;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::outputs::files::{RUN_MCAP, WORLD_MCAP};
use base64::Engine as _;
use serde_json::json;
use sim_core::sync::time_map::{world_at, Knot, TIME_MAP_CSV};
use world_server::foxglove::{
    drone_topic, schemas, stamp, write_message, write_options, Channels, KnownChannels,
};

/// Default for the `mcap_power_every` key: every 10th 1 ms row of
/// `power.csv` (100 Hz) goes into `run.mcap`. Every row made the race's
/// file 103 MB, 70 MB of it these channels; 100 Hz still resolves the
/// motors' current steps in a plot, and `power.csv` keeps every row.
pub const DEFAULT_POWER_EVERY: u64 = 10;

/// Why `run.mcap` could not be written.
#[derive(Debug, thiserror::Error)]
pub enum McapMergeError {
    #[error("cannot read {path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
}

/// One platform's outputs to merge.
#[derive(Debug, Clone)]
pub struct DroneOutputs {
    /// Its name in the world (`cf1` in a world without `[[drone]]`).
    pub name: String,
    /// The directory with its `power.csv` (and `map.csv`).
    pub dir: PathBuf,
    /// Cell side of its `map.csv` (m), when it left a map.
    pub map_cell_m: Option<f64>,
}

/// What the merge wrote.
#[derive(Debug, Clone)]
pub struct Merged {
    pub path: PathBuf,
    pub messages: usize,
    /// Something that was not whole (a truncated `world.mcap`).
    pub warning: Option<String>,
}

type Channel = Arc<mcap::Channel<'static>>;

struct Msg {
    log_time: u64,
    channel: Channel,
    data: Cow<'static, [u8]>,
}

/// [`write_run_mcap`] on a thread of its own (the caller draws its plots
/// meanwhile); collect it with [`join`].
pub fn spawn_run_mcap(
    out: &Path,
    drones: Vec<DroneOutputs>,
    power_every: u64,
) -> std::thread::JoinHandle<Result<Merged, McapMergeError>> {
    let out = out.to_path_buf();
    std::thread::spawn(move || write_run_mcap(&out, &drones, power_every))
}

/// The result of [`spawn_run_mcap`]; a panic on its thread is an error.
pub fn join(
    job: std::thread::JoinHandle<Result<Merged, McapMergeError>>,
) -> Result<Merged, McapMergeError> {
    job.join().unwrap_or_else(|_| {
        Err(McapMergeError::Write {
            path: PathBuf::from(RUN_MCAP),
            message: "the writer thread panicked".into(),
        })
    })
}

/// Writes `out/run.mcap` from `out/world.mcap` (if the world wrote one)
/// and each drone's outputs, then removes `world.mcap`. Of each
/// `power.csv`, every `power_every`th row and the last go in (0: none).
pub fn write_run_mcap(
    out: &Path,
    drones: &[DroneOutputs],
    power_every: u64,
) -> Result<Merged, McapMergeError> {
    let world_path = out.join(WORLD_MCAP);
    let (mut msgs, warning, max_schema, max_channel) = read_world(&world_path)?;
    let mut channels = Channels::after(max_schema, max_channel);
    for d in drones {
        if power_every > 0 {
            read_power(&d.dir, &d.name, power_every, &mut channels, &mut msgs)?;
        }
    }
    // Stable: the world's messages first at equal times, then the drones'.
    msgs.sort_by_key(|m| m.log_time);
    let end = msgs.last().map_or(0, |m| m.log_time);
    for d in drones {
        if let Some(cell) = d.map_cell_m {
            let path = d.dir.join(crate::outputs::map_files::MAP_CSV);
            let grid = read_map(&path, cell)?;
            let channel = channels.foxglove(&drone_topic(&d.name, "map"), schemas::GRID);
            let mut grid = grid;
            grid["timestamp"] = stamp(end);
            msgs.push(Msg {
                log_time: end,
                channel,
                data: Cow::Owned(serde_json::to_vec(&grid).expect("JSON serialises")),
            });
        }
    }
    let path = out.join(RUN_MCAP);
    let werr = |e: &dyn std::fmt::Display| McapMergeError::Write {
        path: path.clone(),
        message: e.to_string(),
    };
    let file = File::create(&path).map_err(|e| werr(&e))?;
    let mut w = write_options()
        .create(BufWriter::with_capacity(1 << 20, file))
        .map_err(|e| werr(&e))?;
    let mut known = KnownChannels::default();
    for (i, m) in msgs.iter().enumerate() {
        let sequence = (i as u32).wrapping_add(1);
        write_message(
            &mut w, &mut known, &m.channel, sequence, m.log_time, &m.data,
        )
        .map_err(|e| werr(&e))?;
    }
    w.finish().map_err(|e| werr(&e))?;
    drop(w);
    if world_path.exists() {
        std::fs::remove_file(&world_path).map_err(|e| McapMergeError::Write {
            path: world_path.clone(),
            message: e.to_string(),
        })?;
    }
    Ok(Merged {
        path,
        messages: msgs.len(),
        warning,
    })
}

/// The world's messages in file order, what went wrong reading them, and
/// the largest schema and channel ids (new channels go after them).
#[allow(clippy::type_complexity)]
fn read_world(path: &Path) -> Result<(Vec<Msg>, Option<String>, u16, u16), McapMergeError> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok((Vec::new(), None, 0, 0));
        }
        Err(e) => {
            return Err(McapMergeError::Read {
                path: path.to_path_buf(),
                message: e.to_string(),
            })
        }
    };
    let mut msgs = Vec::new();
    let (mut max_schema, mut max_channel) = (0u16, 0u16);
    let mut warning = None;
    // A world killed mid-run leaves no summary and no end magic.
    let stream =
        mcap::MessageStream::new_with_options(&bytes, mcap::read::Options::IgnoreEndMagic.into())
            .map_err(|e| McapMergeError::Read {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    for m in stream {
        match m {
            Ok(m) => {
                max_channel = max_channel.max(m.channel.id);
                if let Some(s) = &m.channel.schema {
                    max_schema = max_schema.max(s.id);
                }
                msgs.push(Msg {
                    log_time: m.log_time,
                    channel: m.channel,
                    data: m.data,
                });
            }
            Err(e) => {
                warning = Some(format!(
                    "{}: {e} after {} messages (the world did not finish it); kept those",
                    path.display(),
                    msgs.len()
                ));
                break;
            }
        }
    }
    Ok((msgs, warning, max_schema, max_channel))
}

/// `power.csv` → `/D/power` (every column) and `/D/battery` (voltage, SOC,
/// current, open-circuit voltage, low flag): rows 0, `every`, 2·`every`, …
/// and the last (so the file ends on the summary's SOC).
fn read_power(
    dir: &Path,
    drone: &str,
    every: u64,
    channels: &mut Channels,
    msgs: &mut Vec<Msg>,
) -> Result<(), McapMergeError> {
    let path = dir.join(sim_core::power::log::POWER_CSV);
    let rerr = |e: &dyn std::fmt::Display| McapMergeError::Read {
        path: path.clone(),
        message: e.to_string(),
    };
    // A platform that died before writing its log: nothing to merge.
    if !protocol::series::exists(&path) {
        return Ok(());
    }
    // Of a log whose writer died, its valid prefix (the report says what
    // was dropped).
    let text = protocol::series::read(&path).map_err(|e| rerr(&e))?;
    let mut r = csv::Reader::from_reader(&text.bytes[..]);
    // Its rows carry platform time; the file's log time is the world's.
    let time_map = read_time_map(dir)?;
    let header = r.byte_headers().map_err(|e| rerr(&e))?.clone();
    let names: Vec<String> = header
        .iter()
        .map(|h| String::from_utf8_lossy(h).into_owned())
        .collect();
    let col = |n: &str| names.iter().position(|h| h == n);
    let t_ps = col("t_ps").ok_or_else(|| rerr(&"no t_ps column"))?;
    let battery_cols: Vec<(&str, usize)> = [
        ("voltage_v", "v_battery_v"),
        ("soc", "soc"),
        ("current_a", "i_battery_a"),
        ("v_oc_v", "v_oc_v"),
        ("low_battery", "low_battery"),
    ]
    .into_iter()
    .filter_map(|(k, c)| col(c).map(|i| (k, i)))
    .collect();
    let power_schema = schemas::plain(
        "cosim.Power",
        &names
            .iter()
            .filter(|n| n.as_str() != "t_ps" && n.as_str() != "power_model")
            .map(|n| (n.as_str(), "number", "a power.csv column (docs/COSIM.md)"))
            .collect::<Vec<_>>(),
    );
    let battery_schema = schemas::plain(
        "cosim.Battery",
        &[
            ("time_s", "number", "world time"),
            ("voltage_v", "number", "terminal voltage"),
            ("soc", "number", "state of charge, 0-1"),
            ("current_a", "number", "battery current"),
            ("v_oc_v", "number", "open-circuit voltage"),
            (
                "low_battery",
                "number",
                "1 once below the firmware's threshold",
            ),
        ],
    );
    let mut power = channels.add(&drone_topic(drone, "power"), &power_schema);
    // The first row's model (the column is the same on every row).
    let mut first = csv::ByteRecord::new();
    let has_first = r.read_byte_record(&mut first).map_err(|e| rerr(&e))?;
    if let (true, Some(i)) = (has_first, col("power_model")) {
        let model = String::from_utf8_lossy(&first[i]).into_owned();
        Arc::make_mut(&mut power)
            .metadata
            .insert("power_model".into(), model);
    }
    let battery = channels.add(&drone_topic(drone, "battery"), &battery_schema);
    // `"name":` of each column, escaped once.
    let key = |k: &str| {
        let mut v = Vec::new();
        json_key(&mut v, k);
        v
    };
    // t_ps is the log time; power_model (one value for the whole log) goes
    // into the channel's metadata: 1 ms rows are the merge's bulk.
    let skip = |n: &str| n == "t_ps" || n == "power_model";
    let power_keys: Vec<(Vec<u8>, usize)> = names
        .iter()
        .enumerate()
        .filter(|(_, n)| !skip(n))
        .map(|(i, n)| (key(n), i))
        .collect();
    let battery_keys: Vec<(Vec<u8>, usize)> =
        battery_cols.iter().map(|(k, i)| (key(k), *i)).collect();
    let time_key = key("time_s");
    let mut rec = first;
    let mut next = csv::ByteRecord::new();
    let mut more = has_first;
    let mut row: u64 = 0;
    while more {
        let has_next = r.read_byte_record(&mut next).map_err(|e| rerr(&e))?;
        let keep = row.is_multiple_of(every) || !has_next;
        row += 1;
        if !keep {
            std::mem::swap(&mut rec, &mut next);
            more = has_next;
            continue;
        }
        let Some(t) = std::str::from_utf8(&rec[t_ps])
            .ok()
            .and_then(|s| s.parse::<u64>().ok())
        else {
            return Err(rerr(&format!(
                "bad t_ps {:?}",
                String::from_utf8_lossy(&rec[t_ps])
            )));
        };
        let t_ns = world_ps(&time_map, t) / 1000;
        let mut p = Vec::with_capacity(512);
        p.push(b'{');
        for (j, (k, i)) in power_keys.iter().enumerate() {
            if j > 0 {
                p.push(b',');
            }
            p.extend_from_slice(k);
            json_field(&mut p, &rec[*i]);
        }
        p.push(b'}');
        let mut b = Vec::with_capacity(160);
        b.push(b'{');
        b.extend_from_slice(&time_key);
        // The world's time of the row (power.csv's time_s is the platform's).
        b.extend_from_slice((t_ns as f64 * 1e-9).to_string().as_bytes());
        for (k, i) in &battery_keys {
            b.push(b',');
            b.extend_from_slice(k);
            json_field(&mut b, &rec[*i]);
        }
        b.push(b'}');
        msgs.push(Msg {
            log_time: t_ns,
            channel: power.clone(),
            data: Cow::Owned(p),
        });
        msgs.push(Msg {
            log_time: t_ns,
            channel: battery.clone(),
            data: Cow::Owned(b),
        });
        std::mem::swap(&mut rec, &mut next);
        more = has_next;
    }
    Ok(())
}

/// The platform's `time_map.csv` (platform → world time, DESIGN.md §3):
/// none from a platform that did not write one (it died first), whose
/// rows then keep their platform time.
fn read_time_map(dir: &Path) -> Result<Option<Vec<Knot>>, McapMergeError> {
    let path = dir.join(TIME_MAP_CSV);
    let rerr = |e: &dyn std::fmt::Display| McapMergeError::Read {
        path: path.clone(),
        message: e.to_string(),
    };
    // Either form; none from a platform that died before writing it.
    if !protocol::series::exists(&path) {
        return Ok(None);
    }
    let text = protocol::series::read(&path).map_err(|e| rerr(&e))?;
    let mut r = csv::Reader::from_reader(&text.bytes[..]);
    let knots = r
        .deserialize::<Knot>()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| rerr(&e))?;
    if knots.windows(2).any(|w| w[1].0 < w[0].0) {
        return Err(rerr(&"platform times out of order"));
    }
    Ok(Some(knots))
}

/// World time (ps, never negative) of the platform time `t_ps`.
fn world_ps(map: &Option<Vec<Knot>>, t_ps: u64) -> u64 {
    match map {
        Some(knots) => world_at(knots, t_ps).max(0) as u64,
        None => t_ps,
    }
}

fn json_key(out: &mut Vec<u8>, key: &str) {
    serde_json::to_writer(&mut *out, key).expect("writing to a Vec cannot fail");
    out.push(b':');
}

/// A CSV field as JSON: numbers as they are written (the logs use Rust's
/// shortest round-trip formatting, valid JSON), anything else as a string.
fn json_field(out: &mut Vec<u8>, field: &[u8]) {
    if is_json_number(field) {
        out.extend_from_slice(field);
    } else {
        let s = String::from_utf8_lossy(field);
        serde_json::to_writer(&mut *out, s.as_ref()).expect("writing to a Vec cannot fail");
    }
}

/// RFC 8259's number: `-? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?`.
fn is_json_number(s: &[u8]) -> bool {
    let mut i = 0;
    let digits = |i: &mut usize| {
        let start = *i;
        while *i < s.len() && s[*i].is_ascii_digit() {
            *i += 1;
        }
        *i - start
    };
    if s.first() == Some(&b'-') {
        i += 1;
    }
    match s.get(i) {
        Some(b'0') => i += 1,
        Some(b'1'..=b'9') => {
            digits(&mut i);
        }
        _ => return false,
    }
    if s.get(i) == Some(&b'.') {
        i += 1;
        if digits(&mut i) == 0 {
            return false;
        }
    }
    if matches!(s.get(i), Some(b'e' | b'E')) {
        i += 1;
        if matches!(s.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        if digits(&mut i) == 0 {
            return false;
        }
    }
    i == s.len()
}

/// `map.csv` (`ix, iy, x, y, p_occupied`, −1 never observed) as a
/// `foxglove.Grid` of one INT8 field `occupancy`: 0–100 (percent), −1
/// unknown — the convention of ROS's OccupancyGrid, which Foxglove's grid
/// colouring understands.
fn read_map(path: &Path, cell_m: f64) -> Result<serde_json::Value, McapMergeError> {
    let rerr = |e: &dyn std::fmt::Display| McapMergeError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut r = csv::Reader::from_path(path).map_err(|e| rerr(&e))?;
    let mut cells: Vec<(usize, usize, f64, f64, f64)> = Vec::new();
    for row in r.deserialize::<(usize, usize, f64, f64, f64)>() {
        cells.push(row.map_err(|e| rerr(&e))?);
    }
    let width = cells.iter().map(|c| c.0 + 1).max().unwrap_or(0);
    let height = cells.iter().map(|c| c.1 + 1).max().unwrap_or(0);
    let Some(&(ix0, iy0, x0, y0, _)) = cells.first() else {
        return Err(rerr(&"no cells"));
    };
    let mut data = vec![-1i8 as u8; width * height];
    for &(ix, iy, _, _, p) in &cells {
        data[iy * width + ix] = if p < 0.0 {
            -1i8 as u8
        } else {
            (p * 100.0).round().clamp(0.0, 100.0) as u8
        };
    }
    // The corner of cell (0, 0) from any cell's centre.
    let ox = x0 - (ix0 as f64 + 0.5) * cell_m;
    let oy = y0 - (iy0 as f64 + 0.5) * cell_m;
    Ok(json!({
        "timestamp": stamp(0),
        "frame_id": "world",
        "pose": {"position": {"x": ox, "y": oy, "z": 0.0},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
        "column_count": width,
        "cell_size": {"x": cell_m, "y": cell_m},
        "row_stride": width,
        "cell_stride": 1,
        "fields": [{"name": "occupancy", "offset": 0, "type": 2}],
        "data": base64::engine::general_purpose::STANDARD.encode(&data),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_numbers_are_recognised_as_rfc_8259_has_them() {
        for ok in [
            "0",
            "-0.0",
            "1.5",
            "0.00014000000000000001",
            "1e-7",
            "2E+10",
            "42",
        ] {
            assert!(is_json_number(ok.as_bytes()), "{ok}");
        }
        for bad in [
            "",
            "-",
            "01",
            ".5",
            "1.",
            "+1",
            "inf",
            "NaN",
            "1e",
            "empirical",
            "1,2",
        ] {
            assert!(!is_json_number(bad.as_bytes()), "{bad}");
        }
    }

    #[test]
    fn a_map_becomes_an_int8_grid_with_its_corner_at_the_first_cell() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("map.csv");
        std::fs::write(
            &p,
            "ix,iy,x,y,p_occupied\n0,0,0.0250,1.0250,-1\n1,0,0.0750,1.0250,0.2689\n0,1,0.0250,1.0750,1\n1,1,0.0750,1.0750,0\n",
        )
        .unwrap();
        let g = read_map(&p, 0.05).unwrap();
        assert_eq!(g["column_count"], 2);
        assert!((g["pose"]["position"]["x"].as_f64().unwrap()).abs() < 1e-12);
        assert!((g["pose"]["position"]["y"].as_f64().unwrap() - 1.0).abs() < 1e-12);
        let data = base64::engine::general_purpose::STANDARD
            .decode(g["data"].as_str().unwrap())
            .unwrap();
        assert_eq!(data, vec![255, 27, 100, 0]);
    }
}
