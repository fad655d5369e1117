//! The channel's random draws, each from its own ChaCha stream keyed by what
//! it is about (docs/SWARM.md §3): a draw depends only on the world's seed and
//! on (sender, sender's frame number, receiver), never on the order in which
//! the world resolves, steps or asks for anything.

use protocol::radio::{Picos, DW1000_STAMP_MASK};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha12Rng;
use rand_distr::{Distribution, StandardNormal};

/// What a stream is for, so that two purposes never share one.
#[derive(Clone, Copy)]
#[repr(u32)]
enum Domain {
    Reception = 0,
    ClockPhase = 1,
    /// Range and flow sensor noise (world file `[sensors]`).
    Sensor = 2,
    /// Per-chip UWB antenna delays (DESIGN.md §16).
    AntennaDelay = 3,
}

/// A ChaCha generator whose 256-bit key is the tuple itself (seed, domain,
/// sender, frame, receiver) laid out byte for byte: distinct tuples give
/// distinct keys (no hashing, so no collisions), and ChaCha's output for
/// related keys is independent (it is a PRF).
fn stream(seed: u64, domain: Domain, sender: u32, frame: u64, receiver: u64) -> ChaCha12Rng {
    let mut key = [0u8; 32];
    key[0..8].copy_from_slice(&seed.to_le_bytes());
    key[8..12].copy_from_slice(&(domain as u32).to_le_bytes());
    key[12..16].copy_from_slice(&sender.to_le_bytes());
    key[16..24].copy_from_slice(&frame.to_le_bytes());
    key[24..32].copy_from_slice(&receiver.to_le_bytes());
    ChaCha12Rng::from_seed(key)
}

/// One wrap of the DW1000 clock in picoseconds: 2^40 ticks of
/// 1e6/63 897.6 ps = 2^40 · 1e7 / 638 976 ps ≈ 17.2 s (floored).
pub fn wrap_ps() -> u64 {
    ((DW1000_STAMP_MASK as u128 + 1) * 10_000_000 / 638_976) as u64
}

/// Drone `drone`'s DW1000 clock phase: uniform over one wrap (DESIGN.md §8).
pub fn clock_phase(seed: u64, drone: usize) -> Picos {
    let mut rng = stream(seed, Domain::ClockPhase, drone as u32, 0, 0);
    Picos(rng.random_range(0..wrap_ps()))
}

/// Drone `drone`'s DW1000 TX and RX antenna delays as standard normals
/// (the channel scales them by `uwb_antenna_delay_sd_ps`).
pub fn antenna_delays(seed: u64, drone: usize) -> (f64, f64) {
    let mut rng = stream(seed, Domain::AntennaDelay, drone as u32, 0, 0);
    (
        StandardNormal.sample(&mut rng),
        StandardNormal.sample(&mut rng),
    )
}

/// A standard normal draw for a sensor reading of drone `drone` at world
/// time `time_ms` on `channel` (the rangers 0-5, the flow axes 6-7): the
/// same reading whenever and however often it is asked for.
pub fn sensor_normal(seed: u64, drone: usize, time_ms: u64, channel: u64) -> f64 {
    let mut rng = stream(seed, Domain::Sensor, drone as u32, time_ms, channel);
    StandardNormal.sample(&mut rng)
}

/// The draws of one (frame, receiver): always all of them, in this order, so
/// that each is the same whichever radio, profile or outcome (the first three
/// are those of the "ideal" channel, unchanged by the ones added after them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceptionDraws {
    /// Standard normal: the ranging noise in units of `uwb_noise_m`.
    pub range_noise: f64,
    /// Standard normal: the RSSI noise in units of its σ.
    pub rssi_noise: f64,
    /// Uniform in [0, 1): the frame is lost when below the loss probability.
    pub loss: f64,
    /// Standard normal: the NLOS spread in units of `uwb_nlos_sd_m`.
    pub nlos: f64,
    /// Uniform in [0, 1): the frame is received when below the reception
    /// probability at the range edge (UWB).
    pub edge: f64,
    /// Standard normal: the innovation of the link's shadowing (P2P).
    pub shadowing: f64,
    /// Uniform in [0, 1): the packet's Rayleigh fading (P2P).
    pub fading: f64,
}

impl ReceptionDraws {
    pub fn new(seed: u64, sender: usize, frame: u64, receiver: usize) -> ReceptionDraws {
        let mut rng = stream(
            seed,
            Domain::Reception,
            sender as u32,
            frame,
            receiver as u64,
        );
        let range_noise = StandardNormal.sample(&mut rng);
        let rssi_noise = StandardNormal.sample(&mut rng);
        let loss = rng.random::<f64>();
        let nlos = StandardNormal.sample(&mut rng);
        let edge = rng.random::<f64>();
        let shadowing = StandardNormal.sample(&mut rng);
        let fading = rng.random::<f64>();
        ReceptionDraws {
            range_noise,
            rssi_noise,
            loss,
            nlos,
            edge,
            shadowing,
            fading,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_a_function_of_their_key_only() {
        let a = ReceptionDraws::new(7, 1, 42, 2);
        let _ = ReceptionDraws::new(7, 2, 42, 1);
        assert_eq!(a, ReceptionDraws::new(7, 1, 42, 2));
        assert_ne!(a, ReceptionDraws::new(7, 2, 42, 1));
        assert_ne!(a, ReceptionDraws::new(8, 1, 42, 2));
        assert_ne!(a, ReceptionDraws::new(7, 1, 43, 2));
        assert!((0.0..1.0).contains(&a.loss));
    }

    #[test]
    fn phases_cover_one_wrap() {
        let w = wrap_ps();
        assert!((w as f64 / 1e12 - 17.207).abs() < 1e-3, "{w}");
        let phases: Vec<u64> = (0..200).map(|d| clock_phase(3, d).0).collect();
        assert!(phases.iter().all(|&p| p < w));
        let mean = phases.iter().map(|&p| p as f64).sum::<f64>() / 200.0;
        // uniform: mean w/2, σ of the mean w/sqrt(12·200) ≈ 0.02 w
        assert!((mean / w as f64 - 0.5).abs() < 0.08, "{}", mean / w as f64);
        assert_ne!(clock_phase(3, 0), clock_phase(4, 0));
    }
}
