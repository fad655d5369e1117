//! The CORE-V XCV instructions on the ISS (DESIGN.md §12, docs/CLUSTER.md
//! "Instructions"): one clang-19 assembly test per group against the
//! manual's closed forms, a clang -O2 C program whose post-increment loads
//! the compiler chose itself, cycle costs and load-use stalls of
//! hand-encoded sequences, and reserved encodings trapping.

mod iss_util;

use iss_util::{firmware, run_firmware};
use sim_core::iss::decode::{decode, op};
use sim_core::iss::CodeCache;
use sim_core::iss::{cause, load_elf, Cpu, CpuConfig, Memory, NoDevices, StopReason};
use sim_core::units::Picos;

#[test]
fn every_xcv_group_passes_its_assembly_test() {
    // (ELF, tests in it): each test number is one checked instruction.
    for (name, min_instret) in [
        ("xcv_alu", 200),
        ("xcv_bitmanip", 120),
        ("xcv_mac", 100),
        ("xcv_mem", 100),
        ("xcv_simd", 350),
        ("xcv_bi", 20),
    ] {
        let (code, _, cpu) = run_firmware(name);
        assert_eq!(code, 0, "{name}: test {code} failed");
        assert!(cpu.instret() >= min_instret, "{name}: {}", cpu.instret());
    }
}

/// The kernels' inputs: the C program's LCG (`xcv_kernels.c`).
struct Lcg(u32);
impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        self.0 >> 8
    }
}

#[test]
fn clang_o2_kernels_use_post_increment_loads_and_compute_what_rust_does() {
    // The compiler emitted the XCV forms on its own: count them in .text.
    let bytes = std::fs::read(firmware("xcv_kernels")).unwrap();
    let elf = load_elf(&bytes).unwrap();
    let mut ops = Vec::new();
    for seg in &elf.segments {
        let mut at = 0;
        while at + 2 <= seg.data.len() {
            let lo = u16::from_le_bytes([seg.data[at], seg.data[at + 1]]);
            let hi = seg
                .data
                .get(at + 2..at + 4)
                .map(|b| u16::from_le_bytes([b[0], b[1]]));
            let Some(d) = decode(lo, || hi) else { break };
            ops.push(d.op);
            at += d.len() as usize;
        }
    }
    let count = |o: u8| ops.iter().filter(|&&x| x == o).count();
    assert!(count(op::CV_LB_PI) >= 2, "cv.lb post-increment");
    assert!(count(op::CV_LH_PI) >= 2, "cv.lh post-increment");
    assert!(count(op::CV_LW_PI) >= 3, "cv.lw post-increment");
    assert!(count(op::CV_SW_PI) >= 1, "cv.sw post-increment");
    assert!(count(op::CV_SDOTSP_B) >= 1, "cv.sdotsp.b");

    const N: usize = 256;
    let mut r = Lcg(12345);
    let (mut a8, mut b8, mut a16, mut b16) =
        (vec![0i8; N], vec![0i8; N], vec![0i16; N], vec![0i16; N]);
    let (mut a32, mut b32, mut y32) = (vec![0i32; N], vec![0i32; N], vec![0i32; N]);
    for i in 0..N {
        a8[i] = r.next() as i8;
        b8[i] = r.next() as i8;
        a16[i] = r.next() as i16;
        b16[i] = r.next() as i16;
        a32[i] = (r.next() & 0x3ff) as i32 - 512;
        b32[i] = r.next() as i32;
        y32[i] = r.next() as i32;
    }
    (a8[0], b8[0]) = (-128, -128);
    let dot8: i32 = a8.iter().zip(&b8).map(|(&x, &y)| x as i32 * y as i32).sum();
    let dot16 = a16
        .iter()
        .zip(&b16)
        .fold(0i32, |s, (&x, &y)| s.wrapping_add(x as i32 * y as i32));
    let mut h = 0u32;
    for i in 0..N {
        y32[i] = y32[i].wrapping_add(7i32.wrapping_mul(b32[i]));
        h = h.wrapping_mul(31).wrapping_add(y32[i] as u32);
    }
    let clamp: i32 = a32.iter().map(|&v| v.clamp(-128, 127)).sum();
    let want = format!(
        "dot8 {dot8}\ndot8_simd {dot8}\ndot16 {dot16}\naxpy {h}\nclamp {clamp}\nclip {} -128 99\n",
        (a32[0] * 1000).clamp(-128, 127)
    );
    let (code, out, _) = run_firmware("xcv_kernels");
    assert_eq!((code, out), (0, want));
}

