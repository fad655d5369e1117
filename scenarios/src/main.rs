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

use clap::{Args, Parser, Subcommand};
use scenarios::sweep::Shard;
use scenarios::tracetool;
use scenarios::Binaries;

mod commands;
use commands::{bench::*, nn::*, nn_deck::*, run::*, sweep::*, trace::*};

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
    /// Every key `--set` accepts: default, accepted values, meaning.
    Keys,
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
    /// The AI deck's cluster on the int8 matmul 64×64×64 (DESIGN.md §12): cycles,
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
        /// The ISS back end: `jit` (the translator, the default on x86-64)
        /// or `interp` (the reference); the results are identical.
        #[arg(long, value_name = "interp|jit", default_value_t = sim_core::iss::Backend::DEFAULT)]
        iss: sim_core::iss::Backend,
    },
    /// Imports an int8 ONNX model (QDQ, as onnxruntime's quantize_static
    /// writes it) and prints its layers: ops, shapes, MACs, weight bytes.
    /// With --input, runs the host's integer reference: the arithmetic the
    /// deck's cluster kernels compute, on this machine, NOT a run on the
    /// ISS (docs/NN_ONNX.md).
    Import {
        /// The .onnx file.
        model: PathBuf,
        /// A float32 .npy of the model's input shape: quantized with the
        /// model's own QuantizeLinear, run by the integer reference.
        #[arg(long, value_name = "X.npy")]
        input: Option<PathBuf>,
        /// Where to write the output (float32 .npy, dequantized with the
        /// model's last DequantizeLinear); needs --input.
        #[arg(long, value_name = "Y.npy", requires = "input")]
        output: Option<PathBuf>,
    },
    /// Runs an int8 ONNX model on the simulated AI deck: the generic
    /// runtime (nn_run.elf) on the ISS, FC + cluster, weights in L2 or
    /// streamed from the HyperRAM (docs/NN_ONNX.md).
    Run {
        /// The .onnx file.
        model: PathBuf,
        /// A float32 .npy of the model's input shape, quantized with the
        /// model's own QuantizeLinear.
        #[arg(long, value_name = "X.npy")]
        input: PathBuf,
        /// Where to write the output (float32 .npy, dequantized with the
        /// model's last DequantizeLinear).
        #[arg(long, value_name = "Y.npy")]
        output: Option<PathBuf>,
        #[command(flatten)]
        deck: DeckArgs,
    },
    /// One inference stopped after every layer: a per-layer table (MACs,
    /// cycles, MAC/cycle, L1/DMA/L3 bytes, time, energy), DIR/profile.json
    /// and DIR/profile.png.
    Profile {
        /// The .onnx file.
        model: PathBuf,
        /// A float32 .npy input (default: N(0, 1) from a fixed seed; the
        /// cycles do not depend on it).
        #[arg(long, value_name = "X.npy")]
        input: Option<PathBuf>,
        /// Where to write profile.json and profile.png.
        #[arg(long, value_name = "DIR", default_value = "out/nn-profile")]
        out: PathBuf,
        #[command(flatten)]
        deck: DeckArgs,
    },
}

/// The simulated deck's options.
#[derive(clap::Args, Debug)]
struct DeckArgs {
    /// Cluster cores (1-8).
    #[arg(long, default_value_t = 8)]
    cores: usize,
    /// Cluster clock, MHz.
    #[arg(long, default_value_t = 175)]
    mhz: u64,
    /// Where the weights go: `auto` (L2 when everything fits, else L3) or
    /// `l3` (every weight streamed from the HyperRAM).
    #[arg(long, value_name = "auto|l3", default_value = "auto")]
    weights: String,
    /// The cluster's supply, V: its dynamic energy scales with the square
    /// (default: the platform file's, 1.2 V).
    #[arg(long, value_name = "V")]
    vdd: Option<f64>,
    /// The runtime (default: sim-core/firmware/bin/nn_run.elf).
    #[arg(long, value_name = "FILE")]
    elf: Option<PathBuf>,
    /// The platform file whose FC and cluster power figures are used
    /// (default: sim-core/platforms/crazyflie-aideck.json).
    #[arg(long, value_name = "FILE")]
    platform: Option<PathBuf>,
    /// The ISS back end: `jit` or `interp`; the results are identical.
    #[arg(long, value_name = "interp|jit", default_value_t = sim_core::iss::Backend::DEFAULT)]
    iss: sim_core::iss::Backend,
}

impl DeckArgs {
    fn config(self) -> anyhow::Result<scenarios::nn::deck::DeckConfig> {
        use scenarios::nn::onnx::deploy::WeightsPlace;
        if !(1..=8).contains(&self.cores) {
            anyhow::bail!("--cores {}: the cluster has 1 to 8 cores", self.cores);
        }
        if self.mhz == 0 {
            anyhow::bail!("--mhz 0: the cluster needs a clock");
        }
        let weights = match self.weights.as_str() {
            "auto" => WeightsPlace::Auto,
            "l3" => WeightsPlace::L3,
            w => anyhow::bail!("--weights {w:?}: auto or l3"),
        };
        if let Some(v) = self.vdd.filter(|v| !(0.5..=1.5).contains(v)) {
            anyhow::bail!("--vdd {v}: GAP8 runs from 1.0 to 1.2 V; 0.5 to 1.5 V are taken");
        }
        let mut c = scenarios::nn::deck::config(self.cores, self.mhz, self.iss);
        c.weights = weights;
        c.vdd = self.vdd;
        if let Some(e) = self.elf {
            c.elf = e;
        }
        if let Some(p) = self.platform {
            c.platform = p;
        }
        Ok(c)
    }
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

fn main() -> ExitCode {
    protocol::heap::keep_freed_memory();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    if let Err(e) = scenarios::signals::install() {
        eprintln!("cosim: cannot receive SIGINT/SIGTERM: {e}");
        return ExitCode::from(2);
    }
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
        Cmd::Keys => commands::keys::cmd_keys(),
        Cmd::Nn {
            what:
                NnCmd::Import {
                    model,
                    input,
                    output,
                },
        } => cmd_nn_import(&model, input.as_deref(), output.as_deref()),
        Cmd::Nn {
            what:
                NnCmd::Run {
                    model,
                    input,
                    output,
                    deck,
                },
        } => deck
            .config()
            .and_then(|c| cmd_nn_run(&model, &input, output.as_deref(), c)),
        Cmd::Nn {
            what:
                NnCmd::Profile {
                    model,
                    input,
                    out,
                    deck,
                },
        } => deck
            .config()
            .and_then(|c| cmd_nn_profile(&model, input.as_deref(), &out, c)),
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
                    iss,
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
                iss,
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
    let code = match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("cosim: {e:#}");
            ExitCode::from(2)
        }
    };
    // Stopped by a signal: the shell's convention, whatever the command
    // made of its shortened run.
    match scenarios::signals::requested() {
        Some(sig) => ExitCode::from((128 + sig) as u8),
        None => code,
    }
}
