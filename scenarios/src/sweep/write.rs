//! A whole sweep's table (`sweep.csv`, `sweep.md`) and plots, written
//! after its runs (or rebuilt by a merge).

use std::path::{Path, PathBuf};

use super::nn;
use super::params::{files, Param, SweepError, SweepRow};
use crate::outcome::RunOutcome;
use crate::plot::{self, Series};
use crate::report::{self, PowerRow, SummaryExt};

/// The table (`sweep.csv`, `sweep.md`) and the plots of a whole sweep.
pub(crate) fn write_outputs(
    params: &[Param],
    rows: &[SweepRow],
    out: &Path,
) -> Result<(), SweepError> {
    write_tables(params, rows, out)?;
    if let Err(e) = write_plots(params, rows, out) {
        tracing::warn!("sweep plots: {e}");
    }
    // Seed 004's radar trials (Tables 7-8), when the runs left radar.json.
    let runs: Vec<(String, PathBuf)> = rows.iter().map(|r| (r.label(), r.dir.clone())).collect();
    if let Some(md) = crate::swarm::radar::sweep_table(&runs) {
        std::fs::write(out.join(crate::swarm::radar::RADAR_MD), md)
            .map_err(|e| SweepError::Output(e.to_string()))?;
    }
    Ok(())
}

/// The columns that depend on the machine and its load, not on the
/// simulation: the only ones in which a merged sweep may differ from a
/// one-machine sweep (with `dir`, which names the output directory).
pub const WALL_CLOCK_COLUMNS: [&str; 2] = ["wall_time_s", "realtime_factor"];

const COLUMNS: [&str; 18] = [
    "status",
    "targets_reached",
    "targets_total",
    "targets_bypassed",
    "platform_time_s",
    "world_time_s",
    "world_time_estimate_s",
    "estimate_error_pct",
    "energy_empirical_j",
    "energy_dandrea_j",
    "energy_stolaroff_j",
    "energy_battery_j",
    "soc_end_pct",
    "flight_time_est_s",
    "wall_time_s",
    "realtime_factor",
    "collisions",
    "error",
];

pub(super) fn row_values(row: &SweepRow) -> Vec<String> {
    let f = |v: f64, d: usize| format!("{v:.d$}");
    let status = if row.error.is_none() { "ok" } else { "failed" };
    let err = row.error.clone().unwrap_or_default();
    match row
        .outcome
        .as_ref()
        .and_then(|o| o.summary.as_ref().map(|s| (o, s)))
    {
        Some((o, s)) => vec![
            status.into(),
            s.targets_reached.to_string(),
            s.targets_total.to_string(),
            s.targets_bypassed.to_string(),
            f(s.platform_time_s, 3),
            s.world_time_s.map_or(String::new(), |w| f(w, 3)),
            f(s.world_time_estimate_s, 3),
            s.estimate_error_pct.map_or(String::new(), |e| f(e, 4)),
            f(s.energy_j.empirical, 2),
            f(s.energy_j.dandrea, 2),
            f(s.energy_j.stolaroff, 2),
            f(s.energy_j.total, 2),
            f(s.battery.soc_end * 100.0, 2),
            s.flight_time_estimate_s(o.soc_init)
                .map_or(String::new(), |t| f(t, 1)),
            f(o.status.wall.as_secs_f64(), 2),
            f(s.realtime_factor, 2),
            s.collisions.map_or(String::new(), |c| c.to_string()),
            err,
        ],
        None => {
            let mut v = vec![status.to_string()];
            v.extend(std::iter::repeat_n(String::new(), COLUMNS.len() - 2));
            v.push(err);
            v
        }
    }
}

/// Columns added when a run of the sweep mapped a room (DESIGN.md §9).
const MAP_COLUMNS: [&str; 9] = [
    "map_cell_m",
    "map_fov_deg",
    "map_cells",
    "map_coverage_pct",
    "map_accuracy_pct",
    "map_free_coverage_pct",
    "map_goals",
    "map_exploration_time_s",
    "map_cycles_pct",
];

