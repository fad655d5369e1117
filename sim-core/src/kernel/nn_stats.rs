//! The `nn` block of `summary.json` (DESIGN.md §13, docs/NN.md "nn-race"):
//! a firmware that defines `nn_race_stats` (sim-core/firmware/src/nn/nn_race.c)
//! keeps its inference counters there; at the end of the run the kernel
//! reads them out of the core's memory, as [`super::map_dump`] reads a map,
//! and joins the cluster's energy from the power network. No device, no
//! firmware cost, and nothing changes for a firmware without the symbol.

use serde::{Deserialize, Serialize};

use super::KernelError;
use crate::iss::{LoadedElf, Memory};

/// The firmware's symbol.
pub const NN_STATS_SYMBOL: &str = "nn_race_stats";
/// `nn_race_stats[0]`: the layout below (nn_race.c's `NN_RS_FORMAT`).
const FORMAT: u32 = 1;
/// Words of the layout (nn_race.c's `NN_RS_*` indices).
const WORDS: usize = 15;
const INFERENCES: usize = 1;
const MACS: usize = 2;
const CL_CYCLES: usize = 3;
const CL_CYCLES_MAX: usize = 5;
const LATENCY: usize = 6;
const LATENCY_MAX: usize = 8;
const PERIOD: usize = 9;
const PERIODS: usize = 11;
const VISIBLE: usize = 12;
const USED: usize = 13;

/// Cluster cycles per inference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CyclesSummary {
    pub mean: f64,
    pub max: u64,
}

/// §13's `nn` block, plus what reading it needs (cores, clocks, the
/// detections).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NnSummary {
    /// Networks run on the cluster.
    pub inferences: u64,
    /// Cluster cycles from the input's DMA to the head back in L2.
    pub cycles_per_inference: CyclesSummary,
    /// FC time from the frame's copy out of the camera to the decoded head
    /// (copy, averaging, the cluster task, decoding), mean over inferences.
    pub latency_ms: f64,
    pub latency_max_ms: f64,
    /// Inferences per second while the network looks (1 / the mean time
    /// between two inferences of the firmware's cadence in a row; not
    /// across turns and holds, when it rests).
    pub fps: f64,
    /// MACs of the network (the firmware's `weights.h`) per cluster cycle.
    pub mac_per_cycle: f64,
    pub mac_per_inference: u64,
    /// The cluster's energy over the run (`energy_j.cluster`: its
    /// `power.csv` columns, idle leakage between inferences included).
    pub energy_j: f64,
    /// `energy_j` / `inferences` (mJ).
    pub energy_per_inference_mj: f64,
    pub cores: usize,
    pub cluster_mhz: u64,
    /// Heads that reported a gate, and sightings the guidance used.
    pub detections: u64,
    pub sightings_used: u64,
}

/// Where the counters live, if the firmware has them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NnStatsSymbol(u32);

impl NnStatsSymbol {
    pub fn find(elf: &LoadedElf) -> Option<NnStatsSymbol> {
        elf.symbol(NN_STATS_SYMBOL).map(NnStatsSymbol)
    }

    /// The block from the counters as the firmware left them. `fc_hz` is
    /// the FC's clock (its time CSR's rate), `cores` and `cluster_mhz` the
    /// platform's cluster, `energy_j` the cluster's energy.
    pub fn read(
        &self,
        mem: &Memory,
        fc_hz: u64,
        cores: usize,
        cluster_mhz: u64,
        energy_j: f64,
    ) -> Result<NnSummary, KernelError> {
        let mut w = [0u32; WORDS];
        for (i, v) in w.iter_mut().enumerate() {
            *v = mem.read_u32(self.0 + 4 * i as u32).ok_or_else(|| {
                KernelError::Core(format!("{NN_STATS_SYMBOL} at {:#x} is not in RAM", self.0))
            })?;
        }
        if w[0] != FORMAT {
            return Err(KernelError::Core(format!(
                "{NN_STATS_SYMBOL}: format {} (this sim-core reads {FORMAT})",
                w[0]
            )));
        }
        let wide = |i: usize| u64::from(w[i]) | u64::from(w[i + 1]) << 32;
        let n = u64::from(w[INFERENCES]);
        let per = |sum: u64| if n > 0 { sum as f64 / n as f64 } else { 0.0 };
        let fc_ms = |cycles: f64| cycles * 1000.0 / fc_hz as f64;
        let macs = u64::from(w[MACS]);
        let cycles = wide(CL_CYCLES);
        let periods = u64::from(w[PERIODS]);
        Ok(NnSummary {
            inferences: n,
            cycles_per_inference: CyclesSummary {
                mean: per(cycles),
                max: u64::from(w[CL_CYCLES_MAX]),
            },
            latency_ms: fc_ms(per(wide(LATENCY))),
            latency_max_ms: fc_ms(f64::from(w[LATENCY_MAX])),
            fps: if periods > 0 && wide(PERIOD) > 0 {
                1000.0 / fc_ms(wide(PERIOD) as f64 / periods as f64)
            } else {
                0.0
            },
            mac_per_cycle: if cycles > 0 {
                (macs * n) as f64 / cycles as f64
            } else {
                0.0
            },
            mac_per_inference: macs,
            energy_j,
            energy_per_inference_mj: per(1) * energy_j * 1000.0,
            cores,
            cluster_mhz,
            detections: u64::from(w[VISIBLE]),
            sightings_used: u64::from(w[USED]),
        })
    }
}
