//! `cosim`: runs the thesis's experiments end to end (DESIGN.md §1, §6).
//!
//! - `cosim run [SCENARIO] [--out DIR] [--set KEY=VALUE]...`
//! - `cosim sweep SCENARIO --param KEY=V1,V2,... [--jobs N]`
//! - `cosim replay TRACE --socket PATH [--frames DIR]`
//! - `cosim trace show TRACE`, `cosim trace-check TRACE [--world-cmd CMD]`
//! - `cosim list`

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Args, Parser, Subcommand};
use scenarios::launch::LaunchOptions;
use scenarios::scenario::{find_repo_file, resolve_scenario, SCENARIO_KEYS};
use scenarios::sweep::{self, Param};
use scenarios::tracetool;
use scenarios::{run_scenario, Binaries, Scenario};
use world_server::replay::{self, ReplayOptions};

/// Co-simulation launcher: the virtual platform (sim-core) and the physics
/// world (world-server) started together, with reports, plots, sweeps and
/// trace tools.
#[derive(Parser, Debug)]
#[command(name = "cosim", version)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
    #[command(flatten)]
    bins: BinArgs,
}

#[derive(Args, Debug, Clone)]
struct BinArgs {
    /// The sim-core binary (default: next to cosim, or $COSIM_SIM_CORE).
    #[arg(long, value_name = "PATH", global = true)]
    sim_core: Option<PathBuf>,
    /// The world-server binary (default: next to cosim, or $COSIM_WORLD_SERVER).
    #[arg(long, value_name = "PATH", global = true)]
    world_server: Option<PathBuf>,
    /// Under `cargo run`, do not `cargo build` sim-core and world-server first.
    #[arg(long, global = true)]
    no_build: bool,
}

impl BinArgs {
    fn locate(&self) -> anyhow::Result<Binaries> {
        Ok(Binaries::locate(
            self.sim_core.clone(),
            self.world_server.clone(),
            !self.no_build,
        )?)
    }
}

