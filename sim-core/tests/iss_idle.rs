//! Exact idle skipping: a firmware that polls a device register (thesis
//! Listing 4.6) and sleeps in `wfi` gives bit-identical architectural state,
//! counters and device-visible access times with skipping on and off, and
//! however the run is cut into `run_until` slices.

mod iss_util;

use iss_util::op_device::{OpDevice, CTRL};
use sim_core::iss::CodeCache;
use sim_core::iss::{CoreStats, CpuConfig, Mmio, StopReason};
use sim_core::units::{Cycles, Picos};

#[derive(Debug, PartialEq, Eq)]
struct Outcome {
    code: i32,
    pc: u32,
    regs: [u32; 32],
    instret: u64,
    cycles: Cycles,
    now: Picos,
    stats: CoreStats,
    writes: Vec<(u32, u32, Picos)>,
    completions_seen: Vec<(u8, Picos)>,
    events: usize,
}

/// Run `idle.elf`; `slices` cuts the run into `run_until` calls that many
/// picoseconds apart (None: one call).
fn run(skip: bool, eventful: bool, latency: u64, slice: Option<u64>) -> Outcome {
    run_elf("idle", skip, eventful, latency, slice)
}

fn run_elf(name: &str, skip: bool, eventful: bool, latency: u64, slice: Option<u64>) -> Outcome {
    let cfg = CpuConfig {
        idle_skip: skip,
        mmio_latency: Cycles(latency),
        ..CpuConfig::default()
    };
    let (mut cpu, mut mem, _, _) = iss_util::load(name, cfg, &[]);
    let mut code = CodeCache::new();
    cpu.set_instruction_limit(Some(50_000_000));
    let mut dev = OpDevice::default();
    dev.eventful = eventful;
    let mut events = 0;
    let code = loop {
        let limit = slice.map_or(Picos::MAX, |s| cpu.now() + Picos(s));
        match cpu.run_until(&mut mem, &mut code, &mut dev, limit) {
            StopReason::Exit { code } => break code,
            StopReason::Limit => assert!(cpu.now() >= limit),
            StopReason::Event => {
                // The "kernel" processes the due event.
                let t = dev.next_event().unwrap();
                assert!(cpu.now() >= t && cpu.now() < t + Picos(20 * 4_000));
                dev.settle(t);
                events += 1;
            }
            other => panic!("unexpected stop {other:?} at pc {:#x}", cpu.pc()),
        }
    };
    Outcome {
        code,
        pc: cpu.pc(),
        regs: *cpu.regs(),
        instret: cpu.instret(),
        cycles: cpu.cycles(),
        now: cpu.now(),
        stats: cpu.stats(),
        writes: dev.writes,
        completions_seen: dev.completions_seen,
        events,
    }
}

fn without_skip_count(mut o: Outcome) -> Outcome {
    o.stats.skipped_instructions = 0;
    o
}

#[test]
fn skipping_is_exact_and_actually_skips() {
    let stepped = run(false, false, 0, None);
    let skipped = run(true, false, 0, None);
    // The firmware's exit status (through semihosting SYS_EXIT_EXTENDED):
    // its little computation between the operations, recomputed here.
    let work = (0..3).fold(0u32, |w, _| {
        (0..100).fold(w, |w, i| w.wrapping_mul(31).wrapping_add(i))
    });
    assert_eq!(stepped.code, (work & 0x7f) as i32);
    assert_eq!(skipped.code, stepped.code);
    assert_eq!(stepped.stats.skipped_instructions, 0);
    // Five operations of 1..5 ms, plus the sleep: almost everything is idle.
    assert!(
        skipped.stats.skipped_instructions > 1_000_000,
        "{:?}",
        skipped.stats
    );
    assert!(stepped.stats.poll_cycles > 0 && stepped.stats.sleep_cycles > 0);
    // Almost all of the ~15 ms is idle: polling or asleep.
    let idle = stepped.stats.poll_cycles + stepped.stats.sleep_cycles;
    assert!(stepped.stats.running_cycles() < idle / 100);
    assert_eq!(without_skip_count(skipped), without_skip_count(stepped));
}

