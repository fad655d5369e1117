//! Several drones in one physics world (DESIGN.md §7, docs/SWARM.md §1):
//! independence, carried paths, drone–drone contacts, range sensors.

use std::path::Path;

use rapier3d::glamx::{DQuat, DVec3};
use world_server::crazyflie::hover_speed;
use world_server::{Millis, MotorCommands, StepConfig, World, WorldDesc};

fn world(text: &str, ts: u64) -> World {
    let desc = WorldDesc::parse(text, Path::new("test.toml")).unwrap();
    World::new(
        &desc,
        StepConfig {
            timestep: Millis(ts),
            substeps: 1,
        },
    )
    .unwrap()
}

fn signed(w: [f64; 4]) -> [f64; 4] {
    [-w[0], w[1], -w[2], w[3]]
}

fn hover(w: &mut World, d: usize) {
    w.motors_mut(d).set_speeds_now(signed([hover_speed(); 4]));
}

#[test]
fn two_hovering_drones_do_not_interact() {
    // Each drone of a two-drone world flies exactly as it would alone.
    let two = "[[drone]]\nname = \"A\"\nposition = [0.0, 0.0, 1.0]\n\
               [[drone]]\nname = \"B\"\nposition = [3.0, 1.0, 1.5]\nyaw = 0.7\n";
    let mut both = world(two, 8);
    let mut a = world("[start]\nposition = [0.0, 0.0, 1.0]\n", 8);
    let mut b = world("[start]\nposition = [3.0, 1.0, 1.5]\nyaw = 0.7\n", 8);
    hover(&mut both, 0);
    hover(&mut both, 1);
    hover(&mut a, 0);
    hover(&mut b, 0);
    // Different commands per drone, so a mix-up would show.
    let ca = MotorCommands([
        hover_speed() + 1.0,
        hover_speed(),
        hover_speed() + 1.0,
        hover_speed(),
    ]);
    let cb = MotorCommands([hover_speed(); 4]);
    both.set_motor_commands(0, ca).unwrap();
    both.set_motor_commands(1, cb).unwrap();
    a.set_motor_commands(0, ca).unwrap();
    b.set_motor_commands(0, cb).unwrap();
    for _ in 0..250 {
        both.step();
        a.step();
        b.step();
        assert_eq!(both.state(0), a.state(0));
        let (sb, s1) = (both.state(1), b.state(0));
        assert_eq!(sb, s1);
    }
    assert_eq!(both.time(), Millis(2000));
    assert!((both.position(1).z - 1.5).abs() < 0.01, "B hovers");
    assert_eq!(both.state(0).collisions + both.state(1).collisions, 0);
}

const CARRIED: &str = r#"
[[drone]]
name = "flyer"
position = [-3.0, 0.0, 0.015]

[[drone]]
name = "table"
yaw = 1.0
carried = [[0.0, 1.0, 0.0, 0.75], [2.5, 1.0, 0.0, 0.75], [4.5, 0.0, 2.0, 0.75], [6.0, 0.0, 2.0, 1.25]]
"#;

#[test]
fn a_carried_drone_follows_its_path_and_ignores_its_motors() {
    let mut w = world(CARRIED, 16);
    assert!(w.is_carried(1) && !w.is_carried(0));
    let path = w.carried_path(1).unwrap().clone();
    let close = |p: DVec3, q: [f64; 3]| (p - DVec3::from_array(q)).length() < 1e-9;
    assert!(close(w.position(1), [1.0, 0.0, 0.75]));
    let mut steps = 0;
    w.warm_up(|w| {
        // Held at its first point during the warm-up (t < 2.5 s).
        assert!(
            close(w.position(1), [1.0, 0.0, 0.75]),
            "{:?}",
            w.position(1)
        );
        steps += 1;
    });
    assert_eq!(steps, 125);
    assert_eq!(w.motors(1).speeds(), [0.0; 4], "no warm-up spin");
    // Accepted and ignored.
    w.set_motor_commands(1, MotorCommands([300.0; 4])).unwrap();
    assert!(w.set_motor_commands(1, MotorCommands([-1.0; 4])).is_err());
    w.stop_propellers(1);
    assert!(w.propellers_stopped(1));
    for _ in 0..300 {
        w.step();
        let t = w.time().as_secs_f64();
        assert!(
            close(w.position(1), path.at(t)),
            "t = {t}: {:?} vs {:?}",
            w.position(1),
            path.at(t)
        );
        assert_eq!(w.motors(1).speeds(), [0.0; 4]);
    }
    // Midway along the second leg, at the end, and its heading kept.
    assert_eq!(path.at(3.5), [0.5, 1.0, 0.75]);
    assert_eq!(path.at(6.0), [0.0, 2.0, 1.25]);
    assert!(close(w.position(1), [0.0, 2.0, 1.25]));
    assert!((w.sensors(1).attitude[2] - 1.0).abs() < 1e-12);
    // Its velocity is the path's: at rest at the end.
    assert!(DVec3::from_array(w.state(1).velocity).length() < 1e-9);
}

