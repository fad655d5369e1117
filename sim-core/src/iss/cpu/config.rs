//! What a core is built with: its clock, hart id, memory timing and the
//! ISS back end that runs it.

use super::*;

/// Core parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CpuConfig {
    /// Core clock (platform file `core.frequency`; default 250 MHz).
    pub clock: Hertz,
    /// Extra cycles of every access to an MMIO window; the device sees the
    /// access at `(issue cycle + latency) × period` (see `mem.rs`).
    pub mmio_latency: Cycles,
    /// Exact idle skipping of polling loops and `wfi` sleeps.
    pub idle_skip: bool,
    /// A plain (non-semihosting) `ebreak` stops the run with
    /// [`StopReason::Breakpoint`] instead of trapping, like a debugger.
    pub ebreak_stops: bool,
    pub hart_id: u32,
    /// What runs the cached blocks: the interpreter or the translator
    /// (identical results; `--iss`, `--set iss=`).
    pub iss: Backend,
}

/// The ISS back end (DESIGN.md §14). Both give bit-identical state,
/// cycles and device-visible times; the translator is faster.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// The threaded interpreter (`exec.rs`), on every host; the reference.
    Interp,
    /// The block translator (`jit/`) in front of the interpreter; x86-64
    /// only (elsewhere it runs as the interpreter).
    Jit,
}

impl Backend {
    /// The translator on x86-64, the interpreter elsewhere.
    pub const DEFAULT: Backend = if cfg!(target_arch = "x86_64") {
        Backend::Jit
    } else {
        Backend::Interp
    };

    pub fn name(self) -> &'static str {
        match self {
            Backend::Interp => "interp",
            Backend::Jit => "jit",
        }
    }
}

impl Default for Backend {
    fn default() -> Self {
        Backend::DEFAULT
    }
}

impl std::str::FromStr for Backend {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "interp" => Ok(Backend::Interp),
            "jit" => Ok(Backend::Jit),
            _ => Err(format!(
                "unknown ISS back end {s:?} (expected interp or jit)"
            )),
        }
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Default for CpuConfig {
    fn default() -> Self {
        CpuConfig {
            clock: Hertz(250_000_000),
            mmio_latency: Cycles(0),
            idle_skip: true,
            ebreak_stops: false,
            hart_id: 0,
            iss: Backend::DEFAULT,
        }
    }
}
