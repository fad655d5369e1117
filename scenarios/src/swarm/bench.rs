//! `cosim bench swarm`: what a bigger swarm costs. Runs the scenarios
//! `swarm-hover-N` (N drones hovering 60 s of platform time at 16 ms with
//! `hover_hold.elf`: RUN_PID, no camera) one after the other — never in
//! parallel, so each has the machine to itself — and prints the real-time
//! factor of each whole run (the world's time at the last STOP over the
//! wall time of all processes). A measurement, not a test: the numbers
//! depend on the machine and its load.

use std::path::{Path, PathBuf};

use crate::launch::{Binaries, LaunchOptions};
use crate::outcome::RunOutcome;
use crate::run::run_scenario;
use crate::scenario::{resolve_scenario, Scenario};
use crate::world::World;

/// The swarm sizes of the benchmark (scenarios `swarm-hover-N`).
pub const SIZES: [usize; 4] = [1, 2, 4, 8];

/// One row of the benchmark table.
#[derive(Debug, Clone)]
pub struct BenchRow {
    pub drones: usize,
    pub completed: bool,
    pub world_time_s: Option<f64>,
    pub wall_s: f64,
    pub realtime_factor: f64,
    /// Simulated platform-seconds per wall second, all drones together.
    pub drone_seconds_per_s: f64,
    pub instructions: u64,
    pub messages: u64,
    pub error: Option<String>,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    #[error(transparent)]
    Launch(#[from] crate::launch::LaunchError),
    #[error("{0}")]
    Output(String),
}

fn row(n: usize, o: &RunOutcome) -> BenchRow {
    let wall = o.status.wall.as_secs_f64();
    let world = o
        .drones
        .iter()
        .filter_map(|d| d.summary.as_ref().and_then(|s| s.world_time_s))
        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.max(t))));
    let platform_s: f64 = o
        .drones
        .iter()
        .filter_map(|d| d.summary.as_ref().map(|s| s.platform_time_s))
        .sum();
    let sum = |f: &dyn Fn(&sim_core::kernel::Summary) -> u64| -> u64 {
        o.drones
            .iter()
            .filter_map(|d| d.summary.as_ref())
            .map(f)
            .sum()
    };
    BenchRow {
        drones: n,
        completed: o.ok(),
        world_time_s: world,
        wall_s: wall,
        realtime_factor: world.map_or(0.0, |w| w / wall.max(1e-9)),
        drone_seconds_per_s: platform_s / wall.max(1e-9),
        instructions: sum(&|s| s.instructions),
        messages: sum(&|s| s.messages),
        error: o.error(),
    }
}

/// The table (header and rows) as text cells.
pub fn table(rows: &[BenchRow]) -> (Vec<String>, Vec<Vec<String>>) {
    let header = [
        "drones",
        "status",
        "world time (s)",
        "wall time (s)",
        "real-time factor",
        "drone-seconds per s",
        "instructions",
        "messages",
        "error",
    ]
    .map(String::from)
    .to_vec();
    let cells = rows
        .iter()
        .map(|r| {
            vec![
                r.drones.to_string(),
                if r.completed { "ok" } else { "failed" }.into(),
                r.world_time_s.map_or(String::new(), |w| format!("{w:.3}")),
                format!("{:.2}", r.wall_s),
                format!("{:.2}", r.realtime_factor),
                format!("{:.2}", r.drone_seconds_per_s),
                r.instructions.to_string(),
                r.messages.to_string(),
                r.error.clone().unwrap_or_default(),
            ]
        })
        .collect();
    (header, cells)
}

/// The table in markdown.
pub fn markdown(header: &[String], rows: &[Vec<String>]) -> String {
    let mut t = format!(
        "| {} |\n|{}\n",
        header.join(" | "),
        "---|".repeat(header.len())
    );
    for r in rows {
        t += &format!("| {} |\n", r.join(" | ").replace('\n', " "));
    }
    t
}

/// Runs `swarm-hover-N` for each size `repeat` times into
/// `out/swarm-hover-N`, keeps the fastest run of each, writes `out/bench.md`
/// and returns the rows.
pub fn bench_swarm(
    sizes: &[usize],
    bins: &Binaries,
    out: &Path,
    sets: &[String],
    repeat: usize,
    opts: &LaunchOptions,
    mut progress: impl FnMut(&str),
) -> Result<Vec<BenchRow>, BenchError> {
    let mut planned: Vec<(usize, Scenario, World, PathBuf)> = Vec::new();
    for &n in sizes {
        let name = format!("swarm-hover-{n}");
        let mut s = Scenario::load(&resolve_scenario(Some(&name))?)?;
        for a in sets {
            s.set(a)?;
        }
        let world = s.check_files()?;
        planned.push((n, s, world, out.join(&name)));
    }
    std::fs::create_dir_all(out)
        .map_err(|e| BenchError::Output(format!("cannot create {}: {e}", out.display())))?;
    let mut rows = Vec::new();
    for (n, s, world, dir) in planned {
        // The fastest of `repeat` runs: the load of other programs only
        // ever slows a run down. A failed run is the size's result.
        let mut best: Option<BenchRow> = None;
        for k in 0..repeat.max(1) {
            progress(&format!("{}: {} drones, run {} ...", s.name, n, k + 1));
            let o = run_scenario(&s, &world, bins, &dir, opts, false)?;
            let r = row(n, &o);
            progress(&format!(
                "{}: {:.2}x real time ({:.2} s wall){}",
                s.name,
                r.realtime_factor,
                r.wall_s,
                r.error
                    .as_deref()
                    .map_or(String::new(), |e| format!(" FAILED: {e}"))
            ));
            let failed = !r.completed;
            if best.as_ref().is_none_or(|b| r.wall_s < b.wall_s) || failed {
                best = Some(r);
            }
            if failed {
                break;
            }
        }
        rows.extend(best);
    }
    let (header, cells) = table(&rows);
    std::fs::write(out.join("bench.md"), markdown(&header, &cells))
        .map_err(|e| BenchError::Output(format!("cannot write bench.md: {e}")))?;
    Ok(rows)
}
