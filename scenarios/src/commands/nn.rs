//! `cosim dataset`, `cosim nn eval`: the gate network's data and its evaluation on the ISS.

use anyhow::Context;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

pub(crate) fn cmd_nn_eval(
    args: scenarios::nn::eval::EvalArgs,
    heads: Option<PathBuf>,
) -> anyhow::Result<ExitCode> {
    let start = std::time::Instant::now();
    let (report, records) = scenarios::nn::eval::evaluate(&args, |i, n| {
        if i % 100 == 0 || i == n {
            eprintln!("cosim nn eval: {i}/{n} images");
        }
    })?;
    let json = serde_json::to_string_pretty(&report)?;
    println!("{json}");
    if let Some(dir) = args.out_json.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(&args.out_json, format!("{json}\n"))
        .with_context(|| format!("writing {}", args.out_json.display()))?;
    if let Some(h) = heads {
        std::fs::write(&h, serde_json::to_string(&records)?)
            .with_context(|| format!("writing {}", h.display()))?;
    }
    eprintln!(
        "cosim nn eval: {} images in {:.1} s -> {}",
        report.images,
        start.elapsed().as_secs_f64(),
        args.out_json.display()
    );
    Ok(ExitCode::SUCCESS)
}

pub(crate) fn cmd_dataset(
    world: &Path,
    count: usize,
    seed: u64,
    out: &Path,
) -> anyhow::Result<ExitCode> {
    let line = world_server::dataset::dataset_command(world, count, seed, out)?;
    println!("cosim: {line}");
    Ok(ExitCode::SUCCESS)
}