const BASE: u32 = 0x8000_0000;
const DATA: u32 = BASE + 0x1000;

fn r(f7: u32, rs2: u32, rs1: u32, f3: u32, rd: u32, opc: u32) -> u32 {
    f7 << 25 | rs2 << 20 | rs1 << 15 | f3 << 12 | rd << 7 | opc
}
fn i(imm: i32, rs1: u32, f3: u32, rd: u32, opc: u32) -> u32 {
    ((imm as u32) & 0xfff) << 20 | rs1 << 15 | f3 << 12 | rd << 7 | opc
}
/// `cv.beqimm` (f3 6) / `cv.bneimm` (f3 7) rs1, imm5, offset.
fn bimm(f3: u32, rs1: u32, imm5: i32, off: i32) -> u32 {
    let o = off as u32;
    (o >> 12 & 1) << 31
        | (o >> 5 & 0x3f) << 25
        | ((imm5 as u32) & 31) << 20
        | rs1 << 15
        | f3 << 12
        | (o >> 1 & 0xf) << 8
        | (o >> 11 & 1) << 7
        | 0x0b
}
const NOP: u32 = 0x13;
fn addi(rd: u32, rs1: u32, imm: i32) -> u32 {
    i(imm, rs1, 0, rd, 0x13)
}
fn lw(rd: u32, rs1: u32) -> u32 {
    i(0, rs1, 2, rd, 0x03)
}
fn cv_lw_pi(rd: u32, rs1: u32, imm: i32) -> u32 {
    i(imm, rs1, 2, rd, 0x0b)
}
fn cv_mac(rd: u32, rs1: u32, rs2: u32) -> u32 {
    r(0b100_1000, rs2, rs1, 3, rd, 0x2b)
}
fn cv_sw_pr(rs2: u32, rs1: u32, rs3: u32) -> u32 {
    r(0b001_0010, rs2, rs1, 3, rs3, 0x2b)
}
fn cv_sdotsp_b(rd: u32, rs1: u32, rs2: u32) -> u32 {
    r(0b101_0100, rs2, rs1, 1, rd, 0x7b)
}

/// Run `prog` at BASE (x6 = DATA, x8 = 3, the others 0, a word 0x0203_0405
/// at DATA) for `n` instructions; the core, its cycles.
fn run(prog: &[u32], n: u64) -> (Cpu, Memory, u64) {
    let mut mem = Memory::new();
    let mut code = CodeCache::new();
    mem.add_ram(BASE, 0x2000).unwrap();
    for (k, w) in prog.iter().chain(&[0x6f]).enumerate() {
        mem.write_bytes(BASE + 4 * k as u32, &w.to_le_bytes())
            .unwrap();
    }
    mem.write_bytes(DATA, &0x0203_0405u32.to_le_bytes())
        .unwrap();
    let mut cpu = Cpu::new(CpuConfig::default());
    cpu.set_pc(BASE);
    cpu.set_reg(6, DATA);
    cpu.set_reg(8, 3);
    cpu.set_instruction_limit(Some(n));
    let stop = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
    assert_eq!(stop, StopReason::InstructionLimit);
    let cycles = cpu.cycles().0;
    (cpu, mem, cycles)
}

