//! Scenario files and the `cosim` launcher (DESIGN.md §1, §6).
//!
//! - [`scenario`]: `scenarios/*.toml`, `--set` overrides, checks.
//! - [`launch`]: the two processes on a private socket, supervised.
//! - [`report`]: outputs read back, plots, the printed summary.
//! - [`sweep`]: cartesian products of parameters run in parallel.
//! - [`replay`]: a world server that answers from a recorded trace.
//! - [`tracetool`]: `cosim trace show` and `cosim trace-check`.
//! - [`plot`]: the PNG figures.
//! - [`swarm`]: scenarios with several drones (`[[platform]]` tables).
//! - [`perturb`]: `cosim world perturb`, courses with displaced gates.
//! - [`mapping`]: the map of an exploration run scored against the world.
//! - [`bench_race`]: `cosim bench race`, what the thesis's race costs.
//! - [`foxglove`]: `run.mcap`, the world's and the platforms' channels merged.
//! - [`signals`]: SIGINT/SIGTERM reach every child; none outlives cosim.

pub mod bench_cluster;
pub mod bench_iss;
pub mod bench_race;
pub mod deck_report;
pub mod endurance;
pub mod foxglove;
pub mod launch;
pub mod mapping;
pub mod nn;
pub mod outputs;
pub mod perturb;
pub mod plot;
pub mod report;
pub mod scenario;
pub mod signals;
mod supervise;
pub mod swarm;
pub mod sweep;
pub mod tracetool;

use std::path::{Path, PathBuf};

pub use launch::{launch, Binaries, LaunchError, LaunchOptions, RunStatus};
pub use scenario::{Scenario, ScenarioError};
use sim_core::kernel::Summary;

/// Everything one `cosim run` produced.
#[derive(Debug)]
pub struct RunOutcome {
    pub status: RunStatus,
    /// `summary.json` as read back (None if sim-core never wrote it).
    pub summary: Option<Summary>,
    /// SOC at the start (from `power.csv`).
    pub soc_init: f64,
    pub plots: Vec<PathBuf>,
    /// Why the outputs could not be read or drawn, if so.
    pub report_error: Option<String>,
    /// The printed summary (also in `report.txt`).
    pub text: String,
    /// A scenario with `[[platform]]` tables: each platform's outcome, in
    /// table order (then `summary` is None: the top-level `summary.json` is
    /// the swarm's, see [`swarm::report::SwarmSummary`]). Empty otherwise.
    pub drones: Vec<DroneOutcome>,
    /// An exploration run's map, scored (the `map` object of summary.json).
    pub map: Option<mapping::MapSummary>,
}

/// One platform of a run with several drones.
#[derive(Debug, Clone)]
pub struct DroneOutcome {
    pub drone: String,
    /// Its outputs (`<out>/<drone>`).
    pub dir: PathBuf,
    /// Its `summary.json` (None if its sim-core wrote none).
    pub summary: Option<Summary>,
    /// The same file as JSON (keys this launcher does not know included).
    pub raw: Option<serde_json::Value>,
    pub soc_init: f64,
    pub plots: Vec<PathBuf>,
    /// Its sim-core's exit code (None: killed).
    pub exit_code: Option<i32>,
    /// Its own report (`<drone>/report.txt`).
    pub text: String,
}

impl RunOutcome {
    /// A run succeeded when both processes ended cleanly, the firmware
    /// completed and the report could be made.
    pub fn ok(&self) -> bool {
        let completed = if self.drones.is_empty() {
            self.summary.as_ref().is_some_and(|s| s.completed)
        } else {
            self.drones
                .iter()
                .all(|d| d.summary.as_ref().is_some_and(|s| s.completed))
        };
        self.status.ok() && self.report_error.is_none() && completed
    }

    /// The first thing that went wrong, in one line.
    pub fn error(&self) -> Option<String> {
        if let Some(e) = &self.status.error {
            return Some(e.clone());
        }
        if let Some(e) = &self.report_error {
            return Some(e.clone());
        }
        for d in &self.drones {
            match &d.summary {
                None => return Some(format!("drone {}: no summary.json", d.drone)),
                Some(s) if !s.completed => {
                    return Some(format!(
                        "drone {}: {}",
                        d.drone,
                        s.error.clone().unwrap_or_else(|| format!(
                            "the run did not complete (exit code {})",
                            s.exit_code
                        ))
                    ))
                }
                Some(_) => {}
            }
        }
        match &self.summary {
            Some(s) if !s.completed => Some(s.error.clone().unwrap_or_else(|| {
                format!("the run did not complete (exit code {})", s.exit_code)
            })),
            _ => None,
        }
    }

