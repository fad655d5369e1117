//! Seed 003's swarm positioning firmware (`firmware/src/swarm/`,
//! docs/SWARM_FIRMWARE.md) runs on the ISS: its self-test passes on its own,
//! and again on scenarios whose DW1000 stamps are computed here with the
//! world's own stamp function (`protocol::radio::dw1000_stamp`): drones with
//! ±20 ppm clocks at known distances exchange real STATUS packets through
//! the firmware's API, and the TOFs (eq. 5.11) and positions (§5.3.2, §6.8)
//! it finds are checked here against closed-form values.

mod iss_util;

use object::{Object, ObjectSymbol};
use protocol::radio::{dw1000_stamp, ppm_to_ppt, Picos, DW1000_TICKS_PER_SECOND};
use sim_core::iss::CodeCache;
use sim_core::iss::{CpuConfig, NoDevices, StopReason};

const ELF: &str = "swarm_selftest";
const SPEED_OF_LIGHT: f64 = 299_792_458.0;
/// Layout of the firmware's `sc_input_t` / `sc_input_event_t`
/// (`swarm_scenario.h`, checked there by static assertions).
const INPUT_MAGIC: u32 = 0x4e49_5753;
const INPUT_DRONES: usize = 8;
const INPUT_HEADER_BYTES: usize = 448;
const INPUT_EVENT_BYTES: usize = 88;

/// Run the self-test, with a scenario written into its unused heap first.
fn run(input: Option<&[u8]>) -> (i32, String) {
    let (mut cpu, mut mem, elf, console) = iss_util::load(ELF, CpuConfig::default(), &[]);
    let mut code = CodeCache::new();
    if let Some(bytes) = input {
        let start = elf.symbol("__heap_start").expect("__heap_start");
        let end = elf.symbol("__heap_end").expect("__heap_end");
        assert_eq!(start % 8, 0);
        assert!(
            bytes.len() <= (end - start) as usize,
            "scenario of {} bytes does not fit the {} bytes of heap",
            bytes.len(),
            end - start
        );
        mem.write_bytes(start, bytes).unwrap();
    }
    cpu.set_instruction_limit(Some(4_000_000_000));
    let code = match cpu.run_until(
        &mut mem,
        &mut code,
        &mut NoDevices,
        sim_core::units::Picos::MAX,
    ) {
        StopReason::Exit { code } => code,
        other => panic!("{ELF}: unexpected stop {other:?} at pc {:#x}", cpu.pc()),
    };
    (code, console.text())
}

fn assert_passed(code: i32, out: &str) {
    let fails: Vec<&str> = out.lines().filter(|l| l.starts_with("FAIL")).collect();
    assert!(
        code == 0 && out.contains("0 failures: PASS"),
        "exit {code}, failures:\n{}",
        fails.join("\n")
    );
}

/// The first line starting with `prefix`, without it.
fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines()
        .find_map(|l| l.strip_prefix(prefix))
        .unwrap_or_else(|| panic!("no line {prefix:?} in:\n{out}"))
}

fn num<T: std::str::FromStr>(s: &str) -> T
where
    T::Err: std::fmt::Debug,
{
    s.trim_matches(|c: char| !c.is_ascii_digit() && c != '-')
        .parse()
        .unwrap_or_else(|e| panic!("{s:?}: {e:?}"))
}

