//! Starting and supervising one run (DESIGN.md §19: a single drone is a
//! swarm of one): `world-server` first, on a fresh private socket (or a
//! world already running elsewhere, `--world-endpoint`), then one
//! `sim-core` per platform: the scenario's one drone, or one per
//! `[[platform]]` (`sim-core --drone NAME`, docs/SWARM.md §5). Every log is
//! forwarded with a prefix (`[world]`, `[sim-core]`, or the drone's name:
//! `[A]`, `[B]`, …); several platforms are shown as one progress line each.
//!
//! If one process dies the others are stopped: the world, when a platform
//! disconnects before its STOP, sends ERROR to the other platforms, flushes
//! its outputs and exits (docs/SWARM.md §2), and the platforms, told so,
//! write theirs and exit. The launcher waits for that to happen, and only
//! then kills what is left: first the world (a platform that loses its
//! world writes its outputs on the broken link), then the platforms.

use std::ffi::OsString;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use protocol::Endpoint;
use sim_core::config::RunConfig;

use crate::signals::Role;
pub use crate::supervise::LaunchError;
use crate::supervise::{
    describe, io_err, wait_for_socket, Echo, LogSink, Supervised, CONSOLE_ECHO_LINES,
};

use crate::outputs::{abs, drone_dir, files, swarm_files};
use crate::scenario::Scenario;
use crate::world::World;

/// How long the world waits for every drone to be claimed: the platforms
/// start right after its socket exists, so this is only a safety net for a
/// loaded machine (docs/SWARM.md §2).
const CONNECT_TIMEOUT_S: u64 = 60;
/// After the first failure: time for the others to end by themselves.
const FAILURE_GRACE: Duration = Duration::from_secs(5);
/// After every platform ended: time for the world to exit by itself.
const WORLD_GRACE: Duration = Duration::from_secs(10);
/// After the world ended cleanly: time for the platforms to write their outputs.
const CLEAN_GRACE: Duration = Duration::from_secs(60);
/// Where no progress bar is drawn: how often a platform's last console line
/// is shown.
const PLAIN_PROGRESS_EVERY: Duration = Duration::from_secs(15);

/// Where the two binaries are.
#[derive(Debug, Clone)]
pub struct Binaries {
    pub sim_core: PathBuf,
    pub world_server: PathBuf,
}

impl Binaries {
    /// `--sim-core`/`--world-server`, else `COSIM_SIM_CORE`/`COSIM_WORLD_SERVER`,
    /// else next to this executable (cargo puts all three in one directory).
    /// When cosim was started by `cargo run` (the `CARGO` variable is set) and
    /// neither binary was given, the two are first brought up to date with
    /// `cargo build` for the same profile and target directory, unless
    /// `build` is false: `cargo run -p scenarios --bin cosim` alone does not
    /// build the other packages' binaries.
    pub fn locate(
        sim_core: Option<PathBuf>,
        world_server: Option<PathBuf>,
        build: bool,
    ) -> Result<Binaries, LaunchError> {
        let env = |k: &str| std::env::var_os(k).map(PathBuf::from);
        let sim_core = sim_core.or_else(|| env("COSIM_SIM_CORE"));
        let world_server = world_server.or_else(|| env("COSIM_WORLD_SERVER"));
        let exe_dir = std::env::current_exe()
            .ok()
            .and_then(|p| p.parent().map(Path::to_path_buf))
            .unwrap_or_else(|| PathBuf::from("."));
        if build && (sim_core.is_none() || world_server.is_none()) {
            if let Some(cargo) = std::env::var_os("CARGO") {
                cargo_build(&cargo, &exe_dir)?;
            }
        }
        let exe = |name: &str| exe_dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
        let b = Binaries {
            sim_core: sim_core.unwrap_or_else(|| exe("sim-core")),
            world_server: world_server.unwrap_or_else(|| exe("world-server")),
        };
        for (what, path, flag) in [
            ("sim-core", &b.sim_core, "--sim-core"),
            ("world-server", &b.world_server, "--world-server"),
        ] {
            if !path.is_file() {
                return Err(LaunchError::MissingBinary {
                    what,
                    path: path.clone(),
                    hint: format!(
                        "build it with `cargo build --release --workspace`, or pass {flag} PATH"
                    ),
                });
            }
        }
        Ok(b)
    }
}

