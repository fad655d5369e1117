//! The Crazyflie in rapier3d: one dynamic rigid body with the PROTO's mass,
//! inertia and bounding cylinder, four propellers pushing at their
//! `centerOfThrust`, and fixed colliders for the ground, gates and boxes.
//!
//! The world advances only in whole basicTimeSteps (DESIGN.md §3), each
//! optionally split into `substeps` physics steps.

use rapier3d::glamx::{DQuat, DVec3};
use rapier3d::prelude::*;

use crate::crazyflie::{
    self, MotorCommandError, MotorCommands, Motors, BODY_HEIGHT_M, BODY_RADIUS_M, GRAVITY, MASS_KG,
    PROPELLER_POSITIONS, RANGE_SENSOR_POSITION,
};
use crate::scene::{scene_boxes, ObjectId, SceneBox};
use crate::sensors::{
    inertial_unit_angles, range_to_mm, DroneState, SensorReadings, RANGE_DIRECTIONS,
};
use crate::time::Millis;
use crate::world_file::WorldDesc;

/// Webots's default contact properties (`ContactProperties { coulombFriction 1 bounce 0.5 }`).
const FRICTION: f64 = 1.0;
const RESTITUTION: f64 = 0.5;

/// How the world steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepConfig {
    /// basicTimeStep (ms, > 0).
    pub timestep: Millis,
    /// Physics steps per basicTimeStep (≥ 1).
    pub substeps: u32,
}

impl Default for StepConfig {
    fn default() -> Self {
        StepConfig {
            timestep: Millis(32),
            substeps: 1,
        }
    }
}

/// Errors of the physics world.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WorldError {
    #[error("timestep must be at least 1 ms")]
    ZeroTimestep,
    #[error("substeps must be at least 1")]
    ZeroSubsteps,
    #[error(transparent)]
    Motor(#[from] MotorCommandError),
    #[error("cannot advance {requested} ms: not a multiple of the {timestep} ms timestep")]
    NotMultiple { requested: u64, timestep: u64 },
}

/// The physics world.
pub struct World {
    phys: PhysicsWorld,
    drone: RigidBodyHandle,
    drone_collider: ColliderHandle,
    motors: Motors,
    time: Millis,
    cfg: StepConfig,
    boxes: Vec<SceneBox>,
    /// Objects touching the drone at the end of the last physics step, sorted.
    touching: Vec<ObjectId>,
    collisions: u64,
    ground_contacts: u64,
}

impl World {
    /// Builds the world of `desc` with the drone at its start pose, at rest, time 0.
    pub fn new(desc: &WorldDesc, cfg: StepConfig) -> Result<World, WorldError> {
        if cfg.timestep.0 == 0 {
            return Err(WorldError::ZeroTimestep);
        }
        if cfg.substeps == 0 {
            return Err(WorldError::ZeroSubsteps);
        }
        let mut phys = PhysicsWorld::new();
        phys.gravity = DVec3::new(0.0, 0.0, -GRAVITY);
        // One integration step per physics step, as ODE does in Webots
        // (DESIGN.md §5: "Physics steps at basicTimeStep unless --substeps
        // says otherwise"). rapier's default splits every step into 4 internal
        // solver substeps with the propeller forces held, which changes the
        // closed-loop attitude response: the race flipped at 8/16 ms and at
        // 32 ms with --substeps 4. Finer stepping stays available as --substeps.
        phys.integration_parameters.num_solver_iterations = 1;

        let ground = ColliderBuilder::halfspace(rapier3d::na::Unit::new_unchecked(Vector::Z))
            .friction(FRICTION)
            .restitution(RESTITUTION)
            .user_data(ObjectId::Ground.to_user_data());
        phys.insert_collider(ground, None);

        let boxes = scene_boxes(desc);
        for b in &boxes {
            let collider = ColliderBuilder::cuboid(b.half.x, b.half.y, b.half.z)
                .position(Pose::from_parts(b.centre, DQuat::from_rotation_z(b.yaw)))
                .friction(FRICTION)
                .restitution(RESTITUTION)
                .user_data(b.object.to_user_data());
            phys.insert_collider(collider, None);
        }

        let [ix, iy, iz] = crazyflie::principal_inertia();
        let start = DVec3::from_array(desc.start.position.0);
        let body = RigidBodyBuilder::dynamic()
            .pose(Pose::from_parts(
                start,
                DQuat::from_rotation_z(desc.start.yaw.0),
            ))
            .additional_mass_properties(MassProperties::new(
                DVec3::ZERO,
                MASS_KG,
                DVec3::new(ix, iy, iz),
            ))
            .linear_damping(desc.physics.linear_damping.0)
            .angular_damping(desc.physics.angular_damping.0)
            .gyroscopic_forces_enabled(true)
            // A crash at race speed moves more than a gate bar's width per 32 ms step.
            .ccd_enabled(true)
            .can_sleep(false);
        let drone = phys.insert_body(body);
        // The PROTO's bounding cylinder has its axis along body z; rapier's is along y.
        let hull = ColliderBuilder::cylinder(BODY_HEIGHT_M / 2.0, BODY_RADIUS_M)
            .rotation(DVec3::X * std::f64::consts::FRAC_PI_2)
            .density(0.0)
            .friction(FRICTION)
            .restitution(RESTITUTION);
        let drone_collider = phys.insert_collider(hull, Some(drone));
        // Make scene queries (range sensors) valid before the first step.
        phys.detect_collisions(&(), &());

        Ok(World {
            phys,
            drone,
            drone_collider,
            motors: Motors::new(),
            time: Millis::ZERO,
            cfg,
            boxes,
            touching: Vec::new(),
            collisions: 0,
            ground_contacts: 0,
        })
    }

