//! The virtual platform: the MESSY + GVSoC side of the thesis (DESIGN.md §1, §3, §4).
//!
//! The thesis's boxes are modules you can find by name:
//! - [`iss`]: the RV32IMC instruction-set simulator (GVSoC's fabric controller),
//! - [`cluster`]: the AI deck's GAP8 cluster (8 cores, L1, DMA, event unit),
//! - [`bus`]: the functional bus and the peripheral window,
//! - [`peripherals`]: camera, STM32 (with the PID) and motors, each with a
//!   functional side and a power side,
//! - [`power`]: power buses, converters, battery and motor power models,
//! - [`sync`]: time and offset bookkeeping against the world (§4.2.4),
//! - [`kernel`]: the event kernel that interleaves the ISS and the devices,
//! - [`machine`]: the FC and the cluster as one machine, and `sim-core run-elf`,
//! - [`config`]: the platform file (MESSY's JSON shape) and the run configuration.

pub mod bus;
pub mod cluster;
pub mod config;
pub mod iss;
pub mod kernel;
pub mod machine;
pub mod map_image;
pub mod peripherals;
pub mod power;
pub mod sync;
pub mod units;
