//! Starting and supervising one run: `world-server` first, `sim-core`
//! second (it retries connecting), on a fresh private socket, both logs
//! forwarded with a prefix; if one dies the other is killed.

use std::ffi::OsString;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use protocol::Endpoint;

use crate::signals::Role;
pub use crate::supervise::LaunchError;
pub(crate) use crate::supervise::{
    describe, io_err, wait_for_socket, Echo, LogSink, Supervised, CONSOLE_ECHO_LINES,
};

use crate::outputs::{abs, files};
use crate::scenario::Scenario;

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

/// How the two processes ended.
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

/// Runs one scenario into `out` (created). Returns how the processes ended;
/// the outputs they wrote stay in `out` whatever happened.
pub fn launch(
    scenario: &Scenario,
    bins: &Binaries,
    out: &Path,
    opts: &LaunchOptions,
) -> Result<RunStatus, LaunchError> {
    std::fs::create_dir_all(out)
        .map_err(|e| io_err(format!("cannot create {}", out.display()), e))?;
    let out = out
        .canonicalize()
        .map_err(|e| io_err(format!("cannot resolve {}", out.display()), e))?;
    write_inputs(scenario, &out)?;
    let log = File::create(out.join(files::LOG))
        .map_err(|e| io_err(format!("cannot create {}", files::LOG), e))?;
    let sink = LogSink {
        file: Arc::new(Mutex::new(log)),
        echo: opts.echo,
        bars: None,
    };
    if let Some(world) = &opts.world_endpoint {
        return launch_platform_only(scenario, bins, world, &out, opts, &sink);
    }
    // A private directory (mode 0700, tempfile's default) for the socket: no
    // other user can connect, and two runs never share a path.
    let sock_dir = tempfile::Builder::new()
        .prefix("cosim-")
        .tempdir()
        .map_err(|e| io_err("cannot create a private socket directory", e))?;
    let socket = sock_dir.path().join("world.sock");

    let mut world_cmd = world_command(scenario, bins, &Endpoint::Unix(socket.clone()), &out, opts)?;
    let sim_cmd = sim_core_command(scenario, bins, &Endpoint::Unix(socket.clone()), &out, opts);
    if let Some(cmd) = &opts.world_cmd {
        let socket_text = socket.display().to_string();
        world_cmd = Command::new("sh");
        world_cmd
            .arg("-c")
            .arg(cmd.replace("{socket}", &socket_text))
            .env("COSIM_SOCKET", &socket_text);
    }

    let started = Instant::now();
    let mut world = Supervised::spawn("world", world_cmd, &sink, Role::First, Echo::All)?;
    if let Some(error) = wait_for_socket(&mut world, &socket) {
        let w = world.join();
        return Ok(RunStatus {
            sim_core: None,
            world: w.and_then(|s| s.code()),
            error: Some(crate::signals::requested().map_or(error, crate::signals::interrupted)),
            wall: started.elapsed(),
        });
    }
    let console = Echo::First(CONSOLE_ECHO_LINES);
    let mut sim = match Supervised::spawn("sim-core", sim_cmd, &sink, Role::Follower, console) {
        Ok(s) => s,
        Err(e) => {
            world.kill();
            world.join();
            return Err(e);
        }
    };

    let mut error: Option<String> = None;
    loop {
        if let Some(st) = sim.poll() {
            // The world exits by itself after STOP; after a failure it may
            // wait for a request forever.
            let grace = if st.success() { 10 } else { 1 };
            if !world.finish_within(Duration::from_secs(grace)) && st.success() {
                error = Some("world-server did not exit after the run ended".into());
            }
            break;
        }
        if let Some(st) = world.poll() {
            if !st.success() {
                error = Some(format!(
                    "world-server failed ({}); sim-core killed",
                    describe(Some(st))
                ));
                // Let sim-core report the broken link itself first (a
                // signal stopped the world: as long as crate::signals lets it).
                let grace = match crate::signals::requested() {
                    Some(_) => crate::signals::FOLLOWER_GRACE + crate::signals::KILL_GRACE,
                    None => Duration::from_secs(2),
                };
                sim.finish_within(grace);
                break;
            }
            // The world ended cleanly (after STOP): sim-core writes its outputs.
            sim.finish_within(Duration::from_secs(60));
            break;
        }
        if let Some(limit) = opts.timeout {
            if started.elapsed() > limit {
                error = Some(format!(
                    "timed out after {limit:?} of wall time; both killed"
                ));
                sim.kill();
                world.kill();
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let sim_status = sim.join();
    let world_status = world.join();
    if let Some(sig) = crate::signals::requested() {
        error = Some(crate::signals::interrupted(sig));
    }
    if error.is_none() {
        match (
            sim_status.map(|s| s.success()),
            world_status.map(|s| s.success()),
        ) {
            (Some(true), Some(true)) => {}
            (Some(true), _) => {
                error = Some(format!(
                    "world-server ended with {}",
                    describe(world_status)
                ))
            }
            _ => error = Some(format!("sim-core failed ({})", describe(sim_status))),
        }
    }
    Ok(RunStatus {
        sim_core: sim_status.and_then(|s| s.code()),
        world: world_status.and_then(|s| s.code()),
        error,
        wall: started.elapsed(),
    })
}

/// sim-core alone, against a world that was started elsewhere: it retries
/// connecting for its `--connect-timeout` (30 s), so the world may come up
/// after it; the run ends when sim-core does.
fn launch_platform_only(
    scenario: &Scenario,
    bins: &Binaries,
    world: &Endpoint,
    out: &Path,
    opts: &LaunchOptions,
    sink: &LogSink,
) -> Result<RunStatus, LaunchError> {
    let started = Instant::now();
    sink.line("cosim", &format!("world at {world} (not started here)"));
    let cmd = sim_core_command(scenario, bins, world, out, opts);
    let console = Echo::First(CONSOLE_ECHO_LINES);
    let mut sim = Supervised::spawn("sim-core", cmd, sink, Role::First, console)?;
    let mut error = None;
    while sim.poll().is_none() {
        if let Some(limit) = opts.timeout {
            if started.elapsed() > limit {
                error = Some(format!(
                    "timed out after {limit:?} of wall time; sim-core killed"
                ));
                sim.kill();
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let status = sim.join();
    if let Some(sig) = crate::signals::requested() {
        error = Some(crate::signals::interrupted(sig));
    }
    if error.is_none() && !status.is_some_and(|s| s.success()) {
        error = Some(format!("sim-core failed ({})", describe(status)));
    }
    Ok(RunStatus {
        sim_core: status.and_then(|s| s.code()),
        world: None,
        error,
        wall: started.elapsed(),
    })
}

/// `world-server` for `scenario`, listening on `listen`: the world file,
/// timestep and substeps, the trajectory (and traces, frames) into `out`.
pub fn world_command(
    scenario: &Scenario,
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
        .arg("--busy-poll-us")
        .arg(scenario.busy_poll_us.to_string());
    mcap_args(&mut cmd, scenario, out);
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

/// `--mcap OUT/world.mcap` (merged into `run.mcap` after the run,
/// [`crate::foxglove`]) unless the scenario says `mcap = false`.
pub(crate) fn mcap_args(cmd: &mut Command, scenario: &Scenario, out: &Path) {
    if scenario.mcap {
        cmd.arg("--mcap")
            .arg(out.join(files::WORLD_MCAP))
            .arg("--mcap-image-every")
            .arg(scenario.mcap_image_every.to_string());
    }
}

/// `sim-core` for `scenario`, connecting to `world`, its outputs into `out`
/// (where `run.toml` was written).
pub fn sim_core_command(
    scenario: &Scenario,
    bins: &Binaries,
    world: &Endpoint,
    out: &Path,
    opts: &LaunchOptions,
) -> Command {
    let mut cmd = Command::new(&bins.sim_core);
    match world {
        // A bare path, as sim-core has always been given.
        Endpoint::Unix(path) => cmd.arg("--socket").arg(path),
        Endpoint::Tcp(_) => cmd.arg("--socket").arg(world.to_string()),
    };
    cmd.arg("--firmware")
        .arg(&scenario.firmware)
        .arg("--config")
        .arg(out.join(files::RUN_CONFIG))
        .arg("--out")
        .arg(out)
        .arg("--image-encoding")
        .arg(scenario.image_encoding.as_str())
        .arg("--busy-poll-us")
        .arg(scenario.busy_poll_us.to_string())
        .arg("--no-progress");
    if let Some(t) = scenario.max_time_s {
        cmd.arg("--max-time").arg(t.to_string());
    }
    // summary.json's gates_total (DESIGN.md §10): the world file's gates.
    if let Ok(w) = world_server::world_file::WorldDesc::load(&scenario.world) {
        if !w.gates.is_empty() {
            cmd.arg("--gates-total").arg(w.gates.len().to_string());
        }
    }
    if opts.traces {
        cmd.arg("--trace")
            .arg(out.join(scenario.run.series.file_name(files::PLATFORM_TRACE)));
        if opts.trace_images {
            cmd.arg("--trace-images");
        }
    }
    cmd.args(&opts.sim_core_args);
    cmd
}

/// Writes the resolved scenario and run configuration into the output
/// directory: sim-core reads `run.toml`, and a user can rerun from both.
fn write_inputs(scenario: &Scenario, out: &Path) -> Result<(), LaunchError> {
    let write = |name: &str, text: String| {
        std::fs::write(out.join(name), text).map_err(|e| io_err(format!("cannot write {name}"), e))
    };
    write(files::RUN_CONFIG, run_toml(&scenario.run))?;
    write(files::SCENARIO, scenario.resolved_toml())
}

/// The run configuration as sim-core reads it, with the platform file (when
/// there is one) as an absolute path so the file can be used from anywhere.
pub(crate) fn run_toml(run: &sim_core::config::RunConfig) -> String {
    let mut run = run.clone();
    if let Some(p) = &run.platform {
        run.platform = Some(PathBuf::from(abs(p)));
    }
    run.to_toml()
}
