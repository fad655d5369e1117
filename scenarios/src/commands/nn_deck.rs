//! `cosim nn run` and `cosim nn profile`: a user's int8 ONNX network on
//! the simulated AI deck (DESIGN.md §18, docs/NN_ONNX.md).

use anyhow::Context;
use std::path::Path;
use std::process::ExitCode;

use scenarios::nn::deck::{Deck, DeckConfig};
use scenarios::nn::onnx::{self, layers::Model, reference};
use scenarios::nn::profile;

use super::nn::print_table;

/// The model's own QuantizeLinear of a float .npy of its input's shape.
fn read_input(model: &Model, path: &Path) -> anyhow::Result<Vec<i32>> {
    let (shape, x) = onnx::read_npy_f32(path)?;
    let want = &model.values[model.input].shape;
    if shape.iter().product::<usize>() != want.iter().product::<usize>() {
        anyhow::bail!(
            "{}: shape {shape:?}; the model's input {:?} is {want:?}",
            path.display(),
            model.input_name
        );
    }
    Ok(reference::quantize_input(model, &x)?)
}

/// `cosim nn run`: one inference on the ISS.
pub(crate) fn cmd_nn_run(
    model_path: &Path,
    input: &Path,
    output: Option<&Path>,
    cfg: DeckConfig,
) -> anyhow::Result<ExitCode> {
    let model = onnx::import(model_path)?;
    let q = read_input(&model, input)?;
    let (cores, mhz) = (cfg.cores, cfg.mhz);
    let mut deck = Deck::new(&model, cfg)?;
    let run = deck.infer(&q, false)?;
    let code = deck.finish()?;
    if code != 0 {
        anyhow::bail!("the runtime exited with code {code}");
    }
    let y = reference::output_floats(&model, &run.output);
    eprintln!(
        "cosim nn run: {} MACs on {cores} cores at {mhz} MHz: {:.3} ms, {:.1} µJ (FC + cluster), \
         {} B from L3, {} values out",
        model.macs(),
        run.latency.as_secs_f64() * 1e3,
        run.energy_j * 1e6,
        run.l3_read_bytes,
        y.len()
    );
    if let Some(out) = output {
        onnx::write_npy_f32(out, &model.values[model.output].shape, &y)?;
        eprintln!("cosim nn run: -> {}", out.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// `cosim nn profile`: one inference stopped after every layer; the
/// table, profile.json and profile.png.
pub(crate) fn cmd_nn_profile(
    model_path: &Path,
    input: Option<&Path>,
    out_dir: &Path,
    cfg: DeckConfig,
) -> anyhow::Result<ExitCode> {
    let model = onnx::import(model_path)?;
    let q = match input {
        Some(p) => read_input(&model, p)?,
        None => profile::seeded_input(&model),
    };
    let (cores, mhz) = (cfg.cores, cfg.mhz);
    let mut deck = Deck::new(&model, cfg)?;
    let run = deck.infer(&q, true)?;
    let plan = deck.plan.clone();
    let code = deck.finish()?;
    if code != 0 {
        anyhow::bail!("the runtime exited with code {code}");
    }
    let name = model_path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let p = profile::Profile::new(&name, &model, &plan, &run, cores, mhz);
    let mut rows = vec![[
        "node", "op", "MACs", "cycles", "MAC/cyc", "L1 B", "DMA B", "L3 B", "ms", "µJ",
    ]
    .map(String::from)
    .to_vec()];
    for l in &p.layers {
        rows.push(vec![
            l.name.clone(),
            l.op.clone(),
            l.macs.to_string(),
            l.cycles.to_string(),
            format!("{:.2}", l.mac_per_cycle),
            l.l1_bytes.to_string(),
            l.dma_bytes.to_string(),
            l.l3_bytes.to_string(),
            format!("{:.3}", l.latency_ms),
            format!("{:.2}", l.energy_uj),
        ]);
    }
    let t = &p.totals;
    rows.push(vec![
        "total".into(),
        format!("{} layers", p.layers.len()),
        t.macs.to_string(),
        t.cycles.to_string(),
        format!("{:.2}", t.mac_per_cycle),
        String::new(),
        p.layers
            .iter()
            .map(|l| l.dma_bytes)
            .sum::<u64>()
            .to_string(),
        t.l3_bytes.to_string(),
        format!("{:.3}", t.latency_ms),
        format!("{:.2}", t.energy_mj * 1e3),
    ]);
    print_table(&rows, 2);
    println!(
        "{cores} cores at {mhz} MHz: {:.1} fps, {:.3} mJ per inference, L2 {} B, L3 {} B",
        t.fps, t.energy_mj, t.l2_bytes, t.l3_bytes
    );
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let json = out_dir.join("profile.json");
    std::fs::write(&json, serde_json::to_string_pretty(&p)? + "\n")
        .with_context(|| format!("writing {}", json.display()))?;
    let png = out_dir.join("profile.png");
    profile::plot(&p, &png)?;
    eprintln!("cosim nn profile: -> {}, {}", json.display(), png.display());
    Ok(ExitCode::SUCCESS)
}
