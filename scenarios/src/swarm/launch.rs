//! Starting and supervising a run with several drones (docs/SWARM.md §5):
//! one `world-server` first, then one `sim-core --drone NAME` per
//! `[[platform]]`, all on one private socket, their logs forwarded with a
//! prefix (`[world]`, `[A]`, `[B]`, …) and shown as one progress line each.
//!
//! If one process dies the others are stopped: the world, when a platform
//! disconnects before its STOP, sends ERROR to the other platforms, flushes
//! its outputs and exits (docs/SWARM.md §2), and the platforms, told so,
//! write theirs and exit. The launcher waits for that to happen, and only
//! then kills what is left: first the world (a platform that loses its
//! world writes its outputs on the broken link), then the platforms.

use std::fs::File;
use std::path::Path;
use std::process::{Command, ExitStatus};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::launch::{
    describe, io_err, run_toml, wait_for_socket, Binaries, Echo, LaunchError, LaunchOptions,
    LogSink, Supervised,
};
use crate::outputs::{files, swarm_files};
use crate::scenario::Scenario;
use crate::signals::Role;

/// How long the world waits for every drone to be claimed: the platforms
/// start right after its socket exists, so this is only a safety net for a
/// loaded machine (docs/SWARM.md §2).
const CONNECT_TIMEOUT_S: u64 = 60;
/// After the first failure: time for the others to end by themselves.
const FAILURE_GRACE: Duration = Duration::from_secs(5);
/// After every platform ended cleanly: time for the world to exit by itself.
const WORLD_GRACE: Duration = Duration::from_secs(10);
/// After the world ended cleanly: time for the platforms to write their outputs.
const CLEAN_GRACE: Duration = Duration::from_secs(60);
/// Where no progress bar is drawn: how often a platform's last console line
/// is shown.
const PLAIN_PROGRESS_EVERY: Duration = Duration::from_secs(15);

/// How the processes of a run with several drones ended.
#[derive(Debug, Clone)]
pub struct SwarmStatus {
    /// world-server's exit code (`None`: killed, by us or a signal).
    pub world: Option<i32>,
    /// Each platform's sim-core exit code, in `[[platform]]` order.
    pub platforms: Vec<(String, Option<i32>)>,
    /// What went wrong first, in one line, naming the process.
    pub error: Option<String>,
    /// Wall time of the whole launch.
    pub wall: Duration,
}

impl SwarmStatus {
    pub fn ok(&self) -> bool {
        self.error.is_none()
    }
}

/// The directory of one platform's outputs.
pub fn drone_dir(out: &Path, drone: &str) -> std::path::PathBuf {
    out.join(drone)
}

fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} {prefix:<10} [{elapsed_precise}] {wide_msg}")
        .expect("a valid template")
}

/// The `sim-core` command of one platform.
fn sim_command(
    scenario: &Scenario,
    bins: &Binaries,
    socket: &Path,
    out: &Path,
    i: usize,
    opts: &LaunchOptions,
) -> Command {
    let p = &scenario.platforms[i];
    let dir = drone_dir(out, &p.drone);
    let mut cmd = Command::new(&bins.sim_core);
    cmd.arg("--socket")
        .arg(socket)
        .arg("--drone")
        .arg(&p.drone)
        .arg("--firmware")
        .arg(&p.firmware)
        .arg("--config")
        .arg(dir.join(files::RUN_CONFIG))
        .arg("--out")
        .arg(&dir)
        .arg("--image-encoding")
        .arg(scenario.image_encoding.as_str())
        .arg("--busy-poll-us")
        .arg(scenario.busy_poll_us.to_string())
        .arg("--no-progress");
    if let Some(t) = scenario.max_time_s {
        cmd.arg("--max-time").arg(t.to_string());
    }
    if opts.traces {
        cmd.arg("--trace")
            .arg(dir.join(scenario.run.series.file_name(files::PLATFORM_TRACE)));
        if opts.trace_images {
            cmd.arg("--trace-images");
        }
    }
    cmd.args(&opts.sim_core_args);
    cmd
}