/// `cargo build -p sim-core -p world-server` into the profile directory
/// `exe_dir` (target/<profile>) of the running cosim. Said on stderr
/// first, with cargo's own progress: on a fresh clone it takes minutes.
fn cargo_build(cargo: &OsString, exe_dir: &Path) -> Result<(), LaunchError> {
    let mut cmd = Command::new(cargo);
    cmd.args(["build", "-p", "sim-core", "-p", "world-server"]);
    let profile = match exe_dir.file_name().and_then(|n| n.to_str()) {
        Some("debug") => "debug",
        Some("release") => {
            cmd.arg("--release");
            "release"
        }
        Some(other) => {
            cmd.args(["--profile", other]);
            other
        }
        None => return Ok(()),
    };
    if let Some(target) = exe_dir.parent() {
        cmd.env("CARGO_TARGET_DIR", target);
    }
    // Build from the source tree cosim itself was built from.
    cmd.current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."));
    eprintln!("cosim: building sim-core and world-server ({profile}) with cargo ...");
    let status = crate::signals::run_to_end(&mut cmd, crate::signals::Role::First)
        .map_err(|e| LaunchError::Build(e.to_string()))?;
    if let Some(sig) = crate::signals::requested() {
        return Err(LaunchError::Build(crate::signals::interrupted(sig)));
    }
    if status.success() {
        Ok(())
    } else {
        Err(LaunchError::Build(status.to_string()))
    }
}

/// How a run is launched.
#[derive(Debug, Clone)]
pub struct LaunchOptions {
    /// Echo the prefixed logs on stderr (always written to `cosim.log`).
    pub echo: bool,
    /// Write `world.trace` and `platform.trace`.
    pub traces: bool,
    /// Keep image pixels in the traces (needed by replay without frames).
    pub trace_images: bool,
    /// Let the world write every camera frame as a PNG into `OUT/frames`
    /// (what replay needs for a trace without pixels).
    pub frames: bool,
    /// Wall-clock limit for the whole run (a safety net, not a result).
    pub timeout: Option<Duration>,
    /// Extra arguments for sim-core (e.g. `--no-idle-skip`).
    pub sim_core_args: Vec<String>,
    /// Another world server instead of ours: a command run by `sh -c`, with
    /// `{socket}` replaced by the socket path (also in `$COSIM_SOCKET`). It
    /// gets none of our world's flags (world file, timestep, traces,
    /// trajectory): the platform's trace and outputs are still written.
    pub world_cmd: Option<String>,
    /// A world already running elsewhere (`tcp:HOST:PORT`, e.g. started
    /// with `cosim world` on another host): only sim-core is started, and
    /// connects there. The world's outputs stay where the world runs.
    pub world_endpoint: Option<Endpoint>,
}

impl Default for LaunchOptions {
    fn default() -> Self {
        LaunchOptions {
            echo: true,
            traces: true,
            trace_images: false,
            frames: false,
            timeout: None,
            sim_core_args: Vec::new(),
            world_cmd: None,
            world_endpoint: None,
        }
    }
}

/// How one drone's run ended, as its report and a sweep's table see it.
#[derive(Debug, Clone)]
pub struct RunStatus {
    /// sim-core's exit code (`None`: killed by a signal).
    pub sim_core: Option<i32>,
    /// world-server's exit code (`None`: killed, by us or a signal).
    pub world: Option<i32>,
    /// What went wrong, in one line (None when both ended cleanly).
    pub error: Option<String>,
    /// Wall time of the whole launch.
    pub wall: Duration,
}

impl RunStatus {
    pub fn ok(&self) -> bool {
        self.error.is_none()
    }
}

/// How the processes of a launch ended.
#[derive(Debug, Clone)]
pub struct LaunchStatus {
    /// world-server's exit code (`None`: killed, by us or a signal, or not
    /// started here).
    pub world: Option<i32>,
    /// Each platform's sim-core exit code, in [`platforms`] order.
    pub platforms: Vec<(String, Option<i32>)>,
    /// What went wrong first, in one line, naming the process.
    pub error: Option<String>,
    /// Wall time of the whole launch.
    pub wall: Duration,
}

impl LaunchStatus {
    pub fn ok(&self) -> bool {
        self.error.is_none()
    }

    /// The status of a run with one platform.
    pub fn single(self) -> RunStatus {
        RunStatus {
            sim_core: self.platforms.first().and_then(|(_, c)| *c),
            world: self.world,
            error: self.error,
            wall: self.wall,
        }
    }
}

