//! Idle skipping on the cluster cores (`iss` module docs, "Idle
//! skipping"): a core polling CTRL's mailbox while the FC works
//! (`master_loop` of the PMSIS runtime waiting for its next task) jumps to
//! the FC's time instead of reading it every few cycles
//! (`CoreBus::stable_until`), and every committed cluster program ends in
//! the same state, cycle for cycle, with skipping on and off.

mod iss_util;

use sim_core::cluster::{Cluster, ClusterConfig};
use sim_core::iss::run_elf::build_memory;
use sim_core::iss::{load_elf, CoreStats, Cpu, CpuConfig, NoDevices};
use sim_core::units::{Hertz, Picos};

use iss_util::Console;

/// What a run leaves: the stop, the FC's registers and statistics, the
/// console, the cluster's reports and DMA totals, and each core's own
/// statistics (`skipped_instructions` apart, returned beside).
fn run(name: &str, idle_skip: bool) -> (String, u64) {
    let bytes = std::fs::read(iss_util::firmware(name)).unwrap();
    let elf = load_elf(&bytes).unwrap();
    let mut mem = build_memory(&[], elf.lowest_address()).unwrap();
    elf.load_into(&mut mem).unwrap();
    let mut cluster = Cluster::new(
        ClusterConfig {
            clock: Hertz(175_000_000),
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
        idle_skip,
        ..CpuConfig::default()
    }));
    Cluster::attach_fc(&mut cpu);
    cpu.set_console(Box::new(console.clone()));
    cpu.set_pc(elf.entry);
    cpu.set_tohost(elf.symbol("tohost"));
    cpu.set_instruction_limit(Some(3_000_000));
    let stop = cluster.run_until(&mut cpu, &mut mem, &mut NoDevices, Picos::MAX);
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
