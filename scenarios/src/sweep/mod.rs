//! `cosim sweep`: the cartesian product of parameter values, run in
//! parallel (each run its own pair of processes and socket), a table of the
//! summary figures (markdown and CSV) and overlay plots. A run that fails is
//! a row marked failed with its error; the other rows are kept.
//!
//! Beyond one machine (DESIGN.md §11): [`plan`] numbers the runs and cuts
//! them into shards `K/N`; every run leaves a record (`sweep-run.json`) in
//! its directory; [`merge`] rebuilds the table and plots from shard outputs.

pub mod merge;
pub mod nn;
pub mod plan;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};

use crate::launch::{Binaries, LaunchOptions};
use crate::outcome::RunOutcome;
use crate::plot::{self, Series};
use crate::report::{self, PowerRow, SummaryExt};
use crate::run::run_scenario;
use crate::scenario::{Scenario, ScenarioError};
pub use merge::merge;
pub use plan::{Plan, PlannedRun, RunRecord, Shard, SweepId, RUN_RECORD};

/// File names of a sweep's outputs.
pub mod files {
    pub const CSV: &str = "sweep.csv";
    pub const MARKDOWN: &str = "sweep.md";
    pub const SOC_PNG: &str = "sweep_soc.png";
    pub const TIMESTEP_PNG: &str = "sweep_timestep.png";
}

/// Why a sweep could not start.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("--param {0:?}: expected KEY=V1,V2,...")]
    BadParam(String),
    // The scenario error is in the message, not chained as a source: the
    // launcher prints the chain, and the line would say it twice.
    #[error("run {label}: {error}")]
    Scenario { label: String, error: ScenarioError },
    #[error("no parameters: give --param KEY=V1,V2,... (or a [sweep] table in the scenario)")]
    NoParams,
    #[error("--shard {0:?}: expected K/N with 1 <= K <= N (run numbers ≡ K mod N)")]
    BadShard(String),
    #[error("{0}")]
    Output(String),
    /// A merge refused: missing, duplicate or foreign runs, a corrupt record
    /// or summary (one line that names the run and the file).
    #[error("merge refused: {0}")]
    Merge(String),
}

/// One swept parameter.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Param {
    pub key: String,
    pub values: Vec<String>,
}

impl std::str::FromStr for Param {
    type Err = SweepError;
    fn from_str(s: &str) -> Result<Param, SweepError> {
        let (key, values) = s
            .split_once('=')
            .ok_or_else(|| SweepError::BadParam(s.into()))?;
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if key.trim().is_empty() || values.is_empty() {
            return Err(SweepError::BadParam(s.into()));
        }
        Ok(Param {
            key: key.trim().to_string(),
            values,
        })
    }
}

