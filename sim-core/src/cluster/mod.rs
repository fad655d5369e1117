//! The AI deck's GAP8 cluster (DESIGN.md §12, docs/CLUSTER.md): N cores
//! (1–8) on their own clock, the L1 with its banks ([`tcdm`]), the DMA
//! ([`dma`]), the event unit ([`event_unit`]), the control unit
//! ([`ctrl`]) and its energy ([`power`]), run beside the fabric controller.
//!
//! # Scheduling: who runs when
//!
//! The FC and the cluster cores are *agents*, each with its own simulated
//! time. [`Cluster::run_until`] always runs the agent with the smallest
//! `(time, rank)` (rank: the FC first, then the cores in an order that
//! rotates every quantum), up to the earliest of the caller's limit, the
//! next DMA completion, and the other agents' smallest time plus one
//! quantum ([`QUANTUM_CYCLES`] cluster cycles; a core also stops a quantum
//! after its own start). A core that runs alone thus still returns every
//! quantum, and no agent is ever more than a quantum (plus one
//! instruction) ahead of the slowest runnable one.
//!
//! Everything agents share goes through the control, event and DMA
//! registers, and every access to them (but the DMA's per-core staging
//! registers) is a *synchronisation point*: it happens only when every
//! other runnable agent is past it in `(time, rank)` order; otherwise the
//! bus answers [`MmioError::Wait`], the agent stops before the instruction,
//! and the scheduler runs the others first. So events, barriers, the
//! mutex, the dispatch FIFOs, the DMA queue and the FC's mailbox see the
//! accesses in exact simulated-time order, whatever the quantum. Plain RAM
//! (L1, L2) shared between cores without going through those registers is
//! seen at quantum granularity (a core may see another's store up to a
//! quantum early or late): synchronise through the event unit, as PULP
//! programs do.
//!
//! L1 bank conflicts are exact in cycles ([`tcdm`]): the arbiter keeps
//! every grant's cycle; which core wins a tie is the order the scheduler
//! ran them in that quantum (rotating).
//!
//! A core asleep in the event unit, halted or off is not an agent: it costs
//! no host time until a wake-up makes it runnable at the wake-up's time,
//! its cycle counter jumping there as gated cycles.
//!
//! The FC asleep in `wfi` with `FC_IRQ` set (the runtime waiting for a
//! task) stays an agent, but its `wfi` ends its run slice
//! ([`Cpu::set_stop_on_sleep`]) and, asleep, it may only advance just past
//! the earliest runnable core or DMA completion: the first core to post an
//! FC event at `t` then finds the FC at its first clock edge after `t`
//! (the write is a synchronisation point, made once the FC is later), and
//! the FC wakes there, whatever the quantum.

mod cores;
pub mod ctrl;
pub mod dma;
pub mod event_unit;
pub mod power;
pub mod tcdm;

pub use cores::{CoreCount, CoreCountError, MAX_CORES};

use std::io::Write;

use crate::iss::{
    AccessSize, CodeCache, Cpu, CpuConfig, IssError, MemTiming, Memory, Mmio, MmioError, StopReason,
};
use crate::units::{Hertz, Picos};

use ctrl::{Ctrl, Who};
use dma::{Dma, DmaRefusal};
use event_unit::{Eu, EventUnit};
use tcdm::{PortStats, Tcdm, L1_BASE, L1_SIZE};

/// The cluster's register window: CTRL, EU, DMA (docs/CLUSTER.md).
pub const WINDOW_BASE: u32 = 0x1020_0000;
pub const WINDOW_SIZE: u32 = 0x1000;
const EU_OFFSET: u32 = 0x400;
const DMA_OFFSET: u32 = 0x800;

/// gap_sdk `ARCHI_FC_CID`: the FC's cluster id, so its `mhartid` is
/// `32 << 5` (DESIGN.md §12).
pub const FC_HART_ID: u32 = 32 << 5;

/// The scheduling quantum in cluster cycles (see the module docs): long
/// enough that switching agents costs little host time (8 busy cores:
/// one switch per ~1000 cycles each), short enough that the L1 arbiter's
/// window ([`tcdm::WINDOW`] = 4× the quantum) holds every live cycle.
pub const QUANTUM_CYCLES: u64 = 1024;

