//! A user's ONNX network on the simulated AI deck (DESIGN.md §18,
//! docs/NN_ONNX.md): the model laid out by [`deploy`], written into the
//! generic runtime firmware's L2 image (`nn_run.elf`'s `nn_l2`) and the
//! HyperRAM, and run on the ISS: FC + cluster, no C compiler.
//!
//! The program's interface (sim-core/firmware/src/nn/runtime/nn_run.c):
//! at each host stop `nn_event` says why (0: waiting for a command, 1: a
//! layer just finished, with `nn_profile` set, its index in
//! `nn_layer_done`); the host writes `nn_command` (1 infer, 2 quit),
//! reads `nn_status` and `nn_stats` (per layer: cluster cycles, DMA bytes,
//! L3 bytes, FC cycles waiting for L3).

use std::path::PathBuf;

use anyhow::{bail, Context};
use sim_core::iss::Backend;
use sim_core::units::Picos;

use super::gap8::{repo_path, Gap8, Gap8Config, Mark};
use super::onnx::deploy::{deploy, Deployment, WeightsPlace};
use super::onnx::layers::Model;

/// The runtime, relative to the repository.
pub const ELF: &str = "sim-core/firmware/bin/nn_run.elf";

pub fn default_elf() -> PathBuf {
    repo_path(ELF)
}

const CMD_INFER: u32 = 1;
const CMD_QUIT: u32 = 2;
const EVENT_LAYER: u32 = 1;
/// Words per layer in `nn_stats` (model.h's nn_layer_stats_t).
const STAT_WORDS: u32 = 4;
/// Simulated time allowed per inference: a stop that never comes must
/// not hang `cosim`. Far above a MobileNet at 10 MHz.
const TIMEOUT: Picos = Picos::from_ms(60_000);

/// How the deck runs a model.
#[derive(Clone, Debug)]
pub struct DeckConfig {
    pub cores: usize,
    pub mhz: u64,
    pub iss: Backend,
    pub elf: PathBuf,
    pub platform: PathBuf,
    pub weights: WeightsPlace,
    /// The cluster's supply, V (default: the platform file's).
    pub vdd: Option<f64>,
}

/// One layer of one inference.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LayerRun {
    /// Cluster cycles of the layer's tasks (the runtime's count).
    pub cycles: u64,
    pub dma_bytes: u64,
    pub l3_bytes: u64,
    /// FC cycles waiting for L3 after the layer's tasks.
    pub fc_wait_cycles: u64,
    /// With profiling: simulated time and FC + cluster energy from the
    /// previous layer's end (the inference's start) to this one's.
    pub time: Picos,
    pub energy_j: f64,
}

/// One inference.
#[derive(Clone, Debug)]
pub struct Inference {
    /// The output's integers, NCHW, native domain.
    pub output: Vec<i32>,
    pub layers: Vec<LayerRun>,
    /// From the command to the output in L2.
    pub latency: Picos,
    pub energy_j: f64,
    pub cluster_instructions: u64,
    pub l1_stall_cycles: u64,
    /// Bytes the µDMA read from the HyperRAM.
    pub l3_read_bytes: u64,
}

/// Symbol addresses of the runtime.
struct Symbols {
    l2: u32,
    command: u32,
    status: u32,
    stats: u32,
    profile: u32,
    layer_done: u32,
    event: u32,
}

/// The deck with a model loaded.
pub struct Deck {
    g: Gap8,
    sym: Symbols,
    pub plan: Deployment,
    n_layers: usize,
    pub cfg: DeckConfig,
}

impl Deck {
    /// Boots the runtime and writes the model into L2 and L3.
    pub fn new(model: &Model, cfg: DeckConfig) -> anyhow::Result<Self> {
        let mut g = Gap8::new(
            &cfg.elf,
            &cfg.platform,
            Gap8Config {
                cores: cfg.cores,
                mhz: cfg.mhz,
                iss: cfg.iss,
                vdd: cfg.vdd,
            },
            &[
                "nn_l2",
                "nn_l2_size",
                "nn_command",
                "nn_status",
                "nn_stats",
                "nn_event",
            ],
            TIMEOUT,
        )?;
        let sym = |name: &str| g.symbol(name);
        let sym = Symbols {
            l2: sym("nn_l2")?,
            command: sym("nn_command")?,
            status: sym("nn_status")?,
            stats: sym("nn_stats")?,
            profile: sym("nn_profile")?,
            layer_done: sym("nn_layer_done")?,
            event: sym("nn_event")?,
        };
        let capacity = g.word(g.symbol("nn_l2_size")?)? as usize;
        let plan = deploy(model, capacity, cfg.weights)?;
        g.mem
            .write_bytes(sym.l2, &plan.l2)
            .context("writing the model into L2")?;
        g.hyper.load(&plan.l3).map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok(Deck {
            g,
            sym,
            plan,
            n_layers: model.layers.len(),
            cfg,
        })
    }

