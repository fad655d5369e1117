//! The range sensors and the optical flow of a world's `[sensors]`
//! (DESIGN.md §9) against closed-form distances: a drone at known poses in
//! a box room, single rays and cones, the maximum range, noise, the flow
//! velocity in the body frame, and the checks of the table. Sensors sit
//! 0.02 m above the body origin (the Multi-ranger's Transform).

use std::f64::consts::{FRAC_PI_2, FRAC_PI_6};
use std::path::Path;

use protocol::{Reply, Request};
use rapier3d::glamx::{DQuat, DVec3};
use world_server::session::{Input, Outputs, Session, SessionError, SessionOutputs};
use world_server::{Millis, StepConfig, World, WorldDesc};

/// A room with its interior at x in [0, 4], y in [0, 3], walls 0.2 m thick
/// and a ceiling slab whose underside is at z = 2.0.
const ROOM: &str = r#"
[start]
position = [1.0, 1.2, 0.015]

[[box]]
centre = [2.0, -0.1, 1.0]
size = [4.4, 0.2, 2.0]
grey = 200
[[box]]
centre = [2.0, 3.1, 1.0]
size = [4.4, 0.2, 2.0]
grey = 200
[[box]]
centre = [-0.1, 1.5, 1.0]
size = [0.2, 3.0, 2.0]
grey = 200
[[box]]
centre = [4.1, 1.5, 1.0]
size = [0.2, 3.0, 2.0]
grey = 200
[[box]]
centre = [2.0, 1.5, 2.1]
size = [4.4, 3.4, 0.2]
grey = 200
"#;

fn desc(sensors: &str, extra: &str) -> WorldDesc {
    let text = format!("{ROOM}{extra}\n[sensors]\n{sensors}\n");
    WorldDesc::parse(&text, Path::new("room.toml")).unwrap()
}

fn world(sensors: &str, extra: &str) -> World {
    World::new(&desc(sensors, extra), StepConfig::default()).unwrap()
}

fn at(w: &mut World, x: f64, y: f64, z: f64, yaw: f64) {
    w.teleport(0, DVec3::new(x, y, z), DQuat::from_rotation_z(yaw));
}

