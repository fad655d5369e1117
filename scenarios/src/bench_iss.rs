//! `cosim bench iss`: the ISS back ends (DESIGN.md §14) on CPU-bound
//! programs. For each ELF, `sim-core run-elf --stats --iss interp` and
//! `--iss jit`, one after the other, never in parallel; per row the
//! instructions, CPU time and MIPS of each back end and their ratio, and
//! `qemu-system-riscv32 -icount shift=0`'s CPU time on the same ELF when
//! asked for (`--qemu`) and QEMU is installed. A measurement, not a test:
//! host figures depend on the machine and its load (the run with the least
//! CPU time of `repeat` is kept); the simulated ones do not, and a back end
//! whose instruction or cycle count differs from the interpreter's is an
//! error.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::bench_cluster::children_cpu_s;
pub use crate::swarm::bench::BenchError;

/// The committed programs measured by default (CPU-bound: the explore
/// self-test's fixed-point kernels, the bench firmware's integer mix, the
/// XCV dot-product loop, the cluster matmul on 8 cores).
pub const ELFS: [&str; 4] = [
    "sim-core/firmware/bin/explore_selftest.elf",
    "sim-core/firmware/bin/bench.elf",
    "sim-core/firmware/bin/xcv_bench.elf",
    "sim-core/firmware/bin/cluster_matmul_bench.elf",
];

/// The default ELFs, beside the repository's sources.
pub fn default_elfs() -> Vec<PathBuf> {
    ELFS.iter()
        .map(|e| Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(e))
        .collect()
}

/// One back end's run of one ELF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run {
    /// Executed instructions (every core's, idle-skipped ones excluded).
    pub instructions: u64,
    /// The FC's cycles.
    pub cycles: u64,
    /// CPU time (user + system) of the process, s.
    pub cpu_s: f64,
}

impl Run {
    pub fn mips(&self) -> f64 {
        self.instructions as f64 / self.cpu_s / 1e6
    }
}

/// One ELF's measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct IssRow {
    pub elf: String,
    pub interp: Run,
    pub jit: Run,
    /// QEMU's CPU time, if measured and the ELF ran there.
    pub qemu_s: Option<f64>,
}

/// The value after `key` on the first stderr line that starts with it.
fn stat(text: &str, key: &str) -> Option<u64> {
    text.lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.trim().parse().ok())
}

fn run_once(sim_core: &Path, elf: &Path, iss: &str) -> Result<Run, BenchError> {
    let err = |m: String| BenchError::Output(format!("{} ({iss}): {m}", elf.display()));
    let before = children_cpu_s();
    let o = Command::new(sim_core)
        .arg("run-elf")
        .arg(elf)
        .args(["--stats", "--iss", iss])
        .stdout(Stdio::null())
        .output()
        .map_err(|e| err(format!("cannot run {}: {e}", sim_core.display())))?;
    let cpu_s = children_cpu_s() - before;
    let stderr = String::from_utf8_lossy(&o.stderr);
    if !o.status.success() {
        return Err(err(format!(
            "run-elf failed ({}): {}",
            o.status,
            stderr.trim()
        )));
    }
    let fc = stat(&stderr, "instructions:").ok_or_else(|| err("no statistics".into()))?;
    let skipped = stderr
        .lines()
        .find_map(|l| l.split("skipped instructions:").nth(1))
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(0);
    let cluster = cluster_instructions(&stderr);
    Ok(Run {
        instructions: fc - skipped + cluster,
        cycles: stat(&stderr, "cycles:").ok_or_else(|| err("no cycle count".into()))?,
        cpu_s,
    })
}

/// QEMU's CPU time on `elf` (`-icount shift=0`: one instruction per
/// virtual nanosecond, its cycle-approximate mode), if it runs there.
fn qemu_once(elf: &Path) -> Option<f64> {
    let before = children_cpu_s();
    let o = Command::new("qemu-system-riscv32")
        .args([
            "-M",
            "virt",
            "-nographic",
            "-bios",
            "none",
            "-icount",
            "shift=0",
        ])
        .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .ok()?;
    let cpu = children_cpu_s() - before;
    o.success().then_some(cpu)
}