    /// One inference of the quantized input (native integers, NCHW).
    /// With `profile` the runtime stops after every layer, and each
    /// layer's time and energy are measured.
    pub fn infer(&mut self, input: &[i32], profile: bool) -> anyhow::Result<Inference> {
        let iv = &self.plan.values[self.plan.input];
        let bytes = self.plan.input_bytes(input);
        self.g
            .mem
            .write_bytes(self.sym.l2 + iv.off as u32, &bytes)
            .context("writing the input")?;
        self.g.set_word(self.sym.profile, profile as u32)?;
        let l3_0 = self.g.hyper.bytes_read;
        let m0 = self.g.mark();
        let e0 = self.g.cluster_energy_j();
        let mut prev: (Mark, f64) = (m0, e0);
        let mut per_layer: Vec<(Picos, f64)> = Vec::new();
        self.g.set_word(self.sym.command, CMD_INFER)?;
        loop {
            self.g.run_to_stop(TIMEOUT)?;
            let status = self.g.word(self.sym.status)? as i32;
            if status != 0 {
                bail!("the runtime refused the model (status {status})");
            }
            if self.g.word(self.sym.event)? != EVENT_LAYER {
                break;
            }
            let k = self.g.word(self.sym.layer_done)? as usize;
            if k != per_layer.len() {
                bail!("the runtime reported layer {k} after {}", per_layer.len());
            }
            let m = self.g.mark();
            let e = self.g.cluster_energy_j();
            per_layer.push((
                m.t.saturating_sub(prev.0.t),
                self.g.energy_between(&prev.0, &m, e - prev.1),
            ));
            prev = (m, e);
        }
        let m1 = self.g.mark();
        let e1 = self.g.cluster_energy_j();
        if profile && per_layer.len() != self.n_layers {
            bail!(
                "the runtime reported {} of {} layers",
                per_layer.len(),
                self.n_layers
            );
        }
        let mut layers = Vec::with_capacity(self.n_layers);
        for i in 0..self.n_layers {
            let w = |k: u32| {
                self.g
                    .word(self.sym.stats + 4 * (STAT_WORDS * i as u32 + k))
                    .map(u64::from)
            };
            let (time, energy_j) = per_layer.get(i).copied().unwrap_or((Picos(0), 0.0));
            layers.push(LayerRun {
                cycles: w(0)?,
                dma_bytes: w(1)?,
                l3_bytes: w(2)?,
                fc_wait_cycles: w(3)?,
                time,
                energy_j,
            });
        }
        let ov = &self.plan.values[self.plan.output];
        let mut raw = vec![0u8; ov.bytes];
        self.g
            .mem
            .read_bytes(self.sym.l2 + ov.off as u32, &mut raw)
            .context("reading the output")?;
        Ok(Inference {
            output: self.plan.output_values(&raw),
            layers,
            latency: m1.t.saturating_sub(m0.t),
            energy_j: self.g.energy_between(&m0, &m1, e1 - e0),
            cluster_instructions: m1.instructions - m0.instructions,
            l1_stall_cycles: m1.l1_stalls - m0.l1_stalls,
            l3_read_bytes: self.g.hyper.bytes_read - l3_0,
        })
    }

    /// Tells the runtime to close the cluster and exit; its exit code.
    pub fn finish(mut self) -> anyhow::Result<i32> {
        self.g.set_word(self.sym.command, CMD_QUIT)?;
        self.g.run_to_exit(TIMEOUT)
    }
}

/// The default deck: `nn_run.elf`, the AI-deck platform file.
pub fn config(cores: usize, mhz: u64, iss: Backend) -> DeckConfig {
    DeckConfig {
        cores,
        mhz,
        iss,
        elf: default_elf(),
        platform: super::gap8::default_platform(),
        weights: WeightsPlace::Auto,
        vdd: None,
    }
}
