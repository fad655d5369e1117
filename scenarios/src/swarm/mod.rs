//! Scenarios with several drones (DESIGN.md §7, docs/SWARM.md §5): one
//! world-server, one sim-core per `[[platform]]`, each platform's outputs
//! in `<out>/<drone>/`, the world's and the overall ones in `<out>/`.
//!
//! The processes are started by [`crate::launch`], as for one drone
//! (DESIGN.md §19); this module reads back what they wrote
//! ([`report_swarm`]).
//!
//! - [`platforms`]: the `[[platform]]` tables of a scenario file.
//! - [`report`]: the outputs split and read back, `summary.json`, the report.
//! - [`plot`]: the top view with every drone and the radio links.
//! - [`console`], [`positioning_spec`], [`positioning`], [`accuracy`],
//!   [`load`]: seed 003's positioning read back (its console lines, the
//!   `[positioning]` table, the estimates against the truth, the tables,
//!   the core's load and the packets).
//! - [`radar`]: seed 004's drone-to-drone radar read back.
//! - [`bench`]: `cosim bench swarm` (real-time factor against the swarm's size).

pub mod accuracy;
pub mod bench;
pub mod console;
pub mod load;
pub mod platforms;
pub mod plot;
pub mod positioning;
pub mod positioning_spec;
pub mod radar;
pub mod report;

use std::collections::BTreeMap;
use std::path::Path;

use sim_core::power::log::POWER_CSV;

use crate::launch::{LaunchStatus, RunStatus};
use crate::outcome::{DroneOutcome, RunOutcome};
use crate::outputs::{drone_dir, files};
use crate::report::{self as run_report, plots, PowerRow};
use crate::scenario::{Scenario, RADIO_ID_KEY};
use crate::world::World;

use self::plot::{DronePath, Link};
use self::report::{DroneFigures, Ranging};
use crate::outputs::swarm_files;

/// The scenario as one platform sees it (for its own report and plots).
fn platform_view(scenario: &Scenario, i: usize) -> Scenario {
    let p = &scenario.platforms[i];
    let mut s = scenario.clone();
    s.name = format!("{}/{}", scenario.name, p.drone);
    s.firmware = p.firmware.clone();
    s.run = p.run.clone();
    s.targets = p.targets.clone();
    s.platforms.clear();
    s
}

