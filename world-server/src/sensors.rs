//! The Crazyflie's sensors as Webots defines them (DESIGN.md §5): GPS,
//! InertialUnit, Gyro and the four DistanceSensors of the multiranger deck;
//! and, when the world file's `[sensors]` asks (DESIGN.md §9), the up and
//! down rangers and the Flow deck's optical-flow velocity.

use rapier3d::glamx::{DQuat, DVec3};

use crate::crazyflie::{RANGE_MAX_M, RANGE_MAX_MM};
use crate::time::Millis;

/// Roll, pitch, yaw (rad) of Webots's InertialUnit from the orientation
/// quaternion, with the formulas of DESIGN.md §5.
pub fn inertial_unit_angles(q: DQuat) -> [f64; 3] {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    // Clamped: rounding can push |2(wy − zx)| a hair above 1 at ±90° pitch.
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    [roll, pitch, yaw]
}

/// The DistanceSensor lookup table `[0 0 0, 2 2000 0]`: metres to millimetres,
/// linear, saturating at 2000 beyond 2 m (and for no hit at all).
pub fn range_to_mm(distance_m: Option<f64>) -> f64 {
    match distance_m {
        Some(d) if d < RANGE_MAX_M => d.max(0.0) * (RANGE_MAX_MM / RANGE_MAX_M),
        _ => RANGE_MAX_MM,
    }
}

/// A reading in metres to millimetres for a ranger of range `max_m`: linear,
/// saturating at the maximum beyond it (and for no hit at all). With
/// `max_m` = 2 this is exactly [`range_to_mm`].
pub fn range_to_mm_within(distance_m: Option<f64>, max_m: f64) -> f64 {
    match distance_m {
        Some(d) if d < max_m => d.max(0.0) * 1000.0,
        _ => max_m * 1000.0,
    }
}

/// Body-frame directions of the up and down rangers (Multi-ranger's up,
/// Flow deck's down), in that order.
pub const UP_DOWN_DIRECTIONS: [DVec3; 2] = [DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0)];

/// Body-frame directions of the four DistanceSensors, in wire order:
/// front (+x), left (+y), back (−x), right (−y).
pub const RANGE_DIRECTIONS: [DVec3; 4] = [
    DVec3::new(1.0, 0.0, 0.0),
    DVec3::new(0.0, 1.0, 0.0),
    DVec3::new(-1.0, 0.0, 0.0),
    DVec3::new(0.0, -1.0, 0.0),
];

/// What `GET_SENSORS` reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorReadings {
    pub time: Millis,
    /// GPS position (m): the GPS node sits at the body origin.
    pub gps: [f64; 3],
    /// Roll, pitch, yaw (rad), InertialUnit.
    pub attitude: [f64; 3],
    /// Gyro: angular velocity in body axes (rad/s).
    pub gyro: [f64; 3],
    /// Front, left, back, right (mm, 0 to the world's maximum: 2000 for
    /// the race).
    pub ranges_mm: [f64; 4],
    /// Up and down (mm), when the world's `[sensors]` has `up_down`.
    pub up_down_mm: Option<[f64; 2]>,
    /// Optical-flow velocity, body frame (m/s), when `[sensors]` has `flow`.
    pub flow: Option<[f64; 2]>,
}

/// Ground truth (`GET_STATE`, trajectory rows, GET_DATA_2/3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DroneState {
    pub time: Millis,
    pub position: [f64; 3],
    /// Orientation quaternion (w, x, y, z).
    pub quaternion: [f64; 4],
    /// Linear velocity, world frame (m/s).
    pub velocity: [f64; 3],
    /// Angular velocity, body frame (rad/s).
    pub omega_body: [f64; 3],
    /// Signed propeller speeds m1..m4 (rad/s).
    pub motor_speeds: [f64; 4],
    /// Contacts begun with gates and boxes.
    pub collisions: u64,
    /// Contacts begun with the ground (take-offs and landings are not collisions).
    pub ground_contacts: u64,
    /// Distinct gates passed (crate::gates), set by the physics world.
    pub gates_passed: u64,
}

impl DroneState {
    pub fn attitude(&self) -> [f64; 3] {
        let [w, x, y, z] = self.quaternion;
        inertial_unit_angles(DQuat::from_xyzw(x, y, z, w))
    }

    /// Horizontal speed (m/s), the `VELOCITY` of GET_DATA_2 and GET_DATA_3.
    pub fn horizontal_speed(&self) -> f64 {
        self.velocity[0].hypot(self.velocity[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn imu_angles_of_single_axis_rotations() {
        assert!(close(
            inertial_unit_angles(DQuat::from_rotation_x(0.3)),
            [0.3, 0.0, 0.0]
        ));
        assert!(close(
            inertial_unit_angles(DQuat::from_rotation_y(-0.2)),
            [0.0, -0.2, 0.0]
        ));
        assert!(close(
            inertial_unit_angles(DQuat::from_rotation_z(FRAC_PI_2)),
            [0.0, 0.0, FRAC_PI_2]
        ));
    }

    #[test]
    fn imu_angles_follow_the_zyx_convention() {
        // Webots's roll/pitch/yaw are the Z-Y-X (yaw, then pitch, then roll) Euler angles.
        let q = DQuat::from_rotation_z(1.0)
            * DQuat::from_rotation_y(0.4)
            * DQuat::from_rotation_x(-0.7);
        assert!(close(inertial_unit_angles(q), [-0.7, 0.4, 1.0]));
    }

    #[test]
    fn range_within_a_max_matches_the_lookup_table_at_2_m() {
        for d in [
            None,
            Some(-0.1),
            Some(0.0),
            Some(0.7),
            Some(1.999),
            Some(2.0),
            Some(3.0),
        ] {
            assert_eq!(range_to_mm_within(d, 2.0), range_to_mm(d));
        }
        assert_eq!(range_to_mm_within(Some(3.5), 4.0), 3500.0);
        assert_eq!(range_to_mm_within(Some(4.5), 4.0), 4000.0);
        assert_eq!(range_to_mm_within(None, 4.0), 4000.0);
    }

    #[test]
    fn range_lookup_table() {
        assert_eq!(range_to_mm(Some(1.5)), 1500.0);
        assert_eq!(range_to_mm(Some(0.0)), 0.0);
        assert_eq!(range_to_mm(Some(2.0)), 2000.0);
        assert_eq!(range_to_mm(Some(7.0)), 2000.0);
        assert_eq!(range_to_mm(None), 2000.0);
    }
}