/// Distance from (x, y) along heading `a` to the room's walls (closed form).
fn to_walls(x: f64, y: f64, a: f64) -> f64 {
    let (s, c) = a.sin_cos();
    let mut d = f64::INFINITY;
    if c > 1e-12 {
        d = d.min((4.0 - x) / c);
    }
    if c < -1e-12 {
        d = d.min(-x / c);
    }
    if s > 1e-12 {
        d = d.min((3.0 - y) / s);
    }
    if s < -1e-12 {
        d = d.min(-y / s);
    }
    d
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn single_rays_read_the_walls_ceiling_and_floor() {
    let mut w = world("range_max_m = 4.0\nup_down = true", "");
    at(&mut w, 1.0, 1.2, 0.5, 0.0);
    let s = w.sensors(0);
    // Front, left, back, right: 3.0, 1.8, 1.0, 1.2 m.
    for (got, want) in s.ranges_mm.iter().zip([3000.0, 1800.0, 1000.0, 1200.0]) {
        assert!(close(*got, want, 1e-6), "{:?}", s.ranges_mm);
    }
    // Up: ceiling at 2.0 from 0.52; down: the floor 0.52 below the sensors.
    let [up, down] = s.up_down_mm.unwrap();
    assert!(
        close(up, 1480.0, 1e-6) && close(down, 520.0, 1e-6),
        "{up} {down}"
    );
    assert_eq!(s.flow, None);
    // Turned 30°: every axis meets a wall at its closed-form distance.
    for yaw in [FRAC_PI_6, -1.0, 2.5] {
        at(&mut w, 1.0, 1.2, 0.5, yaw);
        let s = w.sensors(0);
        for (k, got) in s.ranges_mm.iter().enumerate() {
            let want = to_walls(1.0, 1.2, yaw + k as f64 * FRAC_PI_2) * 1000.0;
            assert!(
                close(*got, want.min(4000.0), 1e-6),
                "yaw {yaw} sensor {k}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn beyond_the_maximum_reads_the_maximum() {
    let mut w = world("range_max_m = 2.5", "");
    at(&mut w, 0.5, 1.5, 0.5, 0.0);
    let s = w.sensors(0);
    // Front: the wall 3.5 m away is beyond 2.5 m; back 0.5, left/right 1.5.
    assert_eq!(s.ranges_mm, [2500.0, 1500.0, 500.0, 1500.0]);
    assert_eq!(s.up_down_mm, None);
}

#[test]
fn a_cone_reports_the_nearest_return_in_its_field_of_view() {
    let cone = "range_max_m = 4.0\nrange_fov_deg = 20.0\nrange_rays = 21";
    let mut w = world(cone, "");
    // Square to the wall the nearest return is the axis: 3.0 m.
    at(&mut w, 1.0, 1.5, 0.5, 0.0);
    assert!(close(w.sensors(0).ranges_mm[0], 3000.0, 1e-6));
    // From (1, 0.5) turned 30°, the ray at 30° - 10° is the nearest:
    // 3 / cos 20° = 3.19 m to the east wall (the 40° ray meets the north
    // wall at 2.5 / sin 40° = 3.89 m).
    at(&mut w, 1.0, 0.5, 0.5, FRAC_PI_6);
    let want = 3.0 / 20f64.to_radians().cos() * 1000.0;
    assert!(close(w.sensors(0).ranges_mm[0], want, 1e-6), "{want}");

    // A 40 mm table leg 8° off the front axis: the single ray misses it,
    // the cone's 8° ray hits its near face at x = 2.48.
    let leg = "[[box]]\ncentre = [2.5, 1.7783, 0.5]\nsize = [0.04, 0.04, 1.0]\ngrey = 50\n";
    let (x, y) = (0.5, 1.5);
    let mut single = world("range_max_m = 4.0", leg);
    at(&mut single, x, y, 0.5, 0.0);
    assert!(close(single.sensors(0).ranges_mm[0], 3500.0, 1e-6));
    let mut w = world(cone, leg);
    at(&mut w, x, y, 0.5, 0.0);
    let want = (2.48 - x) / 8f64.to_radians().cos() * 1000.0;
    assert!(close(w.sensors(0).ranges_mm[0], want, 1e-6), "{want}");
}

#[test]
fn noise_is_gaussian_seeded_and_the_same_on_every_read() {
    let cfg = "range_max_m = 4.0\nrange_noise_m = 0.01\nseed = 7";
    let mut w = world(cfg, "");
    at(&mut w, 1.0, 1.5, 0.5, 0.0);
    let mut errs = Vec::new();
    for _ in 0..400 {
        let a = w.sensors(0);
        assert_eq!(a, w.sensors(0), "a reading depends on the time only");
        errs.push(a.ranges_mm[0] - 3000.0);
        w.advance(32).unwrap();
        at(&mut w, 1.0, 1.5, 0.5, 0.0);
    }
    let n = errs.len() as f64;
    let mean = errs.iter().sum::<f64>() / n;
    let sd = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    // σ = 10 mm: the mean of 400 within 4 σ/√n = 2 mm, the spread within 15 %.
    assert!(mean.abs() < 2.0, "mean {mean}");
    assert!((sd - 10.0).abs() < 1.5, "sd {sd}");
    // Same seed, same readings; another seed, others.
    let mut w2 = world(cfg, "");
    at(&mut w2, 1.0, 1.5, 0.5, 0.0);
    let mut w3 = world(&cfg.replace("seed = 7", "seed = 8"), "");
    at(&mut w3, 1.0, 1.5, 0.5, 0.0);
    let first = world(cfg, "").sensors(0);
    assert_eq!(w2.sensors(0).ranges_mm, {
        let mut w = world(cfg, "");
        at(&mut w, 1.0, 1.5, 0.5, 0.0);
        w.sensors(0).ranges_mm
    });
    assert_ne!(w2.sensors(0).ranges_mm[0], w3.sensors(0).ranges_mm[0]);
    // A reading at the maximum (nothing within) carries no noise.
    assert_eq!(first.time, Millis(0));
}

#[test]
fn flow_is_the_body_frame_velocity_scaled() {
    let mut w = world("flow = true\nflow_scale = 1.02", "");
    at(&mut w, 1.0, 1.5, 0.5, FRAC_PI_2);
    w.set_velocities(0, DVec3::new(0.3, 0.4, 0.0), DVec3::ZERO);
    // Facing +y: forward is world +y (0.4), left is world −x (−0.3).
    let [vx, vy] = w.sensors(0).flow.unwrap();
    assert!(
        close(vx, 0.408, 1e-12) && close(vy, -0.306, 1e-12),
        "{vx} {vy}"
    );
    // Noise σ = 0.05 m/s about it.
    let mut w = world("flow = true\nflow_noise_m_s = 0.05\nseed = 3", "");
    at(&mut w, 1.0, 1.5, 0.5, 0.0);
    w.set_velocities(0, DVec3::new(0.3, 0.0, 0.0), DVec3::ZERO);
    let [vx, _] = w.sensors(0).flow.unwrap();
    assert!(vx != 0.3 && (vx - 0.3).abs() < 0.25, "{vx}");
}

#[test]
fn the_race_default_has_four_2_m_rays_and_nothing_more() {
    let text = ROOM.to_string();
    let d = WorldDesc::parse(&text, Path::new("room.toml")).unwrap();
    assert!(d.sensors.is_race_rangers());
    let mut w = World::new(&d, StepConfig::default()).unwrap();
    at(&mut w, 1.0, 1.2, 0.5, 0.0);
    let s = w.sensors(0);
    assert_eq!(s.ranges_mm, [2000.0, 1800.0, 1000.0, 1200.0]);
    assert_eq!((s.up_down_mm, s.flow), (None, None));
}

fn error_of(sensors: &str) -> String {
    let text = format!("{ROOM}\n[sensors]\n{sensors}\n");
    WorldDesc::parse(&text, Path::new("room.toml"))
        .unwrap_err()
        .to_string()
}

#[test]
fn bad_sensor_tables_are_refused_with_the_reason() {
    let e = error_of("range_fov_deg = 120.0");
    assert!(e.contains("sensors") && e.contains("wider than 90"), "{e}");
    let e = error_of("range_fov_deg = 20.0\nrange_rays = 1");
    assert!(e.contains("needs range_rays >= 2"), "{e}");
    let e = error_of("range_rays = 5");
    assert!(e.contains("needs range_fov_deg > 0"), "{e}");
    let e = error_of("range_fov_deg = 20.0\nrange_rays = 1000");
    assert!(e.contains("1..=181"), "{e}");
    let e = error_of("range_max_m = -1.0");
    assert!(e.contains("> 0"), "{e}");
    let e = error_of("flow_noise = 0.1");
    assert!(e.contains("unknown field `flow_noise`"), "{e}");
}

/// The replies of a session.
#[derive(Default)]
struct Replies(Vec<Reply>);

impl Outputs for Replies {
    fn request(&mut self, _: usize, _: &[u8], _: bool, _: Millis) -> Result<(), SessionError> {
        Ok(())
    }
    fn reply(&mut self, _: usize, reply: Reply, _: Millis) -> Result<(), SessionError> {
        self.0.push(reply);
        Ok(())
    }
}

#[test]
fn get_sensors_carries_up_down_and_flow_when_the_world_asks() {
    let get = |sensors: &str| {
        let d = desc(sensors, "");
        let mut s = Session::new(&d, StepConfig::default(), SessionOutputs::default()).unwrap();
        s.warm_up().unwrap();
        let mut body = Vec::new();
        protocol::encode_request(&Request::GetSensors, &mut body);
        let request = protocol::decode_request(&body);
        s.push(0, Input::Frame { body, request }).unwrap();
        let mut out = Replies::default();
        s.run(&mut out).unwrap();
        match out.0.pop() {
            Some(Reply::Sensors(x)) => x,
            other => panic!("{other:?}"),
        }
    };
    let s = get("range_max_m = 4.0\nup_down = true\nflow = true");
    // On the ground after the warm-up (the drone rests within a few
    // millimetres and milliradians of its start pose): the floor 0.035 m
    // below the sensors, the ceiling 1.965 m above, the left wall 1.8 m
    // away. (The front ray, tilted 13 mrad down, meets the floor at 2.8 m.)
    assert!(close(s.range_down.unwrap(), 35.0, 1.0), "{s:?}");
    assert!(close(s.range_up.unwrap(), 1965.0, 1.0), "{s:?}");
    assert!(close(s.range_left, 1800.0, 1.0), "{s:?}");
    assert!(
        s.flow_vx.unwrap().abs() < 0.02 && s.flow_vy.unwrap().abs() < 0.02,
        "{s:?}"
    );
    let s = get("range_max_m = 4.0");
    assert_eq!(
        (s.range_up, s.range_down, s.flow_vx, s.flow_vy),
        (None, None, None, None)
    );
}
