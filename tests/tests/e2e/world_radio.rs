//! End-to-end tests of the radio channel through a real `world-server`
//! (DESIGN.md §8, docs/SWARM.md §3): RADIO_SEND / RADIO_RECV between
//! hand-written platforms, against the closed form, and bad radio input.

use crate::multi;

use std::thread;

use multi::{init, stop, World};
use protocol::radio::{dw1000_stamp, ppm_to_ppt, Picos};
use protocol::{Radio, RadioPacket, Reply, Request, TxDone};
use world_server::radio::{Channel, DroneRadio, RadioConfig, SPEED_OF_LIGHT_M_S};

/// Two carried drones (exact positions) 5 m apart, with ±20 ppm clocks.
const PAIR: &str = r#"
[[drone]]
name = "A"
clock_ppm = 20.0
carried = [[0.0, 0.0, 0.0, 1.0]]

[[drone]]
name = "B"
clock_ppm = -20.0
radios = ["uwb"]
carried = [[0.0, 3.0, 4.0, 1.0]]

[radio]
seed = 7
uwb_noise_m = 0.0
"#;

fn recv(c: &mut protocol::blocking::Connection) -> (Vec<RadioPacket>, Vec<TxDone>) {
    match c.request(&Request::RadioRecv).unwrap() {
        Some(Reply::RadioRecv { packets, tx_done }) => (packets, tx_done),
        other => panic!("{other:?}"),
    }
}

fn send(c: &mut protocol::blocking::Connection, data: &[u8], offset_ps: u64) {
    c.send(&Request::RadioSend {
        radio: Radio::Uwb,
        data: data.to_vec(),
        offset_ps,
    })
    .unwrap();
}

#[test]
fn a_ping_and_its_reply_carry_the_closed_form_stamps() {
    let mut w = World::start(PAIR, &["--radio-log", "radio.csv"]);
    // The same seed gives the same clock phases (DESIGN.md §8: drawn per
    // drone from the world's seed).
    let cfg = RadioConfig {
        seed: 7,
        uwb_noise_m: 0.0,
        ..RadioConfig::default()
    };
    let drones = [("A", 20.0), ("B", -20.0)].map(|(n, ppm)| DroneRadio {
        name: n.into(),
        clock_ppm: ppm,
        radios: vec![Radio::Uwb],
    });
    let channel = Channel::new(cfg.clone(), drones.to_vec());
    let stamp = |d: usize, t: u64| {
        dw1000_stamp(
            Picos(t),
            ppm_to_ppt(drones[d].clock_ppm),
            channel.phase(d).unwrap(),
        )
        .0
    };
    // 5 m at c, rounded to the picosecond.
    let tof = (5.0 / SPEED_OF_LIGHT_M_S * 1e12).round() as u64;
    assert_eq!(tof, 16_678);
    let ping_start = Picos::from_ms(2000).0 + 1234;
    let pong_start = Picos::from_ms(2032).0 + 500_000_000;
    let (ping_air, pong_air) = (Radio::Uwb.airtime(4).0, Radio::Uwb.airtime(5).0);

    let sock = World::attach(w.socket.clone());
    let b = thread::spawn(move || {
        let mut b = sock.claim("B");
        b.send(&Request::AdvanceTime { time: 32 }).unwrap();
        let (packets, tx_done) = recv(&mut b);
        send(&mut b, b"pong!", 500_000_000);
        b.send(&Request::AdvanceTime { time: 32 }).unwrap();
        let (_, pong_done) = recv(&mut b);
        stop(&mut b);
        (packets, tx_done, pong_done)
    });
    let mut a = w.claim("A");
    send(&mut a, b"ping", 1234);
    // Nothing has ended yet at 2000 ms.
    assert_eq!(recv(&mut a), (vec![], vec![]));
    a.send(&Request::AdvanceTime { time: 32 }).unwrap();
    let (none, ping_done) = recv(&mut a);
    a.send(&Request::AdvanceTime { time: 32 }).unwrap();
    let (pong, no_more) = recv(&mut a);
    stop(&mut a);
    let (b_packets, b_tx_done, pong_done) = b.join().unwrap();
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");

    assert!(none.is_empty() && no_more.is_empty() && b_tx_done.is_empty());
    assert_eq!(
        ping_done,
        vec![TxDone {
            radio: Radio::Uwb,
            time_ps: ping_start + ping_air,
            tx_stamp: Some(stamp(0, ping_start)),
        }]
    );
    let rssi = cfg.uwb_rssi_1m_dbm - 10.0 * cfg.uwb_path_loss_exp * 5f64.log10();
    assert_eq!(b_packets.len(), 1);
    let p = &b_packets[0];
    assert_eq!(
        (p.radio, p.from.as_str(), &p.data[..]),
        (Radio::Uwb, "A", &b"ping"[..])
    );
    assert_eq!(p.time_ps, ping_start + tof + ping_air);
    assert_eq!(p.rx_stamp, Some(stamp(1, ping_start + tof)));
    assert!((p.rssi - rssi).abs() < 1e-9, "{} vs {rssi}", p.rssi);
    assert_eq!(
        pong_done,
        vec![TxDone {
            radio: Radio::Uwb,
            time_ps: pong_start + pong_air,
            tx_stamp: Some(stamp(1, pong_start)),
        }]
    );
    assert_eq!(pong.len(), 1);
    assert_eq!(
        (pong[0].from.as_str(), &pong[0].data[..]),
        ("B", &b"pong!"[..])
    );
    assert_eq!(pong[0].time_ps, pong_start + tof + pong_air);
    assert_eq!(pong[0].rx_stamp, Some(stamp(0, pong_start + tof)));
    // The radio log: one row per frame and receiver, both received.
    let log = w.read("radio.csv");
    let rows: Vec<&str> = log.lines().collect();
    assert_eq!(rows.len(), 3, "{log}");
    assert!(
        rows[1].contains(",A,B,") && rows[1].contains(",received,"),
        "{log}"
    );
    assert!(
        rows[2].contains(",B,A,") && rows[2].contains(",received,"),
        "{log}"
    );
}

