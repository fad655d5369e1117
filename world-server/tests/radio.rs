//! The radio channel (DESIGN.md §8, docs/SWARM.md §3) against closed-form
//! results: DW1000 stamps, flight times, SDS-TWR of seed 003 (eq. 5.11),
//! collisions, half duplex, range, loss and RSSI statistics, determinism, and
//! the fit of the P2P RSSI model to seed 004's Table 7.

use std::io::Write;
use std::sync::{Arc, Mutex};

use protocol::radio::{Picos, Radio, DW1000_STAMP_MASK};
use protocol::{RadioPacket, TxDone};
use world_server::radio::{
    log_distance, Channel, ChannelError, DroneRadio, RadioConfig, SPEED_OF_LIGHT_M_S,
};

const MS: u64 = Picos::PER_MS;

fn drone(name: &str, clock_ppm: f64) -> DroneRadio {
    DroneRadio {
        name: name.into(),
        clock_ppm,
        radios: vec![Radio::Uwb, Radio::P2p],
    }
}

fn exact() -> RadioConfig {
    RadioConfig {
        seed: 1,
        uwb_noise_m: 0.0,
        p2p_rssi_noise_db: 0.0,
        ..RadioConfig::default()
    }
}

/// Fixed positions along x.
fn line(xs: Vec<f64>) -> impl Fn(usize, Picos) -> [f64; 3] {
    move |d, _| [xs[d], 0.0, 0.5]
}

/// A log the test can read back.
#[derive(Clone, Default)]
struct SharedBuf(Arc<Mutex<Vec<u8>>>);
impl Write for SharedBuf {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}
impl SharedBuf {
    fn text(&self) -> String {
        String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
    }
    /// (from, to, outcome) of every row.
    fn outcomes(&self) -> Vec<(String, String, String)> {
        let text = self.text();
        let mut r = csv::Reader::from_reader(text.as_bytes());
        r.records()
            .map(|rec| {
                let rec = rec.unwrap();
                (rec[3].to_string(), rec[4].to_string(), rec[7].to_string())
            })
            .collect()
    }
}

fn tick_ps() -> f64 {
    1e12 / protocol::radio::DW1000_TICKS_PER_SECOND
}

// ---------------------------------------------------------------- stamps ---

/// DESIGN.md §8 written independently with integer ppm:
/// floor((t·(1e6 + ppm)/1e6 + phase) / tick) mod 2^40, tick = 1e6/63 897.6 ps.
fn stamp_formula(t: u64, ppm: i64, phase: u64) -> u64 {
    let local_ps_e6 = t as i128 * (1_000_000 + ppm as i128) + phase as i128 * 1_000_000;
    let ticks = local_ps_e6 * 638_976 / (1_000_000i128 * 10_000_000);
    (ticks as u64) & DW1000_STAMP_MASK
}

#[test]
fn stamps_follow_the_design_formula_with_wrap_and_20_ppm_clocks() {
    let ch = Channel::new(
        exact(),
        vec![drone("A", 20.0), drone("B", -20.0), drone("C", 0.0)],
    );
    for d in 0..3 {
        let ppm = [20, -20, 0][d];
        let phase = ch.phase(d).unwrap().0;
        for t in [
            0u64,
            1,
            15_650,
            2_000 * MS,
            17_207 * MS,
            40_000 * MS + 123_456,
        ] {
            let s = ch.stamp(d, Picos(t)).0;
            assert_eq!(s, stamp_formula(t, ppm, phase), "drone {d} t {t}");
            // and within one tick of the same formula in floating point
            let f = ((t as f64 * (1.0 + ppm as f64 * 1e-6) + phase as f64) / tick_ps()).floor()
                % 2f64.powi(40);
            assert!((s as f64 - f).abs() <= 1.0, "drone {d} t {t}: {s} vs {f}");
        }
    }
    // Across the 40-bit wrap: find the world time where drone A's clock wraps
    // and check that `since` still gives the elapsed ticks of its clock.
    let phase = ch.phase(0).unwrap().0 as f64;
    let wrap_local_ps = 2f64.powi(40) * tick_ps();
    let t_wrap = ((wrap_local_ps - phase) / (1.0 + 20e-6)) as u64;
    let before = ch.stamp(0, Picos(t_wrap - MS));
    let after = ch.stamp(0, Picos(t_wrap + MS));
    assert!(
        after.0 < before.0,
        "the clock wrapped: {before:?} {after:?}"
    );
    // 2 ms of a +20 ppm clock: 2e-3 · 63.8976e9 · (1 + 20e-6) ticks
    let expect = 2e-3 * protocol::radio::DW1000_TICKS_PER_SECOND * (1.0 + 20e-6);
    assert!((after.since(before) as f64 - expect).abs() <= 1.0);
}