#[test]
fn post_increment_loads_stall_on_the_loaded_register_not_on_the_address() {
    // cv.lw x5, (x6), 4 then a use of the new address: 1 + 1 cycles.
    let (cpu, _, c) = run(&[cv_lw_pi(5, 6, 4), addi(7, 6, 0)], 2);
    assert_eq!((cpu.reg(5), cpu.reg(7), c), (0x0203_0405, DATA + 4, 2));
    // ... then a use of the loaded register: + the load-use stall.
    let (cpu, _, c) = run(&[cv_lw_pi(5, 6, -4), addi(7, 5, 1)], 2);
    assert_eq!((cpu.reg(6), cpu.reg(7), c), (DATA - 4, 0x0203_0406, 3));
    // A misaligned post-increment load costs the extra bus transaction.
    let (_, _, c) = run(&[addi(6, 6, 2), cv_lw_pi(5, 6, 4), NOP], 3);
    assert_eq!(c, 4);
}

#[test]
fn accumulators_and_store_registers_count_as_reads_for_the_load_use_stall() {
    // lw x5 then cv.mac x5 (reads its rd): stalled, 1 + 1 + 1.
    let (cpu, _, c) = run(&[lw(5, 6), cv_mac(5, 8, 8)], 2);
    assert_eq!((cpu.reg(5), c), (0x0203_0405 + 9, 3));
    // Not stalled when the loaded register is not read.
    let (_, _, c) = run(&[lw(9, 6), cv_mac(5, 8, 8)], 2);
    assert_eq!(c, 2);
    // cv.sw x0, (x6), x9 reads rs3 = x9 (in the rd field).
    let (cpu, mem, c) = run(&[lw(9, 6), cv_sw_pr(0, 6, 9)], 2);
    assert_eq!((cpu.reg(6), c), (DATA + 0x0203_0405, 3));
    assert_eq!(mem.read_u32(DATA), Some(0));
    // A dot product is one cycle, and its accumulator is a read too.
    let (cpu, _, c) = run(&[cv_sdotsp_b(8, 6, 6), lw(5, 6), cv_sdotsp_b(5, 0, 0)], 3);
    assert_eq!(c, 1 + 1 + 2);
    // 3 + (DATA's bytes 0x00, 0x10, 0x00, 0x80 as i8)^2 sum.
    let b = DATA.to_le_bytes().map(|x| x as i8 as i32);
    assert_eq!(cpu.reg(8), 3 + b.iter().map(|x| x * x).sum::<i32>() as u32);
}

#[test]
fn immediate_branches_cost_as_branches() {
    // x8 = 3: cv.beqimm x8, 3 taken (3 cycles), cv.bneimm x8, 3 not (1).
    let (cpu, _, c) = run(&[bimm(6, 8, 3, 8), addi(9, 0, 1), addi(10, 0, 1)], 2);
    assert_eq!((cpu.reg(9), cpu.reg(10), c), (0, 1, 4));
    let (_, _, c) = run(&[bimm(7, 8, 3, 8), NOP], 2);
    assert_eq!(c, 2);
    // A negative immediate is sign-extended: x9 = -16.
    let (cpu, _, _) = run(
        &[addi(9, 0, -16), bimm(6, 9, -16, 8), addi(10, 0, 1), NOP],
        3,
    );
    assert_eq!(cpu.reg(10), 0);
}

