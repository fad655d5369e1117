//! Seed 004's drone-to-drone radar (§4.3.2.A, §5.3 Tables 7–8;
//! docs/SWARM.md "Radar"): what a run of `radar.elf` gives, read back from
//! the platforms' consoles and the world's outputs — who detected whom,
//! the true distance at detection (the world's `radio.csv`: the frame the
//! firmware acted on, its `distance_m` at transmit time), the distance
//! after both landed (the seed measured that one), the closest approach and
//! the collisions — into `radar.json`; a sweep gathers its runs into
//! `radar.md` (Table 7 / 8 with mean ± std).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::report::{mean_sd_population, DroneTrack};

/// The file a radar run leaves in its directory.
pub const RADAR_JSON: &str = "radar.json";
/// The sweep's table.
pub const RADAR_MD: &str = "radar.md";

/// One run's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RadarRun {
    /// The drone that detected first (None: nobody did).
    pub detected_by: Option<String>,
    /// The drone it detected.
    pub detected: Option<String>,
    /// RSSI of the detecting packet, dBm.
    pub rssi_dbm: Option<f64>,
    /// World time at which that packet ended, s.
    pub time_s: Option<f64>,
    /// True centre distance when that packet left, m (radio.csv).
    pub distance_m: Option<f64>,
    /// Distance between the same two drones at the end of the run (both
    /// landed: what the seed measured), m.
    pub landed_distance_m: Option<f64>,
    /// Smallest distance between the detecting pair during the run, m.
    pub min_distance_m: Option<f64>,
    /// Drones whose firmware landed (a `RADAR end` line).
    pub landed: Vec<String>,
    /// Collisions counted by the world over all drones.
    pub collisions: Option<u64>,
}

/// `RADAR detect ...` of one console: (from id, rssi in 1/100 dBm).
fn detection(console: &str) -> Option<(u64, i64)> {
    let line = console.lines().find(|l| l.starts_with("RADAR detect "))?;
    let field = |k: &str| {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(k)?.strip_prefix('='))
    };
    Some((
        field("from")?.parse().ok()?,
        field("rssi_cdbm")?.parse().ok()?,
    ))
}

fn radar_id(console: &str) -> Option<u64> {
    let line = console.lines().find(|l| l.starts_with("RADAR start "))?;
    line.split_whitespace()
        .find_map(|w| w.strip_prefix("id="))?
        .parse()
        .ok()
}

/// A received p2p frame of radio.csv: (end_ps, from, to, distance_m, rssi).
type Frame = (u64, String, String, f64, f64);

/// Why a radar run cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum RadarError {
    #[error("{}: {source}", path.display())]
    Csv { path: PathBuf, source: csv::Error },
    #[error("{}: a malformed row", path.display())]
    MalformedRow { path: PathBuf },
    #[error("{drone} detected radio id {id}, which no drone has")]
    UnknownId { drone: String, id: u64 },
    #[error("{drone}'s detection of {from} is not in radio.csv")]
    NotInRadioLog { drone: String, from: String },
}

fn received_frames(path: &Path) -> Result<Vec<Frame>, RadarError> {
    let csv = |source| RadarError::Csv {
        path: path.to_path_buf(),
        source,
    };
    let mut r = csv::Reader::from_path(path).map_err(csv)?;
    let mut out = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(csv)?;
        if rec.get(2) != Some("p2p") || rec.get(7) != Some("received") {
            continue;
        }
        let num = |i: usize| rec.get(i).and_then(|v| v.parse::<f64>().ok());
        let (Some(end), Some(d), Some(rssi)) =
            (rec.get(1).and_then(|v| v.parse().ok()), num(5), num(6))
        else {
            return Err(RadarError::MalformedRow {
                path: path.to_path_buf(),
            });
        };
        out.push((end, rec[3].to_string(), rec[4].to_string(), d, rssi));
    }
    Ok(out)
}

