//! ISS speed: MIPS with timing on for the CPU-bound benchmark firmware, and
//! the idle-polling firmware with idle skipping on and off. Prints MIPS
//! (instructions per wall second of `run_until`, ELF loading excluded) next
//! to criterion's numbers. Timing is always on in this ISS.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use sim_core::iss::CodeCache;
use sim_core::iss::{load_elf, Cpu, CpuConfig, Memory, StopReason};
use sim_core::machine::run_elf::build_memory;
use sim_core::units::Picos;

#[path = "../tests/iss_util/op_device.rs"]
mod op_device;
use op_device::OpDevice;

fn elf(name: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("firmware/bin/{name}.elf"));
    std::fs::read(p).expect("firmware ELF")
}

/// A core with the ELF loaded (the setup is kept out of the timings).
fn prepare(bytes: &[u8], skip: bool) -> (Cpu, Memory, OpDevice) {
    let elf = load_elf(bytes).unwrap();
    let mut mem = build_memory(&[], elf.lowest_address()).unwrap();
    elf.load_into(&mut mem).unwrap();
    let mut cpu = Cpu::new(CpuConfig {
        idle_skip: skip,
        ..CpuConfig::default()
    });
    cpu.set_console(Box::new(std::io::sink()));
    cpu.set_pc(elf.entry);
    (cpu, mem, OpDevice::default())
}

/// Run to the end; returns (instructions retired, instructions interpreted).
fn run((mut cpu, mut mem, mut dev): (Cpu, Memory, OpDevice)) -> (u64, u64) {
    match cpu.run_until(&mut mem, &mut CodeCache::new(), &mut dev, Picos::MAX) {
        StopReason::Exit { .. } => {}
        other => panic!("{other:?}"),
    }
    let s = cpu.stats();
    (s.instructions, s.instructions - s.skipped_instructions)
}

fn report_mips(label: &str, bytes: &[u8], skip: bool) {
    let mut busy = Duration::ZERO;
    let mut interpreted = 0;
    let mut retired = 0;
    let mut runs = 0;
    while busy < Duration::from_secs(2) || runs < 3 {
        let state = prepare(bytes, skip);
        let start = Instant::now();
        let (r, i) = run(state);
        busy += start.elapsed();
        retired += r;
        interpreted += i;
        runs += 1;
    }
    let secs = busy.as_secs_f64();
    eprintln!(
        "{label}: {:.0} MIPS interpreted, {:.0} MIPS simulated ({} instructions per run, {runs} runs)",
        interpreted as f64 / secs / 1e6,
        retired as f64 / secs / 1e6,
        retired / runs,
    );
}

fn benches(c: &mut Criterion) {
    let bench = elf("bench");
    let idle = elf("idle");
    report_mips("bench.elf (timing on)", &bench, true);
    report_mips("idle.elf, idle skipping on", &idle, true);
    report_mips("idle.elf, idle skipping off", &idle, false);
    // The NN inner loop on the CORE-V extensions: cv.lw post-increment +
    // cv.sdotsp.b (docs/CLUSTER.md "Instructions").
    report_mips(
        "xcv_bench.elf (cv.lw + cv.sdotsp.b)",
        &elf("xcv_bench"),
        true,
    );

    let mut g = c.benchmark_group("iss");
    g.sample_size(10);
    let batch = criterion::BatchSize::LargeInput;
    g.throughput(Throughput::Elements(run(prepare(&bench, true)).0));
    g.bench_function("bench_elf", |b| {
        b.iter_batched(|| prepare(&bench, true), run, batch)
    });
    g.throughput(Throughput::Elements(run(prepare(&idle, true)).0));
    g.bench_function("idle_elf_skip_on", |b| {
        b.iter_batched(|| prepare(&idle, true), run, batch)
    });
    g.bench_function("idle_elf_skip_off", |b| {
        b.iter_batched(|| prepare(&idle, false), run, batch)
    });
    g.finish();
}

criterion_group!(iss, benches);
criterion_main!(iss);
