//! The power network of §4.5 (MESSY's power side):
//!
//! ```text
//!  core ─┐ (converters, ideal by default)
//!  camera ┤
//!  stm32 ─┼─ VCC bus 3.0 V ── LDO (η = Vout/Vin, clamped) ──┐
//!  uwb ───┤                                                  │
//!  p2p ───┘                                                  ├── battery (SOC polynomials)
//!  motors ── motor bus at the battery voltage (η = 1) ───────┘
//! ```
//!
//! [`PowerNetwork::sample`] is called every 1 ms of simulated time (MESSY's
//! default resolution) with the devices' power states ([`Loads`]) and the
//! drone's state for the motor models ([`MotorState`]). It computes the three
//! motor models, drains the battery with the selected one plus the VCC
//! current seen through the LDO, integrates energies and raises the
//! low-battery event. [`PowerNetwork::advance_to`] takes every 1 ms sample up
//! to a time at once, holding the loads.
//!
//! Ordering within a sample follows MESSY's one-step port delays: the LDO's
//! efficiency and the motor-bus voltage use the battery's terminal voltage of
//! the previous sample (at the first sample, `v_oc` at the initial SOC).

pub mod battery;
pub mod bus;
pub mod converter;
pub mod csv_line;
pub mod deck;
pub mod log;
pub mod models;
pub mod motor_drive;
pub mod operating_point;
pub mod sag;
pub mod sample;

use std::fmt;
use std::path::PathBuf;

use thiserror::Error;

use crate::config::{BusKind, PlatformConfig, RunConfig};
use crate::units::{Amps, Picos, Volts};

use battery::{Battery, BatteryModel};
use bus::PowerBus;
use converter::{ldo_efficiency, Converter};
use deck::DeckSupply;
pub use log::PowerLogger;
use models::MotorModels;
pub use models::{MotorState, PowerModelKind};
pub use sample::{CoreState, Energy, Loads, PowerSample, SensorState, RADIOS};

/// A name reduced to lower-case letters and digits, so that `D'Andrea`,
/// `dandrea` and `LPHD-6520030` compare as their configuration names do.
fn name_key(s: &str) -> String {
    s.chars()
        .filter(char::is_ascii_alphanumeric)
        .collect::<String>()
        .to_ascii_lowercase()
}

/// Resistance in ohms.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Ohms(pub f64);

/// Power in watts.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Watts(pub f64);

/// Energy in joules.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Joules(pub f64);

/// The power sampling period: 1 ms (§4.5, MESSY's `SC_MS` resolution).
pub const SAMPLE_PERIOD: Picos = Picos::from_ms(1);

/// What can go wrong in the power network.
#[derive(Debug, Error)]
pub enum PowerError {
    /// The battery reached `soc_end`: MESSY stops the simulation there.
    #[error(
        "battery {part} is empty at t = {t}: SOC {soc_pct:.3} % reached soc_end {soc_end_pct} % \
         while drawing {current_a:.3} A; the run needs more charge than the battery holds \
         (choose a larger battery or a shorter flight)"
    )]
    BatteryEmpty {
        part: &'static str,
        t: Picos,
        soc_pct: f64,
        soc_end_pct: f64,
        current_a: f64,
    },
    /// A sample earlier than the previous one.
    #[error("power sample at {t} is earlier than the previous one at {last}")]
    TimeWentBack { t: Picos, last: Picos },
    /// The platform description cannot be turned into a network.
    #[error("platform: {0}")]
    Platform(String),
    /// A log file could not be created or flushed.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Resolved per-state currents of the VCC loads.
#[derive(Debug, Clone, Copy)]
struct StateCurrents {
    core: [Amps; 2],
    camera: [Amps; 3],
    stm32: [Amps; 3],
}

