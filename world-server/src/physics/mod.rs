//! The Crazyflies in rapier3d: one body per drone of the world file (flown:
//! dynamic, with the PROTO's mass, inertia and bounding cylinder and four
//! propellers pushing at their `centerOfThrust`; carried: kinematic, moved
//! along its path), and fixed colliders for the ground, gates and boxes.
//!
//! The world advances only in whole basicTimeSteps (DESIGN.md §3), each
//! optionally split into `substeps` physics steps; all drones step together.
//! With one drone, every operation is the one the single-drone world did, in
//! the same order, so its trajectories are bit-identical to it.

mod drone;

use rapier3d::glamx::{DQuat, DVec3};
use rapier3d::prelude::*;

use crate::crazyflie::{self, MotorCommandError, MotorCommands, Motors, GRAVITY};
use crate::gates::{openings, GateTracker};
use crate::scene::{scene_boxes, ObjectId, SceneBox};
use crate::sensors::{DroneState, SensorReadings};
use crate::time::Millis;
use crate::world_file::{CarriedPath, SensorConfig, WorldDesc};

use drone::DroneBody;

/// Webots's default contact friction (`ContactProperties { coulombFriction 1 }`);
/// its `bounce 0.5` is the world file's `[physics] restitution` default.
const FRICTION: f64 = 1.0;

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
    /// Out of the timestep's one range (`protocol::TimestepMs`).
    #[error(transparent)]
    Timestep(#[from] protocol::TimestepError),
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
    /// In world-file order.
    drones: Vec<DroneBody>,
    time: Millis,
    cfg: StepConfig,
    boxes: Vec<SceneBox>,
    /// Gates passed by each drone (DESIGN.md §10).
    gates: GateTracker,
    /// The world file's `[sensors]`.
    sensor_cfg: SensorConfig,
}

