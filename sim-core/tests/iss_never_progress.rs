//! A core that can never progress ends the run with one clear error naming
//! the hart and the pc (DESIGN.md §19), instead of spinning silently: a
//! branch or jump to itself with no interrupt that could end it, and `wfi`
//! with no interrupt enabled. A self-loop an interrupt will end is left
//! alone, under both back ends.

mod iss_util;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use iss_util::encode::{csr, i, jal, s};
use sim_core::iss::CodeCache;
use sim_core::iss::{
    cause, load_elf, Backend, Cpu, CpuConfig, IssError, Memory, NoDevices, StopReason, Stuck,
};
use sim_core::units::Picos;

/// An official riscv-test: its start-up parks every hart but hart 0 in a
/// branch to itself with interrupts off.
fn riscv_test(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/compliance/riscv-tests")
        .join(format!("{name}.elf"))
}

/// Whether the instruction at `pc` of the ELF is a conditional branch to
/// itself (`bxx` or `c.beqz`/`c.bnez` with offset 0).
fn branch_to_itself(elf: &Path, pc: u32) -> bool {
    let bytes = std::fs::read(elf).unwrap();
    let elf = load_elf(&bytes).unwrap();
    let mut mem = Memory::new();
    mem.add_ram(elf.lowest_address().unwrap() & !0xffff, 16 << 20)
        .unwrap();
    elf.load_into(&mut mem).unwrap();
    let w = mem.read_u32(pc).expect("pc in the program");
    let h = w as u16;
    (w & 0x7f == 0x63 && w & 0xfe00_0f80 == 0) || (h & 0xc003 == 0xc001 && h & 0x1c7c == 0)
}

#[test]
fn a_hart_0_test_beside_the_cluster_ends_with_one_line_naming_hart_and_pc() {
    let elf = riscv_test("rv32ui-p-add");
    for iss in ["interp", "jit"] {
        let t0 = Instant::now();
        // The instruction limit only bounds a regression (exit 124).
        let out = Command::new(env!("CARGO_BIN_EXE_sim-core"))
            .args(["run-elf", "--iss", iss, "--max-instructions", "200000000"])
            .arg(&elf)
            .output()
            .expect("run sim-core");
        let took = t0.elapsed();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{iss}: {err}");
        assert!(took < Duration::from_secs(10), "{iss}: took {took:?}");
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 1, "{iss}: one line: {err}");
        let line = lines[0];
        // The FC is hart 0x400 beside the cluster.
        assert!(line.contains("hart 0x400 (FC) at 0x"), "{iss}: {line}");
        assert!(line.contains("interrupts off"), "{iss}: {line}");
        assert!(line.contains("can never progress"), "{iss}: {line}");
        assert!(line.contains("--no-cluster"), "{iss}: {line}");
        let pc = line.split("at 0x").nth(1).unwrap();
        let pc = u32::from_str_radix(&pc[..8], 16).unwrap();
        assert!(branch_to_itself(&elf, pc), "{iss}: {pc:#x} is not the loop");
    }
    // With --no-cluster the FC is hart 0 and the test passes.
    let out = Command::new(env!("CARGO_BIN_EXE_sim-core"))
        .args(["run-elf", "--no-cluster"])
        .arg(&elf)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
}

const BASE: u32 = 0x8000_0000;
const HANDLER: u32 = BASE + 0x800;
const CLINT_MTIMECMP: u32 = 0x0200_4000;
const WFI: u32 = 0x1050_0073;
const SPIN: u32 = 0x0000_006f; // jal x0, 0

fn core(prog: &[u32], iss: Backend) -> (Cpu, Memory) {
    let mut mem = Memory::new();
    mem.add_ram(BASE, 0x1_0000).unwrap();
    for (k, w) in prog.iter().enumerate() {
        mem.write_bytes(BASE + 4 * k as u32, &w.to_le_bytes())
            .unwrap();
    }
    // The trap handler spins too, with interrupts off (a trap clears MIE).
    mem.write_bytes(HANDLER, &SPIN.to_le_bytes()).unwrap();
    let mut cpu = Cpu::new(CpuConfig {
        hart_id: 5,
        iss,
        ..CpuConfig::default()
    });
    cpu.set_pc(BASE);
    (cpu, mem)
}

