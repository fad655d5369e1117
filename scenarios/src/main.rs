//! `cosim`: runs the thesis's experiments end to end (DESIGN.md §1, §6).
//!
//! - `cosim run [SCENARIO] [--out DIR] [--set KEY=VALUE]...`
//! - `cosim sweep SCENARIO --param KEY=V1,V2,... [--jobs N]`
//! - `cosim sweep SCENARIO --plan`, `cosim sweep SCENARIO --shard K/N [--out DIR]`,
//!   `cosim sweep --merge DIR... --out DIR` (a sweep across machines)
//! - `cosim replay TRACE --socket PATH [--frames DIR]`
//! - `cosim trace show TRACE`, `cosim trace-check TRACE [--world-cmd CMD]`
//! - `cosim world SCENARIO --listen tcp:HOST:PORT`, `cosim run SCENARIO
//!   --world-endpoint tcp:HOST:PORT` (a platform and its world on two hosts)
//! - `cosim bench swarm [--sizes 1,2,4,8]`, `cosim bench race`,
//!   `cosim bench cluster [--cores 1,2,4,8]`, `cosim bench iss [--qemu]`
//! - `cosim dataset WORLD --count N --seed S --out DIR` (labelled camera images)
//! - `cosim nn eval DIR [--cores N --mhz F --limit K --out FILE]` (the int8
//!   network on the ISS over a dataset)
//! - `cosim list`

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Args, Parser, Subcommand};
use scenarios::launch::LaunchOptions;
use scenarios::scenario::{find_repo_file, resolve_scenario, SCENARIO_KEYS};
use scenarios::sweep::{self, Param, Plan, Shard};
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
    /// Runs the scenario in another world file (the same as `--set
    /// world=FILE`), e.g. a perturbed course of `cosim perturb`.
    #[arg(long, value_name = "FILE")]
    world: Option<PathBuf>,
    /// No world.trace / platform.trace.
    #[arg(long)]
    no_trace: bool,
    /// Keep the camera pixels in the traces (large; replay can use --frames instead).
    #[arg(long)]
    trace_images: bool,
    /// Let the world write every camera frame as a PNG into OUT/frames.
    #[arg(long)]
    frames: bool,
    /// No run.mcap (the same as `--set mcap=false`; docs/FOXGLOVE.md).
    #[arg(long)]
    no_mcap: bool,
    /// Kill the run after this many seconds of wall time.
    #[arg(long, value_name = "S")]
    timeout: Option<f64>,
    /// Run another world server instead of ours: a shell command with
    /// `{socket}` for the socket path, e.g.
    /// `--world-cmd 'python3 examples/python-world/world.py --socket {socket}'`.
    #[arg(long, value_name = "CMD")]
    world_cmd: Option<String>,
}