/// Extra cycles of a cluster core's access to L2: the request leaves the
/// cluster through its AXI port and crosses the SoC interconnect to L2
/// (GAP8 reference manual, "System bus architecture"). Our assumption,
/// no public cycle figure was found: see docs/CLUSTER.md.
pub const L2_EXTRA_CYCLES: u64 = 10;

/// Extra FC cycles of an FC access to L1 (the reverse path, SoC
/// interconnect to the cluster's AXI slave port; assumption, as above).
pub const FC_L1_EXTRA_CYCLES: u64 = 10;

/// L2 as the cluster sees it (DESIGN.md §4).
const L2: (u32, u32) = (crate::iss::map::L2_BASE, crate::iss::map::L2_SIZE);

/// The platform file's `"cluster"` section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClusterConfig {
    /// 1–8 cores (default 8).
    pub cores: usize,
    /// The cluster clock (default 175 MHz, GAP8's maximum, GreenWaves).
    pub clock: Hertz,
    /// The cluster's supply voltage (default 1.2 V) for the power model.
    pub vref: f64,
    pub idle_skip: bool,
    /// The cores' ISS back end (the FC's own is in its `CpuConfig`).
    pub iss: crate::iss::Backend,
}

impl Default for ClusterConfig {
    fn default() -> Self {
        ClusterConfig {
            cores: 8,
            clock: Hertz(175_000_000),
            vref: 1.2,
            idle_skip: true,
            iss: crate::iss::Backend::DEFAULT,
        }
    }
}

/// A cluster core's scheduling state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CoreState {
    /// Never started (or the cluster is off).
    Off,
    /// An agent: runs (or waits to retry a synchronising access).
    Running,
    /// Asleep in the event unit (clock gated).
    Gated,
    /// Stopped by HALT or by powering the cluster off.
    Halted,
}

/// The state the buses share: the registers and the agents' times.
#[derive(Debug)]
pub struct Shared {
    pub n: usize,
    quantum: Picos,
    pub state: [CoreState; MAX_CORES],
    /// Each core's time when it is not running (its wake-up or start
    /// time for a core about to run).
    pub time: [Picos; MAX_CORES],
    /// A core's pending FETCH_EN: restart at this pc.
    pub start: [Option<u32>; MAX_CORES],
    /// An agent stopped before a synchronising access at this time
    /// (index MAX_CORES: the FC).
    blocked_at: [Option<Picos>; MAX_CORES + 1],
    pub fc_time: Picos,
    pub ctrl: Ctrl,
    pub eu: EventUnit,
    pub dma: Dma,
    /// The running core asked to stop (HALT).
    pub stop: bool,
    /// Cores asleep until the DMA queue has room.
    dma_full: u32,
    /// An FC access changed the cluster's level on the FC's interrupt
    /// line: its run stops after the access so the line follows.
    fc_irq_changed: bool,
    /// The platform's devices asked the FC's run to stop (for the caller).
    platform_stop: bool,
}

const FC: usize = MAX_CORES;

impl Shared {
    /// The tie rank of an agent at time `t`: the FC first, then the cores
    /// in an order rotating every quantum.
    fn rank(&self, agent: usize, t: Picos) -> usize {
        if agent == FC {
            return 0;
        }
        let rot = ((t.0 / self.quantum.0.max(1)) % self.n as u64) as usize;
        1 + (agent + self.n - rot) % self.n
    }

    /// The L1 arbiter's floor ([`Tcdm::retire`]): a quantum before the
    /// slowest of the FC and the runnable cores, in cluster cycles of
    /// `period`. Every later access is at or above it: a core runs from
    /// its own time on, and a core that wakes or starts does so at the
    /// time of the agent that wakes it (the FC or a core, all at or above
    /// the slowest), or at a DMA completion, which no agent passes by more
    /// than an instruction; the quantum is the margin. The fastest core is
    /// at most a quantum (and an instruction) above the slowest, so the
    /// arbiter's window (four quanta) holds every cycle between.
    fn arbiter_floor(&self, period: Picos) -> u64 {
        let slowest = (0..self.n)
            .filter(|&j| self.state[j] == CoreState::Running)
            .map(|j| self.time[j])
            .fold(self.fc_time, Picos::min);
        (slowest.0 / period.0.max(1)).saturating_sub(QUANTUM_CYCLES)
    }

