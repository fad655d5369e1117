//! The flow-mode state estimator of the STM32 model (DESIGN.md §9): a Kalman
//! filter on the horizontal velocity, predicted from the attitude and
//! corrected by the Flow deck's optical-flow velocity; the position is the
//! integral of the filtered velocity (dead reckoning: its error is never
//! corrected, so it drifts, as the seed's maps did, §5.1).
//!
//! Structure, after the Bitcraze EKF (crazyflie-firmware
//! `src/modules/src/kalman_core/kalman_core.c` and `mm_flow.c`), reduced to
//! what the model has:
//!
//! - **Prediction.** The Bitcraze EKF integrates the accelerometer's
//!   thrust along the body z axis, rotated into the world frame. The model
//!   has no accelerometer (GET_SENSORS gives the InertialUnit's attitude,
//!   the gyro, GPS, ranges and flow), so the thrust is taken as what holds
//!   the height (its vertical part equals m·g): the horizontal acceleration
//!   is g·(body z)ₓᵧ/(body z)₂. With Webots's roll φ, pitch θ (ZYX) this is
//!   g·tan θ forward and −g·tan φ / cos θ to the left, in the yaw frame, then
//!   rotated by the yaw. The acceleration over a step is the mean of the
//!   two samples' (trapezoid). The model's errors (thrust ≠ m·g while
//!   climbing, attitude changes within the step, contact with the ground)
//!   are the process noise: white acceleration of σₐ.
//! - **Measurement.** `mm_flow.c` predicts the flow pixels from the body
//!   velocity, the height and the gyro; the world's flow sensor gives the
//!   body-frame velocity directly (scaled and noisy, no rotation term), so
//!   the measurement is that velocity, rotated by the yaw into the world
//!   frame (tilt neglected: the flow of the tilted body's x, y axes differs
//!   from the yaw frame's by vz·sin θ and v·(1 − cos θ), below 1 mm/s at
//!   the 0.2 m/s and 5° of these flights). Its noise σ is white and the
//!   same on both axes, so rotating it keeps its covariance σ²·I.
//! - **Covariance.** With isotropic noise on both axes and an isotropic
//!   start, the 2 × 2 covariance stays σᵥ²·I: one scalar per filter, two
//!   scalar updates (as `mm_flow.c`'s two scalar updates).
//!
//! - **External positions** (DESIGN.md §17: cflib's `send_extpos`, a motion
//!   capture system's measurement). The Bitcraze EKF fuses them as a
//!   position measurement with the standard deviation `locSrv.extPosStdDev`
//!   (`mm_position.c`). Here the position is not a state of the velocity
//!   filter, so the update is a scalar Kalman update on the dead-reckoned
//!   position alone, one per axis, with its own error variance Pₚ:
//!   K = Pₚ/(Pₚ + σₘ²), p += K·(m − p), Pₚ = (1 − K)·Pₚ. Pₚ is 0 at the
//!   known start and grows each step by what dead reckoning adds: the flow
//!   noise integrated, (σ·dt)² (the filter has unit gain at low frequency,
//!   so the integral of its estimate's noise grows as the raw flow's), plus
//!   a flow scale error of [`FLOW_SCALE_STD`] × the speed, (ε·|v|·dt)². The
//!   velocity is not corrected (it has no covariance with the position
//!   here): the next steps integrate from the corrected position, so the
//!   drift is pulled back at every measurement and cannot accumulate. No
//!   measurement, no change: without external positions the filter's
//!   estimate is exactly the dead reckoning it was.
//!
//! Why a filter and not the raw flow: the velocity loop of the Bitcraze
//! controller differentiates the velocity error (kd_vel_xy = 0.5 over a
//! 32 ms step), so per-sample noise σ becomes attitude demands of about
//! 0.5·σ·√2/0.032 rad. A low-pass filter lags the loop; this filter does
//! not, since the attitude it predicts from is the loop's own output, and
//! only the model's error is filtered.

use std::f64::consts::PI;

// Gravity (m/s²): the power models' (Table 4.4), the world's too.
use crate::power::models::G;

/// A speed or its standard deviation (m/s).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct MetresPerSecond(pub f64);

/// An acceleration or its standard deviation (m/s²).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct MetresPerSecond2(pub f64);

/// A distance or its standard deviation (m).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Metres(pub f64);

/// A time step (s).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Seconds(pub f64);

