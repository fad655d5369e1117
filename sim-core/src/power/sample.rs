//! What one sample of the power network takes and gives: the devices'
//! power states ([`Loads`]), the sample's figures ([`PowerSample`]) and the
//! energies integrated so far ([`Energy`]).

use super::models::{ModelOutput, MotorState, PowerModelKind};
use super::Joules;
use crate::units::{Amps, Picos, Volts};

/// The core's power state (platform file `core.states`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CoreState {
    #[default]
    Running,
    /// In `wfi` or otherwise idle.
    Sleeping,
}

/// A sensor's power state (platform file `states.read/write/idle`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SensorState {
    Read,
    Write,
    #[default]
    Idle,
}

impl SensorState {
    pub(crate) const fn index(self) -> usize {
        match self {
            SensorState::Read => 0,
            SensorState::Write => 1,
            SensorState::Idle => 2,
        }
    }
}

/// The devices' power states at a sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Loads {
    pub core: CoreState,
    pub camera: SensorState,
    pub stm32: SensorState,
    /// The radios' mean currents over the sample's interval (UWB, P2P; see
    /// `peripherals::radio`); 0 for a radio never switched on.
    pub radios: [Amps; 2],
}

/// Names of the radios on the VCC bus, in [`Loads::radios`] order.
pub const RADIOS: [&str; 2] = ["uwb", "p2p"];

/// Everything computed at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerSample {
    /// Simulated time of the sample.
    pub t: Picos,
    /// Time integrated by this sample (since the previous one).
    pub dt: Picos,
    /// Core current on the VCC bus (after its converter), A.
    pub i_core: Amps,
    /// Camera current on the VCC bus, A.
    pub i_camera: Amps,
    /// STM32 current on the VCC bus, A.
    pub i_stm32: Amps,
    /// Any other sensors (at their idle current), both buses, and the AI
    /// deck's cluster (`deck`) at the battery, A.
    pub i_other: Amps,
    /// The radios' currents on the VCC bus (UWB, P2P), A.
    pub i_radios: [Amps; 2],
    /// VCC bus total at the bus voltage, A.
    pub i_vcc: Amps,
    /// LDO efficiency used at this sample (Vout/Vin clamped, Eq. 4.1).
    pub ldo_efficiency: f64,
    /// VCC current as drawn from the battery through the LDO, A.
    pub i_vcc_battery: Amps,
    /// Motor-bus current of the selected model, A.
    pub i_motor: Amps,
    /// Battery current (VCC through the LDO + motor bus + others), A.
    pub i_battery: Amps,
    /// Open-circuit voltage after this sample.
    pub v_oc: Volts,
    /// Terminal voltage after this sample (`v_oc − r_s·I`).
    pub v_battery: Volts,
    /// State of charge after this sample (fraction, 1 = full).
    pub soc: f64,
    /// The drone state the models saw.
    pub motor: MotorState,
    /// The three models' outputs, indexed by [`PowerModelKind::index`].
    pub models: [ModelOutput; 3],
    /// The model that drains the battery.
    pub selected: PowerModelKind,
    /// SOC under the low-battery threshold (BATTERY_LOW, §4.5.4).
    pub low_battery: bool,
    /// True only at the sample where the SOC first went under the threshold.
    pub low_battery_crossed: bool,
    /// The cluster's mean power over the interval, on a platform with a
    /// cluster (`crate::cluster::power`; its own `power.csv` columns).
    pub cluster: Option<crate::cluster::power::ClusterPower>,
}

impl PowerSample {
    /// The selected model's output.
    pub fn selected_output(&self) -> ModelOutput {
        self.models[self.selected.index()]
    }
}

/// Energy integrated since the start (right rectangles: each sample's power
/// held over the interval that ends at it).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// Each model's own power, indexed by [`PowerModelKind::index`].
    pub models: [Joules; 3],
    /// The VCC bus (at its voltage).
    pub vcc: Joules,
    /// The radios (UWB, P2P), at the VCC bus voltage.
    pub radios: [Joules; 2],
    /// Drawn from the battery at its terminal voltage (the summary's `total`).
    pub battery: Joules,
    /// The AI deck's part of `battery`: the cluster's power through the
    /// deck's regulators (`deck`), at the battery's terminal voltage; 0
    /// without a cluster.
    pub deck: Joules,
}

impl Energy {
    /// One model's energy.
    pub fn model(&self, kind: PowerModelKind) -> Joules {
        self.models[kind.index()]
    }
}
