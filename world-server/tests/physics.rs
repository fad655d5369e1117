//! Physics and sensors against closed-form results (DESIGN.md §5).

use std::path::Path;

use rapier3d::glamx::{DQuat, DVec3};
use world_server::crazyflie::{self, hover_speed, principal_inertia, TORQUE_CONSTANT};
use world_server::{Millis, MotorCommands, StepConfig, World, WorldDesc};

fn world(text: &str, ts: u64, substeps: u32) -> World {
    let desc = WorldDesc::parse(text, Path::new("test.toml")).unwrap();
    World::new(
        &desc,
        StepConfig {
            timestep: Millis(ts),
            substeps,
        },
    )
    .unwrap()
}

const EMPTY: &str = "[start]\nposition = [0.0, 0.0, 0.015]\n";

fn signed(w: [f64; 4]) -> [f64; 4] {
    [-w[0], w[1], -w[2], w[3]]
}

#[test]
fn hover_speed_holds_altitude() {
    for ts in [8, 32] {
        let mut w = world(EMPTY, ts, 1);
        w.teleport(0, DVec3::new(0.0, 0.0, 1.0), DQuat::IDENTITY);
        w.motors_mut(0).set_speeds_now(signed([hover_speed(); 4]));
        w.advance(2048 / ts * ts).unwrap();
        let p = w.position(0);
        assert!((p.z - 1.0).abs() < 0.01, "ts {ts}: z drifted to {}", p.z);
        assert!(p.x.abs() < 1e-9 && p.y.abs() < 1e-9, "ts {ts}: {p:?}");
        assert_eq!(w.state(0).collisions, 0);
    }
}

#[test]
fn free_fall_matches_g_t_squared_over_two() {
    // Symplectic Euler (rapier and ODE alike) is exact in velocity and off by
    // at most g·h·t/2 in position for a physics step h.
    for (ts, substeps) in [(32u64, 1u32), (32, 8), (8, 1)] {
        let mut w = world(EMPTY, ts, substeps);
        w.teleport(0, DVec3::new(0.0, 0.0, 20.0), DQuat::IDENTITY);
        w.advance(ts * (1024 / ts)).unwrap();
        let t = (ts * (1024 / ts)) as f64 / 1000.0;
        let h = ts as f64 / 1000.0 / substeps as f64;
        let g = crazyflie::GRAVITY;
        let fallen = 20.0 - w.position(0).z;
        let exact = g * t * t / 2.0;
        assert!(
            (fallen - exact).abs() <= g * h * t / 2.0 + 1e-9,
            "ts {ts}/{substeps}: fell {fallen}, g t²/2 = {exact}"
        );
        assert!((w.state(0).velocity[2] + g * t).abs() < 1e-9);
    }
    // Substeps converge on the closed form.
    let err = |substeps| {
        let mut w = world(EMPTY, 32, substeps);
        w.teleport(0, DVec3::new(0.0, 0.0, 20.0), DQuat::IDENTITY);
        w.advance(1024).unwrap();
        (20.0 - w.position(0).z - 9.81 * 1.024f64.powi(2) / 2.0).abs()
    };
    assert!(err(8) < err(1) / 4.0);
}

#[test]
fn a_motor_takes_55_over_30_seconds_from_0_to_55() {
    let ts = 8;
    let mut w = world(EMPTY, ts, 1);
    w.set_motor_commands(0, MotorCommands([55.0; 4])).unwrap();
    let mut steps = 0u64;
    while w.motors(0).speeds()[0] != -55.0 {
        w.step();
        steps += 1;
        assert!(steps < 10_000);
    }
    let t = (steps * ts) as f64 / 1000.0;
    assert!(
        t >= 55.0 / 30.0 && t < 55.0 / 30.0 + ts as f64 / 1000.0,
        "reached 55 rad/s after {t} s"
    );
    assert_eq!(w.motors(0).speeds(), [-55.0, 55.0, -55.0, 55.0]);
}

#[test]
fn yaw_torque_imbalance_turns_the_drone_as_the_proto_signs_give() {
    // m1 and m3 spin negative: their reaction torque −c·ω|ω| points up (+z),
    // so speeding them up yaws the drone counter-clockwise (the PID's +yaw).
    let ts = 8;
    let mut w = world(EMPTY, ts, 1);
    w.teleport(0, DVec3::new(0.0, 0.0, 5.0), DQuat::IDENTITY);
    let (fast, slow) = (60.0, 50.0);
    w.motors_mut(0)
        .set_speeds_now(signed([fast, slow, fast, slow]));
    w.advance(80).unwrap();
    let tau = 2.0 * TORQUE_CONSTANT * (fast * fast - slow * slow);
    let alpha = tau / principal_inertia()[2];
    let rate = w.sensors(0).gyro[2];
    assert!(rate > 0.0);
    assert!(
        ((rate - alpha * 0.08) / (alpha * 0.08)).abs() < 1e-9,
        "{rate} vs {}",
        alpha * 0.08
    );
    // The other way round turns clockwise.
    let mut w = world(EMPTY, ts, 1);
    w.teleport(0, DVec3::new(0.0, 0.0, 5.0), DQuat::IDENTITY);
    w.motors_mut(0)
        .set_speeds_now(signed([slow, fast, slow, fast]));
    w.advance(80).unwrap();
    assert!(w.sensors(0).gyro[2] < 0.0);
}

