//! The GAP8 (FC + cluster) running `nn_eval.elf` in this process, frame
//! after frame (docs/NN.md "cosim nn eval").
//!
//! The ELF is loaded once and the machine kept: the cluster stays open
//! between frames as a real AI-deck program keeps it, and nothing is
//! reloaded per image. The program stops the run at a plain `ebreak`
//! (the ISS's `ebreak_stops`) whenever it wants a frame; the host then
//! reads the previous frame's results from the program's symbols
//! (`nn_head`, `nn_out`, `nn_stats`), writes the next frame into
//! `nn_image` and `nn_command`, and resumes after the `ebreak`. The
//! geometry comes from the program (`nn_shape`), which takes it from
//! `weights.h`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use sim_core::iss::Backend;
use sim_core::units::Picos;

pub use super::gap8::default_platform;
use super::gap8::{repo_path, Gap8, Gap8Config};

/// `nn_command` values (nn_eval.c).
const CMD_INFER: u32 = 1;
const CMD_QUIT: u32 = 2;
/// Stats words before the per-layer cycles (nn_eval.c's `nn_stats`).
const STATS_HEAD: usize = 3;
/// Words of `nn_out` (decode.h's nn_output_t): visible, score, cell x, y,
/// u, v, distance, 8 corners.
const OUT_WORDS: usize = 15;
/// A stop that never comes (the program looping) must not hang `cosim`:
/// simulated time allowed per frame, far above one inference (~1 ms).
const FRAME_TIMEOUT: Picos = Picos::from_ms(2_000);

/// The ELF, relative to the repository.
pub const ELF: &str = "sim-core/firmware/bin/nn_eval.elf";

pub fn default_elf() -> PathBuf {
    repo_path(ELF)
}

/// The network's geometry as the program reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Shape {
    pub camera: usize,
    pub grid: usize,
    pub head_channels: usize,
    pub macs: u64,
    pub layer_macs: Vec<u64>,
}

/// The decoded outputs (training/int8_ref.decode's keys).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Outputs {
    pub visible: bool,
    pub score: i32,
    pub cell: [i32; 2],
    pub u_q4: i32,
    pub v_q4: i32,
    pub distance_mm: i32,
    pub corners_q4: [i32; 8],
}

/// One frame through the network.
#[derive(Debug, Clone, PartialEq)]
pub struct Inference {
    /// The head's int16 grid, HWC, as the cluster wrote it to L2.
    pub head: Vec<i16>,
    pub outputs: Outputs,
    /// FC cycles of the 4x4 averaging.
    pub fc_cycles: u64,
    /// Cluster cycles of the network (input DMA to the head in L2).
    pub cluster_cycles: u64,
    pub layer_cycles: Vec<u64>,
    /// Simulated time from the frame's arrival to the decoded outputs.
    pub latency: Picos,
    /// FC + cluster energy over that time, J.
    pub energy_j: f64,
    /// Instructions every cluster core executed, and the cycles they
    /// stalled on L1 bank conflicts, over that time.
    pub cluster_instructions: u64,
    pub l1_stall_cycles: u64,
}

/// Symbol addresses of the program's interface.
struct Symbols {
    image: u32,
    command: u32,
    head: u32,
    out: u32,
    stats: u32,
    shape: u32,
}

pub struct NnMachine {
    g: Gap8,
    sym: Symbols,
    pub shape: Shape,
    n_layers: usize,
}