#[test]
fn clang_xcv_polling_loops_are_skipped_exactly() {
    // idle.c built by clang-19 with the XCV extensions polls with
    // `lbu` + `cv.bneimm` and `lw` + `cv.bneimm`.
    let stepped = run_elf("xcv_idle", false, false, 0, None);
    let skipped = run_elf("xcv_idle", true, false, 0, None);
    assert_eq!(skipped.code, run(false, false, 0, None).code);
    assert!(
        skipped.stats.skipped_instructions > 1_000_000,
        "{:?}",
        skipped.stats
    );
    assert_eq!(without_skip_count(skipped), without_skip_count(stepped));
}

#[test]
fn stats_since_a_sample_add_up() {
    // Sample the counters every millisecond as a power model would.
    let (mut cpu, mut mem, _, _) = iss_util::load("idle", CpuConfig::default(), &[]);
    let mut code = CodeCache::new();
    let mut dev = iss_util::op_device::OpDevice::default();
    let (mut prev, mut total) = (cpu.stats(), CoreStats::default());
    loop {
        let r = cpu.run_until(&mut mem, &mut code, &mut dev, cpu.now() + Picos::from_ms(1));
        let s = cpu.stats();
        let d = s.since(&prev);
        assert_eq!(
            d.running_cycles() + d.poll_cycles + d.sleep_cycles,
            d.cycles
        );
        total.cycles += d.cycles;
        total.poll_cycles += d.poll_cycles;
        total.sleep_cycles += d.sleep_cycles;
        prev = s;
        if let StopReason::Exit { .. } = r {
            break;
        }
    }
    let s = cpu.stats();
    assert_eq!(
        (total.cycles, total.poll_cycles, total.sleep_cycles),
        (s.cycles, s.poll_cycles, s.sleep_cycles)
    );
}

#[test]
fn device_sees_the_operation_complete_no_earlier_than_scheduled() {
    let o = run(true, false, 0, None);
    let ctrl_writes: Vec<_> = o
        .writes
        .iter()
        .filter(|w| w.0 == CTRL && w.1 != 0)
        .collect();
    assert_eq!(ctrl_writes.len(), 5);
    for (w, seen) in ctrl_writes.iter().zip(&o.completions_seen) {
        let due = w.2 + OpDevice::delay(w.1 as u8);
        assert_eq!(seen.0 as u32, w.1);
        // The completing read is the first poll at or after the due time:
        // within one polling iteration (a few cycles) of it.
        assert!(
            seen.1 >= due && seen.1 < due + Picos(10 * 4_000),
            "{seen:?} vs {due:?}"
        );
    }
    // Total time is dominated by the 1+2+3+4+5 ms of operations.
    assert!(o.now > Picos::from_ms(15) && o.now < Picos::from_ms(16));
}

#[test]
fn peripheral_latency_and_slicing_do_not_break_exactness() {
    let reference = without_skip_count(run(false, false, 3, None));
    assert_eq!(without_skip_count(run(true, false, 3, None)), reference);
    // Slices that are not multiples of anything in the program.
    assert_eq!(
        without_skip_count(run(true, false, 3, Some(777_777_777))),
        reference
    );
    assert_eq!(
        without_skip_count(run(false, false, 3, Some(123_456_789))),
        reference
    );
    // The device sees an access `latency` cycles after it issues: the first
    // control write (the first MMIO access) lands exactly 3 cycles later.
    let no_latency = run(false, false, 0, None);
    assert_eq!(
        reference.writes[0].2,
        no_latency.writes[0].2 + Picos(3 * 4_000)
    );
}

#[test]
fn device_events_stop_the_core_identically_in_both_modes() {
    let stepped = run(false, true, 2, None);
    let skipped = run(true, true, 2, None);
    // An event whose time a poll read reaches first is settled lazily by the
    // device and never stops the core; the others do.
    assert!(stepped.events > 0 && stepped.events <= 5);
    assert_eq!(without_skip_count(skipped), without_skip_count(stepped));
}

