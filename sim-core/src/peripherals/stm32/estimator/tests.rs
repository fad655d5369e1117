//! Closed-form checks of the flow filter.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::*;

const DT: Seconds = Seconds(0.032);

fn level(yaw: f64) -> Attitude {
    Attitude {
        roll: 0.0,
        pitch: 0.0,
        yaw,
    }
}

#[test]
fn the_covariance_converges_to_the_riccati_fixed_point() {
    let p = FlowFilterParams::default();
    let mut f = FlowFilter::new(p, [0.0; 2]);
    for _ in 0..2000 {
        f.step(DT, level(0.0), [0.0, 0.0]);
    }
    // After the update, P = (1 − K)·P⁻ = K·r at the fixed point.
    let k = p.steady_state_gain(DT);
    let expected = k * p.flow_std.0.powi(2);
    assert!(
        (f.variance() - expected).abs() < 1e-9 * expected.max(1e-12),
        "{} vs {expected}",
        f.variance()
    );
    // With the defaults (σ = 0.069 m/s, σₐ = 0.03 m/s², 32 ms): q = 9.216e-7,
    // r = 4.761e-3, P⁻ = 6.670e-5, K = 0.01382.
    assert!((k - 0.01382).abs() < 1e-5, "K = {k}");
}

#[test]
fn stationary_noise_is_reduced_by_the_predicted_factor() {
    // Hovering level, flow = pure noise: the estimate's variance is
    // K/(2 − K)·σ² (0.00696·σ² with the defaults: σ 0.069 → 0.0058 m/s).
    let p = FlowFilterParams::default();
    let mut f = FlowFilter::new(p, [0.0; 2]);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let sigma = p.flow_std.0;
    let (mut sum, mut sum2, mut n) = ([0.0; 2], [0.0; 2], 0.0);
    for i in 0..400_000 {
        let z: [f64; 2] = std::array::from_fn(|_| {
            let x: f64 = StandardNormal.sample(&mut rng);
            sigma * x
        });
        f.step(DT, level(0.3), z);
        if i >= 1000 {
            for a in 0..2 {
                sum[a] += f.velocity()[a];
                sum2[a] += f.velocity()[a].powi(2);
            }
            n += 1.0;
        }
    }
    let predicted = p.steady_state_noise_variance(DT);
    for a in 0..2 {
        let mean = sum[a] / n;
        let var = sum2[a] / n - mean * mean;
        // 400 000 correlated samples (correlation time 1/K ≈ 72 steps):
        // about 5 500 independent ones, a relative error of √(2/5500) = 1.9 %.
        assert!(
            (var / predicted - 1.0).abs() < 0.08,
            "axis {a}: variance {var:.3e}, predicted {predicted:.3e}"
        );
        assert!(
            predicted / sigma.powi(2) < 0.01,
            "reduction {}",
            predicted / sigma.powi(2)
        );
    }
}

#[test]
fn a_constant_tilt_is_tracked_without_lag() {
    // Pitch 3° at yaw 90°: forward is world +y, a = g·tan 3° = 0.514 m/s².
    // The flow (the true body velocity + noise) and the prediction agree,
    // so the estimate follows v = a·t with only the noise's error.
    let p = FlowFilterParams::default();
    let att = Attitude {
        roll: 0.0,
        pitch: 3f64.to_radians(),
        yaw: std::f64::consts::FRAC_PI_2,
    };
    let a = G * att.pitch.tan();
    let mut f = FlowFilter::new(p, [1.0, 2.0]);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let bound = 4.0 * p.steady_state_noise_variance(DT).sqrt();
    let mut t = 0.0;
    for _ in 0..100 {
        t += DT.0;
        let v = a * t;
        let n: [f64; 2] = std::array::from_fn(|_| {
            let x: f64 = StandardNormal.sample(&mut rng);
            p.flow_std.0 * x
        });
        f.step(DT, att, [v + n[0], n[1]]);
        let e = f.velocity();
        assert!(e[0].abs() < bound, "sideways {} at {t}", e[0]);
        assert!((e[1] - v).abs() < bound, "{} vs {v} at {t}", e[1]);
    }
    // Position: ½·a·t² (3.2 s: 2.63 m), up to the integrated noise and the
    // half step of the rectangle rule (a·t·dt/2 = 0.026 m).
    let x = f.position();
    let expected = 0.5 * a * t * t;
    assert!((x[0] - 1.0).abs() < 0.05, "x {}", x[0]);
    assert!(
        (x[1] - 2.0 - expected).abs() < 0.06,
        "{} vs {expected}",
        x[1] - 2.0
    );
}

