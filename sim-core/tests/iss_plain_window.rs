//! Device registers that read like memory (`Mmio::plain_window`, the
//! camera's image registers): the block executor loads them in its hot
//! loop instead of leaving for the general path at every access, with the
//! general path's exact cost (the MMIO latency, no split cycle). A frame
//! copy loop must end in the same state, cycle for cycle, with the window
//! offered or not, interpreted or translated, run whole or in slices.

use sim_core::iss::CodeCache;
use sim_core::iss::StopReason;

mod iss_util;

use iss_util::encode::{b, i, lui, r, s};
use sim_core::iss::{
    AccessSize, Backend, CoreStats, Cpu, CpuConfig, IssError, Memory, Mmio, MmioError,
};
use sim_core::units::{Cycles, Picos};

const RAM: u32 = 0x8000_0000;
const WINDOW: u32 = 0x2000_0000;
const WINDOW_BYTES: usize = 1024;

/// A frame buffer behind an MMIO window, offered as a plain window or not.
struct Frame {
    bytes: Vec<u8>,
    plain: bool,
    /// Reads that went through `Mmio::read` (the general path).
    reads: u64,
}

impl Frame {
    fn new(plain: bool) -> Frame {
        // Deterministic pseudo-random pixels (an LCG: any pattern whose
        // bytes differ will do).
        let mut x = 0x1234_5678u32;
        let bytes = (0..WINDOW_BYTES)
            .map(|_| {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (x >> 24) as u8
            })
            .collect();
        Frame {
            bytes,
            plain,
            reads: 0,
        }
    }
}

impl Mmio for Frame {
    fn read(&mut self, addr: u32, size: AccessSize, _now: Picos) -> Result<u32, MmioError> {
        self.reads += 1;
        let off = addr.wrapping_sub(WINDOW) as usize;
        let n = size.bytes() as usize;
        let b = self
            .bytes
            .get(off..off + n)
            .ok_or(MmioError::AccessFault { addr })?;
        Ok(b.iter().rev().fold(0, |v, &x| (v << 8) | u32::from(x)))
    }
    fn write(&mut self, addr: u32, _: AccessSize, _: u32, _: Picos) -> Result<(), MmioError> {
        Err(MmioError::AccessFault { addr })
    }
    fn plain_window(&mut self) -> Option<(u32, &[u8])> {
        self.plain.then_some((WINDOW, &self.bytes[..]))
    }
}

/// Copies 200 words of the frame into RAM with every load width, aligned
/// and misaligned, with load-use stalls, then reads `mcycle` and spins.
fn program() -> Vec<u32> {
    vec![
        lui(5, WINDOW >> 12),         // 0: x5 = the window
        lui(6, (RAM + 0x1000) >> 12), // 1: x6 = the copy in RAM
        i(200, 0, 0, 7, 0x13),        // 2: x7 = 200
        i(0, 5, 2, 8, 0x03),          // 3: lw x8, 0(x5)
        s(0, 8, 6, 2),                // 4: sw x8, 0(x6)
        i(1, 5, 1, 9, 0x03),          // 5: lh x9, 1(x5)
        i(3, 5, 4, 10, 0x03),         // 6: lbu x10, 3(x5)
        r(0, 9, 10, 0, 11, 0x33),     // 7: add x11, x10, x9 (load-use)
        i(2, 5, 2, 12, 0x03),         // 8: lw x12, 2(x5) (misaligned)
        r(0, 12, 11, 0, 13, 0x33),    // 9: add x13, x11, x12 (load-use)
        s(4, 13, 6, 2),               // 10: sw x13, 4(x6)
        i(3, 5, 5, 14, 0x03),         // 11: lhu x14, 3(x5) (split half)
        i(2, 5, 0, 15, 0x03),         // 12: lb x15, 2(x5)
        r(0, 15, 14, 4, 16, 0x33),    // 13: xor x16, x14, x15
        s(8, 16, 6, 2),               // 14: sw x16, 8(x6)
        i(4, 5, 0, 5, 0x13),          // 15: addi x5, x5, 4
        i(12, 6, 0, 6, 0x13),         // 16: addi x6, x6, 12
        i(-1, 7, 0, 7, 0x13),         // 17: addi x7, x7, -1
        b(-60, 0, 7, 1),              // 18: bne x7, x0, -60 (to 3)
        0xb000_2573,                  // 19: csrr x10, mcycle
        0x0000_006f,                  // 20: j .
    ]
}