#[test]
fn a_frame_over_3_m_takes_3_over_c_on_the_receivers_clock() {
    let mut ch = Channel::new(exact(), vec![drone("A", 20.0), drone("B", -20.0)]);
    let start = Picos(2_000 * MS + 123_456_789);
    ch.send(0, Radio::Uwb, vec![7; 20], start).unwrap();
    ch.resolve(Picos(2_010 * MS), &line(vec![0.0, 3.0]));
    let (p, _) = ch.take(1, Picos(2_010 * MS));
    assert_eq!(p.len(), 1);
    let p = &p[0];
    let tof_ps = 3.0 / SPEED_OF_LIGHT_M_S * 1e12; // 10 006.9 ps
    assert_eq!(
        p.time_ps,
        start.0 + tof_ps.round() as u64 + Radio::Uwb.airtime(20).0
    );
    assert_eq!(p.from, "A");
    assert_eq!(p.data, vec![7; 20]);
    // B's clock over the flight: rx_stamp − stamp_B(start) = 3/c·(1 − 20 ppm)
    let rx = protocol::radio::Dw1000Ticks(p.rx_stamp.unwrap());
    let ticks = rx.since(ch.stamp(1, start)) as f64;
    let expect = tof_ps * (1.0 - 20e-6) / tick_ps(); // ≈ 639.4 ticks
    assert!((ticks - expect).abs() <= 1.0, "{ticks} vs {expect}");
    // and the sender's TX-done carries stamp_A(start)
    let (_, tx) = ch.take(0, Picos(2_010 * MS));
    assert_eq!(
        tx,
        vec![TxDone {
            radio: Radio::Uwb,
            time_ps: start.0 + Radio::Uwb.airtime(20).0,
            tx_stamp: Some(ch.stamp(0, start).0),
        }]
    );
}

/// Seed 003 §5.2, eq. 5.11: M computes the ToF to X from its own stamps and
/// X's, with X's clock ratio from two of X's frames; ±20 ppm clocks, 3 m.
#[test]
fn sds_twr_of_seed_003_recovers_the_flight_time() {
    let mut ch = Channel::new(exact(), vec![drone("M", 20.0), drone("X", -20.0)]);
    let pos = line(vec![0.0, 3.0]);
    let len = 30;
    let x1 = Picos(2_000 * MS);
    let m1 = Picos(2_010 * MS + 777_777);
    let x2 = Picos(2_020 * MS + 31_415);
    ch.send(1, Radio::Uwb, vec![1; len], x1).unwrap();
    ch.send(0, Radio::Uwb, vec![2; len], m1).unwrap();
    ch.send(1, Radio::Uwb, vec![3; len], x2).unwrap();
    ch.resolve(Picos(2_030 * MS), &pos);
    let (at_m, tx_m) = ch.take(0, Picos(2_030 * MS));
    let (at_x, tx_x) = ch.take(1, Picos(2_030 * MS));
    let st = |v: Option<u64>| protocol::radio::Dw1000Ticks(v.unwrap());
    let (rx_m_x1, rx_m_x2) = (st(at_m[0].rx_stamp), st(at_m[1].rx_stamp));
    let rx_x_m1 = st(at_x[0].rx_stamp);
    let tx_m1 = st(tx_m[0].tx_stamp);
    let (tx_x1, tx_x2) = (st(tx_x[0].tx_stamp), st(tx_x[1].tx_stamp));
    let round_m = rx_m_x2.since(tx_m1) as f64;
    let reply_x = tx_x2.since(rx_x_m1) as f64;
    let since_last_m = rx_m_x2.since(rx_m_x1) as f64;
    let since_last_x = tx_x2.since(tx_x1) as f64;
    let tof_m = (round_m - reply_x * since_last_m / since_last_x) / 2.0;
    let expect =
        3.0 / SPEED_OF_LIGHT_M_S * protocol::radio::DW1000_TICKS_PER_SECOND * (1.0 + 20e-6);
    assert!((tof_m - expect).abs() < 2.0, "{tof_m} vs {expect} ticks");
}

