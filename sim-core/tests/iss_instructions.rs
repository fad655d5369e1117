//! Instruction-level tests: every RV32IM instruction's result and cycle
//! cost (CV32E40P table, DESIGN.md §4), and every trap and interrupt the
//! core takes. Instructions are encoded here by an encoder written from the
//! ISA manual's formats, independent of the ISS's decoder.

mod iss_util;

use iss_util::encode::{b, csr, i, jal, r, s};

use sim_core::iss::CodeCache;
use sim_core::iss::{
    cause, Cpu, CpuConfig, IssError, Memory, NoDevices, Privilege, StopReason, Stuck,
};
use sim_core::units::Picos;

const BASE: u32 = 0x8000_0000;
const HANDLER: u32 = BASE + 0x800;

const ECALL: u32 = 0x0000_0073;
const EBREAK: u32 = 0x0010_0073;
const MRET: u32 = 0x3020_0073;
const WFI: u32 = 0x1050_0073;
const NOP: u32 = 0x0000_0013;
const SPIN: u32 = 0x0000_006f; // jal x0, 0

/// A core at BASE with `prog` there, a spinning handler at HANDLER
/// (mtvec), 64 KiB of RAM. The handler's spin, with interrupts off after
/// the trap, can never progress: a run that reaches it ends there.
fn setup(prog: &[u32]) -> (Cpu, Memory) {
    let mut mem = Memory::new();
    mem.add_ram(BASE, 0x1_0000).unwrap();
    for (k, w) in prog.iter().enumerate() {
        mem.write_bytes(BASE + 4 * k as u32, &w.to_le_bytes())
            .unwrap();
    }
    mem.write_bytes(HANDLER, &SPIN.to_le_bytes()).unwrap();
    let mut cpu = Cpu::new(CpuConfig::default());
    cpu.set_pc(BASE);
    (cpu, mem)
}

/// Retire `n` more instructions, or fewer if a trap parks the core in the
/// handler's spin.
fn step(cpu: &mut Cpu, mem: &mut Memory, n: u64) {
    cpu.set_instruction_limit(Some(cpu.instret() + n));
    // A fresh code cache each time: it decodes again what it needs.
    let r = cpu.run_until(mem, &mut CodeCache::new(), &mut NoDevices, Picos::MAX);
    if r != parked(HANDLER) {
        assert_eq!(r, StopReason::InstructionLimit);
    }
}

/// The stop of a core that spins at `pc` with interrupts off.
fn parked(pc: u32) -> StopReason {
    StopReason::Fatal(IssError::NeverProgress {
        hart: 0,
        pc,
        why: Stuck::SpinsInterruptsOff,
    })
}

/// Run `prog` after an mtvec setup; returns the core after `n` instructions
/// of `prog` (the setup's own two are not counted in `cycles`).
fn exec(prog: &[u32], regs: &[(usize, u32)], n: u64) -> (Cpu, Memory, u64) {
    // A nop (never run) keeps the program at BASE + 8, then csrw mtvec, x31.
    let mut full = vec![NOP, csr(1, 0, 31, 0x305)];
    full.extend_from_slice(prog);
    let (mut cpu, mut mem) = setup(&full);
    cpu.set_pc(BASE + 4);
    cpu.set_reg(31, HANDLER);
    step(&mut cpu, &mut mem, 1);
    for &(k, v) in regs {
        cpu.set_reg(k, v);
    }
    let c0 = cpu.cycles().0;
    step(&mut cpu, &mut mem, n);
    let cycles = cpu.cycles().0 - c0;
    (cpu, mem, cycles)
}