#[derive(Debug, PartialEq)]
struct State {
    regs: [u32; 32],
    pc: u32,
    cycles: u64,
    instret: u64,
    stats: CoreStats,
    ram: Vec<u8>,
}

/// Runs the copy to its final spin (which, with interrupts off, can never
/// progress and ends the run; an instruction limit bounds a regression), whole or in
/// slices of `slice` ps; returns the state, the general-path reads and the
/// instructions retired in translated code.
fn run(iss: Backend, plain: bool, slice: Option<u64>) -> (State, u64, u64) {
    let mut mem = Memory::new();
    let mut code = CodeCache::new();
    mem.add_ram(RAM, 0x1_0000).unwrap();
    mem.add_mmio_window(WINDOW, 0x1000).unwrap();
    for (k, w) in program().iter().enumerate() {
        mem.write_bytes(RAM + 4 * k as u32, &w.to_le_bytes())
            .unwrap();
    }
    let mut cpu = Cpu::new(CpuConfig {
        iss,
        mmio_latency: Cycles(3),
        ..CpuConfig::default()
    });
    cpu.set_pc(RAM);
    cpu.set_instruction_limit(Some(200 * 16 + 500));
    let mut dev = Frame::new(plain);
    loop {
        let limit = slice.map_or(Picos::MAX, |s| cpu.now() + Picos(s));
        match cpu.run_until(&mut mem, &mut code, &mut dev, limit) {
            StopReason::Fatal(IssError::NeverProgress { pc, .. }) if pc == RAM + 80 => break,
            StopReason::Limit => assert!(slice.is_some()),
            other => panic!("unexpected stop {other:?} at pc {:#x}", cpu.pc()),
        }
    }
    let mut ram = vec![0u8; 200 * 12];
    mem.read_bytes(RAM + 0x1000, &mut ram).unwrap();
    let state = State {
        regs: *cpu.regs(),
        pc: cpu.pc(),
        cycles: cpu.cycles().0,
        instret: cpu.instret(),
        stats: cpu.stats(),
        ram,
    };
    (state, dev.reads, cpu.translated_instructions())
}

#[test]
fn a_plain_window_reads_as_the_general_path_does() {
    let (general, general_reads, _) = run(Backend::Interp, false, None);
    // Every load of the copy went to the device: 6 per word.
    assert_eq!(general_reads, 200 * 6);
    // The copy is the frame's bytes.
    let frame = Frame::new(false).bytes;
    assert_eq!(general.ram[..4], frame[..4]);
    assert_eq!(
        general.ram[12 * 199..12 * 199 + 4],
        frame[4 * 199..4 * 199 + 4]
    );

    let mut backends = vec![Backend::Interp];
    if cfg!(target_arch = "x86_64") {
        backends.push(Backend::Jit);
    }
    for iss in backends {
        for slice in [None, Some(7_777), Some(123_457)] {
            let (plain, reads, translated) = run(iss, true, slice);
            assert_eq!(plain, general, "{iss:?}, slices {slice:?}");
            // Not vacuous: every load of the window ran in the executor's
            // loop, none on the general path.
            assert_eq!(reads, 0, "{iss:?}: {reads} reads on the general path");
            // And the translator reads the window itself: the copy runs
            // translated (it ran interpreted before `mem::window_load`).
            // Slices of a few cycles leave no block room to be entered.
            if iss == Backend::Jit && slice.is_none() {
                let share = translated as f64 / plain.instret as f64;
                assert!(share > 0.9, "slices {slice:?}: {share:.3} translated");
            }
            let (off, _, _) = run(iss, false, slice);
            assert_eq!(off, general, "{iss:?} without the window, slices {slice:?}");
        }
    }
}
