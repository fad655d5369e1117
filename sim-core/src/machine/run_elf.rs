//! `sim-core run-elf`: run a bare-metal RISC-V ELF on the ISS alone, the way
//! riscv-tests (`tohost`) and the architecture tests (`--signature`) expect.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};

use crate::cluster::{Cluster, ClusterConfig};
use crate::units::{Hertz, Picos};

use crate::iss::{
    load_elf, map, Backend, CpuConfig, IssError, LoadedElf, Memory, NoDevices, StopReason,
};

/// Default RAM: 16 MiB from the lowest loaded address rounded down to 64 KiB.
pub const DEFAULT_RAM_SIZE: u32 = 16 << 20;
const DEFAULT_RAM_ALIGN: u32 = 64 << 10;

/// Exit status when `--max-instructions` is reached (as `timeout(1)`).
pub const EXIT_INSTRUCTION_LIMIT: i32 = 124;

/// A RAM region given on the command line as `BASE:SIZE`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RamSpec {
    pub base: u32,
    pub size: u32,
}

fn parse_num(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (digits, mult) = match s.char_indices().last() {
        Some((i, 'K' | 'k')) => (&s[..i], 1u64 << 10),
        Some((i, 'M' | 'm')) => (&s[..i], 1 << 20),
        _ => (s, 1),
    };
    let v = match digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16),
        None => digits.replace('_', "").parse(),
    }
    .map_err(|e| format!("bad number {s:?}: {e}"))?;
    v.checked_mul(mult)
        .ok_or_else(|| format!("{s:?} is too large"))
}

impl std::str::FromStr for RamSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (b, z) = s
            .split_once(':')
            .ok_or_else(|| format!("expected BASE:SIZE, got {s:?}"))?;
        let base = parse_num(b)?;
        let size = parse_num(z)?;
        if base > u32::MAX as u64 || size == 0 || base + size > 1 << 32 {
            return Err(format!("region {s:?} does not fit in 32-bit addresses"));
        }
        Ok(RamSpec {
            base: base as u32,
            size: size as u32,
        })
    }
}

/// Arguments of `sim-core run-elf`.
#[derive(Debug, Clone, clap::Args)]
pub struct RunElfArgs {
    /// The ELF executable to run.
    pub file: PathBuf,
    /// A RAM region BASE:SIZE (hex with 0x, or decimal; K/M suffixes);
    /// repeatable. Replaces the default 16 MiB region.
    #[arg(long = "ram", value_name = "BASE:SIZE")]
    pub ram: Vec<RamSpec>,
    /// Write the words between `begin_signature` and `end_signature` here.
    #[arg(long, value_name = "FILE")]
    pub signature: Option<PathBuf>,
    /// Stop after N instructions (exit status 124).
    #[arg(long, value_name = "N")]
    pub max_instructions: Option<u64>,
    /// Print instructions, cycles, simulated time, wall time and MIPS to
    /// stderr.
    #[arg(long)]
    pub stats: bool,
    /// Disable idle skipping (for comparisons; results are identical).
    #[arg(long)]
    pub no_idle_skip: bool,
    /// Cluster cores (1-8) beside the FC (DESIGN.md §12, docs/CLUSTER.md);
    /// the cluster is off until the program powers it.
    #[arg(long, value_name = "N", default_value_t = 8)]
    pub cluster_cores: usize,
    /// The cluster clock in MHz.
    #[arg(long, value_name = "MHZ", default_value_t = 175)]
    pub cluster_mhz: u64,
    /// Run the FC alone, as before the cluster existed (its mhartid is
    /// then 0, and 0x1000_0000 is free for --ram). Programs that park
    /// every hart but hart 0, as riscv-tests do, need it.
    #[arg(long)]
    pub no_cluster: bool,
    /// The ISS back end: `jit` (the block translator, x86-64 hosts) or
    /// `interp` (the interpreter, the reference); identical results.
    #[arg(long, value_name = "interp|jit", default_value_t = Backend::DEFAULT)]
    pub iss: Backend,
}

/// Build the memory map for `run-elf`: the given regions (or the default
/// one), plus L2 and the peripheral window of the GAP8-like map where they do
/// not collide.
pub fn build_memory(regions: &[RamSpec], lowest: Option<u32>) -> anyhow::Result<Memory> {
    let mut mem = Memory::new();
    if regions.is_empty() {
        let base = lowest.unwrap_or(map::L2_BASE) & !(DEFAULT_RAM_ALIGN - 1);
        let size = (DEFAULT_RAM_SIZE as u64).min((1u64 << 32) - base as u64) as u32;
        mem.add_ram(base, size)
            .with_context(|| format!("default RAM at {base:#010x}"))?;
    }
    for r in regions {
        mem.add_ram(r.base, r.size)
            .with_context(|| format!("--ram {:#x}:{:#x}", r.base, r.size))?;
    }
    // The GAP8-like map, unless the program's own RAM already covers it.
    let _ = mem.add_ram(map::L2_BASE, map::L2_SIZE);
    let _ = mem.add_mmio_window(map::PERIPH_BASE, map::PERIPH_SIZE);
    Ok(mem)
}