fn backends() -> Vec<Backend> {
    if cfg!(target_arch = "x86_64") {
        vec![Backend::Interp, Backend::Jit]
    } else {
        vec![Backend::Interp]
    }
}

#[test]
fn a_self_loop_the_timer_will_end_runs_until_the_timer_fires() {
    // mtvec = HANDLER, mtimecmp = 5000, mie = MTIE, mstatus.MIE, then
    // spin: the spin lasts until the timer interrupt, then the handler's
    // own spin (interrupts off) can never progress.
    let prog = [
        csr(1, 0, 20, 0x305), // csrw mtvec, x20
        s(0, 21, 22, 2),      // sw x21, 0(x22): mtimecmp lo
        s(4, 0, 22, 2),       // sw x0, 4(x22): mtimecmp hi
        csr(1, 0, 23, 0x304), // csrw mie, x23
        csr(2, 0, 24, 0x300), // csrs mstatus, x24
        jal(0, 0),            // j .
    ];
    for iss in backends() {
        let (mut cpu, mut mem) = core(&prog, iss);
        let mut code = CodeCache::new();
        cpu.set_reg(20, HANDLER);
        cpu.set_reg(21, 5000);
        cpu.set_reg(22, CLINT_MTIMECMP);
        cpu.set_reg(23, 1 << 7);
        cpu.set_reg(24, 1 << 3);
        let r = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
        assert_eq!(
            r,
            StopReason::Fatal(IssError::NeverProgress {
                hart: 5,
                pc: HANDLER,
                why: Stuck::SpinsInterruptsOff
            }),
            "{iss:?}"
        );
        assert!(cpu.cycles().0 >= 5000, "{iss:?}: spun until the timer");
        assert_eq!(cpu.csr(0x342), Some(cause::INTERRUPT | 7), "{iss:?}");
        assert_eq!(cpu.csr(0x341), Some(BASE + 20), "{iss:?}: mepc = the j .");
        assert_eq!(cpu.pc(), HANDLER);
    }
}

#[test]
fn a_self_loop_with_interrupts_on_but_none_enabled_never_progresses() {
    // mstatus.MIE set, mie 0: no interrupt can be taken.
    let prog = [csr(2, 0, 24, 0x300), jal(0, 0)];
    for iss in backends() {
        let (mut cpu, mut mem) = core(&prog, iss);
        let mut code = CodeCache::new();
        cpu.set_reg(24, 1 << 3);
        let r = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
        assert_eq!(
            r,
            StopReason::Fatal(IssError::NeverProgress {
                hart: 5,
                pc: BASE + 4,
                why: Stuck::SpinsNoInterrupt
            }),
            "{iss:?}"
        );
        let msg = match r {
            StopReason::Fatal(e) => e.to_string(),
            _ => unreachable!(),
        };
        assert_eq!(
            msg,
            "hart 0x5 at 0x80000004 spins on itself with no interrupt enabled that could fire: \
             it can never progress"
        );
    }
}

#[test]
fn a_loop_that_is_not_a_self_loop_runs_to_its_end() {
    // A countdown to itself through another instruction: it ends.
    // addi x5, x5, -1; bnez x5, -4; then spin with interrupts off.
    let bnez_back = iss_util::encode::b(-4, 0, 5, 1);
    let prog = [i(-1, 5, 0, 5, 0x13), bnez_back, SPIN];
    for iss in backends() {
        let (mut cpu, mut mem) = core(&prog, iss);
        let mut code = CodeCache::new();
        cpu.set_reg(5, 1000);
        let r = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
        assert!(
            matches!(r, StopReason::Fatal(IssError::NeverProgress { pc, .. }) if pc == BASE + 8),
            "{iss:?}: {r:?}"
        );
        assert_eq!(cpu.reg(5), 0, "{iss:?}: the countdown ran to its end");
        assert!(cpu.instret() >= 2000, "{iss:?}: the countdown ran");
    }
}

#[test]
fn wfi_with_no_interrupt_enabled_never_progresses() {
    for iss in backends() {
        let (mut cpu, mut mem) = core(&[WFI], iss);
        let mut code = CodeCache::new();
        let r = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::from_ms(1));
        assert_eq!(
            r,
            StopReason::Fatal(IssError::NeverProgress {
                hart: 5,
                pc: BASE,
                why: Stuck::Asleep
            }),
            "{iss:?}"
        );
    }
}
