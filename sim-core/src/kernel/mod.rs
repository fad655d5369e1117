//! The event kernel (MESSY's SystemC side, thesis §3.2.2): it alternates the
//! ISS, run "until the next event" as MESSY's core adapter calls GVSoC's
//! `step_until`, with the device models and the 1 ms power sampling, all on
//! one integer-picosecond clock.
//!
//! One loop turn: the next stop is the earlier of the next power sample
//! (every 1 ms, DESIGN.md §4) and the devices' next own action (the STM32's
//! GET_STABLE / RUN_PID / GO_DOWN iterations). The ISS runs to it (skipping
//! idle polling exactly), the due device actions run, the due samples are
//! taken with the devices' power states at that time, and the battery's
//! low flag is handed to the STM32.

pub mod cli;
mod console;
mod firmware_params;
mod map_dump;
mod nn_stats;
mod summary;

pub use console::Console;
pub use map_dump::MAP_FILE;
pub use nn_stats::{CyclesSummary, NnSummary, NN_STATS_SYMBOL};
pub use summary::{
    BatterySummary, EnergySummary, FlowDriftSummary, RadioSummary, RadiosSummary, Summary,
};

use std::path::{Path, PathBuf};
use std::time::Instant;

use protocol::ImageEncoding;
use thiserror::Error;

use crate::bus::{Platform, PERIPHERAL_BASE, WINDOW_SIZE};
use crate::cluster::power::{Meter, Totals};
use crate::cluster::Cluster;
use crate::config::{PlatformConfig, RunConfig};
use crate::iss::{load_elf, CodeCache, Cpu, CpuConfig, ElfError, Memory, StopReason};
use crate::machine::Machine;
use crate::peripherals::radio::{self, RadioDevice};
use crate::peripherals::stm32::crtp::console::ConsoleTap;
use crate::peripherals::stm32::crtp::{CrtpConfig, CrtpServer, PowerTelemetry};
use crate::peripherals::stm32::estimator::{FlowFilterParams, MetresPerSecond};
use crate::peripherals::stm32::{PositionSource, Stm32Config};
use crate::peripherals::{Camera, DeviceError, DevicePower, Stm32, WorldLink, WorldSession};
use crate::power::sag::OnEmpty;
use crate::power::{CoreState, Loads, PowerError, PowerLogger, PowerNetwork};
use crate::sync::TimeKeeper;
use crate::units::{Cycles, Hertz, Millis, Picos};

/// L2 RAM of the GAP8-like map (DESIGN.md §4).
pub const L2_BASE: u32 = 0x1C00_0000;
pub const L2_SIZE: u32 = 512 * 1024;
/// The CRTP link's arrivals in the output directory (docs/CFLIB.md).
pub const CRTP_RECORDING: &str = "crtp.jsonl";
/// A paced live CRTP link's steps: platform time, wall time, lag
/// (docs/CFLIB.md "Pacing").
pub const PACING_CSV: &str = "pacing.csv";
/// Power samples every millisecond (DESIGN.md §4).
pub const SAMPLE_PERIOD: Picos = Picos::from_ms(1);

/// Everything a run needs besides the firmware and the world.
#[derive(Debug, Clone)]
pub struct KernelConfig {
    pub platform: PlatformConfig,
    pub run: RunConfig,
    pub image_encoding: ImageEncoding,
    /// How long the link polls for the world's replies (µs; `--busy-poll-us`,
    /// recorded in `summary.json`; it changes no simulated result).
    pub busy_poll_us: u64,
    /// The drone claimed in GET_INIT_DATA (`--drone`; `None` for a world
    /// with one drone, whose frames then stay the thesis's).
    pub drone: Option<String>,
    /// Exact skipping of idle polling (off only to compare).
    pub idle_skip: bool,
    /// Extra cycles per access to the peripheral window.
    pub mmio_latency: u64,
    /// Where the outputs go (power CSVs, console.log, summary.json).
    pub out_dir: Option<PathBuf>,
    /// Echo the firmware's console on stdout.
    pub echo_console: bool,
    /// Show a progress line on a terminal.
    pub progress: bool,
    /// Stop (as failed) after this much simulated time, if set.
    pub max_time: Option<Picos>,
    /// The number of gates in the world file, for `summary.json`
    /// (`--gates-total`; the world's STOP reply carries only the gates passed).
    pub gates_total: Option<u64>,
}

