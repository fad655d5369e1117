//! `cosim sweep --merge DIR… --out DIR` (DESIGN.md §11): the table and the
//! plots of a sweep rebuilt from the run directories that shards wrote, on
//! one host or many. Everything is checked before anything is written: a
//! run missing or present twice, runs of another sweep (scenario,
//! parameters, settings or input files), a record or a summary that does
//! not read back as written — each is refused with one line naming the run
//! and the file. The result equals the one-machine sweep's but for the
//! wall-clock columns ([`super::WALL_CLOCK_COLUMNS`]).

use std::collections::BTreeMap;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::time::Duration;

use super::params::{dir_name, product, Param, SweepError, SweepRow};
use super::plan::{sha256_hex, RunRecord, SweepId, RECORD_FORMAT, RUN_RECORD};
use super::write::write_outputs;
use crate::launch::RunStatus;
use crate::outcome::RunOutcome;
use crate::outputs::files;
use crate::report::{self, PowerRow};
use sim_core::kernel::Summary;

/// A merged sweep.
#[derive(Debug)]
pub struct Merged {
    pub id: SweepId,
    /// Every run, in order.
    pub rows: Vec<SweepRow>,
}

/// One run directory found in a shard output.
struct Found {
    path: PathBuf,
    record: RunRecord,
    /// The record's bytes (to recognise a run already merged into `out`).
    raw: Vec<u8>,
    summary: Option<Summary>,
}

fn refuse(msg: String) -> SweepError {
    SweepError::Merge(msg)
}

fn params_text(params: &[Param]) -> String {
    params
        .iter()
        .map(|p| format!("{}={}", p.key, p.values.join(",")))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Merges the run directories under `dirs` into `out`: checks them, links
/// (or copies) the runs that are not already there into `out`, and writes
/// `sweep.csv`, `sweep.md` and the plots.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Merged, SweepError> {
    if dirs.is_empty() {
        return Err(refuse("no directories to merge".into()));
    }
    let mut runs: BTreeMap<usize, Found> = BTreeMap::new();
    let mut reference: Option<(PathBuf, SweepId)> = None;
    for dir in dirs {
        for path in run_dirs(dir)? {
            let found = read_run(&path)?;
            let id = &found.record.sweep;
            match &reference {
                None => reference = Some((path.clone(), id.clone())),
                Some((first, rid)) => same_sweep(&path, id, first, rid)?,
            }
            let n = found.record.run;
            if let Some(prev) = runs.get(&n) {
                return Err(refuse(format!(
                    "run {n} ({}) is in both {} and {}",
                    settings_text(&found.record.settings),
                    prev.path.display(),
                    path.display()
                )));
            }
            runs.insert(n, found);
        }
    }
    let (_, id) = reference.expect("run_dirs refuses a directory without runs");
    let combos = product(&id.params);
    let missing: Vec<String> = (1..=id.runs)
        .filter(|n| !runs.contains_key(n))
        .map(|n| format!("{n} ({})", settings_text(&combos[n - 1])))
        .collect();
    if !missing.is_empty() {
        let shown = if missing.len() > 8 {
            format!("{}, … ({} in all)", missing[..8].join(", "), missing.len())
        } else {
            missing.join(", ")
        };
        return Err(refuse(format!(
            "missing run(s) {shown} of {}: a shard not run, not finished or not copied",
            id.runs
        )));
    }

    // Where each run goes; decided for all before anything is written.
    fs::create_dir_all(out)
        .map_err(|e| SweepError::Output(format!("cannot create {}: {e}", out.display())))?;
    let mut to_link = Vec::new();
    for found in runs.values() {
        let target = out.join(&found.record.dir);
        if !target.exists() {
            to_link.push((found.path.clone(), target));
            continue;
        }
        if same_file(&target, &found.path) {
            continue;
        }
        let there = fs::read(target.join(RUN_RECORD)).ok();
        if there.as_deref() != Some(&found.raw[..]) {
            return Err(refuse(format!(
                "{} already exists and is not run {} of {}: merge into an empty directory or into the shards' own",
                target.display(),
                found.record.run,
                found.path.display()
            )));
        }
    }
    for (src, target) in to_link {
        link_tree(&src, &target).map_err(|e| {
            SweepError::Output(format!(
                "cannot copy {} to {}: {e}",
                src.display(),
                target.display()
            ))
        })?;
    }

    let rows: Vec<SweepRow> = runs.into_values().map(|found| row(found, out)).collect();
    write_outputs(&id.params, &rows, out)?;
    Ok(Merged { id, rows })
}

/// The `run-*` directories of a shard output, by name.
fn run_dirs(dir: &Path) -> Result<Vec<PathBuf>, SweepError> {
    let entries =
        fs::read_dir(dir).map_err(|e| refuse(format!("cannot read {}: {e}", dir.display())))?;
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_dir()
                && p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with("run-"))
        })
        .collect();
    found.sort();
    if found.is_empty() {
        return Err(refuse(format!(
            "{} holds no run directories (run-NNN_…): not the output of a sweep or a shard",
            dir.display()
        )));
    }
    Ok(found)
}

