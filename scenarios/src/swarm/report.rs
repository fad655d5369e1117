//! After a run with several drones: the world's outputs split per drone,
//! the radio log counted, the distances the firmware measured set against
//! the true ones, the top-level `summary.json` (a `drones` map and the
//! totals) and the overall report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use protocol::series::{self, SeriesFormat, SeriesWriter};
use serde::{Deserialize, Serialize};
use sim_core::kernel::Summary;

use crate::outputs::files;
use crate::report::{ReportError, SummaryExt};

fn read_err(path: &Path, e: impl std::fmt::Display) -> ReportError {
    ReportError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// One drone's positions, world step by world step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DroneTrack {
    /// (time_ms, [x, y, z]).
    pub points: Vec<(u64, [f64; 3])>,
}

/// Splits the world's `trajectory.csv` (one row per drone per step, the
/// drone in the second column, DESIGN.md §7) into `<drone>/trajectory.csv`
/// with the columns of a run with one drone, so every platform's folder has
/// the complete outputs of DESIGN.md §6. A trajectory without a `drone`
/// column (a world with one drone) belongs to the only platform. Returns
/// each drone's track.
pub fn split_trajectory(
    out: &Path,
    drones: &[String],
) -> Result<BTreeMap<String, DroneTrack>, ReportError> {
    let text = series::read(&out.join(files::TRAJECTORY))?;
    if let Some(w) = text.warning() {
        tracing::warn!("{w}");
    }
    // Each drone's file in the form of the world's.
    let form = SeriesFormat::of_path(&text.path);
    let path = text.path;
    let mut r = csv::Reader::from_reader(&text.bytes[..]);
    let header = r.headers().map_err(|e| read_err(&path, e))?.clone();
    let col = |name: &str| header.iter().position(|h| h == name);
    let drone_col = col("drone");
    let (Some(t), Some(x), Some(y), Some(z)) = (col("time_ms"), col("x"), col("y"), col("z"))
    else {
        return Err(read_err(&path, "no time_ms, x, y, z columns"));
    };
    if drone_col.is_none() && drones.len() != 1 {
        return Err(read_err(
            &path,
            format!("no drone column for {} platforms", drones.len()),
        ));
    }
    let strip = |rec: &csv::StringRecord| -> csv::StringRecord {
        rec.iter()
            .enumerate()
            .filter(|(i, _)| Some(*i) != drone_col)
            .map(|(_, v)| v)
            .collect()
    };
    let mut writers = BTreeMap::new();
    for d in drones {
        let p = crate::outputs::drone_dir(out, d).join(form.file_name(files::TRAJECTORY));
        let mut w =
            csv::Writer::from_writer(SeriesWriter::create(&p).map_err(|e| read_err(&p, e))?);
        w.write_record(&strip(&header))
            .map_err(|e| read_err(&p, e))?;
        writers.insert(d.clone(), w);
    }
    let mut tracks: BTreeMap<String, DroneTrack> = drones
        .iter()
        .map(|d| (d.clone(), DroneTrack::default()))
        .collect();
    for rec in r.records() {
        let rec = rec.map_err(|e| read_err(&path, e))?;
        let name = match drone_col {
            Some(i) => rec.get(i).unwrap_or_default().to_string(),
            None => drones[0].clone(),
        };
        let Some(w) = writers.get_mut(&name) else {
            continue;
        };
        w.write_record(&strip(&rec))
            .map_err(|e| read_err(&path, e))?;
        let num = |i: usize| -> Result<f64, ReportError> {
            rec.get(i)
                .and_then(|v| v.parse::<f64>().ok())
                .ok_or_else(|| read_err(&path, format!("bad number in row {:?}", rec.position())))
        };
        let time = num(t)?.round() as u64;
        tracks
            .get_mut(&name)
            .expect("a track per writer")
            .points
            .push((time, [num(x)?, num(y)?, num(z)?]));
    }
    for (d, w) in writers {
        w.into_inner()
            .map_err(|e| e.to_string())
            .and_then(|mut s| s.finish().map_err(|e| e.to_string()))
            .map_err(|e| read_err(&out.join(&d), e))?;
    }
    Ok(tracks)
}