/// Polling loops with exits, as compiled from the race firmware
/// (`race.c`, `run_single_pid_iter`): the loop body holds conditional
/// branches that leave it. Programs are hand-encoded here (formats from the
/// ISA manual) and run against a device whose status register follows a
/// script of timed changes.
mod exits {
    use std::collections::VecDeque;

    use sim_core::iss::{
        AccessSize, CodeCache, CoreStats, Cpu, CpuConfig, Memory, Mmio, MmioError, StopReason,
    };
    use sim_core::units::{Cycles, Picos};

    const BASE: u32 = 0x8000_0000;
    const DEV: u32 = 0x2000_0000;
    // Register numbers.
    const T0: u32 = 5;
    const S1: u32 = 9;
    const A2: u32 = 12;
    const A3: u32 = 13;
    const A4: u32 = 14;
    const A5: u32 = 15;
    const S2: u32 = 18;
    const S3: u32 = 19;
    const S4: u32 = 20;
    const EBREAK: u32 = 0x0010_0073;
    const NOP: u32 = 0x0000_0013;

    use crate::iss_util::encode::{self, i};
    fn addi(rd: u32, rs1: u32, imm: i32) -> u32 {
        i(imm, rs1, 0, rd, 0x13)
    }
    fn andi(rd: u32, rs1: u32, imm: i32) -> u32 {
        i(imm, rs1, 7, rd, 0x13)
    }
    fn slli(rd: u32, rs1: u32, sh: i32) -> u32 {
        i(sh, rs1, 1, rd, 0x13)
    }
    fn add(rd: u32, rs1: u32, rs2: u32) -> u32 {
        rs2 << 20 | rs1 << 15 | rd << 7 | 0x33
    }
    fn lbu(rd: u32, rs1: u32, imm: i32) -> u32 {
        i(imm, rs1, 4, rd, 0x03)
    }
    fn lw(rd: u32, rs1: u32, imm: i32) -> u32 {
        i(imm, rs1, 2, rd, 0x03)
    }
    fn lui(rd: u32, imm: u32) -> u32 {
        imm & 0xffff_f000 | rd << 7 | 0x37
    }
    fn sb(rs2: u32, rs1: u32, imm: i32) -> u32 {
        encode::s(imm, rs2, rs1, 0)
    }
    /// Conditional branch from word `at` to word `to` (funct3 `f3`).
    fn br(f3: u32, rs1: u32, rs2: u32, at: usize, to: usize) -> u32 {
        encode::b(4 * (to as i32 - at as i32), rs2, rs1, f3)
    }
    const BEQ: u32 = 0;
    const BNE: u32 = 1;
    /// `jal x0` from word `at` to word `to`.
    fn j(at: usize, to: usize) -> u32 {
        encode::jal(4 * (to as i32 - at as i32), 0)
    }

    /// A device in the STM32's style: a status byte at +3 (also the top
    /// byte of the word at +0) that changes at scripted times, an
    /// acknowledge register at +2 (a write clears the status) and a log
    /// register at +0. `kernel` holds device events: at each, the kernel
    /// schedules one more status change, so what `stable_until` promises
    /// changes at a scheduled time.
    #[derive(Debug, Default)]
    struct ScriptDevice {
        status: u8,
        changes: VecDeque<(Picos, u8)>,
        kernel: VecDeque<(Picos, (Picos, u8))>,
        writes: Vec<(u32, u32, Picos)>,
        /// Each read that returned a value different from the previous
        /// read, with its time (the same in skipped and stepped runs).
        seen: Vec<(u32, Picos)>,
        last: Option<u32>,
    }

    impl ScriptDevice {
        fn new(changes: &[(u64, u8)], kernel: &[(u64, (u64, u8))]) -> Self {
            ScriptDevice {
                changes: changes.iter().map(|&(t, v)| (Picos(t), v)).collect(),
                kernel: kernel
                    .iter()
                    .map(|&(t, (c, v))| (Picos(t), (Picos(c), v)))
                    .collect(),
                ..Self::default()
            }
        }

        fn settle(&mut self, now: Picos) {
            while let Some(&(t, v)) = self.changes.front() {
                if t > now {
                    break;
                }
                self.status = v;
                self.changes.pop_front();
            }
        }