/// The `world-server` command (or `--world-cmd`'s).
fn world_command(
    scenario: &Scenario,
    bins: &Binaries,
    socket: &Path,
    out: &Path,
    opts: &LaunchOptions,
) -> Result<Command, LaunchError> {
    if let Some(cmd) = &opts.world_cmd {
        let socket_text = socket.display().to_string();
        let mut c = Command::new("sh");
        c.arg("-c")
            .arg(cmd.replace("{socket}", &socket_text))
            .env("COSIM_SOCKET", &socket_text);
        return Ok(c);
    }
    let mut c = Command::new(&bins.world_server);
    c.arg("--socket")
        .arg(socket)
        .arg("--world")
        .arg(
            scenario
                .world_file_for_run(out)
                .map_err(|e| LaunchError::Io(e.to_string()))?,
        )
        .arg("--timestep")
        .arg(scenario.timestep_ms.to_string())
        .arg("--substeps")
        .arg(scenario.substeps.to_string())
        .arg("--trajectory")
        .arg(out.join(scenario.run.series.file_name(files::TRAJECTORY)))
        .arg("--radio-log")
        .arg(out.join(swarm_files::RADIO_LOG))
        .arg("--connect-timeout")
        .arg(CONNECT_TIMEOUT_S.to_string())
        .arg("--busy-poll-us")
        .arg(scenario.busy_poll_us.to_string());
    crate::launch::mcap_args(&mut c, scenario, out);
    if opts.traces {
        c.arg("--trace")
            .arg(out.join(scenario.run.series.file_name(files::WORLD_TRACE)));
        if opts.trace_images {
            c.arg("--trace-images");
        }
    }
    if opts.frames {
        let frames = out.join(files::FRAMES);
        std::fs::create_dir_all(&frames)
            .map_err(|e| io_err(format!("cannot create {}", frames.display()), e))?;
        c.arg("--frames-dir").arg(frames);
    }
    Ok(c)
}

/// Writes the resolved scenario (`scenario.toml`, top level) and each
/// platform's run configuration (`<drone>/run.toml`, what its sim-core reads).
fn write_inputs(scenario: &Scenario, out: &Path) -> Result<(), LaunchError> {
    let write = |path: &Path, text: String| {
        std::fs::write(path, text)
            .map_err(|e| io_err(format!("cannot write {}", path.display()), e))
    };
    for p in &scenario.platforms {
        let dir = drone_dir(out, &p.drone);
        std::fs::create_dir_all(&dir)
            .map_err(|e| io_err(format!("cannot create {}", dir.display()), e))?;
        write(&dir.join(files::RUN_CONFIG), run_toml(&p.run))?;
    }
    write(&out.join(files::SCENARIO), scenario.resolved_toml())
}

/// A platform that exited with an error but whose drone was stopped (its
/// summary has the world's STOP time) left the world in order: the others
/// go on. Any other end before the world's is a death.
fn stopped_in_order(out: &Path, drone: &str) -> bool {
    crate::report::read_summary(&drone_dir(out, drone)).is_ok_and(|s| s.world_time_s.is_some())
}

/// A process that ended badly by itself.
#[derive(Debug, Clone, Copy)]
enum Failure {
    /// Platform `i`; `in_order`: its drone had been stopped.
    Sim {
        i: usize,
        st: ExitStatus,
        in_order: bool,
    },
    World(ExitStatus),
}

/// Whether a platform's error blames another drone (the world's ERROR to
/// the others reads "drone B: …", docs/SWARM.md §2).
fn blames_another(out: &Path, scenario: &Scenario, i: usize) -> bool {
    let me = &scenario.platforms[i].drone;
    let Some(err) = crate::report::read_summary(&drone_dir(out, me))
        .ok()
        .and_then(|s| s.error)
    else {
        return false;
    };
    scenario.platforms.iter().any(|p| {
        p.drone != *me
            && err
                .match_indices(&format!("drone {}", p.drone))
                .any(|(at, m)| {
                    !err[at + m.len()..]
                        .starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-')
                })
    })
}

