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
use sim_core::cluster::power::{Meter, Totals};
use sim_core::cluster::{Cluster, ClusterConfig};
use sim_core::config::PlatformConfig;
use sim_core::iss::{
    load_elf, Backend, CodeCache, Cpu, CpuConfig, LoadedElf, Memory, NoDevices, StopReason,
};
use sim_core::machine::{run_elf::build_memory, Machine};
use sim_core::units::{Hertz, Picos};

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
/// The platform file whose FC and cluster power figures are used.
pub const PLATFORM: &str = "sim-core/platforms/crazyflie-aideck.json";

fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}
pub fn default_elf() -> PathBuf {
    repo_path(ELF)
}
pub fn default_platform() -> PathBuf {
    repo_path(PLATFORM)
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
    mem: Memory,
    code: CodeCache,
    cluster: Cluster,
    fc: Cpu,
    sym: Symbols,
    pub shape: Shape,
    n_layers: usize,
    meter: Meter,
    /// FC power while it runs and while it sleeps in `wfi` (the platform's
    /// `core.states.running` and `sleeping` currents at `core.vref`): it
    /// sleeps while the cluster infers (pmsis `pi_task_wait_on`).
    fc_running_w: f64,
    fc_sleeping_w: f64,
    /// The FC's clock period (its sleep is counted in cycles).
    fc_period: Picos,
    done: bool,
}