// ----------------------------------------------------- losses on the air ---

#[test]
fn overlapping_frames_collide_where_both_are_heard_only() {
    // S1 at 0, S2 at 10 (in range of each other: 10 m ≤ 10 m), R at 5 hears
    // both, R2 at -4 hears S1 only (14 m from S2 > 10 m).
    let mut ch = Channel::new(
        exact(),
        vec![
            drone("S1", 0.0),
            drone("S2", 0.0),
            drone("R", 0.0),
            drone("R2", 0.0),
        ],
    );
    let log = SharedBuf::default();
    ch.set_log(Box::new(log.clone()));
    let t = Picos(2_000 * MS);
    ch.send(0, Radio::Uwb, vec![1; 20], t).unwrap();
    ch.send(1, Radio::Uwb, vec![2; 20], t + Picos(50_000_000))
        .unwrap(); // 50 µs later
    ch.resolve(Picos(2_001 * MS), &line(vec![0.0, 10.0, 5.0, -4.0]));
    ch.flush_log().unwrap();
    assert!(ch.take(2, Picos(2_001 * MS)).0.is_empty(), "R: both lost");
    let r2 = ch.take(3, Picos(2_001 * MS)).0;
    assert_eq!(r2.len(), 1);
    assert_eq!(r2[0].from, "S1");
    let o = log.outcomes();
    let find = |f: &str, t: &str| {
        o.iter()
            .find(|(a, b, _)| a == f && b == t)
            .unwrap()
            .2
            .clone()
    };
    assert_eq!(find("S1", "R"), "collision");
    assert_eq!(find("S2", "R"), "collision");
    assert_eq!(find("S1", "R2"), "received");
    assert_eq!(find("S2", "R2"), "out_of_range");
    assert_eq!(find("S1", "S2"), "half_duplex");
    assert_eq!(find("S2", "S1"), "half_duplex");
    assert_eq!(o.len(), 6);
}

#[test]
fn a_drone_that_transmits_hears_nothing_on_that_radio() {
    let mut ch = Channel::new(exact(), vec![drone("A", 0.0), drone("B", 0.0)]);
    let t = Picos(2_000 * MS);
    let air = Radio::Uwb.airtime(20);
    // B's frame arrives at A while A's own frame is still leaving (A's ends
    // 1 ns after B's starts): A hears nothing, B hears nothing either.
    ch.send(0, Radio::Uwb, vec![1; 20], t).unwrap();
    ch.send(1, Radio::Uwb, vec![2; 20], Picos(t.0 + air.0 - 1_000))
        .unwrap();
    // A p2p packet during A's uwb transmission is heard (another radio).
    ch.send(1, Radio::P2p, vec![3; 10], t).unwrap();
    ch.resolve(Picos(2_002 * MS), &line(vec![0.0, 0.0]));
    let (a, _) = ch.take(0, Picos(2_002 * MS));
    let (b, _) = ch.take(1, Picos(2_002 * MS));
    assert_eq!(a.len(), 1, "{a:?}");
    assert_eq!(a[0].radio, Radio::P2p);
    assert!(b.is_empty(), "{b:?}");
}