/// Run the program; returns the process exit status.
pub fn run(args: &RunElfArgs) -> anyhow::Result<i32> {
    let bytes =
        std::fs::read(&args.file).with_context(|| format!("reading {}", args.file.display()))?;
    let elf = load_elf(&bytes).with_context(|| format!("loading {}", args.file.display()))?;
    let mut mem = build_memory(&args.ram, elf.lowest_address())?;
    elf.load_into(&mut mem)
        .with_context(|| format!("loading {}", args.file.display()))?;

    let fc_cfg = CpuConfig {
        idle_skip: !args.no_idle_skip,
        iss: args.iss,
        ..CpuConfig::default()
    };
    let cluster_cfg = (!args.no_cluster).then(|| ClusterConfig {
        cores: args.cluster_cores,
        clock: Hertz(args.cluster_mhz.saturating_mul(1_000_000)),
        idle_skip: !args.no_idle_skip,
        iss: args.iss,
        ..ClusterConfig::default()
    });
    let super::Machine {
        fc: mut cpu,
        mut cluster,
        code: mut cache,
    } = super::Machine::new(&mut mem, fc_cfg, cluster_cfg)
        .context("the cluster (--no-cluster to run the FC alone)")?;
    cpu.set_pc(elf.entry);
    cpu.set_tohost(elf.symbol("tohost"));
    cpu.set_instruction_limit(args.max_instructions);

    let wall = Instant::now();
    let reason = match cluster.as_mut() {
        Some(c) => c.run_until(&mut cpu, &mut mem, &mut cache, &mut NoDevices, Picos::MAX),
        None => cpu.run_until(&mut mem, &mut cache, &mut NoDevices, Picos::MAX),
    };
    let wall = wall.elapsed();
    cpu.flush_console().context("flushing the console")?;
    if let Some(c) = cluster.as_mut() {
        c.flush_console().context("flushing the console")?;
    }

    let code = match reason {
        StopReason::Exit { code } => code,
        StopReason::InstructionLimit => {
            eprintln!(
                "sim-core: stopped after {} instructions (--max-instructions)",
                cpu.instret()
            );
            EXIT_INSTRUCTION_LIMIT
        }
        StopReason::Idle => bail!(
            "hart {:#x} (FC) at {:#010x} is idle forever (wfi or polling with nothing to wake it)",
            cpu.config().hart_id,
            cpu.pc()
        ),
        StopReason::Fatal(IssError::NeverProgress { hart, pc, why }) => {
            // riscv-tests and most bare-metal start-up code park every hart
            // but hart 0; with the cluster the FC is not hart 0.
            let hint = if cluster.is_some() && hart != 0 {
                " (a hart-0 program? try --no-cluster)"
            } else {
                ""
            };
            bail!("hart {hart:#x} (FC) at {pc:#010x} {why}: it can never progress{hint}")
        }
        StopReason::Fatal(e) => bail!("{e}"),
        other => bail!("unexpected stop: {other:?} at pc {:#010x}", cpu.pc()),
    };

    if let Some(path) = &args.signature {
        write_signature(&mem, &elf, path)?;
    }
    if args.stats {
        let s = cpu.stats();
        let secs = wall.as_secs_f64();
        eprintln!("instructions: {}", s.instructions);
        eprintln!("cycles: {}", s.cycles);
        eprintln!("simulated time: {}", cpu.now());
        eprintln!("wall time: {secs:.6} s");
        eprintln!(
            "MIPS: {:.1}",
            (s.instructions - s.skipped_instructions) as f64 / secs.max(1e-9) / 1e6
        );
        eprintln!(
            "sleep cycles: {}, polling cycles: {}, skipped instructions: {}",
            s.sleep_cycles, s.poll_cycles, s.skipped_instructions
        );
        #[cfg(target_arch = "x86_64")]
        if let Some(j) = cache.jit_stats() {
            eprintln!(
                "jit: {} blocks translated, {} KiB of code, {} flushes",
                j.translated,
                j.code_bytes / 1024,
                j.flushes
            );
        }
        if let Some(c) = &cluster {
            print_cluster_stats(c, &mem, secs);
        }
    }
    Ok(code)
}

/// One line per cluster core (`--stats`): what it ran, how long it was
/// awake and gated, its L1 accesses and bank-conflict stalls; then the DMA.
fn print_cluster_stats(c: &Cluster, mem: &Memory, secs: f64) {
    let reports = c.report(mem);
    let mut total = 0;
    for (i, r) in reports.iter().enumerate() {
        total += r.instructions;
        eprintln!(
            "cluster core {i}: instructions {}, cycles {} (gated {}), L1 accesses {}, L1 stall cycles {}",
            r.instructions, r.active_cycles, r.gated_cycles, r.l1_accesses, r.l1_stall_cycles
        );
    }
    let (bytes, cycles) = c.dma_totals();
    eprintln!("cluster DMA: {bytes} bytes, {cycles} transfer cycles");
    eprintln!("cluster MIPS: {:.1}", total as f64 / secs.max(1e-9) / 1e6);
}

/// The RISCOF/Spike signature: one word per line, 8 lowercase hex digits.
pub fn signature_text(mem: &Memory, begin: u32, end: u32) -> anyhow::Result<String> {
    if end < begin {
        bail!("end_signature ({end:#010x}) is before begin_signature ({begin:#010x})");
    }
    let mut out = String::with_capacity(((end - begin) / 4 * 9) as usize);
    let mut a = begin;
    while a < end {
        let w = mem
            .read_u32(a)
            .with_context(|| format!("signature word at {a:#010x} is not in RAM"))?;
        out.push_str(&format!("{w:08x}\n"));
        a += 4;
    }
    Ok(out)
}

fn write_signature(mem: &Memory, elf: &LoadedElf, path: &std::path::Path) -> anyhow::Result<()> {
    let (Some(b), Some(e)) = (elf.symbol("begin_signature"), elf.symbol("end_signature")) else {
        bail!("--signature: the ELF has no begin_signature/end_signature symbols");
    };
    let text = signature_text(mem, b, e)?;
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
