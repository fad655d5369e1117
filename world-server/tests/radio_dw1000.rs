//! The "dw1000" UWB profile (DESIGN.md §16) against closed form: per-chip
//! antenna delays bias an SDS-TWR range by (δ_A + δ_B)·c/2, with δ a chip's
//! TX plus RX delay beyond the nominal the firmware subtracts; NLOS only
//! when the direct path crosses a box or a drone's body; the reception edge
//! near the range limit; "ideal" keeps the stamps of DESIGN.md §8.

use protocol::radio::{Dw1000Ticks, Picos, Radio, DW1000_TICKS_PER_SECOND};
use world_server::radio::geometry::Obstacle;
use world_server::radio::profile::{Profile, FIRMWARE_ANTENNA_DELAY_TICKS, NOMINAL_PATH_DELAY_PS};
use world_server::radio::{Channel, DroneRadio, RadioConfig, SPEED_OF_LIGHT_M_S};

const MS: u64 = Picos::PER_MS;

fn drones(n: usize) -> Vec<DroneRadio> {
    (0..n)
        .map(|i| DroneRadio {
            name: format!("d{i}"),
            clock_ppm: 0.0,
            radios: vec![Radio::Uwb],
        })
        .collect()
}

fn dw1000(seed: u64) -> RadioConfig {
    RadioConfig {
        seed,
        uwb_noise_m: 0.0,
        profile: Profile::Dw1000,
        uwb_nlos_bias_m: Some(0.0),
        uwb_nlos_sd_m: Some(0.0),
        ..RadioConfig::default()
    }
}

/// One SDS-TWR exchange between drones 0 and 1 (poll, response, final as in
/// seed 003 eq. 5.11 with equal clocks): the TOF in ticks minus the
/// firmware's one constant, as swarm_exchange_tof computes it.
fn twr_tof_ticks(ch: &mut Channel, pos: &dyn Fn(usize, Picos) -> [f64; 3]) -> f64 {
    let a1 = Picos(2_000 * MS);
    let b1 = Picos(2_010 * MS + 123_457);
    ch.send(0, Radio::Uwb, vec![1; 20], a1).unwrap();
    ch.send(1, Radio::Uwb, vec![2; 20], b1).unwrap();
    ch.resolve(Picos(2_030 * MS), pos);
    let (at_a, tx_a) = ch.take(0, Picos(2_030 * MS));
    let (at_b, tx_b) = ch.take(1, Picos(2_030 * MS));
    let st = |v: Option<u64>| Dw1000Ticks(v.unwrap());
    let round = st(at_a[0].rx_stamp).since(st(tx_a[0].tx_stamp)) as f64;
    let reply = st(tx_b[0].tx_stamp).since(st(at_b[0].rx_stamp)) as f64;
    (round - reply) / 2.0 - FIRMWARE_ANTENNA_DELAY_TICKS as f64
}

#[test]
fn antenna_delays_bias_the_range_by_half_their_excess_times_c() {
    let pos = |d: usize, _| [d as f64 * 2.0, 0.0, 0.5];
    let mut biases = Vec::new();
    for seed in 0..20 {
        let mut ch = Channel::new(dw1000(seed), drones(2));
        let tof = twr_tof_ticks(&mut ch, &pos);
        let excess = |d: usize| {
            let (tx, rx) = ch.antenna_delays(d).unwrap();
            (tx + rx) as f64 - 2.0 * NOMINAL_PATH_DELAY_PS
        };
        // (δ_A + δ_B)·c/2, δ in ps.
        let bias_m = (excess(0) + excess(1)) * 1e-12 * SPEED_OF_LIGHT_M_S / 2.0;
        let range_m = tof / DW1000_TICKS_PER_SECOND * SPEED_OF_LIGHT_M_S;
        // Stamps are whole ticks (15.65 ps = 4.7 mm each, two per side).
        assert!(
            (range_m - (2.0 + bias_m)).abs() < 0.01,
            "seed {seed}: {range_m} m vs 2 + {bias_m}"
        );
        biases.push(bias_m);
    }
    // σ 250 ps per path: a pair's bias is Gaussian with σ 7.5 cm.
    let sd = (biases.iter().map(|b| b * b).sum::<f64>() / biases.len() as f64).sqrt();
    assert!((0.03..0.15).contains(&sd), "spread of the biases {sd} m");
    assert!(biases.iter().all(|b| b.abs() < 0.35), "{biases:?}");
}

