//! `cosim bench swarm|race|cluster|iss`.

use crate::BinArgs;
use anyhow::bail;
use scenarios::launch::LaunchOptions;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

pub(crate) fn cmd_bench_swarm(
    sizes: Vec<usize>,
    out: Option<PathBuf>,
    set: Vec<String>,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if sizes.is_empty() || sizes.contains(&0) {
        bail!("--sizes: expected swarm sizes >= 1, e.g. 1,2,4,8");
    }
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per size");
    }
    let out = out.unwrap_or_else(|| Path::new("out").join("bench-swarm"));
    let bins = bins.locate()?;
    let opts = LaunchOptions {
        echo: false,
        ..LaunchOptions::default()
    };
    let rows =
        scenarios::swarm::bench::bench_swarm(&sizes, &bins, &out, &set, repeat, &opts, |m| {
            eprintln!("cosim bench: {m}")
        })?;
    let (header, cells) = scenarios::swarm::bench::table(&rows);
    println!("{}", scenarios::swarm::bench::markdown(&header, &cells));
    println!("table: {}", out.join("bench.md").display());
    Ok(if rows.iter().all(|r| r.completed) {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

pub(crate) fn cmd_bench_race(
    out: Option<PathBuf>,
    set: Vec<String>,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per measurement");
    }
    let out = out.unwrap_or_else(scenarios::bench_race::default_out);
    let bins = bins.locate()?;
    let b = scenarios::bench_race::bench_race(&bins, &out, &set, repeat, |m| {
        eprintln!("cosim bench: {m}")
    })?;
    println!("{}", b.markdown());
    println!("table: {}", out.join("bench.md").display());
    Ok(if b.defaults.completed && b.fast.completed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

pub(crate) fn cmd_bench_cluster(
    cores: Vec<u32>,
    elf: Option<PathBuf>,
    out: Option<PathBuf>,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per measurement");
    }
    for &n in &cores {
        if let Err(e) = sim_core::cluster::CoreCount::new(n as usize) {
            bail!("--cores: {e}");
        }
    }
    let elf = elf.unwrap_or_else(scenarios::bench_cluster::default_elf);
    let out = out.unwrap_or_else(scenarios::bench_cluster::default_out);
    let bins = bins.locate()?;
    let rows =
        scenarios::bench_cluster::bench_cluster(&bins.sim_core, &elf, &cores, &out, repeat, |m| {
            eprintln!("cosim bench: {m}")
        })?;
    println!("{}", scenarios::bench_cluster::markdown(&rows));
    println!("table: {}", out.join("bench.md").display());
    Ok(ExitCode::SUCCESS)
}

pub(crate) fn cmd_bench_iss(
    elfs: Vec<PathBuf>,
    qemu: bool,
    repeat: usize,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    if repeat == 0 {
        bail!("--repeat: expected at least 1 run per measurement");
    }
    let elfs = if elfs.is_empty() {
        scenarios::bench_iss::default_elfs()
    } else {
        elfs
    };
    let bins = bins.locate()?;
    let rows = scenarios::bench_iss::bench_iss(&bins.sim_core, &elfs, qemu, repeat, |m| {
        eprintln!("cosim bench: {m}")
    })?;
    println!("{}", scenarios::bench_iss::markdown(&rows));
    Ok(ExitCode::SUCCESS)
}