/// One platform of a run: one `sim-core`.
#[derive(Debug, Clone)]
pub struct Platform<'a> {
    /// Its log prefix and the name errors give it: the drone of a
    /// `[[platform]]` table, `sim-core` for a scenario's one drone.
    pub label: String,
    /// The world's drone it claims (`--drone`); `None`: the world's only
    /// drone, as a scenario without `[[platform]]` tables flies it.
    pub drone: Option<&'a str>,
    pub firmware: &'a Path,
    pub run: &'a RunConfig,
    /// Where its outputs go: `OUT` for a scenario's one drone (the layout
    /// of DESIGN.md §6), `OUT/<drone>` for a `[[platform]]` (§7).
    pub dir: PathBuf,
}

/// The platforms a scenario starts, outputs under `out`: its one drone, or
/// one per `[[platform]]`, in file order.
pub fn platforms<'a>(scenario: &'a Scenario, out: &Path) -> Vec<Platform<'a>> {
    if scenario.platforms.is_empty() {
        return vec![Platform {
            label: "sim-core".into(),
            drone: None,
            firmware: &scenario.firmware,
            run: &scenario.run,
            dir: out.to_path_buf(),
        }];
    }
    scenario
        .platforms
        .iter()
        .map(|p| Platform {
            label: p.drone.clone(),
            drone: Some(&p.drone),
            firmware: &p.firmware,
            run: &p.run,
            dir: drone_dir(out, &p.drone),
        })
        .collect()
}

fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} {prefix:<10} [{elapsed_precise}] {wide_msg}")
        .expect("a valid template")
}