/// Mean distance between two drones over the world steps both have (m).
pub fn mean_distance(a: &DroneTrack, b: &DroneTrack) -> Option<f64> {
    let bt: BTreeMap<u64, [f64; 3]> = b.points.iter().copied().collect();
    let (mut sum, mut n) = (0.0, 0usize);
    for (t, pa) in &a.points {
        if let Some(pb) = bt.get(t) {
            sum += ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2))
                .sqrt();
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// The world's radio log counted (docs/SWARM.md §2–§3: one row per frame
/// and receiver with its outcome).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RadioCounts {
    /// Rows (frame, receiver).
    pub rows: u64,
    /// Frames received, per (sender, receiver).
    pub received: BTreeMap<(String, String), u64>,
    /// Rows whose outcome was a loss, per outcome.
    pub lost: BTreeMap<String, u64>,
}

impl RadioCounts {
    pub fn received_total(&self) -> u64 {
        self.received.values().sum()
    }

    pub fn lost_total(&self) -> u64 {
        self.lost.values().sum()
    }

    /// Frames received between a and b, both directions.
    pub fn between(&self, a: &str, b: &str) -> u64 {
        let get = |x: &str, y: &str| {
            self.received
                .get(&(x.to_string(), y.to_string()))
                .copied()
                .unwrap_or(0)
        };
        get(a, b) + get(b, a)
    }
}

/// The columns of the radio log this report reads (world-server
/// `radio/log.rs`: start_ps, end_ps, radio, from, to, distance_m, rssi_dbm,
/// outcome, tx_stamp, rx_stamp).
const FROM: &str = "from";
const TO: &str = "to";
const OUTCOME: &str = "outcome";
/// The outcome of a delivered frame (the others are losses: collision,
/// half_duplex, out_of_range, lost, retired).
const RECEIVED: &str = "received";

/// Reads the radio log (`radio.csv`).
pub fn read_radio_log(path: &Path) -> Result<RadioCounts, ReportError> {
    let mut r = csv::Reader::from_path(path).map_err(|e| read_err(path, e))?;
    let header = r.headers().map_err(|e| read_err(path, e))?.clone();
    let find = |name: &str| header.iter().position(|h| h == name);
    let (Some(from), Some(to), Some(outcome)) = (find(FROM), find(TO), find(OUTCOME)) else {
        return Err(read_err(
            path,
            format!(
                "expected the columns {FROM}, {TO} and {OUTCOME}, found {}",
                header.iter().collect::<Vec<_>>().join(",")
            ),
        ));
    };
    let mut c = RadioCounts::default();
    for rec in r.records() {
        let rec = rec.map_err(|e| read_err(path, e))?;
        c.rows += 1;
        let field = |i: usize| rec.get(i).unwrap_or_default().to_string();
        let o = field(outcome);
        if o == RECEIVED {
            *c.received.entry((field(from), field(to))).or_default() += 1;
        } else {
            *c.lost.entry(o).or_default() += 1;
        }
    }
    Ok(c)
}

/// Distances a firmware printed (radio_ping.elf and its kind): every line of
/// `console.log` with the word "distance" and a number after it, in m (or
/// `mm`/`cm` when the number is followed by that unit). The peer is the
/// drone whose name appears in the line as a word, or whose radio
/// identifier appears as `id N` / `eui N`; with two drones, the other one.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Measured {
    /// Per peer: the distances (m), in console order.
    pub per_peer: BTreeMap<String, Vec<f64>>,
}

fn number_after(text: &str) -> Option<(f64, &str)> {
    let start = text.find(|c: char| c.is_ascii_digit() || c == '-')?;
    let rest = &text[start..];
    let end = rest
        .char_indices()
        .find(|(i, c)| !(c.is_ascii_digit() || *c == '.' || (*i == 0 && *c == '-')))
        .map_or(rest.len(), |(i, _)| i);
    let v = rest[..end].parse::<f64>().ok()?;
    Some((v, &rest[end..]))
}