#[derive(Args, Debug, Clone)]
struct RunArgs {
    /// Overrides a scenario or run key (repeatable), e.g. `--set battery=ufx250`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// No world.trace / platform.trace.
    #[arg(long)]
    no_trace: bool,
    /// Keep the camera pixels in the traces (large; replay can use --frames instead).
    #[arg(long)]
    trace_images: bool,
    /// Let the world write every camera frame as a PNG into OUT/frames.
    #[arg(long)]
    frames: bool,
    /// Kill the run after this many seconds of wall time.
    #[arg(long, value_name = "S")]
    timeout: Option<f64>,
    /// Run another world server instead of ours: a shell command with
    /// `{socket}` for the socket path, e.g.
    /// `--world-cmd 'python3 examples/python-world/world.py --socket {socket}'`.
    #[arg(long, value_name = "CMD")]
    world_cmd: Option<String>,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Runs one scenario (default: the thesis race) and reports it.
    Run {
        /// A scenario file or a name in scenarios/ (thesis-race, hover-endurance, ...).
        scenario: Option<String>,
        /// Output directory (default: out/<scenario>).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        #[command(flatten)]
        run: RunArgs,
        /// No PNG plots.
        #[arg(long)]
        no_plots: bool,
        /// Do not echo the two programs' logs (cosim.log still has them).
        #[arg(long, short)]
        quiet: bool,
    },
    /// Runs every combination of parameter values, in parallel.
    Sweep {
        /// A scenario file or a name in scenarios/.
        scenario: String,
        /// KEY=V1,V2,... (repeatable; default: the scenario's [sweep] table).
        #[arg(long, value_name = "KEY=V1,V2,...")]
        param: Vec<String>,
        /// Runs at a time.
        #[arg(long, default_value_t = 2)]
        jobs: usize,
        /// Output directory (default: out/<scenario>-sweep).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Serves one platform from a recorded trace (world side).
    Replay {
        /// A trace (world.trace or platform.trace of a run).
        trace: PathBuf,
        /// UNIX socket to listen on.
        #[arg(long, value_name = "PATH")]
        socket: PathBuf,
        /// The PNG frames of the recorded run (for traces without image pixels).
        #[arg(long, value_name = "DIR")]
        frames: Option<PathBuf>,
        /// Relative tolerance when comparing requests (0: exact).
        #[arg(long, default_value_t = 0.0)]
        tolerance: f64,
    },
    /// Prints a trace as a readable listing.
    Trace {
        #[command(subcommand)]
        what: TraceCmd,
    },
    /// Sends a trace's requests to a live world server; reports the first reply that differs.
    TraceCheck {
        trace: PathBuf,
        /// Command that starts the world; `{socket}` is replaced by the socket
        /// path (also in $COSIM_SOCKET). Default: our world-server.
        #[arg(long, value_name = "CMD")]
        world_cmd: Option<String>,
        /// World file for the default world-server (default: the thesis course).
        #[arg(long, value_name = "FILE")]
        world: Option<PathBuf>,
        /// Relative tolerance for numbers.
        #[arg(long, default_value_t = 1e-9)]
        tolerance: f64,
    },
    /// Lists the scenarios shipped in scenarios/.
    List,
}

#[derive(Subcommand, Debug)]
enum TraceCmd {
    /// The listing: sequence, clock, direction, command, fields.
    Show {
        trace: PathBuf,
        /// Only this command.
        #[arg(long, value_name = "COMMAND")]
        command: Option<String>,
        /// At most N lines.
        #[arg(long, value_name = "N")]
        limit: Option<usize>,
        /// Whole messages instead of short fields.
        #[arg(long)]
        full: bool,
    },
}

fn load_scenario(arg: Option<&str>, sets: &[String]) -> anyhow::Result<Scenario> {
    let path = resolve_scenario(arg)?;
    let mut s = Scenario::load(&path)?;
    for a in sets {
        s.set(a)?;
    }
    s.check_files()?;
    Ok(s)
}

fn launch_options(run: &RunArgs, echo: bool) -> anyhow::Result<LaunchOptions> {
    let timeout = match run.timeout {
        Some(t) if t.is_finite() && t > 0.0 => Some(Duration::from_secs_f64(t)),
        Some(_) => bail!("--timeout must be a positive number of seconds"),
        None => None,
    };
    Ok(LaunchOptions {
        echo,
        traces: !run.no_trace,
        trace_images: run.trace_images,
        frames: run.frames,
        timeout,
        sim_core_args: Vec::new(),
        world_cmd: run.world_cmd.clone(),
    })
}

fn cmd_run(
    scenario: Option<String>,
    out: Option<PathBuf>,
    run: RunArgs,
    no_plots: bool,
    quiet: bool,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    let s = load_scenario(scenario.as_deref(), &run.set)?;
    let out = out.unwrap_or_else(|| Path::new("out").join(&s.name));
    let bins = bins.locate()?;
    eprintln!("cosim: {} — {} -> {}", s.name, s.description, out.display());
    let o = run_scenario(&s, &bins, &out, &launch_options(&run, !quiet)?, !no_plots)?;
    println!("{}", o.text);
    Ok(if o.ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn cmd_sweep(
    scenario: String,
    param: Vec<String>,
    jobs: usize,
    out: Option<PathBuf>,
    run: RunArgs,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    let s = load_scenario(Some(&scenario), &run.set)?;
    let params: Vec<Param> = if param.is_empty() {
        s.sweep
            .iter()
            .map(|(k, v)| Param {
                key: k.clone(),
                values: v.clone(),
            })
            .collect()
    } else {
        param.iter().map(|p| p.parse()).collect::<Result<_, _>>()?
    };
    let out = out.unwrap_or_else(|| Path::new("out").join(format!("{}-sweep", s.name)));
    let bins = bins.locate()?;
    let opts = launch_options(&run, false)?;
    let rows = sweep::run_sweep(&s, &params, &bins, &out, jobs, &opts)?;
    let md = std::fs::read_to_string(out.join(sweep::files::MARKDOWN))
        .context("reading the sweep table back")?;
    println!("{md}");
    let failed = rows.iter().filter(|r| r.error.is_some()).count();
    println!(
        "{} runs, {} failed; table {} and {}; plots in {}",
        rows.len(),
        failed,
        out.join(sweep::files::MARKDOWN).display(),
        out.join(sweep::files::CSV).display(),
        out.display()
    );
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn cmd_replay(
    trace: PathBuf,
    socket: PathBuf,
    frames: Option<PathBuf>,
    tolerance: f64,
) -> anyhow::Result<ExitCode> {
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        bail!("--tolerance must be a number >= 0");
    }
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

fn cmd_trace_check(
    trace: PathBuf,
    world_cmd: Option<String>,
    world: Option<PathBuf>,
    tolerance: f64,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    let records = tracetool::read_trace(&trace)?;
    let cmd = match world_cmd {
        Some(c) => c,
        None => {
            let ws = bins.locate()?.world_server;
            let world = match world {
                Some(w) => w,
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
    let report = tracetool::check(
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

fn cmd_list() -> anyhow::Result<ExitCode> {
    let dir = find_repo_file("scenarios/thesis-race.toml")
        .and_then(|p| p.parent().map(Path::to_path_buf))
        .context("scenarios/ not found")?;
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        // The crate's own manifest shares the directory with the scenarios.
        .filter(|p| p.file_name().is_some_and(|n| n != "Cargo.toml"))
        .collect();
    names.sort();
    for p in names {
        match Scenario::load(&p) {
            Ok(s) => println!("{:<18} {}", s.name, s.description),
            Err(e) => println!("{:<18} (invalid: {e})", p.display()),
        }
    }
    println!("\n--set keys: {}", SCENARIO_KEYS.map(|(k, _)| k).join(", "));
    println!(
        "run keys:   {}",
        sim_core::config::RUN_KEYS.map(|(k, _)| k).join(", ")
    );
    Ok(ExitCode::SUCCESS)
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let bins = cli.bins;
    let result = match cli.command {
        Cmd::Run {
            scenario,
            out,
            run,
            no_plots,
            quiet,
        } => cmd_run(scenario, out, run, no_plots, quiet, bins),
        Cmd::Sweep {
            scenario,
            param,
            jobs,
            out,
            run,
        } => cmd_sweep(scenario, param, jobs, out, run, bins),
        Cmd::Replay {
            trace,
            socket,
            frames,
            tolerance,
        } => cmd_replay(trace, socket, frames, tolerance),
        Cmd::Trace {
            what:
                TraceCmd::Show {
                    trace,
                    command,
                    limit,
                    full,
                },
        } => tracetool::read_trace(&trace)
            .map(|r| {
                print!("{}", tracetool::show(&r, command.as_deref(), limit, full));
                ExitCode::SUCCESS
            })
            .map_err(Into::into),
        Cmd::TraceCheck {
            trace,
            world_cmd,
            world,
            tolerance,
        } => cmd_trace_check(trace, world_cmd, world, tolerance, bins),
        Cmd::List => cmd_list(),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("cosim: {e:#}");
            ExitCode::from(2)
        }
    }
}
