//! World steps per second (physics + sensors) and camera frames per second.
//!
//! `cargo bench -p world-server --bench world`; criterion prints the time per
//! iteration, whose inverse is the rate.
//!
//! Times are the benchmark thread's CPU time (CLOCK_THREAD_CPUTIME_ID), not
//! wall time: the cost asked for is "on one core", and the build
//! machine is shared, so wall time would mostly measure the other processes.
//! On an idle core the two agree.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rapier3d::glamx::{DQuat, DVec3};
use world_server::camera::Camera;
use world_server::crazyflie::hover_speed;
use world_server::scene::scene_boxes;
use world_server::{Millis, StepConfig, World, WorldDesc};

/// CPU time consumed by the calling thread.
fn thread_cpu_time() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// Runs `f` `iters` times and returns the thread CPU time it took.
fn cpu_time(iters: u64, mut f: impl FnMut()) -> Duration {
    let t0 = thread_cpu_time();
    for _ in 0..iters {
        f();
    }
    thread_cpu_time() - t0
}

fn course() -> WorldDesc {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/worlds/thesis-course.toml");
    WorldDesc::load(&path).expect("course world file")
}

fn steps(c: &mut Criterion) {
    let desc = course();
    let mut g = c.benchmark_group("world");
    g.throughput(Throughput::Elements(1));
    for (name, substeps) in [
        ("step_32ms+sensors", 1),
        ("step_32ms_4_substeps+sensors", 4),
    ] {
        let mut w = World::new(
            &desc,
            StepConfig {
                timestep: Millis(32),
                substeps,
            },
        )
        .unwrap();
        // Hovering at 1 m among the gates, near gate 1.
        let h = hover_speed();
        w.teleport(
            0,
            DVec3::new(-0.8, 1.0, 1.0),
            DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
        );
        w.motors_mut(0).set_speeds_now([-h, h, -h, h]);
        g.bench_function(name, |b| {
            b.iter_custom(|iters| {
                cpu_time(iters, || {
                    w.step();
                    black_box(w.sensors(0));
                })
            })
        });
    }
    g.finish();
}

fn frames(c: &mut Criterion) {
    let desc = course();
    let mut cam = Camera::new(&desc, &scene_boxes(&desc));
    let mut g = c.benchmark_group("camera");
    g.throughput(Throughput::Elements(1));
    let start = DVec3::from_array(desc.start.position.0);
    let views = [
        (
            "start_view",
            start,
            DQuat::from_rotation_z(desc.start.yaw.0),
        ),
        // At 1 m turned towards gate 1, with gates 1 and 2 in view.
        (
            "gate_view",
            DVec3::new(-2.6, 0.0, 0.99),
            DQuat::from_rotation_z(0.6947),
        ),
        // Hovering at 1 m facing +y, as in the race.
        (
            "race_view",
            DVec3::new(2.0, -0.4, 1.0),
            DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
        ),
    ];
    for (name, pos, rot) in views {
        g.bench_function(name, |b| {
            b.iter_custom(|iters| {
                cpu_time(iters, || {
                    black_box(cam.render(pos, rot)[0]);
                })
            })
        });
    }
    g.finish();
}

criterion_group!(benches, steps, frames);
criterion_main!(benches);
