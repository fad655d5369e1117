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

/// `cosim nn import`: the layer table, and with `--input` the host's
/// integer reference run.
pub(crate) fn cmd_nn_import(
    model_path: &Path,
    input: Option<&Path>,
    output: Option<&Path>,
) -> anyhow::Result<ExitCode> {
    use scenarios::nn::onnx;
    let model = onnx::import(model_path)?;
    let shape = |id: usize| format!("{:?}", model.values[id].shape);
    let mut rows = vec![vec![
        "node".to_string(),
        "op".into(),
        "input".into(),
        "output".into(),
        "MACs".into(),
        "weight B".into(),
    ]];
    for l in &model.layers {
        let ins: Vec<String> = l.inputs.iter().map(|&i| shape(i)).collect();
        rows.push(vec![
            l.name.clone(),
            l.op.clone(),
            ins.join(" "),
            shape(l.output),
            l.macs.to_string(),
            l.weight_bytes().to_string(),
        ]);
    }
    rows.push(vec![
        "total".into(),
        format!("{} layers", model.layers.len()),
        shape(model.input),
        shape(model.output),
        model.macs().to_string(),
        model.weight_bytes().to_string(),
    ]);
    print_table(&rows, 4);
    if model.output_sigmoid {
        println!("output: Sigmoid on the dequantized output (float)");
    }
    let Some(input) = input else {
        return Ok(ExitCode::SUCCESS);
    };
    let (in_shape, x) = onnx::read_npy_f32(input)?;
    let want = &model.values[model.input].shape;
    if in_shape.iter().product::<usize>() != want.iter().product::<usize>() {
        anyhow::bail!(
            "{}: shape {in_shape:?}; the model's input {:?} is {want:?}",
            input.display(),
            model.input_name
        );
    }
    let y = onnx::reference::run(&model, &x)?;
    eprintln!(
        "cosim nn import: the host's integer reference (not the ISS): {} values out",
        y.len()
    );
    if let Some(out) = output {
        onnx::write_npy_f32(out, &model.values[model.output].shape, &y)?;
        eprintln!("cosim nn import: -> {}", out.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Columns padded to their widest cell, text left and numbers (columns
/// from `first_numeric`) right; a rule above the last row (the total).
pub(crate) fn print_table(rows: &[Vec<String>], first_numeric: usize) {
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0);
    let mut widths = vec![0usize; cols];
    for r in rows {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    for (i, r) in rows.iter().enumerate() {
        if i == rows.len() - 1 {
            println!("{}", "-".repeat(widths.iter().sum::<usize>() + 2 * cols));
        }
        let mut line = String::new();
        for (k, (c, w)) in r.iter().zip(&widths).enumerate() {
            let w = *w;
            if k >= first_numeric {
                line += &format!("  {c:>w$}");
            } else {
                line += &format!("{}{c:<w$}", if k == 0 { "" } else { "  " });
            }
        }
        println!("{}", line.trim_end());
    }
}
