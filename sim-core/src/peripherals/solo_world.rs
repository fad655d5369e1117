//! A world for one drone in the same process ([`SoloWorld`]): what
//! world-server's lockstep is for a world with a single drone that never
//! leaves its start, without the physics. It keeps the drone's clock exactly
//! as the lockstep does (docs/SWARM.md §2: the warm-up, then SET_VELOCITY one
//! basicTimeStep, ADVANCE_TIME `time`), serves the radio messages of DESIGN.md
//! §8 (a transmission ends one airtime after `clock + offset_ps`; there is no
//! other drone, so it reaches nobody and comes back only as `tx_done`, with
//! its DW1000 stamp), and answers STOP at once (the motors never spun up).
//!
//! Used by the platform's tests (the ticker, the radios' timing) and usable
//! to run a radio firmware on its own. [`SoloWorld::inject`] queues a
//! reception as another drone's frame would arrive, for tests of the receive
//! path; every request is kept in [`SoloWorld::log`].

use std::collections::VecDeque;

use protocol::radio::{dw1000_stamp, ppm_to_ppt, Picos as WorldPicos, RadioPacket, TxDone};
use protocol::{ImageEncoding, Reply, Request, State};

use super::{LinkError, LinkStats, WorldLink};
use crate::units::{Millis, Picos};

/// One request as the world saw it: the drone's clock when it came, the
/// platform's time, and the request.
#[derive(Debug, Clone, PartialEq)]
pub struct Logged {
    pub clock: Millis,
    pub platform: Picos,
    pub request: Request,
}

/// The world (see the module documentation).
#[derive(Debug, Clone)]
pub struct SoloWorld {
    pub start: [f64; 3],
    pub timestep: Millis,
    pub warmup: Millis,
    /// This drone's radio crystal error (ppm).
    pub clock_ppm: f64,
    /// The drone's clock (ms of world time); 0 until GET_INIT_DATA.
    clock: Millis,
    opened: bool,
    stopped: bool,
    /// This drone's transmissions not yet reported (end time ps, tx_done).
    tx: VecDeque<(u64, TxDone)>,
    /// Receptions queued by [`SoloWorld::inject`], in the order they end.
    rx: VecDeque<RadioPacket>,
    pub log: Vec<Logged>,
    stats: LinkStats,
}

impl SoloWorld {
    /// A drone at `start` in a world stepping `timestep`, with the thesis's
    /// 2000 ms warm-up.
    pub fn new(start: [f64; 3], timestep: Millis) -> Self {
        SoloWorld {
            start,
            timestep,
            warmup: Millis(2000),
            clock_ppm: 0.0,
            clock: Millis(0),
            opened: false,
            stopped: false,
            tx: VecDeque::new(),
            rx: VecDeque::new(),
            log: Vec::new(),
            stats: LinkStats::default(),
        }
    }

    /// The drone's clock (ms of world time).
    pub fn clock(&self) -> Millis {
        self.clock
    }

    /// Queues a reception (its `time_ps` is when it ends); it is reported at
    /// the first RADIO_RECV whose clock has reached that time.
    pub fn inject(&mut self, packet: RadioPacket) {
        self.rx.push_back(packet);
    }

    /// The requests of one kind, in order.
    pub fn requests(&self, command: &str) -> Vec<&Logged> {
        self.log
            .iter()
            .filter(|l| l.request.command() == command)
            .collect()
    }

    fn stamp(&self, t_ps: u64) -> u64 {
        dw1000_stamp(WorldPicos(t_ps), ppm_to_ppt(self.clock_ppm), WorldPicos(0)).0
    }

    fn serve(&mut self, request: &Request, now: Picos) -> Result<Option<Reply>, LinkError> {
        let refuse = |message: String| LinkError::Remote {
            request: request.command(),
            message,
        };
        self.log.push(Logged {
            clock: self.clock,
            platform: now,
            request: request.clone(),
        });
        self.stats.messages += 1;
        if self.stopped {
            return Err(LinkError::Closed {
                request: request.command(),
            });
        }
        if !self.opened && !matches!(request, Request::GetInitData { .. }) {
            return Err(refuse("the first request must be GET_INIT_DATA".into()));
        }
        let clock_ps = self.clock.to_picos().0;
        Ok(match request {
            Request::GetInitData { image_encoding, .. } => {
                if self.opened {
                    return Err(refuse("GET_INIT_DATA twice".into()));
                }
                self.opened = true;
                self.clock = self.warmup;
                Some(Reply::InitData {
                    x: self.start[0],
                    y: self.start[1],
                    z: self.start[2],
                    time_s: self.warmup.0 as f64 / 1000.0,
                    timestep_ms: self.timestep.0,
                    image_encoding: image_encoding.unwrap_or(ImageEncoding::Array),
                    drone: None,
                })
            }
            Request::SetVelocity { .. } => {
                self.clock = self.clock + self.timestep;
                None
            }
            Request::AdvanceTime { time } => {
                if *time % self.timestep.0 != 0 {
                    return Err(refuse(format!(
                        "ADVANCE_TIME {time} ms is not a multiple of the {} ms timestep",
                        self.timestep.0
                    )));
                }
                self.clock = self.clock + Millis(*time);
                None
            }
            Request::RadioSend {
                radio,
                data,
                offset_ps,
            } => {
                if data.is_empty() || data.len() > radio.max_payload() {
                    return Err(refuse(format!("{}-byte {radio} frame", data.len())));
                }
                let start = clock_ps + offset_ps;
                if self
                    .tx
                    .back()
                    .is_some_and(|(end, d)| d.radio == *radio && *end > start)
                {
                    return Err(refuse("a transmission overlaps the previous one".into()));
                }
                let end = start + radio.airtime(data.len()).0;
                let tx_stamp = (*radio == protocol::radio::Radio::Uwb).then(|| self.stamp(start));
                self.tx.push_back((
                    end,
                    TxDone {
                        radio: *radio,
                        time_ps: end,
                        tx_stamp,
                    },
                ));
                None
            }
            Request::RadioRecv => {
                let mut tx_done = Vec::new();
                while self.tx.front().is_some_and(|(end, _)| *end <= clock_ps) {
                    tx_done.push(self.tx.pop_front().expect("front").1);
                }
                let mut packets = Vec::new();
                while self.rx.front().is_some_and(|p| p.time_ps <= clock_ps) {
                    packets.push(self.rx.pop_front().expect("front"));
                }
                Some(Reply::RadioRecv { packets, tx_done })
            }
            Request::GetState => Some(Reply::State(State {
                time_s: self.clock.0 as f64 / 1000.0,
                x: self.start[0],
                y: self.start[1],
                z: self.start[2],
                qw: 1.0,
                ..State::default()
            })),
            Request::Stop => {
                self.stopped = true;
                Some(Reply::Stop {
                    time_s: self.clock.0 as f64 / 1000.0,
                    stop_time_ms: 0,
                    gates_passed: None,
                })
            }
            other => {
                return Err(refuse(format!(
                    "{} is not served by this world (it has no physics)",
                    other.command()
                )))
            }
        })
    }
}

impl WorldLink for SoloWorld {
    fn call(&mut self, request: &Request, now: Picos) -> Result<Reply, LinkError> {
        match self.serve(request, now)? {
            Some(reply) => Ok(reply),
            None => Err(LinkError::Unexpected {
                request: request.command(),
                reply: "no reply",
            }),
        }
    }

    fn send(&mut self, request: &Request, now: Picos) -> Result<(), LinkError> {
        self.serve(request, now).map(|_| ())
    }

    fn stats(&self) -> LinkStats {
        self.stats
    }
}