/// Reads and checks one run directory: its record and its summary.
fn read_run(path: &Path) -> Result<Found, SweepError> {
    let rec_path = path.join(RUN_RECORD);
    let raw = match fs::read(&rec_path) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            return Err(refuse(format!(
                "{} has no {RUN_RECORD}: the run did not finish (rerun its shard) or the directory is not a sweep's",
                path.display()
            )))
        }
        Err(e) => return Err(refuse(format!("cannot read {}: {e}", rec_path.display()))),
    };
    let record: RunRecord = serde_json::from_slice(&raw)
        .map_err(|e| refuse(format!("{} is corrupt: {e}", rec_path.display())))?;
    if record.format != RECORD_FORMAT {
        return Err(refuse(format!(
            "{} has format {:?}, this cosim reads {RECORD_FORMAT:?}",
            rec_path.display(),
            record.format
        )));
    }
    // The record must describe the run its directory holds in the sweep it
    // names: its number, its settings and its directory name agree.
    let id = &record.sweep;
    let n = record.run;
    let combos = product(&id.params);
    let consistent = id.runs == combos.len()
        && (1..=id.runs).contains(&n)
        && combos[n - 1] == record.settings
        && record.dir == dir_name(n - 1, &record.settings)
        && path.file_name().and_then(|f| f.to_str()) == Some(record.dir.as_str());
    if !consistent {
        return Err(refuse(format!(
            "{} is corrupt: run {n} ({}) does not match its sweep's parameters or its directory's name",
            rec_path.display(),
            settings_text(&record.settings)
        )));
    }
    let mut summary = None;
    if let Some(o) = &record.outcome {
        if !(o.wall_s.is_finite() && o.wall_s >= 0.0) {
            return Err(refuse(format!(
                "{} is corrupt: wall_s {}",
                rec_path.display(),
                o.wall_s
            )));
        }
        if let Some(hash) = &o.summary_sha256 {
            let sp = path.join(files::SUMMARY);
            let bytes = fs::read(&sp).map_err(|e| {
                refuse(format!(
                    "{}: {e} (the run wrote one; it was lost on the way)",
                    sp.display()
                ))
            })?;
            if sha256_hex(&bytes) != *hash {
                return Err(refuse(format!(
                    "{} is corrupt: its SHA-256 is not the one recorded when the run ended",
                    sp.display()
                )));
            }
            // A run with several drones has the swarm's summary at the top
            // (its drones' own are read back with the row).
            if !crate::swarm::is_swarm_summary(&bytes) {
                summary = Some(
                    serde_json::from_slice::<Summary>(&bytes)
                        .map_err(|e| refuse(format!("{} is corrupt: {e}", sp.display())))?,
                );
            }
        }
    }
    Ok(Found {
        path: path.to_path_buf(),
        record,
        raw,
        summary,
    })
}

fn settings_text(settings: &[(String, String)]) -> String {
    settings
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Refuses a run of another sweep, saying how it differs.
fn same_sweep(path: &Path, id: &SweepId, first: &Path, rid: &SweepId) -> Result<(), SweepError> {
    let (p, f) = (path.display(), first.display());
    if id.scenario != rid.scenario {
        return Err(refuse(format!(
            "{p} is a run of scenario {}, {f} of {}: not one sweep",
            id.scenario, rid.scenario
        )));
    }
    if id.params != rid.params {
        return Err(refuse(format!(
            "{p} swept {}, {f} swept {}: not one sweep",
            params_text(&id.params),
            params_text(&rid.params)
        )));
    }
    if id.fingerprint != rid.fingerprint || id.runs != rid.runs {
        return Err(refuse(format!(
            "{p} and {f} ran with different settings or input files (scenario file, --set, world, firmware or platform file): not one sweep"
        )));
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Recreates `src` at `dst`, files hard-linked where the filesystem allows
/// (no space used, nothing to copy) and copied otherwise.
fn link_tree(src: &Path, dst: &Path) -> io::Result<()> {
    fs::create_dir(dst)?;
    let mut entries: Vec<_> = fs::read_dir(src)?.collect::<Result<_, _>>()?;
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let (from, to) = (e.path(), dst.join(e.file_name()));
        let ft = e.file_type()?;
        if ft.is_dir() {
            link_tree(&from, &to)?;
        } else if ft.is_symlink() {
            std::os::unix::fs::symlink(fs::read_link(&from)?, &to)?;
        } else if fs::hard_link(&from, &to).is_err() {
            fs::copy(&from, &to)?;
        }
    }
    Ok(())
}

/// The table row of a checked run, as the one-machine sweep built it.
fn row(found: Found, out: &Path) -> SweepRow {
    let Found {
        record, summary, ..
    } = found;
    let dir = out.join(&record.dir);
    let outcome = record.outcome.map(|o| {
        // As run_scenario: the SOC at the start from power.csv, 1.0 without.
        let power: Vec<PowerRow> =
            report::read_csv(&dir.join(sim_core::power::log::POWER_CSV)).unwrap_or_default();
        RunOutcome {
            status: RunStatus {
                sim_core: o.sim_core_exit,
                world: o.world_exit,
                error: o.launch_error,
                wall: Duration::from_secs_f64(o.wall_s),
            },
            summary,
            soc_init: report::initial_soc(&power),
            plots: Vec::new(),
            report_error: o.report_error,
            text: String::new(),
            drones: crate::swarm::read_drones(&dir),
            map: crate::mapping::read_from_summary(&dir),
        }
    });
    SweepRow {
        index: record.run - 1,
        assignments: record.settings,
        dir,
        outcome,
        error: record.error,
    }
}
