//! What one run produced, as the launcher hands it on (to its report, a
//! sweep's tables, the benchmarks).

use std::path::PathBuf;

use sim_core::kernel::Summary;

use crate::launch::RunStatus;

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
    /// the swarm's, see [`crate::swarm::report::SwarmSummary`]). Empty otherwise.
    pub drones: Vec<DroneOutcome>,
    /// An exploration run's map, scored (the `map` object of summary.json).
    pub map: Option<crate::mapping::MapSummary>,
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
