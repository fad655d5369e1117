//! `cosim bench cluster`: the AI deck's cluster on the int8 matmul of
//! DESIGN.md §12 (docs/CLUSTER.md "Benchmark"). For each core count, one
//! `sim-core run-elf --stats` of `cluster_matmul_bench.elf` (the kernel
//! [`REPS`] times on every core of a cluster of that size), one after the
//! other, never in parallel. Per row: simulated cycles per matmul,
//! MAC/cycle, speedup over one core, the cluster's energy per MAC (the
//! power model applied to `--stats`' counters), and the host's cost: CPU
//! and wall time, MIPS (every core's executed instructions over the CPU
//! time) and host CPU time per simulated cycle relative to one core (the
//! goal: 8 busy cores cost at most 9× one core's host time). A
//! measurement, not a test: the host figures depend on the machine and its
//! load (the run with the least CPU time of `repeat` is kept); the
//! simulated ones do not (two repeats that differ are an error).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use sim_core::cluster::power::{EnergyModel, REF_VOLTS};

pub use crate::swarm::bench::BenchError;

/// Core counts measured by default.
pub const CORES: [u32; 4] = [1, 2, 4, 8];
/// Matmuls per run: `-DBENCH_REPS` of the ELF's Makefile rule.
pub const REPS: u64 = 256;
/// The cluster clock of every run (MHz, DESIGN.md §12's default).
pub const MHZ: u64 = 175;
/// Multiply-accumulates of one 64×64×64 matmul.
pub const MACS: u64 = 64 * 64 * 64;

/// The ELF, relative to the repository.
pub const ELF: &str = "sim-core/firmware/bin/cluster_matmul_bench.elf";

/// One core count's measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterRow {
    pub cores: u32,
    /// Simulated cluster cycles of one matmul (fork to barrier).
    pub cycles: u64,
    pub checksum: String,
    /// Every core's counters from `--stats`.
    pub stats: RunStats,
    /// Host wall time of the process (the run with the least CPU time of
    /// the repeats).
    pub wall_s: f64,
    /// Its CPU time (user + system): what the host figures use, since the
    /// wall time also counts other programs' load.
    pub cpu_s: f64,
}

impl ClusterRow {
    pub fn mac_per_cycle(&self) -> f64 {
        MACS as f64 / self.cycles as f64
    }
    pub fn mips(&self) -> f64 {
        self.stats.instructions as f64 / self.cpu_s / 1e6
    }
    /// Host CPU seconds per simulated cluster cycle.
    pub fn host_per_cycle(&self) -> f64 {
        self.cpu_s / (self.cycles * REPS) as f64
    }
    /// The cluster's energy per MAC over the whole time it was on (boot,
    /// DMA and the dispatches included), pJ.
    pub fn pj_per_mac(&self) -> f64 {
        self.stats.cluster_energy_j(MHZ) / (MACS * REPS) as f64 * 1e12
    }
}

/// The default ELF: beside the repository's sources.
pub fn default_elf() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(ELF)
}

/// Default output directory.
pub fn default_out() -> PathBuf {
    Path::new("out").join("bench-cluster")
}

/// The value after `key` on the first line that starts with it.
fn field<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    text.lines()
        .find_map(|l| l.trim_start().strip_prefix(key))
        .map(str::trim)
}

/// What `run-elf --stats` reports: the FC's `instructions: N`, each
/// `cluster core I: instructions N, cycles C (gated G), L1 accesses A, ...`
/// and `cluster DMA: B bytes, ...`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunStats {
    /// Every core's executed instructions (the FC's included, without
    /// those idle skipping jumped over).
    pub instructions: u64,
    pub active_cycles: u64,
    pub gated_cycles: u64,
    pub l1_accesses: u64,
    pub dma_bytes: u64,
    /// The longest core's awake + gated cycles: how long the cluster ran.
    pub powered_cycles: u64,
}

impl RunStats {
    /// The cluster's energy with the model of `power.csv` (docs/CLUSTER.md
    /// "Power", sim_core::cluster::power) at its reference voltage.
    pub fn cluster_energy_j(&self, mhz: u64) -> f64 {
        let m = EnergyModel::at(REF_VOLTS);
        // A gated core costs no dynamic energy, only its share of the
        // leakage, which `leakage_w` already holds.
        self.active_cycles as f64 * m.core_active_j
            + self.l1_accesses as f64 * m.l1_access_j
            + self.dma_bytes as f64 * m.dma_byte_j
            + m.leakage_w * self.powered_cycles as f64 / (mhz as f64 * 1e6)
    }
}