#[test]
fn register_register_results_and_cycles() {
    // (name, f7, f3, a, b, result, cycles)
    let cases: &[(&str, u32, u32, u32, u32, u32, u64)] = &[
        ("add", 0, 0, 0x7fff_ffff, 1, 0x8000_0000, 1),
        ("sub", 0x20, 0, 0, 1, 0xffff_ffff, 1),
        ("sll", 0, 1, 1, 35, 8, 1),
        ("slt", 0, 2, 0xffff_ffff, 0, 1, 1),
        ("sltu", 0, 3, 0xffff_ffff, 0, 0, 1),
        ("xor", 0, 4, 0xff00_ff00, 0x0ff0_0ff0, 0xf0f0_f0f0, 1),
        ("srl", 0, 5, 0x8000_0000, 4, 0x0800_0000, 1),
        ("sra", 0x20, 5, 0x8000_0000, 4, 0xf800_0000, 1),
        ("or", 0, 6, 0xff00_0000, 0x00ff, 0xff00_00ff, 1),
        ("and", 0, 7, 0xff00_ff00, 0x0ff0_0ff0, 0x0f00_0f00, 1),
        ("mul", 1, 0, 0xffff_ffff, 0xffff_ffff, 1, 1),
        ("mulh", 1, 1, 0xffff_ffff, 0xffff_ffff, 0, 5),
        ("mulhsu", 1, 2, 0xffff_ffff, 0xffff_ffff, 0xffff_ffff, 5),
        ("mulhu", 1, 3, 0xffff_ffff, 0xffff_ffff, 0xffff_fffe, 5),
        // Division: 3 + leading zeros of the divisor (|b| when signed).
        ("div", 1, 4, 100, 7, 14, 3 + 29),
        ("div -", 1, 4, (-100i32) as u32, 7, (-14i32) as u32, 3 + 29),
        (
            "div by -7",
            1,
            4,
            100,
            (-7i32) as u32,
            (-14i32) as u32,
            3 + 29,
        ),
        ("divu", 1, 5, 100, 0x8000_0000, 0, 3),
        ("rem", 1, 6, (-100i32) as u32, 7, (-2i32) as u32, 3 + 29),
        ("remu", 1, 7, 100, 7, 2, 3 + 29),
        ("div by 0", 1, 4, 5, 0, 0xffff_ffff, 35),
        ("rem by 0", 1, 6, 5, 0, 5, 35),
        (
            "div overflow",
            1,
            4,
            0x8000_0000,
            0xffff_ffff,
            0x8000_0000,
            3 + 31,
        ),
        ("rem overflow", 1, 6, 0x8000_0000, 0xffff_ffff, 0, 3 + 31),
    ];
    for &(name, f7, f3, a, bv, want, cycles) in cases {
        let (cpu, _, c) = exec(&[r(f7, 12, 11, f3, 10, 0x33)], &[(11, a), (12, bv)], 1);
        assert_eq!(cpu.reg(10), want, "{name}");
        assert_eq!(c, cycles, "{name} cycles");
    }
}

#[test]
fn register_immediate_results() {
    // (name, f3, imm (with funct7 bits for shifts), a, result)
    let cases: &[(&str, u32, i32, u32, u32)] = &[
        ("addi", 0, -1, 1, 0),
        ("slti", 2, 0, 0xffff_ffff, 1),
        ("sltiu", 3, -1, 5, 1),
        ("xori", 4, -1, 0x0f0f_0f0f, 0xf0f0_f0f0),
        ("ori", 6, 0x0f0, 0x0f00, 0x0ff0),
        ("andi", 7, 0x0f0, 0x0ff0, 0x00f0),
        ("slli", 1, 31, 1, 0x8000_0000),
        ("srli", 5, 31, 0x8000_0000, 1),
        ("srai", 5, 0x400 | 31, 0x8000_0000, 0xffff_ffff),
    ];
    for &(name, f3, imm, a, want) in cases {
        let (cpu, _, c) = exec(&[i(imm, 11, f3, 10, 0x13)], &[(11, a)], 1);
        assert_eq!(cpu.reg(10), want, "{name}");
        assert_eq!(c, 1, "{name} cycles");
    }
    // x0 stays zero.
    let (cpu, _, _) = exec(&[i(5, 0, 0, 0, 0x13)], &[], 1);
    assert_eq!(cpu.reg(0), 0);
}

#[test]
fn upper_immediates_and_jumps() {
    let (cpu, _, c) = exec(&[0xabcd_e537], &[], 1); // lui a0, 0xabcde
    assert_eq!((cpu.reg(10), c), (0xabcd_e000, 1));
    let (cpu, _, _) = exec(&[0x0000_1517], &[], 1); // auipc a0, 1 at BASE+8
    assert_eq!(cpu.reg(10), BASE + 8 + 0x1000);
    let (cpu, _, c) = exec(&[jal(12, 1)], &[], 1);
    assert_eq!((cpu.pc(), cpu.reg(1), c), (BASE + 8 + 12, BASE + 12, 2));
    // jalr clears bit 0 of the target.
    let (cpu, _, c) = exec(&[i(3, 11, 0, 1, 0x67)], &[(11, BASE + 0x100)], 1);
    assert_eq!((cpu.pc(), cpu.reg(1), c), (BASE + 0x102, BASE + 12, 2));
}