/// `cosim perturb` / `cosim world perturb`.
#[derive(Args, Debug)]
struct PerturbArgs {
    /// The world file to start from (default: the thesis course).
    #[arg(long, value_name = "FILE")]
    from: Option<PathBuf>,
    /// Seed of the draw (ChaCha8).
    #[arg(long, value_name = "S")]
    seed: u64,
    /// Largest sideways offset in m (sideways offsets are drawn in
    /// [M/2, M], vertical ones in [-M/2, M/2]).
    #[arg(long, value_name = "M")]
    max_offset: f64,
    /// Where to write the new world file.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

#[derive(Subcommand, Debug)]
enum WorldCmd {
    /// Writes a world file whose gates are displaced (seeded) from the
    /// course's nominal positions (the same as `cosim perturb`).
    Perturb(PerturbArgs),
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
        /// Use a world that is already running, e.g. on another host
        /// (`cosim world SCENARIO --listen tcp:0.0.0.0:PORT` there): only
        /// sim-core is started, connecting to tcp:HOST:PORT (or unix:PATH).
        #[arg(long, value_name = "ENDPOINT", conflicts_with = "world_cmd")]
        world_endpoint: Option<protocol::Endpoint>,
    },
    /// Writes a world file whose gates are displaced (seeded) from the
    /// course's nominal positions: sideways in each gate's plane and
    /// vertically (`cosim world perturb ...` is the same command).
    Perturb(PerturbArgs),
    /// Renders N labelled camera images (PGM + labels.csv) of a world's
    /// course from random poses, gates moved and greys jittered (DESIGN.md
    /// §13; docs/NN.md): the neural network's training and test data.
    Dataset {
        /// The world file (e.g. scenarios/worlds/thesis-course.toml).
        world: PathBuf,
        /// Number of images.
        #[arg(long, value_name = "N")]
        count: usize,
        /// Seed of every draw (ChaCha8): same world, N and S give the same bytes.
        #[arg(long, value_name = "S")]
        seed: u64,
        /// Output directory (created if missing).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
    },
    /// Serves the world of a scenario on an endpoint, for one platform run
    /// elsewhere with `cosim run SCENARIO --world-endpoint ...`; exits after
    /// the run's STOP.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    World {
        /// `cosim world perturb ...`: the same as `cosim perturb ...` (a
        /// scenario named "perturb" cannot be served).
        #[command(subcommand)]
        action: Option<WorldCmd>,
        /// A scenario file or a name in scenarios/ (default: thesis-race).
        scenario: Option<String>,
        /// Where to listen: tcp:HOST:PORT (tcp:0.0.0.0:7000 for any
        /// interface; the protocol has no authentication: a trusted network
        /// only) or unix:PATH.
        #[arg(long, value_name = "ENDPOINT", required = true)]
        listen: Option<protocol::Endpoint>,
        /// Output directory for trajectory.csv and world.trace (default: out/<scenario>-world).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Overrides a scenario key (repeatable), as on the platform's side.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// No world.trace.
        #[arg(long)]
        no_trace: bool,
        /// Keep the camera pixels in the trace.
        #[arg(long)]
        trace_images: bool,
        /// Write every camera frame as a PNG into OUT/frames.
        #[arg(long)]
        frames: bool,
    },
    /// Runs every combination of parameter values, in parallel; or prints
    /// them (--plan), runs one shard of them (--shard) or merges shards
    /// (--merge): a sweep across machines (docs/COSIM.md).
    Sweep {
        /// A scenario file or a name in scenarios/ (none with --merge).
        #[arg(required_unless_present = "merge")]
        scenario: Option<String>,
        /// KEY=V1,V2,... (repeatable; default: the scenario's [sweep] table).
        #[arg(long, value_name = "KEY=V1,V2,...")]
        param: Vec<String>,
        /// Runs at a time.
        #[arg(long, default_value_t = 2)]
        jobs: usize,
        /// Output directory (default: out/<scenario>-sweep).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Prints the runs, one a line (`NUMBER key=value...`), and exits.
        #[arg(long, conflicts_with = "merge")]
        plan: bool,
        /// Runs only the runs whose number is ≡ K (mod N), 1 <= K <= N, into
        /// OUT's run directories (no table: `--merge` makes it).
        #[arg(long, value_name = "K/N", conflicts_with = "merge")]
        shard: Option<Shard>,
        /// Merges the runs under these directories (shard outputs) into
        /// OUT: the table and plots of the whole sweep.
        #[arg(long, value_name = "DIR", num_args = 1.., requires = "out",
              conflicts_with_all = ["scenario", "param"])]
        merge: Vec<PathBuf>,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Serves one platform from a recorded trace (world side).
    Replay {
        /// A trace (world.trace or platform.trace of a run).
        trace: PathBuf,
        /// In a world trace of several drones: the drone whose frames are
        /// served (to `sim-core --drone NAME`).
        #[arg(long, value_name = "NAME")]
        drone: Option<String>,
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
    /// The int8 gate network on the GAP8 (DESIGN.md §13, docs/NN.md).
    Nn {
        #[command(subcommand)]
        what: NnCmd,
    },
    /// Lists the scenarios shipped in scenarios/.
    List,
    /// Measurements (not tests): what a run costs.
    Bench {
        #[command(subcommand)]
        what: BenchCmd,
    },
}