    fn eff_time(&self, agent: usize, now: Picos) -> Picos {
        self.blocked_at[agent].map_or(now, |b| b.max(now))
    }

    /// Whether `agent` may do a synchronising access at `t`: every other
    /// runnable agent is later in `(time, rank)` order and no DMA
    /// completion at or before `t` is still to be applied.
    fn synced(&self, agent: usize, t: Picos) -> bool {
        if self.dma.next_completion().is_some_and(|c| c <= t) {
            return false;
        }
        let me = (t, self.rank(agent, t));
        let later = |other: usize, ot: Picos| (ot, self.rank(other, ot)) > me;
        if agent != FC && !later(FC, self.eff_time(FC, self.fc_time)) {
            return false;
        }
        (0..self.n).all(|j| {
            j == agent
                || self.state[j] != CoreState::Running
                || later(j, self.eff_time(j, self.time[j]))
        })
    }

    /// Make the cores the event unit released runnable at their wake-up.
    fn collect_wakes(&mut self) {
        for i in 0..self.n {
            if let Some(t) = self.eu.take_wake(i) {
                if self.state[i] == CoreState::Gated {
                    self.state[i] = CoreState::Running;
                    self.time[i] = t;
                }
            }
        }
    }

    /// The earliest time a runnable core is at (`Picos::MAX`: none).
    fn min_core_time(&self) -> Picos {
        (0..self.n)
            .filter(|&j| self.state[j] == CoreState::Running)
            .map(|j| self.eff_time(j, self.time[j]))
            .min()
            .unwrap_or(Picos::MAX)
    }

    /// One 32-bit access by `agent` to the cluster window at `t`.
    fn access(
        &mut self,
        agent: usize,
        addr: u32,
        size: AccessSize,
        write: Option<u32>,
        t: Picos,
    ) -> Result<u32, MmioError> {
        let fault = Err(MmioError::AccessFault { addr });
        let off = addr.wrapping_sub(WINDOW_BASE);
        if size != AccessSize::Word || off >= WINDOW_SIZE {
            return fault;
        }
        let who = if agent == FC {
            Who::Fc
        } else {
            Who::Core(agent)
        };
        let staging = off >= DMA_OFFSET && off - DMA_OFFSET < dma::CMD;
        if !staging {
            if !self.synced(agent, t) {
                self.blocked_at[agent] = Some(t);
                return Err(MmioError::Wait { addr });
            }
            self.blocked_at[agent] = None;
        }
        let r = if off < EU_OFFSET {
            match write {
                Some(v) => self.ctrl_write(who, off, v, t).then_some(0),
                None => self.ctrl_read(who, off),
            }
            .ok_or(MmioError::AccessFault { addr })
        } else {
            let Who::Core(i) = who else { return fault };
            if !self.ctrl.is_on() {
                return fault;
            }
            let sleep = |s: &mut Shared| {
                s.state[i] = CoreState::Gated;
                Err(MmioError::Wait { addr })
            };
            if off < DMA_OFFSET {
                let o = off - EU_OFFSET;
                let r = match write {
                    Some(v) => self.eu.write(i, o, v, t).map(|()| 0),
                    None => self.eu.read(i, o, t),
                };
                match r {
                    Ok(v) => Ok(v),
                    Err(Eu::Sleep) => sleep(self),
                    Err(Eu::Fault) => fault,
                }
            } else {
                let o = off - DMA_OFFSET;
                let r = match write {
                    Some(v) => self.dma.write(i, o, v, t).map(|()| 0),
                    None => self.dma.read(i, o),
                };
                match r {
                    Ok(v) => Ok(v),
                    Err(DmaRefusal::Full) => {
                        self.dma_full |= 1 << i;
                        sleep(self)
                    }
                    Err(DmaRefusal::Fault) => fault,
                }
            }
        };
        self.collect_wakes();
        r
    }
}

/// The FC's bus: the cluster window, and the platform's devices.
struct FcBus<'a> {
    sh: &'a mut Shared,
    dev: &'a mut dyn Mmio,
}

fn in_window(addr: u32) -> bool {
    addr.wrapping_sub(WINDOW_BASE) < WINDOW_SIZE
}

