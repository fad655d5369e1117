//! `[radio]` of a world file (DESIGN.md §8, docs/SWARM.md §3.1): the channel's
//! parameters, their defaults and where each default comes from.

use serde::Deserialize;

use super::fading::{FastFading, Shadowing};
use super::profile::{Profile, Uwb};

/// The radio channel's parameters. Every key has a default (the table in
/// docs/SWARM.md §3.1 gives each one's source); unknown keys are an error.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RadioConfig {
    /// Seed of every random draw of the channel (per-drone DW1000 clock
    /// phases, ranging noise, RSSI noise, losses).
    pub seed: u64,
    /// σ of the UWB ranging noise, metres: the error of the receiver's
    /// timestamp of a frame's arrival, σ/c in time. 0 gives exact ranges.
    pub uwb_noise_m: f64,
    /// Probability that a UWB frame that reached a receiver (in range, no
    /// collision, receiver not transmitting) is lost anyway.
    pub uwb_loss: f64,
    /// Same for a P2P packet.
    pub p2p_loss: f64,
    /// Beyond this centre distance (m) a UWB frame is not received (and does
    /// not interfere).
    pub uwb_max_range_m: f64,
    /// P2P RSSI at 1 m, dBm (log-distance model; fitted to seed 004 Table 7).
    pub p2p_rssi_1m_dbm: f64,
    /// P2P path-loss exponent n of the log-distance model.
    pub p2p_path_loss_exp: f64,
    /// σ of the P2P RSSI's Gaussian noise, dB (fitted to seed 004 Table 7).
    pub p2p_rssi_noise_db: f64,
    /// The nRF51's receiver sensitivity, dBm: a packet whose RSSI is below it
    /// is not received (and does not interfere).
    pub p2p_sensitivity_dbm: f64,
    /// UWB received power at 1 m, dBm (log-distance estimate, reported as the
    /// `rssi` of a UWB packet; seed 003 does not use it).
    pub uwb_rssi_1m_dbm: f64,
    /// Path-loss exponent of the UWB power estimate.
    pub uwb_path_loss_exp: f64,
    /// `"ideal"` (today's channel) or `"dw1000"` (the UWB as measured):
    /// the defaults of the next four keys (DESIGN.md §16, [`super::profile`]).
    pub profile: Profile,
    /// σ of each chip's TX and RX antenna delay about the nominal, ps.
    pub uwb_antenna_delay_sd_ps: Option<f64>,
    /// Extra range of a frame whose direct path crosses a box or a drone, m.
    pub uwb_nlos_bias_m: Option<f64>,
    /// σ of its extra spread, m.
    pub uwb_nlos_sd_m: Option<f64>,
    /// σ of the reception edge at the range limit, dB (0: a hard limit).
    pub uwb_edge_db: Option<f64>,
    /// σ of the P2P shadowing per link, dB (0: none; [`super::fading`]).
    pub p2p_shadowing_db: f64,
    /// Its decorrelation distance (m the two ends have moved).
    pub p2p_shadowing_decorr_m: f64,
    /// Its decorrelation time (s).
    pub p2p_shadowing_tau_s: f64,
    /// P2P fast fading per packet: `"none"` or `"rayleigh"`.
    pub p2p_fading: FastFading,
}