/// The power network of the Crazyflie (see the module documentation).
pub struct PowerNetwork {
    vcc_voltage: Volts,
    /// Loads on the VCC bus: core, camera, stm32, other VCC sensors, then
    /// the two radios (last, so a radio drawing nothing leaves every sum
    /// bit for bit as without radios).
    vcc: PowerBus,
    /// Load currents in `vcc`'s order (the first three change per sample).
    vcc_load_currents: Vec<Amps>,
    vcc_bus_currents: Vec<Amps>,
    states: StateCurrents,
    /// Other sensors on the motor bus (at their idle current) with their converters.
    battery_side_idle: Vec<(Amps, Converter)>,
    motor_converter: Converter,
    ldo: Converter,
    battery: Battery,
    models: MotorModels,
    selected: PowerModelKind,
    last_t: Picos,
    next_sample: Picos,
    v_terminal: Volts,
    energy: Energy,
    low_reported: bool,
    empty_reported: bool,
    logger: Option<PowerLogger>,
    last: Option<PowerSample>,
    /// The cluster's power for the next sample ([`PowerNetwork::set_cluster_power`]).
    cluster: Option<crate::cluster::power::ClusterPower>,
    /// The AI deck's supply of the cluster, on a platform with a cluster
    /// (`deck`): the cluster's power drawn from the battery.
    deck: Option<DeckSupply>,
    /// The deck's battery current at the previous sample, A, and the charge
    /// it drew so far, Ah (integrated as the battery integrates).
    deck_i_prev: f64,
    deck_charge_ah: f64,
}

impl fmt::Debug for PowerNetwork {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PowerNetwork")
            .field("battery", &self.battery)
            .field("selected", &self.selected)
            .field("last_t", &self.last_t)
            .field("energy", &self.energy)
            .finish_non_exhaustive()
    }
}

fn state_current(platform: &PlatformConfig, sensor: &str, state: &str) -> Result<Amps, PowerError> {
    platform
        .sensor(sensor)
        .and_then(|s| s.state(state))
        .map(|s| s.current())
        .ok_or_else(|| PowerError::Platform(format!("sensor {sensor} has no {state} state")))
}

impl PowerNetwork {
    /// Builds the network of `platform` with the battery and motor model of
    /// `run` (the platform file's battery when `run.battery` is `None`).
    pub fn new(platform: &PlatformConfig, run: &RunConfig) -> Result<PowerNetwork, PowerError> {
        platform.validate().map_err(PowerError::Platform)?;
        let vcc_voltage = platform.vcc();
        let mut vcc = PowerBus::new();
        vcc.attach(
            "core",
            Volts(platform.core.vref),
            platform.core_converter().map_err(PowerError::Platform)?,
        );
        let mut vcc_load_currents = vec![Amps(0.0); 3];
        let mut battery_side_idle = Vec::new();
        let mut motor_converter = Converter::ideal();
        // camera and stm32 first, in that order, then the rest by name
        // (BTreeMap order: deterministic).
        let names = ["camera", "stm32"].into_iter().chain(
            platform
                .peripherals
                .sensors
                .keys()
                .map(String::as_str)
                .filter(|n| *n != "camera" && *n != "stm32" && !RADIOS.contains(n)),
        );
        for name in names {
            let s = platform
                .sensor(name)
                .ok_or_else(|| PowerError::Platform(format!("no sensor {name}")))?;
            let converter = s.converter().map_err(PowerError::Platform)?;
            if name == "motors" {
                motor_converter = converter;
                continue;
            }
            let idle = if s.power {
                s.state("idle").map_or(Amps(0.0), |st| st.current())
            } else {
                Amps(0.0)
            };
            match s.bus {
                BusKind::Vcc => {
                    vcc.attach(name, Volts(s.vref.unwrap_or(vcc_voltage.0)), converter);
                    if name != "camera" && name != "stm32" {
                        vcc_load_currents.push(idle);
                    }
                }
                BusKind::Battery => battery_side_idle.push((idle, converter)),
            }
        }
        // The radios: always on the bus, drawing what the radio device says
        // (nothing until it is switched on).
        for name in RADIOS {
            let (vref, converter) = match platform.sensor(name) {
                Some(s) => (
                    Volts(s.vref.unwrap_or(vcc_voltage.0)),
                    s.converter().map_err(PowerError::Platform)?,
                ),
                None => (vcc_voltage, Converter::ideal()),
            };
            vcc.attach(name, vref, converter);
            vcc_load_currents.push(Amps(0.0));
        }
        let core_state = |name: &str| {
            platform
                .core
                .states
                .get(name)
                .map(|s| s.current())
                .ok_or_else(|| PowerError::Platform(format!("core has no {name} state")))
        };
        let states = StateCurrents {
            core: [core_state("running")?, core_state("sleeping")?],
            camera: [
                state_current(platform, "camera", "read")?,
                state_current(platform, "camera", "write")?,
                state_current(platform, "camera", "idle")?,
            ],
            stm32: [
                state_current(platform, "stm32", "read")?,
                state_current(platform, "stm32", "write")?,
                state_current(platform, "stm32", "idle")?,
            ],
        };
        let b = platform.battery();
        let model: BatteryModel = run.battery.unwrap_or(b.model);
        let battery = Battery::new(
            model,
            b.soc_init / 100.0,
            b.soc_end / 100.0,
            run.soc_low.unwrap_or(b.soc_low) / 100.0,
        )
        .with_axis(run.battery_curve)
        .with_load(run.battery_load);
        let ldo = b.converter().map_err(PowerError::Platform)?;
        let v_terminal = battery.voltage(Amps(0.0));
        let vcc_bus_currents = vec![Amps(0.0); vcc_load_currents.len()];
        Ok(PowerNetwork {
            vcc_voltage,
            vcc,
            vcc_load_currents,
            vcc_bus_currents,
            states,
            battery_side_idle,
            motor_converter,
            ldo,
            battery,
            models: MotorModels::new(model.mass_kg(), &run.models),
            selected: run.power_model,
            last_t: Picos::ZERO,
            next_sample: SAMPLE_PERIOD,
            v_terminal,
            energy: Energy::default(),
            low_reported: false,
            empty_reported: false,
            logger: None,
            last: None,
            cluster: None,
            deck: DeckSupply::of(platform).map_err(PowerError::Platform)?,
            deck_i_prev: 0.0,
            deck_charge_ah: 0.0,
        })
    }