/// Reads `--stats` (stderr); None without the FC's instruction count.
pub fn parse_stats(stats: &str) -> Option<RunStats> {
    // The FC's instructions that idle skipping jumped over cost no host
    // time: they do not count for MIPS.
    let skipped: u64 = stats
        .lines()
        .find_map(|l| l.split_once("skipped instructions: "))
        .and_then(|(_, v)| v.trim().parse().ok())
        .unwrap_or(0);
    let mut r = RunStats {
        instructions: field(stats, "instructions:")?
            .parse::<u64>()
            .ok()?
            .saturating_sub(skipped),
        ..RunStats::default()
    };
    // The number after `key` in a comma-separated line.
    let after = |l: &str, key: &str| -> Option<u64> {
        let (_, rest) = l.split_once(key)?;
        rest.split([',', ' ', ')'])
            .find(|w| !w.is_empty())?
            .parse()
            .ok()
    };
    for l in stats.lines() {
        if l.starts_with("cluster core ") {
            let active = after(l, "cycles ")?;
            let gated = after(l, "(gated ")?;
            r.instructions += after(l, ": instructions ")?;
            r.active_cycles += active;
            r.gated_cycles += gated;
            r.l1_accesses += after(l, "L1 accesses ")?;
            r.powered_cycles = r.powered_cycles.max(active + gated);
        } else if let Some(rest) = l.strip_prefix("cluster DMA: ") {
            r.dma_bytes = after(rest, "")?;
        }
    }
    Some(r)
}

/// Why the ELF's `bench` line cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BenchLineError {
    #[error("no `bench` line in the program's output: {0:?}")]
    NoLine(String),
    #[error("no {key} in {line:?}")]
    Missing { key: &'static str, line: String },
    #[error("{key} in {line:?}: {source}")]
    NotANumber {
        key: &'static str,
        line: String,
        source: std::num::ParseIntError,
    },
}

/// Reads the ELF's line `bench cores N reps R cycles C checksum X`.
pub fn parse_bench_line(stdout: &str) -> Result<(u32, u64, u64, String), BenchLineError> {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("bench "))
        .ok_or_else(|| BenchLineError::NoLine(stdout.to_string()))?;
    let f: Vec<&str> = line.split_whitespace().collect();
    let get = |key: &'static str| -> Result<&str, BenchLineError> {
        f.iter()
            .position(|w| *w == key)
            .and_then(|i| f.get(i + 1).copied())
            .ok_or_else(|| BenchLineError::Missing {
                key,
                line: line.to_string(),
            })
    };
    let num = |key: &'static str| -> Result<u64, BenchLineError> {
        get(key)?
            .parse()
            .map_err(|source| BenchLineError::NotANumber {
                key,
                line: line.to_string(),
                source,
            })
    };
    Ok((
        num("cores")? as u32,
        num("reps")?,
        num("cycles")?,
        get("checksum")?.to_string(),
    ))
}

/// CPU time (user + system) of this process's waited-for children, s.
pub(crate) fn children_cpu_s() -> f64 {
    // SAFETY: getrusage only writes the struct it is given.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut u) } != 0 {
        return 0.0;
    }
    let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    s(u.ru_utime) + s(u.ru_stime)
}

/// One run of `sim-core run-elf --stats` on a cluster of `cores` cores.
fn run_once(sim_core: &Path, elf: &Path, cores: u32) -> Result<ClusterRow, BenchError> {
    let err = |m: String| BenchError::Output(format!("{cores} cores: {m}"));
    let started = Instant::now();
    let cpu_before = children_cpu_s();
    let o = Command::new(sim_core)
        .arg("run-elf")
        .arg(elf)
        .arg("--stats")
        .arg("--cluster-cores")
        .arg(cores.to_string())
        .arg("--cluster-mhz")
        .arg(MHZ.to_string())
        .output()
        .map_err(|e| err(format!("cannot run {}: {e}", sim_core.display())))?;
    let wall_s = started.elapsed().as_secs_f64();
    let cpu_s = children_cpu_s() - cpu_before;
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    if !o.status.success() {
        return Err(err(format!(
            "sim-core run-elf failed ({}): {}",
            o.status,
            stderr.trim()
        )));
    }
    let (got, reps, cycles, checksum) =
        parse_bench_line(&stdout).map_err(|e| err(e.to_string()))?;
    if got != cores || reps != REPS || cycles == 0 {
        return Err(err(format!(
            "the program ran {reps} matmuls on {got} cores in {cycles} cycles"
        )));
    }
    Ok(ClusterRow {
        cores,
        cycles: cycles / REPS,
        checksum,
        stats: parse_stats(&stderr).ok_or_else(|| err(format!("no statistics in {stderr:?}")))?,
        wall_s,
        cpu_s,
    })
}

