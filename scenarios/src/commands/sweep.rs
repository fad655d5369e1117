//! `cosim sweep` (plans, shards, merges).

use super::run::{launch_options, load_scenario};
use crate::{BinArgs, RunArgs};
use anyhow::{bail, Context};
use scenarios::sweep::{self, Param, Plan, Shard};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

pub(crate) struct SweepArgs {
    pub(crate) scenario: Option<String>,
    pub(crate) param: Vec<String>,
    pub(crate) jobs: usize,
    pub(crate) out: Option<PathBuf>,
    pub(crate) plan: bool,
    pub(crate) shard: Option<Shard>,
    pub(crate) merge: Vec<PathBuf>,
    pub(crate) run: RunArgs,
}

pub(crate) fn cmd_sweep(a: SweepArgs, bins: BinArgs) -> anyhow::Result<ExitCode> {
    if !a.merge.is_empty() {
        if !a.run.set.is_empty() {
            bail!("--merge takes no --set: the settings are in the runs' records");
        }
        let out = a.out.context("--merge needs --out DIR")?;
        return cmd_merge(&a.merge, &out);
    }
    let scenario = a
        .scenario
        .context("a scenario is needed (or --merge DIR...)")?;
    let (s, _) = load_scenario(Some(&scenario), &a.run.sets())?;
    let params: Vec<Param> = if a.param.is_empty() {
        s.sweep
            .iter()
            .map(|(k, v)| Param {
                key: k.clone(),
                values: v.clone(),
            })
            .collect()
    } else {
        a.param
            .iter()
            .map(|p| p.parse())
            .collect::<Result<_, _>>()?
    };
    let plan = Plan::new(&s, &params)?;
    if a.plan {
        print!("{}", plan.listing(a.shard));
        return Ok(ExitCode::SUCCESS);
    }
    let out = a
        .out
        .unwrap_or_else(|| Path::new("out").join(format!("{}-sweep", s.name)));
    if let Some(shard) = a.shard {
        if plan.select(Some(shard)).is_empty() {
            println!("shard {shard}: no runs (the sweep has {})", plan.runs.len());
            return Ok(ExitCode::SUCCESS);
        }
    }
    let bins = bins.locate()?;
    let opts = launch_options(&a.run, false)?;
    let rows = sweep::run_planned(&plan, a.shard, &bins, &out, a.jobs, &opts)?;
    let failed = rows.iter().filter(|r| r.error.is_some()).count();
    if let Some(sig) = scenarios::signals::requested() {
        eprintln!(
            "cosim: the sweep was stopped by {}: {} of its {} runs not started",
            scenarios::signals::name(sig),
            plan.select(a.shard).len() - rows.len(),
            plan.select(a.shard).len()
        );
    }
    match a.shard {
        None => {
            let md = std::fs::read_to_string(out.join(sweep::files::MARKDOWN))
                .context("reading the sweep table back")?;
            println!("{md}");
            println!(
                "{} runs, {} failed; table {} and {}; plots in {}",
                rows.len(),
                failed,
                out.join(sweep::files::MARKDOWN).display(),
                out.join(sweep::files::CSV).display(),
                out.display()
            );
        }
        Some(shard) => {
            let (header, table) = sweep::table(&plan.id.params, &rows);
            println!("{}", sweep::markdown(&header, &table));
            println!(
                "shard {shard}: {} of {} runs, {} failed, in {}; once every shard is done: cosim sweep --merge {} --out {}",
                rows.len(),
                plan.runs.len(),
                failed,
                out.display(),
                out.display(),
                out.display()
            );
        }
    }
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

pub(crate) fn cmd_merge(dirs: &[PathBuf], out: &Path) -> anyhow::Result<ExitCode> {
    let merged = sweep::merge(dirs, out)?;
    let md = std::fs::read_to_string(out.join(sweep::files::MARKDOWN))
        .context("reading the sweep table back")?;
    println!("{md}");
    let failed = merged.rows.iter().filter(|r| r.error.is_some()).count();
    println!(
        "{}: {} runs merged from {} director{}, {} failed; table {} and {}; plots in {}",
        merged.id.scenario,
        merged.rows.len(),
        dirs.len(),
        if dirs.len() == 1 { "y" } else { "ies" },
        failed,
        out.join(sweep::files::MARKDOWN).display(),
        out.join(sweep::files::CSV).display(),
        out.display()
    );
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
