//! The platform mode of the `sim-core` binary (DESIGN.md §2, §6):
//! `sim-core --socket PATH --firmware ELF [--platform FILE] [--config FILE]
//! [--out DIR] [--trace FILE] [--trace-images] [--connect-timeout S]`.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use protocol::{Endpoint, ImageEncoding};

use super::{read_firmware, simulate, KernelConfig};
use crate::config::RunConfig;
use crate::peripherals::SocketWorld;
use crate::units::Picos;

/// Flags of the platform mode.
#[derive(Debug, Clone, clap::Args)]
pub struct PlatformArgs {
    /// The world's endpoint: a socket path, `unix:PATH` or `tcp:HOST:PORT`.
    #[arg(long, value_name = "PATH")]
    pub socket: Option<String>,
    /// The firmware ELF the core runs (e.g. sim-core/firmware/bin/race.elf).
    #[arg(long, value_name = "ELF")]
    pub firmware: Option<PathBuf>,
    /// Platform file in MESSY's JSON shape (default: the Crazyflie with the AI deck).
    #[arg(long, value_name = "FILE")]
    pub platform: Option<PathBuf>,
    /// Run configuration (TOML; default: the thesis's `simul_configs.hpp`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Serves cflib's CRTP link: `udp:HOST:PORT` (cflib's `udp://HOST:PORT`)
    /// or `replay:FILE` (a run's `crtp.jsonl`); the same as `--set crtp=…`.
    /// The firmware starts it (sim-core/firmware/bin/crtp_host.elf).
    #[arg(long, value_name = "SPEC")]
    pub crtp: Option<String>,
    /// Sets one run-configuration value (repeatable), e.g. `--set battery=ufx250`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Directory for summary.json, power.csv, the model CSVs and console.log.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Writes every frame exchanged with the world as a JSON line.
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
    /// Keeps the image data in the trace (default: width, height, SHA-256).
    #[arg(long)]
    pub trace_images: bool,
    /// Microseconds to poll for the world's reply before sleeping (0: sleep
    /// at once). Saves the cost of being woken on another core; gives the
    /// core away while polling (docs/COSIM.md "Performance").
    #[arg(long, value_name = "US", default_value_t = protocol::busy_poll::DEFAULT_US)]
    pub busy_poll_us: u64,
    /// Seconds to keep retrying the connection (the world may start second).
    #[arg(long, value_name = "S", default_value_t = 30.0)]
    pub connect_timeout: f64,
    /// The drone of a world with several drones that this platform flies
    /// (GET_INIT_DATA then carries `"drone": NAME`, docs/SWARM.md §4).
    #[arg(long, value_name = "NAME")]
    pub drone: Option<String>,
    /// Image encoding asked for in GET_INIT_DATA.
    #[arg(long, value_name = "ENC", default_value = "array")]
    pub image_encoding: ImageEncoding,
    /// Steps every polling loop instead of skipping it (same results, slower).
    #[arg(long)]
    pub no_idle_skip: bool,
    /// The ISS back end, `jit` or `interp` (same results; overrides the
    /// run key `iss`).
    #[arg(long, value_name = "interp|jit")]
    pub iss: Option<crate::iss::Backend>,
    /// Extra core cycles per access to the peripheral window.
    #[arg(long, value_name = "CYCLES", default_value_t = 0)]
    pub mmio_latency: u64,
    /// Gives up (as failed) after this many simulated seconds.
    #[arg(long, value_name = "S")]
    pub max_time: Option<f64>,
    /// The number of gates in the world file, written to summary.json as
    /// `gates_total` (the world's STOP reply carries the gates passed).
    #[arg(long, value_name = "N")]
    pub gates_total: Option<u64>,
    /// Does not echo the firmware's console on stdout (console.log still has it).
    #[arg(long)]
    pub quiet: bool,
    /// No progress line, even on a terminal.
    #[arg(long)]
    pub no_progress: bool,
}

