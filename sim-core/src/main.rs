//! The `sim-core` binary: the virtual platform (`sim-core --socket PATH
//! --firmware ELF ...`) and the bare ISS (`sim-core run-elf FILE ...`).

use clap::{Parser, Subcommand};

use sim_core::kernel::cli::{load_run_config, run_platform, PlatformArgs};
use sim_core::machine::run_elf::{self, RunElfArgs};

#[derive(Debug, Parser)]
#[command(
    name = "sim-core",
    version,
    about = "The virtual platform: RV32IMC ISS, camera, STM32, motors, power network and battery",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    platform: PlatformArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a bare-metal RV32IMC ELF on the ISS alone (riscv-tests tohost,
    /// semihosting, architecture-test signatures).
    RunElf(RunElfArgs),
}

/// Logs go to stderr; RUST_LOG wins over the run configuration's debug level.
fn init_logs(default_directive: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_directive));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
}

fn main() {
    protocol::heap::keep_freed_memory();
    protocol::sched::request_short_slice();
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::RunElf(args)) => {
            init_logs("warn");
            run_elf::run(&args)
        }
        None => match load_run_config(&cli.platform) {
            Ok(run) => {
                init_logs(run.debug_level.filter_directive());
                run_platform(&cli.platform, run)
            }
            Err(e) => {
                init_logs("warn");
                Err(e)
            }
        },
    };
    let code = match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("sim-core: error: {e:#}");
            1
        }
    };
    std::process::exit(code);
}