/// The filter's noise settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowFilterParams {
    /// The flow measurement's standard deviation per sample (run key
    /// `stm32.flow_std_m_s`; it should match the world's `flow_noise_m_s`).
    pub flow_std: MetresPerSecond,
    /// The prediction's error: white acceleration noise.
    pub accel_std: MetresPerSecond2,
}

/// Default process noise σₐ (m/s²). Tuned on the world's Crazyflie, not a
/// Bitcraze number (the EKF's process noise is on the accelerometer, which
/// the model has not): small enough that the filter's steady-state gain
/// keeps the noise's step-to-step change well below what tips the velocity
/// loop's derivative term (see the module's note), large enough that the
/// thrust ≠ m·g of a climb is followed within a second.
pub const DEFAULT_ACCEL_STD: MetresPerSecond2 = MetresPerSecond2(0.03);

/// Default flow σ per 32 ms sample (m/s), the Flow deck v2's: the Bitcraze
/// EKF weighs each 10 ms PMW3901 reading with σ = 2.0 × 0.1 pixels
/// (`flowdeck_v1v2.c`: `flowStdFixed = 2.0`; `mm_flow.c`: `FLOW_RESOLUTION
/// = 0.1`), and a pixel count N over dt is a velocity N·z·θₚ/(Nₚ·dt) with
/// Nₚ = 35 pixels and θₚ = 0.71674 rad (`mm_flow.c`). At the seed's 0.3 m
/// flight height a 10 ms reading has σ = 0.2 · 0.3 · 0.71674 / (35 · 0.01)
/// = 0.123 m/s; a 32 ms sample sums 3.2 readings' pixels: σ = 0.123/√3.2 =
/// 0.069 m/s.
pub const DEFAULT_FLOW_STD: MetresPerSecond = MetresPerSecond(0.069);

/// The flow's scale uncertainty assumed by the position variance (a
/// fraction of the speed): the Flow deck's velocity is the pixel rate times
/// the height, so a height misjudged by 5 % scales it by 5 % (the world's
/// `flow_scale` = 1.05 in seed 004's room models exactly this).
pub const FLOW_SCALE_STD: f64 = 0.05;

impl Default for FlowFilterParams {
    fn default() -> Self {
        FlowFilterParams {
            flow_std: DEFAULT_FLOW_STD,
            accel_std: DEFAULT_ACCEL_STD,
        }
    }
}

impl FlowFilterParams {
    /// The steady-state Kalman gain of one axis at step `dt`: the fixed
    /// point of P⁻ = P + q, K = P⁻/(P⁻ + r), P = (1 − K)·P⁻ with
    /// q = (σₐ·dt)², r = σ²: P⁻ = (q + √(q² + 4qr))/2.
    pub fn steady_state_gain(&self, dt: Seconds) -> f64 {
        let q = (self.accel_std.0 * dt.0).powi(2);
        let r = self.flow_std.0.powi(2);
        let prior = (q + (q * q + 4.0 * q * r).sqrt()) / 2.0;
        prior / (prior + r)
    }

    /// The steady-state variance of the velocity estimate's error from the
    /// flow noise alone, for a perfect model: the filter is then the
    /// first-order recursion e' = (1 − K)·e + K·n, whose variance is
    /// K/(2 − K)·σ².
    pub fn steady_state_noise_variance(&self, dt: Seconds) -> f64 {
        let k = self.steady_state_gain(dt);
        k / (2.0 - k) * self.flow_std.0.powi(2)
    }
}

/// The attitude of one sensor read (rad): Webots's InertialUnit angles.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Attitude {
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}

/// The horizontal acceleration (world frame, m/s²) of a drone whose thrust
/// holds its height, at `att` (see the module's note).
pub fn tilt_acceleration(att: Attitude) -> [f64; 2] {
    // Beyond ±80° the model is meaningless (and tan grows without bound):
    // a flipped drone is the world's to report, the filter only stays finite.
    let lim = 80.0 * PI / 180.0;
    let (roll, pitch) = (att.roll.clamp(-lim, lim), att.pitch.clamp(-lim, lim));
    let forward = G * pitch.tan();
    let left = -G * roll.tan() / pitch.cos();
    rotate(att.yaw, [forward, left])
}

/// A body (yaw-frame) vector rotated by `yaw` into the world frame.
pub fn rotate(yaw: f64, v: [f64; 2]) -> [f64; 2] {
    let (s, c) = yaw.sin_cos();
    [v[0] * c - v[1] * s, v[0] * s + v[1] * c]
}