    pub fn config(&self) -> StepConfig {
        self.cfg
    }

    pub fn time(&self) -> Millis {
        self.time
    }

    /// The static boxes of the scene (for the camera).
    pub fn scene_boxes(&self) -> &[SceneBox] {
        &self.boxes
    }

    pub fn motors(&self) -> &Motors {
        &self.motors
    }

    pub fn motors_mut(&mut self) -> &mut Motors {
        &mut self.motors
    }

    /// New PID motor targets (magnitudes, rad/s); nothing changes if one is invalid.
    pub fn set_motor_commands(&mut self, cmd: MotorCommands) -> Result<(), WorldError> {
        cmd.validate()?;
        self.motors.set_targets(cmd);
        Ok(())
    }

    /// The thesis's warm-up: motors at ±1 rad/s, 2000 ms (Appendix E).
    ///
    /// The contract has TIME start at exactly 2.000 s, but 2000 is not a
    /// multiple of every timestep (32 ms: 62.5 steps), so the warm-up ends
    /// with one shorter step of the remainder. It is the only step that is not
    /// a whole basicTimeStep, and it happens before any request is served.
    pub fn warm_up(&mut self, mut on_step: impl FnMut(&World)) {
        use crazyflie::{SPIN_SIGNS, WARMUP_MS, WARMUP_SPEED};
        self.motors
            .set_signed_targets(SPIN_SIGNS.map(|s| s * WARMUP_SPEED));
        let ts = self.cfg.timestep.0;
        for _ in 0..WARMUP_MS / ts {
            self.step();
            on_step(self);
        }
        let rest = WARMUP_MS % ts;
        if rest > 0 {
            self.step_ms(Millis(rest));
            on_step(self);
        }
    }

    /// Advances `ms` milliseconds holding the motor targets (ADVANCE_TIME);
    /// `on_step` sees every step. Nothing happens if `ms` is not a multiple
    /// of the timestep.
    pub fn advance_observed(
        &mut self,
        ms: u64,
        mut on_step: impl FnMut(&World),
    ) -> Result<(), WorldError> {
        let ts = self.cfg.timestep.0;
        if !ms.is_multiple_of(ts) {
            return Err(WorldError::NotMultiple {
                requested: ms,
                timestep: ts,
            });
        }
        for _ in 0..ms / ts {
            self.step();
            on_step(self);
        }
        Ok(())
    }

    /// [`World::advance_observed`] without an observer.
    pub fn advance(&mut self, ms: u64) -> Result<(), WorldError> {
        self.advance_observed(ms, |_| {})
    }

