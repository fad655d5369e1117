//! The shipped world files: the thesis's course puts a gate on every race
//! target (DESIGN.md §5), facing along the path, and leaves the straight legs
//! between targets clear of every bar and leg.

use std::path::{Path, PathBuf};

use rapier3d::glamx::{DQuat, DVec3};
use world_server::crazyflie::BODY_RADIUS_M;
use world_server::scene::{scene_boxes, SceneBox};
use world_server::WorldDesc;

fn world(name: &str) -> WorldDesc {
    let p: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios/worlds")
        .join(name);
    WorldDesc::load(&p).unwrap()
}

/// The race targets of Appendix D, after the start.
const TARGETS: [[f64; 3]; 11] = [
    [-0.8, 1.5, 1.0],
    [2.0, -0.4, 1.0],
    [4.7, 1.7, 1.0],
    [7.7, 3.1, 1.0],
    [9.8, 2.0, 1.0],
    [11.3, -3.5, 1.0],
    [9.4, -6.4, 2.15],
    [5.3, -6.5, 3.15],
    [1.6, -5.8, 1.65],
    [-0.3, -4.7, 1.35],
    [-2.6, 0.0, 1.0],
];

/// Distance from `p` to an oriented box (0 inside).
fn distance(b: &SceneBox, p: DVec3) -> f64 {
    let local = DQuat::from_rotation_z(-b.yaw) * (p - b.centre);
    (local.abs() - b.half).max(DVec3::ZERO).length()
}

#[test]
fn every_target_but_home_is_a_gate_centre_facing_along_the_path() {
    let w = world("thesis-course.toml");
    assert_eq!(w.start.position.0, [-2.6, 0.0, 0.015]);
    assert!((w.start.yaw.0 - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert_eq!(w.gates.len(), 10);
    let mut prev = DVec3::from_array(w.start.position.0);
    for (i, g) in w.gates.iter().enumerate() {
        let t = DVec3::from_array(TARGETS[i]);
        assert_eq!(g.centre.0, TARGETS[i], "gate {}", i + 1);
        // The gate normal is within 40° of both the incoming and the outgoing leg.
        let normal = DVec3::new(g.yaw.0.cos(), g.yaw.0.sin(), 0.0);
        let next = DVec3::from_array(TARGETS[i + 1]);
        for leg in [t - prev, next - t] {
            let leg = leg.with_z(0.0).normalize();
            let angle = leg.dot(normal).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(angle < 40.0, "gate {}: {angle:.1}° off the path", i + 1);
        }
        prev = t;
    }
}

#[test]
fn the_legs_between_targets_clear_every_gate() {
    let w = world("thesis-course.toml");
    let boxes = scene_boxes(&w);
    // Take-off above the start, then the race, with the altitude changing
    // linearly along each leg; the drone needs its radius plus 10 cm.
    let mut points = vec![DVec3::new(-2.6, 0.0, 1.0)];
    points.extend(TARGETS.iter().map(|t| DVec3::from_array(*t)));
    let clearance = BODY_RADIUS_M + 0.1;
    for leg in points.windows(2) {
        let n = ((leg[1] - leg[0]).length() / 0.01).ceil() as usize;
        for k in 0..=n {
            let p = leg[0].lerp(leg[1], k as f64 / n as f64);
            for b in &boxes {
                let d = distance(b, p);
                assert!(
                    d > clearance,
                    "{p:?} on the leg {:?} → {:?} is {d:.3} m from {:?}",
                    leg[0],
                    leg[1],
                    b.object
                );
            }
        }
    }
}

#[test]
fn the_empty_world_is_empty() {
    let w = world("empty.toml");
    assert!(w.gates.is_empty() && w.boxes.is_empty());
    assert_eq!(w.start.position.0, [-2.6, 0.0, 0.015]);
}
