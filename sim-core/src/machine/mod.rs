//! Machines built on the ISS: the FC and, when the platform has one, the
//! cluster beside it (DESIGN.md §4, §12). The ISS below (`crate::iss`)
//! knows nothing of the cluster; this is where the two meet.
//!
//! - [`run_elf`]: the `sim-core run-elf` driver (riscv-tests `tohost`,
//!   semihosting, RISCOF signatures).

pub mod run_elf;