#[test]
fn self_test_passes_and_reports_costs_and_ram() {
    let (code, out) = run(None);
    assert_passed(code, &out);

    // Eq. 5.11 over 625 exchanges with ±20 ppm clocks: within 2 ticks.
    let eq = line(&out, "eq. 5.11: ");
    let worst: f64 = num::<f64>(eq.split_whitespace().nth(4).unwrap());
    assert!(worst <= 2.0, "{eq}");
    assert!(out.contains("without the clock correction: every such exchange is rejected"));

    // §7.3: two drones in 1D placed from each other drift with σ = 0 and
    // stay put with σ = 0.25 (drift of the pair / std of one / distance
    // error, mm).
    let l = line(&out, "§7.3 1D pair, 20 s, ranging noise 3 cm: ");
    let triple = |tag: &str| -> Vec<i64> {
        let rest = l.split(tag).nth(1).unwrap();
        rest.split(|c: char| c == ',' || c.is_whitespace())
            .find(|w| w.contains('/'))
            .unwrap()
            .split('/')
            .map(num)
            .collect()
    };
    let (s25, s0) = (triple("σ=0.25 "), triple("σ=0 "));
    assert!(s25[0] < 100 && s0[0] > 5 * s25[0], "{l}");
    assert!(s0[1] > 3 * s25[1] && s25[2].abs() < 10, "{l}");

    // Every piece's cost is measured (mcycle) and plausible.
    for piece in [
        "eq. 5.11 swarm_exchange_tof",
        "kalman update (distance)",
        "float mul (soft)",
        "sqrtf (soft)",
    ] {
        let c: u64 = num(line(&out, &format!("cycles {piece}: mean ")));
        assert!(c > 0 && c < 100_000, "{piece}: {c}");
    }
    // The 17-drone scenario: each drone processes its 16 neighbours.
    let rx = line(&out, "swarm17: cycles swarm_on_rx: mean ");
    let mean: u64 = num(rx.split_whitespace().next().unwrap());
    assert!(mean > 1000 && mean < 1_000_000, "{rx}");

    // RAM of one drone's context with the seed's 16 neighbours, from the
    // ELF's symbol table: the same as the firmware's sizeof, and below the
    // seed's 10 408 bytes (Code Blocks 7.1-7.2: 88 560 - 78 152).
    let sizeof: usize = num(line(&out, "sizeof swarm_t ")
        .split_whitespace()
        .next()
        .unwrap());
    let bytes = std::fs::read(iss_util::firmware(ELF)).unwrap();
    let file = object::File::parse(&*bytes).unwrap();
    let sym = file
        .symbols()
        .find(|s| s.name() == Ok("swarm_ctx"))
        .expect("swarm_ctx");
    assert_eq!(sym.size() as usize, sizeof);
    assert!(sizeof < 10_408, "{sizeof} bytes");

    // The 100 Hz output line (docs/SWARM_FIRMWARE.md §5).
    let l = out
        .lines()
        .filter_map(|l| l.strip_prefix("tetra5: "))
        .rfind(|l| l.starts_with("swarm t=") && l.contains("frame=built"))
        .expect("an output line with the frame built");
    let f: Vec<&str> = l.split_whitespace().collect();
    assert_eq!(f[0], "swarm");
    let n: usize = num(f[4].strip_prefix("n=").unwrap());
    assert_eq!(n, 4);
    assert_eq!(f.len(), 5 + n + 1, "{l}");
    for node in &f[5..] {
        let (_, v) = node.split_once('=').unwrap();
        let parts: Vec<&str> = v.split(',').collect();
        assert_eq!(parts.len(), 5, "{node}");
        assert_eq!(parts[4], "s", "every node stable: {l}");
    }
}

