//! Cost of the 1 ms power samples (the kernel takes one per simulated ms),
//! and the hover endurance of each battery with each motor model, printed.
//!
//! `cargo bench -p sim-core --bench power`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use sim_core::config::{PlatformConfig, RunConfig};
use sim_core::power::battery::BatteryModel;
use sim_core::power::models::PowerModelKind;
use sim_core::power::{CoreState, Loads, MotorState, PowerNetwork, SensorState};
use sim_core::units::Picos;

fn loads() -> Loads {
    Loads {
        core: CoreState::Running,
        camera: SensorState::Idle,
        stm32: SensorState::Read,
        ..Loads::default()
    }
}

/// The world's hover: 4·4e-5·ω² = 0.05·9.81.
fn hover() -> MotorState {
    let w = (0.05 * 9.81 / 1.6e-4_f64).sqrt();
    MotorState {
        omega: [-w, w, -w, w],
        ..MotorState::default()
    }
}

fn network(run: &RunConfig) -> PowerNetwork {
    PowerNetwork::new(&PlatformConfig::default_crazyflie(), run).unwrap()
}

/// Simulated seconds at hover until BATTERY_LOW (10 % SOC).
fn endurance(battery: BatteryModel, model: PowerModelKind) -> f64 {
    let mut net = network(&RunConfig {
        battery: Some(battery),
        power_model: model,
        ..RunConfig::default()
    });
    let mut t = Picos::ZERO;
    while !net.low_battery() {
        t += Picos::from_ms(1);
        net.sample(t, &loads(), &hover()).unwrap();
    }
    t.as_secs_f64()
}

fn print_endurance() {
    println!("hover time to 10 % SOC (s), world hover speed, flight loads:");
    println!(
        "{:<28} {:>10} {:>10} {:>10}",
        "battery", "empirical", "dandrea", "stolaroff"
    );
    for b in BatteryModel::ALL {
        let row: Vec<f64> = PowerModelKind::ALL
            .iter()
            .map(|m| endurance(b, *m))
            .collect();
        println!(
            "{:<28} {:>10.1} {:>10.1} {:>10.1}",
            b.part(),
            row[0],
            row[1],
            row[2]
        );
    }
}

fn bench_sample(c: &mut Criterion) {
    print_endurance();
    let run = RunConfig::default();
    let (l, m) = (loads(), hover());
    // 1000 samples (1 s of simulated time) per iteration on a fresh network,
    // so the battery never empties however long criterion runs.
    c.bench_function("power_1000_samples", |b| {
        b.iter_batched(
            || network(&run),
            |mut net| {
                for k in 1..=1000 {
                    black_box(net.sample(Picos::from_ms(k), &l, &m).unwrap());
                }
                net
            },
            BatchSize::SmallInput,
        )
    });
}

criterion_group!(benches, bench_sample);
criterion_main!(benches);