#[test]
fn frames_beyond_range_or_below_sensitivity_are_not_received() {
    let cfg = RadioConfig {
        p2p_rssi_1m_dbm: -40.0,
        p2p_path_loss_exp: 2.0,
        p2p_sensitivity_dbm: -85.0, // reached at 10^(45/20) = 177.8 m
        ..exact()
    };
    let mut ch = Channel::new(cfg, vec![drone("A", 0.0), drone("B", 0.0), drone("C", 0.0)]);
    let t = Picos(2_000 * MS);
    ch.send(0, Radio::Uwb, vec![1; 20], t).unwrap();
    ch.send(0, Radio::P2p, vec![1; 20], t + Picos(MS)).unwrap();
    ch.resolve(Picos(2_010 * MS), &line(vec![0.0, 9.99, 10.01]));
    assert_eq!(ch.take(1, Picos(2_010 * MS)).0.len(), 2);
    let c = ch.take(2, Picos(2_010 * MS)).0;
    assert_eq!(c.len(), 1, "uwb beyond 10 m");
    assert_eq!(c[0].radio, Radio::P2p);
    ch.send(0, Radio::P2p, vec![1; 20], Picos(2_020 * MS))
        .unwrap();
    ch.resolve(Picos(2_030 * MS), &line(vec![0.0, 170.0, 180.0]));
    let b = ch.take(1, Picos(2_030 * MS)).0;
    assert_eq!(b.len(), 1);
    assert!((b[0].rssi - log_distance(-40.0, 2.0, 170.0)).abs() < 1e-9);
    assert!(ch.take(2, Picos(2_030 * MS)).0.is_empty(), "below -85 dBm");
}

#[test]
fn the_loss_probability_loses_that_fraction() {
    let cfg = RadioConfig {
        uwb_loss: 0.3,
        p2p_loss: 0.1,
        ..exact()
    };
    let mut ch = Channel::new(cfg, vec![drone("A", 0.0), drone("B", 0.0)]);
    let n = 4000;
    for k in 0..n {
        ch.send(0, Radio::Uwb, vec![0; 8], Picos((2_000 + k) * MS))
            .unwrap();
        ch.send(0, Radio::P2p, vec![0; 8], Picos((2_000 + k) * MS + MS / 2))
            .unwrap();
    }
    ch.resolve(Picos((2_001 + n) * MS), &line(vec![0.0, 2.0]));
    let (p, _) = ch.take(1, Picos((2_001 + n) * MS));
    for (radio, loss) in [(Radio::Uwb, 0.3), (Radio::P2p, 0.1)] {
        let got = p.iter().filter(|x| x.radio == radio).count() as f64 / n as f64;
        let sigma = (loss * (1.0 - loss) / n as f64).sqrt();
        assert!(
            (got - (1.0 - loss)).abs() < 4.0 * sigma,
            "{radio}: received {got}, expected {}",
            1.0 - loss
        );
    }
}

#[test]
fn rssi_and_ranging_noise_have_the_configured_mean_and_sigma() {
    let cfg = RadioConfig {
        p2p_rssi_1m_dbm: -50.0,
        p2p_path_loss_exp: 2.5,
        p2p_rssi_noise_db: 4.0,
        uwb_noise_m: 0.1,
        ..exact()
    };
    let mut ch = Channel::new(cfg, vec![drone("A", 0.0), drone("B", 0.0)]);
    let n = 3000u64;
    let start = |k: u64| Picos((2_000 + k) * MS + 12_345);
    for k in 0..n {
        ch.send(0, Radio::P2p, vec![0; 4], start(k)).unwrap();
        ch.send(0, Radio::Uwb, vec![0; 4], start(k) + Picos(MS / 2))
            .unwrap();
    }
    ch.resolve(Picos((2_001 + n) * MS), &line(vec![0.0, 2.0]));
    let (p, _) = ch.take(1, Picos((2_001 + n) * MS));
    let stats = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
        (m, s)
    };
    let rssi: Vec<f64> = p
        .iter()
        .filter(|x| x.radio == Radio::P2p)
        .map(|x| x.rssi)
        .collect();
    assert_eq!(rssi.len(), n as usize);
    let (m, s) = stats(&rssi);
    let expect = -50.0 - 25.0 * 2f64.log10(); // -57.53 dBm
    assert!((m - expect).abs() < 4.0 * 4.0 / (n as f64).sqrt(), "{m}");
    assert!((s - 4.0).abs() < 0.25, "{s}");
    // ranging error in metres: (rx_stamp − stamp_B(start)) ticks · tick · c − 2 m
    let err: Vec<f64> = p
        .iter()
        .filter(|x| x.radio == Radio::Uwb)
        .enumerate()
        .map(|(k, x)| {
            let t0 = ch.stamp(1, start(k as u64) + Picos(MS / 2));
            let ticks = protocol::radio::Dw1000Ticks(x.rx_stamp.unwrap()).since(t0) as f64;
            ticks * tick_ps() * 1e-12 * SPEED_OF_LIGHT_M_S - 2.0
        })
        .collect();
    let (m, s) = stats(&err);
    // the stamp's floor costs half a tick (2.3 mm) on average
    assert!(
        (m + 0.5 * tick_ps() * 1e-12 * SPEED_OF_LIGHT_M_S).abs() < 0.01,
        "{m}"
    );
    assert!((s - 0.1).abs() < 0.008, "{s}");
}