impl Mmio for FcBus<'_> {
    fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError> {
        if in_window(addr) {
            return self.sh.access(FC, addr, size, None, now);
        }
        self.dev.read(addr, size, now)
    }
    fn write(&mut self, addr: u32, size: AccessSize, v: u32, now: Picos) -> Result<(), MmioError> {
        if in_window(addr) {
            return self.sh.access(FC, addr, size, Some(v), now).map(|_| ());
        }
        self.dev.write(addr, size, v, now)
    }
    fn stable_until(&self, addr: u32, size: AccessSize, now: Picos) -> Picos {
        if !in_window(addr) {
            return self.dev.stable_until(addr, size, now);
        }
        // Only cores change CTRL (and DMA completions wake cores): it holds
        // until the earliest runnable core may act. A pending FC event
        // would be cleared by the read: no promise then.
        if self.sh.ctrl.fc_events != 0 {
            return now;
        }
        let dma = self.sh.dma.next_completion().unwrap_or(Picos::MAX);
        self.sh.min_core_time().min(dma).max(now)
    }
    fn next_event(&self) -> Option<Picos> {
        self.dev.next_event()
    }
    fn take_stop_request(&mut self) -> bool {
        let platform = self.dev.take_stop_request();
        self.sh.platform_stop |= platform;
        platform | std::mem::take(&mut self.sh.fc_irq_changed)
    }
    fn plain_window(&mut self) -> Option<(u32, &[u8])> {
        // The cluster's window is never plain (every access is a
        // synchronisation point); the platform's may be.
        self.dev.plain_window()
    }
}

/// A cluster core's bus: the cluster window only.
struct CoreBus<'a> {
    sh: &'a mut Shared,
    core: usize,
}

impl Mmio for CoreBus<'_> {
    fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError> {
        self.sh.access(self.core, addr, size, None, now)
    }
    fn write(&mut self, addr: u32, size: AccessSize, v: u32, now: Picos) -> Result<(), MmioError> {
        self.sh
            .access(self.core, addr, size, Some(v), now)
            .map(|_| ())
    }
    /// A core's read of CTRL's plain registers (not the FC's event
    /// counter, which a core cannot read, nor the event unit or the DMA,
    /// whose reads act) holds until another agent may act: the FC or
    /// another runnable core at its time, or a DMA completion. Cores that
    /// sleep in the event unit wake only on what those do, and a read is
    /// only made once every other agent is later (`Shared::synced`). So
    /// a core polling the mailbox while the FC works skips to the FC's
    /// time instead of reading it every few cycles (the PMSIS runtime's
    /// core 0 sleeps on the mailbox event instead; a user's runtime may
    /// poll).
    fn stable_until(&self, addr: u32, size: AccessSize, now: Picos) -> Picos {
        use ctrl::{BOOT_ADDR, FREQ_HZ, MAILBOX, NB_CORES, POWER, RUNNING};
        let off = addr.wrapping_sub(WINDOW_BASE);
        let plain = matches!(
            off,
            POWER | NB_CORES | FREQ_HZ | BOOT_ADDR | RUNNING | MAILBOX
        );
        if size != AccessSize::Word || !plain {
            return now;
        }
        let sh = &*self.sh;
        let others = (0..sh.n)
            .filter(|&j| j != self.core && sh.state[j] == CoreState::Running)
            .map(|j| sh.eff_time(j, sh.time[j]))
            .chain([
                sh.eff_time(FC, sh.fc_time),
                sh.dma.next_completion().unwrap_or(Picos::MAX),
            ])
            .min()
            .unwrap_or(Picos::MAX);
        others.max(now)
    }
    fn take_stop_request(&mut self) -> bool {
        std::mem::take(&mut self.sh.stop)
    }
}

/// Per-core figures for `--stats` and the power model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoreReport {
    pub instructions: u64,
    /// Cycles awake (mcycle).
    pub active_cycles: u64,
    /// Cycles clock-gated (asleep in the event unit) since the core first
    /// started.
    pub gated_cycles: u64,
    pub l1_accesses: u64,
    pub l1_stall_cycles: u64,
}

/// The cluster.
pub struct Cluster {
    cfg: ClusterConfig,
    cores: Vec<Cpu>,
    /// Cycles before each core's first start (not gated: off).
    off_cycles: Vec<u64>,
    sh: Shared,
}

impl std::fmt::Debug for Cluster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cluster")
            .field("cfg", &self.cfg)
            .field("state", &&self.sh.state[..self.sh.n])
            .finish_non_exhaustive()
    }
}

