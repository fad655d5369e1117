//! Exact idle skipping: a firmware that polls a device register (thesis
//! Listing 4.6) and sleeps in `wfi` gives bit-identical architectural state,
//! counters and device-visible access times with skipping on and off, and
//! however the run is cut into `run_until` slices.

mod iss_util;

use iss_util::op_device::{OpDevice, CTRL};
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
    let cfg = CpuConfig {
        idle_skip: skip,
        mmio_latency: Cycles(latency),
        ..CpuConfig::default()
    };
    let (mut cpu, mut mem, _, _) = iss_util::load("idle", cfg, &[]);
    cpu.set_instruction_limit(Some(50_000_000));
    let mut dev = OpDevice::default();
    dev.eventful = eventful;
    let mut events = 0;
    let code = loop {
        let limit = slice.map_or(Picos::MAX, |s| cpu.now() + Picos(s));
        match cpu.run_until(&mut mem, &mut dev, limit) {
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
fn stats_since_a_sample_add_up() {
    // Sample the counters every millisecond as a power model would.
    let (mut cpu, mut mem, _, _) = iss_util::load("idle", CpuConfig::default(), &[]);
    let mut dev = iss_util::op_device::OpDevice::default();
    let (mut prev, mut total) = (cpu.stats(), CoreStats::default());
    loop {
        let r = cpu.run_until(&mut mem, &mut dev, cpu.now() + Picos::from_ms(1));
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