// ---------------------------------------------------- reports and order ---

type Reports = Vec<(usize, Vec<RadioPacket>, Vec<TxDone>)>;

/// Three moving drones sending on both radios at seeded random times; the
/// channel is driven in `step` ms steps (resolve then take for every drone),
/// with the sends of one instant made in `drone_order`.
fn busy_run(step: u64, drone_order: [usize; 3]) -> (Reports, String) {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    // per drone, sends (start, radio, len) in its own order
    let mut sends: Vec<Vec<(u64, Radio, usize)>> = vec![Vec::new(); 3];
    for (d, s) in sends.iter_mut().enumerate() {
        let mut t = 2_000 * MS + d as u64 * 1_000;
        while t < 2_300 * MS {
            let radio = if rng.random_bool(0.5) {
                Radio::Uwb
            } else {
                Radio::P2p
            };
            let len = rng.random_range(1..=radio.max_payload());
            s.push((t, radio, len));
            t += rng.random_range(100_000..3 * MS); // 0.1–3 ms apart: some overlap
        }
    }
    let cfg = RadioConfig {
        seed: 5,
        uwb_loss: 0.1,
        p2p_loss: 0.05,
        ..RadioConfig::default()
    };
    let mut ch = Channel::new(
        cfg,
        vec![drone("A", 10.0), drone("B", -5.0), drone("C", 1.5)],
    );
    let log = SharedBuf::default();
    ch.set_log(Box::new(log.clone()));
    let pos = |d: usize, t: Picos| {
        let s = t.0 as f64 * 1e-12;
        [d as f64 * 2.0 + 0.5 * s.sin(), 0.3 * d as f64 * s, 1.0]
    };
    let mut next = [0usize; 3];
    let mut reports = Vec::new();
    let mut now = 2_000 * MS;
    while now < 2_310 * MS {
        let until = now + step * MS;
        // sends made at this step: those starting before `until`
        for &d in &drone_order {
            while let Some(&(t, radio, len)) = sends[d].get(next[d]) {
                if t >= until {
                    break;
                }
                ch.send(d, radio, vec![d as u8; len], Picos(t)).unwrap();
                next[d] += 1;
            }
        }
        ch.resolve(Picos(until), &pos);
        for d in 0..3 {
            let (p, t) = ch.take(d, Picos(until));
            if !p.is_empty() || !t.is_empty() {
                reports.push((d, p, t));
            }
        }
        now = until;
    }
    ch.flush_log().unwrap();
    (reports, log.text())
}

fn flatten(r: &Reports) -> Vec<Vec<String>> {
    let mut per = vec![Vec::new(); 3];
    for (d, p, t) in r {
        per[*d].extend(p.iter().map(|x| format!("{x:?}")));
        per[*d].extend(t.iter().map(|x| format!("{x:?}")));
    }
    per
}

#[test]
fn results_do_not_depend_on_step_size_or_call_order() {
    let (fine, log_fine) = busy_run(1, [0, 1, 2]);
    let (coarse, log_coarse) = busy_run(400, [2, 0, 1]);
    let (mid, log_mid) = busy_run(7, [1, 2, 0]);
    // the packets of each drone are the same (taken at other times)
    let received: usize = fine.iter().map(|(_, p, _)| p.len()).sum();
    assert!(received > 100, "a busy channel: {received} receptions");
    let sorted = |r: &Reports| {
        let mut per = flatten(r);
        per.iter_mut().for_each(|v| v.sort());
        per
    };
    assert_eq!(sorted(&fine), sorted(&coarse));
    assert_eq!(sorted(&fine), sorted(&mid));
    // the log is byte for byte the same
    assert_eq!(log_fine, log_coarse);
    assert_eq!(log_fine, log_mid);
    for o in ["received", "collision", "half_duplex", "lost"] {
        assert!(log_fine.contains(o), "some {o} in a busy channel");
    }
}