/// Two drones 0.5 m apart at 1 m, hovering; A pushed towards B at 1 m/s.
fn head_on(b_carried: bool) -> World {
    let b = if b_carried {
        "carried = [[0.0, 0.5, 0.0, 1.0]]"
    } else {
        "position = [0.5, 0.0, 1.0]"
    };
    let text = format!(
        "[[drone]]\nname = \"A\"\nposition = [0.0, 0.0, 1.0]\n[[drone]]\nname = \"B\"\n{b}\n"
    );
    let mut w = world(&text, 8);
    hover(&mut w, 0);
    if !b_carried {
        hover(&mut w, 1);
    }
    w.set_velocities(0, DVec3::new(1.0, 0.0, 0.0), DVec3::ZERO);
    w
}

#[test]
fn a_drone_drone_contact_is_a_collision_of_both() {
    for b_carried in [false, true] {
        let mut w = head_on(b_carried);
        let mut met = None;
        for k in 0..100 {
            w.step();
            if w.state(0).collisions > 0 {
                met = Some(k);
                break;
            }
        }
        // The hulls (r = 0.05 m) touch after 0.4 m, at 1 m/s: ~400 ms.
        let k = met.expect("A never hit B");
        assert!((45..=55).contains(&k), "contact after {k} steps of 8 ms");
        assert_eq!(w.state(0).collisions, 1, "carried B: {b_carried}");
        assert_eq!(w.state(1).collisions, 1, "carried B: {b_carried}");
        assert_eq!(w.state(0).ground_contacts, 0);
        if b_carried {
            // Nothing moves a carried drone.
            assert_eq!(w.position(1), DVec3::new(0.5, 0.0, 1.0));
        }
    }
}

#[test]
fn a_carried_drone_through_a_box_counts_a_collision() {
    // Carried at 0.5 m/s through a box standing 1 m ahead.
    let text = "[[drone]]\nname = \"A\"\nposition = [-5.0, 0.0, 0.015]\n\
                [[drone]]\nname = \"B\"\ncarried = [[2.0, 0.0, 0.0, 0.5], [6.0, 2.0, 0.0, 0.5]]\n\
                [[box]]\ncentre = [1.0, 0.0, 0.5]\nsize = [0.2, 0.2, 1.0]\ngrey = 60\n";
    let mut w = world(text, 16);
    w.warm_up(|_| {});
    assert_eq!(w.state(1).collisions, 0);
    w.advance(4000).unwrap();
    assert_eq!(w.state(1).collisions, 1);
    assert_eq!(w.state(0).collisions, 0);
}

#[test]
fn range_sensors_see_the_other_drones() {
    // B's hull (r 0.05, h 0.03) across A's front ray, which starts 2 cm
    // above A's centre: B sits 2 cm higher, 1 m ahead.
    let text = "[[drone]]\nname = \"A\"\nposition = [0.0, 0.0, 1.0]\n\
                [[drone]]\nname = \"B\"\nposition = [1.0, 0.0, 1.02]\n";
    let mut w = world(text, 32);
    let s = w.sensors(0);
    assert!((s.ranges_mm[0] - 950.0).abs() < 1e-6, "{:?}", s.ranges_mm);
    assert_eq!(&s.ranges_mm[1..], &[2000.0; 3]);
    // A drone does not see itself; B's back ray passes above A.
    assert_eq!(w.sensors(1).ranges_mm, [2000.0; 4]);
    // Turned by 90°, A sees B on its right.
    w.teleport(
        0,
        DVec3::new(0.0, 0.0, 1.0),
        DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
    );
    let r = w.sensors(0).ranges_mm;
    assert!((r[3] - 950.0).abs() < 1e-6, "{r:?}");
}