fn symbol(elf: &LoadedElf, name: &str) -> anyhow::Result<u32> {
    elf.symbol(name)
        .with_context(|| format!("the ELF has no symbol {name} (not nn_eval.elf?)"))
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
        let bytes =
            std::fs::read(elf_path).with_context(|| format!("reading {}", elf_path.display()))?;
        let elf = load_elf(&bytes).with_context(|| format!("loading {}", elf_path.display()))?;
        let plat = PlatformConfig::from_path(platform)
            .map_err(|e| anyhow::anyhow!("{}: {e}", platform.display()))?;
        let running = plat
            .core
            .states
            .get("running")
            .with_context(|| format!("{}: no core state `running`", platform.display()))?;
        let sleeping = plat
            .core
            .states
            .get("sleeping")
            .with_context(|| format!("{}: no core state `sleeping`", platform.display()))?;
        let vref = plat.cluster.as_ref().map_or(1.2, |c| c.vref);
        let sym = Symbols {
            image: symbol(&elf, "nn_image")?,
            command: symbol(&elf, "nn_command")?,
            head: symbol(&elf, "nn_head")?,
            out: symbol(&elf, "nn_out")?,
            stats: symbol(&elf, "nn_stats")?,
            shape: symbol(&elf, "nn_shape")?,
        };
        let mut mem = build_memory(&[], elf.lowest_address())?;
        elf.load_into(&mut mem)
            .with_context(|| format!("loading {}", elf_path.display()))?;
        let cfg = ClusterConfig {
            cores,
            clock: Hertz(mhz.saturating_mul(1_000_000)),
            vref,
            idle_skip: true,
            iss,
        };
        let fc_cfg = CpuConfig {
            clock: Hertz(plat.core.frequency),
            ebreak_stops: true,
            iss,
            ..CpuConfig::default()
        };
        let Machine {
            mut fc,
            cluster,
            code,
        } = Machine::new(&mut mem, fc_cfg, Some(cfg)).context("the cluster")?;
        let mut cluster = cluster.expect("a cluster was asked for");
        // The program's console (errors only) must not mix with cosim's
        // stdout, which carries the results.
        fc.set_console(Box::new(std::io::stderr()));
        cluster.set_console(|| Box::new(std::io::stderr()));
        fc.set_pc(elf.entry);
        fc.set_tohost(elf.symbol("tohost"));
        let mut m = NnMachine {
            mem,
            code,
            cluster,
            fc,
            sym,
            shape: Shape {
                camera: 0,
                grid: 0,
                head_channels: 0,
                macs: 0,
                layer_macs: Vec::new(),
            },
            n_layers: 0,
            meter: Meter::new(vref, cfg.clock),
            fc_running_w: running.current().0 * plat.core.vref,
            fc_sleeping_w: sleeping.current().0 * plat.core.vref,
            fc_period: Hertz(plat.core.frequency).period(),
            done: false,
        };
        m.run_to_stop()?;
        let w = |i: u32| m.word(m.sym.shape + 4 * i);
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
        m.shape = shape;
        m.n_layers = n_layers;
        Ok(m)
    }

    fn word(&self, addr: u32) -> anyhow::Result<u32> {
        self.mem
            .read_u32(addr)
            .with_context(|| format!("reading {addr:#010x}"))
    }

    /// Runs until the program's next `ebreak` (then steps over it).
    fn run_to_stop(&mut self) -> anyhow::Result<()> {
        let limit = Picos(self.fc.now().0.saturating_add(FRAME_TIMEOUT.0));
        match self.cluster.run_until(
            &mut self.fc,
            &mut self.mem,
            &mut self.code,
            &mut NoDevices,
            limit,
        ) {
            StopReason::Breakpoint { pc } => {
                self.fc.set_pc(pc.wrapping_add(4));
                Ok(())
            }
            StopReason::Exit { code } => {
                self.done = true;
                let _ = self.fc.flush_console();
                let _ = self.cluster.flush_console();
                bail!("the program ended (exit code {code}) instead of asking for a frame")
            }
            StopReason::Limit => bail!(
                "no result within {} of simulated time (pc {:#010x})",
                FRAME_TIMEOUT,
                self.fc.pc()
            ),
            StopReason::Fatal(e) => bail!("the program failed: {e}"),
            other => bail!("unexpected stop {other:?} at pc {:#010x}", self.fc.pc()),
        }
    }

    /// Every cluster core's instructions and L1 stall cycles so far.
    fn core_counts(&self) -> (u64, u64) {
        self.cluster
            .report_at(&self.mem, self.fc.now())
            .iter()
            .fold((0, 0), |(i, s), r| {
                (i + r.instructions, s + r.l1_stall_cycles)
            })
    }

    /// FC + cluster energy since the meter's last sample (at `t0`, when the
    /// FC had slept `slept0` cycles), J.
    fn energy_since(&mut self, t0: Picos, slept0: u64) -> f64 {
        let now = self.fc.now();
        let before = self.meter.energy_j;
        self.meter
            .sample(Totals::of(&self.cluster, &self.mem, now), now);
        let elapsed = now.saturating_sub(t0).as_secs_f64();
        let slept = self.fc.stats().sleep_cycles - slept0;
        let asleep = Picos(slept.saturating_mul(self.fc_period.0)).as_secs_f64();
        let fc = self.fc_running_w * (elapsed - asleep).max(0.0) + self.fc_sleeping_w * asleep;
        self.meter.energy_j - before + fc
    }

    /// One frame (`camera`² bytes, row-major) through the network.
    pub fn infer(&mut self, image: &[u8]) -> anyhow::Result<Inference> {
        let n = self.shape.camera * self.shape.camera;
        if image.len() != n {
            bail!("a frame is {n} bytes, got {}", image.len());
        }
        // Energy and latency from the frame's arrival: what came before
        // (boot, the previous frame's stop) is not this inference's.
        let t0 = self.fc.now();
        let slept0 = self.fc.stats().sleep_cycles;
        self.energy_since(t0, slept0);
        let counts0 = self.core_counts();
        self.mem.write_bytes(self.sym.image, image)?;
        self.mem
            .write_bytes(self.sym.command, &CMD_INFER.to_le_bytes())?;
        self.run_to_stop()?;
        let latency = self.fc.now().saturating_sub(t0);
        let energy_j = self.energy_since(t0, slept0);
        let counts = self.core_counts();
        let stat = |i: usize| self.word(self.sym.stats + 4 * i as u32);
        if stat(0)? != 0 {
            bail!(
                "the network failed on the cluster (status {})",
                stat(0)? as i32
            );
        }
        let cells = self.shape.grid * self.shape.grid * self.shape.head_channels;
        let mut raw = vec![0u8; cells * 2];
        self.mem.read_bytes(self.sym.head, &mut raw)?;
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
            cluster_instructions: counts.0 - counts0.0,
            l1_stall_cycles: counts.1 - counts0.1,
        })
    }

    /// Tells the program to close the cluster and exit; its exit code.
    pub fn finish(mut self) -> anyhow::Result<i32> {
        if self.done {
            return Ok(0);
        }
        self.mem
            .write_bytes(self.sym.command, &CMD_QUIT.to_le_bytes())?;
        let limit = Picos(self.fc.now().0.saturating_add(FRAME_TIMEOUT.0));
        let stop = self.cluster.run_until(
            &mut self.fc,
            &mut self.mem,
            &mut self.code,
            &mut NoDevices,
            limit,
        );
        self.fc.flush_console()?;
        self.cluster.flush_console()?;
        match stop {
            StopReason::Exit { code } => Ok(code),
            other => bail!("the program did not exit after its last frame: {other:?}"),
        }
    }
}
