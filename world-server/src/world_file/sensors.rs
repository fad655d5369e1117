//! `[sensors]`: the range sensors and the optical flow of a world
//! (DESIGN.md §9). Without the table a world has the race's sensors: the
//! four DistanceSensors of the Webots PROTO, single rays, 2 m, no noise, no
//! up/down ranges and no flow, so the race's outputs do not change.

use serde::Deserialize;

use super::{NonNegative, Positive};
use crate::crazyflie::RANGE_MAX_M;

/// Most rays one ranger may cast (one ray per 0.1° over a 90° fan is 900:
/// far beyond what any map needs; the bound keeps GET_SENSORS cheap).
pub const MAX_RAYS: u32 = 181;

/// The widest field of view accepted, degrees.
pub const MAX_FOV_DEG: f64 = 90.0;

/// The world's range sensors and flow sensor, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorConfig {
    /// Maximum range of every ranger (m); nothing within it reads as the
    /// maximum. The race's lookup table saturates at 2 m (DESIGN.md §5);
    /// the VL53L1x of the Multi-ranger and Flow decks measures up to 4 m
    /// (seed 004 §3.1).
    pub range_max_m: f64,
    /// σ of the Gaussian noise added to a ranger's reading (m), drawn per
    /// drone, sensor and world time; 0 = none.
    pub range_noise_m: f64,
    /// Field of view of a ranger (degrees): it reports the nearest return of
    /// `range_rays` rays spread evenly over the FOV in the body's horizontal
    /// plane (the up and down rangers: in the body's x-z plane). 0 = one ray.
    pub range_fov_deg: f64,
    /// Rays per ranger (1 when the FOV is 0).
    pub range_rays: u32,
    /// Report `RANGE_UP` and `RANGE_DOWN` in GET_SENSORS.
    pub up_down: bool,
    /// Report the optical-flow velocity `FLOW_VX`, `FLOW_VY` in GET_SENSORS.
    pub flow: bool,
    /// σ of the flow velocity's Gaussian noise (m/s), per axis and 32 ms
    /// sample; at another timestep the world scales it by √(32 ms / ts)
    /// (`TimestepMs::white_noise_scale`: the same noise density).
    pub flow_noise_m_s: f64,
    /// Scale factor of the flow velocity (1 = exact): a flow sensor that
    /// misjudges the height over the floor or the texture scales every
    /// reading, and dead reckoning drifts with the distance flown.
    pub flow_scale: f64,
    /// Seed of the sensor noise (ChaCha streams keyed by seed, drone,
    /// sensor and time).
    pub seed: u64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            range_max_m: RANGE_MAX_M,
            range_noise_m: 0.0,
            range_fov_deg: 0.0,
            range_rays: 1,
            up_down: false,
            flow: false,
            flow_noise_m_s: 0.0,
            flow_scale: 1.0,
            seed: 0,
        }
    }
}

impl SensorConfig {
    /// True when the rangers are the race's (one ray, 2 m, no noise).
    pub fn is_race_rangers(&self) -> bool {
        self.range_max_m == RANGE_MAX_M
            && self.range_noise_m == 0.0
            && self.range_fov_deg == 0.0
            && self.range_rays == 1
    }

    /// The rays' angles (rad) about the sensor's axis, evenly spread over
    /// the FOV, ends included (one ray: 0). An iterator: asked for on every
    /// GET_SENSORS, so nothing is allocated.
    pub fn ray_angles(&self) -> impl Iterator<Item = f64> + Clone {
        let n = self.range_rays.max(1);
        let half = self.range_fov_deg.to_radians() / 2.0;
        (0..n).map(move |i| {
            if n == 1 {
                0.0
            } else {
                -half + 2.0 * half * f64::from(i) / f64::from(n - 1)
            }
        })
    }
}

/// `[sensors]` as written (checked by `SensorConfig::try_from`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSensors {
    #[serde(default)]
    range_max_m: Option<Positive>,
    #[serde(default)]
    range_noise_m: NonNegative,
    #[serde(default)]
    range_fov_deg: NonNegative,
    #[serde(default)]
    range_rays: Option<u32>,
    #[serde(default)]
    up_down: bool,
    #[serde(default)]
    flow: bool,
    #[serde(default)]
    flow_noise_m_s: NonNegative,
    #[serde(default)]
    flow_scale: Option<Positive>,
    #[serde(default)]
    seed: u64,
}

impl TryFrom<RawSensors> for SensorConfig {
    type Error = String;
    fn try_from(r: RawSensors) -> Result<Self, String> {
        let fov = r.range_fov_deg.0;
        if fov > MAX_FOV_DEG {
            return Err(format!(
                "range_fov_deg = {fov} is wider than {MAX_FOV_DEG} degrees"
            ));
        }
        let rays = r.range_rays.unwrap_or(if fov > 0.0 { 9 } else { 1 });
        if rays == 0 || rays > MAX_RAYS {
            return Err(format!("range_rays = {rays} must be 1..={MAX_RAYS}"));
        }
        if fov > 0.0 && rays < 2 {
            return Err(format!(
                "range_fov_deg = {fov} needs range_rays >= 2 (one ray has no width)"
            ));
        }
        if fov == 0.0 && rays != 1 {
            return Err(format!(
                "range_rays = {rays} needs range_fov_deg > 0 (rays over a zero FOV coincide)"
            ));
        }
        Ok(SensorConfig {
            range_max_m: r.range_max_m.map_or(RANGE_MAX_M, |p| p.0),
            range_noise_m: r.range_noise_m.0,
            range_fov_deg: fov,
            range_rays: rays,
            up_down: r.up_down,
            flow: r.flow,
            flow_noise_m_s: r.flow_noise_m_s.0,
            flow_scale: r.flow_scale.map_or(1.0, |p| p.0),
            seed: r.seed,
        })
    }
}