#[test]
fn ideal_stamps_carry_no_antenna_delay() {
    let cfg = RadioConfig {
        seed: 3,
        uwb_noise_m: 0.0,
        ..RadioConfig::default()
    };
    let mut ch = Channel::new(cfg, drones(2));
    assert_eq!(ch.antenna_delays(0), Some((0, 0)));
    let tof = twr_tof_ticks(&mut ch, &|d, _| [d as f64 * 2.0, 0.0, 0.5])
        + FIRMWARE_ANTENNA_DELAY_TICKS as f64;
    let range_m = tof / DW1000_TICKS_PER_SECOND * SPEED_OF_LIGHT_M_S;
    assert!((range_m - 2.0).abs() < 0.01, "{range_m}");
}

/// The range 0 → 1 of one exchange with a third drone or a box placed.
fn range_with(cfg: RadioConfig, third: [f64; 3], boxes: Vec<Obstacle>) -> f64 {
    let mut ch = Channel::new(cfg, drones(3)).with_obstacles(boxes);
    let pos = move |d: usize, _| match d {
        0 => [0.0, 0.0, 1.0],
        1 => [3.0, 0.0, 1.0],
        _ => third,
    };
    let tof = twr_tof_ticks(&mut ch, &pos);
    tof / DW1000_TICKS_PER_SECOND * SPEED_OF_LIGHT_M_S
}

#[test]
fn nlos_only_when_the_path_crosses_a_body() {
    let cfg = RadioConfig {
        uwb_antenna_delay_sd_ps: Some(0.0),
        uwb_nlos_bias_m: Some(0.3),
        uwb_nlos_sd_m: Some(0.0),
        ..dw1000(5)
    };
    let clear = range_with(cfg.clone(), [1.5, 0.2, 1.0], vec![]);
    assert!((clear - 3.0).abs() < 0.01, "line of sight: {clear}");
    // A drone in the middle: both frames cross it, each stamped 0.3 m late.
    let drone = range_with(cfg.clone(), [1.5, 0.0, 1.0], vec![]);
    assert!((drone - 3.3).abs() < 0.01, "through a drone: {drone}");
    // A box in the way; the same box beside the path changes nothing.
    let wall = |y: f64| Obstacle {
        centre: [1.5, y, 1.0],
        size: [0.2, 1.0, 2.0],
        yaw: 0.0,
    };
    let far = [1.5, 5.0, 1.0];
    let boxed = range_with(cfg.clone(), far, vec![wall(0.0)]);
    assert!((boxed - 3.3).abs() < 0.01, "through a box: {boxed}");
    let beside = range_with(cfg, far, vec![wall(1.0)]);
    assert!((beside - 3.0).abs() < 0.01, "beside a box: {beside}");
}

#[test]
fn reception_fades_out_near_the_range_limit() {
    // Share received of 400 frames at a distance, "dw1000" edge σ 3 dB about
    // the power at 10 m: Φ(20·log10(10/d) / 3).
    let share = |d: f64| {
        let mut ch = Channel::new(dw1000(9), drones(2));
        let pos = move |i: usize, _| [i as f64 * d, 0.0, 0.5];
        for k in 0..400u64 {
            ch.send(0, Radio::Uwb, vec![1; 10], Picos(2_000 * MS + k * MS))
                .unwrap();
        }
        ch.resolve(Picos(2_500 * MS), &pos);
        ch.take(1, Picos(2_500 * MS)).0.len() as f64 / 400.0
    };
    let near = share(5.0);
    assert!(
        (near - 0.977).abs() < 0.03,
        "6 dB above the edge: Φ(2) = 97.7 %, got {near}"
    );
    let at_limit = share(10.0);
    assert!((at_limit - 0.5).abs() < 0.08, "{at_limit}");
    let beyond = share(14.0);
    // 20·log10(10/14) = −2.92 dB: Φ(−0.974) = 16.5 %
    assert!((beyond - 0.165).abs() < 0.06, "{beyond}");
    assert_eq!(share(40.0), 0.0, "12 dB (4 σ) below: not even heard");
}
