//! The physics world: the Webots Crazyflie in rapier3d (DESIGN.md §5), its
//! sensors, its camera and the gate course, served over the wire protocol of
//! DESIGN.md §2 by the `world-server` binary.

pub mod camera;
pub mod crazyflie;
pub mod physics;
pub mod replay;
pub mod scene;
pub mod sensors;
pub mod server;
pub mod time;
pub mod trajectory;
pub mod world_file;

pub use crazyflie::MotorCommands;
pub use physics::{StepConfig, World, WorldError};
pub use time::Millis;
pub use world_file::WorldDesc;
