//! The outputs of a mapping run (DESIGN.md §9): when the platform leaves
//! the firmware's map (`map.cfog`, copied out of the core's memory at the
//! end of the run, sim-core's `kernel::map_dump`), `cosim` writes
//! `map.csv`, `exploration.csv`, `map.png` and adds the `map` object to
//! `summary.json`, scoring the map against the world's true floor plan
//! ([`truth`]).
//!
//! The firmware (`explore_app.elf`, docs/EXPLORE.md) reports on its console
//! in `EXPLORE <what> key=value ...` lines: `settings` (cell, FOV, height),
//! `start` (its position estimate at take-off), one `goal` per frontier goal,
//! `error` (settings refused) and `end` (its counters).

mod plot;
pub mod truth;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim_core::map_image::{MapError, MapImage};
use world_server::WorldDesc;

use crate::outputs::map_files as files;
// Defined with the figure that draws it: the map module and its plot
// share it without importing each other.
pub use plot::Goal;
use truth::{footprints, Quality, TruePlan, TruthError};

/// Why the mapping outputs could not be made.
#[derive(Debug, thiserror::Error)]
pub enum MappingError {
    #[error("cannot read {path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("{path}: {source}")]
    Image {
        path: PathBuf,
        #[source]
        source: MapError,
    },
    #[error("console.log: {0}")]
    Console(String),
    #[error("true plan: {0}")]
    Truth(#[from] TruthError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}

/// One `EXPLORE` console line: what, and its key=value pairs.
#[derive(Debug, Clone, PartialEq)]
struct Line {
    what: String,
    fields: BTreeMap<String, String>,
    /// The text after `EXPLORE error `.
    text: String,
}

fn parse_lines(console: &str) -> Vec<Line> {
    console
        .lines()
        .filter_map(|l| l.strip_prefix("EXPLORE "))
        .map(|rest| {
            let (what, tail) = rest.split_once(' ').unwrap_or((rest, ""));
            let fields = tail
                .split_whitespace()
                .filter_map(|kv| kv.split_once('='))
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            Line {
                what: what.to_string(),
                fields,
                text: tail.trim().to_string(),
            }
        })
        .collect()
}

impl Line {
    fn num(&self, key: &str) -> Result<f64, MappingError> {
        let v = self.fields.get(key).ok_or_else(|| {
            MappingError::Console(format!("EXPLORE {} line without {key}=", self.what))
        })?;
        v.parse::<f64>().map_err(|_| {
            MappingError::Console(format!("EXPLORE {}: {key}={v} is not a number", self.what))
        })
    }
}

/// The `map` object of `summary.json` (DESIGN.md §9) and a few more figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapSummary {
    pub cell_m: f64,
    pub fov_deg: f64,
    pub cells: usize,
    pub coverage_pct: f64,
    pub accuracy_pct: f64,
    pub goals: usize,
    /// From the first control step to landing (the firmware's own clock).
    pub exploration_time_s: Option<f64>,
    pub map_cycles: Option<u64>,
    pub width: usize,
    pub height: usize,
    /// Truly free cells mapped free.
    pub free_coverage_pct: f64,
    pub truth_free_cells: usize,
    pub judged_cells: usize,
    /// Mapping's share of the core's cycles (%).
    pub map_cycles_pct: Option<f64>,
    pub map_updates: Option<u64>,
    pub plan_cycles: Option<u64>,
    pub goals_reached: Option<u64>,
    pub goals_failed: Option<u64>,
    pub regions_unreachable: Option<u64>,
    /// Offset added to the map's frame to put it in the world's (m): the
    /// world's take-off point minus the firmware's estimate there.
    pub frame_offset_m: [f64; 2],
}

/// What the firmware said on its console.
#[derive(Debug, Clone, PartialEq, Default)]
struct Report {
    height_m: Option<f64>,
    start_estimate_m: Option<[f64; 2]>,
    goals_estimate: Vec<Goal>,
    end: Option<BTreeMap<String, String>>,
    error: Option<String>,
}

fn read_report(console: &str) -> Result<Report, MappingError> {
    let mut r = Report::default();
    for l in parse_lines(console) {
        match l.what.as_str() {
            "settings" => r.height_m = Some(l.num("height_mm")? / 1000.0),
            "start" => {
                r.start_estimate_m = Some([l.num("x_mm")? / 1000.0, l.num("y_mm")? / 1000.0])
            }
            "goal" => r.goals_estimate.push(Goal {
                time_s: l.num("t_ms")? / 1000.0,
                x: l.num("x_mm")? / 1000.0,
                y: l.num("y_mm")? / 1000.0,
            }),
            "end" => r.end = Some(l.fields.clone()),
            "error" => r.error = Some(l.text.clone()),
            _ => {}
        }
    }
    Ok(r)
}

fn end_u64(r: &Report, key: &str) -> Option<u64> {
    r.end.as_ref()?.get(key)?.parse().ok()
}

fn read(path: &Path) -> Result<Vec<u8>, MappingError> {
    std::fs::read(path).map_err(|e| MappingError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

fn write(path: &Path, text: &str) -> Result<(), MappingError> {
    std::fs::write(path, text).map_err(|e| MappingError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// `map.csv`: one row per cell, `ix, iy, x, y` (cell centre, m, world
/// frame) and `p_occupied`, or −1 for a cell never observed.
fn map_csv(map: &MapImage, offset: [f64; 2]) -> String {
    let c = map.cell_mm as f64 / 1000.0;
    let mut s = String::from("ix,iy,x,y,p_occupied\n");
    for iy in 0..map.height {
        for ix in 0..map.width {
            let x = map.origin_x_mm as f64 / 1000.0 + (ix as f64 + 0.5) * c + offset[0];
            let y = map.origin_y_mm as f64 / 1000.0 + (iy as f64 + 0.5) * c + offset[1];
            let p = map
                .p_occupied(ix, iy)
                .map_or(-1.0, |p| (p * 1e4).round() / 1e4);
            s.push_str(&format!("{ix},{iy},{x:.4},{y:.4},{p}\n"));
        }
    }
    s
}

fn exploration_csv(goals: &[Goal]) -> String {
    let mut s = String::from("time_s,x,y\n");
    for g in goals {
        s.push_str(&format!("{:.3},{:.4},{:.4}\n", g.time_s, g.x, g.y));
    }
    s
}

/// Makes the mapping outputs of the run in `out` if the firmware left a
/// map; `Ok(None)` when it did not (not a mapping run). `world` is the run's
/// world file, `total_cycles` the core's cycles (summary.json).
pub fn process(
    world: &WorldDesc,
    out: &Path,
    total_cycles: Option<u64>,
    draw: bool,
) -> Result<Option<MapSummary>, MappingError> {
    let cfog = out.join(files::MAP_CFOG);
    if !cfog.exists() {
        return Ok(None);
    }
    let console_path = out.join(crate::outputs::files::CONSOLE);
    let console = String::from_utf8_lossy(&read(&console_path)?).into_owned();
    let report = read_report(&console)?;
    if let Some(e) = &report.error {
        return Err(MappingError::Console(format!(
            "the firmware refused its settings: {e}"
        )));
    }
    let bytes = read(&cfog)?;
    let map = MapImage::parse(&bytes).map_err(|source| MappingError::Image {
        path: cfog.clone(),
        source,
    })?;
    let start = world.start.position.0;
    let est = report.start_estimate_m.unwrap_or([start[0], start[1]]);
    let offset = [start[0] - est[0], start[1] - est[1]];
    let height = report
        .height_m
        .ok_or_else(|| MappingError::Console("no EXPLORE settings line (height_mm)".into()))?;
    // The plan in the map's frame: obstacles moved by −offset.
    let obstacles: Vec<_> = footprints(world, height)
        .into_iter()
        .map(|mut f| {
            f.centre = [f.centre[0] - offset[0], f.centre[1] - offset[1]];
            f
        })
        .collect();
    let plan = TruePlan::new(&map, &obstacles, est)?;
    let q = Quality::of(&map, &plan);
    let goals: Vec<Goal> = report
        .goals_estimate
        .iter()
        .map(|g| Goal {
            x: g.x + offset[0],
            y: g.y + offset[1],
            ..*g
        })
        .collect();
    write(&out.join(files::MAP_CSV), &map_csv(&map, offset))?;
    write(&out.join(files::EXPLORATION_CSV), &exploration_csv(&goals))?;
    let map_cycles = end_u64(&report, "map_cycles");
    let time = match (end_u64(&report, "start_ms"), end_u64(&report, "end_ms")) {
        (Some(a), Some(b)) if b >= a => Some((b - a) as f64 / 1000.0),
        _ => None,
    };
    let round2 = |v: f64| (v * 100.0).round() / 100.0;
    let summary = MapSummary {
        cell_m: map.cell_mm as f64 / 1000.0,
        fov_deg: map.fov_cdeg as f64 / 100.0,
        cells: map.width * map.height,
        coverage_pct: round2(q.coverage_pct()),
        accuracy_pct: round2(q.accuracy_pct()),
        goals: goals.len(),
        exploration_time_s: time,
        map_cycles,
        width: map.width,
        height: map.height,
        free_coverage_pct: round2(q.free_coverage_pct()),
        truth_free_cells: q.truth_free,
        judged_cells: q.judged,
        map_cycles_pct: match (map_cycles, total_cycles) {
            (Some(m), Some(t)) if t > 0 => Some(round2(100.0 * m as f64 / t as f64)),
            _ => None,
        },
        map_updates: end_u64(&report, "map_updates"),
        plan_cycles: end_u64(&report, "plan_cycles"),
        goals_reached: end_u64(&report, "reached"),
        goals_failed: end_u64(&report, "failed"),
        regions_unreachable: end_u64(&report, "unreachable"),
        frame_offset_m: offset,
    };
    if draw {
        plot::map_png(
            &out.join(files::MAP_PNG),
            &map,
            &plan,
            offset,
            &goals,
            [start[0], start[1]],
            &q,
        )?;
    }
    add_to_summary(&out.join(crate::outputs::files::SUMMARY), &summary)?;
    Ok(Some(summary))
}

/// The `map` object of `dir/summary.json`, if it has one (merged sweeps).
pub fn read_from_summary(dir: &Path) -> Option<MapSummary> {
    let text = std::fs::read_to_string(dir.join(crate::outputs::files::SUMMARY)).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    serde_json::from_value(v.get("map")?.clone()).ok()
}

/// The line `cosim run` prints for a mapping run.
pub fn summary_line(m: &MapSummary) -> String {
    let opt = |v: Option<f64>, unit: &str| v.map_or("n/a".to_string(), |v| format!("{v:.1}{unit}"));
    format!(
        "   map            {} x {} cells of {} cm, FOV {}°: coverage {:.1} %, accuracy {:.1} %, {} goals, {} exploring, mapping {} of the cycles\n",
        m.width,
        m.height,
        m.cell_m * 100.0,
        m.fov_deg,
        m.coverage_pct,
        m.accuracy_pct,
        m.goals,
        opt(m.exploration_time_s, " s"),
        opt(m.map_cycles_pct, " %"),
    )
}

/// Adds (or replaces) the `map` object of `summary.json`, keeping the rest.
fn add_to_summary(path: &Path, map: &MapSummary) -> Result<(), MappingError> {
    let text = String::from_utf8_lossy(&read(path)?).into_owned();
    let mut v: serde_json::Value = serde_json::from_str(&text).map_err(|e| MappingError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let obj = v.as_object_mut().ok_or_else(|| MappingError::Read {
        path: path.to_path_buf(),
        message: "not a JSON object".into(),
    })?;
    obj.insert(
        "map".into(),
        serde_json::to_value(map).map_err(|e| MappingError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?,
    );
    let text = serde_json::to_string_pretty(&v).map_err(|e| MappingError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write(path, &(text + "\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn console_lines_are_read() {
        let c = "boot\nEXPLORE settings mode=0 cell_mm=50 fov_cdeg=400 height_mm=300\n\
                 EXPLORE start x_mm=500 y_mm=-250\nEXPLORE goal t_ms=12500 x_mm=1500 y_mm=1200\n\
                 EXPLORE end map_cycles=123456789012 start_ms=2000 end_ms=90000\n";
        let r = read_report(c).unwrap();
        assert_eq!(r.height_m, Some(0.3));
        assert_eq!(r.start_estimate_m, Some([0.5, -0.25]));
        assert_eq!(
            r.goals_estimate,
            vec![Goal {
                time_s: 12.5,
                x: 1.5,
                y: 1.2
            }]
        );
        assert_eq!(end_u64(&r, "map_cycles"), Some(123_456_789_012));
        let e = read_report("EXPLORE goal t_ms=1 x_mm=zz y_mm=0\n").unwrap_err();
        assert!(e.to_string().contains("x_mm=zz"), "{e}");
        let r =
            read_report("EXPLORE error explore: grid 400 x 400 = 160000 cells exceeds\n").unwrap();
        assert!(r.error.unwrap().starts_with("explore: grid 400"));
    }

    #[test]
    fn csv_rows_follow_the_contract() {
        let map = MapImage {
            width: 2,
            height: 1,
            cell_mm: 50,
            fov_cdeg: 400,
            origin_x_mm: -50,
            origin_y_mm: 0,
            lo_per_nat: 16,
            l_min: -32,
            l_max: 56,
            cells: vec![0, -16],
        };
        let s = map_csv(&map, [1.0, 2.0]);
        assert_eq!(
            s,
            "ix,iy,x,y,p_occupied\n0,0,0.9750,2.0250,-1\n1,0,1.0250,2.0250,0.2689\n"
        );
        let g = exploration_csv(&[Goal {
            time_s: 3.0,
            x: 1.0,
            y: -0.5,
        }]);
        assert_eq!(g, "time_s,x,y\n3.000,1.0000,-0.5000\n");
    }
}
