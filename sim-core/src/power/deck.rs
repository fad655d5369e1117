//! The AI deck as a load on the battery (docs/AIDECK_POWER.md).
//!
//! On a platform with a cluster (`crazyflie-aideck.json`) the GAP8's
//! cluster draws its power (`crate::cluster::power`, the `p_cluster_*`
//! columns of `power.csv`) through the deck's regulators from the
//! battery's rail (the expansion connector's VCOM, the battery voltage):
//!
//! ```text
//!  cluster (P at cluster.vref) ── deck regulators (η) ── battery
//! ```
//!
//! `I_battery += P / (η · V_battery)`. The GAP8's fabric controller and
//! the camera are already loads of the VCC bus (`core`, `camera`: the
//! thesis's network), so only the cluster is added here. A platform
//! without a cluster has no deck load: its network is the thesis's, bit
//! for bit.

use super::converter::Converter;
use crate::config::PlatformConfig;
use crate::units::{Amps, Volts};

/// The cluster's supply path: its voltage and the regulators between it
/// and the battery.
#[derive(Debug, Clone, PartialEq)]
pub struct DeckSupply {
    /// The cluster's supply voltage (`cluster.vref`).
    vref: Volts,
    /// The deck's regulators, battery to cluster (`cluster.converter`).
    converter: Converter,
}

impl DeckSupply {
    /// The supply of `platform`'s cluster; `None` without a cluster.
    pub fn of(platform: &PlatformConfig) -> Result<Option<DeckSupply>, String> {
        let Some(c) = &platform.cluster else {
            return Ok(None);
        };
        Ok(Some(DeckSupply {
            vref: Volts(c.vref),
            converter: c.converter()?,
        }))
    }

    /// A supply at `vref` through `converter` (tests, tools).
    pub fn new(vref: Volts, converter: Converter) -> DeckSupply {
        DeckSupply { vref, converter }
    }

    /// The battery current that delivers `power_w` to the cluster when the
    /// battery's rail is at `v_battery`: `P / (η · V_battery)`.
    pub fn battery_current(&self, power_w: f64, v_battery: Volts) -> Amps {
        if power_w <= 0.0 {
            return Amps(0.0);
        }
        let i_out = Amps(power_w / self.vref.0);
        self.converter.input_current(i_out, self.vref, v_battery)
    }

    /// The regulators' efficiency when delivering `power_w` from `v_battery`.
    pub fn efficiency(&self, power_w: f64, v_battery: Volts) -> f64 {
        self.converter
            .efficiency(Amps(power_w / self.vref.0), self.vref, v_battery)
    }
}

/// `summary.json`'s `deck` block (a platform with a cluster only): what
/// the AI deck's cluster cost the battery, and what it did to the flight
/// time.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeckSummary {
    /// Energy the deck drew from the battery, J (part of `energy_j.total`).
    pub energy_j: f64,
    /// Its share of `energy_j.total`, %.
    pub share_pct: f64,
    /// Its mean power at the battery over the run, W.
    pub mean_power_w: f64,
    /// The charge it drew, mAh.
    pub charge_mah: f64,
    /// Flight time extrapolated from the charge used (platform time / SOC
    /// used, as the printed summary's estimate), s; null if none was used.
    pub flight_time_s: Option<f64>,
    /// The same without the deck's charge, s.
    pub flight_time_without_deck_s: Option<f64>,
}