#[test]
fn branches_taken_cost_3_not_taken_1() {
    // (f3, a, b, taken)
    let cases = [
        (0, 1, 1, true),
        (0, 1, 2, false),
        (1, 1, 2, true),
        (4, 0xffff_ffff, 0, true),
        (5, 0xffff_ffff, 0, false),
        (6, 0xffff_ffff, 0, false),
        (7, 0xffff_ffff, 0, true),
    ];
    for (f3, a, bv, taken) in cases {
        let (cpu, _, c) = exec(&[b(-8, 12, 11, f3)], &[(11, a), (12, bv)], 1);
        let want_pc = if taken { BASE + 8 - 8 } else { BASE + 12 };
        assert_eq!(cpu.pc(), want_pc, "f3 {f3}");
        assert_eq!(c, if taken { 3 } else { 1 }, "f3 {f3}");
    }
}

#[test]
fn loads_stores_misalignment_and_load_use_stall() {
    let data = BASE + 0x1000;
    let prog = [
        s(0, 12, 11, 2),           // sw a2, 0(a1)
        i(0, 11, 0, 10, 0x03),     // lb a0, 0(a1)
        i(1, 11, 4, 13, 0x03),     // lbu a3, 1(a1)
        i(2, 11, 1, 14, 0x03),     // lh a4, 2(a1)
        i(2, 11, 5, 15, 0x03),     // lhu a5, 2(a1)
        i(3, 11, 2, 16, 0x03),     // lw a6, 3(a1): crosses a word, +1
        r(0, 16, 16, 0, 17, 0x33), // add a7, a6, a6: load-use stall, +1
    ];
    let (cpu, mem, c) = exec(&prog, &[(11, data), (12, 0x8081_7f80)], 7);
    assert_eq!(cpu.reg(10), 0xffff_ff80);
    assert_eq!(cpu.reg(13), 0x7f);
    assert_eq!(cpu.reg(14), 0xffff_8081);
    assert_eq!(cpu.reg(15), 0x8081);
    assert_eq!(cpu.reg(16), 0x0000_0080, "bytes 3..7: 0x80 then zeros");
    assert_eq!(cpu.reg(17), 0x100);
    assert_eq!(mem.read_u32(data), Some(0x8081_7f80));
    assert_eq!(c, 7 + 1 + 1);
    // Misaligned stores and halfwords within a word: no extra cycle for sh
    // at offset 1, one for sw at offset 2.
    let prog = [s(1, 12, 11, 1), s(2, 12, 11, 2)];
    let (_, mem, c) = exec(&prog, &[(11, data), (12, 0xaabb_ccdd)], 2);
    assert_eq!(mem.read_u32(data), Some(0xccdd_dd00));
    assert_eq!(mem.read_u32(data + 4), Some(0x0000_aabb));
    assert_eq!(c, 1 + 2);
}

fn trap_state(cpu: &Cpu) -> (u32, u32, u32, u32) {
    (
        cpu.pc(),
        cpu.csr(0x342).unwrap(),
        cpu.csr(0x341).unwrap(),
        cpu.csr(0x343).unwrap(),
    )
}

#[test]
fn exceptions_set_mcause_mepc_mtval() {
    let at = BASE + 8; // the first instruction after the mtvec setup
    let (cpu, _, _) = exec(&[0xffff_ffff], &[], 1);
    assert_eq!(
        trap_state(&cpu),
        (HANDLER, cause::ILLEGAL_INSTRUCTION, at, 0xffff_ffff)
    );
    let (cpu, _, _) = exec(&[ECALL], &[], 1);
    assert_eq!(trap_state(&cpu), (HANDLER, cause::ECALL_M, at, 0));
    let (cpu, _, _) = exec(&[EBREAK], &[], 1);
    assert_eq!(trap_state(&cpu), (HANDLER, cause::BREAKPOINT, at, at));
    let (cpu, _, _) = exec(&[i(4, 11, 2, 10, 0x03)], &[(11, 0x10)], 1);
    assert_eq!(trap_state(&cpu), (HANDLER, cause::LOAD_ACCESS, at, 0x14));
    let (cpu, _, _) = exec(&[s(-4, 12, 11, 2)], &[(11, 0x10)], 1);
    assert_eq!(trap_state(&cpu), (HANDLER, cause::STORE_ACCESS, at, 0xc));
    // Jump to unmapped memory: instruction access fault at the target.
    let (cpu, _, _) = exec(&[i(0, 11, 0, 0, 0x67)], &[(11, 0x4000_0000)], 2);
    assert_eq!(
        trap_state(&cpu),
        (HANDLER, cause::FETCH_ACCESS, 0x4000_0000, 0x4000_0000)
    );
    // A trap saves MIE in MPIE, clears MIE, saves the privilege in MPP.
    let (cpu, _, _) = exec(&[csr(6, 0, 8, 0x300), ECALL], &[], 2); // csrrsi mstatus, 8
    let mstatus = cpu.csr(0x300).unwrap();
    assert_eq!(mstatus & (1 << 3), 0);
    assert_ne!(mstatus & (1 << 7), 0);
    assert_eq!(mstatus >> 11 & 3, 3);
}