pub(super) fn map_values(row: &SweepRow) -> Vec<String> {
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.2}"));
    match row.outcome.as_ref().and_then(|o| o.map.as_ref()) {
        Some(m) => vec![
            format!("{}", m.cell_m),
            format!("{}", m.fov_deg),
            m.cells.to_string(),
            format!("{:.2}", m.coverage_pct),
            format!("{:.2}", m.accuracy_pct),
            format!("{:.2}", m.free_coverage_pct),
            m.goals.to_string(),
            opt(m.exploration_time_s),
            opt(m.map_cycles_pct),
        ],
        None => vec![String::new(); MAP_COLUMNS.len()],
    }
}

/// The sweep table: header and one row of cells per run.
pub fn table(params: &[Param], rows: &[SweepRow]) -> (Vec<String>, Vec<Vec<String>>) {
    let mut header: Vec<String> = vec!["run".into()];
    header.extend(params.iter().map(|p| p.key.clone()));
    // A scenario with several drones: one row per drone (its own figures,
    // the run's status and wall time), a `drone` column after the parameters.
    let swarm = rows
        .iter()
        .any(|r| r.outcome.as_ref().is_some_and(|o| !o.drones.is_empty()));
    if swarm {
        header.push("drone".into());
    }
    header.extend(COLUMNS.iter().map(|c| c.to_string()));
    let mapped = rows
        .iter()
        .any(|r| r.outcome.as_ref().is_some_and(|o| o.map.is_some()));
    if mapped {
        header.extend(MAP_COLUMNS.iter().map(|c| c.to_string()));
    }
    let with_nn = nn::any(rows);
    if with_nn {
        header.extend(nn::NN_COLUMNS.iter().map(|c| c.to_string()));
    }
    header.push("dir".into());
    let mut table: Vec<Vec<String>> = Vec::new();
    for r in rows {
        let mut head = vec![(r.index + 1).to_string()];
        head.extend(r.assignments.iter().map(|(_, val)| val.clone()));
        let per = r
            .outcome
            .as_ref()
            .map(RunOutcome::per_drone)
            .unwrap_or_default();
        if per.is_empty() {
            let mut v = head.clone();
            if swarm {
                v.push(String::new());
            }
            v.extend(row_values(r));
            if mapped {
                v.extend(map_values(r));
            }
            if with_nn {
                v.extend(nn::values(r));
            }
            v.push(r.dir.display().to_string());
            table.push(v);
        }
        for (drone, o) in per {
            let d = SweepRow {
                index: r.index,
                assignments: Vec::new(),
                dir: r.dir.join(&drone),
                outcome: Some(o),
                error: r.error.clone(),
            };
            let mut v = head.clone();
            v.push(drone);
            v.extend(row_values(&d));
            v.push(d.dir.display().to_string());
            table.push(v);
        }
    }
    (header, table)
}

pub(super) fn write_tables(
    params: &[Param],
    rows: &[SweepRow],
    out: &Path,
) -> Result<(), SweepError> {
    let oerr = |e: &dyn std::fmt::Display| SweepError::Output(e.to_string());
    let (header, table) = table(params, rows);
    let mut w = csv::Writer::from_path(out.join(files::CSV)).map_err(|e| oerr(&e))?;
    w.write_record(&header).map_err(|e| oerr(&e))?;
    for r in &table {
        w.write_record(r).map_err(|e| oerr(&e))?;
    }
    w.flush().map_err(|e| oerr(&e))?;
    std::fs::write(out.join(files::MARKDOWN), markdown(&header, &table)).map_err(|e| oerr(&e))
}

/// A markdown table (the `dir` column left out: it is in the CSV).
pub fn markdown(header: &[String], rows: &[Vec<String>]) -> String {
    let keep = header.len().saturating_sub(1);
    let cell = |s: &str| s.replace('|', "\\|").replace('\n', " ");
    let mut t = format!("| {} |\n", header[..keep].join(" | "));
    t += &format!("|{}\n", "---|".repeat(keep));
    for r in rows {
        let cells: Vec<String> = r[..keep].iter().map(|c| cell(c)).collect();
        t += &format!("| {} |\n", cells.join(" | "));
    }
    t
}