        /// The kernel processes the device event due at `now`.
        fn on_event(&mut self, now: Picos) {
            let (t, change) = self.kernel.pop_front().unwrap();
            assert!(now >= t);
            self.changes.push_back(change);
        }
    }

    impl Mmio for ScriptDevice {
        fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError> {
            self.settle(now);
            let v = match (addr - DEV, size) {
                (3, AccessSize::Byte) => self.status as u32,
                (0, AccessSize::Word) => (self.status as u32) << 24,
                _ => return Err(MmioError::AccessFault { addr }),
            };
            if self.last != Some(v) {
                self.seen.push((v, now));
                self.last = Some(v);
            }
            Ok(v)
        }

        fn write(
            &mut self,
            addr: u32,
            size: AccessSize,
            value: u32,
            now: Picos,
        ) -> Result<(), MmioError> {
            self.settle(now);
            self.writes.push((addr, value, now));
            match (addr - DEV, size) {
                (0, AccessSize::Byte) => {}
                (2, AccessSize::Byte) => self.status = 0,
                _ => return Err(MmioError::AccessFault { addr }),
            }
            Ok(())
        }

        fn stable_until(&self, _addr: u32, _size: AccessSize, now: Picos) -> Picos {
            match self.changes.front() {
                Some(&(t, _)) => t.max(now),
                None => Picos::MAX,
            }
        }

        fn next_event(&self) -> Option<Picos> {
            self.kernel.front().map(|e| e.0)
        }
    }

    #[derive(Debug, PartialEq, Eq)]
    struct Outcome {
        stop: StopReason,
        pc: u32,
        regs: [u32; 32],
        instret: u64,
        cycles: Cycles,
        stats: CoreStats,
        writes: Vec<(u32, u32, Picos)>,
        seen: Vec<(u32, Picos)>,
    }

    /// Run `prog` at BASE against `dev` until a breakpoint or `end`, in
    /// `run_until` slices of `slice` ps (None: one call).
    fn run(
        prog: &[u32],
        mut dev: ScriptDevice,
        skip: bool,
        latency: u64,
        slice: Option<u64>,
        end: Picos,
    ) -> Outcome {
        let mut mem = Memory::new();
        let mut code = CodeCache::new();
        mem.add_ram(BASE, 0x1_0000).unwrap();
        mem.add_mmio_window(DEV, 0x1000).unwrap();
        for (k, w) in prog.iter().enumerate() {
            mem.write_bytes(BASE + 4 * k as u32, &w.to_le_bytes())
                .unwrap();
        }
        let mut cpu = Cpu::new(CpuConfig {
            idle_skip: skip,
            mmio_latency: Cycles(latency),
            ebreak_stops: true,
            ..CpuConfig::default()
        });
        cpu.set_pc(BASE);
        cpu.set_instruction_limit(Some(100_000_000));
        let stop = loop {
            let limit = slice.map_or(end, |s| (cpu.now() + Picos(s)).min(end));
            match cpu.run_until(&mut mem, &mut code, &mut dev, limit) {
                StopReason::Event => {
                    let t = dev.next_event().unwrap();
                    assert!(cpu.now() >= t && cpu.now() < t + Picos(10 * 4_000));
                    dev.on_event(t);
                }
                StopReason::Limit if cpu.now() < end => assert!(cpu.now() >= limit),
                r @ (StopReason::Limit | StopReason::Breakpoint { .. }) => break r,
                other => panic!("unexpected stop {other:?} at pc {:#x}", cpu.pc()),
            }
        };
        Outcome {
            stop,
            pc: cpu.pc(),
            regs: *cpu.regs(),
            instret: cpu.instret(),
            cycles: cpu.cycles(),
            stats: cpu.stats(),
            writes: dev.writes,
            seen: dev.seen,
        }
    }

