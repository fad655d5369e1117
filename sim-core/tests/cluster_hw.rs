//! The cluster hardware (DESIGN.md §12, docs/CLUSTER.md) with its
//! test firmware (`sim-core/firmware/src/cluster/cluster_hw_test.c`) on
//! the ISS: boot through CTRL, `mhartid`, the event unit, L1 bank
//! conflicts, the DMA's bytes and closed-form time, determinism.

mod iss_util;

use std::process::Command;

use iss_util::{firmware, Console};
use sim_core::cluster::dma::SETUP_CYCLES;
use sim_core::cluster::event_unit::WAKE_LATENCY_CYCLES;
use sim_core::cluster::{
    Cluster, ClusterConfig, CoreReport, FC_HART_ID, FC_L1_EXTRA_CYCLES, L2_EXTRA_CYCLES,
};
use sim_core::iss::CodeCache;
use sim_core::iss::{load_elf, Cpu, CpuConfig, NoDevices, StopReason};
use sim_core::machine::run_elf::build_memory;
use sim_core::units::Picos;

/// Word indices in the firmware's `struct results`.
mod r {
    pub const NCORES: usize = 0;
    pub const HARTID: usize = 1;
    pub const DISPATCHED: usize = 9;
    pub const ARRIVE: usize = 17;
    pub const LEAVE: usize = 25;
    pub const COUNTER: usize = 33;
    pub const WOKE_VALUE: usize = 34;
    pub const TRIG_TIME: usize = 35;
    pub const WOKE_TIME: usize = 36;
    pub const SAME_BANK: usize = 37;
    pub const OWN_BANK: usize = 45;
    pub const DMA_START: usize = 53;
    pub const DMA_END: usize = 54;
    pub const DMA_OK_1D: usize = 55;
    pub const DMA_OK_2D: usize = 56;
    pub const DMA_OK_BACK: usize = 57;
    pub const OVERLAP_START: usize = 58;
    pub const OVERLAP_END: usize = 60;
    pub const COMPUTE_ONLY: usize = 61;
    pub const INSTRET_BEFORE: usize = 62;
    pub const INSTRET_AFTER: usize = 63;
    pub const FC_HARTID: usize = 64;
    pub const FC_L1: usize = 65;
    pub const FC_L2: usize = 66;
    pub const CORE_L1: usize = 67;
    pub const CORE_L2: usize = 68;
    pub const MAILBOX_SEEN: usize = 69;
    pub const WORDS: usize = 70;
}

struct Outcome {
    words: Vec<u32>,
    reports: Vec<CoreReport>,
    fc_cycles: u64,
    console: String,
}

fn run(cores: usize) -> Outcome {
    run_with(cores, true)
}

fn run_with(cores: usize, idle_skip: bool) -> Outcome {
    let bytes = std::fs::read(firmware("cluster_hw_test")).unwrap();
    let elf = load_elf(&bytes).unwrap();
    let mut mem = build_memory(&[], elf.lowest_address()).unwrap();
    let mut code = CodeCache::new();
    elf.load_into(&mut mem).unwrap();
    let cfg = ClusterConfig {
        cores,
        idle_skip,
        ..ClusterConfig::default()
    };
    let mut cluster = Cluster::new(cfg, &mut mem).unwrap();
    let mut fc = Cpu::new(Cluster::fc_config(CpuConfig {
        idle_skip,
        ..CpuConfig::default()
    }));
    Cluster::attach_fc(&mut fc);
    fc.set_pc(elf.entry);
    let console = Console::default();
    fc.set_console(Box::new(console.clone()));
    fc.set_instruction_limit(Some(50_000_000));
    let stop = cluster.run_until(&mut fc, &mut mem, &mut code, &mut NoDevices, Picos::MAX);
    assert_eq!(stop, StopReason::Exit { code: 0 }, "{}", console.text());
    let base = elf.symbol("results").unwrap();
    let words = (0..r::WORDS)
        .map(|i| mem.read_u32(base + 4 * i as u32).unwrap())
        .collect();
    Outcome {
        words,
        reports: cluster.report(&mem),
        fc_cycles: fc.cycles().0,
        console: console.text(),
    }
}