    /// Sets every target to 0 and steps until all propellers have stopped
    /// (STOP); returns the world time spent stopping. `on_step` sees every step.
    pub fn stop_motors(&mut self, mut on_step: impl FnMut(&World)) -> Millis {
        self.motors.set_signed_targets([0.0; 4]);
        let t0 = self.time;
        while !self.motors.all_stopped() {
            self.step();
            on_step(self);
        }
        Millis(self.time.0 - t0.0)
    }

    /// One basicTimeStep.
    pub fn step(&mut self) {
        self.step_ms(self.cfg.timestep);
    }

    /// One step of `ms` milliseconds, split into the configured substeps.
    fn step_ms(&mut self, ms: Millis) {
        let h = ms.0 as f64 / 1000.0 / self.cfg.substeps as f64;
        self.phys.integration_parameters.dt = h;
        for _ in 0..self.cfg.substeps {
            self.motors.advance(h);
            self.apply_propeller_forces();
            self.phys.step();
            self.update_contacts();
        }
        self.time += ms;
    }

    /// Thrust along body +z at each propeller and the reaction torques.
    fn apply_propeller_forces(&mut self) {
        let body = &mut self.phys.bodies[self.drone];
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

    /// Counts contacts begun, per touched object.
    fn update_contacts(&mut self) {
        let mut now: Vec<ObjectId> = Vec::new();
        for pair in self
            .phys
            .narrow_phase
            .contact_pairs_with(self.drone_collider)
        {
            if !pair.has_any_active_contact() {
                continue;
            }
            let other = if pair.collider1 == self.drone_collider {
                pair.collider2
            } else {
                pair.collider1
            };
            if let Some(c) = self.phys.colliders.get(other) {
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
                        tracing::debug!(time_ms = self.time.0, object = ?id, "collision");
                    }
                }
            }
        }
        self.touching = now;
    }

    /// Places the drone at a pose, at rest (tests, and later replay).
    pub fn teleport(&mut self, position: DVec3, rotation: DQuat) {
        let body = &mut self.phys.bodies[self.drone];
        body.set_position(Pose::from_parts(position, rotation), true);
        body.set_linvel(DVec3::ZERO, true);
        body.set_angvel(DVec3::ZERO, true);
    }

    /// Sets the drone's velocities (tests).
    pub fn set_velocities(&mut self, linvel: DVec3, angvel_world: DVec3) {
        let body = &mut self.phys.bodies[self.drone];
        body.set_linvel(linvel, true);
        body.set_angvel(angvel_world, true);
    }

    pub fn position(&self) -> DVec3 {
        self.phys.bodies[self.drone].translation()
    }

    pub fn rotation(&self) -> DQuat {
        *self.phys.bodies[self.drone].rotation()
    }

    /// Ground truth.
    pub fn state(&self) -> DroneState {
        let body = &self.phys.bodies[self.drone];
        let rot = *body.rotation();
        DroneState {
            time: self.time,
            position: body.translation().to_array(),
            quaternion: [rot.w, rot.x, rot.y, rot.z],
            velocity: body.linvel().to_array(),
            omega_body: (rot.inverse() * body.angvel()).to_array(),
            motor_speeds: self.motors.speeds(),
            collisions: self.collisions,
            ground_contacts: self.ground_contacts,
        }
    }

    /// GPS, InertialUnit, Gyro and the four DistanceSensors.
    pub fn sensors(&self) -> SensorReadings {
        let body = &self.phys.bodies[self.drone];
        let rot = *body.rotation();
        let pos = body.translation();
        let origin = pos + rot * DVec3::from_array(RANGE_SENSOR_POSITION);
        let filter = QueryFilter::default().exclude_rigid_body(self.drone);
        let query = self.phys.query_pipeline_with_filter(filter);
        let ranges_mm = RANGE_DIRECTIONS.map(|d| {
            let ray = Ray::new(origin, rot * d);
            range_to_mm(
                query
                    .cast_ray(&ray, crazyflie::RANGE_MAX_M, true)
                    .map(|(_, toi)| toi),
            )
        });
        SensorReadings {
            time: self.time,
            gps: pos.to_array(),
            attitude: inertial_unit_angles(rot),
            gyro: (rot.inverse() * body.angvel()).to_array(),
            ranges_mm,
        }
    }
}
