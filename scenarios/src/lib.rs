//! Scenario files and the `cosim` launcher (DESIGN.md §1, §6).
//!
//! - [`scenario`]: `scenarios/*.toml`, `--set` overrides, checks.
//! - [`launch`]: the two processes on a private socket, supervised.
//! - [`report`]: outputs read back, plots, the printed summary.
//! - [`sweep`]: cartesian products of parameters run in parallel.
//! - [`replay`]: a world server that answers from a recorded trace.
//! - [`tracetool`]: `cosim trace show` and `cosim trace-check`.
//! - [`plot`]: the PNG figures.
//! - [`swarm`]: scenarios with several drones (`[[platform]]` tables).
//! - [`perturb`]: `cosim world perturb`, courses with displaced gates.
//! - [`mapping`]: the map of an exploration run scored against the world.
//! - [`bench_race`]: `cosim bench race`, what the thesis's race costs.
//! - [`foxglove`]: `run.mcap`, the world's and the platforms' channels merged.
//! - [`signals`]: SIGINT/SIGTERM reach every child; none outlives cosim.

pub mod bench_cluster;
pub mod bench_iss;
pub mod bench_race;
pub mod deck_report;
pub mod endurance;
pub mod foxglove;
pub mod launch;
pub mod mapping;
pub mod nn;
pub mod outcome;
pub mod outputs;
pub mod perturb;
pub mod plot;
pub mod report;
pub mod rows;
pub mod run;
pub mod run_table;
pub mod scenario;
pub mod signals;
mod supervise;
pub mod swarm;
pub mod sweep;
pub mod tracetool;

pub use launch::{launch, Binaries, LaunchError, LaunchOptions, RunStatus};
pub use outcome::{DroneOutcome, RunOutcome};
pub use run::run_scenario;
pub use scenario::{Scenario, ScenarioError};