#[test]
fn cores_boot_with_their_hart_ids_and_dispatch_reaches_each() {
    for n in [1, 3, 8] {
        let o = run(n);
        let w = &o.words;
        assert_eq!(w[r::NCORES], n as u32);
        assert_eq!(w[r::FC_HARTID], FC_HART_ID);
        for i in 0..n {
            assert_eq!(w[r::HARTID + i], i as u32, "core {i} of {n}");
            assert_eq!(w[r::DISPATCHED + i], 0x100 + i as u32, "core {i} of {n}");
        }
        // The mutex kept every increment of every core.
        assert_eq!(w[r::COUNTER], 100 * n as u32);
        assert!(o
            .console
            .contains(&format!("cluster: {n} cores, counter {}", 100 * n)));
    }
}

#[test]
fn l2_costs_cluster_cores_extra_cycles_and_l1_costs_the_fc() {
    let o = run(2);
    let w = &o.words;
    // One load between two mcycle reads: the first read's 3 extra cycles
    // (a 4-cycle CSR, CV32E40P), the load's 1 and the second read's 1; a
    // cluster core's L1 load and the FC's L2 load cost the same.
    let base = 3 + 1 + 1;
    assert_eq!((w[r::CORE_L1], w[r::FC_L2]), (base, base));
    assert_eq!(w[r::CORE_L2] as u64, base as u64 + L2_EXTRA_CYCLES);
    assert_eq!(w[r::FC_L1] as u64, base as u64 + FC_L1_EXTRA_CYCLES);
}

#[test]
fn barrier_releases_at_the_last_arrival_plus_the_wake_latency() {
    let o = run(8);
    let w = &o.words;
    // Core 0 arrives last (its delay is the longest); the others slept and
    // leave exactly WAKE_LATENCY_CYCLES after it (same code after the
    // barrier load).
    let last = (1..8).map(|i| w[r::ARRIVE + i]).max().unwrap();
    assert!(w[r::ARRIVE] > last);
    for i in 1..8 {
        assert!(w[r::ARRIVE + i] < w[r::ARRIVE + i + 1] || i == 7);
        assert_eq!(
            w[r::LEAVE + i] - w[r::LEAVE],
            WAKE_LATENCY_CYCLES as u32,
            "core {i}"
        );
    }
}

#[test]
fn one_bank_serialises_the_cores_spread_banks_do_not() {
    for n in [4, 8] {
        let o = run(n);
        let w = &o.words;
        // Cores 1..n leave the barrier in the same cycle and load 64 words
        // back to back: each bank serves one per cycle, so on one bank the
        // k-th core served waits for k × 64 loads; on their own banks none
        // waits.
        let own: Vec<u32> = (1..n).map(|i| w[r::OWN_BANK + i]).collect();
        assert!(own.iter().all(|&c| c == own[0]), "{own:?}");
        let mut stalls: Vec<u32> = (1..n).map(|i| w[r::SAME_BANK + i] - own[0]).collect();
        stalls.sort_unstable();
        let expected: Vec<u32> = (0..n as u32 - 1).map(|k| 64 * k).collect();
        assert_eq!(stalls, expected);
        // The arbiter's own count agrees.
        let counted: u64 = o.reports[1..n].iter().map(|r| r.l1_stall_cycles).sum();
        assert_eq!(counted, expected.iter().map(|&s| s as u64).sum::<u64>());
    }
}

#[test]
fn dma_copies_exactly_in_closed_form_time_and_overlaps_compute() {
    let o = run(8);
    let w = &o.words;
    assert_eq!(
        (w[r::DMA_OK_1D], w[r::DMA_OK_2D], w[r::DMA_OK_BACK]),
        (1, 1, 1)
    );
    // 1024 bytes: setup + 1024 / 8 cycles, plus the documented constant
    // of the measurement: the wake-up latency, the CMD store and the
    // event-wait load.
    let took = (w[r::DMA_END] - w[r::DMA_START]) as u64;
    let closed = SETUP_CYCLES + 1024 / 8;
    assert_eq!(took, closed + WAKE_LATENCY_CYCLES + 2, "took {took}");
    // 8 KiB (1024 transfer cycles) with ~1000 cycles of compute: the total
    // is less than the sum, and at least the transfer.
    let total = w[r::OVERLAP_END] - w[r::OVERLAP_START];
    let compute = w[r::COMPUTE_ONLY];
    assert!(compute > 500, "compute {compute}");
    assert!(total >= 1024 && total < 1024 + compute, "total {total}");
}