#[test]
fn user_mode_privilege_checks_and_mret() {
    // mret with MPP = U (reset value 0) drops to user mode at mepc.
    let user = BASE + 0x100;
    let prog = [csr(1, 0, 11, 0x341), MRET]; // csrw mepc, a1; mret
    let (mut cpu, mut mem, c) = exec(&prog, &[(11, user)], 2);
    assert_eq!((cpu.pc(), cpu.privilege()), (user, Privilege::User));
    // csrw mepc is a 4-cycle CSR, mret a 2-cycle jump.
    assert_eq!(c, 4 + 2);
    // In U: reading a machine CSR, mret and wfi are illegal; ecall is cause 8.
    for (inst, want) in [
        (csr(2, 10, 0, 0x300), cause::ILLEGAL_INSTRUCTION),
        (MRET, cause::ILLEGAL_INSTRUCTION),
        (WFI, cause::ILLEGAL_INSTRUCTION),
        (csr(2, 10, 0, 0xc00), cause::ILLEGAL_INSTRUCTION), // cycle, mcounteren = 0
        (ECALL, cause::ECALL_U),
    ] {
        mem.write_bytes(user, &inst.to_le_bytes()).unwrap();
        cpu.set_pc(user);
        // Back to user mode the way firmware would: mret with MPP = U.
        let (mut c2, mut m2) = (cpu, mem);
        step(&mut c2, &mut m2, 1);
        assert_eq!(c2.csr(0x342), Some(want), "{inst:#x}");
        assert_eq!(c2.privilege(), Privilege::Machine);
        assert_eq!(c2.csr(0x300).unwrap() >> 11 & 3, 0, "MPP = U");
        // Re-enter user mode for the next case.
        let (c3, m3, _) = exec(&prog, &[(11, user)], 2);
        cpu = c3;
        mem = m3;
    }
}

#[test]
fn csr_rules() {
    // misa is read-only WARL: writes ignored; mhartid is read-only: illegal.
    let (cpu, _, _) = exec(&[csr(1, 0, 11, 0x301), csr(2, 10, 0, 0x301)], &[(11, 0)], 2);
    assert_eq!(cpu.reg(10), 0x4010_1104);
    let (cpu, _, _) = exec(&[csr(1, 0, 11, 0xf14)], &[(11, 1)], 1);
    assert_eq!(cpu.csr(0x342), Some(cause::ILLEGAL_INSTRUCTION));
    // Unimplemented CSRs are illegal (here: satp).
    let (cpu, _, _) = exec(&[csr(2, 10, 0, 0x180)], &[], 1);
    assert_eq!(cpu.csr(0x342), Some(cause::ILLEGAL_INSTRUCTION));
    // MPP only takes U or M.
    let (cpu, _, _) = exec(&[csr(1, 0, 11, 0x300)], &[(11, 1 << 11)], 1);
    assert_eq!(cpu.csr(0x300).unwrap() >> 11 & 3, 0);
    // minstret written to N reads N + 1 one instruction later.
    let prog = [csr(1, 0, 11, 0xb02), csr(2, 10, 0, 0xb02)];
    let (cpu, _, _) = exec(&prog, &[(11, 1000)], 2);
    assert_eq!(cpu.reg(10), 1000);
}