impl Default for RadioConfig {
    /// The documented defaults (docs/SWARM.md §3.1).
    fn default() -> Self {
        RadioConfig {
            seed: 0,
            // DW1000 datasheet §1: "precision location to within 10 cm"
            // (ranging accuracy); seed 003 §7.1's static positions scatter
            // by 0.3-1 cm σ once filtered, its §7.3 filter assumes 0.25 m.
            uwb_noise_m: 0.10,
            // Collisions, half duplex and range are modelled here and a
            // receiver that is off loses frames in the peripheral (SWARM §4.3):
            // nothing is lost beyond that by default (SWARM §3.1).
            uwb_loss: 0.0,
            p2p_loss: 0.0,
            // Seed 003 §4.3: "maximum range is around 10 meters" (measured,
            // default configuration, line of sight); its §7.4 also rejects
            // ToFs beyond 10 m as invalid.
            uwb_max_range_m: 10.0,
            // Fitted to seed 004 Table 7 with n = 2 fixed (SWARM §3.1).
            p2p_rssi_1m_dbm: P2P_RSSI_1M_DBM,
            p2p_path_loss_exp: 2.0,
            p2p_rssi_noise_db: P2P_RSSI_NOISE_DB,
            // nRF51822 Product Specification v3.x, §8.5 "Receiver", RX
            // sensitivity at 2 Msps (the Crazyflie's data rate): -85 dBm.
            p2p_sensitivity_dbm: -85.0,
            // Friis at the DW1000's channel 2 (3993.6 MHz) with the
            // FCC/ETSI limit of -41.3 dBm/MHz over its 499.2 MHz:
            // -14.3 dBm EIRP - 44.5 dB free-space loss at 1 m (SWARM §3.1).
            uwb_rssi_1m_dbm: -58.8,
            uwb_path_loss_exp: 2.0,
            profile: Profile::Ideal,
            uwb_antenna_delay_sd_ps: None,
            uwb_nlos_bias_m: None,
            uwb_nlos_sd_m: None,
            uwb_edge_db: None,
            p2p_shadowing_db: 0.0,
            // Indoor shadowing decorrelates over about a metre at 2.4 GHz
            // (Gudmundson's model as used indoors; docs/SWARM.md §3.1) and,
            // for drones that stay put, over seconds as the room changes.
            p2p_shadowing_decorr_m: 1.0,
            p2p_shadowing_tau_s: 5.0,
            p2p_fading: FastFading::None,
        }
    }
}

/// The fit of docs/SWARM.md §3.1 (seed 004 Table 7: detection at 117.9 ±
/// 65.0 cm with a -48 dBm threshold, B approaching A from 3 m at 0.2 m/s).
pub const P2P_RSSI_1M_DBM: f64 = -71.0;
/// See [`P2P_RSSI_1M_DBM`].
pub const P2P_RSSI_NOISE_DB: f64 = 10.3;

impl RadioConfig {
    /// The UWB effects: the profile's, each key set in the file winning.
    pub fn uwb(&self) -> Uwb {
        let p = Uwb::of(self.profile);
        Uwb {
            antenna_delay_sd_ps: self
                .uwb_antenna_delay_sd_ps
                .unwrap_or(p.antenna_delay_sd_ps),
            antenna_delays: p.antenna_delays || self.uwb_antenna_delay_sd_ps.is_some(),
            nlos_bias_m: self.uwb_nlos_bias_m.unwrap_or(p.nlos_bias_m),
            nlos_sd_m: self.uwb_nlos_sd_m.unwrap_or(p.nlos_sd_m),
            edge_db: self.uwb_edge_db.unwrap_or(p.edge_db),
        }
    }

    /// The P2P shadowing, `None` when its σ is 0.
    pub fn shadowing(&self) -> Option<Shadowing> {
        (self.p2p_shadowing_db > 0.0).then_some(Shadowing {
            sd_db: self.p2p_shadowing_db,
            decorr_m: self.p2p_shadowing_decorr_m,
            tau_s: self.p2p_shadowing_tau_s,
        })
    }

