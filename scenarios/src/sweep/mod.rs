//! `cosim sweep`: the cartesian product of parameter values, run in
//! parallel (each run its own pair of processes and socket), a table of the
//! summary figures (markdown and CSV) and overlay plots. A run that fails is
//! a row marked failed with its error; the other rows are kept.
//!
//! Beyond one machine (DESIGN.md §11): [`plan`] numbers the runs and cuts
//! them into shards `K/N`; every run leaves a record (`sweep-run.json`) in
//! its directory; [`merge`] rebuilds the table and plots from shard outputs.

pub mod merge;
pub mod nn;
pub mod params;
pub mod plan;
pub mod write;

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};

use crate::launch::{Binaries, LaunchOptions};
use crate::run::run_scenario;
use crate::scenario::Scenario;
pub use merge::merge;
pub use params::{files, product, Param, SweepError, SweepRow};
pub use plan::{Plan, PlannedRun, RunRecord, Shard, SweepId, RUN_RECORD};
use write::write_outputs;
pub use write::{markdown, table, WALL_CLOCK_COLUMNS};

/// Checks every combination, then runs them `jobs` at a time into
/// `out/run-NNN_key=value...`, and writes the table and the plots.
pub fn run_sweep(
    base: &Scenario,
    params: &[Param],
    bins: &Binaries,
    out: &Path,
    jobs: usize,
    opts: &LaunchOptions,
) -> Result<Vec<SweepRow>, SweepError> {
    let plan = Plan::new(base, params)?;
    run_planned(&plan, None, bins, out, jobs, opts)
}

/// Runs the runs of `shard` (all without one) `jobs` at a time into
/// `out/run-NNN_key=value...`, each leaving its [`RunRecord`]. The whole
/// sweep writes the table and the plots; a shard writes only its run
/// directories, so that shards may share `out` (a shared filesystem) and
/// `cosim sweep --merge` makes the table.
pub fn run_planned(
    plan: &Plan,
    shard: Option<Shard>,
    bins: &Binaries,
    out: &Path,
    jobs: usize,
    opts: &LaunchOptions,
) -> Result<Vec<SweepRow>, SweepError> {
    let planned = plan.select(shard);
    let record_shard = shard.unwrap_or(Shard { k: 1, n: 1 });
    std::fs::create_dir_all(out)
        .map_err(|e| SweepError::Output(format!("cannot create {}: {e}", out.display())))?;
    let bar = ProgressBar::new(planned.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .expect("a valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<SweepRow>> = Mutex::new(Vec::new());
    let run_opts = LaunchOptions {
        echo: false,
        ..opts.clone()
    };
    std::thread::scope(|scope| {
        for _ in 0..jobs.clamp(1, planned.len().max(1)) {
            scope.spawn(|| loop {
                // Stopped by a signal: the runs started end (crate::signals),
                // no new one starts; the table has the runs that exist.
                if crate::signals::requested().is_some() {
                    break;
                }
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(run) = planned.get(i) else {
                    break;
                };
                let dir = out.join(run.dir_name());
                // A panic in one run (a bug in the report code, say) is that
                // run's failure, not the sweep's.
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    run_scenario(&run.scenario, &run.world, bins, &dir, &run_opts, true)
                }));
                let (outcome, mut error) = match result {
                    Ok(Ok(o)) => {
                        let e = o.error();
                        (Some(o), e)
                    }
                    Ok(Err(e)) => (None, Some(e.to_string())),
                    Err(_) => (None, Some("the run panicked (see the log above)".into())),
                };
                let record = RunRecord::new(
                    &plan.id,
                    run,
                    record_shard,
                    &dir,
                    outcome.as_ref(),
                    error.as_deref(),
                );
                if let Err(e) = record.write(&dir) {
                    // Without its record the merge would report the run
                    // missing; say why here, in the row.
                    error = Some(match error {
                        Some(prev) => format!("{prev}; {e}"),
                        None => e.to_string(),
                    });
                }
                let row = SweepRow {
                    index: run.index,
                    assignments: run.assignments.clone(),
                    dir,
                    outcome,
                    error,
                };
                bar.set_message(format!(
                    "{}: {}",
                    row.label(),
                    row.error
                        .as_deref()
                        .map_or("ok".to_string(), |e| format!("FAILED {e}"))
                ));
                bar.inc(1);
                rows.lock().unwrap_or_else(|e| e.into_inner()).push(row);
            });
        }
    });
    bar.finish();
    let mut rows = rows.into_inner().unwrap_or_else(|e| e.into_inner());
    rows.sort_by_key(|r| r.index);
    if shard.is_none() {
        write_outputs(&plan.id.params, &rows, out)?;
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::params::dir_name;
    use super::*;

    #[test]
    fn params_parse_and_multiply() {
        let a: Param = "battery=lipol250, ufx250".parse().unwrap();
        let b: Param = "timestep_ms=16,32,".parse().unwrap();
        assert_eq!(a.values, ["lipol250", "ufx250"]);
        let p = product(&[a, b]);
        assert_eq!(p.len(), 4);
        assert_eq!(
            p[1],
            [
                ("battery".into(), "lipol250".into()),
                ("timestep_ms".into(), "32".into())
            ]
        );
        assert_eq!(p[2][0].1, "ufx250");
        for bad in ["battery", "=1,2", "battery=", "battery=,"] {
            assert!(bad.parse::<Param>().is_err(), "{bad}");
        }
    }

    #[test]
    fn run_directories_are_flat_and_distinct() {
        let a = dir_name(0, &[("world".into(), "../w/x.toml".into())]);
        assert_eq!(a, "run-001_world=.._w_x.toml");
        assert!(!a.contains('/'));
    }

    #[test]
    fn markdown_escapes_cells_and_drops_the_dir_column() {
        let h: Vec<String> = ["run", "error", "dir"].map(String::from).to_vec();
        let t = markdown(&h, &[vec!["1".into(), "a|b".into(), "/x".into()]]);
        assert_eq!(t, "| run | error |\n|---|---|\n| 1 | a\\|b |\n");
    }
}