impl DeckSummary {
    /// The block from the run's totals: the deck's energy and charge, the
    /// battery's, the capacity, the SOC at the start and at the end.
    pub fn new(
        deck_j: f64,
        total_j: f64,
        deck_ah: f64,
        capacity_ah: f64,
        soc: (f64, f64),
        platform_time_s: f64,
    ) -> DeckSummary {
        let used = soc.0 - soc.1;
        let deck_soc = deck_ah / capacity_ah;
        let flight = |used: f64| (used > 1e-9).then(|| platform_time_s / used);
        DeckSummary {
            energy_j: deck_j,
            share_pct: if total_j > 0.0 {
                100.0 * deck_j / total_j
            } else {
                0.0
            },
            mean_power_w: if platform_time_s > 0.0 {
                deck_j / platform_time_s
            } else {
                0.0
            },
            charge_mah: deck_ah * 1000.0,
            flight_time_s: flight(used),
            flight_time_without_deck_s: flight(used - deck_soc),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::power::ClusterPower;
    use crate::config::RunConfig;
    use crate::power::{Loads, MotorState, PowerNetwork, SAMPLE_PERIOD};
    use crate::units::Picos;

    fn aideck(efficiency: f64) -> PlatformConfig {
        let mut p = PlatformConfig::default_crazyflie();
        let json = format!(r#"{{ "vref": 1.2, "converter": {{ "efficiency": {efficiency} }} }}"#);
        p.cluster = Some(serde_json::from_str(&json).unwrap());
        p
    }

    #[test]
    fn battery_current_is_power_over_efficiency_and_voltage() {
        let d = DeckSupply::new(Volts(1.2), Converter::fixed(0.8));
        let i = d.battery_current(0.096, Volts(4.0));
        assert!((i.0 - 0.096 / (0.8 * 4.0)).abs() < 1e-15);
        assert_eq!(d.battery_current(0.0, Volts(4.0)), Amps(0.0));
        assert!((d.efficiency(0.096, Volts(4.0)) - 0.8).abs() < 1e-15);
    }

    #[test]
    fn summary_extrapolates_with_and_without_the_deck() {
        // 100 s used 40 % of 0.25 Ah, the deck 0.01 Ah of it (4 %).
        let d = DeckSummary::new(2.0, 50.0, 0.01, 0.25, (1.0, 0.6), 100.0);
        assert!((d.share_pct - 4.0).abs() < 1e-12);
        assert!((d.mean_power_w - 0.02).abs() < 1e-12);
        assert!((d.charge_mah - 10.0).abs() < 1e-12);
        assert!((d.flight_time_s.unwrap() - 250.0).abs() < 1e-9);
        assert!((d.flight_time_without_deck_s.unwrap() - 100.0 / 0.36).abs() < 1e-9);
        assert_eq!(
            DeckSummary::new(0.0, 0.0, 0.0, 0.25, (1.0, 1.0), 0.0).flight_time_s,
            None
        );
    }

    #[test]
    fn no_cluster_no_deck() {
        assert_eq!(
            DeckSupply::of(&PlatformConfig::default_crazyflie()).unwrap(),
            None
        );
    }

    /// A constant deck load for 10 s: the battery loses, beyond what the
    /// same network loses without it, the charge ∫ P/(η·V) dt — with V the
    /// terminal voltage each sample used (the thesis's one-sample delay) —
    /// and its energy counts P/η at the battery.
    #[test]
    fn constant_load_drains_its_charge_through_the_regulators() {
        const P: f64 = 0.096; // GAP8's cluster at full load, W
        const ETA: f64 = 0.8;
        let run = RunConfig::default();
        let mut with = PowerNetwork::new(&aideck(ETA), &run).unwrap();
        let mut without = PowerNetwork::new(&aideck(ETA), &run).unwrap();
        let loads = Loads::default();
        let motor = MotorState::default();
        let mut v_prev = with.battery().voltage(Amps(0.0)).0;
        let mut want_ah = 0.0;
        let mut want_j = 0.0;
        let mut i_prev = 0.0;
        let n = 10_000;
        for k in 1..=n {
            let t = Picos(SAMPLE_PERIOD.0 * k);
            with.set_cluster_power(ClusterPower {
                cores_active_w: P,
                ..ClusterPower::default()
            });
            let s = with.sample(t, &loads, &motor).unwrap();
            without.sample(t, &loads, &motor).unwrap();
            // The battery integrates its current with the trapezoid rule.
            let i = P / (ETA * v_prev);
            want_ah += (i + i_prev) * 1e-3 / (2.0 * 3600.0);
            want_j += s.v_battery.0 * i * 1e-3;
            i_prev = i;
            v_prev = s.v_battery.0;
        }
        let cap = with.battery().capacity_ah();
        let lost = (without.battery().soc() - with.battery().soc()) * cap;
        assert!(
            (lost - want_ah).abs() < 1e-6 * want_ah,
            "{lost} Ah, want {want_ah}"
        );
        // About I·t/η at the battery's ~4.1 V: 0.096/(0.8·4.1)·10 s = 0.29 C.
        let closed = P / (ETA * 4.1) * 10.0 / 3600.0;
        assert!((lost - closed).abs() < 0.02 * closed, "{lost} vs {closed}");
        let e = with.energy();
        assert!((e.deck.0 - want_j).abs() < 1e-9, "{} J", e.deck.0);
        // The deck's energy is part of what the battery gave.
        let extra = e.battery.0 - without.energy().battery.0;
        assert!(
            (extra - e.deck.0).abs() < 0.01 * e.deck.0,
            "{extra} {}",
            e.deck.0
        );
        assert!((with.deck_charge_ah() - want_ah).abs() < 1e-6 * want_ah);
    }
}