/// After the launch of a scenario with `[[platform]]` tables in `world`
/// into `out` ([`crate::launch::launch`]), which ended as `st`: splits and
/// reads the outputs, draws the plots and writes `summary.json` and the
/// reports. A run that failed is an outcome.
pub fn report_swarm(
    scenario: &Scenario,
    world: &World,
    st: LaunchStatus,
    out: &Path,
    draw: bool,
) -> RunOutcome {
    // run.mcap on its own thread while the reports and plots are made
    // (docs/FOXGLOVE.md "Cost").
    let mcap_job = scenario.mcap.then(|| {
        let outputs = scenario
            .platforms
            .iter()
            .map(|p| crate::foxglove::DroneOutputs {
                name: p.drone.clone(),
                dir: drone_dir(out, &p.drone),
                map_cell_m: None,
            })
            .collect();
        crate::foxglove::spawn_run_mcap(out, outputs, scenario.mcap_power_every)
    });
    let names: Vec<String> = scenario.platforms.iter().map(|p| p.drone.clone()).collect();
    let mut report_error: Option<String> = None;
    // After a failure, outputs cut short are its consequence, not news.
    let failed = st.error.is_some();
    let mut note = |e: String| {
        if failed {
            tracing::debug!("{e}");
        } else {
            tracing::warn!("{e}");
            report_error.get_or_insert(e);
        }
    };

    // The world's outputs, per drone. Another world server (--world-cmd)
    // may write no trajectory: then there is no top view.
    let traj = out.join(files::TRAJECTORY);
    let tracks = if protocol::series::exists(&traj) {
        match report::split_trajectory(out, &names) {
            Ok(t) => t,
            Err(e) => {
                note(e.to_string());
                BTreeMap::new()
            }
        }
    } else {
        BTreeMap::new()
    };
    let radio_path = out.join(swarm_files::RADIO_LOG);
    let radio = if radio_path.exists() {
        match report::read_radio_log(&radio_path) {
            Ok(r) => Some(r),
            Err(e) => {
                note(e.to_string());
                None
            }
        }
    } else {
        None
    };

    let exit_of = |d: &str| {
        st.platforms
            .iter()
            .find(|(n, _)| n == d)
            .and_then(|(_, c)| *c)
    };
    let mut drones = Vec::new();
    for (i, p) in scenario.platforms.iter().enumerate() {
        let dir = drone_dir(out, &p.drone);
        let summary = run_report::read_summary(&dir).ok();
        let raw = std::fs::read_to_string(dir.join(files::SUMMARY))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
        let power: Vec<PowerRow> = run_report::read_csv(&dir.join(POWER_CSV)).unwrap_or_default();
        let soc_init = run_report::initial_soc(&power);
        drop(power);
        let view = platform_view(scenario, i);
        let mut plots = Vec::new();
        if draw && summary.is_some() {
            match run_report::draw_power_plots(&view, &dir) {
                Ok(p) => plots.extend(p),
                Err(e) => note(format!("{}: {e}", p.drone)),
            }
            if let Some(t) = tracks.get(&p.drone) {
                let top = dir.join(plots::TOP_VIEW);
                let path = drone_path(scenario, world, i, t);
                match plot::swarm_top_view(
                    &top,
                    &format!("{}: flight seen from above", view.name),
                    &[path],
                    &[],
                    Some(&world.desc),
                ) {
                    Ok(()) => plots.push(top),
                    Err(e) => note(e.to_string()),
                }
            }
        }
        let own = RunStatus {
            sim_core: exit_of(&p.drone),
            world: st.world,
            error: match exit_of(&p.drone) {
                Some(0) => None,
                code => Some(format!(
                    "sim-core ended with {}",
                    code.map_or("a signal".into(), |c| format!("exit code {c}"))
                )),
            },
            wall: st.wall,
        };
        let text = match &summary {
            Some(s) => run_report::summary_text(&view, s, &own, soc_init, &dir, &plots),
            None => format!(
                "== {} — FAILED: {}\n   outputs        {}\n",
                view.name,
                own.error
                    .clone()
                    .unwrap_or_else(|| "no summary.json".into()),
                dir.display()
            ),
        };
        let _ = std::fs::write(dir.join(files::REPORT), &text);
        drones.push(DroneOutcome {
            drone: p.drone.clone(),
            dir,
            summary,
            raw,
            soc_init,
            plots,
            exit_code: exit_of(&p.drone),
            text,
        });
    }

    if let Some(job) = mcap_job {
        match crate::foxglove::join(job) {
            Ok(m) => {
                if let Some(w) = m.warning {
                    note(w);
                }
            }
            Err(e) => note(e.to_string()),
        }
    }

    let ranging = ranging(scenario, out, &tracks);
    let positioning = match positioning::analyse(scenario, out, &tracks, draw) {
        Ok(p) => p,
        Err(e) => {
            note(e.to_string());
            None
        }
    };
    let figures: Vec<DroneFigures<'_>> = drones
        .iter()
        .map(|d| DroneFigures {
            drone: &d.drone,
            summary: d.summary.as_ref(),
            raw: d.raw.clone(),
            exit_code: d.exit_code,
        })
        .collect();
    let sum = report::swarm_summary(
        &scenario.name,
        scenario.timestep_ms.get(),
        &figures,
        st.world,
        st.error.clone(),
        st.wall.as_secs_f64(),
        radio.as_ref(),
        ranging,
    );
    match serde_json::to_string_pretty(&sum) {
        Ok(text) => {
            if let Err(e) = std::fs::write(out.join(files::SUMMARY), text + "\n") {
                note(format!("cannot write {}: {e}", files::SUMMARY));
            }
        }
        Err(e) => note(format!("cannot write {}: {e}", files::SUMMARY)),
    }

    // Seed 004's radar (radar.elf): who detected whom, and how far apart.
    match radar::read_run(out, &names, &tracks, sum.collisions) {
        Ok(Some(r)) => {
            let path = out.join(radar::RADAR_JSON);
            let text = serde_json::to_string_pretty(&r).unwrap_or_default();
            if let Err(e) = std::fs::write(&path, text + "\n") {
                note(format!("cannot write {}: {e}", path.display()));
            }
        }
        Ok(None) => {}
        Err(e) => note(format!("radar: {e}")),
    }

    let mut top_plots = Vec::new();
    if draw && !tracks.is_empty() {
        let paths: Vec<DronePath> = scenario
            .platforms
            .iter()
            .enumerate()
            .map(|(i, p)| {
                drone_path(
                    scenario,
                    world,
                    i,
                    tracks.get(&p.drone).unwrap_or(&Default::default()),
                )
            })
            .collect();
        let mut links = Vec::new();
        if let Some(r) = &radio {
            for a in 0..names.len() {
                for b in a + 1..names.len() {
                    let frames = r.between(&names[a], &names[b]);
                    if frames > 0 {
                        links.push(Link { a, b, frames });
                    }
                }
            }
        }
        let top = out.join(plots::TOP_VIEW);
        match plot::swarm_top_view(
            &top,
            &format!("{}: {} drones seen from above", scenario.name, names.len()),
            &paths,
            &links,
            Some(&world.desc),
        ) {
            Ok(()) => top_plots.push(top),
            Err(e) => note(e.to_string()),
        }
    }
    let lines: Vec<String> = drones
        .iter()
        .map(|d| report::drone_line(&d.drone, d.summary.as_ref(), d.soc_init, d.exit_code))
        .collect();
    if let Some(p) = &positioning {
        top_plots.extend(p.plots.iter().cloned());
    }
    let mut text = report::swarm_text(
        &scenario.name,
        &scenario.description,
        &scenario.overrides_label(),
        &sum,
        &lines,
        out,
        &top_plots,
    );
    if let Some(p) = &positioning {
        text.push_str(&p.text);
    }
    let _ = std::fs::write(out.join(files::REPORT), &text);
    let failed_code = st
        .platforms
        .iter()
        .map(|(_, c)| *c)
        .find(|c| *c != Some(0))
        .unwrap_or(Some(0));
    RunOutcome {
        status: RunStatus {
            sim_core: failed_code,
            world: st.world,
            error: st.error,
            wall: st.wall,
        },
        summary: None,
        soc_init: 1.0,
        plots: top_plots,
        report_error,
        text,
        drones,
        map: None,
    }
}

