//! One drone's body in the physics world: a flown Crazyflie (dynamic body,
//! four propellers) or a carried one (kinematic body moved along its path,
//! DESIGN.md §7), its contacts and collision counters, its ground truth and
//! its sensors.

use rapier3d::glamx::{DQuat, DVec3};
use rapier3d::prelude::*;

use crate::crazyflie::{
    self, Motors, BODY_HEIGHT_M, BODY_RADIUS_M, MASS_KG, PROPELLER_POSITIONS, RANGE_SENSOR_POSITION,
};
use crate::radio::draw::sensor_normal;
use crate::scene::ObjectId;
use crate::sensors::{
    inertial_unit_angles, range_to_mm_within, DroneState, SensorReadings, RANGE_DIRECTIONS,
    UP_DOWN_DIRECTIONS,
};
use crate::time::Millis;
use crate::world_file::{CarriedPath, DroneDesc, PhysicsOptions, SensorConfig};

use super::FRICTION;

/// A drone's body, motors and contact bookkeeping.
pub(super) struct DroneBody {
    pub(super) body: RigidBodyHandle,
    collider: ColliderHandle,
    pub(super) motors: Motors,
    /// `Some`: carried along this path, motors ignored.
    carried: Option<CarriedPath>,
    /// Objects touching the drone at the end of the last physics step, sorted.
    touching: Vec<ObjectId>,
    collisions: u64,
    ground_contacts: u64,
}

impl DroneBody {
    /// Inserts drone `index` of the world file at its start pose, at rest.
    pub(super) fn insert(
        phys: &mut PhysicsWorld,
        index: usize,
        desc: &DroneDesc,
        opts: &PhysicsOptions,
    ) -> DroneBody {
        let start = DVec3::from_array(desc.start.position.0);
        let pose = Pose::from_parts(start, DQuat::from_rotation_z(desc.start.yaw.0));
        let [ix, iy, iz] = crazyflie::principal_inertia();
        let mass = MassProperties::new(DVec3::ZERO, MASS_KG, DVec3::new(ix, iy, iz));
        let builder = if desc.is_carried() {
            // Moved by hand (seed 003's table experiment): the path decides
            // where it is; whatever hits it does not move it.
            RigidBodyBuilder::kinematic_position_based()
                .pose(pose)
                .additional_mass_properties(mass)
        } else {
            RigidBodyBuilder::dynamic()
                .pose(pose)
                .additional_mass_properties(mass)
                .linear_damping(opts.linear_damping.0)
                .angular_damping(opts.angular_damping.0)
                .gyroscopic_forces_enabled(true)
                // A crash at race speed moves more than a gate bar's width per 32 ms step.
                .ccd_enabled(true)
        };
        let body = phys.insert_body(builder.can_sleep(false));
        // The PROTO's bounding cylinder has its axis along body z; rapier's is along y.
        let mut hull = ColliderBuilder::cylinder(BODY_HEIGHT_M / 2.0, BODY_RADIUS_M)
            .rotation(DVec3::X * std::f64::consts::FRAC_PI_2)
            .density(0.0)
            .friction(FRICTION)
            .restitution(opts.restitution.0)
            .user_data(ObjectId::Drone(index).to_user_data());
        if desc.is_carried() {
            // rapier skips kinematic–fixed and kinematic–kinematic pairs by
            // default; a carried drone touching a gate, the ground or another
            // carried drone is still a contact (it counts, without forces).
            hull = hull.active_collision_types(ActiveCollisionTypes::all());
        }
        let collider = phys.insert_collider(hull, Some(body));
        DroneBody {
            body,
            collider,
            motors: Motors::with_response(opts.motors),
            carried: desc.carried.clone(),
            touching: Vec::new(),
            collisions: 0,
            ground_contacts: 0,
        }
    }

    pub(super) fn is_carried(&self) -> bool {
        self.carried.is_some()
    }

    pub(super) fn carried(&self) -> Option<&CarriedPath> {
        self.carried.as_ref()
    }

    /// Before one physics (sub)step that ends at world time `t_end_s`:
    /// slew the motors and push the propeller forces, or move a carried
    /// drone's body to where its path is at the end of the step.
    pub(super) fn prepare_substep(&mut self, phys: &mut PhysicsWorld, h: f64, t_end_s: f64) {
        match &self.carried {
            None => {
                self.motors.advance(h);
                self.apply_propeller_forces(phys);
            }
            Some(path) => {
                let body = &mut phys.bodies[self.body];
                let rot = *body.rotation();
                let next = Pose::from_parts(DVec3::from_array(path.at(t_end_s)), rot);
                body.set_next_kinematic_position(next);
            }
        }
    }

    /// Thrust along body +z at each propeller and the reaction torques.
    fn apply_propeller_forces(&mut self, phys: &mut PhysicsWorld) {
        let body = &mut phys.bodies[self.body];
        let rot = *body.rotation();
        let up = rot * DVec3::Z;
        let mut force = DVec3::ZERO;
        let mut torque = DVec3::ZERO;
        for (i, p) in PROPELLER_POSITIONS.iter().enumerate() {
            let f = up * self.motors.thrust(i);
            // Torque about the centre of mass (the body origin) computed here rather
            // than with `add_force_at_point`, whose world COM is only refreshed by a step
            // (stale after a teleport).
            torque += (rot * DVec3::from_array(*p)).cross(f);
            torque += up * self.motors.reaction_torque(i);
            force += f;
        }
        body.reset_forces(true);
        body.reset_torques(true);
        body.add_force(force, true);
        body.add_torque(torque, true);
    }

