//! `cosim nn profile`'s report (DESIGN.md §18): per layer and in total,
//! what one inference of an imported model costs on the simulated deck;
//! `profile.json` and `profile.png`.

use std::path::Path;

use plotters::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::deck::Inference;
use super::onnx::deploy::Deployment;
use super::onnx::layers::Model;
use crate::plot::{self, PlotError};

/// One layer.
#[derive(Clone, Debug, Serialize)]
pub struct LayerProfile {
    /// The ONNX node.
    pub name: String,
    pub op: String,
    /// From the ONNX shapes (Conv: Cout·Hout·Wout·Cin/groups·Kh·Kw; Gemm:
    /// in·out).
    pub macs: u64,
    /// Cluster cycles of the layer's tasks.
    pub cycles: u64,
    pub mac_per_cycle: f64,
    /// The L1 tile's bytes (both buffers).
    pub l1_bytes: u64,
    /// Bytes the cluster DMA moved, both ways.
    pub dma_bytes: u64,
    /// Bytes read from the HyperRAM for the layer.
    pub l3_bytes: u64,
    /// Simulated time from the previous layer's end, ms (the FC's
    /// dispatch and any wait for L3 included).
    pub latency_ms: f64,
    /// FC + cluster energy over that time, µJ.
    pub energy_uj: f64,
}

/// The whole inference.
#[derive(Clone, Debug, Serialize)]
pub struct Totals {
    pub macs: u64,
    /// The layers' cycles, summed.
    pub cycles: u64,
    /// From the command to the output in L2.
    pub latency_ms: f64,
    pub fps: f64,
    /// MACs over the layers' cycles.
    pub mac_per_cycle: f64,
    pub energy_mj: f64,
    /// The L2 image (descriptors, parameters kept in L2, the stage
    /// buffers, the activations).
    pub l2_bytes: u64,
    /// Weights in the HyperRAM.
    pub l3_bytes: u64,
}

/// `profile.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Profile {
    pub model: String,
    pub cores: usize,
    pub mhz: u64,
    pub layers: Vec<LayerProfile>,
    pub totals: Totals,
}

impl Profile {
    pub fn new(
        name: &str,
        model: &Model,
        plan: &Deployment,
        run: &Inference,
        cores: usize,
        mhz: u64,
    ) -> Profile {
        let ratio = |m: u64, c: u64| if c == 0 { 0.0 } else { m as f64 / c as f64 };
        let layers: Vec<LayerProfile> = model
            .layers
            .iter()
            .zip(&plan.layers)
            .zip(&run.layers)
            .map(|((l, p), r)| LayerProfile {
                name: l.name.clone(),
                op: l.op.clone(),
                macs: l.macs,
                cycles: r.cycles,
                mac_per_cycle: ratio(l.macs, r.cycles),
                l1_bytes: p.l1_bytes as u64,
                dma_bytes: r.dma_bytes,
                l3_bytes: r.l3_bytes,
                latency_ms: r.time.as_secs_f64() * 1e3,
                energy_uj: r.energy_j * 1e6,
            })
            .collect();
        let cycles = layers.iter().map(|l| l.cycles).sum();
        let latency_ms = run.latency.as_secs_f64() * 1e3;
        Profile {
            model: name.to_string(),
            cores,
            mhz,
            totals: Totals {
                macs: model.macs(),
                cycles,
                latency_ms,
                fps: if latency_ms > 0.0 {
                    1e3 / latency_ms
                } else {
                    0.0
                },
                mac_per_cycle: ratio(model.macs(), cycles),
                energy_mj: run.energy_j * 1e3,
                l2_bytes: plan.l2.len() as u64,
                l3_bytes: plan.l3.len() as u64,
            },
            layers,
        }
    }
}

/// A float input of the model's shape, N(0, 1) from a fixed seed,
/// quantized by the model's QuantizeLinear: the cycles do not depend on
/// the values, and the same profile comes out every time.
pub fn seeded_input(model: &Model) -> Vec<i32> {
    let v = &model.values[model.input];
    let n: usize = v.shape.iter().product();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let x: Vec<f32> = (0..n)
        .map(|_| {
            // Box-Muller: a normal from two uniforms.
            let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
            ((-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()) as f32
        })
        .collect();
    super::onnx::reference::quantize(&x, v.q)
}

/// Latency and energy per layer, two bar charts one above the other.
pub fn plot(p: &Profile, path: &Path) -> Result<(), PlotError> {
    plot::fonts();
    let e = |e| plot::err(path, e);
    let n = p.layers.len().max(1);
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let root = root
        .titled(
            &format!(
                "{}: {} cores at {} MHz, {:.2} ms, {:.3} mJ, {:.2} MAC/cycle",
                p.model,
                p.cores,
                p.mhz,
                p.totals.latency_ms,
                p.totals.energy_mj,
                p.totals.mac_per_cycle
            ),
            (plot::FONT, 20),
        )
        .map_err(e)?;
    let halves = root.split_evenly((2, 1));
    let panels: [(&str, Vec<f64>); 2] = [
        (
            "latency per layer, ms",
            p.layers.iter().map(|l| l.latency_ms).collect(),
        ),
        (
            "FC + cluster energy per layer, µJ",
            p.layers.iter().map(|l| l.energy_uj).collect(),
        ),
    ];
    for (area, (label, vals)) in halves.iter().zip(panels) {
        let top = vals.iter().copied().fold(0.0f64, f64::max).max(1e-9) * 1.1;
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(0f64..n as f64, 0f64..top)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .max_light_lines(1)
            .x_desc("layer (ONNX order)")
            .y_desc(label)
            .x_label_formatter(&|x| format!("{}", *x as usize))
            .label_style((plot::FONT, 14))
            .draw()
            .map_err(e)?;
        chart
            .draw_series(vals.iter().enumerate().map(|(i, &v)| {
                Rectangle::new(
                    [(i as f64 + 0.1, 0.0), (i as f64 + 0.9, v)],
                    BLUE.mix(0.7).filled(),
                )
            }))
            .map_err(e)?;
    }
    root.present().map_err(e)?;
    Ok(())
}
