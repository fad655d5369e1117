//! The names of the files a run writes, and how paths are written into
//! them: a leaf that imports nothing from this crate, so every module that
//! reads or writes outputs can name them without importing the module that
//! makes them.

use std::path::Path;

/// Output file names of a run (DESIGN.md §6 plus the launcher's own).
pub mod files {
    pub const SUMMARY: &str = "summary.json";
    pub const TRAJECTORY: &str = "trajectory.csv";
    pub const CONSOLE: &str = "console.log";
    pub const WORLD_TRACE: &str = "world.trace";
    pub const PLATFORM_TRACE: &str = "platform.trace";
    pub const RUN_CONFIG: &str = "run.toml";
    pub const SCENARIO: &str = "scenario.toml";
    pub const LOG: &str = "cosim.log";
    pub const REPORT: &str = "report.txt";
    pub const FRAMES: &str = "frames";
    /// The merged file of a run.
    pub const RUN_MCAP: &str = "run.mcap";
    /// The world's half, written during the run and removed by the merge.
    pub const WORLD_MCAP: &str = "world.mcap";
}

/// File names of the mapping outputs.
pub mod map_files {
    pub const MAP_CFOG: &str = sim_core::kernel::MAP_FILE;
    pub const MAP_CSV: &str = "map.csv";
    pub const MAP_PNG: &str = "map.png";
    pub const EXPLORATION_CSV: &str = "exploration.csv";
}

/// The world's outputs of a run with several drones (besides DESIGN.md §6's
/// `trajectory.csv` and `world.trace`).
pub mod swarm_files {
    /// One row per (frame, receiver) with its outcome (`world-server --radio-log`).
    pub const RADIO_LOG: &str = "radio.csv";
}

/// A path as written into the outputs (`run.toml`, `scenario.toml`):
/// absolute, so the file can be used from anywhere.
pub fn abs(p: &Path) -> String {
    p.canonicalize()
        .unwrap_or_else(|_| p.to_path_buf())
        .display()
        .to_string()
}

/// The directory of one platform's outputs in a run with `[[platform]]`
/// tables (DESIGN.md §7); a scenario's one drone writes into `out` itself.
pub fn drone_dir(out: &Path, drone: &str) -> std::path::PathBuf {
    out.join(drone)
}