    /// Skipped and stepped runs, whole and sliced, with and without
    /// peripheral latency, all agree (but for the skip count); returns the
    /// skipped run and the reference.
    fn compare(prog: &[u32], dev: impl Fn() -> ScriptDevice, end: Picos) -> (Outcome, Outcome) {
        let clear = |mut o: Outcome| {
            o.stats.skipped_instructions = 0;
            o
        };
        let mut first = None;
        for latency in [0, 3] {
            let stepped = run(prog, dev(), false, latency, None, end);
            assert_eq!(stepped.stats.skipped_instructions, 0);
            let skipped = run(prog, dev(), true, latency, None, end);
            let sliced = run(prog, dev(), true, latency, Some(777_777_777), end);
            let reference = clear(stepped);
            assert_eq!(clear(sliced), reference, "latency {latency}, sliced");
            if first.is_none() {
                first = Some((skipped, reference));
            } else {
                assert_eq!(clear(skipped), reference, "latency {latency}");
            }
        }
        let (skipped, reference) = first.unwrap();
        assert_eq!(
            {
                let mut s = skipped.stats;
                s.skipped_instructions = 0;
                s
            },
            reference.stats
        );
        (skipped, reference)
    }

    /// `run_single_pid_iter`'s loop, instruction for instruction as gcc
    /// compiled it (entered in the middle, at the status read), then the
    /// firmware's reaction to each way out: code 1 (RUN_SINGLE_STEP_PID
    /// seen, the closing `bne` falls through), 2 (BATTERY_LOW), 3
    /// (TARGET_REACHED), acknowledged at +2 and accumulated in s3.
    fn race_program(rounds: i32) -> Vec<u32> {
        const L: usize = 6;
        const CHECK: usize = 8;
        const EXA: usize = 13;
        const EXB: usize = 15;
        const DONE: usize = 16;
        const END: usize = 22;
        let p = vec![
            lui(A3, DEV),            // 0
            addi(S1, 0, 9),          // 1  BATTERY_LOW
            addi(S2, 0, 6),          // 2  TARGET_REACHED
            addi(A2, 0, 4),          // 3  RUN_SINGLE_STEP_PID
            addi(S4, 0, rounds),     // 4
            j(5, CHECK),             // 5
            br(BEQ, A4, S1, L, EXA), // 6  L: exit
            br(BEQ, A4, S2, 7, EXB), // 7     exit
            lbu(A5, A3, 3),          // 8  CHECK: status read
            andi(A4, A5, 255),       // 9  zext.b
            br(BNE, A5, A2, 10, L),  // 10 loop
            addi(T0, 0, 1),          // 11
            j(12, DONE),             // 12
            addi(T0, 0, 2),          // 13 EXA
            j(14, DONE),             // 14
            addi(T0, 0, 3),          // 15 EXB
            sb(T0, A3, 2),           // 16 DONE: acknowledge
            slli(S3, S3, 2),         // 17
            add(S3, S3, T0),         // 18
            addi(S4, S4, -1),        // 19
            br(BEQ, S4, 0, 20, END), // 20
            j(21, CHECK),            // 21
            EBREAK,                  // 22 END
        ];
        assert_eq!(p.len(), END + 1);
        p
    }

    #[test]
    fn race_loop_with_exits_is_skipped_exactly() {
        let dev = || {
            ScriptDevice::new(
                &[
                    // Same value again: only the promise changes.
                    (1_000_001_234, 0),
                    (1_500_003_001, 9), // BATTERY_LOW: first exit taken
                    (2_700_000_999, 4), // the loop value: falls through
                    (3_100_000_003, 6), // TARGET_REACHED: second exit
                    (3_100_200_003, 9), // right after the acknowledge
                    (4_000_000_001, 4),
                ],
                // At 4.5 ms the kernel schedules one more change; until
                // then the device promises the status forever.
                &[(4_500_000_777, (4_800_000_788, 6))],
            )
        };
        let (skipped, stepped) = compare(&race_program(6), dev, Picos::MAX);
        assert_eq!(stepped.stop, StopReason::Breakpoint { pc: BASE + 4 * 22 });
        // Exits in order: 2 (battery), 1 (run), 3 (target), 2, 1, 3.
        let codes = [2, 1, 3, 2, 1, 3];
        assert_eq!(
            stepped.regs[S3 as usize],
            codes.iter().fold(0, |a, c| a << 2 | c)
        );
        let acks: Vec<_> = stepped.writes.iter().map(|w| w.1).collect();
        assert_eq!(acks, codes);
        // Every change was seen within one iteration (5 instructions, ~12
        // cycles with a latency of 0) of its time, none before.
        for (v, due) in [
            (9, 1_500_003_001),
            (4, 2_700_000_999),
            (6, 3_100_000_003),
            (6, 4_800_000_788),
        ] {
            let t = stepped
                .seen
                .iter()
                .find(|s| s.0 == v && s.1 .0 >= due)
                .unwrap()
                .1;
            assert!(t.0 < due + 20 * 4_000, "{v} at {t:?}, due {due}");
        }
        // Nearly all of the ~4.8 ms is polling, and skipping skips it.
        assert!(
            stepped.stats.poll_cycles > stepped.stats.cycles * 99 / 100,
            "{:?}",
            stepped.stats
        );
        assert!(skipped.stats.skipped_instructions > stepped.stats.poll_instructions * 99 / 100);
    }