#[test]
fn reports_come_once_in_end_order_with_tx_done() {
    let (reports, _) = busy_run(1, [0, 1, 2]);
    for d in 0..3 {
        let packets: Vec<&RadioPacket> = reports
            .iter()
            .filter(|(q, _, _)| *q == d)
            .flat_map(|(_, p, _)| p)
            .collect();
        let ends: Vec<u64> = packets.iter().map(|p| p.time_ps).collect();
        assert!(
            ends.windows(2).all(|w| w[0] <= w[1]),
            "drone {d} in end order"
        );
        let tx: Vec<&TxDone> = reports
            .iter()
            .filter(|(q, _, _)| *q == d)
            .flat_map(|(_, _, t)| t)
            .collect();
        assert!(tx.windows(2).all(|w| w[0].time_ps <= w[1].time_ps));
        assert!(tx.len() > 50);
        assert!(tx
            .iter()
            .all(|t| (t.radio == Radio::Uwb) == t.tx_stamp.is_some()));
    }
    // each once: a second take gives nothing; an early take waits for the end
    let mut ch = Channel::new(exact(), vec![drone("A", 0.0), drone("B", 0.0)]);
    let start = Picos(2_000 * MS);
    ch.send(0, Radio::P2p, vec![1; 60], start).unwrap();
    ch.resolve(Picos(2_001 * MS), &line(vec![0.0, 1.0]));
    let end = start.0 + 3_336 + Radio::P2p.airtime(60).0; // 1 m: 3.336 ns
    assert_eq!(ch.take(1, Picos(end - 1)).0.len(), 0);
    assert_eq!(ch.take(0, Picos(end - 1 - 3_336)).1.len(), 0);
    let (p, _) = ch.take(1, Picos(end));
    assert_eq!(p.len(), 1);
    assert_eq!(p[0].rx_stamp, None, "p2p has no stamps");
    assert!(ch.take(1, Picos(2_001 * MS)).0.is_empty());
    let (_, t) = ch.take(0, Picos(2_001 * MS));
    assert_eq!(t.len(), 1);
    assert!(ch.take(0, Picos(2_001 * MS)).1.is_empty());
}

#[test]
fn bad_sends_are_errors_and_retired_drones_are_silent() {
    let mut ch = Channel::new(
        exact(),
        vec![
            drone("A", 0.0),
            DroneRadio {
                name: "B".into(),
                clock_ppm: 0.0,
                radios: vec![Radio::P2p],
            },
            drone("C", 0.0),
        ],
    );
    let log = SharedBuf::default();
    ch.set_log(Box::new(log.clone()));
    let t = Picos(2_000 * MS);
    assert_eq!(
        ch.send(3, Radio::Uwb, vec![1], t),
        Err(ChannelError::UnknownDrone(3))
    );
    let e = ch.send(1, Radio::Uwb, vec![1], t).unwrap_err();
    assert_eq!(e.to_string(), "drone B has no uwb radio");
    assert!(matches!(
        ch.send(0, Radio::P2p, vec![1; 61], t),
        Err(ChannelError::BadLength {
            len: 61,
            max: 60,
            ..
        })
    ));
    assert!(matches!(
        ch.send(0, Radio::Uwb, vec![], t),
        Err(ChannelError::BadLength { len: 0, .. })
    ));
    // a uwb frame to C (B lacks uwb: no row for B)
    ch.send(0, Radio::Uwb, vec![1; 100], t).unwrap();
    ch.resolve(Picos(t.0 + 100_000), &line(vec![0.0, 1.0, 2.0]));
    let e = ch
        .send(0, Radio::Uwb, vec![1], Picos(t.0 + 99_999))
        .unwrap_err();
    assert!(e.to_string().contains("in the past"), "{e}");
    // C stops while receiving: its reception ends as `retired`
    ch.retire(2);
    assert!(matches!(
        ch.send(2, Radio::P2p, vec![1], Picos(2_001 * MS)),
        Err(ChannelError::Retired { .. })
    ));
    ch.send(0, Radio::P2p, vec![1], Picos(2_001 * MS)).unwrap();
    ch.resolve(Picos(2_002 * MS), &line(vec![0.0, 1.0, 2.0]));
    assert!(ch.take(2, Picos(2_002 * MS)).0.is_empty());
    assert_eq!(ch.take(1, Picos(2_002 * MS)).0.len(), 1);
    ch.flush_log().unwrap();
    let o = log.outcomes();
    assert_eq!(
        o,
        vec![
            ("A".into(), "C".into(), "retired".into()),
            ("A".into(), "B".into(), "received".into()),
        ]
    );
    assert!(log.text().starts_with(
        "start_ps,end_ps,radio,from,to,distance_m,rssi_dbm,outcome,tx_stamp,rx_stamp\n"
    ));
}