#[test]
fn timer_and_external_interrupts() {
    // mtimecmp = 100 cycles ahead; enable MTIE and MIE; spin.
    let prog = [
        s(0, 12, 11, 2),      // sw a2, 0(a1)  (mtimecmp lo)
        s(4, 0, 11, 2),       // sw x0, 4(a1)  (mtimecmp hi)
        csr(1, 0, 13, 0x304), // csrw mie, a3
        csr(6, 0, 8, 0x300),  // csrsi mstatus, MIE
        SPIN,
    ];
    let (mut cpu, mut mem, _) = exec(&prog, &[(11, 0x0200_4000), (12, 500), (13, 1 << 7)], 4);
    let mut code = CodeCache::new();
    assert_eq!(cpu.pc(), BASE + 24);
    cpu.set_instruction_limit(None);
    let r = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::from_us(10));
    assert_eq!(r, parked(HANDLER));
    assert!(cpu.cycles().0 >= 500, "the spin waited for the timer");
    assert_eq!(cpu.csr(0x342), Some(cause::INTERRUPT | 7));
    assert_eq!(cpu.csr(0x341), Some(BASE + 24));
    assert_eq!(cpu.pc(), HANDLER);

    // External interrupt: vectored mtvec sends it to base + 4 * 11.
    let vec_base = BASE + 0x400;
    let (mut cpu, mut mem, _) = exec(
        &[
            csr(1, 0, 11, 0x305),
            csr(1, 0, 12, 0x304),
            csr(6, 0, 8, 0x300),
            SPIN,
        ],
        &[(11, vec_base | 1), (12, 1 << 11)],
        3,
    );
    let mut code = CodeCache::new();
    mem.write_bytes(vec_base + 44, &SPIN.to_le_bytes()).unwrap();
    cpu.set_external_irq(true);
    cpu.set_instruction_limit(None);
    assert_eq!(
        cpu.run_until(
            &mut mem,
            &mut code,
            &mut NoDevices,
            cpu.now() + Picos::from_us(1)
        ),
        parked(vec_base + 44)
    );
    assert_eq!(cpu.csr(0x342), Some(cause::INTERRUPT | 11));
    assert_eq!(cpu.pc(), vec_base + 44);
}

#[test]
fn wfi_sleeps_until_the_timer_and_mcycle_skips_sleep() {
    let prog = [
        s(0, 12, 11, 2),      // mtimecmp lo = 1000
        s(4, 0, 11, 2),       // mtimecmp hi = 0
        csr(1, 0, 13, 0x304), // mie = MTIE (MIE stays off: no trap)
        WFI,
        csr(2, 10, 0, 0xb00), // csrr a0, mcycle
    ];
    let (cpu, _, _) = exec(&prog, &[(11, 0x0200_4000), (12, 1000), (13, 1 << 7)], 5);
    assert!(cpu.cycles().0 >= 1000, "woke at the timer");
    let s = cpu.stats();
    assert!(s.sleep_cycles > 900);
    // mcycle counts awake cycles only. The csrr (the last instruction run,
    // a 4-cycle CSR) reads it in its first cycle.
    assert_eq!(cpu.reg(10) as u64, cpu.cycles().0 - s.sleep_cycles - 3);

    // An interrupt enabled that nothing raises: Idle.
    let (mut cpu, mut mem, _) = exec(&[csr(1, 0, 13, 0x304), WFI], &[(13, 1 << 11)], 1);
    let mut code = CodeCache::new();
    cpu.set_instruction_limit(None);
    assert_eq!(
        cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX),
        StopReason::Idle
    );
}

#[test]
fn a_core_can_move_to_another_memory() {
    // The core caches where its code lives; a different Memory (here one
    // with no RAM at all) must give a clean error, not an index panic.
    let (mut cpu, _, _) = exec(&[NOP, NOP], &[], 2);
    cpu.set_instruction_limit(None);
    let mut other = Memory::new();
    let mut code = CodeCache::new();
    let r = cpu.run_until(&mut other, &mut code, &mut NoDevices, Picos::MAX);
    assert!(
        matches!(&r, StopReason::Fatal(e) if e.to_string().contains("fetch")),
        "{r:?}"
    );
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]
    /// Random code (with random register values and an MMIO window that
    /// faults) never panics the core, whatever it does: every outcome is a
    /// StopReason.
    #[test]
    fn random_code_never_panics(
        raw in proptest::collection::vec(proptest::prelude::any::<u32>(), 64),
        opcodes in proptest::collection::vec(0usize..16, 64),
        regs in proptest::collection::vec(proptest::prelude::any::<u32>(), 31),
    ) {
        // Mostly well-formed instructions: random fields under a real major
        // opcode (OP-IMM, OP, LOAD, STORE, BRANCH, LUI, AUIPC, JAL, JALR,
        // SYSTEM, MISC-MEM, the four CORE-V XCV custom opcodes), or a
        // random 16-bit pair.
        const MAJOR: [u32; 15] = [
            0x13, 0x33, 0x03, 0x23, 0x63, 0x37, 0x17, 0x6f, 0x67, 0x73, 0x0f, 0x0b, 0x2b, 0x5b, 0x7b,
        ];
        let words: Vec<u32> = raw
            .iter()
            .zip(&opcodes)
            .map(|(&w, &k)| MAJOR.get(k).map_or(w, |&m| (w & !0x7f) | m))
            .collect();
        // csrw mtvec, x31 first; traps go back to the start of the random
        // code (which may of course rewrite mtvec or itself).
        let mut prog = vec![csr(1, 0, 31, 0x305)];
        prog.extend_from_slice(&words);
        let (mut cpu, mut mem) = setup(&prog);
        let mut code = CodeCache::new();
        mem.add_mmio_window(0x2000_0000, 0x1000).unwrap();
        for (k, v) in regs.iter().enumerate() {
            cpu.set_reg(k + 1, *v);
        }
        cpu.set_reg(31, HANDLER);
        let back = jal((BASE + 4) as i32 - HANDLER as i32, 0);
        mem.write_bytes(HANDLER, &back.to_le_bytes()).unwrap();
        cpu.set_instruction_limit(Some(5_000));
        let r = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::from_ms(1));
        proptest::prop_assert!(cpu.instret() > 0, "{:?}", r);
    }
}