#[derive(Subcommand, Debug)]
enum BenchCmd {
    /// Real-time factor of N drones hovering 60 s (scenarios swarm-hover-N),
    /// run one after the other.
    Swarm {
        /// Swarm sizes (scenarios swarm-hover-N must exist).
        #[arg(long, value_delimiter = ',', default_values_t = scenarios::swarm::bench::SIZES)]
        sizes: Vec<usize>,
        /// Output directory (default: out/bench-swarm).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Overrides a scenario or run key of every run (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Runs per size; the table keeps the fastest (others' load only slows).
        #[arg(long, default_value_t = 1)]
        repeat: usize,
    },
    /// The 32 ms race's real-time factor with the thesis's defaults and
    /// with the fast options (shared-memory images, no traces), then the
    /// world alone fed the same requests: one run after the other.
    Race {
        /// Output directory (default: out/bench-race).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Overrides a scenario or run key of every run (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Runs per measurement; the fastest is kept (others' load only slows).
        #[arg(long, default_value_t = 1)]
        repeat: usize,
    },
    /// The AI deck's cluster on the int8 matmul 64×64×64 (issue 18): cycles,
    /// MAC/cycle, speedup, energy per MAC and host cost per core count, one
    /// `sim-core run-elf` after the other.
    Cluster {
        /// Cluster sizes (1-8).
        #[arg(long, value_delimiter = ',', default_values_t = scenarios::bench_cluster::CORES)]
        cores: Vec<u32>,
        /// The benchmark's ELF (default: sim-core/firmware/bin/cluster_matmul_bench.elf).
        #[arg(long, value_name = "FILE")]
        elf: Option<PathBuf>,
        /// Output directory (default: out/bench-cluster).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Runs per size; the fastest is kept (others' load only slows).
        #[arg(long, default_value_t = 1)]
        repeat: usize,
    },
    /// The ISS back ends (interpreter, block translator) on CPU-bound
    /// programs: CPU time, MIPS and their ratio; QEMU's with --qemu.
    Iss {
        /// ELFs to run (default: the committed CPU-bound programs).
        #[arg(long = "elf", value_name = "FILE")]
        elfs: Vec<PathBuf>,
        /// Also time `qemu-system-riscv32 -icount shift=0` (virt machine,
        /// semihosting) on each ELF, where it runs.
        #[arg(long)]
        qemu: bool,
        /// Runs per measurement; the fastest is kept (others' load only slows).
        #[arg(long, default_value_t = 1)]
        repeat: usize,
    },
}