/// Runs a scenario into `out` (created): the world (unless it runs
/// elsewhere, `--world-endpoint`) and every platform of [`platforms`].
/// Returns how the processes ended; the outputs they wrote stay in `out`
/// whatever happened.
pub fn launch(
    scenario: &Scenario,
    world_file: &World,
    bins: &Binaries,
    out: &Path,
    opts: &LaunchOptions,
) -> Result<LaunchStatus, LaunchError> {
    std::fs::create_dir_all(out)
        .map_err(|e| io_err(format!("cannot create {}", out.display()), e))?;
    let out = out
        .canonicalize()
        .map_err(|e| io_err(format!("cannot resolve {}", out.display()), e))?;
    let platforms = platforms(scenario, &out);
    write_inputs(scenario, &platforms, &out)?;
    let log = File::create(out.join(files::LOG))
        .map_err(|e| io_err(format!("cannot create {}", files::LOG), e))?;
    // With `[[platform]]` tables: one progress line per process.
    let bars = (opts.echo && !scenario.platforms.is_empty())
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
    let finish_bar = |bar: &Option<ProgressBar>, status: Option<ExitStatus>| {
        if let Some(b) = bar {
            b.finish_with_message(format!("ended ({})", describe(status)));
        }
    };
    let not_started = || -> Vec<(String, Option<i32>)> {
        platforms.iter().map(|p| (p.label.clone(), None)).collect()
    };

    let started = Instant::now();
    // A private directory (mode 0700, tempfile's default) for the socket: no
    // other user can connect, and two runs never share a path. Kept until
    // the processes ended.
    let mut _sock_dir = None;
    // A world that runs elsewhere has no line here.
    let world_bar = opts
        .world_endpoint
        .is_none()
        .then(|| new_bar("world"))
        .flatten();
    let (endpoint, mut world) = match &opts.world_endpoint {
        Some(ep) => {
            sink.line("cosim", &format!("world at {ep} (not started here)"));
            (ep.clone(), None)
        }
        None => {
            let dir = tempfile::Builder::new()
                .prefix("cosim-")
                .tempdir()
                .map_err(|e| io_err("cannot create a private socket directory", e))?;
            let socket = dir.path().join("world.sock");
            _sock_dir = Some(dir);
            let cmd = match &opts.world_cmd {
                Some(cmd) => foreign_world_command(cmd, &socket),
                None => world_command(
                    scenario,
                    world_file,
                    bins,
                    &Endpoint::Unix(socket.clone()),
                    &out,
                    opts,
                )?,
            };
            let mut w = Supervised::spawn(
                "world-server",
                "world".into(),
                cmd,
                &sink,
                world_bar.clone(),
                Role::First,
                Echo::All,
            )?;
            if let Some(error) = wait_for_socket(&mut w, &socket) {
                let st = w.join();
                finish_bar(&world_bar, st);
                return Ok(LaunchStatus {
                    world: st.and_then(|s| s.code()),
                    platforms: not_started(),
                    error: Some(
                        crate::signals::requested().map_or(error, crate::signals::interrupted),
                    ),
                    wall: started.elapsed(),
                });
            }
            (Endpoint::Unix(socket), Some(w))
        }
    };

    // One drone's console is echoed (its first lines); the consoles of
    // several (thousands of lines: a swarm's estimates at 100 Hz) go to the
    // logs, and the terminal shows each one's last line on its progress
    // bar, or, where no bar is drawn, one line now and then.
    let console = match &bars {
        _ if scenario.platforms.is_empty() => Echo::First(CONSOLE_ECHO_LINES),
        Some(b) if !b.is_hidden() => Echo::Never,
        _ => Echo::Every(PLAIN_PROGRESS_EVERY),
    };
    // Against a world started elsewhere the platforms are the first to be
    // told of a signal (crate::signals), else the world is.
    let role = if world.is_some() {
        Role::Follower
    } else {
        Role::First
    };
    let gates = world_file.desc.gates.len();
    let mut sims: Vec<(Supervised, Option<ProgressBar>)> = Vec::new();
    for p in &platforms {
        let bar = new_bar(&p.label);
        let cmd = sim_core_command(scenario, p, gates, bins, &endpoint, opts);
        match Supervised::spawn(
            "sim-core",
            p.label.clone(),
            cmd,
            &sink,
            bar.clone(),
            role,
            console,
        ) {
            Ok(s) => sims.push((s, bar)),
            Err(e) => {
                for (s, _) in &mut sims {
                    s.kill();
                }
                if let Some(w) = &mut world {
                    w.kill();
                }
                for (s, _) in sims {
                    s.join();
                }
                if let Some(w) = world {
                    w.join();
                }
                return Err(e);
            }
        }
    }

    let names = Names::of(&platforms);
    let mut error: Option<String> = None;
    // Every process that ended badly by itself, in the order seen: the one
    // to blame is chosen once all have ended (a platform told by the world
    // that another died may be seen first).
    let mut failures: Vec<Failure> = Vec::new();
    // Once set: when the processes still running are killed.
    let mut stop_at: Option<Instant> = None;
    let mut world_done = world.is_none();
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
            let in_order = stopped_in_order(&platforms[i].dir);
            failures.push(Failure::Sim { i, st, in_order });
            if !in_order {
                stop_at.get_or_insert(Instant::now() + FAILURE_GRACE);
            }
        }
        if let (Some(w), false) = (&mut world, world_done) {
            if let Some(st) = w.poll() {
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
        // Every platform ended and the world is still running (a firmware
        // that never claimed its drone, a world that missed a STOP): it
        // gets 10 s to exit by itself.
        if !world_done && sim_done.iter().all(|d| *d) && stop_at.is_none() {
            stop_at = Some(Instant::now() + WORLD_GRACE);
            world_lingers = failures.is_empty();
        }
        if let Some(limit) = opts.timeout {
            if started.elapsed() > limit {
                error = Some(format!(
                    "timed out after {limit:?} of wall time; every process killed"
                ));
                if let Some(w) = &mut world {
                    w.kill();
                }
                for (s, _) in &mut sims {
                    s.kill();
                }
                break;
            }
        }
        if stop_at.is_some_and(|t| Instant::now() > t) {
            // The world first: a platform that loses its world writes its
            // outputs on the broken link.
            if let (Some(w), false) = (&mut world, world_done) {
                if world_lingers {
                    error.get_or_insert_with(|| {
                        format!(
                            "world-server did not exit within {WORLD_GRACE:?} after the platforms ended; killed"
                        )
                    });
                } else {
                    tracing::warn!("world-server still running after a failure; killing it");
                }
                w.kill();
            }
            let until = Instant::now() + Duration::from_secs(2);
            for (s, _) in &mut sims {
                s.finish_within(until.saturating_duration_since(Instant::now()));
            }
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut statuses = Vec::new();
    let mut failed_sim = None;
    for ((s, bar), p) in sims.into_iter().zip(&platforms) {
        let st = s.join();
        if !bar.as_ref().is_some_and(|b| b.is_finished()) {
            finish_bar(&bar, st);
        }
        if failed_sim.is_none() && !st.is_some_and(|s| s.success()) {
            failed_sim = Some(format!("{} failed ({})", names.sim(p), describe(st)));
        }
        statuses.push((p.label.clone(), st.and_then(|s| s.code())));
    }
    let started_here = world.is_some();
    let world_status = world.and_then(|w| w.join());
    if started_here && !world_bar.as_ref().is_some_and(|b| b.is_finished()) {
        finish_bar(&world_bar, world_status);
    }
    if let Some(sig) = crate::signals::requested() {
        error = Some(crate::signals::interrupted(sig));
    }
    if error.is_none() {
        error = blame(&failures, &platforms, &names);
    }
    if error.is_none() {
        if let Some(e) = failed_sim {
            error = Some(e);
        } else if started_here && !world_status.is_some_and(|s| s.success()) {
            error = Some(format!(
                "world-server ended with {}",
                describe(world_status)
            ));
        }
    }
    Ok(LaunchStatus {
        world: world_status.and_then(|s| s.code()),
        platforms: statuses,
        error,
        wall: started.elapsed(),
    })
}

/// How errors name the processes: `sim-core` when there is one platform,
/// `platform A: sim-core` among several.
struct Names {
    several: bool,
}

impl Names {
    fn of(platforms: &[Platform<'_>]) -> Names {
        Names {
            several: platforms.iter().any(|p| p.drone.is_some()),
        }
    }

    fn sim(&self, p: &Platform<'_>) -> String {
        if self.several {
            format!("platform {}: sim-core", p.label)
        } else {
            "sim-core".into()
        }
    }

    /// What was stopped after the world failed.
    fn platforms(&self) -> &'static str {
        if self.several {
            "the platforms were stopped"
        } else {
            "sim-core was stopped"
        }
    }
}

/// A platform that exited with an error but whose drone was stopped (its
/// summary has the world's STOP time) left the world in order: the others
/// go on. Any other end before the world's is a death.
fn stopped_in_order(dir: &Path) -> bool {
    summary_of(dir).is_some_and(|s| s.world_time_s.is_some())
}

/// A platform's `summary.json`, if it wrote one that reads (what the
/// report reads in full later; here only its error and STOP time matter).
fn summary_of(dir: &Path) -> Option<sim_core::kernel::Summary> {
    let text = std::fs::read_to_string(dir.join(files::SUMMARY)).ok()?;
    serde_json::from_str(&text).ok()
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
fn blames_another(platforms: &[Platform<'_>], i: usize) -> bool {
    let me = &platforms[i];
    let Some(err) = summary_of(&me.dir).and_then(|s| s.error) else {
        return false;
    };
    platforms.iter().filter_map(|p| p.drone).any(|other| {
        Some(other) != me.drone
            && err.match_indices(&format!("drone {other}")).any(|(at, m)| {
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
fn blame(failures: &[Failure], platforms: &[Platform<'_>], names: &Names) -> Option<String> {
    let sim = |i: usize, st: ExitStatus| {
        format!(
            "{} died ({}); the other processes were stopped",
            names.sim(&platforms[i]),
            describe(Some(st))
        )
    };
    let world = |st: ExitStatus| {
        format!(
            "world-server failed ({}); {}",
            describe(Some(st)),
            names.platforms()
        )
    };
    let signalled = |st: &ExitStatus| st.code().is_none();
    failures
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
                } if !blames_another(platforms, *i) => Some(sim(*i, *st)),
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
                    "{} ended with {}",
                    names.sim(&platforms[*i]),
                    describe(Some(*st))
                )),
                _ => None,
            })
        })
}

/// `--world-cmd`: another world server, run by `sh -c` with `{socket}`
/// replaced by the socket path (also in `$COSIM_SOCKET`).
fn foreign_world_command(cmd: &str, socket: &Path) -> Command {
    let socket_text = socket.display().to_string();
    let mut c = Command::new("sh");
    c.arg("-c")
        .arg(cmd.replace("{socket}", &socket_text))
        .env("COSIM_SOCKET", &socket_text);
    c
}

/// `world-server` for `scenario`, listening on `listen`: the world file,
/// timestep and substeps, the trajectory (and traces, frames, run.mcap's
/// part, with `[[platform]]` tables the radio log) into `out`.
pub fn world_command(
    scenario: &Scenario,
    world: &World,
    bins: &Binaries,
    listen: &Endpoint,
    out: &Path,
    opts: &LaunchOptions,
) -> Result<Command, LaunchError> {
    let mut cmd = Command::new(&bins.world_server);
    match listen {
        Endpoint::Unix(path) => cmd.arg("--socket").arg(path),
        Endpoint::Tcp(addr) => cmd.arg("--tcp").arg(addr),
    };
    cmd.arg("--world")
        .arg(
            world
                .file_for_run(scenario.radio_seed, out)
                .map_err(|e| LaunchError::Io(e.to_string()))?,
        )
        .arg("--timestep")
        .arg(scenario.timestep_ms.to_string())
        .arg("--substeps")
        .arg(scenario.substeps.to_string())
        .arg("--trajectory")
        .arg(out.join(scenario.run.series.file_name(files::TRAJECTORY)));
    if !scenario.platforms.is_empty() {
        cmd.arg("--radio-log").arg(out.join(swarm_files::RADIO_LOG));
    }
    cmd.arg("--connect-timeout")
        .arg(CONNECT_TIMEOUT_S.to_string())
        .arg("--busy-poll-us")
        .arg(scenario.busy_poll_us().to_string());
    // `OUT/world.mcap`, merged into `run.mcap` after the run
    // (crate::foxglove), unless the scenario says `mcap = false`.
    if scenario.mcap {
        cmd.arg("--mcap")
            .arg(out.join(files::WORLD_MCAP))
            .arg("--mcap-image-every")
            .arg(scenario.mcap_image_every.to_string());
    }
    if opts.traces {
        cmd.arg("--trace")
            .arg(out.join(scenario.run.series.file_name(files::WORLD_TRACE)));
        if opts.trace_images {
            cmd.arg("--trace-images");
        }
    }
    if opts.frames {
        let frames = out.join(files::FRAMES);
        std::fs::create_dir_all(&frames)
            .map_err(|e| io_err(format!("cannot create {}", frames.display()), e))?;
        cmd.arg("--frames-dir").arg(frames);
    }
    Ok(cmd)
}

/// `sim-core` for platform `p`, connecting to `world`, its outputs into
/// `p.dir` (where its `run.toml` was written); `gates`: the world file's
/// gates (summary.json's `gates_total`, DESIGN.md §10).
fn sim_core_command(
    scenario: &Scenario,
    p: &Platform<'_>,
    gates: usize,
    bins: &Binaries,
    world: &Endpoint,
    opts: &LaunchOptions,
) -> Command {
    let mut cmd = Command::new(&bins.sim_core);
    match world {
        // A bare path, as sim-core has always been given.
        Endpoint::Unix(path) => cmd.arg("--socket").arg(path),
        Endpoint::Tcp(_) => cmd.arg("--socket").arg(world.to_string()),
    };
    if let Some(drone) = p.drone {
        cmd.arg("--drone").arg(drone);
    }
    cmd.arg("--firmware")
        .arg(p.firmware)
        .arg("--config")
        .arg(p.dir.join(files::RUN_CONFIG))
        .arg("--out")
        .arg(&p.dir)
        .arg("--image-encoding")
        .arg(scenario.image_encoding.as_str())
        .arg("--busy-poll-us")
        .arg(scenario.busy_poll_us().to_string())
        .arg("--no-progress");
    if let Some(t) = scenario.max_time_s {
        cmd.arg("--max-time").arg(t.to_string());
    }
    if gates > 0 {
        cmd.arg("--gates-total").arg(gates.to_string());
    }
    if opts.traces {
        cmd.arg("--trace").arg(
            p.dir
                .join(scenario.run.series.file_name(files::PLATFORM_TRACE)),
        );
        if opts.trace_images {
            cmd.arg("--trace-images");
        }
    }
    cmd.args(&opts.sim_core_args);
    cmd
}

/// Writes each platform's run configuration (`run.toml` in its directory,
/// what its sim-core reads) and the resolved scenario (`scenario.toml`, top
/// level): a user can rerun from them.
fn write_inputs(
    scenario: &Scenario,
    platforms: &[Platform<'_>],
    out: &Path,
) -> Result<(), LaunchError> {
    let write = |path: &Path, text: String| {
        std::fs::write(path, text)
            .map_err(|e| io_err(format!("cannot write {}", path.display()), e))
    };
    for p in platforms {
        std::fs::create_dir_all(&p.dir)
            .map_err(|e| io_err(format!("cannot create {}", p.dir.display()), e))?;
        write(&p.dir.join(files::RUN_CONFIG), run_toml(p.run))?;
    }
    write(&out.join(files::SCENARIO), scenario.resolved_toml())
}

/// The run configuration as sim-core reads it, with the platform file (when
/// there is one) as an absolute path so the file can be used from anywhere.
fn run_toml(run: &RunConfig) -> String {
    let mut run = run.clone();
    if let Some(p) = &run.platform {
        run.platform = Some(PathBuf::from(abs(p)));
    }
    run.to_toml()
}