#[test]
fn roll_accelerates_to_the_right_and_yaw_rotates_the_flow() {
    // Positive roll tilts the thrust to −y (the controller's roll demand
    // is −kp·vy error, pid.rs).
    let a = tilt_acceleration(Attitude {
        roll: 0.1,
        pitch: 0.0,
        yaw: 0.0,
    });
    assert!((a[1] + G * 0.1f64.tan()).abs() < 1e-12 && a[0].abs() < 1e-12);
    // Yaw 90°: the body's forward flow is world +y.
    let w = rotate(std::f64::consts::FRAC_PI_2, [1.0, 0.0]);
    assert!(w[0].abs() < 1e-12 && (w[1] - 1.0).abs() < 1e-12);
}

#[test]
fn without_noise_the_filter_is_the_raw_flow() {
    // σ = 0: the gain is 1, the estimate is the flow and the position its
    // integral (the model before this filter).
    let p = FlowFilterParams {
        flow_std: MetresPerSecond(0.0),
        ..FlowFilterParams::default()
    };
    let mut f = FlowFilter::new(p, [0.0; 2]);
    f.step(DT, level(0.0), [0.3, -0.1]);
    f.step(DT, level(0.0), [0.5, -0.2]);
    assert_eq!(f.velocity(), [0.5, -0.2]);
    let x = f.position();
    assert!((x[0] - 0.8 * DT.0).abs() < 1e-15 && (x[1] + 0.3 * DT.0).abs() < 1e-15);
}

#[test]
fn an_external_position_is_a_scalar_kalman_update() {
    let p = FlowFilterParams::default();
    let mut f = FlowFilter::new(p, [0.0, 0.0]);
    // At the known start the estimate is exact: a measurement moves nothing.
    assert_eq!(f.fuse_position([0.3, 0.3], Metres(0.01)), [0.0, 0.0]);
    // Each step adds (σ·dt)² + (ε·|v|·dt)², |v| the step's filtered speed.
    let mut expected = 0.0;
    for _ in 0..100 {
        f.step(DT, level(0.0), [0.5, 0.0]);
        let v = f.velocity()[0].hypot(f.velocity()[1]);
        expected += (p.flow_std.0 * DT.0).powi(2) + (FLOW_SCALE_STD * v * DT.0).powi(2);
    }
    let var = f.position_variance();
    assert!((var - expected).abs() < 1e-15, "{var} vs {expected}");
    let before = f.position();
    let r: f64 = 0.02 * 0.02;
    let k = var / (var + r);
    let m = [before[0] - 0.1, before[1] + 0.2];
    let after = f.fuse_position(m, Metres(0.02));
    assert!((after[0] - (before[0] - 0.1 * k)).abs() < 1e-12);
    assert!((after[1] - (before[1] + 0.2 * k)).abs() < 1e-12);
    assert!((f.position_variance() - (1.0 - k) * var).abs() < 1e-15);
    // The velocity is untouched.
    assert_eq!(f.velocity()[1], 0.0);
}

#[test]
fn external_positions_bound_the_drift_of_a_scaled_flow() {
    // The Flow deck reads 5 % fast (seed 004's room: flow_scale 1.05). The
    // drone pitches 0.05 rad for 1 s (0.49 m/s) and cruises level for 19 s
    // (9.3 m): dead reckoning drifts by about 5 % of that, and a 10 Hz
    // position measurement (σ 1 cm, every third 32 ms step) keeps the
    // error at a few centimetres.
    let p = FlowFilterParams::default();
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    let mut noise = || -> f64 {
        let x: f64 = StandardNormal.sample(&mut rng);
        x
    };
    let (mut free, mut fused) = (FlowFilter::new(p, [0.0; 2]), FlowFilter::new(p, [0.0; 2]));
    let (mut x, mut v) = (0.0, 0.0);
    let mut worst_fused: f64 = 0.0;
    for i in 1..=625 {
        let pitch = if i <= 31 { 0.05 } else { 0.0 };
        let att = Attitude {
            pitch,
            ..level(0.0)
        };
        v += G * f64::tan(pitch) * DT.0;
        x += v * DT.0;
        let flow = [1.05 * v + p.flow_std.0 * noise(), p.flow_std.0 * noise()];
        free.step(DT, att, flow);
        fused.step(DT, att, flow);
        if i % 3 == 0 {
            fused.fuse_position([x + 0.01 * noise(), 0.01 * noise()], Metres(0.01));
        }
        let e = fused.position();
        worst_fused = worst_fused.max((e[0] - x).hypot(e[1]));
    }
    let free_error = (free.position()[0] - x).hypot(free.position()[1]);
    assert!(
        free_error > 0.3,
        "dead reckoning drifted only {free_error} m in {x} m"
    );
    assert!(worst_fused < 0.05, "fused error up to {worst_fused} m");
    eprintln!("free {free_error} m, fused at most {worst_fused} m over {x} m");
}