    /// The cluster's mean power over the interval the next sample closes
    /// (the kernel's hook; logged in `power.csv`'s cluster columns).
    pub fn set_cluster_power(&mut self, p: crate::cluster::power::ClusterPower) {
        self.cluster = Some(p);
    }

    /// The charge the AI deck drew from the battery so far, Ah (0 without
    /// a cluster).
    pub fn deck_charge_ah(&self) -> f64 {
        self.deck_charge_ah
    }

    /// Logs every sample to `logger` from now on.
    pub fn attach_logger(&mut self, logger: PowerLogger) {
        self.logger = Some(logger);
    }

    /// The battery.
    pub fn battery(&self) -> &Battery {
        &self.battery
    }

    /// The highest motor speed (rad/s) the battery's terminal voltage of the
    /// last sample allows ([`motor_drive`]), with `battery_load = "sag"`;
    /// `None` with the thesis's battery (the motors' 600 rad/s only).
    pub fn motor_speed_cap(&self) -> Option<f64> {
        match self.battery.load() {
            sag::BatteryLoad::Thesis => None,
            sag::BatteryLoad::Sag => Some(motor_drive::speed_cap(self.v_terminal)),
        }
    }

    /// The motor models (with the drone's total mass).
    pub fn models(&self) -> &MotorModels {
        &self.models
    }

    /// The model that drains the battery.
    pub fn selected(&self) -> PowerModelKind {
        self.selected
    }

    /// Energies so far.
    pub fn energy(&self) -> Energy {
        self.energy
    }

    /// Whether the low-battery event has been raised (BATTERY_LOW).
    pub fn low_battery(&self) -> bool {
        self.low_reported
    }

    /// The latest sample (also after a [`PowerError::BatteryEmpty`]).
    pub fn last_sample(&self) -> Option<&PowerSample> {
        self.last.as_ref()
    }

    /// When [`PowerNetwork::advance_to`] takes its next sample.
    pub fn next_sample_time(&self) -> Picos {
        self.next_sample
    }

