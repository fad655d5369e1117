//! `summary.json` (DESIGN.md §6): the figures of one run.

use std::io;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{KernelConfig, KernelError};
use crate::bus::Platform;
use crate::iss::Cpu;
use crate::peripherals::WorldLink;
use crate::power::{PowerModelKind, PowerNetwork};
use crate::sync::TimeReport;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatterySummary {
    pub model: String,
    pub soc_end: f64,
    pub low_battery: bool,
    /// Platform time (s) at which the SOC reached `soc_end`, if it did
    /// (with `battery_empty = "end"` the flight ended there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub empty_at_s: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnergySummary {
    pub empirical: f64,
    pub dandrea: f64,
    pub stolaroff: f64,
    /// Energy drawn from the battery (selected motor model + VCC through the LDO).
    pub total: f64,
    /// The UWB radio's energy at the VCC bus (platforms that report their
    /// radios only, see `KernelConfig::reports_radios`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uwb: Option<f64>,
    /// The P2P radio's energy at the VCC bus (same).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p2p: Option<f64>,
    /// The GAP8 cluster's energy (platforms with a cluster only;
    /// `crate::cluster::power`, the sum of its `power.csv` columns).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster: Option<f64>,
}

/// What each radio did (platforms that report their radios only).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RadiosSummary {
    pub uwb: RadioSummary,
    pub p2p: RadioSummary,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RadioSummary {
    /// Switched on (INIT) during the run.
    pub used: bool,
    pub frames_sent: u64,
    pub frames_received: u64,
    /// Frames that ended while the receiver was off.
    pub frames_missed: u64,
    /// Frames lost to a full receive FIFO.
    pub rx_overruns: u64,
    pub energy_j: f64,
}

/// The contract of DESIGN.md §6, plus a few figures that help reading it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub completed: bool,
    pub exit_code: i32,
    /// Why the run failed, if it did.
    pub error: Option<String>,
    pub targets_total: u32,
    pub targets_reached: u32,
    pub targets_bypassed: u32,
    /// SET_TARGETs replaced by the next one before reached or bypassed
    /// (`Stm32Stats::targets_replaced`); absent in older summaries.
    #[serde(default)]
    pub targets_replaced: u32,
    pub targets_skipped_low_battery: u32,
    pub platform_time_s: f64,
    /// The world's time at STOP (null when the run did not get there).
    pub world_time_s: Option<f64>,
    pub world_time_estimate_s: f64,
    pub estimate_error_pct: Option<f64>,
    pub sensors_offset_ms: f64,
    pub sim_off_accum_ms: f64,
    pub stop_time_ms: Option<u64>,
    pub instructions: u64,
    pub cycles: u64,
    pub wall_time_s: f64,
    pub realtime_factor: f64,
    pub battery: BatterySummary,
    pub energy_j: EnergySummary,
    pub power_model: String,
    pub sync: String,
    pub timestep_ms: u64,
    pub image_encoding: String,
    /// µs the link polled for each reply before sleeping (0: off).
    #[serde(default)]
    pub busy_poll_us: u64,
    pub frames: u64,
    pub pid_iterations: u64,
    pub messages: u64,
    pub bytes_to_world: u64,
    pub bytes_to_platform: u64,
    /// Contacts begun in the world (GET_STATE before STOP; null if unknown).
    pub collisions: Option<u64>,
    /// The drone this platform flew in a world with several (`--drone`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drone: Option<String>,
    /// The radios (platforms that report their radios only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radios: Option<RadiosSummary>,
    /// Distinct gates the drone's centre passed through (the world's STOP
    /// reply, DESIGN.md §10; absent when the world has no gates).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gates_passed: Option<u64>,
    /// Gates in the world file (`--gates-total`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gates_total: Option<u64>,
    /// Flow mode (`stm32.position_source = flow`): how far the STM32's
    /// dead-reckoned x, y strayed from the world's GPS.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flow_drift: Option<FlowDriftSummary>,
    /// The network's inferences (DESIGN.md §13; a firmware with
    /// `nn_race_stats` on a platform with a cluster only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nn: Option<super::NnSummary>,
    /// The AI deck as a load on the battery (a platform with a cluster
    /// only; docs/AIDECK_POWER.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deck: Option<crate::power::deck::DeckSummary>,
    /// How a paced live CRTP link held the wall clock (DESIGN.md §20,
    /// docs/CFLIB.md "Pacing"); absent when unpaced (`pace = 0`, a replay,
    /// no CRTP link).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pacing: Option<crate::peripherals::stm32::crtp::PacingSummary>,
}

/// The flow estimate's horizontal distance from the GPS over a run (m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlowDriftSummary {
    /// At the last sensor read.
    pub final_m: f64,
    pub max_m: f64,
    pub mean_m: f64,
}