impl World {
    /// Builds the world of `desc` with every drone at its start pose, at
    /// rest, time 0.
    pub fn new(desc: &WorldDesc, cfg: StepConfig) -> Result<World, WorldError> {
        protocol::TimestepMs::new(cfg.timestep.0)?;
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
            .restitution(desc.physics.restitution.0)
            .user_data(ObjectId::Ground.to_user_data());
        phys.insert_collider(ground, None);

        let boxes = scene_boxes(desc);
        for b in &boxes {
            let collider = ColliderBuilder::cuboid(b.half.x, b.half.y, b.half.z)
                .position(Pose::from_parts(b.centre, DQuat::from_rotation_z(b.yaw)))
                .friction(FRICTION)
                .restitution(desc.physics.restitution.0)
                .user_data(b.object.to_user_data());
            phys.insert_collider(collider, None);
        }

        let drones: Vec<DroneBody> = desc
            .drones
            .iter()
            .enumerate()
            .map(|(i, d)| DroneBody::insert(&mut phys, i, d, &desc.physics))
            .collect();
        let starts: Vec<DVec3> = drones.iter().map(|d| d.position(&phys)).collect();
        let gates = GateTracker::new(openings(desc), &starts);
        // Make scene queries (range sensors) valid before the first step.
        phys.detect_collisions(&(), &());

        Ok(World {
            phys,
            drones,
            time: Millis::ZERO,
            cfg,
            boxes,
            gates,
            sensor_cfg: SensorConfig {
                // σ per 32 ms sample in the file: the same noise density at
                // this timestep.
                flow_noise_m_s: desc.sensors.flow_noise_m_s
                    * protocol::TimestepMs::new(cfg.timestep.0)?.white_noise_scale(),
                ..desc.sensors.clone()
            },
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

    /// Number of drones (world-file order is their index).
    pub fn drone_count(&self) -> usize {
        self.drones.len()
    }

    /// True when drone `d` is carried along a path rather than flown.
    pub fn is_carried(&self, d: usize) -> bool {
        self.drones[d].is_carried()
    }

    pub fn motors(&self, d: usize) -> &Motors {
        &self.drones[d].motors
    }

    pub fn motors_mut(&mut self, d: usize) -> &mut Motors {
        &mut self.drones[d].motors
    }

    /// New PID motor targets (magnitudes, rad/s) of drone `d`; nothing
    /// changes if one is invalid. A carried drone's are checked and ignored.
    pub fn set_motor_commands(&mut self, d: usize, cmd: MotorCommands) -> Result<(), WorldError> {
        cmd.validate()?;
        let drone = &mut self.drones[d];
        if !drone.is_carried() {
            drone.motors.set_targets(cmd);
        }
        Ok(())
    }

    /// STOP of drone `d`: its motor targets go to 0 (the world then steps
    /// until [`World::propellers_stopped`]).
    pub fn stop_propellers(&mut self, d: usize) {
        self.drones[d].motors.set_signed_targets([0.0; 4]);
    }

    /// True when every propeller of drone `d` stands still (always for a
    /// carried drone, whose motors never turn).
    pub fn propellers_stopped(&self, d: usize) -> bool {
        self.drones[d].motors.all_stopped()
    }

    /// The thesis's warm-up: every flown drone's motors at ±1 rad/s, 2000 ms
    /// (Appendix E), one warm-up for all drones.
    ///
    /// The contract has TIME start at exactly 2.000 s, but 2000 is not a
    /// multiple of every timestep (32 ms: 62.5 steps), so the warm-up ends
    /// with one shorter step of the remainder. It is the only step that is not
    /// a whole basicTimeStep, and it happens before any request is served.
    pub fn warm_up(&mut self, mut on_step: impl FnMut(&World)) {
        use crazyflie::{SPIN_SIGNS, WARMUP_MS, WARMUP_SPEED};
        for d in self.drones.iter_mut().filter(|d| !d.is_carried()) {
            d.motors
                .set_signed_targets(SPIN_SIGNS.map(|s| s * WARMUP_SPEED));
        }
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

    /// Advances `ms` milliseconds holding the motor targets (ADVANCE_TIME
    /// of a single-drone world, tests); `on_step` sees every step. Nothing
    /// happens if `ms` is not a multiple of the timestep.
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

    /// Sets drone `d`'s targets to 0 and steps until its propellers have
    /// stopped; returns the world time spent stopping. `on_step` sees every
    /// step. (The server does the same through its lockstep.)
    pub fn stop_motors(&mut self, d: usize, mut on_step: impl FnMut(&World)) -> Millis {
        self.stop_propellers(d);
        let t0 = self.time;
        while !self.propellers_stopped(d) {
            self.step();
            on_step(self);
        }
        Millis(self.time.0 - t0.0)
    }

    /// One basicTimeStep of every drone.
    pub fn step(&mut self) {
        self.step_ms(self.cfg.timestep);
    }

    /// One step of `ms` milliseconds, split into the configured substeps.
    fn step_ms(&mut self, ms: Millis) {
        let substeps = self.cfg.substeps;
        let h = ms.0 as f64 / 1000.0 / substeps as f64;
        self.phys.integration_parameters.dt = h;
        for k in 1..=substeps {
            // Where a carried drone must be at the end of this substep (s).
            let t_end_s = (self.time.0 as f64 + ms.0 as f64 * k as f64 / substeps as f64) / 1000.0;
            for d in &mut self.drones {
                d.prepare_substep(&mut self.phys, h, t_end_s);
            }
            self.phys.step();
            for (i, d) in self.drones.iter_mut().enumerate() {
                d.update_contacts(&self.phys, self.time);
                self.gates.moved(i, d.position(&self.phys));
            }
        }
        self.time += ms;
    }

    /// Places drone `d` at a pose, at rest (tests, and later replay).
    pub fn teleport(&mut self, d: usize, position: DVec3, rotation: DQuat) {
        let body = &mut self.phys.bodies[self.drones[d].body];
        body.set_position(Pose::from_parts(position, rotation), true);
        body.set_linvel(DVec3::ZERO, true);
        body.set_angvel(DVec3::ZERO, true);
        self.gates.placed(d, position);
    }

    /// Sets drone `d`'s velocities (tests).
    pub fn set_velocities(&mut self, d: usize, linvel: DVec3, angvel_world: DVec3) {
        let body = &mut self.phys.bodies[self.drones[d].body];
        body.set_linvel(linvel, true);
        body.set_angvel(angvel_world, true);
    }

    pub fn position(&self, d: usize) -> DVec3 {
        self.drones[d].position(&self.phys)
    }

    pub fn rotation(&self, d: usize) -> DQuat {
        *self.phys.bodies[self.drones[d].body].rotation()
    }

    /// Every drone's centre (m), in world-file order.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.drones
            .iter()
            .map(|d| d.position(&self.phys).to_array())
            .collect()
    }

    /// The path of drone `d` if it is carried.
    pub fn carried_path(&self, d: usize) -> Option<&CarriedPath> {
        self.drones[d].carried()
    }

    /// Ground truth of drone `d`.
    pub fn state(&self, d: usize) -> DroneState {
        let mut s = self.drones[d].state(&self.phys, self.time);
        s.gates_passed = self.gates.passed(d);
        s
    }

    /// Number of gates in the world.
    pub fn gates_total(&self) -> u64 {
        self.gates.total()
    }

    /// GPS, InertialUnit, Gyro and the four DistanceSensors of drone `d`
    /// (and what the world's `[sensors]` adds).
    pub fn sensors(&self, d: usize) -> SensorReadings {
        self.drones[d].sensors(&self.phys, self.time, &self.sensor_cfg, d)
    }
}