#[test]
fn reserved_encodings_raise_illegal_instruction() {
    for (what, word) in [
        ("cv.abs with rs2 != 0", r(0b010_1000, 1, 5, 3, 5, 0x2b)),
        ("cv.elw (xcvelw)", i(0, 5, 3, 5, 0x0b)),
        ("hardware loop (xcvhwlp)", i(0, 0, 4, 0, 0x2b)),
        ("SIMD funct3 010", r(0, 1, 5, 2, 5, 0x7b)),
        ("cv.add.h with funct1", r(1, 1, 5, 0, 5, 0x7b)),
        (
            "cv.sll.sci.h, Imm6[5:4] set",
            r(0b010_1000, 0b10000, 5, 6, 5, 0x7b),
        ),
        (
            "cv.extract.h, Imm6[5:1] set",
            r(0b101_1100, 1, 5, 0, 5, 0x7b),
        ),
        (
            "undefined SIMD funct5 01111",
            r(0b011_1100, 1, 5, 0, 5, 0x7b),
        ),
        ("cv.bitrev with Is3 > 3", r(0b110_0100, 0, 5, 1, 5, 0x5b)),
        ("custom-1 funct7 1111111", r(0x7f, 1, 5, 3, 5, 0x2b)),
    ] {
        // At BASE + 0x100: csrw mtvec, x31 (= BASE + 0x800, a spin); jal
        // to the word at BASE + 4, which must trap there.
        let mut mem = Memory::new();
        let mut code = CodeCache::new();
        mem.add_ram(BASE, 0x2000).unwrap();
        let jal_back = 0xf01f_f06f; // at 0x104: jal x0, -0x100
        for (at, w) in [
            (4, word),
            (0x100, 0x305f_9073),
            (0x104, jal_back),
            (0x800, 0x6f),
        ] {
            mem.write_bytes(BASE + at, &u32::to_le_bytes(w)).unwrap();
        }
        let mut cpu = Cpu::new(CpuConfig::default());
        cpu.set_reg(31, BASE + 0x800);
        cpu.set_pc(BASE + 0x100);
        cpu.set_instruction_limit(Some(3));
        cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
        assert_eq!(cpu.pc(), BASE + 0x800, "{what}: {word:#010x}");
        assert_eq!(cpu.csr(0x342), Some(cause::ILLEGAL_INSTRUCTION), "{what}");
        assert_eq!(cpu.csr(0x343), Some(word), "{what}: mtval");
    }
}

#[test]
fn post_increment_accesses_off_the_fast_path_update_the_base_too() {
    // A load from a second RAM region (the executor's cold twin) and a
    // post-increment store into the running block's own code (the core's
    // general path), which rewrites the next instruction.
    let new = addi(10, 0, 42);
    let prog = [
        cv_lw_pi(5, 11, 4),
        13 << 20 | 12 << 15 | 2 << 12 | 4 << 7 | 0x2b, // cv.sw x13, (x12), 4
        addi(10, 0, 1),                                // overwritten before it runs
        NOP,
    ];
    let mut mem = Memory::new();
    let mut code = CodeCache::new();
    mem.add_ram(BASE, 0x2000).unwrap();
    mem.add_ram(0x9000_0000, 0x100).unwrap();
    for (k, w) in prog.iter().enumerate() {
        mem.write_bytes(BASE + 4 * k as u32, &w.to_le_bytes())
            .unwrap();
    }
    mem.write_bytes(0x9000_0000, &0xfeed_beefu32.to_le_bytes())
        .unwrap();
    let mut cpu = Cpu::new(CpuConfig::default());
    cpu.set_pc(BASE);
    cpu.set_reg(11, 0x9000_0000);
    cpu.set_reg(12, BASE + 8);
    cpu.set_reg(13, new);
    cpu.set_instruction_limit(Some(3));
    cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
    assert_eq!((cpu.reg(5), cpu.reg(11)), (0xfeed_beef, 0x9000_0004));
    assert_eq!((cpu.reg(12), cpu.reg(10)), (BASE + 12, 42));
    assert_eq!(mem.read_u32(BASE + 8), Some(new));
}