#[derive(Subcommand, Debug)]
enum NnCmd {
    /// Runs the network on the ISS (FC + cluster, nn_eval.elf) over a
    /// `cosim dataset` directory, scores it as training/evaluate.py does,
    /// prints and writes eval.json.
    Eval {
        /// The dataset directory (labels.csv and the PGMs).
        data: PathBuf,
        /// Cluster cores (1-8).
        #[arg(long, default_value_t = 8)]
        cores: usize,
        /// Cluster clock, MHz.
        #[arg(long, default_value_t = 175)]
        mhz: u64,
        /// Only the first K images.
        #[arg(long, value_name = "K")]
        limit: Option<usize>,
        /// Where to write eval.json (default: out/nn-eval/eval.json).
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// Also write every image's raw head and decoded outputs (JSON, the
        /// fields of training/golden/golden.json).
        #[arg(long, value_name = "FILE")]
        heads: Option<PathBuf>,
        /// The program (default: sim-core/firmware/bin/nn_eval.elf).
        #[arg(long, value_name = "FILE")]
        elf: Option<PathBuf>,
        /// The platform file whose FC power figures are used (default:
        /// sim-core/platforms/crazyflie-aideck.json).
        #[arg(long, value_name = "FILE")]
        platform: Option<PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
enum TraceCmd {
    /// The listing: sequence, clock, direction, command, fields.
    Show {
        trace: PathBuf,
        /// Only this command.
        #[arg(long, value_name = "COMMAND")]
        command: Option<String>,
        /// Only this drone's frames (a world trace of several drones).
        #[arg(long, value_name = "NAME")]
        drone: Option<String>,
        /// At most N lines.
        #[arg(long, value_name = "N")]
        limit: Option<usize>,
        /// Whole messages instead of short fields.
        #[arg(long)]
        full: bool,
    },
}

impl RunArgs {
    /// The `--set` assignments, then `--world` and `--no-mcap`.
    fn sets(&self) -> Vec<String> {
        let mut sets = self.set.clone();
        if let Some(w) = &self.world {
            sets.push(format!("world={}", w.display()));
        }
        if self.no_mcap {
            sets.push("mcap=false".into());
        }
        sets
    }
}

fn cmd_perturb(
    PerturbArgs {
        from,
        seed,
        max_offset,
        out,
    }: PerturbArgs,
) -> anyhow::Result<ExitCode> {
    let out = out.as_path();
    let from = match from {
        Some(p) => p,
        None => scenarios::scenario::find_repo_file("scenarios/worlds/thesis-course.toml")
            .context("cannot find scenarios/worlds/thesis-course.toml: pass --from FILE")?,
    };
    let text = std::fs::read_to_string(&from)
        .with_context(|| format!("cannot read {}", from.display()))?;
    let (world, offsets) =
        scenarios::perturb::perturb(&text, &from.display().to_string(), seed, max_offset)
            .with_context(|| format!("{}", from.display()))?;
    // The result must be a world the server accepts.
    world_server::world_file::WorldDesc::parse(&world, out)
        .map_err(|e| anyhow::anyhow!("the perturbed world is not valid: {e}"))?;
    std::fs::write(out, world).with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "cosim: {} gates moved (seed {seed}, max offset {max_offset} m) -> {}",
        offsets.len(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
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
        world_endpoint: None,
    })
}

fn cmd_run(
    scenario: Option<String>,
    out: Option<PathBuf>,
    run: RunArgs,
    no_plots: bool,
    quiet: bool,
    world_endpoint: Option<protocol::Endpoint>,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    let s = load_scenario(scenario.as_deref(), &run.sets())?;
    let out = out.unwrap_or_else(|| Path::new("out").join(&s.name));
    let bins = bins.locate()?;
    eprintln!("cosim: {} — {} -> {}", s.name, s.description, out.display());
    let opts = LaunchOptions {
        world_endpoint: world_endpoint.clone(),
        ..launch_options(&run, !quiet)?
    };
    let o = run_scenario(&s, &bins, &out, &opts, !no_plots)?;
    println!("{}", o.text);
    // A world started by hand elsewhere may not be this scenario's: the
    // platform learns the world's timestep in GET_INIT_DATA, so a mismatch
    // shows in the summary.
    if let (Some(ep), Some(sum)) = (&world_endpoint, &o.summary) {
        if sum.timestep_ms != s.timestep_ms {
            eprintln!(
                "cosim: the world at {ep} ran at {} ms, the scenario says {} ms: start it with `cosim world {} --listen ...` and the same --set",
                sum.timestep_ms, s.timestep_ms, s.name
            );
            return Ok(ExitCode::FAILURE);
        }
    }
    Ok(if o.ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

struct WorldArgs {
    scenario: Option<String>,
    listen: protocol::Endpoint,
    out: Option<PathBuf>,
    set: Vec<String>,
    no_trace: bool,
    trace_images: bool,
    frames: bool,
}

fn cmd_world(a: WorldArgs, bins: BinArgs) -> anyhow::Result<ExitCode> {
    let s = load_scenario(a.scenario.as_deref(), &a.set)?;
    let out = a
        .out
        .unwrap_or_else(|| Path::new("out").join(format!("{}-world", s.name)));
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let bins = bins.locate()?;
    let opts = LaunchOptions {
        traces: !a.no_trace,
        trace_images: a.trace_images,
        frames: a.frames,
        ..LaunchOptions::default()
    };
    let mut cmd = scenarios::launch::world_command(&s, &bins, &a.listen, &out, &opts)?;
    // What the platform's host connects to: this host's name in place of
    // an any-interface address.
    let connect = match &a.listen {
        protocol::Endpoint::Tcp(addr) => match addr.rsplit_once(':') {
            Some((host, port)) if ["0.0.0.0", "[::]", "::"].contains(&host) => {
                format!("tcp:THIS-HOST:{port}")
            }
            _ => a.listen.to_string(),
        },
        unix => unix.to_string(),
    };
    eprintln!(
        "cosim world: {} ({} ms) on {}, outputs in {}; on the platform's host: cosim run {}{} --world-endpoint {connect}",
        s.name,
        s.timestep_ms,
        a.listen,
        out.display(),
        s.name,
        s.overrides
            .iter()
            .map(|(k, v)| format!(" --set {k}={v}"))
            .collect::<String>(),
    );
    let status = cmd
        .status()
        .with_context(|| format!("cannot start {}", bins.world_server.display()))?;
    Ok(if status.success() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

struct SweepArgs {
    scenario: Option<String>,
    param: Vec<String>,
    jobs: usize,
    out: Option<PathBuf>,
    plan: bool,
    shard: Option<Shard>,
    merge: Vec<PathBuf>,
    run: RunArgs,
}

fn cmd_sweep(a: SweepArgs, bins: BinArgs) -> anyhow::Result<ExitCode> {
    if !a.merge.is_empty() {
        if !a.run.set.is_empty() {
            bail!("--merge takes no --set: the settings are in the runs' records");
        }
        let out = a.out.context("--merge needs --out DIR")?;
        return cmd_merge(&a.merge, &out);
    }
    let scenario = a
        .scenario
        .context("a scenario is needed (or --merge DIR...)")?;
    let s = load_scenario(Some(&scenario), &a.run.sets())?;
    let params: Vec<Param> = if a.param.is_empty() {
        s.sweep
            .iter()
            .map(|(k, v)| Param {
                key: k.clone(),
                values: v.clone(),
            })
            .collect()
    } else {
        a.param
            .iter()
            .map(|p| p.parse())
            .collect::<Result<_, _>>()?
    };
    let plan = Plan::new(&s, &params)?;
    if a.plan {
        print!("{}", plan.listing(a.shard));
        return Ok(ExitCode::SUCCESS);
    }
    let out = a
        .out
        .unwrap_or_else(|| Path::new("out").join(format!("{}-sweep", s.name)));
    if let Some(shard) = a.shard {
        if plan.select(Some(shard)).is_empty() {
            println!("shard {shard}: no runs (the sweep has {})", plan.runs.len());
            return Ok(ExitCode::SUCCESS);
        }
    }
    let bins = bins.locate()?;
    let opts = launch_options(&a.run, false)?;
    let rows = sweep::run_planned(&plan, a.shard, &bins, &out, a.jobs, &opts)?;
    let failed = rows.iter().filter(|r| r.error.is_some()).count();
    match a.shard {
        None => {
            let md = std::fs::read_to_string(out.join(sweep::files::MARKDOWN))
                .context("reading the sweep table back")?;
            println!("{md}");
            println!(
                "{} runs, {} failed; table {} and {}; plots in {}",
                rows.len(),
                failed,
                out.join(sweep::files::MARKDOWN).display(),
                out.join(sweep::files::CSV).display(),
                out.display()
            );
        }
        Some(shard) => {
            let (header, table) = sweep::table(&plan.id.params, &rows);
            println!("{}", sweep::markdown(&header, &table));
            println!(
                "shard {shard}: {} of {} runs, {} failed, in {}; once every shard is done: cosim sweep --merge {} --out {}",
                rows.len(),
                plan.runs.len(),
                failed,
                out.display(),
                out.display(),
                out.display()
            );
        }
    }
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn cmd_merge(dirs: &[PathBuf], out: &Path) -> anyhow::Result<ExitCode> {
    let merged = sweep::merge(dirs, out)?;
    let md = std::fs::read_to_string(out.join(sweep::files::MARKDOWN))
        .context("reading the sweep table back")?;
    println!("{md}");
    let failed = merged.rows.iter().filter(|r| r.error.is_some()).count();
    println!(
        "{}: {} runs merged from {} director{}, {} failed; table {} and {}; plots in {}",
        merged.id.scenario,
        merged.rows.len(),
        dirs.len(),
        if dirs.len() == 1 { "y" } else { "ies" },
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

fn cmd_trace_check(
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

fn cmd_bench_swarm(
    sizes: Vec<usize>,
    out: Option<PathBuf>,
    set: Vec<String>,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if sizes.is_empty() || sizes.contains(&0) {
        bail!("--sizes: expected swarm sizes >= 1, e.g. 1,2,4,8");
    }
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per size");
    }
    let out = out.unwrap_or_else(|| Path::new("out").join("bench-swarm"));
    let bins = bins.locate()?;
    let opts = LaunchOptions {
        echo: false,
        ..LaunchOptions::default()
    };
    let rows =
        scenarios::swarm::bench::bench_swarm(&sizes, &bins, &out, &set, repeat, &opts, |m| {
            eprintln!("cosim bench: {m}")
        })?;
    let (header, cells) = scenarios::swarm::bench::table(&rows);
    println!("{}", scenarios::swarm::bench::markdown(&header, &cells));
    println!("table: {}", out.join("bench.md").display());
    Ok(if rows.iter().all(|r| r.completed) {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn cmd_bench_race(
    out: Option<PathBuf>,
    set: Vec<String>,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per measurement");
    }
    let out = out.unwrap_or_else(scenarios::bench_race::default_out);
    let bins = bins.locate()?;
    let b = scenarios::bench_race::bench_race(&bins, &out, &set, repeat, |m| {
        eprintln!("cosim bench: {m}")
    })?;
    println!("{}", b.markdown());
    println!("table: {}", out.join("bench.md").display());
    Ok(if b.defaults.completed && b.fast.completed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn cmd_bench_cluster(
    cores: Vec<u32>,
    elf: Option<PathBuf>,
    out: Option<PathBuf>,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per measurement");
    }
    if let Some(bad) = cores.iter().find(|&&n| !(1..=8).contains(&n)) {
        bail!("--cores: {bad} is not a cluster size (1-8)");
    }
    let elf = elf.unwrap_or_else(scenarios::bench_cluster::default_elf);
    let out = out.unwrap_or_else(scenarios::bench_cluster::default_out);
    let bins = bins.locate()?;
    let rows =
        scenarios::bench_cluster::bench_cluster(&bins.sim_core, &elf, &cores, &out, repeat, |m| {
            eprintln!("cosim bench: {m}")
        })?;
    println!("{}", scenarios::bench_cluster::markdown(&rows));
    println!("table: {}", out.join("bench.md").display());
    Ok(ExitCode::SUCCESS)
}

fn cmd_nn_eval(
    args: scenarios::nn::eval::EvalArgs,
    heads: Option<PathBuf>,
) -> anyhow::Result<ExitCode> {
    let start = std::time::Instant::now();
    let (report, records) = scenarios::nn::eval::evaluate(&args, |i, n| {
        if i % 100 == 0 || i == n {
            eprintln!("cosim nn eval: {i}/{n} images");
        }
    })?;
    let json = serde_json::to_string_pretty(&report)?;
    println!("{json}");
    if let Some(dir) = args.out_json.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(&args.out_json, format!("{json}\n"))
        .with_context(|| format!("writing {}", args.out_json.display()))?;
    if let Some(h) = heads {
        std::fs::write(&h, serde_json::to_string(&records)?)
            .with_context(|| format!("writing {}", h.display()))?;
    }
    eprintln!(
        "cosim nn eval: {} images in {:.1} s -> {}",
        report.images,
        start.elapsed().as_secs_f64(),
        args.out_json.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn cmd_bench_iss(
    elfs: Vec<PathBuf>,
    qemu: bool,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per measurement");
    }
    let elfs = if elfs.is_empty() {
        scenarios::bench_iss::default_elfs()
    } else {
        elfs
    };
    let bins = bins.locate()?;
    let rows = scenarios::bench_iss::bench_iss(&bins.sim_core, &elfs, qemu, repeat, |m| {
        eprintln!("cosim bench: {m}")
    })?;
    println!("{}", scenarios::bench_iss::markdown(&rows));
    Ok(ExitCode::SUCCESS)
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

fn cmd_dataset(world: &Path, count: usize, seed: u64, out: &Path) -> anyhow::Result<ExitCode> {
    let desc = world_server::WorldDesc::load(world).map_err(|e| anyhow::anyhow!("{e}"))?;
    let spec = world_server::dataset::DatasetSpec::new(count, seed);
    let start = std::time::Instant::now();
    let labels = world_server::dataset::write_dataset(&desc, &spec, out)?;
    let secs = start.elapsed().as_secs_f64();
    let visible = labels.iter().filter(|l| l.gate.is_some()).count();
    println!(
        "cosim: {count} images ({visible} with a gate) -> {} in {secs:.1} s ({:.0} images/min)",
        out.display(),
        count as f64 / secs.max(1e-9) * 60.0
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
            world_endpoint,
        } => cmd_run(scenario, out, run, no_plots, quiet, world_endpoint, bins),
        Cmd::Perturb(p)
        | Cmd::World {
            action: Some(WorldCmd::Perturb(p)),
            ..
        } => cmd_perturb(p),
        Cmd::Dataset {
            world,
            count,
            seed,
            out,
        } => cmd_dataset(&world, count, seed, &out),
        Cmd::World {
            action: None,
            scenario,
            listen: Some(listen),
            out,
            set,
            no_trace,
            trace_images,
            frames,
        } => cmd_world(
            WorldArgs {
                scenario,
                listen,
                out,
                set,
                no_trace,
                trace_images,
                frames,
            },
            bins,
        ),
        Cmd::World { listen: None, .. } => {
            unreachable!("clap requires --listen without a subcommand")
        }
        Cmd::Sweep {
            scenario,
            param,
            jobs,
            out,
            plan,
            shard,
            merge,
            run,
        } => cmd_sweep(
            SweepArgs {
                scenario,
                param,
                jobs,
                out,
                plan,
                shard,
                merge,
                run,
            },
            bins,
        ),
        Cmd::Replay {
            trace,
            drone,
            socket,
            frames,
            tolerance,
        } => cmd_replay(trace, drone, socket, frames, tolerance),
        Cmd::Trace {
            what:
                TraceCmd::Show {
                    trace,
                    command,
                    drone,
                    limit,
                    full,
                },
        } => tracetool::read_trace(&trace)
            .map(|r| {
                print!(
                    "{}",
                    tracetool::show(&r, command.as_deref(), drone.as_deref(), limit, full)
                );
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
        Cmd::Nn {
            what:
                NnCmd::Eval {
                    data,
                    cores,
                    mhz,
                    limit,
                    out,
                    heads,
                    elf,
                    platform,
                },
        } => cmd_nn_eval(
            scenarios::nn::eval::EvalArgs {
                out_json: out.unwrap_or_else(|| Path::new("out").join("nn-eval").join("eval.json")),
                data,
                cores,
                mhz,
                limit,
                elf: elf.unwrap_or_else(scenarios::nn::machine::default_elf),
                platform: platform.unwrap_or_else(scenarios::nn::machine::default_platform),
            },
            heads,
        ),
        Cmd::Bench {
            what:
                BenchCmd::Swarm {
                    sizes,
                    out,
                    set,
                    repeat,
                },
        } => cmd_bench_swarm(sizes, out, set, repeat, bins),
        Cmd::Bench {
            what: BenchCmd::Race { out, set, repeat },
        } => cmd_bench_race(out, set, repeat, bins),
        Cmd::Bench {
            what:
                BenchCmd::Cluster {
                    cores,
                    elf,
                    out,
                    repeat,
                },
        } => cmd_bench_cluster(cores, elf, out, repeat, bins),
        Cmd::Bench {
            what: BenchCmd::Iss { elfs, qemu, repeat },
        } => cmd_bench_iss(elfs, qemu, repeat, bins),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("cosim: {e:#}");
            ExitCode::from(2)
        }
    }
}