/// A deterministic generator for the scenarios (splitmix64).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box-Muller).
    fn gauss(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

struct Scenario {
    positions: Vec<[f64; 3]>,
    clock_ppm: Vec<f64>,
    planar: bool,
    duration_s: f64,
    /// Transmissions per second of each drone (§6.5: 400 / drones).
    rate_hz: f64,
    loss: f64,
    /// σ of the ranging noise, as the world's `uwb_noise_m`.
    noise_m: f64,
    tof_bound_ticks: f64,
    pos_tol_m: f64,
    dist_tol_m: f64,
    seed: u64,
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The true TOF from i to j in i's ticks.
fn true_tof_ticks(s: &Scenario, i: usize, j: usize) -> f64 {
    dist(&s.positions[i], &s.positions[j]) / SPEED_OF_LIGHT
        * DW1000_TICKS_PER_SECOND
        * (1.0 + s.clock_ppm[i] * 1e-6)
}

/// The firmware's input: header and events, little endian.
fn build_input(s: &Scenario) -> Vec<u8> {
    let n = s.positions.len();
    assert!(n <= INPUT_DRONES);
    let mut rng = Rng(s.seed);
    // Phases anywhere in the wrap, as the world draws them; drone 0's
    // counter wraps one second into the run (§6.4.1).
    let wrap_ps = ((1u64 << 40) as f64 / DW1000_TICKS_PER_SECOND * 1e12) as u64;
    let mut phase: Vec<Picos> = (0..n).map(|_| Picos(rng.next() % wrap_ps)).collect();
    phase[0] = Picos(wrap_ps - 3_000_000_000_000);
    let ppt: Vec<i64> = s.clock_ppm.iter().map(|&p| ppm_to_ppt(p)).collect();
    // The world's warm-up ends at 2 s; each drone transmits uniformly in
    // [T/2, 3T/2) after its previous transmission.
    let start = 2_000_000_000_000u64;
    let period_ps = 1e12 / s.rate_hz;
    let mut next: Vec<u64> = (0..n)
        .map(|_| start + (rng.uniform() * period_ps) as u64)
        .collect();
    let end = start + (s.duration_s * 1e12) as u64;
    let mut events = Vec::new();
    loop {
        let d = (0..n).min_by_key(|&i| (next[i], i)).unwrap();
        let t = next[d];
        if t >= end {
            break;
        }
        let mut ev = Vec::with_capacity(INPUT_EVENT_BYTES);
        ev.extend_from_slice(&(d as u32).to_le_bytes());
        ev.extend_from_slice(&((t / 1_000_000) as u32).to_le_bytes());
        ev.extend_from_slice(&dw1000_stamp(Picos(t), ppt[d], phase[d]).0.to_le_bytes());
        let mut lost = 0u32;
        for q in 0..INPUT_DRONES {
            let stamp = if q < n && q != d {
                let flight = dist(&s.positions[d], &s.positions[q]) / SPEED_OF_LIGHT
                    + s.noise_m / SPEED_OF_LIGHT * rng.gauss();
                if rng.uniform() < s.loss {
                    lost |= 1 << q;
                }
                dw1000_stamp(Picos(t + (flight * 1e12).round() as u64), ppt[q], phase[q]).0
            } else {
                0
            };
            ev.extend_from_slice(&stamp.to_le_bytes());
        }
        ev.extend_from_slice(&lost.to_le_bytes());
        ev.extend_from_slice(&0u32.to_le_bytes());
        assert_eq!(ev.len(), INPUT_EVENT_BYTES);
        events.push(ev);
        next[d] = t + ((0.5 + rng.uniform()) * period_ps) as u64;
    }
    let mut b = Vec::with_capacity(INPUT_HEADER_BYTES + events.len() * INPUT_EVENT_BYTES);
    for v in [
        INPUT_MAGIC,
        1,
        n as u32,
        events.len() as u32,
        s.planar as u32,
        (s.tof_bound_ticks * 1000.0) as u32,
        (s.pos_tol_m * 1000.0) as u32,
        (s.dist_tol_m * 1000.0) as u32,
    ] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for i in 0..INPUT_DRONES {
        // EUIs as cosim gives them: 1, 2, 3, ...
        b.extend_from_slice(&(i as u64 + 1).to_le_bytes());
    }
    for i in 0..INPUT_DRONES {
        for k in 0..3 {
            let mm = if i < n {
                (s.positions[i][k] * 1000.0).round() as i32
            } else {
                0
            };
            b.extend_from_slice(&mm.to_le_bytes());
        }
    }
    for i in 0..INPUT_DRONES {
        for j in 0..INPUT_DRONES {
            let t = if i < n && j < n && i != j {
                (true_tof_ticks(s, i, j) * 1000.0).round() as u32
            } else {
                0
            };
            b.extend_from_slice(&t.to_le_bytes());
        }
    }
    assert_eq!(b.len(), INPUT_HEADER_BYTES);
    for ev in events {
        b.extend_from_slice(&ev);
    }
    b
}

fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn scale(a: &[f64; 3], k: f64) -> [f64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Coordinates of every drone in the seed's frame (§5.3.2) built on the
/// drones `frame` (origin, +X, XY plane with +Y, +Z side).
fn seed_frame(pos: &[[f64; 3]], frame: &[usize], planar: bool) -> Vec<[f64; 3]> {
    let o = pos[frame[0]];
    let x = sub(&pos[frame[1]], &o);
    let ex = scale(&x, 1.0 / dot(&x, &x).sqrt());
    let v = sub(&pos[frame[2]], &o);
    let y = sub(&v, &scale(&ex, dot(&v, &ex)));
    let ey = scale(&y, 1.0 / dot(&y, &y).sqrt());
    let mut ez = cross(&ex, &ey);
    if !planar && dot(&sub(&pos[frame[3]], &o), &ez) < 0.0 {
        ez = scale(&ez, -1.0);
    }
    pos.iter()
        .map(|p| {
            let v = sub(p, &o);
            [dot(&v, &ex), dot(&v, &ey), dot(&v, &ez)]
        })
        .collect()
}

fn check_scenario(s: &Scenario) {
    let input = build_input(s);
    let (code, out) = run(Some(&input));
    if let Ok(path) = std::env::var("SWARM_FIRMWARE_DUMP") {
        std::fs::write(path, &out).unwrap();
    }
    assert_passed(code, &out);
    let n = s.positions.len();
    let mut worst_tof: f64 = 0.0;
    let mut worst_pos: f64 = 0.0;
    for i in 0..n {
        // TOFs the drone measured itself (eq. 5.11), against closed form.
        for j in (0..n).filter(|&j| j != i) {
            let l = line(&out, &format!("input: tof {i} {j} "));
            let got: f64 = num(l.split_whitespace().next().unwrap());
            let err = (got - true_tof_ticks(s, i, j)).abs();
            assert!(err <= s.tof_bound_ticks, "tof {i}-{j}: {l}");
            worst_tof = worst_tof.max(err);
        }
        // Its frame: the references it chose, completed by itself when
        // the swarm is too small (the thesis's three-drone table).
        let l = line(&out, &format!("input: drone {i} id "));
        let mut frame: Vec<usize> = l
            .split(" refs ")
            .nth(1)
            .unwrap()
            .split_whitespace()
            .map(num)
            .collect();
        let need = if s.planar { 3 } else { 4 };
        if frame.len() < need {
            frame.push(i);
        }
        assert_eq!(frame.len(), need, "{l}");
        let want = seed_frame(&s.positions, &frame, s.planar);
        for (j, w) in want.iter().enumerate() {
            let l = line(&out, &format!("input: pos {i} {j} "));
            let est: Vec<f64> = l
                .split_whitespace()
                .next()
                .unwrap()
                .split(',')
                .map(|v| num::<f64>(v) / 1000.0)
                .collect();
            let err = dist(&[est[0], est[1], est[2]], w);
            assert!(
                err <= s.pos_tol_m && l.ends_with("stable"),
                "drone {i}'s estimate of {j}: {l}; want {w:?}"
            );
            worst_pos = worst_pos.max(err);
        }
    }
    eprintln!(
        "{} drones, {} events: worst TOF error {worst_tof:.2} ticks, worst position error {:.0} mm",
        n,
        (input.len() - INPUT_HEADER_BYTES) / INPUT_EVENT_BYTES,
        worst_pos * 1000.0
    );
}

/// Eq. 5.11 on the world's stamps: five drones in 3D, ±20 ppm clocks, 10 %
/// of the frames lost, no ranging noise: every TOF within 2 ticks
/// (9.4 mm), every position within 3 cm of the seed's frame.
#[test]
fn world_stamps_give_tick_level_tofs_and_the_seed_frame() {
    check_scenario(&Scenario {
        positions: vec![
            [0.3, 0.2, 0.1],
            [2.8, 0.5, 0.3],
            [1.2, 3.1, 0.2],
            [1.5, 1.4, 2.6],
            [3.5, 3.0, 1.6],
        ],
        clock_ppm: vec![20.0, -20.0, 13.5, -7.25, 0.0],
        planar: false,
        duration_s: 3.0,
        rate_hz: 80.0,
        loss: 0.1,
        noise_m: 0.0,
        tof_bound_ticks: 2.0,
        pos_tol_m: 0.03,
        dist_tol_m: 0.03,
        seed: 3,
    });
}

/// With the world's ranging noise (σ 5 cm) the Kalman filters (σ 0.25,
/// §7.3) still place the swarm within 25 cm of the seed's frame and its
/// inter-drone distances within 15 cm. (The weakest coordinate is that of
/// a drone 10 cm from its frame's XY plane, known only through the 2 mm
/// that distances change between it and its mirror image.)
#[test]
fn noisy_ranging_converges_with_the_seed_sigma() {
    check_scenario(&Scenario {
        positions: vec![
            [0.3, 0.2, 0.1],
            [2.8, 0.5, 0.3],
            [1.2, 3.1, 0.2],
            [1.5, 1.4, 2.6],
            [3.5, 3.0, 1.6],
            [2.0, 2.0, 1.0],
        ],
        clock_ppm: vec![20.0, -20.0, 13.5, -7.25, 0.0, 4.0],
        planar: false,
        duration_s: 3.0,
        rate_hz: 400.0 / 6.0,
        loss: 0.1,
        noise_m: 0.05,
        // One TOF has the noise of two arrivals / 2: σ ≈ 7.5 ticks.
        tof_bound_ticks: 40.0,
        pos_tol_m: 0.25,
        dist_tol_m: 0.15,
        seed: 7,
    });
}

/// The thesis's table (§7.1, location 2): B at (0, 0), C at (1, 0) and A at
/// (0.5, 0.25), in 2D, ranging noise 3 cm.
#[test]
fn the_thesis_table_in_2d() {
    check_scenario(&Scenario {
        positions: vec![[0.5, 0.25, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        clock_ppm: vec![10.0, -15.0, 5.0],
        planar: true,
        duration_s: 3.0,
        rate_hz: 100.0,
        loss: 0.1,
        noise_m: 0.03,
        tof_bound_ticks: 30.0,
        pos_tol_m: 0.1,
        dist_tol_m: 0.1,
        seed: 71,
    });
}