    /// Counts contacts begun, per touched object (another drone included:
    /// a drone–drone contact is a collision of both, each counts its own).
    pub(super) fn update_contacts(&mut self, phys: &PhysicsWorld, time: Millis) {
        let mut now: Vec<ObjectId> = Vec::new();
        for pair in phys.narrow_phase.contact_pairs_with(self.collider) {
            if !pair.has_any_active_contact() {
                continue;
            }
            let other = if pair.collider1 == self.collider {
                pair.collider2
            } else {
                pair.collider1
            };
            if let Some(c) = phys.colliders.get(other) {
                now.push(ObjectId::from_user_data(c.user_data));
            }
        }
        now.sort();
        now.dedup();
        for id in &now {
            if self.touching.binary_search(id).is_err() {
                match id {
                    ObjectId::Ground => self.ground_contacts += 1,
                    _ => {
                        self.collisions += 1;
                        tracing::debug!(time_ms = time.0, object = ?id, "collision");
                    }
                }
            }
        }
        self.touching = now;
    }

    pub(super) fn position(&self, phys: &PhysicsWorld) -> DVec3 {
        phys.bodies[self.body].translation()
    }

    /// Ground truth at world time `time`.
    pub(super) fn state(&self, phys: &PhysicsWorld, time: Millis) -> DroneState {
        let body = &phys.bodies[self.body];
        let rot = *body.rotation();
        DroneState {
            time,
            position: body.translation().to_array(),
            quaternion: [rot.w, rot.x, rot.y, rot.z],
            velocity: body.linvel().to_array(),
            omega_body: (rot.inverse() * body.angvel()).to_array(),
            motor_speeds: self.motors.speeds(),
            collisions: self.collisions,
            ground_contacts: self.ground_contacts,
            gates_passed: 0,
        }
    }

    /// GPS, InertialUnit, Gyro and the four DistanceSensors (which see
    /// everything but this drone: other drones included); the up and down
    /// rangers and the optical flow when the world's `[sensors]` asks.
    /// `index` is the drone's (it keys the noise).
    pub(super) fn sensors(
        &self,
        phys: &PhysicsWorld,
        time: Millis,
        cfg: &SensorConfig,
        index: usize,
    ) -> SensorReadings {
        let body = &phys.bodies[self.body];
        let rot = *body.rotation();
        let pos = body.translation();
        let origin = pos + rot * DVec3::from_array(RANGE_SENSOR_POSITION);
        let filter = QueryFilter::default().exclude_rigid_body(self.body);
        let query = phys.query_pipeline_with_filter(filter);
        // Channels of the noise: the four rangers 0-3, then up and down 4-5.
        // (The race's single 2 m ray without noise reads exactly the
        // DistanceSensor lookup table, `range_to_mm`.)
        let mut channel = 0..;
        let mut ranger = |d: DVec3| {
            let k = channel.next().expect("unbounded");
            ranger_mm(&query, origin, rot, d, cfg, (index, time, k))
        };
        let ranges_mm = RANGE_DIRECTIONS.map(&mut ranger);
        let up_down_mm = cfg.up_down.then(|| UP_DOWN_DIRECTIONS.map(&mut ranger));
        let flow = cfg.flow.then(|| {
            // The Flow deck's PMW3901 sees the floor move under the drone:
            // the velocity in the body frame, scaled and noisy.
            let v = rot.inverse() * body.linvel();
            let n = |channel: u64| {
                if cfg.flow_noise_m_s > 0.0 {
                    cfg.flow_noise_m_s * sensor_normal(cfg.seed, index, time.0, channel)
                } else {
                    0.0
                }
            };
            [v.x * cfg.flow_scale + n(6), v.y * cfg.flow_scale + n(7)]
        });
        SensorReadings {
            time,
            gps: pos.to_array(),
            attitude: inertial_unit_angles(rot),
            gyro: (rot.inverse() * body.angvel()).to_array(),
            ranges_mm,
            up_down_mm,
            flow,
        }
    }
}

/// One ranger (mm): the nearest return of its rays, the sensor's axis `dir`
/// (body frame) turned by each of the `[sensors]` ray angles about the
/// body's z axis (about y for the up and down rangers), plus Gaussian noise keyed by (drone, time,
/// channel); nothing within `range_max_m` reads the maximum.
fn ranger_mm(
    query: &QueryPipeline<'_>,
    origin: DVec3,
    rot: DQuat,
    dir: DVec3,
    cfg: &SensorConfig,
    (drone, time, channel): (usize, Millis, u64),
) -> f64 {
    let axis = if dir.z == 0.0 { DVec3::Z } else { DVec3::Y };
    let nearest = cfg
        .ray_angles()
        .filter_map(|a| {
            let d = if a == 0.0 {
                dir
            } else {
                DQuat::from_axis_angle(axis, a) * dir
            };
            query
                .cast_ray(&Ray::new(origin, rot * d), cfg.range_max_m, true)
                .map(|(_, toi)| toi)
        })
        .reduce(f64::min);
    let noisy = nearest.map(|d| {
        if cfg.range_noise_m > 0.0 {
            d + cfg.range_noise_m * sensor_normal(cfg.seed, drone, time.0, channel)
        } else {
            d
        }
    });
    range_to_mm_within(noisy, cfg.range_max_m)
}