/// A and B claim; A sends `body` (a RADIO_SEND the world refuses): A gets
/// ERROR, B's next request gets ERROR, the world exits non-zero.
fn refused(body: &[u8]) -> (String, String, String) {
    let mut w = World::start(PAIR, &[]);
    let sock = World::attach(w.socket.clone());
    // B's claim is answered at once (DESIGN.md §15); its reply one step
    // later needs A's clock there: it meets the end of the run, A's bad
    // request.
    let b = thread::spawn(move || sock.claim_step_and_fail("B"));
    let mut a = w.claim("A");
    a.send_raw(body).unwrap();
    let own = match a.recv_reply().unwrap() {
        Some(Reply::Error { error }) => error,
        other => panic!("{other:?}"),
    };
    // The world closes after the ERROR; the platform leaves, so the world
    // need not wait for it (server::DRAIN).
    assert!(a.recv_raw().unwrap().is_none());
    drop(a);
    let other = b.join().unwrap();
    let (status, err) = w.finish();
    assert!(!status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    (own, other, err)
}

#[test]
fn bad_radio_sends_end_the_run() {
    let oversize = format!(
        r#"{{"command":"RADIO_SEND","data":"{}","offset_ps":0,"radio":"uwb"}}"#,
        "A".repeat(172) // 129 bytes of base64
    );
    let cases: [(&[u8], &str); 6] = [
        (
            br#"{"command":"RADIO_SEND","data":"!!!!","offset_ps":0,"radio":"uwb"}"#,
            "not base64",
        ),
        (
            br#"{"command":"RADIO_SEND","data":"","offset_ps":0,"radio":"uwb"}"#,
            "1 to 127 bytes, got 0",
        ),
        (oversize.as_bytes(), "1 to 127 bytes, got 129"),
        (
            br#"{"command":"RADIO_SEND","data":"cGluZw==","offset_ps":-1,"radio":"uwb"}"#,
            "offset_ps must be an integer >= 0",
        ),
        (
            br#"{"command":"RADIO_SEND","data":"cGluZw==","offset_ps":0,"radio":"wifi"}"#,
            "unknown radio",
        ),
        // B has no P2P radio, A has: so A's P2P frame is fine, B's is not;
        // here A sends past the end of time.
        (
            br#"{"command":"RADIO_SEND","data":"cGluZw==","offset_ps":18446744073709551615,"radio":"p2p"}"#,
            "beyond the end of time",
        ),
    ];
    for (body, needle) in cases {
        let (own, other, err) = refused(body);
        assert!(own.contains(needle), "{needle}: {own}");
        assert!(
            other.starts_with("drone A: ") && other.contains(needle),
            "{other}"
        );
        assert!(err.contains(needle), "{err}");
    }
}

#[test]
fn a_radio_the_drone_lacks_ends_the_run() {
    let mut w = World::start(PAIR, &[]);
    let sock = World::attach(w.socket.clone());
    let a = thread::spawn(move || {
        let mut a = sock.claim("A");
        // At 2032 ms A waits for B, whose P2P frame ends the run.
        a.send(&Request::AdvanceTime { time: 32 }).unwrap();
        multi::error_of(&mut a, &Request::GetSensors)
    });
    let mut b = w.claim("B");
    b.send(&Request::RadioSend {
        radio: Radio::P2p,
        data: b"hello".to_vec(),
        offset_ps: 0,
    })
    .unwrap();
    let own = match b.recv_reply().unwrap() {
        Some(Reply::Error { error }) => error,
        other => panic!("{other:?}"),
    };
    // The world closes after the ERROR; the platform leaves, so the world
    // need not wait for it (server::DRAIN).
    assert!(b.recv_raw().unwrap().is_none());
    drop(b);
    assert!(own.contains("drone B has no p2p radio"), "{own}");
    let other = a.join().unwrap();
    assert!(other.starts_with("drone B: RADIO_SEND: "), "{other}");
    let (status, err) = w.finish();
    assert!(!status.success());
    assert!(err.contains("has no p2p radio"), "{err}");
    // A single-drone world has a channel too (nobody to hear it).
    let mut w = World::start("[start]\nposition = [0.0, 0.0, 0.015]\n", &[]);
    let mut c = w.connect();
    c.request(&init(None)).unwrap();
    send(&mut c, b"alone", 0);
    c.send(&Request::AdvanceTime { time: 32 }).unwrap();
    let (packets, done) = recv(&mut c);
    assert!(packets.is_empty());
    assert_eq!(done.len(), 1);
    stop(&mut c);
    let (status, err) = w.finish();
    assert!(status.success(), "{err}");
}