/// Loads the run configuration: the file (if any), then every `--set`.
pub fn load_run_config(args: &PlatformArgs) -> anyhow::Result<RunConfig> {
    let mut run = match &args.config {
        Some(path) => RunConfig::from_path(path)?,
        None => RunConfig::default(),
    };
    if let Some(p) = &args.platform {
        run.platform = Some(p.clone());
    }
    run.apply_overrides(&args.set)?;
    if let Some(spec) = &args.crtp {
        run.set("crtp", spec)?;
    }
    if let Some(iss) = args.iss {
        run.iss = iss;
    }
    Ok(run)
}

/// Runs the platform mode; returns the process exit code.
pub fn run_platform(args: &PlatformArgs, run: RunConfig) -> anyhow::Result<i32> {
    let Some(socket) = &args.socket else {
        bail!("--socket is required (the world's endpoint); see `sim-core --help`");
    };
    let Some(firmware_path) = &args.firmware else {
        bail!("--firmware is required (e.g. sim-core/firmware/bin/race.elf)");
    };
    let endpoint: Endpoint = socket
        .parse()
        .map_err(|e| anyhow::anyhow!("--socket {socket}: {e}"))?;
    if args.drone.as_deref().is_some_and(|d| d.trim().is_empty()) {
        bail!("--drone needs a drone name from the world file");
    }
    let platform = run.load_platform()?;
    let firmware = read_firmware(firmware_path)?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the output directory {}", dir.display()))?;
    }
    if !(args.connect_timeout.is_finite() && args.connect_timeout >= 0.0) {
        bail!("--connect-timeout must be a non-negative number of seconds");
    }
    let world = SocketWorld::connect(
        &endpoint,
        Duration::from_secs_f64(args.connect_timeout),
        protocol::busy_poll::BusyPoll::from_micros(args.busy_poll_us),
        args.trace.as_deref().map(|p| (p, args.trace_images)),
    )?;
    let cfg = KernelConfig {
        platform,
        run,
        image_encoding: args.image_encoding,
        busy_poll_us: args.busy_poll_us,
        drone: args.drone.clone(),
        idle_skip: !args.no_idle_skip,
        mmio_latency: args.mmio_latency,
        out_dir: args.out.clone(),
        echo_console: !args.quiet,
        progress: !args.no_progress,
        max_time: args
            .max_time
            .map(|s| Picos((s.max(0.0) * Picos::PER_S as f64) as u64)),
        gates_total: args.gates_total,
    };
    let outcome = simulate(&firmware, &cfg, world);
    let s = &outcome.summary;
    eprintln!(
        "sim-core: {} | targets {}/{} reached, {} bypassed, {} replaced, {} skipped | platform {:.3} s, world {} | estimate error {} | SOC {:.1} % | {:.2} s wall, {:.1}x real time{}",
        if s.completed { "completed" } else { "did not complete" },
        s.targets_reached,
        s.targets_total,
        s.targets_bypassed,
        s.targets_replaced,
        s.targets_skipped_low_battery,
        s.platform_time_s,
        s.world_time_s.map_or("n/a".into(), |w| format!("{w:.3} s")),
        s.estimate_error_pct.map_or("n/a".into(), |e| format!("{e:.4} %")),
        s.battery.soc_end * 100.0,
        s.wall_time_s,
        s.realtime_factor,
        // cosim leaves this line out and reports the pacing on its own.
        s.pacing.as_ref().map_or(String::new(), |p| match p.warning() {
            Some(w) => format!(" | WARNING: {w}"),
            None => format!(
                " | paced {:.3}x of {}, worst lag {:.1} ms",
                p.achieved_pace, p.pace, p.worst_lag_ms
            ),
        }),
    );
    if let Some(e) = outcome.error {
        return Err(anyhow::Error::new(e));
    }
    Ok(s.exit_code)
}