#[test]
fn a_failing_log_is_an_error_not_a_panic() {
    struct Broken;
    impl Write for Broken {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("disk full"))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Err(std::io::Error::other("disk full"))
        }
    }
    let mut ch = Channel::new(exact(), vec![drone("A", 0.0), drone("B", 0.0)]);
    ch.set_log(Box::new(Broken));
    ch.send(0, Radio::P2p, vec![1], Picos(2_000 * MS)).unwrap();
    ch.resolve(Picos(2_001 * MS), &line(vec![0.0, 1.0]));
    let e = ch.flush_log().unwrap_err();
    assert!(e.to_string().contains("disk full"), "{e}");
}

// ------------------------------------------- seed 004, Table 7: the fit ---

/// Seed 004 §5 (Table 7): A hovers, B flies towards it from 3 m at 0.2 m/s,
/// both broadcast a P2P packet every 100 ms (§4.3.2.A); the first packet
/// either way with RSSI > -48 dBm is the detection. Returns the distance (m)
/// at that packet's start, or None if B reached A undetected.
fn seed_004_trial(cfg: &RadioConfig, trial: u64) -> Option<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(trial);
    let cfg = RadioConfig {
        seed: trial,
        ..cfg.clone()
    };
    let mut ch = Channel::new(cfg, vec![drone("A", 0.0), drone("B", 0.0)]);
    let t0 = 2_000 * MS;
    let period = 100 * MS;
    // each drone's broadcast phase inside the period (they are not synchronised)
    let phase = [rng.random_range(0..period), rng.random_range(0..period)];
    let gap = |t: Picos| 3.0 - 0.2 * (t.0 - t0) as f64 * 1e-12;
    let pos = move |d: usize, t: Picos| {
        if d == 0 {
            [0.0, 0.0, 0.5]
        } else {
            [gap(t), 0.0, 0.5]
        }
    };
    let step = 10 * MS;
    let mut next = phase;
    let mut now = t0;
    while gap(Picos(now)) > 0.0 {
        let until = now + step;
        for (d, next) in next.iter_mut().enumerate() {
            while *next + t0 < until {
                ch.send(d, Radio::P2p, vec![d as u8 + 1], Picos(t0 + *next))
                    .unwrap();
                *next += period;
            }
        }
        ch.resolve(Picos(until), &pos);
        for d in 0..2 {
            let (p, _) = ch.take(d, Picos(until));
            if let Some(hit) = p.iter().find(|p| p.rssi > -48.0) {
                let start = hit.time_ps - Radio::P2p.airtime(1).0;
                return Some(gap(Picos(start)));
            }
        }
        now = until;
    }
    None
}

fn detection_stats(cfg: &RadioConfig, trials: u64) -> (f64, f64) {
    let d: Vec<f64> = (0..trials)
        .map(|k| 100.0 * seed_004_trial(cfg, k).unwrap_or(0.0))
        .collect();
    let m = d.iter().sum::<f64>() / d.len() as f64;
    let s = (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (d.len() - 1) as f64).sqrt();
    (m, s)
}

/// The defaults reproduce seed 004's Table 7: detection at 117.9 ± 65.0 cm
/// (8 trials there; here 600 seeded trials through the real channel).
#[test]
fn the_default_p2p_rssi_reproduces_seed_004_table_7() {
    let (m, s) = detection_stats(&RadioConfig::default(), 600);
    println!("detection distance over 600 trials: {m:.1} ± {s:.1} cm (seed 004: 117.9 ± 65.0)");
    // 600 trials: σ of the mean 65/√600 = 2.7 cm, of the std ≈ 1.9 cm
    assert!((m - 117.9).abs() < 9.0, "mean {m}");
    assert!((s - 65.0).abs() < 7.0, "std {s}");
}