/// Parses one drone's console (`me` is its name; `others` the other drones
/// with their radio identifiers).
pub fn parse_measured(console: &str, me: &str, others: &[(String, Option<u64>)]) -> Measured {
    let mut m = Measured::default();
    for line in console.lines() {
        let lower = line.to_ascii_lowercase();
        let Some(at) = lower.find("distance") else {
            continue;
        };
        let Some((value, rest)) = number_after(&line[at + "distance".len()..]) else {
            continue;
        };
        let unit = rest.trim_start();
        let metres = if unit.starts_with("mm") {
            value / 1000.0
        } else if unit.starts_with("cm") {
            value / 100.0
        } else {
            value
        };
        let words: Vec<String> = line
            .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == '-'))
            .filter(|w| !w.is_empty())
            .map(String::from)
            .collect();
        let by_name = others
            .iter()
            .find(|(n, _)| n != me && words.iter().any(|w| w == n));
        let by_id = || {
            words.windows(2).find_map(|w| {
                let k = w[0].to_ascii_lowercase();
                if k != "id" && k != "eui" {
                    return None;
                }
                let id: u64 = w[1].parse().ok()?;
                others.iter().find(|(_, r)| *r == Some(id))
            })
        };
        let peer = by_name.or_else(by_id).map(|(n, _)| n.clone()).or_else(|| {
            let rest: Vec<&String> = others.iter().map(|(n, _)| n).filter(|n| *n != me).collect();
            (rest.len() == 1).then(|| rest[0].clone())
        });
        if let Some(peer) = peer {
            m.per_peer.entry(peer).or_default().push(metres);
        }
    }
    m
}

/// Mean and population standard deviation (divided by n: the seed's
/// 117.88 ± 65.02 cm of seed 004's Table 7 is that; n − 1 would give
/// 69.51 cm).
pub fn mean_sd_population(v: &[f64]) -> Option<(f64, f64)> {
    if v.is_empty() {
        return None;
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    Some((mean, var.sqrt()))
}

/// Mean and sample standard deviation.
pub fn mean_sd(v: &[f64]) -> Option<(f64, f64)> {
    if v.is_empty() {
        return None;
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = if v.len() > 1 {
        v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    Some((mean, var.sqrt()))
}

/// One measured pair of the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ranging {
    pub from: String,
    pub to: String,
    pub count: usize,
    pub measured_mean_m: f64,
    pub measured_sd_m: f64,
    /// Mean distance between the two centres over the run (trajectory).
    pub true_m: Option<f64>,
}

/// Radio figures of the top-level summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RadioSummary {
    pub rows: u64,
    pub received: u64,
    pub lost: u64,
    /// Frames received per "sender->receiver".
    pub links: BTreeMap<String, u64>,
}

/// The top-level `summary.json` of a run with several drones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SwarmSummary {
    pub scenario: String,
    /// Every platform completed and every process ended cleanly.
    pub completed: bool,
    /// What went wrong first (null when nothing did).
    pub error: Option<String>,
    /// The platforms' drones in `[[platform]]` order.
    pub platforms: Vec<String>,
    /// Each drone's own `summary.json` (null if its platform wrote none).
    pub drones: BTreeMap<String, serde_json::Value>,
    pub world_exit_code: Option<i32>,
    /// Each platform's sim-core exit code (null: killed).
    pub platform_exit_codes: BTreeMap<String, Option<i32>>,
    pub timestep_ms: u64,
    /// The world time when the last drone stopped (max of the drones').
    pub world_time_s: Option<f64>,
    /// Wall time of the whole run, all processes.
    pub wall_time_s: f64,
    /// world_time_s (else the longest platform time) / wall_time_s.
    pub realtime_factor: f64,
    pub targets_total: u32,
    pub targets_reached: u32,
    pub instructions: u64,
    pub cycles: u64,
    pub messages: u64,
    pub bytes_to_world: u64,
    pub bytes_to_platform: u64,
    /// Energy drawn from all batteries (J).
    pub energy_j: f64,
    pub collisions: Option<u64>,
    pub radio: Option<RadioSummary>,
    pub ranging: Vec<Ranging>,
}

/// What the totals are made of, per drone.
pub struct DroneFigures<'a> {
    pub drone: &'a str,
    pub summary: Option<&'a Summary>,
    pub raw: Option<serde_json::Value>,
    pub exit_code: Option<i32>,
}