    #[test]
    fn common_shapes_are_skipped_exactly() {
        // while ((*status & 0x0f) != 4);  — lbu; andi; bne
        let lbu_andi = vec![
            lui(A3, DEV),
            addi(A2, 0, 4),
            lbu(A5, A3, 3),        // 2
            andi(A5, A5, 0x0f),    // 3
            br(BNE, A5, A2, 4, 2), // 4
            sb(A5, A3, 2),
            lbu(A5, A3, 3),        // 6
            andi(A5, A5, 0x0f),    // 7
            br(BNE, A5, A2, 8, 6), // 8
            EBREAK,
        ];
        let dev = || {
            ScriptDevice::new(
                &[
                    (700_000_001, 0x13),
                    (900_000_003, 0x14),
                    (2_000_000_000, 0x24),
                ],
                &[],
            )
        };
        let (skipped, stepped) = compare(&lbu_andi, dev, Picos::MAX);
        assert_eq!(stepped.stop, StopReason::Breakpoint { pc: BASE + 4 * 9 });
        assert!(
            skipped.stats.skipped_instructions > 200_000,
            "{:?}",
            skipped.stats
        );

        // while (*word == 0);  — lw; beqz
        let lw_beqz = vec![
            lui(A3, DEV),
            lw(A5, A3, 0),        // 1
            br(BEQ, A5, 0, 2, 1), // 2
            EBREAK,
        ];
        let dev = || ScriptDevice::new(&[(300_000_000, 0), (1_234_567_891, 7)], &[]);
        let (skipped, stepped) = compare(&lw_beqz, dev, Picos::MAX);
        assert_eq!(stepped.regs[A5 as usize], 7 << 24);
        assert!(
            skipped.stats.skipped_instructions > 100_000,
            "{:?}",
            skipped.stats
        );
    }

    #[test]
    fn a_detour_through_an_exit_is_never_skipped() {
        // The exit leaves the body, writes the device and jumps back to the
        // closing branch: as many instructions as the body, the same
        // registers after each round, one device read — but a store and a
        // jump on the way, so no round may be skipped.
        const L: usize = 3;
        const B: usize = 7;
        const EX: usize = 8;
        let prog = vec![
            lui(A3, DEV),           // 0
            addi(S1, 0, 9),         // 1
            addi(A2, 0, 4),         // 2
            br(BEQ, A5, S1, L, EX), // 3 L
            NOP,                    // 4
            NOP,                    // 5
            lbu(A5, A3, 3),         // 6
            br(BNE, A5, A2, B, L),  // 7 B
            lbu(T0, A3, 3),         // 8 EX
            sb(T0, A3, 0),          // 9 log
            j(10, B),               // 10
        ];
        let dev = || ScriptDevice::new(&[(1_000_000_001, 9)], &[]);
        let (skipped, stepped) = compare(&prog, dev, Picos::from_ms(3));
        assert_eq!(stepped.stop, StopReason::Limit);
        // The quiet first millisecond is skipped; the detour writes the log
        // on every round until the end (~2 ms of 5-instruction rounds).
        assert!(skipped.stats.skipped_instructions > 100_000);
        assert!(stepped.writes.len() > 40_000, "{}", stepped.writes.len());
    }
}