    /// Takes one sample at `t`, integrating since the previous one (or
    /// since 0). Logs it if a logger is attached. Returns
    /// [`PowerError::BatteryEmpty`] at the sample where the SOC reaches
    /// `soc_end` (the sample is logged and kept in [`Self::last_sample`]).
    pub fn sample(
        &mut self,
        t: Picos,
        loads: &Loads,
        motor: &MotorState,
    ) -> Result<PowerSample, PowerError> {
        if t < self.last_t {
            return Err(PowerError::TimeWentBack {
                t,
                last: self.last_t,
            });
        }
        let dt = t - self.last_t;
        let dt_s = dt.as_secs_f64();
        let v_prev = self.v_terminal;

        // VCC bus: the three devices' states, the other loads at idle.
        self.vcc_load_currents[0] = self.states.core[match loads.core {
            CoreState::Running => 0,
            CoreState::Sleeping => 1,
        }];
        self.vcc_load_currents[1] = self.states.camera[loads.camera.index()];
        self.vcc_load_currents[2] = self.states.stm32[loads.stm32.index()];
        let n = self.vcc_load_currents.len();
        self.vcc_load_currents[n - 2] = loads.radios[0];
        self.vcc_load_currents[n - 1] = loads.radios[1];
        let i_vcc = self.vcc.draw(
            self.vcc_voltage,
            &self.vcc_load_currents,
            &mut self.vcc_bus_currents,
        );
        // The AI deck's cluster power, drawn from the battery's rail.
        let p_deck = match (&self.deck, &self.cluster) {
            (Some(_), Some(c)) => c.total_w(),
            _ => 0.0,
        };
        let deck_current = |v: Volts| self.deck.as_ref().map(|d| d.battery_current(p_deck, v).0);
        // The battery-side currents at a bus voltage `v` (the deck's
        // added only on a platform with one, so that every other sum is
        // the thesis's bit for bit).
        let currents = |v: Volts| {
            let i_vcc_battery = self.ldo.input_current(i_vcc, self.vcc_voltage, v);
            let models = self.models.evaluate(motor, v);
            let i_motor =
                self.motor_converter
                    .input_current(models[self.selected.index()].current, v, v);
            let i_battery_side: f64 = self
                .battery_side_idle
                .iter()
                .map(|(i, c)| c.input_current(*i, v, v).0)
                .sum();
            let i_battery_side = match deck_current(v) {
                Some(i) => i_battery_side + i,
                None => i_battery_side,
            };
            (i_vcc_battery, models, i_motor, i_battery_side)
        };
        // The thesis's network takes the loads at the previous sample's
        // voltage (its milliohm resistances make that exact to the µV);
        // under sag the battery's operating point is solved
        // (`operating_point`: the explicit step diverges there).
        let (v_bus, starved_at) = match self.battery.load() {
            sag::BatteryLoad::Thesis => (v_prev, None),
            sag::BatteryLoad::Sag => {
                let op = operating_point::solve(self.battery.v_oc(), self.battery.r_s(), |v| {
                    let (a, _, b, c) = currents(v);
                    Amps(a.0 + b.0 + c)
                });
                (op.v, op.starved.then_some(op.i))
            }
        };
        let ldo_efficiency = match self.ldo.kind() {
            converter::Efficiency::Ldo => ldo_efficiency(self.vcc_voltage, v_bus),
            _ => self.ldo.efficiency(i_vcc, self.vcc_voltage, v_bus),
        };
        let (i_vcc_battery, models, mut i_motor, i_battery_side) = currents(v_bus);
        let i_deck = deck_current(v_bus);
        if let Some(i_max) = starved_at {
            // The battery gives its maximum power; the motors, last on the
            // bus, get what the electronics leave (their speed cap, from
            // the voltage, is what the world feels).
            i_motor = Amps((i_max.0 - i_vcc_battery.0 - i_battery_side).max(0.0));
        }
        let i_other = Amps(
            self.vcc_bus_currents[3..n - 2]
                .iter()
                .map(|i| i.0)
                .sum::<f64>()
                + i_battery_side,
        );
        let i_radios = [self.vcc_bus_currents[n - 2], self.vcc_bus_currents[n - 1]];
        let i_battery = Amps(i_vcc_battery.0 + i_motor.0 + i_battery_side);

        self.battery.step(i_battery, dt_s);
        let v_battery = self.battery.voltage(i_battery);
        self.v_terminal = v_battery;

        for (e, out) in self.energy.models.iter_mut().zip(models.iter()) {
            e.0 += out.power.0 * dt_s;
        }
        self.energy.vcc.0 += self.vcc_voltage.0 * i_vcc.0 * dt_s;
        for (e, i) in self.energy.radios.iter_mut().zip(i_radios) {
            e.0 += self.vcc_voltage.0 * i.0 * dt_s;
        }
        self.energy.battery.0 += v_battery.0 * i_battery.0 * dt_s;
        if let Some(i_deck) = i_deck {
            self.energy.deck.0 += v_battery.0 * i_deck * dt_s;
            self.deck_charge_ah += (i_deck + self.deck_i_prev) * dt_s / (2.0 * 3600.0);
            self.deck_i_prev = i_deck;
        }

        let low_battery = self.battery.is_low();
        let low_battery_crossed = low_battery && !self.low_reported;
        if low_battery_crossed {
            self.low_reported = true;
            tracing::warn!(
                t = %t,
                soc = self.battery.soc(),
                "battery low: SOC under the BATTERY_LOW threshold"
            );
        }
        let sample = PowerSample {
            t,
            dt,
            i_core: self.vcc_bus_currents[0],
            i_camera: self.vcc_bus_currents[1],
            i_stm32: self.vcc_bus_currents[2],
            i_other,
            i_radios,
            i_vcc,
            ldo_efficiency,
            i_vcc_battery,
            i_motor,
            i_battery,
            v_oc: self.battery.v_oc(),
            v_battery,
            soc: self.battery.soc(),
            motor: *motor,
            models,
            selected: self.selected,
            low_battery,
            low_battery_crossed,
            cluster: self.cluster.take(),
        };
        self.last_t = t;
        self.next_sample = Picos((t.0 / SAMPLE_PERIOD.0 + 1) * SAMPLE_PERIOD.0);
        self.last = Some(sample);
        if let Some(logger) = &mut self.logger {
            logger.log(&sample)?;
        }
        if self.battery.is_empty() && !self.empty_reported {
            self.empty_reported = true;
            if let Some(logger) = &mut self.logger {
                logger.flush()?;
            }
            return Err(PowerError::BatteryEmpty {
                part: self.battery.model().part(),
                t,
                soc_pct: self.battery.soc() * 100.0,
                soc_end_pct: self.battery.soc_end() * 100.0,
                current_a: i_battery.0,
            });
        }
        Ok(sample)
    }

