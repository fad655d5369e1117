//! Golden values of the STM32's velocity controller (`peripherals::stm32::pid`
//! and the measurement of `flight.rs`) for the Python port
//! (`python/src/crazyflie_cosim/controller.py`, DESIGN.md §15).
//!
//! The cases are drawn from a seeded generator; the controller's outputs on
//! them are compared with `python/tests/data/pid_golden.json`, which the
//! Python test replays through the port. Both sides must reproduce the file
//! bit for bit, so a change to either controller fails a test until the other
//! follows. `COSIM_BLESS=1 cargo test -p sim-core --test pid_golden` rewrites
//! the file after a deliberate change of the Rust controller.

use std::path::PathBuf;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};
use sim_core::peripherals::stm32::pid::{
    body_velocity, to_body, ActualState, DesiredState, PidController, PidGains,
};

/// One flight of `STEPS` controller iterations on random measurements, as
/// `flight.rs` runs them: body velocities from two GPS fixes, the height
/// set-point integrated from a vertical speed demand, then the PID.
const CASES: u64 = 6;
const STEPS: usize = 40;

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../python/tests/data/pid_golden.json")
}

fn flight(seed: u64) -> Value {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Timesteps the race runs at (docs/COSIM.md, thesis §5.2) and one odd dt.
    let dt_choices = [0.008, 0.016, 0.024, 0.032, 0.007];
    let dt = dt_choices[(seed as usize) % dt_choices.len()];
    let mut pid = PidController::new(PidGains::default());
    let (mut x, mut y, mut z) = (
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
        rng.random_range(0.0..2.0),
    );
    let start = [x, y, z];
    let mut time = 2.0;
    let (mut past_x, mut past_y, mut past_time) = (x, y, time);
    let mut height_desired = z;
    let mut steps = Vec::new();
    for _ in 0..STEPS {
        time += dt;
        x += rng.random_range(-0.03..0.03);
        y += rng.random_range(-0.03..0.03);
        z += rng.random_range(-0.02..0.02);
        let roll: f64 = rng.random_range(-0.4..0.4);
        let pitch: f64 = rng.random_range(-0.4..0.4);
        let yaw: f64 = rng.random_range(-3.1..3.1);
        let yaw_rate: f64 = rng.random_range(-2.0..2.0);
        let cmd: [f64; 4] = [
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-0.5..0.5),
            rng.random_range(-1.0..1.0),
        ];
        // flight.rs `measured`: the finite difference rotated by −yaw.
        let step_dt = time - past_time;
        let (vx, vy) = body_velocity(x - past_x, y - past_y, step_dt, yaw);
        let actual = ActualState {
            roll,
            pitch,
            yaw_rate,
            altitude: z,
            vx,
            vy,
        };
        height_desired += cmd[2] * step_dt;
        let (dvx, dvy) = to_body(cmd[0], cmd[1], yaw);
        let mut desired = DesiredState {
            yaw_rate: cmd[3],
            vx: dvx,
            vy: dvy,
            altitude: height_desired,
            ..DesiredState::default()
        };
        let m = pid.step(&actual, &mut desired, step_dt);
        (past_x, past_y, past_time) = (x, y, time);
        steps.push(json!({
            "time_s": time, "x": x, "y": y, "z": z,
            "roll": roll, "pitch": pitch, "yaw": yaw, "yaw_rate": yaw_rate,
            "command": cmd,
            "body_velocity": [vx, vy],
            "desired_roll": desired.roll, "desired_pitch": desired.pitch,
            "motors": m.as_array(),
        }));
    }
    json!({ "seed": seed, "dt": dt, "start": start, "start_time_s": 2.0, "steps": steps })
}

#[test]
fn the_python_port_s_golden_file_matches_the_rust_controller() {
    let flights: Vec<Value> = (1..=CASES).map(flight).collect();
    let golden = json!({
        "about": "sim-core/tests/pid_golden.rs: the STM32 velocity controller on seeded random flights",
        "flights": flights,
    });
    let path = golden_path();
    if std::env::var_os("COSIM_BLESS").is_some() {
        let text = serde_json::to_string_pretty(&golden).expect("JSON") + "\n";
        std::fs::write(&path, text).expect("write the golden file");
        return;
    }
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (COSIM_BLESS=1 writes it)", path.display()));
    let stored: Value = serde_json::from_str(&text).expect("golden file is JSON");
    assert_eq!(
        stored,
        golden,
        "the Rust controller no longer gives {}; if the change is deliberate, \
         re-bless it (COSIM_BLESS=1) and port the change to controller.py",
        path.display()
    );
}
