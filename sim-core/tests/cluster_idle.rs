//! Idle skipping on the cluster cores (`iss` module docs, "Idle
//! skipping"): a core polling CTRL's mailbox while the FC works (core 0 at
//! the end of `cluster_hw_test.c`; a user's runtime may poll as ours did
//! before its core 0 slept on the mailbox event) jumps to the FC's time
//! instead of reading it every few cycles (`CoreBus::stable_until`), and
//! every committed cluster program ends in the same state, cycle for
//! cycle, with skipping on and off.

mod iss_util;

use sim_core::iss::{Backend, CoreStats, NoDevices};
use sim_core::units::Picos;

/// What a run leaves: the stop, the FC's registers and statistics, the
/// console, the cluster's reports and DMA totals, and each core's own
/// statistics (`skipped_instructions` apart, returned beside).
fn run(name: &str, idle_skip: bool) -> (String, u64) {
    let iss_util::ClusterRun {
        mut cpu,
        mut mem,
        mut code,
        mut cluster,
        console,
    } = iss_util::cluster_run(name, Backend::DEFAULT, idle_skip, 3_000_000);
    let stop = cluster.run_until(&mut cpu, &mut mem, &mut code, &mut NoDevices, Picos::MAX);
    cpu.flush_console().unwrap();
    cluster.flush_console().unwrap();
    let unskipped = |s: CoreStats| CoreStats {
        skipped_instructions: 0,
        ..s
    };
    let cores = cluster.core_stats();
    let skipped = cores.iter().map(|s| s.skipped_instructions).sum();
    let state = format!(
        "{stop:?} {:?} {:?} {:?}\n{}\n{:?} {:?}\n{:?}",
        cpu.regs(),
        unskipped(cpu.stats()),
        cpu.cycles(),
        console.text(),
        cluster.report(&mem),
        cluster.dma_totals(),
        cores.into_iter().map(unskipped).collect::<Vec<_>>(),
    );
    (state, skipped)
}

#[test]
fn cluster_programs_end_alike_with_and_without_idle_skipping() {
    let mut skipped_somewhere = false;
    for name in [
        "cluster_hello",
        "cluster_selftest",
        "cluster_matmul",
        "cluster_hw_repeat",
        "cluster_hw_test",
        "nn_selftest",
    ] {
        let (on, skipped) = run(name, true);
        let (off, none) = run(name, false);
        assert_eq!(on, off, "{name}");
        assert_eq!(none, 0, "{name}");
        skipped_somewhere |= skipped > 0;
    }
    // Not vacuous: some core skipped polling iterations.
    assert!(skipped_somewhere);
}