    /// Takes every 1 ms sample due up to and including `t`, holding `loads`
    /// and `motor`; returns the last one taken (if any).
    pub fn advance_to(
        &mut self,
        t: Picos,
        loads: &Loads,
        motor: &MotorState,
    ) -> Result<Option<PowerSample>, PowerError> {
        let mut last = None;
        while self.next_sample <= t {
            last = Some(self.sample(self.next_sample, loads, motor)?);
        }
        Ok(last)
    }

    /// Flushes the logs.
    pub fn flush(&mut self) -> Result<(), PowerError> {
        match &mut self.logger {
            Some(logger) => logger.flush(),
            None => Ok(()),
        }
    }

    /// Ends the logs (call at the end of a run, also after an error;
    /// dropping the network ends them too, ignoring errors).
    pub fn finish_logs(&mut self) -> Result<(), PowerError> {
        match &mut self.logger {
            Some(logger) => logger.finish(),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn network() -> PowerNetwork {
        PowerNetwork::new(&PlatformConfig::default_crazyflie(), &RunConfig::default()).unwrap()
    }

    #[test]
    fn idle_vcc_current_by_hand() {
        let mut n = network();
        let loads = Loads {
            core: CoreState::Sleeping,
            camera: SensorState::Idle,
            stm32: SensorState::Idle,
            radios: [Amps(0.0); 2],
        };
        let s = n
            .sample(SAMPLE_PERIOD, &loads, &MotorState::default())
            .unwrap();
        // core 0.002 mA at 1.2 V → 1.2·0.000002/3.0 = 0.0000008 A;
        // camera 0.14 mA; stm32 60 mA: 0.0000008 + 0.00014 + 0.06 = 0.0601408 A
        assert!((s.i_vcc.0 - 0.0601408).abs() < 1e-12);
        // The LDO passes its current through while V_bat > 3.0 V.
        assert!((s.i_vcc_battery.0 - s.i_vcc.0).abs() < 1e-12);
        assert_eq!(s.i_motor, Amps(0.0));
        // A full battery: Eq. 4.2 at 1 − SOC = 0 is its constant term,
        // 4.15517 V → η = 3.0/4.15517.
        assert!((s.ldo_efficiency - 3.0 / 4.15517).abs() < 1e-9);
    }

    #[test]
    fn advance_to_takes_every_millisecond() {
        let mut n = network();
        let last = n
            .advance_to(
                Picos::from_ms(32),
                &Loads::default(),
                &MotorState::default(),
            )
            .unwrap()
            .unwrap();
        assert_eq!(last.t, Picos::from_ms(32));
        assert_eq!(n.next_sample_time(), Picos::from_ms(33));
        // Nothing more is due until 33 ms.
        assert!(n
            .advance_to(
                Picos(Picos::from_ms(33).0 - 1),
                &Loads::default(),
                &MotorState::default()
            )
            .unwrap()
            .is_none());
    }

    #[test]
    fn time_cannot_go_back() {
        let mut n = network();
        n.sample(Picos::from_ms(5), &Loads::default(), &MotorState::default())
            .unwrap();
        let e = n
            .sample(Picos::from_ms(4), &Loads::default(), &MotorState::default())
            .unwrap_err();
        assert!(matches!(e, PowerError::TimeWentBack { .. }));
    }
}