/// Distance between two tracks at their last common point.
fn last_distance(a: &DroneTrack, b: &DroneTrack) -> Option<f64> {
    let (_, pa) = a.points.last()?;
    let (_, pb) = b.points.last()?;
    Some(dist(pa, pb))
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Reads a radar run in `out` (the drones' consoles under `out/<drone>/`,
/// `radio.csv`); None when no platform ran radar.elf.
pub fn read_run(
    out: &Path,
    drones: &[String],
    tracks: &BTreeMap<String, DroneTrack>,
    collisions: Option<u64>,
) -> Result<Option<RadarRun>, RadarError> {
    let mut ids = BTreeMap::new();
    let mut consoles = BTreeMap::new();
    for d in drones {
        let p = crate::outputs::drone_dir(out, d).join(crate::outputs::files::CONSOLE);
        let text = std::fs::read_to_string(&p).unwrap_or_default();
        if let Some(id) = radar_id(&text) {
            ids.insert(id, d.clone());
        }
        consoles.insert(d.clone(), text);
    }
    if ids.is_empty() {
        return Ok(None);
    }
    let frames = received_frames(&out.join(crate::outputs::swarm_files::RADIO_LOG))?;
    // The first detection in world time: each detecting drone's packet is
    // the earliest received frame from that sender with its RSSI.
    let mut best: Option<(String, String, Frame)> = None;
    for (d, text) in &consoles {
        let Some((from_id, cdbm)) = detection(text) else {
            continue;
        };
        let from = ids
            .get(&from_id)
            .cloned()
            .ok_or_else(|| RadarError::UnknownId {
                drone: d.clone(),
                id: from_id,
            })?;
        let f = frames
            .iter()
            .find(|f| &f.2 == d && f.1 == from && (f.4 * 100.0).round() as i64 == cdbm)
            .ok_or_else(|| RadarError::NotInRadioLog {
                drone: d.clone(),
                from: from.clone(),
            })?;
        if best.as_ref().is_none_or(|b| f.0 < b.2 .0) {
            best = Some((d.clone(), from, f.clone()));
        }
    }
    let landed = consoles
        .iter()
        .filter(|(_, t)| t.lines().any(|l| l.starts_with("RADAR end ")))
        .map(|(d, _)| d.clone())
        .collect();
    // Closest approach of the detecting pair (whole run, same world steps).
    let min_distance_m = best.as_ref().and_then(|(a, b, _)| {
        let (ta, tb) = (tracks.get(a)?, tracks.get(b)?);
        ta.points
            .iter()
            .zip(&tb.points)
            .filter(|((x, _), (y, _))| x == y)
            .map(|((_, pa), (_, pb))| dist(pa, pb))
            .reduce(f64::min)
    });
    let landed_distance_m = best
        .as_ref()
        .and_then(|(a, b, _)| last_distance(tracks.get(a)?, tracks.get(b)?));
    Ok(Some(RadarRun {
        detected_by: best.as_ref().map(|b| b.0.clone()),
        detected: best.as_ref().map(|b| b.1.clone()),
        rssi_dbm: best.as_ref().map(|b| b.2 .4),
        time_s: best.as_ref().map(|b| b.2 .0 as f64 * 1e-12),
        distance_m: best.as_ref().map(|b| b.2 .3),
        landed_distance_m,
        min_distance_m,
        landed,
        collisions,
    }))
}

/// The sweep's Table 7/8: one row per run; None unless every run directory
/// holds a readable radar.json (a sweep with a failed run gets no table).
pub fn sweep_table(runs: &[(String, PathBuf)]) -> Option<String> {
    let mut rows = Vec::new();
    for (label, dir) in runs {
        let text = std::fs::read_to_string(dir.join(RADAR_JSON)).ok()?;
        rows.push((label.clone(), serde_json::from_str::<RadarRun>(&text).ok()?));
    }
    if rows.is_empty() {
        return None;
    }
    let cm = |v: Option<f64>| v.map_or("-".into(), |m| format!("{:.0}", m * 100.0));
    let mut md = String::from(
        "| run | distance at detection (cm) | detected by | RSSI (dBm) | after landing (cm) | closest, same pair (cm) | world collisions (all drones) |\n|---|---|---|---|---|---|---|\n",
    );
    for (label, r) in &rows {
        md.push_str(&format!(
            "| {label} | {} | {} | {} | {} | {} | {} |\n",
            cm(r.distance_m),
            r.detected_by.as_deref().unwrap_or("nobody"),
            r.rssi_dbm.map_or("-".into(), |v| format!("{v:.1}")),
            cm(r.landed_distance_m),
            cm(r.min_distance_m),
            r.collisions.map_or("?".into(), |c| c.to_string()),
        ));
    }
    let at: Vec<f64> = rows.iter().filter_map(|(_, r)| r.distance_m).collect();
    let after: Vec<f64> = rows
        .iter()
        .filter_map(|(_, r)| r.landed_distance_m)
        .collect();
    let ms = |v: &[f64]| {
        mean_sd_population(v).map_or("-".into(), |(m, s)| {
            format!("{:.1} ± {:.1}", m * 100.0, s * 100.0)
        })
    };
    md.push_str(&format!(
        "\nDistance at detection: {} cm over {} detections of {} runs; after landing: {} cm. \
         Collisions: {}.\n",
        ms(&at),
        at.len(),
        rows.len(),
        ms(&after),
        rows.iter()
            .map(|(_, r)| r.collisions.unwrap_or(0))
            .sum::<u64>()
    ));
    Some(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_std_is_the_population_deviation_of_seed_004_tables_7_and_8() {
        // Table 7's eight distances: 117.88 ± 65.02 cm.
        let v = [156.0, 90.0, 195.0, 54.0, 170.0, 197.0, 58.0, 23.0];
        let (m, s) = mean_sd_population(&v).unwrap();
        assert!(
            (m - 117.875).abs() < 1e-9 && (s - 65.02).abs() < 0.01,
            "{m} {s}"
        );
    }

    #[test]
    fn console_lines_are_parsed() {
        let c = "RADAR start id=2 height_mm=500\nRADAR detect t_ms=1 id=2 from=1 seq=3 rssi_cdbm=-4198 x_mm=1\n";
        assert_eq!(radar_id(c), Some(2));
        assert_eq!(detection(c), Some((1, -4198)));
        assert_eq!(detection("RADAR start id=1\n"), None);
    }
}
