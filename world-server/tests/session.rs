//! The world serving its drones without sockets (`session::Session`): the
//! radio sees a flown drone where the physics put it, linearly between the
//! two step boundaries around the transmission (docs/SWARM.md §3), and the
//! session's outputs come in processing order.

use std::path::Path;

use protocol::radio::Picos;
use protocol::{Radio, Reply, Request};
use world_server::radio::SPEED_OF_LIGHT_M_S;
use world_server::session::{Input, Outputs, Progress, Session, SessionError, SessionOutputs};
use world_server::{Millis, StepConfig, WorldDesc};

/// What the session sent, in order.
#[derive(Default)]
struct Collected {
    lines: Vec<(usize, String, Millis)>,
    replies: Vec<(usize, Reply)>,
}

impl Outputs for Collected {
    fn request(
        &mut self,
        drone: usize,
        body: &[u8],
        _valid: bool,
        now: Millis,
    ) -> Result<(), SessionError> {
        let text = String::from_utf8_lossy(body).into_owned();
        self.lines.push((drone, text, now));
        Ok(())
    }

    fn reply(&mut self, drone: usize, reply: Reply, now: Millis) -> Result<(), SessionError> {
        self.lines.push((drone, reply.command().to_string(), now));
        self.replies.push((drone, reply));
        Ok(())
    }
}

fn frame(req: &Request) -> Input {
    let mut body = Vec::new();
    protocol::encode_request(req, &mut body);
    let request = protocol::decode_request(&body);
    Input::Frame { body, request }
}

/// A falls freely from 100 m (its motors are never commanded: they keep the
/// warm-up's 1 rad/s, a negligible thrust); B is carried, fixed, 3 m beside
/// A's column. A transmits a quarter into a 32 ms step.
const WORLD: &str = r#"
[[drone]]
name = "A"
position = [0.0, 0.0, 100.0]

[[drone]]
name = "B"
carried = [[0.0, 3.0, 0.0, 70.0]]

[radio]
uwb_noise_m = 0.0
uwb_max_range_m = 100.0
"#;

#[test]
fn a_flown_drone_transmits_from_between_its_step_boundaries() {
    let desc = WorldDesc::parse(WORLD, Path::new("w.toml")).unwrap();
    let step = StepConfig {
        timestep: Millis(32),
        substeps: 1,
    };
    let mut s = Session::new(&desc, step, SessionOutputs::default()).unwrap();
    s.warm_up().unwrap();
    let mut out = Collected::default();
    let init = |name: &str| Request::GetInitData {
        image_encoding: None,
        drone: Some(name.into()),
    };
    s.push(0, frame(&init("A"))).unwrap();
    s.push(1, frame(&init("B"))).unwrap();
    // A at 2000 ms: an advance, so that B's init (2000, B) can be served.
    s.push(0, frame(&Request::AdvanceTime { time: 64 }))
        .unwrap();
    assert_eq!(s.run(&mut out).unwrap(), Progress::Waiting);
    assert_eq!(out.replies.len(), 2, "both GET_INIT_DATA answered");
    // B transmits? No: A does, at 2064 ms + 8 ms, from wherever it falls.
    s.push(1, frame(&Request::AdvanceTime { time: 128 }))
        .unwrap();
    assert_eq!(s.run(&mut out).unwrap(), Progress::Waiting);
    let offset = Picos(8 * Picos::PER_MS);
    s.push(
        0,
        frame(&Request::RadioSend {
            radio: Radio::Uwb,
            data: b"falling".to_vec(),
            offset_ps: offset.0,
        }),
    )
    .unwrap();
    s.push(0, frame(&Request::GetState)).unwrap();
    s.push(0, frame(&Request::AdvanceTime { time: 32 }))
        .unwrap();
    s.push(0, frame(&Request::GetState)).unwrap();
    s.run(&mut out).unwrap();
    let z = |r: &Reply| match r {
        Reply::State(st) => st.z,
        other => panic!("{other:?}"),
    };
    let n = out.replies.len();
    let (z0, z1) = (z(&out.replies[n - 2].1), z(&out.replies[n - 1].1));
    assert!(z0 > z1 && z0 < 80.0, "A falls: {z0} then {z1}");
    // B's RADIO_RECV at 2192 ms.
    s.push(1, frame(&Request::RadioRecv)).unwrap();
    s.push(0, frame(&Request::Stop)).unwrap();
    s.run(&mut out).unwrap();
    let packet = out
        .replies
        .iter()
        .find_map(|(d, r)| match (d, r) {
            (1, Reply::RadioRecv { packets, .. }) => packets.first().cloned(),
            _ => None,
        })
        .expect("B heard A");
    // A's centre at 2072 ms: a quarter of the way from 2064 to 2096.
    let za = z0 + (z1 - z0) * 0.25;
    let distance = (3.0f64.powi(2) + (za - 70.0).powi(2)).sqrt();
    let start = Picos::from_ms(2064).0 + offset.0;
    let tof = (distance / SPEED_OF_LIGHT_M_S * 1e12).round() as u64;
    assert_eq!(
        packet.time_ps,
        start + tof + Radio::Uwb.airtime(7).0,
        "distance {distance} m"
    );
    // Not the distance at either boundary (they differ by centimetres of fall,
    // i.e. by more than a picosecond of flight).
    for zb in [z0, z1] {
        let d = (9.0 + (zb - 70.0).powi(2)).sqrt();
        let t = (d / SPEED_OF_LIGHT_M_S * 1e12).round() as u64;
        assert_ne!(t, tof);
    }
    // B stops; both done.
    s.push(1, frame(&Request::Stop)).unwrap();
    assert_eq!(s.run(&mut out).unwrap(), Progress::Finished);
    // The lines: every request at its drone's clock, in (time, drone) order.
    let mut last = (Millis(0), 0);
    for (d, text, now) in &out.lines {
        if text.starts_with('{') {
            assert!((*now, *d) >= last, "{text} at {now} after {last:?}");
            last = (*now, *d);
        }
    }
}

#[test]
fn a_request_after_stop_and_a_claim_of_another_drone_fail() {
    let desc = WorldDesc::parse(WORLD, Path::new("w.toml")).unwrap();
    let mut s = Session::new(&desc, StepConfig::default(), SessionOutputs::default()).unwrap();
    s.warm_up().unwrap();
    let mut out = Collected::default();
    // B's own claim names A.
    s.push(
        1,
        frame(&Request::GetInitData {
            image_encoding: None,
            drone: Some("A".into()),
        }),
    )
    .unwrap();
    s.push(0, frame(&Request::Stop)).unwrap();
    let e = s.run(&mut out).unwrap_err();
    assert_eq!(e.drone(), Some(1));
    assert!(e.message().contains("claims drone \"A\""), "{e}");
    assert!(e.to_string().starts_with("drone B: "), "{e}");
    // A's STOP came first (A before B): A, a falling drone, is stopping.
    let e = s.push(0, frame(&Request::GetSensors)).unwrap_err();
    assert_eq!(e.drone(), Some(0));
    assert!(e.message().contains("GET_SENSORS after STOP"), "{e}");
}