impl NnMachine {
    /// Loads the ELF on a GAP8 with `cores` cluster cores at `mhz`, the FC
    /// and the cores on the ISS back end `iss`, runs it to its first
    /// request for a frame.
    pub fn new(
        elf_path: &Path,
        platform: &Path,
        cores: usize,
        mhz: u64,
        iss: Backend,
    ) -> anyhow::Result<Self> {
        let g = Gap8::new(
            elf_path,
            platform,
            Gap8Config {
                cores,
                mhz,
                iss,
                vdd: None,
            },
            FRAME_TIMEOUT,
        )?;
        let sym = |name: &str| g.symbol(name).context("not nn_eval.elf?");
        let sym = Symbols {
            image: sym("nn_image")?,
            command: sym("nn_command")?,
            head: sym("nn_head")?,
            out: sym("nn_out")?,
            stats: sym("nn_stats")?,
            shape: sym("nn_shape")?,
        };
        let w = |i: u32| g.word(sym.shape + 4 * i);
        let n_layers = w(3)? as usize;
        if n_layers == 0 || n_layers > 64 {
            bail!("nn_shape reports {n_layers} layers");
        }
        let shape = Shape {
            camera: w(0)? as usize,
            grid: w(1)? as usize,
            head_channels: w(2)? as usize,
            macs: w(4)? as u64,
            layer_macs: (0..n_layers as u32)
                .map(|i| w(5 + i).map(u64::from))
                .collect::<anyhow::Result<_>>()?,
        };
        Ok(NnMachine {
            g,
            sym,
            shape,
            n_layers,
        })
    }

    fn word(&self, addr: u32) -> anyhow::Result<u32> {
        self.g.word(addr)
    }

    /// One frame (`camera`² bytes, row-major) through the network.
    pub fn infer(&mut self, image: &[u8]) -> anyhow::Result<Inference> {
        let n = self.shape.camera * self.shape.camera;
        if image.len() != n {
            bail!("a frame is {n} bytes, got {}", image.len());
        }
        // Energy and latency from the frame's arrival: what came before
        // (boot, the previous frame's stop) is not this inference's.
        let m0 = self.g.mark();
        let e0 = self.g.cluster_energy_j();
        self.g.mem.write_bytes(self.sym.image, image)?;
        self.g.set_word(self.sym.command, CMD_INFER)?;
        self.g.run_to_stop(FRAME_TIMEOUT)?;
        let m1 = self.g.mark();
        let latency = m1.t.saturating_sub(m0.t);
        let energy_j = self
            .g
            .energy_between(&m0, &m1, self.g.cluster_energy_j() - e0);
        let stat = |i: usize| self.word(self.sym.stats + 4 * i as u32);
        if stat(0)? != 0 {
            bail!(
                "the network failed on the cluster (status {})",
                stat(0)? as i32
            );
        }
        let cells = self.shape.grid * self.shape.grid * self.shape.head_channels;
        let mut raw = vec![0u8; cells * 2];
        self.g.mem.read_bytes(self.sym.head, &mut raw)?;
        let head = raw
            .chunks_exact(2)
            .map(|b| i16::from_le_bytes([b[0], b[1]]))
            .collect();
        let o = (0..OUT_WORDS)
            .map(|i| self.word(self.sym.out + 4 * i as u32).map(|w| w as i32))
            .collect::<anyhow::Result<Vec<i32>>>()?;
        let mut corners_q4 = [0; 8];
        corners_q4.copy_from_slice(&o[7..15]);
        Ok(Inference {
            head,
            outputs: Outputs {
                visible: o[0] != 0,
                score: o[1],
                cell: [o[2], o[3]],
                u_q4: o[4],
                v_q4: o[5],
                distance_mm: o[6],
                corners_q4,
            },
            fc_cycles: stat(1)? as u64,
            cluster_cycles: stat(2)? as u64,
            layer_cycles: (0..self.n_layers)
                .map(|i| stat(STATS_HEAD + i).map(u64::from))
                .collect::<anyhow::Result<_>>()?,
            latency,
            energy_j,
            cluster_instructions: m1.instructions - m0.instructions,
            l1_stall_cycles: m1.l1_stalls - m0.l1_stalls,
        })
    }

    /// Tells the program to close the cluster and exit; its exit code.
    pub fn finish(mut self) -> anyhow::Result<i32> {
        if self.g.done {
            return Ok(0);
        }
        self.g.set_word(self.sym.command, CMD_QUIT)?;
        self.g.run_to_exit(FRAME_TIMEOUT)
    }
}