/// Every combination, the first parameter varying slowest.
pub fn product(params: &[Param]) -> Vec<Vec<(String, String)>> {
    let mut combos: Vec<Vec<(String, String)>> = vec![Vec::new()];
    for p in params {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                p.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((p.key.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    combos
}

/// One row of the sweep table.
#[derive(Debug)]
pub struct SweepRow {
    pub index: usize,
    pub assignments: Vec<(String, String)>,
    pub dir: PathBuf,
    /// The run (None if it could not even be launched).
    pub outcome: Option<RunOutcome>,
    /// Why the run failed (None: it completed).
    pub error: Option<String>,
}

impl SweepRow {
    pub fn label(&self) -> String {
        self.assignments
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

fn dir_name(index: usize, assignments: &[(String, String)]) -> String {
    let mut name = format!("run-{:03}", index + 1);
    for (k, v) in assignments {
        name.push('_');
        name.push_str(k);
        name.push('=');
        // Path separators and the like would nest or break the directory.
        name.extend(v.chars().map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        }));
    }
    name
}

/// Checks every combination, then runs them `jobs` at a time into
/// `out/run-NNN_key=value...`, and writes the table and the plots.
pub fn run_sweep(
    base: &Scenario,
    params: &[Param],
    bins: &Binaries,
    out: &Path,
    jobs: usize,
    opts: &LaunchOptions,
) -> Result<Vec<SweepRow>, SweepError> {
    let plan = Plan::new(base, params)?;
    run_planned(&plan, None, bins, out, jobs, opts)
}

/// Runs the runs of `shard` (all without one) `jobs` at a time into
/// `out/run-NNN_key=value...`, each leaving its [`RunRecord`]. The whole
/// sweep writes the table and the plots; a shard writes only its run
/// directories, so that shards may share `out` (a shared filesystem) and
/// `cosim sweep --merge` makes the table.
pub fn run_planned(
    plan: &Plan,
    shard: Option<Shard>,
    bins: &Binaries,
    out: &Path,
    jobs: usize,
    opts: &LaunchOptions,
) -> Result<Vec<SweepRow>, SweepError> {
    let planned = plan.select(shard);
    let record_shard = shard.unwrap_or(Shard { k: 1, n: 1 });
    std::fs::create_dir_all(out)
        .map_err(|e| SweepError::Output(format!("cannot create {}: {e}", out.display())))?;
    let bar = ProgressBar::new(planned.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .expect("a valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<SweepRow>> = Mutex::new(Vec::new());
    let run_opts = LaunchOptions {
        echo: false,
        ..opts.clone()
    };
    std::thread::scope(|scope| {
        for _ in 0..jobs.clamp(1, planned.len().max(1)) {
            scope.spawn(|| loop {
                // Stopped by a signal: the runs started end (crate::signals),
                // no new one starts; the table has the runs that exist.
                if crate::signals::requested().is_some() {
                    break;
                }
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(run) = planned.get(i) else {
                    break;
                };
                let dir = out.join(run.dir_name());
                // A panic in one run (a bug in the report code, say) is that
                // run's failure, not the sweep's.
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    run_scenario(&run.scenario, bins, &dir, &run_opts, true)
                }));
                let (outcome, mut error) = match result {
                    Ok(Ok(o)) => {
                        let e = o.error();
                        (Some(o), e)
                    }
                    Ok(Err(e)) => (None, Some(e.to_string())),
                    Err(_) => (None, Some("the run panicked (see the log above)".into())),
                };
                let record = RunRecord::new(
                    &plan.id,
                    run,
                    record_shard,
                    &dir,
                    outcome.as_ref(),
                    error.as_deref(),
                );
                if let Err(e) = record.write(&dir) {
                    // Without its record the merge would report the run
                    // missing; say why here, in the row.
                    error = Some(match error {
                        Some(prev) => format!("{prev}; {e}"),
                        None => e.to_string(),
                    });
                }
                let row = SweepRow {
                    index: run.index,
                    assignments: run.assignments.clone(),
                    dir,
                    outcome,
                    error,
                };
                bar.set_message(format!(
                    "{}: {}",
                    row.label(),
                    row.error
                        .as_deref()
                        .map_or("ok".to_string(), |e| format!("FAILED {e}"))
                ));
                bar.inc(1);
                rows.lock().unwrap_or_else(|e| e.into_inner()).push(row);
            });
        }
    });
    bar.finish();
    let mut rows = rows.into_inner().unwrap_or_else(|e| e.into_inner());
    rows.sort_by_key(|r| r.index);
    if shard.is_none() {
        write_outputs(&plan.id.params, &rows, out)?;
    }
    Ok(rows)
}

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

fn row_values(row: &SweepRow) -> Vec<String> {
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

fn map_values(row: &SweepRow) -> Vec<String> {
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

fn write_tables(params: &[Param], rows: &[SweepRow], out: &Path) -> Result<(), SweepError> {
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

fn write_plots(params: &[Param], rows: &[SweepRow], out: &Path) -> Result<(), SweepError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_parse_and_multiply() {
        let a: Param = "battery=lipol250, ufx250".parse().unwrap();
        let b: Param = "timestep_ms=16,32,".parse().unwrap();
        assert_eq!(a.values, ["lipol250", "ufx250"]);
        let p = product(&[a, b]);
        assert_eq!(p.len(), 4);
        assert_eq!(
            p[1],
            [
                ("battery".into(), "lipol250".into()),
                ("timestep_ms".into(), "32".into())
            ]
        );
        assert_eq!(p[2][0].1, "ufx250");
        for bad in ["battery", "=1,2", "battery=", "battery=,"] {
            assert!(bad.parse::<Param>().is_err(), "{bad}");
        }
    }

    #[test]
    fn run_directories_are_flat_and_distinct() {
        let a = dir_name(0, &[("world".into(), "../w/x.toml".into())]);
        assert_eq!(a, "run-001_world=.._w_x.toml");
        assert!(!a.contains('/'));
    }

    #[test]
    fn markdown_escapes_cells_and_drops_the_dir_column() {
        let h: Vec<String> = ["run", "error", "dir"].map(String::from).to_vec();
        let t = markdown(&h, &[vec!["1".into(), "a|b".into(), "/x".into()]]);
        assert_eq!(t, "| run | error |\n|---|---|\n| 1 | a\\|b |\n");
    }
}
