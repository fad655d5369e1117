//! Helpers shared by the ISS integration tests.
#![allow(dead_code)]

pub mod encode;
pub mod op_device;

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use sim_core::iss::CodeCache;
use sim_core::iss::{load_elf, Cpu, CpuConfig, LoadedElf, Memory, NoDevices, StopReason};
use sim_core::machine::run_elf::{build_memory, RamSpec};
use sim_core::units::Picos;

/// A console sink the test can read back.
#[derive(Clone, Default)]
pub struct Console(pub Arc<Mutex<Vec<u8>>>);

impl Write for Console {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Console {
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.0.lock().unwrap()).into_owned()
    }
}

pub fn firmware(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("firmware/bin")
        .join(format!("{name}.elf"))
}

/// A core and memory with the ELF loaded as `run-elf` would.
pub fn load(name: &str, cfg: CpuConfig, ram: &[RamSpec]) -> (Cpu, Memory, LoadedElf, Console) {
    let bytes =
        std::fs::read(firmware(name)).expect("firmware ELF (run make -C sim-core/firmware)");
    let elf = load_elf(&bytes).unwrap();
    let mut mem = build_memory(ram, elf.lowest_address()).unwrap();
    elf.load_into(&mut mem).unwrap();
    let mut cpu = Cpu::new(cfg);
    cpu.set_pc(elf.entry);
    cpu.set_tohost(elf.symbol("tohost"));
    let console = Console::default();
    cpu.set_console(Box::new(console.clone()));
    (cpu, mem, elf, console)
}

/// Run a firmware to its end; returns the exit code and the console text.
pub fn run_firmware(name: &str) -> (i32, String, Cpu) {
    let (mut cpu, mut mem, _, console) = load(name, CpuConfig::default(), &[]);
    let mut code = CodeCache::new();
    cpu.set_instruction_limit(Some(200_000_000));
    let code = match cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX) {
        StopReason::Exit { code } => code,
        other => panic!("{name}: unexpected stop {other:?} at pc {:#x}", cpu.pc()),
    };
    (code, console.text(), cpu)
}

/// Random code for the ISS property tests (`iss_instructions`' block-vs-step
/// test, `iss_jit`'s translator-vs-interpreter test): real major opcodes
/// chosen by `opcodes` (an index past the table keeps the raw word: any
/// encoding, illegal ones included) with random fields from `raw`, every
/// register field x0..x7 (results often used by the next instruction:
/// load-use stalls), loads and stores (XCV's post-increment ones too) with
/// small positive offsets, so most accesses hit the program's own memory
/// and some rewrite code. The four custom opcodes are CORE-V XCV.
pub fn random_code(raw: &[u32], opcodes: &[usize]) -> Vec<u32> {
    const MAJOR: [u32; 15] = [
        0x13, 0x33, 0x03, 0x23, 0x63, 0x37, 0x17, 0x6f, 0x67, 0x73, 0x0f, 0x0b, 0x2b, 0x5b, 0x7b,
    ];
    const HIGH_REG_BITS: u32 = 0x18 << 7 | 0x18 << 15 | 0x18 << 20;
    raw.iter()
        .zip(opcodes)
        .map(|(&w, &k)| match MAJOR.get(k) {
            Some(&m @ (0x03 | 0x23 | 0x0b | 0x2b)) => {
                (w & !0x7f & !HIGH_REG_BITS & 0x0fff_ffff) | m
            }
            Some(&m) => (w & !0x7f & !HIGH_REG_BITS) | m,
            None => w,
        })
        .collect()
}

/// A committed firmware set up as `sim-core run-elf` runs it: the FC with
/// the cluster beside it (8 cores at 175 MHz), one console for both, at
/// most `limit` FC instructions.
pub struct ClusterRun {
    pub cpu: Cpu,
    pub mem: Memory,
    pub code: CodeCache,
    pub cluster: sim_core::cluster::Cluster,
    pub console: Console,
}

pub fn cluster_run(
    name: &str,
    iss: sim_core::iss::Backend,
    idle_skip: bool,
    limit: u64,
) -> ClusterRun {
    use sim_core::cluster::{Cluster, ClusterConfig};
    let bytes = std::fs::read(firmware(name)).unwrap();
    let elf = load_elf(&bytes).unwrap();
    let mut mem = build_memory(&[], elf.lowest_address()).unwrap();
    elf.load_into(&mut mem).unwrap();
    let mut cluster = Cluster::new(
        ClusterConfig {
            clock: sim_core::units::Hertz(175_000_000),
            iss,
            idle_skip,
            ..ClusterConfig::default()
        },
        &mut mem,
    )
    .unwrap();
    let console = Console::default();
    let c2 = console.clone();
    cluster.set_console(move || Box::new(c2.clone()));
    let mut cpu = Cpu::new(Cluster::fc_config(CpuConfig {
        iss,
        idle_skip,
        ..CpuConfig::default()
    }));
    Cluster::attach_fc(&mut cpu);
    cpu.set_console(Box::new(console.clone()));
    cpu.set_pc(elf.entry);
    cpu.set_tohost(elf.symbol("tohost"));
    cpu.set_instruction_limit(Some(limit));
    ClusterRun {
        cpu,
        mem,
        code: CodeCache::new(),
        cluster,
        console,
    }
}
