//! `profile = "ideal" | "dw1000"` of `[radio]` (DESIGN.md §16): the UWB
//! radio as the channel of DESIGN.md §8 has it ("ideal": stamps at the
//! antenna, line of sight through everything, a hard range limit), or as the
//! hardware measures ("dw1000"): per-chip antenna delays, non-line-of-sight
//! bias and spread, reception fading out near the range limit. Each of the
//! three is also a key of its own, which wins over the profile.

use serde::Deserialize;

/// The UWB profile.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Today's channel, exactly (tests that need exact ranges).
    #[default]
    Ideal,
    /// The DW1000 as measured (the defaults of [`Uwb::dw1000`]).
    Dw1000,
}

/// The nominal antenna delay of one path (TX or RX) of a chip, ps: half of
/// seed 003 §6.4.2's 515.7 ns, the one constant the thesis subtracts from
/// every TOF. A TOF carries one TX and one RX delay of each chip halved
/// ((δ_tx,A + δ_rx,B + δ_tx,B + δ_rx,A) / 2, APS014 §2.1.1), so with every
/// path at its nominal value the firmware's correction is exact.
pub const NOMINAL_PATH_DELAY_PS: f64 = 515_700.0 / 2.0;

/// The firmware's correction for the "dw1000" profile in DW1000 ticks of
/// 1/(128 · 499.2 MHz): 515.7 ns · 63.8976 GHz = 32 952.
pub const FIRMWARE_ANTENNA_DELAY_TICKS: i32 = 32_952;

/// The UWB effects of a profile, resolved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Uwb {
    /// σ of each path's (TX, RX) antenna delay about its nominal value, ps;
    /// 0 with the nominal itself 0 ("ideal": no antenna delay at all).
    pub antenna_delay_sd_ps: f64,
    /// Whether the chips have antenna delays ("dw1000") or stamp at the
    /// antenna ("ideal").
    pub antenna_delays: bool,
    /// Extra distance of a frame whose direct path crosses a body, m.
    pub nlos_bias_m: f64,
    /// σ of its extra spread, m.
    pub nlos_sd_m: f64,
    /// σ (dB) of the reception edge around the range limit: a frame is
    /// received with probability Φ((P − P(max range)) / σ); 0 is a hard
    /// cut at `uwb_max_range_m`.
    pub edge_db: f64,
}

impl Uwb {
    /// Today's channel: nothing of the above.
    pub const IDEAL: Uwb = Uwb {
        antenna_delay_sd_ps: 0.0,
        antenna_delays: false,
        nlos_bias_m: 0.0,
        nlos_sd_m: 0.0,
        edge_db: 0.0,
    };

    /// The DW1000 as measured.
    ///
    /// - Antenna delays: Decawave's APS014 (v1.01, §1–2) calibrates every
    ///   product because the delay varies from chip to chip and board to
    ///   board; left uncalibrated, a DW1000 system's ranges are off by a
    ///   constant of typically 10–50 cm (user reports, e.g. the Qorvo
    ///   forum), and seed 003's own boards, corrected with one constant,
    ///   measured 1 m as 0.85–0.94 m (Tables 7.1–7.4). σ = 250 ps per path
    ///   makes a pair's range error (δ_A + δ_B)·c/2 with δ = δ_tx + δ_rx
    ///   Gaussian of σ = 2 · 250 ps · c / 2 = 7.5 cm: a few cm to 20 cm.
    /// - NLOS: when the first path is blocked the DW1000 stamps a later,
    ///   reflected or attenuated path: ranges are longer and noisier,
    ///   by tens of cm indoors (Decawave APS006 Part 2, "NLOS operation and
    ///   optimization"; Maranò et al., "NLOS identification and mitigation
    ///   for localization based on UWB experimental data", IEEE JSAC 28(7),
    ///   2010): bias 0.25 m, σ 0.15 m.
    /// - Edge: the DW1000's packet error rate climbs from ~0 to ~1 over a
    ///   few dB about its sensitivity (DW1000 datasheet, receiver
    ///   sensitivity characteristics): σ = 3 dB about the power at seed
    ///   003 §4.3's 10 m.
    pub const DW1000: Uwb = Uwb {
        antenna_delay_sd_ps: 250.0,
        antenna_delays: true,
        nlos_bias_m: 0.25,
        nlos_sd_m: 0.15,
        edge_db: 3.0,
    };

    pub const fn of(profile: Profile) -> Uwb {
        match profile {
            Profile::Ideal => Uwb::IDEAL,
            Profile::Dw1000 => Uwb::DW1000,
        }
    }
}

/// Standard normal cumulative distribution (Abramowitz & Stegun 7.1.26
/// for erf, |error| < 1.5e-7: ample for a reception probability).
pub fn phi(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erf = 1.0 - poly * (-z * z).exp();
    if x >= 0.0 {
        0.5 * (1.0 + erf)
    } else {
        0.5 * (1.0 - erf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phi_at_known_points() {
        assert!((phi(0.0) - 0.5).abs() < 1e-9);
        assert!((phi(1.0) - 0.841_344_746).abs() < 2e-7);
        assert!((phi(-1.959_964) - 0.025).abs() < 2e-7);
    }

    #[test]
    fn firmware_constant_is_the_thesis_s_515_7_ns() {
        // 2 paths · nominal = 515.7 ns = 32 952 ticks of 15.65 ps.
        let ticks = 2.0 * NOMINAL_PATH_DELAY_PS * 1e-12 * 128.0 * 499.2e6;
        assert_eq!(ticks.round() as i32, FIRMWARE_ANTENNA_DELAY_TICKS);
    }
}