#[test]
fn left_motors_faster_roll_the_drone_right_side_down() {
    // m3, m4 are on the left (+y): more thrust there gives positive roll.
    let mut w = world(EMPTY, 8, 1);
    w.teleport(0, DVec3::new(0.0, 0.0, 5.0), DQuat::IDENTITY);
    w.motors_mut(0)
        .set_speeds_now(signed([55.0, 55.0, 56.0, 56.0]));
    w.advance(160).unwrap();
    let s = w.sensors(0);
    assert!(s.attitude[0] > 0.0 && s.gyro[0] > 0.0, "{s:?}");
    // Front motors faster: nose up, i.e. negative pitch (rotation about +y).
    let mut w = world(EMPTY, 8, 1);
    w.teleport(0, DVec3::new(0.0, 0.0, 5.0), DQuat::IDENTITY);
    w.motors_mut(0)
        .set_speeds_now(signed([56.0, 55.0, 55.0, 56.0]));
    w.advance(160).unwrap();
    assert!(w.sensors(0).attitude[1] < 0.0);
}

#[test]
fn warm_up_rests_on_the_ground_for_two_seconds() {
    let mut w = world(EMPTY, 32, 1);
    w.warm_up(|_| {});
    assert_eq!(w.time(), Millis(2000));
    let s = w.state(0);
    assert!((s.position[2] - 0.015).abs() < 0.003, "{s:?}");
    assert_eq!(s.motor_speeds, [-1.0, 1.0, -1.0, 1.0]);
    assert_eq!(s.collisions, 0);
    assert_eq!(s.ground_contacts, 1);
}

#[test]
fn stop_waits_for_every_propeller() {
    let mut w = world(EMPTY, 32, 1);
    w.motors_mut(0).set_speeds_now(signed([48.0; 4]));
    let stopped = w.stop_motors(0, |_| {});
    // 48 rad/s at 30 rad/s² is 1.6 s = 50 steps of 32 ms.
    assert_eq!(stopped, Millis(1600));
    assert!(w.motors(0).all_stopped());
}

#[test]
fn advance_rejects_partial_timesteps() {
    let mut w = world(EMPTY, 32, 1);
    assert!(w.advance(33).is_err());
    assert_eq!(w.time(), Millis(0));
    w.advance(64).unwrap();
    assert_eq!(w.time(), Millis(64));
}

const WALL: &str = r#"
[start]
position = [0.0, 0.0, 0.015]
[[box]]
centre = [1.6, 0.0, 1.0]
size = [0.2, 4.0, 2.0]
grey = 50
"#;

#[test]
fn a_wall_1_5_m_ahead_reads_1500_mm_front_and_2000_elsewhere() {
    let mut w = world(WALL, 32, 1);
    // Sensor origin at body z + 0.02; the wall's near face is at x = 1.5.
    w.teleport(0, DVec3::new(0.0, 0.0, 0.98), DQuat::IDENTITY);
    let s = w.sensors(0);
    assert!((s.ranges_mm[0] - 1500.0).abs() < 1e-6, "{s:?}");
    assert_eq!(&s.ranges_mm[1..], &[2000.0, 2000.0, 2000.0]);
    // Turned left by 90°, the same wall is on the right.
    w.teleport(
        0,
        DVec3::new(0.0, 0.0, 0.98),
        DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
    );
    let s = w.sensors(0);
    assert!((s.ranges_mm[3] - 1500.0).abs() < 1e-6, "{s:?}");
    assert_eq!(
        [s.ranges_mm[0], s.ranges_mm[1], s.ranges_mm[2]],
        [2000.0; 3]
    );
    // Closer than 2 m on the back side after turning round and stepping closer.
    w.teleport(
        0,
        DVec3::new(0.7, 0.0, 0.98),
        DQuat::from_rotation_z(std::f64::consts::PI),
    );
    assert!((w.sensors(0).ranges_mm[2] - 800.0).abs() < 1e-6);
}

#[test]
fn known_poses_give_known_imu_gps_and_gyro() {
    let mut w = world(EMPTY, 32, 1);
    let q =
        DQuat::from_rotation_z(0.9) * DQuat::from_rotation_y(0.2) * DQuat::from_rotation_x(-0.1);
    w.teleport(0, DVec3::new(1.0, -2.0, 3.0), q);
    // Spin about world z: the gyro sees it in body axes.
    w.set_velocities(0, DVec3::new(0.5, 0.0, 0.0), DVec3::new(0.0, 0.0, 1.0));
    let s = w.sensors(0);
    assert_eq!(s.gps, [1.0, -2.0, 3.0]);
    for (got, want) in s.attitude.iter().zip([-0.1, 0.2, 0.9]) {
        assert!((got - want).abs() < 1e-12, "{:?}", s.attitude);
    }
    let expected = q.inverse() * DVec3::Z;
    for (got, want) in s.gyro.iter().zip(expected.to_array()) {
        assert!((got - want).abs() < 1e-12);
    }
    assert_eq!(w.state(0).horizontal_speed(), 0.5);
}