/// Totals over the drones.
#[allow(clippy::too_many_arguments)]
pub fn swarm_summary(
    scenario: &str,
    timestep_ms: u64,
    drones: &[DroneFigures<'_>],
    world_exit_code: Option<i32>,
    error: Option<String>,
    wall_s: f64,
    radio: Option<&RadioCounts>,
    ranging: Vec<Ranging>,
) -> SwarmSummary {
    let sums = |f: &dyn Fn(&Summary) -> u64| -> u64 {
        drones.iter().filter_map(|d| d.summary).map(f).sum()
    };
    let world_time_s = drones
        .iter()
        .filter_map(|d| d.summary.and_then(|s| s.world_time_s))
        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.max(t))));
    let simulated = world_time_s.unwrap_or_else(|| {
        drones
            .iter()
            .filter_map(|d| d.summary.map(|s| s.platform_time_s))
            .fold(0.0, f64::max)
    });
    let all_done = drones
        .iter()
        .all(|d| d.summary.is_some_and(|s| s.completed));
    let collisions = drones
        .iter()
        .map(|d| d.summary.and_then(|s| s.collisions))
        .try_fold(0u64, |acc, c| c.map(|c| acc + c));
    SwarmSummary {
        scenario: scenario.to_string(),
        completed: error.is_none() && all_done,
        error,
        platforms: drones.iter().map(|d| d.drone.to_string()).collect(),
        drones: drones
            .iter()
            .map(|d| {
                (
                    d.drone.to_string(),
                    d.raw.clone().unwrap_or(serde_json::Value::Null),
                )
            })
            .collect(),
        world_exit_code,
        platform_exit_codes: drones
            .iter()
            .map(|d| (d.drone.to_string(), d.exit_code))
            .collect(),
        timestep_ms,
        world_time_s,
        wall_time_s: wall_s,
        realtime_factor: if wall_s > 0.0 {
            simulated / wall_s
        } else {
            0.0
        },
        targets_total: sums(&|s| u64::from(s.targets_total)) as u32,
        targets_reached: sums(&|s| u64::from(s.targets_reached)) as u32,
        instructions: sums(&|s| s.instructions),
        cycles: sums(&|s| s.cycles),
        messages: sums(&|s| s.messages),
        bytes_to_world: sums(&|s| s.bytes_to_world),
        bytes_to_platform: sums(&|s| s.bytes_to_platform),
        // A fold from +0.0: an empty f64 sum is -0.0.
        energy_j: drones
            .iter()
            .filter_map(|d| d.summary.map(|s| s.energy_j.total))
            .fold(0.0, |a, e| a + e),
        collisions,
        radio: radio.map(|r| RadioSummary {
            rows: r.rows,
            received: r.received_total(),
            lost: r.lost_total(),
            links: r
                .received
                .iter()
                .map(|((a, b), n)| (format!("{a}->{b}"), *n))
                .collect(),
        }),
        ranging,
    }
}

/// One drone's line of the overall report.
pub fn drone_line(drone: &str, s: Option<&Summary>, soc_init: f64, exit: Option<i32>) -> String {
    match s {
        None => format!(
            "   {drone:<14} no summary.json (sim-core {})\n",
            exit.map_or("killed".into(), |c| format!("exit code {c}"))
        ),
        Some(s) => format!(
            "   {drone:<14} {} | platform {:.3} s | world {} | SOC {:.1} % -> {:.1} % | {:.1} J | {} messages{}\n",
            if s.completed { "completed" } else { "did not complete" },
            s.platform_time_s,
            s.world_time_s.map_or("n/a".into(), |w| format!("{w:.3} s")),
            soc_init * 100.0,
            s.battery.soc_end * 100.0,
            s.energy_j.total,
            s.messages,
            s.flight_time_estimate_s(soc_init)
                .filter(|_| s.targets_total > 0)
                .map_or(String::new(), |f| format!(" | est. flight {f:.0} s")),
        ),
    }
}