/// A drone's path for the plots: its track, its start from the world file,
/// its targets.
fn drone_path(
    scenario: &Scenario,
    world: &World,
    i: usize,
    track: &report::DroneTrack,
) -> DronePath {
    let p = &scenario.platforms[i];
    let start = world
        .start_of(&p.drone)
        .map(|s| (s[0], s[1]))
        .or_else(|| track.points.first().map(|(_, q)| (q[0], q[1])))
        .unwrap_or((0.0, 0.0));
    let pts: Vec<(f64, f64)> = track.points.iter().map(|(_, q)| (q[0], q[1])).collect();
    DronePath {
        name: p.drone.clone(),
        points: plot::thin(&pts, 5000),
        start,
        targets: p.targets.clone(),
    }
}

/// The distances each firmware printed, against the true ones.
fn ranging(
    scenario: &Scenario,
    out: &Path,
    tracks: &BTreeMap<String, report::DroneTrack>,
) -> Vec<Ranging> {
    let ids: Vec<(String, Option<u64>)> = scenario
        .platforms
        .iter()
        .map(|p| {
            (
                p.drone.clone(),
                p.run.get(RADIO_ID_KEY).ok().and_then(|v| v.parse().ok()),
            )
        })
        .collect();
    let mut out_v = Vec::new();
    for p in &scenario.platforms {
        let console = std::fs::read_to_string(drone_dir(out, &p.drone).join(files::CONSOLE))
            .unwrap_or_default();
        let m = report::parse_measured(&console, &p.drone, &ids);
        for (peer, v) in &m.per_peer {
            let Some((mean, sd)) = report::mean_sd(v) else {
                continue;
            };
            let true_m = match (tracks.get(&p.drone), tracks.get(peer)) {
                (Some(a), Some(b)) => report::mean_distance(a, b),
                _ => None,
            };
            out_v.push(Ranging {
                from: p.drone.clone(),
                to: peer.clone(),
                count: v.len(),
                measured_mean_m: mean,
                measured_sd_m: sd,
                true_m,
            });
        }
    }
    out_v
}

/// Whether a `summary.json` is the top-level summary of a run with several
/// drones (a [`report::SwarmSummary`], with its `drones` map) rather than
/// one platform's.
pub fn is_swarm_summary(json: &[u8]) -> bool {
    serde_json::from_slice::<serde_json::Value>(json)
        .is_ok_and(|v| v.get("drones").is_some_and(serde_json::Value::is_object))
}

/// The platforms' outcomes of a finished run with several drones, read back
/// from its directory (for tools that rebuild a table from run directories,
/// e.g. a sweep merged from shards). Empty for a run with one drone.
pub fn read_drones(run_dir: &Path) -> Vec<DroneOutcome> {
    let Ok(top) = std::fs::read(run_dir.join(files::SUMMARY)) else {
        return Vec::new();
    };
    let Ok(sum) = serde_json::from_slice::<report::SwarmSummary>(&top) else {
        return Vec::new();
    };
    sum.platforms
        .iter()
        .map(|d| {
            let dir = drone_dir(run_dir, d);
            let power: Vec<PowerRow> =
                run_report::read_csv(&dir.join(POWER_CSV)).unwrap_or_default();
            let plots = [plots::POWER, plots::BATTERY, plots::TOP_VIEW]
                .iter()
                .map(|p| dir.join(p))
                .filter(|p| p.is_file())
                .collect();
            DroneOutcome {
                drone: d.clone(),
                summary: run_report::read_summary(&dir).ok(),
                raw: sum.drones.get(d).filter(|v| !v.is_null()).cloned(),
                soc_init: run_report::initial_soc(&power),
                plots,
                exit_code: sum.platform_exit_codes.get(d).copied().flatten(),
                text: std::fs::read_to_string(dir.join(files::REPORT)).unwrap_or_default(),
                dir,
            }
        })
        .collect()
}
