//! The physics world: the Webots Crazyflie in rapier3d (DESIGN.md §5), its
//! sensors, its camera and the gate course, served over the wire protocol of
//! DESIGN.md §2 by the `world-server` binary; with several drones in
//! lockstep and the radio channel between them (DESIGN.md §7–§8,
//! docs/SWARM.md).

pub mod camera;
pub mod crazyflie;
pub mod dataset;
pub mod foxglove;
pub mod gates;
pub mod lockstep;
pub mod physics;
pub mod radio;
pub mod replay;
pub mod scene;
pub mod sensors;
pub mod server;
pub mod session;
pub mod time;
pub mod trajectory;
pub mod world_file;

pub use crazyflie::MotorCommands;
pub use physics::{StepConfig, World, WorldError};
pub use time::Millis;
pub use world_file::WorldDesc;