#[test]
fn a_sleeping_core_is_gated_wait_and_trigger() {
    let o = run(8);
    let w = &o.words;
    assert_eq!(w[r::WOKE_VALUE], 1 << 3);
    // Asleep through the DMA tests: no instruction retired meanwhile (the
    // few between the two minstret reads), its cycles gated.
    let between = w[r::INSTRET_AFTER] - w[r::INSTRET_BEFORE];
    assert!(between < 10, "{between}");
    // From core 0's time stamp to core 1's: the wake-up latency plus two
    // stores of the stamps to L2 (one each side, L2_EXTRA_CYCLES each) and
    // a few single-cycle instructions.
    let latency = (w[r::WOKE_TIME] - w[r::TRIG_TIME]) as u64;
    let floor = WAKE_LATENCY_CYCLES + 2 * L2_EXTRA_CYCLES;
    assert!((floor..=floor + 8).contains(&latency), "{latency}");
    let c1 = &o.reports[1];
    assert!(c1.gated_cycles > (w[r::OVERLAP_END] - w[r::DMA_START]) as u64);
    // Gated cycles are not in mcycle (active) and add no instructions.
    assert!(c1.active_cycles < 10_000 && c1.instructions < 3_000);
}

/// The FC's write of a task to MAILBOX: core 0, polling it, reads it; the
/// write also raises core 0's mailbox event (the PMSIS runtime's core 0
/// sleeps on it: cluster_runtime.rs, `runtime_selftest_passes`).
#[test]
fn core_0_sees_the_fcs_mailbox_write() {
    let o = run(8);
    assert_eq!(o.words[r::MAILBOX_SEEN], 1);
}

#[test]
fn same_elf_same_cycles_and_results() {
    let a = run(8);
    let b = run(8);
    assert_eq!(a.words, b.words);
    assert_eq!(a.reports, b.reports);
    assert_eq!(a.fc_cycles, b.fc_cycles);
    // Idle skipping of the FC's polling (FC_EVENT, RUNNING) is exact: a
    // step-by-step run lands on the same cycles.
    let c = run_with(8, false);
    assert_eq!(a.words, c.words);
    assert_eq!(a.reports, c.reports);
    assert_eq!(a.fc_cycles, c.fc_cycles);
}

#[test]
fn run_elf_prints_each_core_in_stats_and_rejects_bad_core_counts() {
    let bin = env!("CARGO_BIN_EXE_sim-core");
    let fw = firmware("cluster_hw_test");
    let o = Command::new(bin)
        .args([
            "run-elf",
            fw.to_str().unwrap(),
            "--stats",
            "--cluster-cores",
            "4",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
    let err = String::from_utf8_lossy(&o.stderr);
    for i in 0..4 {
        assert!(
            err.contains(&format!("cluster core {i}: instructions ")),
            "{err}"
        );
    }
    assert!(!err.contains("cluster core 4"));
    let bad = Command::new(bin)
        .args(["run-elf", fw.to_str().unwrap(), "--cluster-cores", "9"])
        .output()
        .unwrap();
    assert_ne!(bad.status.code(), Some(0));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("cluster.cores must be 1 to 8"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

#[test]
fn a_dma_command_outside_l1_is_a_clear_error_naming_the_core() {
    let bin = env!("CARGO_BIN_EXE_sim-core");
    let fw = firmware("cluster_bad_dma");
    let o = Command::new(bin)
        .args(["run-elf", fw.to_str().unwrap()])
        .output()
        .unwrap();
    assert_ne!(o.status.code(), Some(0));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("cluster core 0") && err.contains("store access fault"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}
