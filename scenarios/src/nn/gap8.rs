//! The AI deck's GAP8 (FC + cluster) and its HyperRAM in this process,
//! driven by a host-stop program (`nn_eval.elf`, `nn_run.elf`): the
//! program stops the run at a plain `ebreak` (the ISS's `ebreak_stops`)
//! whenever it wants the host, which reads and writes its symbols and
//! resumes after the `ebreak`. The ELF is loaded once and the machine
//! kept: the cluster stays open between requests as a real AI-deck
//! program keeps it.
//!
//! Energy: the cluster's power model (`cluster::power`) plus the FC's
//! running and sleeping power from the platform file.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use sim_core::cluster::power::{Meter, Totals};
use sim_core::cluster::{Cluster, ClusterConfig};
use sim_core::config::PlatformConfig;
use sim_core::iss::{load_elf, Backend, CodeCache, Cpu, CpuConfig, LoadedElf, Memory, StopReason};
use sim_core::machine::{run_elf::build_memory, Machine};
use sim_core::peripherals::hyperram::{self, HyperRam};
use sim_core::units::{Hertz, Picos};

/// The platform file whose FC and cluster power figures are used.
pub const PLATFORM: &str = "sim-core/platforms/crazyflie-aideck.json";

/// A path relative to the repository.
pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}
pub fn default_platform() -> PathBuf {
    repo_path(PLATFORM)
}

/// What the GAP8 is built with.
#[derive(Clone, Copy, Debug)]
pub struct Gap8Config {
    pub cores: usize,
    pub mhz: u64,
    pub iss: Backend,
    /// The cluster's supply, V (default: the platform file's `cluster.vref`).
    pub vdd: Option<f64>,
}

/// The machine.
pub struct Gap8 {
    pub mem: Memory,
    code: CodeCache,
    cluster: Cluster,
    pub fc: Cpu,
    /// L3, on the FC's µDMA.
    pub hyper: HyperRam,
    pub elf: LoadedElf,
    meter: Meter,
    /// FC power while it runs and while it sleeps in `wfi` (the platform's
    /// `core.states.running` and `sleeping` currents at `core.vref`): it
    /// sleeps while the cluster works (pmsis `pi_task_wait_on`).
    fc_running_w: f64,
    fc_sleeping_w: f64,
    fc_period: Picos,
    /// The program has exited.
    pub done: bool,
}

/// A mark to measure from: time, FC sleep, cluster instructions and L1
/// stalls.
#[derive(Clone, Copy, Debug)]
pub struct Mark {
    pub t: Picos,
    slept: u64,
    pub instructions: u64,
    pub l1_stalls: u64,
}

impl Gap8 {
    /// Loads the ELF, checks it has the `interface` symbols (before it
    /// runs: another program would run to its end), and runs it to its
    /// first host stop.
    pub fn new(
        elf_path: &Path,
        platform: &Path,
        cfg: Gap8Config,
        interface: &[&str],
        timeout: Picos,
    ) -> anyhow::Result<Self> {
        let bytes =
            std::fs::read(elf_path).with_context(|| format!("reading {}", elf_path.display()))?;
        let elf = load_elf(&bytes).with_context(|| format!("loading {}", elf_path.display()))?;
        if let Some(missing) = interface.iter().find(|s| elf.symbol(s).is_none()) {
            bail!(
                "{}: no symbol {missing}: not the program this command drives",
                elf_path.display()
            );
        }
        let plat = PlatformConfig::from_path(platform)
            .map_err(|e| anyhow::anyhow!("{}: {e}", platform.display()))?;
        let state = |name: &str| {
            plat.core
                .states
                .get(name)
                .with_context(|| format!("{}: no core state `{name}`", platform.display()))
        };
        let fc_running_w = state("running")?.current().0 * plat.core.vref;
        let fc_sleeping_w = state("sleeping")?.current().0 * plat.core.vref;
        let vref = cfg
            .vdd
            .unwrap_or_else(|| plat.cluster.as_ref().map_or(1.2, |c| c.vref));
        let mut mem = build_memory(&[], elf.lowest_address())?;
        mem.add_mmio_window(hyperram::BASE, hyperram::WINDOW)
            .context("the µDMA window")?;
        elf.load_into(&mut mem)
            .with_context(|| format!("loading {}", elf_path.display()))?;
        let ccfg = ClusterConfig {
            cores: cfg.cores,
            clock: Hertz(cfg.mhz.saturating_mul(1_000_000)),
            vref,
            idle_skip: true,
            iss: cfg.iss,
        };
        let fc_cfg = CpuConfig {
            clock: Hertz(plat.core.frequency),
            ebreak_stops: true,
            iss: cfg.iss,
            ..CpuConfig::default()
        };
        let Machine {
            mut fc,
            cluster,
            code,
        } = Machine::new(&mut mem, fc_cfg, Some(ccfg)).context("the cluster")?;
        let mut cluster = cluster.expect("a cluster was asked for");
        // The program's console (errors only) must not mix with cosim's
        // stdout, which carries the results.
        fc.set_console(Box::new(std::io::stderr()));
        cluster.set_console(|| Box::new(std::io::stderr()));
        fc.set_pc(elf.entry);
        fc.set_tohost(elf.symbol("tohost"));
        let mut m = Gap8 {
            mem,
            code,
            cluster,
            fc,
            hyper: HyperRam::default(),
            elf,
            meter: Meter::new(vref, ccfg.clock),
            fc_running_w,
            fc_sleeping_w,
            fc_period: Hertz(plat.core.frequency).period(),
            done: false,
        };
        m.run_to_stop(timeout)?;
        Ok(m)
    }

