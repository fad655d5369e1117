//! `cosim replay`, `cosim trace-check`.

use crate::BinArgs;
use anyhow::{bail, Context};
use scenarios::scenario::find_repo_file;
use scenarios::tracetool;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use world_server::replay::{self, ReplayOptions};

pub(crate) fn cmd_replay(
    trace: PathBuf,
    drone: Option<String>,
    socket: PathBuf,
    frames: Option<PathBuf>,
    tolerance: f64,
) -> anyhow::Result<ExitCode> {
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        bail!("--tolerance must be a number >= 0");
    }
    // One drone of a world trace of several: its lines, byte for byte, in
    // a file of their own (the replay serves one platform).
    let scratch = tempfile::tempdir().context("cannot create a scratch directory")?;
    let trace = match drone {
        None => {
            let drones = tracetool::trace_drones(&tracetool::read_trace(&trace)?);
            if !drones.is_empty() {
                bail!(
                    "{} holds the frames of several drones ({}); pick one with --drone NAME",
                    trace.display(),
                    drones.join(", ")
                );
            }
            trace
        }
        Some(d) => {
            let dest = scratch.path().join("drone.trace");
            if tracetool::extract_drone(&trace, &d, &dest)? == 0 {
                let drones = tracetool::trace_drones(&tracetool::read_trace(&trace)?);
                bail!(
                    "{} has no frames of drone {d:?} (drones: {})",
                    trace.display(),
                    if drones.is_empty() {
                        "none named: a trace of one drone needs no --drone".to_string()
                    } else {
                        drones.join(", ")
                    }
                );
            }
            dest
        }
    };
    let ok = replay::replay_and_report(
        &trace,
        &protocol::Endpoint::Unix(socket),
        &ReplayOptions { frames, tolerance },
    )?;
    Ok(if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

pub(crate) fn cmd_trace_check(
    trace: PathBuf,
    world_cmd: Option<String>,
    world: Option<PathBuf>,
    tolerance: f64,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    let records = tracetool::read_trace(&trace)?;
    let drones = tracetool::trace_drones(&records);
    let cmd = match world_cmd {
        Some(c) => c,
        None => {
            let ws = bins.locate()?.world_server;
            let world = match world {
                Some(w) => w,
                None if !drones.is_empty() => bail!(
                    "{} is a trace of several drones ({}): pass --world with the world file it was recorded in",
                    trace.display(),
                    drones.join(", ")
                ),
                None => find_repo_file("scenarios/worlds/thesis-course.toml")
                    .context("the default world scenarios/worlds/thesis-course.toml was not found; pass --world")?,
            };
            let ts = tracetool::trace_timestep(&records).unwrap_or(32);
            format!(
                "'{}' --socket '{{socket}}' --world '{}' --timestep {ts}",
                ws.display(),
                world.display()
            )
        }
    };
    let proc_ = tracetool::start_world(&cmd)?;
    let report = tracetool::check_drones(
        &records,
        &proc_.endpoint,
        tolerance,
        Duration::from_secs(30),
    )?;
    match report.first_difference {
        None => {
            println!(
                "trace-check: {} requests sent, {} replies compared, all within {tolerance}",
                report.requests, report.replies
            );
            Ok(ExitCode::SUCCESS)
        }
        Some((seq, cmd, d)) => {
            println!(
                "trace-check: first reply that differs: #{seq} ({cmd}) after {} requests: {d}",
                report.requests
            );
            Ok(ExitCode::FAILURE)
        }
    }
}