pub(super) fn write_plots(
    params: &[Param],
    rows: &[SweepRow],
    out: &Path,
) -> Result<(), SweepError> {
    let perr = |e: plot::PlotError| SweepError::Output(e.to_string());
    // SOC over time, one line per run (Figs. 5.6, 5.11, 5.17).
    let mut soc = Vec::new();
    for r in rows {
        // A run with several drones: a line per drone.
        let drones = r.outcome.as_ref().map_or(Vec::new(), |o| {
            o.drones
                .iter()
                .map(|d| (format!(" {}", d.drone), d.dir.clone()))
                .collect()
        });
        let dirs = if drones.is_empty() {
            vec![(String::new(), r.dir.clone())]
        } else {
            drones
        };
        for (drone, dir) in dirs {
            let power: Vec<PowerRow> =
                match report::read_csv(&dir.join(sim_core::power::log::POWER_CSV)) {
                    Ok(p) => p,
                    Err(_) => continue,
                };
            let pts: Vec<(f64, f64)> = power.iter().map(|p| (p.time_s, p.soc * 100.0)).collect();
            let failed = if r.error.is_some() { " (failed)" } else { "" };
            soc.push(Series {
                label: format!("{}{drone}{failed}", r.label()),
                points: plot::decimate(&pts, 1500),
            });
        }
    }
    if !soc.is_empty() {
        plot::overlay(
            &out.join(files::SOC_PNG),
            "Battery discharge per run",
            "time (s)",
            "SOC (%)",
            &soc,
            false,
        )
        .map_err(perr)?;
    }
    nn::write_plot(rows, out).map_err(perr)?;
    // Wall time and world time against the timestep (Tables 5.1-5.4),
    // one line per combination of the other parameters; completed runs
    // only, as the thesis's tables (a run cut short has a shorter wall time
    // that means nothing).
    if let Some(ts_pos) = params.iter().position(|p| p.key == "timestep_ms") {
        let mut wall: Vec<Series> = Vec::new();
        let mut world: Vec<Series> = Vec::new();
        for r in rows {
            if r.error.is_some() {
                continue;
            }
            let Some(o) = &r.outcome else { continue };
            let Some(s) = &o.summary else { continue };
            let Ok(ts) = r.assignments[ts_pos].1.parse::<f64>() else {
                continue;
            };
            let others: Vec<String> = r
                .assignments
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != ts_pos)
                .map(|(_, (k, v))| format!("{k}={v}"))
                .collect();
            let label = if others.is_empty() {
                "wall time".into()
            } else {
                others.join(" ")
            };
            let find = |v: &mut Vec<Series>, label: &str| -> usize {
                match v.iter().position(|s| s.label == label) {
                    Some(i) => i,
                    None => {
                        v.push(Series {
                            label: label.to_string(),
                            points: Vec::new(),
                        });
                        v.len() - 1
                    }
                }
            };
            let i = find(&mut wall, &label);
            wall[i].points.push((ts, o.status.wall.as_secs_f64()));
            if let Some(w) = s.world_time_s {
                let i = find(&mut world, &label);
                world[i].points.push((ts, w));
            }
        }
        for s in wall.iter_mut().chain(world.iter_mut()) {
            s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        if !wall.is_empty() {
            plot::panels(
                &out.join(files::TIMESTEP_PNG),
                "basicTimeStep (ms)",
                &[
                    (
                        "Wall time of the co-simulation (completed runs)".into(),
                        "wall time (s)".into(),
                        wall,
                    ),
                    ("World time at STOP".into(), "world time (s)".into(), world),
                ],
                true,
            )
            .map_err(perr)?;
        }
    }
    Ok(())
}