    /// One outcome per drone, for tables with a row per drone (sweeps): each
    /// platform's summary with the run's status; a run with one drone is
    /// empty (its row is the run's).
    pub fn per_drone(&self) -> Vec<(String, RunOutcome)> {
        if self.drones.is_empty() {
            return Vec::new();
        }
        self.drones
            .iter()
            .map(|d| {
                (
                    d.drone.clone(),
                    RunOutcome {
                        status: self.status.clone(),
                        summary: d.summary.clone(),
                        soc_init: d.soc_init,
                        plots: d.plots.clone(),
                        report_error: self.report_error.clone(),
                        text: d.text.clone(),
                        drones: Vec::new(),
                        map: None,
                    },
                )
            })
            .collect()
    }
}

/// Runs a scenario into `out`, then reads the outputs, draws the plots and
/// writes `report.txt`. Launch errors (a binary missing) are errors; a run
/// that failed is an outcome with its error.
pub fn run_scenario(
    scenario: &Scenario,
    bins: &Binaries,
    out: &Path,
    opts: &LaunchOptions,
    draw: bool,
) -> Result<RunOutcome, LaunchError> {
    if !scenario.platforms.is_empty() {
        return swarm::run_swarm(scenario, bins, out, opts, draw);
    }
    let status = launch(scenario, bins, out, opts)?;
    let summary = report::read_summary(out);
    // Only the first row's SOC is needed here (the plots read the rest).
    let first: Option<report::PowerRow> =
        report::read_first(&out.join(sim_core::power::log::POWER_CSV)).unwrap_or_default();
    let soc_init = report::initial_soc(first.as_slice());
    let mut report_error = None;
    let mut plots = Vec::new();
    let summary = match summary {
        Ok(s) => Some(s),
        Err(e) => {
            report_error = Some(e.to_string());
            None
        }
    };
    // The map first: run.mcap carries it.
    let map = mapping::process(
        &scenario.world,
        out,
        summary.as_ref().map(|s| s.cycles),
        draw,
    );
    // run.mcap is written on its own thread while the plots are drawn
    // (docs/FOXGLOVE.md "Cost").
    let mcap_job = scenario.mcap.then(|| {
        let name = world_server::WorldDesc::load(&scenario.world)
            .ok()
            .and_then(|w| w.drones.first().map(|d| d.name.clone()))
            .unwrap_or_else(|| "cf1".into());
        let drone = foxglove::DroneOutputs {
            name,
            dir: out.to_path_buf(),
            map_cell_m: map.as_ref().ok().and_then(|m| m.as_ref()).map(|m| m.cell_m),
        };
        foxglove::spawn_run_mcap(out, vec![drone], scenario.mcap_power_every)
    });
    if draw && summary.is_some() {
        match report::draw_run_plots(scenario, out) {
            Ok(p) => plots = p,
            Err(e) => report_error = Some(e.to_string()),
        }
    }
    let map = match map {
        Ok(m) => m,
        Err(e) => {
            report_error = Some(e.to_string());
            None
        }
    };
    if map.is_some() && draw {
        plots.push(out.join(outputs::map_files::MAP_PNG));
    }
    if let Some(job) = mcap_job {
        match foxglove::join(job) {
            // A world that died left its file cut short: the run's own
            // error says why; a clean run with a cut file is an error.
            Ok(m) => match m.warning {
                Some(w) if status.ok() => {
                    report_error.get_or_insert(w);
                }
                Some(w) => tracing::debug!("{w}"),
                None => {}
            },
            Err(e) => {
                report_error.get_or_insert(e.to_string());
            }
        }
    }
    let text = match &summary {
        Some(s) => {
            let mut t = report::summary_text(scenario, s, &status, soc_init, out, &plots);
            if let Some(m) = &map {
                t.push_str(&mapping::summary_line(m));
            }
            // A peer killed mid-run left its series cut short: the report
            // above was made from what they hold.
            for w in report::torn_series(out) {
                t.push_str(&format!("   dropped        {w}\n"));
            }
            if let Some(e) = &report_error {
                t.push_str(&format!("   report error   {e}\n"));
            }
            t
        }
        None => format!(
            "== {} — FAILED: {}\n   outputs        {} (see {})\n",
            scenario.name,
            status
                .error
                .clone()
                .or_else(|| report_error.clone())
                .unwrap_or_default(),
            out.display(),
            outputs::files::LOG
        ),
    };
    // The report is a convenience copy of what is printed; failing to
    // write it must not hide the run's result.
    let _ = std::fs::write(out.join(outputs::files::REPORT), &text);
    Ok(RunOutcome {
        status,
        summary,
        soc_init,
        plots,
        report_error,
        text,
        drones: Vec::new(),
        map,
    })
}