/// Runs the benchmark: `repeat` runs per core count, the fastest kept.
pub fn bench_cluster(
    sim_core: &Path,
    elf: &Path,
    cores: &[u32],
    out: &Path,
    repeat: usize,
    mut progress: impl FnMut(&str),
) -> Result<Vec<ClusterRow>, BenchError> {
    if !elf.is_file() {
        return Err(BenchError::Output(format!(
            "no ELF at {} (make -C sim-core/firmware)",
            elf.display()
        )));
    }
    std::fs::create_dir_all(out)
        .map_err(|e| BenchError::Output(format!("cannot create {}: {e}", out.display())))?;
    let mut rows: Vec<ClusterRow> = Vec::new();
    for &n in cores {
        let mut best: Option<ClusterRow> = None;
        for _ in 0..repeat.max(1) {
            let r = run_once(sim_core, elf, n)?;
            if let Some(b) = &best {
                // Simulated results are deterministic: a change is a bug.
                if b.cycles != r.cycles || b.checksum != r.checksum {
                    return Err(BenchError::Output(format!(
                        "{n} cores: two runs differ ({} vs {} cycles)",
                        b.cycles, r.cycles
                    )));
                }
            }
            if best.as_ref().is_none_or(|b| r.cpu_s < b.cpu_s) {
                best = Some(r);
            }
        }
        let r = best.expect("at least one run");
        progress(&format!(
            "{n} cores: {} cycles, {:.2} MAC/cycle, {:.3} s CPU",
            r.cycles,
            r.mac_per_cycle(),
            r.cpu_s
        ));
        if let Some(first) = rows.first() {
            if first.checksum != r.checksum {
                return Err(BenchError::Output(format!(
                    "{n} cores: checksum {} differs from 1 core's {}",
                    r.checksum, first.checksum
                )));
            }
        }
        rows.push(r);
    }
    std::fs::write(out.join("bench.md"), markdown(&rows))
        .map_err(|e| BenchError::Output(format!("cannot write bench.md: {e}")))?;
    Ok(rows)
}

/// The table, speedup and host cost relative to the first row.
pub fn markdown(rows: &[ClusterRow]) -> String {
    let mut s = String::from(
        "| cores | cycles/matmul | MAC/cycle | speedup | pJ/MAC | host CPU (s) | host wall (s) | MIPS | host time per cycle vs 1st row |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let Some(first) = rows.first() else {
        return s;
    };
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {:.2} | {:.2} | {:.1} | {:.3} | {:.3} | {:.1} | {:.2} |\n",
            r.cores,
            r.cycles,
            r.mac_per_cycle(),
            first.cycles as f64 / r.cycles as f64,
            r.pj_per_mac(),
            r.cpu_s,
            r.wall_s,
            r.mips(),
            r.host_per_cycle() / first.host_per_cycle(),
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bench_line_is_read_and_bad_lines_are_errors() {
        let out = "cluster_matmul: ...\nbench cores 8 reps 16 cycles 300000 checksum 1234abcd\n";
        assert_eq!(
            parse_bench_line(out).unwrap(),
            (8, 16, 300_000, "1234abcd".to_string())
        );
        assert!(matches!(
            parse_bench_line("nothing\n"),
            Err(BenchLineError::NoLine(_))
        ));
        let e = parse_bench_line("bench cores x reps 1 cycles 2 checksum 0\n").unwrap_err();
        assert!(
            matches!(e, BenchLineError::NotANumber { key: "cores", .. }),
            "{e}"
        );
        let e = parse_bench_line("bench cores 1 reps 1 cycles 2\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "no checksum in \"bench cores 1 reps 1 cycles 2\""
        );
    }

    #[test]
    fn stats_of_every_core_are_summed() {
        let stats = "instructions: 130\ncycles: 5\n\
            sleep cycles: 0, polling cycles: 60, skipped instructions: 30\n\
            cluster core 0: instructions 20, cycles 90 (gated 10), L1 accesses 7, L1 stall cycles 0\n\
            cluster core 1: instructions 3, cycles 9 (gated 41), L1 accesses 1, L1 stall cycles 2\n\
            cluster DMA: 512 bytes, 70 transfer cycles\ncluster MIPS: 1.0\n";
        let r = parse_stats(stats).unwrap();
        assert_eq!(
            r,
            RunStats {
                instructions: 123,
                active_cycles: 99,
                gated_cycles: 51,
                l1_accesses: 8,
                dma_bytes: 512,
                powered_cycles: 100,
            }
        );
        let m = EnergyModel::at(REF_VOLTS);
        let want = 99.0 * m.core_active_j
            + 8.0 * m.l1_access_j
            + 512.0 * m.dma_byte_j
            + m.leakage_w * 100.0 / 175e6;
        assert!((r.cluster_energy_j(175) - want).abs() < 1e-18);
        assert_eq!(parse_stats("cycles: 5\n"), None);
    }

    #[test]
    fn table_relates_rows_to_the_first() {
        let row = |cores, cycles, cpu_s| ClusterRow {
            cores,
            cycles,
            checksum: "0".into(),
            stats: RunStats {
                instructions: 1_000_000,
                ..RunStats::default()
            },
            wall_s: 2.0,
            cpu_s,
        };
        let t = markdown(&[row(1, 262_144, 1.0), row(8, 32_768, 1.0)]);
        // 8× fewer cycles in the same wall time: 8× the host time per cycle.
        assert!(
            t.contains("| 8 | 32768 | 8.00 | 8.00 | 0.0 | 1.000 | 2.000 | 1.0 | 8.00 |"),
            "{t}"
        );
        assert!(t.contains("| 1 | 262144 | 1.00 | 1.00 | 0.0 |"), "{t}");
    }
}