impl KernelConfig {
    /// Whether this platform reports its radios on their own (columns in
    /// `power.csv`, keys in `summary.json`): a swarm member (`--drone`) or
    /// a platform file that lists a radio. Otherwise a radio's current is
    /// counted with the other loads, and a run that never switches a radio
    /// on has exactly the outputs it had before the radios existed.
    pub fn reports_radios(&self) -> bool {
        self.drone.is_some()
            || crate::config::RADIO_SENSORS
                .iter()
                .any(|n| self.platform.sensor(n).is_some())
    }
}

/// Why a run failed.
#[derive(Debug, Error)]
pub enum KernelError {
    #[error("firmware: {0}")]
    Elf(#[from] ElfError),
    #[error("firmware does not fit the memory map: {0}")]
    Memory(String),
    #[error("platform: {0}")]
    Config(String),
    #[error(transparent)]
    Device(#[from] DeviceError),
    #[error(transparent)]
    Power(#[from] PowerError),
    #[error("core: {0}")]
    Core(String),
    #[error("cannot write outputs: {0}")]
    Io(#[from] std::io::Error),
}

/// The outcome of a run: the summary is there even when the run failed.
pub struct RunOutcome {
    pub summary: Summary,
    pub error: Option<KernelError>,
}

/// Builds the STM32's settings from the run configuration.
fn stm32_config(cfg: &KernelConfig) -> Stm32Config {
    Stm32Config {
        tolerance: cfg.run.tolerance,
        target_cycles: cfg.run.target_cycles,
        unlock_cycles: cfg.run.unlock_cycles,
        position_source: cfg.run.position_source,
        controller: cfg.run.controller,
        range_max_mm: cfg.run.range_max_m * 1000.0,
        flow_filter: FlowFilterParams {
            flow_std: MetresPerSecond(cfg.run.flow_std_m_s),
            ..FlowFilterParams::default()
        },
        ..Stm32Config::default()
    }
}

fn write_delay(platform: &PlatformConfig, sensor: &str) -> Picos {
    platform
        .sensor(sensor)
        .and_then(|s| s.state("write"))
        .and_then(|s| s.delay())
        .map_or(Picos::ZERO, Millis::to_picos)
}

fn capture_time(platform: &PlatformConfig) -> Millis {
    // The camera's read delay is its capture time (16 ms, §4.2.1).
    platform
        .sensor("camera")
        .and_then(|s| s.state("read"))
        .and_then(|s| s.delay())
        .unwrap_or(Millis(16))
}

/// Runs `firmware` against `world` until the firmware exits or fails.
pub fn simulate<W: WorldLink>(firmware: &[u8], cfg: &KernelConfig, world: W) -> RunOutcome {
    let wall = Instant::now();
    let mut run = match Run::new(firmware, cfg, world) {
        Ok(run) => run,
        Err(e) => {
            let mut summary = Summary::failed_before_start(cfg);
            summary.wall_time_s = wall.elapsed().as_secs_f64();
            summary.error = Some(e.to_string());
            // A run that could not start still leaves its summary, so that a
            // sweep or a script reads why.
            if let Some(dir) = &cfg.out_dir {
                if let Err(io) = summary.write(&dir.join("summary.json")) {
                    tracing::error!("cannot write summary.json: {io}");
                }
            }
            return RunOutcome {
                summary,
                error: Some(e),
            };
        }
    };
    let result = run.main_loop(cfg);
    run.finish(cfg, wall, result)
}

struct Run<W: WorldLink> {
    cpu: Cpu,
    mem: Memory,
    /// The code decoded and translated from `mem`, beside it.
    code: CodeCache,
    platform: Platform<W>,
    power: PowerNetwork,
    console: Console,
    exit_code: Option<i32>,
    /// The platform's time at the end of the run: the firmware's exit, or
    /// the end of the motors' stop when the platform sent STOP for it.
    end_time: Picos,
    /// The firmware's map image, copied to `map.cfog` at the end.
    map: Option<map_dump::MapSymbols>,
    /// The firmware's inference counters, read into `summary.json`'s `nn`.
    nn_stats: Option<nn_stats::NnStatsSymbol>,
    /// The GAP8 cluster, when the platform file has one (DESIGN.md §12),
    /// and its energy meter.
    cluster: Option<(Cluster, Meter)>,
    /// When the battery reached `soc_end` (the power sample's time).
    battery_empty_at: Option<Picos>,
}

impl<W: WorldLink> Run<W> {
    fn new(firmware: &[u8], cfg: &KernelConfig, mut world: W) -> Result<Self, KernelError> {
        let elf = load_elf(firmware)?;
        let map = map_dump::MapSymbols::find(&elf);
        let nn_stats = nn_stats::NnStatsSymbol::find(&elf);
        let mut mem = Memory::new();
        mem.add_ram(L2_BASE, L2_SIZE)
            .map_err(|e| KernelError::Memory(e.to_string()))?;
        mem.add_mmio_window(PERIPHERAL_BASE, WINDOW_SIZE)
            .map_err(|e| KernelError::Memory(e.to_string()))?;
        elf.load_into(&mut mem)?;
        firmware_params::apply(&elf, &mut mem, &cfg.run.firmware_params)?;

        let cluster_cfg = cfg
            .platform
            .cluster
            .as_ref()
            .map(|section| section.cluster_config(cfg.idle_skip, cfg.run.iss));
        let fc_cfg = CpuConfig {
            clock: Hertz(cfg.platform.core.frequency),
            mmio_latency: Cycles(cfg.mmio_latency),
            idle_skip: cfg.idle_skip,
            iss: cfg.run.iss,
            ..CpuConfig::default()
        };
        let Machine {
            fc: mut cpu,
            cluster,
            code,
        } = Machine::new(&mut mem, fc_cfg, cluster_cfg)
            .map_err(|e| KernelError::Config(e.to_string()))?;
        let cluster = cluster
            .zip(cluster_cfg)
            .map(|(c, cc)| (c, Meter::new(cc.vref, cc.clock)));
        cpu.set_pc(elf.entry);
        if let Some(sp) = elf.symbol("__stack") {
            cpu.set_reg(2, sp);
        }
        cpu.set_tohost(elf.symbol("tohost"));
        let console = Console::create(cfg.out_dir.as_deref(), cfg.echo_console)?;
        cpu.set_console(Box::new(console.writer()));
        let mut cluster = cluster;
        if let Some((c, _)) = cluster.as_mut() {
            c.set_console(|| Box::new(console.writer()));
        }

        let camera = Camera::new(
            capture_time(&cfg.platform),
            DevicePower::new(write_delay(&cfg.platform, "camera")),
        );
        let mut stm32 = Stm32::new(
            stm32_config(cfg),
            DevicePower::new(write_delay(&cfg.platform, "stm32")),
        );
        if let Some(spec) = &cfg.run.crtp {
            // The console's text goes to the CRTP client too (port 0).
            let tap = ConsoleTap::default();
            let server = CrtpServer::open(
                CrtpConfig {
                    spec: spec.clone(),
                    pace: cfg.run.pace,
                    idle: Picos((cfg.run.crtp_idle_s * Picos::PER_S as f64).round() as u64),
                    record: cfg.out_dir.as_ref().map(|d| d.join(CRTP_RECORDING)),
                    pacing_log: cfg.out_dir.as_ref().map(|d| d.join(PACING_CSV)),
                    ai_deck: cfg.platform.sensor("camera").is_some()
                        || cfg.platform.cluster.is_some(),
                    cluster: cfg.platform.cluster.is_some(),
                    position_variance: cfg.run.position_source == PositionSource::Flow,
                },
                tap.clone(),
            )?;
            console.set_tap(tap);
            stm32.attach_crtp(server);
        }
        let radios = [radio::uwb::SPEC, radio::p2p::SPEC]
            .map(|spec| RadioDevice::new(spec, cfg.run.radio_id, spec.currents(&cfg.platform)));
        let time = TimeKeeper::new(cfg.run.sync);
        let session = WorldSession::new(cfg.drone.clone(), cfg.image_encoding);

        let mut power = PowerNetwork::new(&cfg.platform, &cfg.run)?;
        if let Some(dir) = &cfg.out_dir {
            let logger = PowerLogger::create_with_cluster(
                dir,
                cfg.reports_radios(),
                cluster.is_some(),
                cfg.run.series,
            )?;
            // The logs are written while the link waits for the world.
            world.add_idle_work(logger.idle_work());
            power.attach_logger(logger);
        }
        let platform = Platform::new(camera, stm32, radios, world, session, time);
        Ok(Run {
            cpu,
            mem,
            code,
            platform,
            power,
            console,
            exit_code: None,
            battery_empty_at: None,
            end_time: Picos::ZERO,
            map,
            nn_stats,
            cluster,
        })
    }

    fn loads_at(&self, t: Picos) -> Loads {
        Loads {
            core: if self.cpu.is_sleeping() {
                CoreState::Sleeping
            } else {
                CoreState::Running
            },
            camera: self.platform.camera.power.state_at(t),
            stm32: self.platform.stm32.power.state_at(t),
            radios: Default::default(),
        }
    }

    fn take_samples(&mut self, now: Picos) -> Result<(), KernelError> {
        while self.power.next_sample_time() <= now {
            let t = self.power.next_sample_time();
            let mut loads = self.loads_at(t);
            // A radio's TX is shorter than a sample: its mean current over
            // the interval, not its state at the instant.
            for (i, r) in loads.radios.iter_mut().zip(&mut self.platform.radios) {
                *i = r.power.take_mean(t);
            }
            let motor = self.platform.motors.state;
            if let Some((c, meter)) = &mut self.cluster {
                // The counters as the cores stand (within a quantum of t).
                let p = meter.sample(Totals::of(c, &self.mem, t), t);
                self.power.set_cluster_power(p);
            }
            let sample = self.power.sample(t, &loads, &motor).inspect_err(|e| {
                if let PowerError::BatteryEmpty { t, .. } = e {
                    self.battery_empty_at = Some(*t);
                }
            })?;
            self.platform.stm32.crtp_power(PowerTelemetry {
                vbat: sample.v_battery.0,
                soc: sample.soc,
                low_battery: sample.low_battery,
                i_battery: sample.i_battery.0,
                i_vcc: sample.i_vcc.0,
                p_motor: sample.selected_output().power.0,
                p_cluster: sample.cluster.map(|c| c.total_w()),
            });
            self.platform.battery_low = sample.low_battery;
            self.platform.motors.speed_cap = self.power.motor_speed_cap();
        }
        Ok(())
    }

    /// Takes the samples due at `now` ([`Self::take_samples`]). With
    /// `battery_empty = "end"` the battery's cut-off ends the flight as a
    /// firmware exit does (the world is told STOP, the run succeeds):
    /// `Ok(true)`. Otherwise the cut-off is MESSY's error.
    fn sample_or_cut_off(&mut self, cfg: &KernelConfig, now: Picos) -> Result<bool, KernelError> {
        match self.take_samples(now) {
            Err(KernelError::Power(PowerError::BatteryEmpty { .. }))
                if cfg.run.battery_empty == OnEmpty::End =>
            {
                self.exit_code = Some(0);
                // The cut-off falls on a 1 ms sample, often inside a device
                // delay: STOP where platform and world agree (at `now` the
                // estimate would be off by the rest of the delay, or by the
                // iteration delays the world had not been sent yet).
                let at = self.platform.settle(now).map_err(KernelError::Device)?;
                let end = self
                    .platform
                    .end_session(at)
                    .map_err(KernelError::Device)?
                    .unwrap_or(at)
                    .max(at);
                self.end_time = end;
                // The motors' stop after STOP, as at a firmware exit.
                self.take_samples(end)?;
                Ok(true)
            }
            other => other.map(|()| false),
        }
    }

    fn drain_device_console(&mut self) {
        for line in self.platform.console.drain(..) {
            self.console.write_str(&line);
        }
    }

    /// The start file's default trap handler exits with 128 + mcause
    /// (`sim-core/firmware/src/start.S`): name the trap instead of leaving
    /// a bare exit status.
    fn default_trap(&self, code: i32) -> Option<KernelError> {
        let cause = self.cpu.csr(0x342)?; // mcause
        if cause & 0x8000_0000 != 0 || code != 128 + (cause & 0x7f) as i32 {
            return None;
        }
        let mepc = self.cpu.csr(0x341).unwrap_or(0);
        let mtval = self.cpu.csr(0x343).unwrap_or(0);
        Some(KernelError::Core(format!(
            "the firmware trapped: {} (mcause {cause}) at pc {mepc:#010x}, mtval {mtval:#010x}",
            crate::iss::cpu::cause_name(cause)
        )))
    }

    fn main_loop(&mut self, cfg: &KernelConfig) -> Result<(), KernelError> {
        let mut progress = crate::kernel::console::Progress::new(cfg.progress);
        loop {
            let next_sample = self.power.next_sample_time();
            let limit = match self.platform.next_event() {
                Some(t) => t.min(next_sample),
                None => next_sample,
            };
            if let Some(max) = cfg.max_time {
                if self.cpu.now() >= max {
                    return Err(KernelError::Core(format!(
                        "the firmware did not finish within {max} of simulated time"
                    )));
                }
            }
            // The radios' interrupt request drives mip.MEIP (the platform
            // asks the ISS to stop whenever it changes, so the line follows
            // at the access or event that changed it).
            let irq = self.platform.irq_level();
            self.platform.irq_line = irq;
            self.cpu.set_external_irq(irq);
            let stop = match &mut self.cluster {
                Some((c, _)) => {
                    let (mem, code) = (&mut self.mem, &mut self.code);
                    c.run_until(&mut self.cpu, mem, code, &mut self.platform, limit)
                }
                None => {
                    self.cpu
                        .run_until(&mut self.mem, &mut self.code, &mut self.platform, limit)
                }
            };
            self.drain_device_console();
            let now = self.cpu.now();
            match stop {
                StopReason::Limit
                | StopReason::Event
                | StopReason::DeviceRequest
                | StopReason::Wait => {}
                StopReason::Exit { code } => {
                    self.exit_code = Some(code);
                    let trap = self.default_trap(code);
                    // A firmware that ends with the world session open says
                    // STOP through the platform (docs/SWARM.md §4.1).
                    let end = match self.platform.end_session(now) {
                        Ok(end) => end.unwrap_or(now).max(now),
                        Err(e) => {
                            self.end_time = now;
                            self.take_samples(now)?;
                            return Err(trap.unwrap_or(KernelError::Device(e)));
                        }
                    };
                    self.end_time = end;
                    self.take_samples(end)?;
                    return match trap {
                        Some(e) => Err(e),
                        None => Ok(()),
                    };
                }
                StopReason::Fatal(e) => {
                    if let Some(dev) = self.platform.failure.take() {
                        return Err(KernelError::Device(dev));
                    }
                    return Err(KernelError::Core(e.to_string()));
                }
                StopReason::Idle => {
                    return Err(KernelError::Core(format!(
                        "the core waits at pc {:#010x} for something that can never happen \
                         (a status register no device will change, or wfi with no interrupt)",
                        self.cpu.pc()
                    )))
                }
                StopReason::InstructionLimit => {
                    return Err(KernelError::Core("instruction limit reached".into()))
                }
                StopReason::Breakpoint { pc } => {
                    return Err(KernelError::Core(format!("breakpoint at {pc:#010x}")))
                }
            }
            if self.platform.next_event().is_some_and(|t| t <= now) {
                self.platform.handle_events(now)?;
                self.drain_device_console();
            }
            if self.sample_or_cut_off(cfg, now)? {
                return Ok(());
            }
            progress.update(now, &self.power);
        }
    }

    fn finish(
        mut self,
        cfg: &KernelConfig,
        wall: Instant,
        result: Result<(), KernelError>,
    ) -> RunOutcome {
        let mut error = result.err();
        if let Err(e) = self.console.flush() {
            error.get_or_insert(KernelError::Io(e));
        }
        if let Err(e) = self.cpu.flush_console() {
            error.get_or_insert(KernelError::Io(e));
        }
        if let Some((c, _)) = &mut self.cluster {
            if let Err(e) = c.flush_console() {
                error.get_or_insert(KernelError::Io(e));
            }
        }
        if let Err(e) = self.power.finish_logs() {
            error.get_or_insert(KernelError::Power(e));
        }
        if let Err(e) = self.platform.stm32.flush_crtp() {
            error.get_or_insert(KernelError::Io(e));
        }
        if let (Some(map), Some(dir)) = (&self.map, &cfg.out_dir) {
            if let Err(e) = map.dump(&self.mem, dir) {
                error.get_or_insert(e);
            }
        }
        let now = self.cpu.now().max(self.end_time);
        let time = self.platform.time.report(now);
        if let Some(dir) = &cfg.out_dir {
            // The world's time base for the platform's logs (run.mcap).
            if let Err(e) = self.platform.time.time_map().write(dir, cfg.run.series) {
                error.get_or_insert(KernelError::Io(e));
            }
        }
        let summary = Summary::build(
            cfg,
            &self.cpu,
            &self.platform,
            &self.power,
            time,
            self.exit_code,
            error.as_ref(),
            wall.elapsed().as_secs_f64(),
        );
        let mut summary = summary;
        summary.energy_j.cluster = self.cluster.as_ref().map(|(_, meter)| meter.energy_j);
        // §13's `nn` block: a firmware with the counters on a platform with
        // a cluster (the counters without a cluster would be all zero).
        if let (Some(sym), Some(section), Some(energy)) = (
            &self.nn_stats,
            &cfg.platform.cluster,
            summary.energy_j.cluster,
        ) {
            let fc_hz = cfg.platform.core.frequency;
            match sym.read(&self.mem, fc_hz, section.cores, section.mhz, energy) {
                Ok(nn) => summary.nn = Some(nn),
                Err(e) => {
                    summary.completed = false;
                    summary.error.get_or_insert(e.to_string());
                    error.get_or_insert(e);
                }
            }
        }
        summary.battery.empty_at_s = self.battery_empty_at.map(|t| t.as_secs_f64());
        if let Some(dir) = &cfg.out_dir {
            if let Err(e) = summary.write(&dir.join("summary.json")) {
                error.get_or_insert(KernelError::Io(e));
            }
        }
        RunOutcome { summary, error }
    }
}

/// Reads a firmware file with a clear error.
pub fn read_firmware(path: &Path) -> Result<Vec<u8>, KernelError> {
    std::fs::read(path).map_err(|e| {
        KernelError::Io(std::io::Error::new(
            e.kind(),
            format!("cannot read firmware {}: {e}", path.display()),
        ))
    })
}