/// The fastest of `repeat` runs (by CPU time).
fn best(repeat: usize, mut f: impl FnMut() -> Result<Run, BenchError>) -> Result<Run, BenchError> {
    let mut best: Option<Run> = None;
    for _ in 0..repeat.max(1) {
        let r = f()?;
        if let Some(b) = best {
            if (b.instructions, b.cycles) != (r.instructions, r.cycles) {
                return Err(BenchError::Output(format!(
                    "two runs of the same program differ: {b:?} and {r:?}"
                )));
            }
        }
        if best.is_none_or(|b| r.cpu_s < b.cpu_s) {
            best = Some(r);
        }
    }
    Ok(best.expect("at least one run"))
}

/// Runs the benchmark.
pub fn bench_iss(
    sim_core: &Path,
    elfs: &[PathBuf],
    qemu: bool,
    repeat: usize,
    mut progress: impl FnMut(&str),
) -> Result<Vec<IssRow>, BenchError> {
    let mut rows = Vec::new();
    for elf in elfs {
        if !elf.is_file() {
            return Err(BenchError::Output(format!(
                "{}: no such ELF",
                elf.display()
            )));
        }
        let name = elf
            .file_name()
            .map_or_else(|| elf.display().to_string(), |n| n.to_string_lossy().into());
        progress(&format!("{name}: interp"));
        let interp = best(repeat, || run_once(sim_core, elf, "interp"))?;
        progress(&format!("{name}: jit"));
        let jit = best(repeat, || run_once(sim_core, elf, "jit"))?;
        if (jit.instructions, jit.cycles) != (interp.instructions, interp.cycles) {
            return Err(BenchError::Output(format!(
                "{name}: the translator's counts differ from the interpreter's: {jit:?} vs {interp:?}"
            )));
        }
        let qemu_s = if qemu {
            progress(&format!("{name}: qemu"));
            (0..repeat.max(1))
                .filter_map(|_| qemu_once(elf))
                .min_by(f64::total_cmp)
        } else {
            None
        };
        rows.push(IssRow {
            elf: name,
            interp,
            jit,
            qemu_s,
        });
    }
    Ok(rows)
}

/// The table (markdown).
pub fn markdown(rows: &[IssRow]) -> String {
    let mut s = String::from(
        "| program | instructions | cycles | interp CPU s (MIPS) | jit CPU s (MIPS) | jit / interp | QEMU -icount CPU s |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {:.3} ({:.0}) | {:.3} ({:.0}) | {:.2}x | {} |\n",
            r.elf,
            r.interp.instructions,
            r.interp.cycles,
            r.interp.cpu_s,
            r.interp.mips(),
            r.jit.cpu_s,
            r.jit.mips(),
            r.interp.cpu_s / r.jit.cpu_s,
            r.qemu_s.map_or("—".to_string(), |q| format!("{q:.3}")),
        ));
    }
    s
}

/// Every cluster core's instructions in `run-elf --stats` output (`cluster
/// core I: instructions N, ...`), summed.
fn cluster_instructions(stderr: &str) -> u64 {
    stderr
        .lines()
        .filter(|l| l.starts_with("cluster core "))
        .filter_map(|l| {
            l.split("instructions ")
                .nth(1)?
                .split(',')
                .next()?
                .parse::<u64>()
                .ok()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_run_elf_statistics() {
        let text = "instructions: 1000\ncycles: 1500\nsimulated time: 6 us\nsleep cycles: 0, polling cycles: 10, skipped instructions: 100\ncluster core 0: instructions 50, cycles 60 (gated 0), L1 accesses 0, L1 stall cycles 0\ncluster core 1: instructions 70, cycles 80 (gated 0), L1 accesses 0, L1 stall cycles 0\n";
        assert_eq!(stat(text, "instructions:"), Some(1000));
        assert_eq!(stat(text, "cycles:"), Some(1500));
        assert_eq!(cluster_instructions(text), 120);
    }
}