/// The one-line error of a run whose processes ended badly: the process
/// that caused it, not those that followed. In order: a platform killed by
/// a signal, the world killed by a signal, a platform that died for a
/// reason of its own (its error does not name another drone), the world's
/// own failure, a platform that failed after its drone was stopped.
fn blame(failures: &[Failure], scenario: &Scenario, out: &Path) -> Option<String> {
    let sim = |i: usize, st: ExitStatus| {
        format!(
            "platform {}: sim-core died ({}); the other processes were stopped",
            scenario.platforms[i].drone,
            describe(Some(st))
        )
    };
    let world = |st: ExitStatus| {
        format!(
            "world-server failed ({}); the platforms were stopped",
            describe(Some(st))
        )
    };
    let signalled = |st: &ExitStatus| st.code().is_none();
    let pick = failures
        .iter()
        .find_map(|f| match f {
            Failure::Sim { i, st, .. } if signalled(st) => Some(sim(*i, *st)),
            _ => None,
        })
        .or_else(|| {
            failures.iter().find_map(|f| match f {
                Failure::World(st) if signalled(st) => Some(world(*st)),
                _ => None,
            })
        })
        .or_else(|| {
            failures.iter().find_map(|f| match f {
                Failure::Sim {
                    i,
                    st,
                    in_order: false,
                } if !blames_another(out, scenario, *i) => Some(sim(*i, *st)),
                _ => None,
            })
        })
        .or_else(|| {
            failures.iter().find_map(|f| match f {
                Failure::World(st) => Some(world(*st)),
                _ => None,
            })
        })
        .or_else(|| {
            failures.iter().find_map(|f| match f {
                Failure::Sim { i, st, .. } => Some(format!(
                    "platform {}: sim-core ended with {}",
                    scenario.platforms[*i].drone,
                    describe(Some(*st))
                )),
                _ => None,
            })
        });
    pick
}