    /// A symbol of the program.
    pub fn symbol(&self, name: &str) -> anyhow::Result<u32> {
        self.elf
            .symbol(name)
            .with_context(|| format!("the ELF has no symbol {name}"))
    }

    pub fn word(&self, addr: u32) -> anyhow::Result<u32> {
        self.mem
            .read_u32(addr)
            .with_context(|| format!("reading {addr:#010x}"))
    }

    pub fn set_word(&mut self, addr: u32, v: u32) -> anyhow::Result<()> {
        self.mem
            .write_bytes(addr, &v.to_le_bytes())
            .with_context(|| format!("writing {addr:#010x}"))
    }

    /// Runs to `limit` or a stop the host must see, completing HyperRAM
    /// transfers on the way (their device events).
    fn run(&mut self, limit: Picos) -> anyhow::Result<StopReason> {
        loop {
            let stop = self.cluster.run_until(
                &mut self.fc,
                &mut self.mem,
                &mut self.code,
                &mut self.hyper,
                limit,
            );
            if !matches!(stop, StopReason::Event) {
                return Ok(stop);
            }
            let now = self.fc.now();
            self.hyper
                .complete(now, &mut self.mem)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
    }

    /// Runs until the program's next `ebreak` (then steps over it), or at
    /// most `timeout` of simulated time.
    pub fn run_to_stop(&mut self, timeout: Picos) -> anyhow::Result<()> {
        let limit = Picos(self.fc.now().0.saturating_add(timeout.0));
        match self.run(limit)? {
            StopReason::Breakpoint { pc } => {
                self.fc.set_pc(pc.wrapping_add(4));
                Ok(())
            }
            StopReason::Exit { code } => {
                self.done = true;
                let _ = self.fc.flush_console();
                let _ = self.cluster.flush_console();
                bail!("the program ended (exit code {code}) instead of stopping for the host")
            }
            StopReason::Limit => bail!(
                "no host stop within {timeout} of simulated time (pc {:#010x}, {}, FC at {})",
                self.fc.pc(),
                self.hyper.describe(),
                self.fc.now()
            ),
            StopReason::Fatal(e) => bail!("the program failed: {e}"),
            other => bail!("unexpected stop {other:?} at pc {:#010x}", self.fc.pc()),
        }
    }

    /// Runs the program to its exit; its exit code.
    pub fn run_to_exit(&mut self, timeout: Picos) -> anyhow::Result<i32> {
        if self.done {
            return Ok(0);
        }
        let limit = Picos(self.fc.now().0.saturating_add(timeout.0));
        let stop = self.run(limit)?;
        self.fc.flush_console()?;
        self.cluster.flush_console()?;
        self.done = true;
        match stop {
            StopReason::Exit { code } => Ok(code),
            other => bail!("the program did not exit: {other:?}"),
        }
    }

    /// A mark at the present time (the energy meter sampled).
    pub fn mark(&mut self) -> Mark {
        let now = self.fc.now();
        self.meter
            .sample(Totals::of(&self.cluster, &self.mem, now), now);
        let (instructions, l1_stalls) = self
            .cluster
            .report_at(&self.mem, now)
            .iter()
            .fold((0, 0), |(i, s), r| {
                (i + r.instructions, s + r.l1_stall_cycles)
            });
        Mark {
            t: now,
            slept: self.fc.stats().sleep_cycles,
            instructions,
            l1_stalls,
        }
    }

    /// FC + cluster energy from `from` to `to` (two marks, in order), J.
    pub fn energy_between(&self, from: &Mark, to: &Mark, cluster_j: f64) -> f64 {
        let elapsed = to.t.saturating_sub(from.t).as_secs_f64();
        let slept = to.slept - from.slept;
        let asleep = Picos(slept.saturating_mul(self.fc_period.0)).as_secs_f64();
        cluster_j + self.fc_running_w * (elapsed - asleep).max(0.0) + self.fc_sleeping_w * asleep
    }

    /// The cluster's energy so far (at the last mark), J.
    pub fn cluster_energy_j(&self) -> f64 {
        self.meter.energy_j
    }
}