/// The overall report of a run with several drones.
pub fn swarm_text(
    name: &str,
    description: &str,
    overrides: &str,
    sum: &SwarmSummary,
    drone_lines: &[String],
    out: &Path,
    plots: &[PathBuf],
) -> String {
    let result = match (&sum.error, sum.completed) {
        (None, true) => "completed".to_string(),
        (None, false) => "did not complete".to_string(),
        (Some(e), _) => format!("FAILED: {e}"),
    };
    let mut t = format!("== {name} ({description}) — {result}\n");
    if !overrides.is_empty() {
        t += &format!("   overrides      {overrides}\n");
    }
    t += &format!(
        "   setup          {} drones, {} ms timestep\n",
        sum.platforms.len(),
        sum.timestep_ms
    );
    for l in drone_lines {
        t += l;
    }
    if let Some(r) = &sum.radio {
        t += &format!(
            "   radio          {} receptions, {} lost ({} rows of {})\n",
            r.received,
            r.lost,
            r.rows,
            crate::outputs::swarm_files::RADIO_LOG
        );
    }
    for r in &sum.ranging {
        let truth = r.true_m.map_or("true n/a".to_string(), |d| {
            format!("true {d:.3} m | error {:+.3} m", r.measured_mean_m - d)
        });
        t += &format!(
            "   ranging        {} -> {}: measured {:.3} m (sd {:.3} m, n = {}) | {truth}\n",
            r.from, r.to, r.measured_mean_m, r.measured_sd_m, r.count
        );
    }
    t += &format!(
        "   cost           {:.2} s wall, {:.2}x real time (world {}), {} instructions, {} messages, {} collisions, world exit code {}\n",
        sum.wall_time_s,
        sum.realtime_factor,
        sum.world_time_s.map_or("n/a".into(), |w| format!("{w:.3} s")),
        sum.instructions,
        sum.messages,
        sum.collisions.map_or("?".into(), |c| c.to_string()),
        sum.world_exit_code.map_or("none (killed)".into(), |c| c.to_string()),
    );
    t += &format!(
        "   outputs        {} (each platform's in {}/<drone>)\n",
        out.display(),
        out.display()
    );
    for p in plots {
        t += &format!("   plot           {}\n", p.display());
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_are_read_from_console_lines() {
        let others = vec![
            ("A".to_string(), Some(1)),
            ("B".to_string(), Some(2)),
            ("C".to_string(), Some(3)),
        ];
        let console = "hello\n[ping] distance to B: 1.503 m\n[ping] id 3 distance=1520 mm\nnothing here\n[ping] distance 12.5 cm to C\n";
        let m = parse_measured(console, "A", &others);
        assert_eq!(m.per_peer["B"], [1.503]);
        assert_eq!(m.per_peer["C"], [1.52, 0.125]);
        let two = vec![("A".to_string(), None), ("B".to_string(), None)];
        let m = parse_measured("distance: -0.25\n", "B", &two);
        assert_eq!(m.per_peer["A"], [-0.25]);
        let (mean, sd) = mean_sd(&[1.0, 2.0, 3.0]).unwrap();
        assert!((mean - 2.0).abs() < 1e-12 && (sd - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_radio_log_is_counted_by_pair_and_outcome() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("radio.csv");
        std::fs::write(
            &p,
            "time_ps,radio,from,to,outcome\n1,uwb,A,B,received\n2,uwb,B,A,received\n3,uwb,A,B,collision\n4,uwb,A,B,received\n",
        )
        .unwrap();
        let c = read_radio_log(&p).unwrap();
        assert_eq!(c.rows, 4);
        assert_eq!(c.between("A", "B"), 3);
        assert_eq!(c.received_total(), 3);
        assert_eq!(c.lost["collision"], 1);
        std::fs::write(&p, "a,b\n1,2\n").unwrap();
        assert!(read_radio_log(&p).is_err());
    }

    #[test]
    fn trajectories_are_split_per_drone() {
        let dir = tempfile::tempdir().unwrap();
        for d in ["A", "B"] {
            std::fs::create_dir_all(dir.path().join(d)).unwrap();
        }
        std::fs::write(
            dir.path().join("trajectory.csv"),
            "time_ms,drone,x,y,z\n0,A,0,0,0\n0,B,3,4,0\n16,A,0,0,0\n16,B,3,4,0\n",
        )
        .unwrap();
        let t = split_trajectory(dir.path(), &["A".into(), "B".into()]).unwrap();
        assert_eq!(t["B"].points, [(0, [3.0, 4.0, 0.0]), (16, [3.0, 4.0, 0.0])]);
        assert_eq!(mean_distance(&t["A"], &t["B"]), Some(5.0));
        let a = std::fs::read_to_string(dir.path().join("A/trajectory.csv")).unwrap();
        assert_eq!(a, "time_ms,x,y,z\n0,0,0,0\n16,0,0,0\n");
    }
}
