//! Scenario files and the `cosim` launcher (DESIGN.md §1, §6).
//!
//! - [`scenario`]: `scenarios/*.toml`, `--set` overrides, checks
//!   ([`run_table`]: their `run` tables applied).
//! - [`world`]: a run's world file, read and parsed once.
//! - [`launch`]: the one launch path (DESIGN.md §19): the world-server and
//!   one sim-core per platform (a single drone is a swarm of one) on a
//!   private socket, supervised (the supervision itself is the private
//!   `supervise`).
//! - [`run`]: one `cosim run`, launched then reported ([`outcome`]: what
//!   it produced).
//! - [`outputs`]: the names of the files a run writes; [`rows`]: the CSV
//!   rows read back.
//! - [`report`]: outputs read back, plots, the printed summary
//!   ([`endurance`], [`deck_report`]: lines of it).
//! - [`sweep`]: cartesian products of parameters run in parallel.
//! - [`tracetool`]: `cosim trace show` and `cosim trace-check` (the replay
//!   itself, `cosim replay`, is world-server's `replay` module).
//! - [`plot`]: the PNG figures.
//! - [`swarm`]: scenarios with several drones (`[[platform]]` tables).
//! - [`perturb`]: `cosim world perturb`, courses with displaced gates.
//! - [`mapping`]: the map of an exploration run scored against the world.
//! - [`bench_race`], [`bench_cluster`], [`bench_iss`]: `cosim bench race`,
//!   `cluster`, `iss`: what the thesis's race, the cluster and the ISS cost.
//! - [`nn`]: the int8 network on the ISS over a dataset (`cosim nn eval`).
//! - [`foxglove`]: `run.mcap`, the world's and the platforms' channels merged.
//! - [`signals`]: SIGINT/SIGTERM reach every child; none outlives cosim.
//!
//! The modules import each other in layers, never in a circle
//! (docs/ARCHITECTURE.md, "Workspace"; `tests/module_graph.rs` checks it).

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
pub mod world;

pub use launch::{launch, Binaries, LaunchError, LaunchOptions, LaunchStatus, RunStatus};
pub use outcome::{DroneOutcome, RunOutcome};
pub use run::run_scenario;
pub use scenario::{Scenario, ScenarioError};