/// Runs a scenario with `[[platform]]` tables into `out` (created). The
/// outputs the processes wrote stay in `out` whatever happened.
pub fn launch_swarm(
    scenario: &Scenario,
    bins: &Binaries,
    out: &Path,
    opts: &LaunchOptions,
) -> Result<SwarmStatus, LaunchError> {
    std::fs::create_dir_all(out)
        .map_err(|e| io_err(format!("cannot create {}", out.display()), e))?;
    let out = out
        .canonicalize()
        .map_err(|e| io_err(format!("cannot resolve {}", out.display()), e))?;
    write_inputs(scenario, &out)?;
    let log = File::create(out.join(files::LOG))
        .map_err(|e| io_err(format!("cannot create {}", files::LOG), e))?;
    let bars = opts
        .echo
        .then(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr_with_hz(4)));
    let sink = LogSink {
        file: Arc::new(Mutex::new(log)),
        echo: opts.echo,
        bars: bars.clone(),
    };
    let new_bar = |name: &str| -> Option<ProgressBar> {
        bars.as_ref().map(|m| {
            let b = m.add(ProgressBar::new_spinner());
            b.set_style(bar_style());
            b.set_prefix(name.to_string());
            b.enable_steady_tick(Duration::from_millis(250));
            b
        })
    };
    // A private directory (mode 0700) for the socket, as for one drone.
    let sock_dir = tempfile::Builder::new()
        .prefix("cosim-")
        .tempdir()
        .map_err(|e| io_err("cannot create a private socket directory", e))?;
    let socket = sock_dir.path().join("world.sock");

    let started = Instant::now();
    let world_bar = new_bar("world");
    let mut world = Supervised::spawn_named(
        "world-server",
        "world".into(),
        world_command(scenario, bins, &socket, &out, opts)?,
        &sink,
        world_bar.clone(),
        Role::First,
        Echo::All,
    )?;
    let finish_bar = |bar: &Option<ProgressBar>, status: Option<ExitStatus>| {
        if let Some(b) = bar {
            b.finish_with_message(format!("ended ({})", describe(status)));
        }
    };
    if let Some(error) = wait_for_socket(&mut world, &socket) {
        let w = world.join();
        finish_bar(&world_bar, w);
        return Ok(SwarmStatus {
            world: w.and_then(|s| s.code()),
            platforms: scenario
                .platforms
                .iter()
                .map(|p| (p.drone.clone(), None))
                .collect(),
            error: Some(crate::signals::requested().map_or(error, crate::signals::interrupted)),
            wall: started.elapsed(),
        });
    }

    // The platforms' consoles (thousands of lines: a swarm's estimates at
    // 100 Hz) go to the logs; the terminal shows each one's last line on
    // its progress bar, or, where no bar is drawn, one line now and then.
    let console = match &bars {
        Some(b) if !b.is_hidden() => Echo::Never,
        _ => Echo::Every(PLAIN_PROGRESS_EVERY),
    };
    let mut sims: Vec<(Supervised, Option<ProgressBar>)> = Vec::new();
    for (i, p) in scenario.platforms.iter().enumerate() {
        let bar = new_bar(&p.drone);
        let cmd = sim_command(scenario, bins, &socket, &out, i, opts);
        match Supervised::spawn_named(
            "sim-core",
            p.drone.clone(),
            cmd,
            &sink,
            bar.clone(),
            Role::Follower,
            console,
        ) {
            Ok(s) => sims.push((s, bar)),
            Err(e) => {
                for (s, _) in &mut sims {
                    s.kill();
                }
                world.kill();
                for (s, _) in sims {
                    s.join();
                }
                world.join();
                return Err(e);
            }
        }
    }

    let mut error: Option<String> = None;
    // Every process that ended badly by itself, in the order seen: the one
    // to blame is chosen once all have ended (a platform told by the world
    // that another died may be seen first).
    let mut failures: Vec<Failure> = Vec::new();
    // Once set: when the processes still running are killed.
    let mut stop_at: Option<Instant> = None;
    let mut world_done = false;
    let mut world_lingers = false;
    let mut sim_done = vec![false; sims.len()];
    loop {
        for (i, (s, bar)) in sims.iter_mut().enumerate() {
            if sim_done[i] {
                continue;
            }
            let Some(st) = s.poll() else { continue };
            sim_done[i] = true;
            finish_bar(bar, Some(st));
            if st.success() {
                continue;
            }
            let in_order = stopped_in_order(&out, &scenario.platforms[i].drone);
            failures.push(Failure::Sim { i, st, in_order });
            if !in_order {
                stop_at.get_or_insert(Instant::now() + FAILURE_GRACE);
            }
        }
        if !world_done {
            if let Some(st) = world.poll() {
                world_done = true;
                finish_bar(&world_bar, Some(st));
                if st.success() {
                    stop_at.get_or_insert(Instant::now() + CLEAN_GRACE);
                } else {
                    failures.push(Failure::World(st));
                    stop_at.get_or_insert(Instant::now() + FAILURE_GRACE);
                }
            }
        }
        if world_done && sim_done.iter().all(|d| *d) {
            break;
        }
        // Every platform ended cleanly and the world is still running (a
        // firmware that never claimed its drone, a world that missed a
        // STOP): as for one drone, it gets 10 s to exit by itself.
        if !world_done && failures.is_empty() && sim_done.iter().all(|d| *d) && stop_at.is_none() {
            stop_at = Some(Instant::now() + WORLD_GRACE);
            world_lingers = true;
        }
        if let Some(limit) = opts.timeout {
            if started.elapsed() > limit {
                error = Some(format!(
                    "timed out after {limit:?} of wall time; every process killed"
                ));
                world.kill();
                for (s, _) in &mut sims {
                    s.kill();
                }
                break;
            }
        }
        if stop_at.is_some_and(|t| Instant::now() > t) {
            // The world first: a platform that loses its world writes its
            // outputs on the broken link.
            if !world_done {
                if world_lingers {
                    error.get_or_insert_with(|| {
                        format!(
                            "world-server did not exit within {WORLD_GRACE:?} after every platform ended; killed"
                        )
                    });
                } else {
                    tracing::warn!("world-server still running after a failure; killing it");
                }
                world.kill();
            }
            let until = Instant::now() + Duration::from_secs(2);
            for (s, _) in &mut sims {
                s.finish_within(until.saturating_duration_since(Instant::now()));
            }
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut platforms = Vec::new();
    let mut failed_sim = None;
    for ((s, bar), p) in sims.into_iter().zip(&scenario.platforms) {
        let st = s.join();
        if !bar.as_ref().is_some_and(|b| b.is_finished()) {
            finish_bar(&bar, st);
        }
        if failed_sim.is_none() && !st.is_some_and(|s| s.success()) {
            failed_sim = Some(format!(
                "platform {}: sim-core failed ({})",
                p.drone,
                describe(st)
            ));
        }
        platforms.push((p.drone.clone(), st.and_then(|s| s.code())));
    }
    let world_status = world.join();
    if !world_bar.as_ref().is_some_and(|b| b.is_finished()) {
        finish_bar(&world_bar, world_status);
    }
    if let Some(sig) = crate::signals::requested() {
        error = Some(crate::signals::interrupted(sig));
    }
    if error.is_none() {
        error = blame(&failures, scenario, &out);
    }
    if error.is_none() {
        if let Some(e) = failed_sim {
            error = Some(e);
        } else if !world_status.is_some_and(|s| s.success()) {
            error = Some(format!(
                "world-server ended with {}",
                describe(world_status)
            ));
        }
    }
    Ok(SwarmStatus {
        world: world_status.and_then(|s| s.code()),
        platforms,
        error,
        wall: started.elapsed(),
    })
}
