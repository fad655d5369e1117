//! One `cosim run`: the processes launched (one launch path for one drone
//! and for several, DESIGN.md §19), then the outputs read back, drawn and
//! summed up in `report.txt`.

use std::path::Path;

use crate::launch::{launch, Binaries, LaunchError, LaunchOptions};
use crate::outcome::RunOutcome;
use crate::scenario::Scenario;
use crate::world::World;
use crate::{foxglove, mapping, outputs, report, swarm};

/// Runs a scenario in `world` (its world file, as
/// [`Scenario::check_files`] read it) into `out`, then reads the outputs,
/// draws the plots and writes `report.txt`. Launch errors (a binary
/// missing) are errors; a run that failed is an outcome with its error.
pub fn run_scenario(
    scenario: &Scenario,
    world: &World,
    bins: &Binaries,
    out: &Path,
    opts: &LaunchOptions,
    draw: bool,
) -> Result<RunOutcome, LaunchError> {
    let launched = launch(scenario, world, bins, out, opts)?;
    if !scenario.platforms.is_empty() {
        return Ok(swarm::report_swarm(scenario, world, launched, out, draw));
    }
    let status = launched.single();
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
    let map = mapping::process(&world.desc, out, summary.as_ref().map(|s| s.cycles), draw);
    // run.mcap is written on its own thread while the plots are drawn
    // (docs/FOXGLOVE.md "Cost").
    let mcap_job = scenario.mcap.then(|| {
        let name = world.drone_names()[0].to_string();
        let drone = foxglove::DroneOutputs {
            name,
            dir: out.to_path_buf(),
            map_cell_m: map.as_ref().ok().and_then(|m| m.as_ref()).map(|m| m.cell_m),
        };
        foxglove::spawn_run_mcap(out, vec![drone], scenario.mcap_power_every)
    });
    if draw && summary.is_some() {
        match report::draw_run_plots(scenario, &world.desc, out) {
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
