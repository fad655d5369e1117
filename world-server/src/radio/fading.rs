//! P2P RSSI beyond path loss (DESIGN.md §16): log-normal
//! shadowing per link, correlated in time and space, and Rayleigh fast
//! fading per packet.
//!
//! - **Shadowing** `S_ab` (dB) of the link between drones a and b (the same
//!   both ways: the channel is reciprocal) is a Gauss–Markov process: from
//!   one packet of the link to the next,
//!   `S ← ρ·S + √(1 − ρ²)·σ·w`, w standard normal, with
//!   `ρ = exp(−Δt / τ) · exp(−Δx / d_c)` — Gudmundson's exponential
//!   correlation model ("Correlation model for shadow fading in mobile radio
//!   systems", Electronics Letters 27(23), 1991) over Δx, the distance the
//!   two ends have moved (m), times a decay in time for a room whose
//!   reflectors (people, doors) move. Its first value is σ·w: stationary
//!   from the start. `p2p_shadowing_db` (σ), `p2p_shadowing_decorr_m` (d_c)
//!   and `p2p_shadowing_tau_s` (τ) of `[radio]`; σ = 0 (the default) turns
//!   it off.
//! - **Fast fading** (`p2p_fading = "rayleigh"`): the packet's power is the
//!   mean's times an exponential of mean 1 (Rayleigh amplitude), drawn per
//!   packet — packets 100 ms apart on drones that vibrate and drift by
//!   centimetres are many 2.4 GHz coherence distances (λ/2 = 6 cm) apart.
//!   In dB it averages −2.51 dB (−γ·10/ln 10); that is added back so that
//!   the mean RSSI still follows the path-loss line.

use super::dist;
use serde::Deserialize;

/// `p2p_fading` of `[radio]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FastFading {
    #[default]
    None,
    Rayleigh,
}

/// E[10·log10(X)] for X exponential of mean 1: −10·γ/ln 10 dB, γ Euler's
/// constant.
pub const RAYLEIGH_MEAN_DB: f64 = -10.0 * 0.577_215_664_901_532_9 / std::f64::consts::LN_10;

/// Rayleigh fading in dB from a uniform draw `u` in [0, 1), centred (mean 0
/// over u).
pub fn rayleigh_db(u: f64) -> f64 {
    let power = -(1.0 - u).ln();
    10.0 * power.max(1e-300).log10() - RAYLEIGH_MEAN_DB
}

/// The shadowing of one link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkShadow {
    /// Its value, dB.
    pub db: f64,
    /// When and where (both ends) it was last drawn.
    t_s: f64,
    a: [f64; 3],
    b: [f64; 3],
}

/// The shadowing parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shadowing {
    pub sd_db: f64,
    pub decorr_m: f64,
    pub tau_s: f64,
}

impl Shadowing {
    /// The link's next value at time `t_s` with its ends at `a` and `b`
    /// (`w` standard normal); `prev` is its last state, `None` at its first
    /// packet.
    pub fn next(
        &self,
        prev: Option<LinkShadow>,
        t_s: f64,
        a: [f64; 3],
        b: [f64; 3],
        w: f64,
    ) -> LinkShadow {
        let db = match prev {
            None => self.sd_db * w,
            Some(p) => {
                let moved = dist(p.a, a) + dist(p.b, b);
                let rho =
                    (-(t_s - p.t_s).abs() / self.tau_s).exp() * (-moved / self.decorr_m).exp();
                rho * p.db + (1.0 - rho * rho).max(0.0).sqrt() * self.sd_db * w
            }
        };
        LinkShadow { db, t_s, a, b }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rayleigh_in_db_is_centred_and_has_its_known_spread() {
        // Midpoint rule over u: mean 0, σ = 10/ln10 · π/√6 = 5.57 dB.
        let n = 200_000;
        let xs: Vec<f64> = (0..n)
            .map(|i| rayleigh_db((i as f64 + 0.5) / n as f64))
            .collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(mean.abs() < 0.01, "{mean}");
        let expect = 10.0 / std::f64::consts::LN_10 * std::f64::consts::PI / 6f64.sqrt();
        assert!((sd - expect).abs() < 0.02, "{sd} vs {expect}");
        assert!((RAYLEIGH_MEAN_DB + 2.5068).abs() < 1e-3);
    }

    #[test]
    fn gauss_markov_correlation_is_exponential() {
        let s = Shadowing {
            sd_db: 6.0,
            decorr_m: 1.0,
            tau_s: 10.0,
        };
        let (a, b) = ([0.0; 3], [2.0, 0.0, 0.0]);
        let first = s.next(None, 0.0, a, b, 1.0);
        assert_eq!(first.db, 6.0);
        // 1 s later, B moved 0.5 m: ρ = e^-0.1 · e^-0.5; with w = 0 the
        // value decays by ρ exactly.
        let b2 = [1.5, 0.0, 0.0];
        let next = s.next(Some(first), 1.0, a, b2, 0.0);
        let rho = (-0.1f64).exp() * (-0.5f64).exp();
        assert!((next.db - 6.0 * rho).abs() < 1e-12);
        // Nothing moved, no time: the same value whatever w.
        let same = s.next(Some(first), 0.0, a, b, 3.0);
        assert!((same.db - 6.0).abs() < 1e-12);
    }
}