    /// Checks every key: probabilities in [0, 1], σ ≥ 0, finite numbers,
    /// positive range and exponents. The message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let finite = [
            ("uwb_noise_m", self.uwb_noise_m),
            ("uwb_loss", self.uwb_loss),
            ("p2p_loss", self.p2p_loss),
            ("uwb_max_range_m", self.uwb_max_range_m),
            ("p2p_rssi_1m_dbm", self.p2p_rssi_1m_dbm),
            ("p2p_path_loss_exp", self.p2p_path_loss_exp),
            ("p2p_rssi_noise_db", self.p2p_rssi_noise_db),
            ("p2p_sensitivity_dbm", self.p2p_sensitivity_dbm),
            ("uwb_rssi_1m_dbm", self.uwb_rssi_1m_dbm),
            ("uwb_path_loss_exp", self.uwb_path_loss_exp),
            ("p2p_shadowing_db", self.p2p_shadowing_db),
            ("p2p_shadowing_decorr_m", self.p2p_shadowing_decorr_m),
            ("p2p_shadowing_tau_s", self.p2p_shadowing_tau_s),
        ];
        let optional = [
            ("uwb_antenna_delay_sd_ps", self.uwb_antenna_delay_sd_ps),
            ("uwb_nlos_bias_m", self.uwb_nlos_bias_m),
            ("uwb_nlos_sd_m", self.uwb_nlos_sd_m),
            ("uwb_edge_db", self.uwb_edge_db),
        ];
        for (key, v) in optional {
            match v {
                Some(v) if !v.is_finite() || v < 0.0 => {
                    return Err(format!(
                        "[radio] {key} must be a finite number >= 0, got {v}"
                    ))
                }
                _ => {}
            }
        }
        for (key, v) in finite {
            if !v.is_finite() {
                return Err(format!("[radio] {key} must be a finite number, got {v}"));
            }
        }
        for (key, p) in [("uwb_loss", self.uwb_loss), ("p2p_loss", self.p2p_loss)] {
            if !(0.0..=1.0).contains(&p) {
                return Err(format!(
                    "[radio] {key} is a probability: it must be in [0, 1], got {p}"
                ));
            }
        }
        for (key, s) in [
            ("uwb_noise_m", self.uwb_noise_m),
            ("p2p_rssi_noise_db", self.p2p_rssi_noise_db),
            ("p2p_shadowing_db", self.p2p_shadowing_db),
        ] {
            if s < 0.0 {
                return Err(format!(
                    "[radio] {key} is a standard deviation: it must be >= 0, got {s}"
                ));
            }
        }
        for (key, v) in [
            ("uwb_max_range_m", self.uwb_max_range_m),
            ("p2p_path_loss_exp", self.p2p_path_loss_exp),
            ("uwb_path_loss_exp", self.uwb_path_loss_exp),
            ("p2p_shadowing_decorr_m", self.p2p_shadowing_decorr_m),
            ("p2p_shadowing_tau_s", self.p2p_shadowing_tau_s),
        ] {
            if v <= 0.0 {
                return Err(format!("[radio] {key} must be > 0, got {v}"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_every_key_is_optional() {
        RadioConfig::default().validate().unwrap();
        let c: RadioConfig = toml::from_str("").unwrap();
        assert_eq!(c, RadioConfig::default());
        let c: RadioConfig = toml::from_str("seed = 7\nuwb_noise_m = 0.0").unwrap();
        assert_eq!(c.seed, 7);
        assert_eq!(c.uwb_noise_m, 0.0);
        assert_eq!(c.uwb_max_range_m, 10.0);
    }

    #[test]
    fn unknown_keys_are_rejected() {
        let e = toml::from_str::<RadioConfig>("uwb_nosie_m = 0.1").unwrap_err();
        assert!(e.to_string().contains("uwb_nosie_m"), "{e}");
    }

    #[test]
    fn bad_values_name_their_key() {
        let bad = |f: fn(&mut RadioConfig), key: &str| {
            let mut c = RadioConfig::default();
            f(&mut c);
            let e = c.validate().unwrap_err();
            assert!(e.contains(key), "{e}");
        };
        bad(|c| c.uwb_loss = 1.5, "uwb_loss");
        bad(|c| c.p2p_loss = -0.1, "p2p_loss");
        bad(|c| c.uwb_noise_m = -1.0, "uwb_noise_m");
        bad(|c| c.p2p_rssi_noise_db = f64::NAN, "p2p_rssi_noise_db");
        bad(|c| c.uwb_max_range_m = 0.0, "uwb_max_range_m");
        bad(|c| c.p2p_path_loss_exp = f64::INFINITY, "p2p_path_loss_exp");
        bad(|c| c.uwb_nlos_sd_m = Some(-0.1), "uwb_nlos_sd_m");
        bad(|c| c.p2p_shadowing_tau_s = 0.0, "p2p_shadowing_tau_s");
    }

    #[test]
    fn the_profile_sets_defaults_and_keys_win() {
        let c: RadioConfig = toml::from_str("").unwrap();
        assert_eq!(c.uwb(), Uwb::IDEAL);
        let c: RadioConfig = toml::from_str("profile = \"dw1000\"").unwrap();
        assert_eq!(c.uwb(), Uwb::DW1000);
        let c: RadioConfig = toml::from_str("profile = \"dw1000\"\nuwb_nlos_bias_m = 0.5").unwrap();
        assert_eq!(c.uwb().nlos_bias_m, 0.5);
        assert_eq!(c.uwb().nlos_sd_m, Uwb::DW1000.nlos_sd_m);
        assert!(toml::from_str::<RadioConfig>("profile = \"real\"").is_err());
        assert_eq!(c.shadowing(), None);
    }
}