/// The filter's state: world-frame velocity and position (x, y).
#[derive(Debug, Clone, PartialEq)]
pub struct FlowFilter {
    params: FlowFilterParams,
    velocity: [f64; 2],
    position: [f64; 2],
    /// Variance of each velocity component's error (m²/s²).
    variance: f64,
    /// Variance of each position component's error (m²), for external
    /// position updates (see the module's note).
    position_variance: f64,
    /// The previous sample's tilt acceleration (for the trapezoid).
    last_accel: Option<[f64; 2]>,
}

impl FlowFilter {
    /// At rest at `position` (INIT_PID: on the ground, motors off, so the
    /// velocity is known to be zero).
    pub fn new(params: FlowFilterParams, position: [f64; 2]) -> Self {
        FlowFilter {
            params,
            velocity: [0.0; 2],
            position,
            variance: 0.0,
            position_variance: 0.0,
            last_accel: None,
        }
    }

    pub fn velocity(&self) -> [f64; 2] {
        self.velocity
    }

    pub fn position(&self) -> [f64; 2] {
        self.position
    }

    /// The velocity error's variance per axis.
    pub fn variance(&self) -> f64 {
        self.variance
    }

    /// The position error's variance per axis (m²): the firmware's
    /// `kalman.varPX`, `varPY`.
    pub fn position_variance(&self) -> f64 {
        self.position_variance
    }

    /// An external position measurement `m` (x, y) with standard deviation
    /// `std` (m): the scalar Kalman update of the module's note. Returns
    /// the corrected position.
    pub fn fuse_position(&mut self, m: [f64; 2], std: Metres) -> [f64; 2] {
        let r = std.0 * std.0;
        let p = self.position_variance;
        // An exact measurement (σ = 0) replaces the estimate; otherwise
        // p + r > 0.
        let k = if r > 0.0 { p / (p + r) } else { 1.0 };
        for (e, m) in self.position.iter_mut().zip(m) {
            *e += k * (m - *e);
        }
        self.position_variance = (1.0 - k) * p;
        self.position
    }

    /// One sensor read `dt` after the previous one: predict with the
    /// attitude, correct with the body-frame flow, integrate the position
    /// with the corrected velocity (so that the position's difference over
    /// the step is the filtered velocity the controller then sees).
    pub fn step(&mut self, dt: Seconds, att: Attitude, flow_body: [f64; 2]) {
        let accel = tilt_acceleration(att);
        let mean = match self.last_accel {
            Some(a) => [(a[0] + accel[0]) / 2.0, (a[1] + accel[1]) / 2.0],
            None => accel,
        };
        self.last_accel = Some(accel);
        if dt.0 <= 0.0 {
            return;
        }
        // Predict.
        for (v, a) in self.velocity.iter_mut().zip(mean) {
            *v += a * dt.0;
        }
        self.variance += (self.params.accel_std.0 * dt.0).powi(2);
        // Correct: two scalar updates with the same gain.
        let r = self.params.flow_std.0.powi(2);
        let z = rotate(att.yaw, flow_body);
        let k = if self.variance + r > 0.0 {
            self.variance / (self.variance + r)
        } else {
            1.0
        };
        for (v, z) in self.velocity.iter_mut().zip(z) {
            *v += k * (z - *v);
        }
        self.variance *= 1.0 - k;
        for (p, v) in self.position.iter_mut().zip(self.velocity) {
            *p += v * dt.0;
        }
        let speed = self.velocity[0].hypot(self.velocity[1]);
        self.position_variance +=
            (self.params.flow_std.0 * dt.0).powi(2) + (FLOW_SCALE_STD * speed * dt.0).powi(2);
    }
}

/// How far the dead-reckoned position strays from the world's GPS (which
/// the flow mode does not fly on): the drift, horizontal, m. Reported in
/// `summary.json` as `flow_drift`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Drift {
    pub samples: u64,
    pub last_m: f64,
    pub max_m: f64,
    sum_m: f64,
}

impl Drift {
    pub fn record(&mut self, truth: [f64; 2], estimate: [f64; 2]) {
        let d = (estimate[0] - truth[0]).hypot(estimate[1] - truth[1]);
        self.samples += 1;
        self.last_m = d;
        self.max_m = self.max_m.max(d);
        self.sum_m += d;
    }

    /// The mean over the samples (0 without any).
    pub fn mean_m(&self) -> f64 {
        if self.samples == 0 {
            0.0
        } else {
            self.sum_m / self.samples as f64
        }
    }
}

#[cfg(test)]
mod tests;
