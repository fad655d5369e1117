//! `world-server`: the physics world that replaces Webots (DESIGN.md §2, §5).
//!
//! `world-server --socket PATH [--world FILE] [--timestep MS] [--substeps N]
//! [--trace FILE] [--trace-images] [--frames-dir DIR] [--tcp HOST:PORT]
//! [--trajectory FILE] [--radio-log FILE] [--mcap FILE [--mcap-image-every N]]
//! [--connect-timeout S]
//! [--replay TRACE [--replay-frames DIR]]`
//!
//! `world-server dataset WORLD --count N --seed S --out DIR`: renders and
//! labels a training set with the camera of the loop (docs/NN.md; the same
//! bytes as `cosim dataset`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use protocol::Endpoint;
use world_server::server::{serve, ServerConfig};
use world_server::{Millis, StepConfig, WorldDesc};

/// The physics world of crazyflie-cosim: the Webots Crazyflie in rapier3d,
/// its sensors, its camera and the gate course, served over a socket.
#[derive(Parser, Debug)]
#[command(
    name = "world-server",
    version,
    subcommand_negates_reqs = true,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// UNIX socket to listen on (the thesis's transport).
    #[arg(long, value_name = "PATH", required_unless_present = "tcp")]
    socket: Option<PathBuf>,
    /// Listen on TCP instead (HOST:PORT).
    #[arg(long, value_name = "HOST:PORT", conflicts_with = "socket")]
    tcp: Option<String>,
    /// World file (TOML). Default: the thesis's 10-gate course.
    #[arg(long, value_name = "FILE")]
    world: Option<PathBuf>,
    /// basicTimeStep in ms (Webots's default is 32).
    #[arg(long, value_name = "MS", default_value_t = 32)]
    timestep: u64,
    /// Physics steps per basicTimeStep.
    #[arg(long, value_name = "N", default_value_t = 1)]
    substeps: u32,
    /// Write every frame to this JSON-lines trace (clock: world ms).
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,
    /// Keep image data in the trace instead of its SHA-256.
    #[arg(long, requires = "trace")]
    trace_images: bool,
    /// Write every camera frame served as a PNG into this directory.
    #[arg(long, value_name = "DIR")]
    frames_dir: Option<PathBuf>,
    /// Write one CSV row per world step (time, pose, velocities, motors, collisions);
    /// with several drones one row per drone per step, with a `drone` column;
    /// zstd-compressed when FILE ends in `.zst`.
    #[arg(long, value_name = "FILE")]
    trajectory: Option<PathBuf>,
    /// Write one CSV row per radio frame and receiver with its outcome.
    #[arg(long, value_name = "FILE")]
    radio_log: Option<PathBuf>,
    /// Write what the world sees (every drone's pose per step, the scene,
    /// camera frames, motors, radio) as an MCAP file Foxglove opens
    /// (docs/FOXGLOVE.md); log time = world time.
    #[arg(long, value_name = "FILE")]
    mcap: Option<PathBuf>,
    /// With --mcap: keep every Nth camera frame served (0: none).
    #[arg(long, value_name = "N", default_value_t = world_server::foxglove::DEFAULT_IMAGE_EVERY, requires = "mcap")]
    mcap_image_every: u64,
    /// Seconds to wait for every drone of the world file to be claimed by a
    /// platform (wall time); then exit non-zero naming the unclaimed ones.
    #[arg(long, value_name = "S", default_value_t = 60.0)]
    connect_timeout: f64,
    /// Microseconds to poll for the next request before sleeping (0: sleep
    /// at once). Saves the cost of being woken on another core; gives the
    /// core away while polling (docs/COSIM.md "Performance").
    #[arg(long, value_name = "US", default_value_t = protocol::busy_poll::DEFAULT_US)]
    busy_poll_us: u64,
    /// Answer the platform from a recorded trace (world.trace or
    /// platform.trace of a run) instead of simulating; report the first
    /// request that differs from the recording (exit 1).
    #[arg(long, value_name = "TRACE")]
    replay: Option<PathBuf>,
    /// With --replay: the PNG frames of the recorded run (its --frames-dir),
    /// for traces that keep only the images' SHA-256.
    #[arg(long, value_name = "DIR", requires = "replay")]
    replay_frames: Option<PathBuf>,
    /// With --replay: relative tolerance for numbers in requests.
    #[arg(long, value_name = "T", default_value_t = 0.0, requires = "replay")]
    replay_tolerance: f64,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render and label N camera images of a world (DESIGN.md §13,
    /// docs/NN.md "The data"): DIR/img_NNNNNN.pgm, labels.csv, gates.csv,
    /// dataset.json. The same world, N and seed give the same bytes.
    Dataset {
        /// World file (TOML).
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
}

/// The course shipped in `scenarios/worlds/`, found from the executable
/// (target/<profile>/world-server → repository root) or the working directory.
fn default_world() -> anyhow::Result<PathBuf> {
    const REL: &str = "scenarios/worlds/thesis-course.toml";
    let mut candidates = vec![PathBuf::from(REL)];
    if let Ok(exe) = std::env::current_exe() {
        candidates.extend(exe.ancestors().skip(1).map(|d| d.join(REL)));
    }
    candidates.push(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join(REL),
    );
    match candidates.into_iter().find(|p| p.is_file()) {
        Some(p) => Ok(p),
        None => bail!("no --world given and the default world {REL} was not found"),
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(Command::Dataset {
        world,
        count,
        seed,
        out,
    }) = &cli.command
    {
        let line = world_server::dataset::dataset_command(world, *count, *seed, out)?;
        println!("world-server: {line}");
        return Ok(());
    }
    // The range only: the platforms' sync mode is theirs to check.
    if let Err(e) = protocol::TimestepMs::new(cli.timestep) {
        bail!("--timestep: {e}");
    }
    if cli.substeps == 0 {
        bail!("--substeps must be at least 1");
    }
    // Bounded so that Duration::from_secs_f64 cannot panic.
    if !(cli.connect_timeout > 0.0 && cli.connect_timeout <= 1e9) {
        bail!("--connect-timeout must be a number of seconds > 0");
    }
    let endpoint = match (&cli.socket, &cli.tcp) {
        (_, Some(addr)) => format!("tcp:{addr}").parse::<Endpoint>()?,
        (Some(path), None) => Endpoint::Unix(path.clone()),
        (None, None) => bail!("one of --socket or --tcp is required"),
    };
    if let Some(trace) = &cli.replay {
        if !(cli.replay_tolerance.is_finite() && cli.replay_tolerance >= 0.0) {
            bail!("--replay-tolerance must be a number >= 0");
        }
        let opts = world_server::replay::ReplayOptions {
            frames: cli.replay_frames.clone(),
            tolerance: cli.replay_tolerance,
        };
        if world_server::replay::replay_and_report(trace, &endpoint, &opts)? {
            return Ok(());
        }
        bail!("the platform did not replay the recording (see above)");
    }
    let world_path = match cli.world {
        Some(p) => p,
        None => default_world()?,
    };
    let world = WorldDesc::load(&world_path)?;
    tracing::info!(world = %world_path.display(), drones = world.drones.len(), gates = world.gates.len(), boxes = world.boxes.len(), "world loaded");
    let cfg = ServerConfig {
        endpoint,
        world,
        step: StepConfig {
            timestep: Millis(cli.timestep),
            substeps: cli.substeps,
        },
        trace: cli.trace,
        trace_images: cli.trace_images,
        frames_dir: cli.frames_dir,
        trajectory: cli.trajectory,
        radio_log: cli.radio_log,
        mcap: cli.mcap,
        mcap_image_every: cli.mcap_image_every,
        connect_timeout: Duration::from_secs_f64(cli.connect_timeout),
        busy_poll: protocol::busy_poll::BusyPoll::from_micros(cli.busy_poll_us),
    };
    // One thread: the drones' requests are processed one at a time in the
    // lockstep's order anyway, and a single thread keeps the world off the
    // cores the platforms need.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?;
    rt.block_on(serve(cfg))?;
    Ok(())
}

fn main() -> ExitCode {
    protocol::heap::keep_freed_memory();
    protocol::sched::request_short_slice();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("world-server: {e:#}");
            ExitCode::FAILURE
        }
    }
}