/// With shadowing and fading (DESIGN.md §16; the [radio] of
/// scenarios/worlds/seed004-radar.toml), Table 7 still holds in
/// distribution: the detection distance's mean and spread within a few
/// standard errors of the seed's 117.9 ± 65.0 cm.
#[test]
fn shadowing_and_fading_keep_seed_004_table_7() {
    let cfg = RadioConfig {
        p2p_shadowing_db: 4.0,
        p2p_shadowing_decorr_m: 1.0,
        p2p_shadowing_tau_s: 5.0,
        p2p_fading: world_server::radio::fading::FastFading::Rayleigh,
        p2p_rssi_noise_db: 6.0,
        p2p_rssi_1m_dbm: -65.0,
        ..RadioConfig::default()
    };
    let (m, s) = detection_stats(&cfg, 600);
    println!("with fading, 600 trials: {m:.1} ± {s:.1} cm (seed 004: 117.9 ± 65.0)");
    assert!((m - 117.9).abs() < 10.0, "mean {m}");
    assert!((s - 65.0).abs() < 8.0, "std {s}");
}

/// The fit itself (docs/SWARM.md §3.1), exact rather than Monte Carlo: for a
/// pair of broadcast phases, packet k (in time order, either drone) is the
/// detection with probability p_k·Π_{j<k}(1 − p_j), p = P(RSSI > -48) =
/// Q((-48 − μ(D)) / σ); the phases are averaged on an 8×8 grid. With
/// n = 2 fixed, grid over P_1m (0.2 dB) and σ (0.1 dB) for the least squares
/// distance to (117.88, 65.02) cm. Run with `--ignored --nocapture`.
#[test]
#[ignore = "the fit of SWARM §3.1 (seconds); prints its result"]
fn fit_p2p_rssi_to_seed_004_table_7() {
    // Q(x) = P(N(0,1) > x)
    let q = |x: f64| 0.5 * libm::erfc(x / std::f64::consts::SQRT_2);
    let stats = |p1: f64, n: f64, sigma: f64| {
        let grid = 8;
        let (mut w, mut m1, mut m2) = (0.0, 0.0, 0.0);
        for i in 0..grid {
            for j in 0..grid {
                let pa = (i as f64 + 0.5) / grid as f64 * 0.1;
                let pb = (j as f64 + 0.5) / grid as f64 * 0.1;
                let mut times: Vec<f64> = (0..150)
                    .flat_map(|k| [pa + 0.1 * k as f64, pb + 0.1 * k as f64])
                    .collect();
                times.sort_by(f64::total_cmp);
                let mut survive = 1.0;
                for t in times {
                    let d = 3.0 - 0.2 * t;
                    if d <= 0.0 {
                        break;
                    }
                    let p = q((-48.0 - log_distance(p1, n, d)) / sigma);
                    w += survive * p;
                    m1 += survive * p * d;
                    m2 += survive * p * d * d;
                    survive *= 1.0 - p;
                }
                w += survive; // undetected: distance 0
            }
        }
        let m = m1 / w;
        (100.0 * m, 100.0 * (m2 / w - m * m).max(0.0).sqrt())
    };
    let mut best = (f64::INFINITY, 0.0, 0.0, 0.0, 0.0);
    for p in 0..=50 {
        let p1 = -76.0 + 0.2 * p as f64;
        for s in 0..=35 {
            let sigma = 8.5 + 0.1 * s as f64;
            let (m, sd) = stats(p1, 2.0, sigma);
            let cost = (m - 117.88).powi(2) + (sd - 65.02).powi(2);
            if cost < best.0 {
                best = (cost, p1, sigma, m, sd);
            }
        }
    }
    println!(
        "n = 2: P_1m = {:.1} dBm, sigma = {:.1} dB -> detection {:.1} ± {:.1} cm",
        best.1, best.2, best.3, best.4
    );
    let d = RadioConfig::default();
    assert!((best.1 - d.p2p_rssi_1m_dbm).abs() <= 0.4, "default P_1m");
    assert!((best.2 - d.p2p_rssi_noise_db).abs() <= 0.2, "default sigma");
}