#[test]
fn the_xcv_benchmark_sums_what_rust_sums() {
    // xcv_bench.c: 2000 int8 dot products of 4096 elements (cv.lw
    // post-increment + cv.sdotsp.b), about 10 M instructions.
    let dot: i32 = (0..4096i32)
        .map(|i| (i * 7 + 3) as i8 as i32 * (i * 13 - 100) as i8 as i32)
        .sum();
    let want = (0..2000).fold(0i32, |s, _| s.wrapping_add(dot));
    let (code, out, cpu) = run_firmware("xcv_bench");
    assert_eq!((code, out), (0, format!("sum {want}\n")));
    // 5 instructions per 4 MACs, 7 cycles (a taken cv.bneimm costs 3).
    let loop_insts = 2000 * 1024 * 5;
    assert!(cpu.instret() > loop_insts && cpu.instret() < loop_insts + 200_000);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
    /// XCV loads and stores give the same registers, cycles, traps and
    /// memory whether their data is in the code's RAM region (the
    /// executor's raw-pointer path) or in a region of its own at the same
    /// addresses (the cold path through the region list).
    #[test]
    fn xcv_memory_ops_agree_on_the_fast_and_the_slow_path(
        raw in proptest::collection::vec(proptest::prelude::any::<u32>(), 40),
        kinds in proptest::collection::vec(0usize..4, 40),
        regs in proptest::collection::vec(0u32..0x1000, 7),
    ) {
        // Registers x0..x7, small immediates; custom-0 loads (funct3 0, 1,
        // 2, 4, 5), custom-1 stores (funct3 0..2) and the register forms
        // (funct3 3 with the load/store funct7s).
        const RR_F7: [u32; 16] = [0, 1, 2, 8, 9, 4, 5, 6, 12, 13, 16, 17, 18, 20, 21, 22];
        let words: Vec<u32> = raw
            .iter()
            .zip(&kinds)
            .map(|(&w, &k)| {
                let (rd, rs1, rs2) = (w & 7, (w >> 3) & 7, (w >> 6) & 7);
                let imm = (((w >> 9) & 0x7f) as i32 - 64) as u32 & 0xfff;
                let f3 = (w >> 16) % 5;
                match k {
                    0 => i(imm as i32, rs1, [0, 1, 2, 4, 5][f3 as usize], rd, 0x0b),
                    1 => (imm >> 5) << 25 | rs2 << 20 | rs1 << 15 | (f3 % 3) << 12 | (imm & 31) << 7 | 0x2b,
                    _ => r(RR_F7[(w >> 27) as usize % 16], rs2, rs1, 3, rd, 0x2b),
                }
            })
            .collect();
        // Data at 0..0x8000, code at 0x8000 (one region, or two); the
        // registers hold addresses and increments in the data.
        const CODE: u32 = 0x8000;
        let run = |split: bool| {
            let mut mem = Memory::new();
            let mut code = CodeCache::new();
            if split {
                mem.add_ram(0, CODE).unwrap();
                mem.add_ram(CODE, 0x8000).unwrap();
            } else {
                mem.add_ram(0, 0x1_0000).unwrap();
            }
            for (k, w) in words.iter().chain(&[0x6f]).enumerate() {
                mem.write_bytes(CODE + 4 * k as u32, &w.to_le_bytes()).unwrap();
            }
            // At CODE + 0x700: csrw mtvec, x31 (a spin at CODE + 0x800);
            // jal x0, CODE.
            for (at, w) in [(0x700, 0x305f_9073u32), (0x704, 0x8fdf_f06f), (0x800, 0x6f)] {
                mem.write_bytes(CODE + at, &w.to_le_bytes()).unwrap();
            }
            let fill: Vec<u8> = (0..CODE).map(|x| (x * 37 + 11) as u8).collect();
            mem.write_bytes(0, &fill).unwrap();
            let mut cpu = Cpu::new(CpuConfig::default());
            cpu.set_pc(CODE + 0x700);
            cpu.set_reg(31, CODE + 0x800);
            for (k, v) in regs.iter().enumerate() {
                cpu.set_reg(k + 1, *v);
            }
            cpu.set_instruction_limit(Some(60));
            let stop = cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX);
            let mut data = vec![0u8; CODE as usize];
            mem.read_bytes(0, &mut data).unwrap();
            (stop, *cpu.regs(), cpu.pc(), cpu.cycles(), cpu.csr(0x342), data)
        };
        proptest::prop_assert_eq!(run(false), run(true));
    }
}