#[test]
fn a_store_into_the_running_block_is_seen_by_the_next_instruction() {
    // sw x5, 0(x10) overwrites the instruction two places ahead, which the
    // core already decoded as part of the same block.
    let new = i(42, 0, 0, 6, 0x13); // addi x6, x0, 42
    let prog = [
        s(0, 5, 10, 2),
        i(7, 0, 0, 7, 0x13),
        i(1, 0, 0, 6, 0x13),
        NOP,
    ];
    let target = BASE + 8 + 8;
    let (cpu, mem, _) = exec(&prog, &[(5, new), (10, target)], 3);
    assert_eq!(mem.read_u32(target), Some(new));
    assert_eq!((cpu.reg(6), cpu.reg(7)), (42, 7));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
    /// The block loop (blocks chained, stalls folded in, x0 writes dropped)
    /// ends in exactly the state of a run that stops after every single
    /// instruction: registers, pc, cycles, instructions, trap CSRs and
    /// memory, for random code that may loop, trap and rewrite itself.
    #[test]
    fn blocks_and_single_steps_agree(
        raw in proptest::collection::vec(proptest::prelude::any::<u32>(), 48),
        opcodes in proptest::collection::vec(0usize..16, 48),
        regs in proptest::collection::vec(0u32..0x200, 30),
    ) {
        // Real major opcodes with random fields, registers x0..x7 only (so
        // results are often used by the next instruction: load-use stalls),
        // registers holding BASE + a small value and loads and stores with
        // small positive offsets, so most accesses hit the program's own
        // 4 KiB and some rewrite code. The four custom opcodes are the
        // CORE-V XCV instructions (post-increment loads and stores move
        // their base by small amounts; dot products, MACs, SIMD).
        let words = iss_util::random_code(&raw, &opcodes);
        let run = |stepwise: bool| {
            let mut prog = vec![csr(1, 0, 31, 0x305)];
            prog.extend_from_slice(&words);
            let (mut cpu, mut mem) = setup(&prog);
            let mut code = CodeCache::new();
            for (k, v) in regs.iter().enumerate() {
                cpu.set_reg(k + 1, BASE + v);
            }
            cpu.set_reg(31, BASE);
            const N: u64 = 3_000;
            let mut stop = StopReason::Limit;
            if stepwise {
                while cpu.instret() < N {
                    cpu.set_instruction_limit(Some(cpu.instret() + 1));
                    stop = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::from_ms(1));
                    if stop != StopReason::InstructionLimit {
                        break;
                    }
                }
            } else {
                cpu.set_instruction_limit(Some(N));
                stop = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::from_ms(1));
            }
            let mut ram = vec![0u8; 0x1000];
            mem.read_bytes(BASE, &mut ram).unwrap();
            let csrs = [0x300u16, 0x341, 0x342, 0x343].map(|c| cpu.csr(c));
            (stop, *cpu.regs(), cpu.pc(), cpu.cycles(), cpu.instret(), csrs, ram)
        };
        let (blocks, steps) = (run(false), run(true));
        proptest::prop_assert_eq!(blocks, steps);
    }
}