const GATE: &str = r#"
[start]
position = [0.0, 0.0, 0.015]
[[gate]]
centre = [2.0, 0.0, 1.0]
yaw = 0.0
inner = 0.8
bar = 0.06
grey = 170
"#;

#[test]
fn flying_into_a_gate_bar_is_a_counted_physical_collision() {
    let mut w = world(GATE, 32, 1);
    // Level with the right-hand side bar (y = −0.43), flying at 3 m/s along +x.
    w.teleport(0, DVec3::new(0.5, -0.43, 1.0), DQuat::IDENTITY);
    w.motors_mut(0).set_speeds_now(signed([hover_speed(); 4]));
    w.set_velocities(0, DVec3::new(3.0, 0.0, 0.0), DVec3::ZERO);
    w.advance(1024).unwrap();
    let s = w.state(0);
    assert!(s.collisions >= 1, "{s:?}");
    // The bar stopped it: no tunnelling through 6 cm at 9.6 cm per step.
    assert!(s.position[0] < 2.0, "{s:?}");
    // The off-centre impact set it spinning.
    let spin: f64 = s.omega_body.iter().map(|w| w * w).sum::<f64>().sqrt();
    assert!(spin > 0.5, "{s:?}");
    // Through the middle of the opening nothing is touched.
    let mut w = world(GATE, 32, 1);
    w.teleport(0, DVec3::new(0.5, 0.0, 1.0), DQuat::IDENTITY);
    w.motors_mut(0).set_speeds_now(signed([hover_speed(); 4]));
    w.set_velocities(0, DVec3::new(3.0, 0.0, 0.0), DVec3::ZERO);
    w.advance(1024).unwrap();
    let s = w.state(0);
    assert_eq!(s.collisions, 0);
    assert!(s.position[0] > 3.0);
}

#[test]
fn same_commands_give_bit_identical_trajectories() {
    let run = || {
        let mut w = world(GATE, 32, 2);
        let mut states = Vec::new();
        w.warm_up(|w| states.push(w.state(0)));
        for k in 0..200 {
            let m = 58.0 + (k % 7) as f64;
            w.set_motor_commands(0, MotorCommands([m; 4])).unwrap();
            w.step();
            states.push(w.state(0));
        }
        states
    };
    let (a, b) = (run(), run());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        // PartialEq on f64 fields: bit-identical apart from ±0 and NaN, which a
        // state never holds.
        assert_eq!(x, y);
    }
    // And the drone actually flew (the comparison is not between two rests).
    assert!(a.last().unwrap().position[2] > 0.5);
}

/// The tilt (rad) of the body's z axis from the vertical.
fn tilt(w: &World) -> f64 {
    let q = w.state(0).quaternion;
    (1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]))
        .clamp(-1.0, 1.0)
        .acos()
}

#[test]
fn a_touchdown_below_the_hover_thrust_settles_flat() {
    // A level drone 2 cm above the floor, falling at `v`, its rotors held
    // at `frac` of the hover speed: with the motors off or at 70 % (the
    // weight on the floor) it settles flat; at the hover speed (no weight
    // on the floor) the impact's rotation is free and tips it (printed:
    // why the CRTP landing stops the motors before touching down,
    // sim-core crtp/high_level.rs `Touchdown`, docs/CFLIB.md "cfclient's Land").
    for frac in [0.0, 0.7, 1.0] {
        for v in [0.1, 0.3, 0.5, 0.7, 1.0] {
            let mut w = world(EMPTY, 32, 1);
            w.teleport(0, DVec3::new(0.0, 0.0, 0.035), DQuat::IDENTITY);
            w.set_velocities(0, DVec3::new(0.0, 0.0, -v), DVec3::ZERO);
            let h = hover_speed() * frac;
            w.motors_mut(0).set_speeds_now(signed([h; 4]));
            let mut most: f64 = 0.0;
            for _ in 0..20 {
                w.set_motor_commands(0, MotorCommands([h; 4])).unwrap();
                w.step();
                most = most.max(tilt(&w));
            }
            println!("rotors {frac:.1} x hover, touchdown at {v:.1} m/s: largest tilt {most:.3} rad, after 0.64 s {:.3} rad", tilt(&w));
            if frac < 1.0 {
                assert!(
                    most < 0.35 && tilt(&w) < 0.01,
                    "{frac} {v}: {most} {}",
                    tilt(&w)
                );
            }
        }
    }
}
