//! Machines built on the ISS: the FC and, when the platform has one, the
//! cluster beside it (DESIGN.md §4, §12). The ISS below (`crate::iss`)
//! knows nothing of the cluster; this is where the two meet.
//!
//! - [`Machine`]: the one place that assembles FC + cluster, used by the
//!   platform's kernel, `sim-core run-elf` and `cosim nn`'s machine;
//! - [`run_elf`]: the `sim-core run-elf` driver (riscv-tests `tohost`,
//!   semihosting, RISCOF signatures).

pub mod run_elf;

use crate::cluster::{Cluster, ClusterConfig, ClusterError};
use crate::iss::{CodeCache, Cpu, CpuConfig, Memory};

/// The FC and its cluster, assembled in the order the hardware needs: the
/// cluster maps its L1 and event unit into `mem` first, then the FC gets
/// the cluster's hart id (GAP8's FC is hart 0x400, not 0: what a
/// riscv-tests start-up parks) and its path to the L1 through the
/// cluster's bank arbiter. Without a cluster the FC is built as
/// configured. The code cache the FC and the cluster's cores share goes
/// beside the memory, as `mem` does with every run (`code` in
/// [`Cpu::run_until`], [`Cluster::run_until`]).
pub struct Machine {
    pub fc: Cpu,
    pub cluster: Option<Cluster>,
    pub code: CodeCache,
}

impl Machine {
    /// Builds the FC from `fc` and, with `cluster`, the cluster on `mem`.
    pub fn new(
        mem: &mut Memory,
        fc: CpuConfig,
        cluster: Option<ClusterConfig>,
    ) -> Result<Machine, ClusterError> {
        let cluster = cluster.map(|c| Cluster::new(c, mem)).transpose()?;
        let fc = match cluster {
            Some(_) => {
                let mut fc = Cpu::new(Cluster::fc_config(fc));
                Cluster::attach_fc(&mut fc);
                fc
            }
            None => Cpu::new(fc),
        };
        Ok(Machine {
            fc,
            cluster,
            code: CodeCache::new(),
        })
    }
}