/// Errors building the cluster.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    #[error(transparent)]
    Cores(#[from] CoreCountError),
    #[error("cluster.mhz must be positive")]
    Clock,
    #[error("cluster memory map: {0}")]
    Memory(#[from] crate::iss::MemError),
}

impl Cluster {
    /// The cluster, off, and its L1, register window and arbiter added to
    /// `mem` (which must hold L2 already). The FC gets its cluster-aware
    /// `mhartid` and view of L1 through [`Cluster::attach_fc`].
    pub fn new(cfg: ClusterConfig, mem: &mut Memory) -> Result<Cluster, ClusterError> {
        CoreCount::new(cfg.cores)?;
        if cfg.clock.0 == 0 {
            return Err(ClusterError::Clock);
        }
        mem.add_ram(L1_BASE, L1_SIZE)?;
        mem.add_mmio_window(WINDOW_BASE, WINDOW_SIZE)?;
        mem.l1_arbiter = Some(Box::new(Tcdm::default()));
        let period = cfg.clock.period();
        let n = cfg.cores;
        let cores = (0..n)
            .map(|i| {
                let mut c = Cpu::new(CpuConfig {
                    clock: cfg.clock,
                    idle_skip: cfg.idle_skip,
                    hart_id: i as u32,
                    iss: cfg.iss,
                    ..CpuConfig::default()
                });
                c.set_mem_timing(MemTiming {
                    l2: L2,
                    l2_extra: L2_EXTRA_CYCLES,
                    l1: (L1_BASE, L1_SIZE),
                    l1_extra: 0,
                    l1_port: Some(i as u8),
                });
                c
            })
            .collect();
        let ctrl = Ctrl {
            freq_hz: cfg.clock.0.min(u32::MAX as u64) as u32,
            ..Ctrl::default()
        };
        Ok(Cluster {
            cfg,
            cores,
            off_cycles: vec![0; n],
            sh: Shared {
                n,
                quantum: Picos(QUANTUM_CYCLES * period.0),
                state: [CoreState::Off; MAX_CORES],
                time: [Picos::ZERO; MAX_CORES],
                start: [None; MAX_CORES],
                blocked_at: [None; MAX_CORES + 1],
                fc_time: Picos::ZERO,
                ctrl,
                eu: EventUnit::new(n, period),
                dma: Dma::new(period, (L1_BASE, L1_SIZE), L2),
                stop: false,
                dma_full: 0,
                fc_irq_changed: false,
                platform_stop: false,
            },
        })
    }

    /// The FC's view of the cluster: `mhartid` 0x400 and L1 latency. Call
    /// with the FC's configuration before creating it.
    pub fn fc_config(cfg: CpuConfig) -> CpuConfig {
        CpuConfig {
            hart_id: FC_HART_ID,
            ..cfg
        }
    }

    /// The FC's memory timing with a cluster: L1 costs
    /// [`FC_L1_EXTRA_CYCLES`], without bank arbitration.
    pub fn attach_fc(fc: &mut Cpu) {
        fc.set_mem_timing(MemTiming {
            l1: (L1_BASE, L1_SIZE),
            l1_extra: FC_L1_EXTRA_CYCLES,
            ..MemTiming::default()
        });
        // The scheduler bounds the FC's sleeps ([`Cluster::run_until`]).
        fc.set_stop_on_sleep(true);
    }

    /// The cores' console (semihosting output of cluster code).
    pub fn set_console(&mut self, mut make: impl FnMut() -> Box<dyn Write + Send>) {
        for c in &mut self.cores {
            c.set_console(make());
        }
    }

    pub fn flush_console(&mut self) -> std::io::Result<()> {
        for c in &mut self.cores {
            c.flush_console()?;
        }
        Ok(())
    }

    /// How long the cluster has been powered by time `t`.
    pub fn powered_time(&self, t: Picos) -> Picos {
        let c = &self.sh.ctrl;
        c.powered_before
            + c.powered_since
                .map_or(Picos::ZERO, |s| Picos(t.0.saturating_sub(s.0)))
    }

    /// DMA totals: (bytes copied, transfer cycles).
    pub fn dma_totals(&self) -> (u64, u64) {
        (self.sh.dma.bytes, self.sh.dma.busy_cycles)
    }

    /// Each core's figures at time `t` (a power sample): as [`report`],
    /// plus, for a core asleep in the event unit, the gated cycles from
    /// its sleep to `t`, which its counter only takes when it wakes. Without
    /// them a long sleep would land whole in the sample where it ends.
    ///
    /// [`report`]: Cluster::report
    pub fn report_at(&self, mem: &Memory, t: Picos) -> Vec<CoreReport> {
        let mut reports = self.report(mem);
        for (i, r) in reports.iter_mut().enumerate() {
            if self.sh.state[i] == CoreState::Gated {
                let c = &self.cores[i];
                let period = c.config().clock.period().0.max(1);
                r.gated_cycles += t.0.saturating_sub(c.now().0) / period;
            }
        }
        reports
    }

    /// Each core's own ISS statistics (polling and skipped instructions
    /// included, which [`Cluster::report`] leaves out).
    pub fn core_stats(&self) -> Vec<crate::iss::CoreStats> {
        self.cores.iter().map(|c| c.stats()).collect()
    }

    /// Each core's instructions retired in translated code
    /// ([`Cpu::translated_instructions`]).
    pub fn translated_instructions(&self) -> Vec<u64> {
        self.cores
            .iter()
            .map(|c| c.translated_instructions())
            .collect()
    }

    /// Each core's figures so far.
    pub fn report(&self, mem: &Memory) -> Vec<CoreReport> {
        let l1: [PortStats; tcdm::PORTS] = match &mem.l1_arbiter {
            Some(a) => std::array::from_fn(|p| a.port_stats(p as u8)),
            None => Default::default(),
        };
        self.cores
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let s = c.stats();
                CoreReport {
                    instructions: s.instructions,
                    active_cycles: s.cycles - s.sleep_cycles,
                    gated_cycles: s.sleep_cycles - self.off_cycles[i],
                    l1_accesses: l1[i].accesses,
                    l1_stall_cycles: l1[i].stall_cycles,
                }
            })
            .collect()
    }

    /// Apply the DMA completions at or before `t`: copy the bytes, clear
    /// the STATUS bit, raise event 8 at the enqueuing core, wake the cores
    /// that wait for room in the queue.
    fn complete_dma(&mut self, mem: &mut Memory, t: Picos) -> Result<(), StopReason> {
        while let Some(c) = self.sh.dma.pop_completed(t) {
            let mut buf = Vec::new();
            for (ext, loc, n) in c.pieces() {
                buf.resize(n as usize, 0);
                let (from, to) = if c.loc2ext { (loc, ext) } else { (ext, loc) };
                let copied = mem
                    .read_bytes(from, &mut buf)
                    .and_then(|()| mem.write_bytes(to, &buf));
                if let Err(e) = copied {
                    let msg = format!("cluster DMA command {}: {e}", c.id);
                    return Err(StopReason::Fatal(IssError::Device(MmioError::Device {
                        addr: from,
                        message: msg,
                    })));
                }
            }
            self.sh
                .eu
                .trigger(event_unit::EVENT_DMA, 1 << c.core, c.done);
            for i in 0..self.sh.n {
                if self.sh.dma_full & (1 << i) != 0 {
                    self.sh.dma_full &= !(1 << i);
                    self.sh.eu.release(i, c.done);
                }
            }
            self.sh.collect_wakes();
        }
        Ok(())
    }

    /// Run the FC and the cluster until simulated time reaches `limit`
    /// (both at or past it: [`StopReason::Limit`]) or the FC stops for
    /// anything else (a device event, a request, its exit...), or a
    /// cluster core ends the program or fails. See the module docs for the
    /// order in which the agents run.
    ///
    /// The FC's external interrupt level the caller set is the platform's;
    /// the cluster ORs its own line (`FC_IRQ`) in before each FC turn and
    /// puts the caller's level back before it returns. `code` is the code
    /// cache kept beside `mem`: the FC and the cores share it.
    pub fn run_until(
        &mut self,
        fc: &mut Cpu,
        mem: &mut Memory,
        code: &mut CodeCache,
        dev: &mut dyn Mmio,
        limit: Picos,
    ) -> StopReason {
        let platform_irq = fc.external_irq();
        let stop = self.run_agents(fc, mem, code, dev, limit, platform_irq);
        fc.set_external_irq(platform_irq);
        stop
    }

    /// [`Cluster::run_until`]'s loop.
    fn run_agents(
        &mut self,
        fc: &mut Cpu,
        mem: &mut Memory,
        code: &mut CodeCache,
        dev: &mut dyn Mmio,
        limit: Picos,
        platform_irq: bool,
    ) -> StopReason {
        loop {
            self.sh.fc_time = fc.now();
            // The earliest runnable agent in `(time, rank)` order. A rank
            // (two divisions) is computed only on a tie in time: once per
            // agent per pass made this loop the scheduler's hottest line.
            let mut pick = (self.sh.eff_time(FC, self.sh.fc_time), Some(0usize), FC);
            for i in 0..self.sh.n {
                if self.sh.state[i] == CoreState::Running {
                    let t = self.sh.eff_time(i, self.sh.time[i]);
                    let earlier = t < pick.0
                        || t == pick.0 && {
                            let r = self.sh.rank(i, t);
                            r < *pick.1.get_or_insert_with(|| self.sh.rank(pick.2, t))
                        };
                    if earlier {
                        pick = (t, None, i);
                    }
                }
            }
            let floor = pick.0;
            if self.sh.dma.next_completion().is_some_and(|c| c <= floor) {
                if let Err(stop) = self.complete_dma(mem, floor) {
                    return stop;
                }
                continue; // a wake-up may have made an earlier agent
            }
            if floor >= limit {
                return StopReason::Limit;
            }
            let who = pick.2;
            let others = (0..self.sh.n)
                .filter(|&j| j != who && self.sh.state[j] == CoreState::Running)
                .map(|j| self.sh.eff_time(j, self.sh.time[j]))
                .chain((who != FC).then_some(self.sh.eff_time(FC, self.sh.fc_time)))
                .min();
            let q = self.sh.quantum;
            let mut horizon = limit;
            if let Some(c) = self.sh.dma.next_completion() {
                horizon = horizon.min(c);
            }
            if let Some(o) = others {
                horizon = horizon.min(Picos(o.0.saturating_add(q.0)));
            }
            if who == FC {
                let line = self.sh.fc_irq_level();
                fc.set_external_irq(platform_irq || line);
                if fc.is_sleeping() && self.sh.ctrl.fc_irq && !line {
                    // Asleep in wfi, a core's FC_EVENT may wake it: it
                    // sleeps only past the earliest time a core (or a DMA
                    // completion, which wakes cores) may act, so that its
                    // wake-up is its first clock edge after the event,
                    // whatever the quantum (docs/CLUSTER.md, FC_IRQ).
                    let earliest = self
                        .sh
                        .min_core_time()
                        .min(self.sh.dma.next_completion().unwrap_or(Picos::MAX));
                    if earliest < Picos::MAX {
                        horizon = horizon.min(Picos(earliest.0 + 1));
                    }
                }
                let mut bus = FcBus {
                    sh: &mut self.sh,
                    dev,
                };
                match fc.run_until(mem, code, &mut bus, horizon) {
                    StopReason::Limit | StopReason::Wait => {}
                    // The cluster's own request (its line changed): the
                    // next FC turn sets it.
                    StopReason::DeviceRequest if !std::mem::take(&mut self.sh.platform_stop) => {}
                    other => return other,
                }
            } else {
                horizon = horizon.min(Picos(floor.0.saturating_add(q.0)));
                let core = &mut self.cores[who];
                if let Some(pc) = self.sh.start[who].take() {
                    core.restart(pc);
                    let before = core.cycles().0;
                    core.gate_until(self.sh.time[who]);
                    self.off_cycles[who] += core.cycles().0 - before;
                }
                core.gate_until(self.sh.time[who]);
                if let Some(t) = mem.l1_arbiter.as_mut() {
                    t.retire(self.sh.arbiter_floor(self.cfg.clock.period()));
                }
                let mut bus = CoreBus {
                    sh: &mut self.sh,
                    core: who,
                };
                let stop = core.run_until(mem, code, &mut bus, horizon);
                self.sh.time[who] = core.now();
                match stop {
                    StopReason::Exit { .. } | StopReason::Breakpoint { .. } => return stop,
                    StopReason::Fatal(e) => {
                        return StopReason::Fatal(IssError::ClusterCore {
                            core: who,
                            source: Box::new(e),
                        })
                    }
                    _ => {}
                }
            }
        }
    }
}