impl Summary {
    /// The summary of a run that could not start (bad firmware or platform).
    pub fn failed_before_start(cfg: &KernelConfig) -> Summary {
        Summary {
            completed: false,
            exit_code: 1,
            error: None,
            targets_total: 0,
            targets_reached: 0,
            targets_bypassed: 0,
            targets_replaced: 0,
            targets_skipped_low_battery: 0,
            platform_time_s: 0.0,
            world_time_s: None,
            world_time_estimate_s: 0.0,
            estimate_error_pct: None,
            sensors_offset_ms: 0.0,
            sim_off_accum_ms: 0.0,
            stop_time_ms: None,
            instructions: 0,
            cycles: 0,
            wall_time_s: 0.0,
            realtime_factor: 0.0,
            battery: BatterySummary {
                model: cfg
                    .run
                    .battery
                    .map(|b| b.to_string())
                    .unwrap_or_else(|| cfg.platform.battery().model.to_string()),
                soc_end: cfg.platform.battery().soc_init / 100.0,
                low_battery: false,
                empty_at_s: None,
            },
            energy_j: EnergySummary {
                empirical: 0.0,
                dandrea: 0.0,
                stolaroff: 0.0,
                total: 0.0,
                uwb: None,
                p2p: None,
                cluster: None,
            },
            power_model: cfg.run.power_model.name().to_string(),
            sync: format!("{:?}", cfg.run.sync).to_lowercase(),
            timestep_ms: 0,
            image_encoding: cfg.image_encoding.as_str().to_string(),
            busy_poll_us: cfg.busy_poll_us,
            frames: 0,
            pid_iterations: 0,
            messages: 0,
            bytes_to_world: 0,
            bytes_to_platform: 0,
            collisions: None,
            drone: cfg.drone.clone(),
            radios: None,
            gates_passed: None,
            gates_total: cfg.gates_total,
            flow_drift: None,
            nn: None,
            deck: None,
            pacing: None,
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn build<W: WorldLink>(
        cfg: &KernelConfig,
        cpu: &Cpu,
        platform: &Platform<W>,
        power: &PowerNetwork,
        time: TimeReport,
        exit_code: Option<i32>,
        error: Option<&KernelError>,
        wall_time_s: f64,
    ) -> Summary {
        let mut s = Summary::failed_before_start(cfg);
        let stats = &platform.stm32.stats;
        let link = platform.world.stats();
        let energy = power.energy();
        let platform_time_s = time.platform_time.as_secs_f64();
        let stop = platform.session.stop_report();
        let world_time_s = stop.map(|s| s.time_s);
        s.exit_code = match (error, exit_code) {
            (None, Some(code)) => code,
            (None, None) => 1,
            (Some(_), Some(code)) if code != 0 => code,
            (Some(_), _) => 1,
        };
        s.error = error.map(|e| e.to_string());
        s.completed = error.is_none() && exit_code == Some(0) && stop.is_some();
        s.targets_total = stats.targets_total;
        s.targets_reached = stats.targets_reached;
        s.targets_bypassed = stats.targets_bypassed;
        s.targets_replaced = stats.targets_replaced;
        s.targets_skipped_low_battery = stats.targets_skipped_low_battery;
        s.platform_time_s = platform_time_s;
        s.world_time_s = world_time_s;
        s.world_time_estimate_s = time.world_time_estimate_ms / 1000.0;
        s.estimate_error_pct = world_time_s
            .filter(|w| *w > 0.0)
            .map(|w| (s.world_time_estimate_s - w) / w * 100.0);
        s.sensors_offset_ms = time.sensors_offset_ms;
        s.sim_off_accum_ms = time.sim_off_accum_ms;
        s.stop_time_ms = stop.map(|s| s.stop_time_ms);
        let core = cpu.stats();
        s.instructions = core.instructions;
        s.cycles = core.cycles;
        s.wall_time_s = wall_time_s;
        s.realtime_factor = if wall_time_s > 0.0 {
            platform_time_s / wall_time_s
        } else {
            0.0
        };
        let battery = power.battery();
        s.battery = BatterySummary {
            model: battery.model().to_string(),
            soc_end: battery.soc(),
            low_battery: power.low_battery(),
            empty_at_s: None,
        };
        s.energy_j = EnergySummary {
            empirical: energy.model(PowerModelKind::Empirical).0,
            dandrea: energy.model(PowerModelKind::DAndrea).0,
            stolaroff: energy.model(PowerModelKind::Stolaroff).0,
            total: energy.battery.0,
            uwb: None,
            p2p: None,
            cluster: None,
        };
        if cfg.reports_radios() {
            s.energy_j.uwb = Some(energy.radios[0].0);
            s.energy_j.p2p = Some(energy.radios[1].0);
            let r = |i: usize| {
                let d = &platform.radios[i];
                RadioSummary {
                    used: d.switched_on(),
                    frames_sent: d.stats.frames_sent,
                    frames_received: d.stats.frames_received,
                    frames_missed: d.stats.frames_missed,
                    rx_overruns: d.stats.rx_overruns,
                    energy_j: energy.radios[i].0,
                }
            };
            s.radios = Some(RadiosSummary {
                uwb: r(0),
                p2p: r(1),
            });
        }
        s.timestep_ms = platform.time.timestep().0;
        s.frames = platform.camera.frames;
        s.pid_iterations = stats.pid_iterations;
        s.messages = link.messages;
        s.bytes_to_world = link.bytes_to_world;
        s.bytes_to_platform = link.bytes_to_platform;
        s.collisions = stop.and_then(|s| s.collisions);
        s.gates_passed = stop.and_then(|s| s.gates_passed);
        if cfg.platform.cluster.is_some() {
            s.deck = Some(crate::power::deck::DeckSummary::new(
                energy.deck.0,
                energy.battery.0,
                power.deck_charge_ah(),
                battery.capacity_ah(),
                (cfg.platform.battery().soc_init / 100.0, battery.soc()),
                platform_time_s,
            ));
        }
        s.pacing = platform.stm32.crtp().and_then(|c| c.pacing());
        s.flow_drift = platform.stm32.flow_drift().map(|d| FlowDriftSummary {
            final_m: d.last_m,
            max_m: d.max_m,
            mean_m: d.mean_m(),
        });
        s
    }

    /// Writes the summary as pretty JSON (atomically: a temporary file
    /// renamed, so a reader never sees half a summary).
    pub fn write(&self, path: &Path) -> io::Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(io::Error::other)?;
        let tmp = path.with_extension("json.tmp");
        std::fs::write(&tmp, text + "\n")?;
        std::fs::rename(&tmp, path)
    }
}
