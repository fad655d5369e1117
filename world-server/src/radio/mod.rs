//! The world's radio channel (DESIGN.md §8, docs/SWARM.md §3): flight times,
//! DW1000 timestamps, signal strength, collisions and losses between the
//! drones' UWB (DW1000, seed 003) and P2P (nRF51, seed 004) radios.
//!
//! The world calls [`Channel::send`] for every RADIO_SEND, in its canonical
//! order; [`Channel::resolve`] once the physics has reached a time (the
//! positions of the frames that started before it are then known); and
//! [`Channel::take`] for a RADIO_RECV. A reception is reported when it ends,
//! and only once nothing that is still to come can change its outcome.
//!
//! Every random draw is keyed by (seed, sender, sender's frame number,
//! receiver) ([`draw`]), so the results depend on the world file and the
//! transmissions' times only, not on the granularity or order of the calls.

mod config;
pub(crate) mod draw;
pub mod fading;
pub mod geometry;
mod link;
mod log;
pub mod profile;

pub use config::{RadioConfig, P2P_RSSI_1M_DBM, P2P_RSSI_NOISE_DB};
pub use log::{LogRow, Outcome, RadioEvent, RadioLog, HEADER as LOG_HEADER};

use std::sync::Arc;

use protocol::radio::{dw1000_stamp, ppm_to_ppt, Dw1000Ticks, Picos, Radio};
use protocol::{RadioPacket, TxDone};

use fading::LinkShadow;
use geometry::{Body, Obstacle};

/// Speed of light in vacuum, m/s (exact, SI).
pub const SPEED_OF_LIGHT_M_S: f64 = 299_792_458.0;

/// Below this centre distance the log-distance RSSI models are not used (the
/// far-field model would diverge at 0): the RSSI is that of 1 cm. Two
/// Crazyflies' centres cannot come that close anyway (92 mm frames).
const MIN_RSSI_DISTANCE_M: f64 = 0.01;

/// One drone as the channel sees it (DESIGN.md §7: `[[drone]]`).
#[derive(Clone, Debug, PartialEq)]
pub struct DroneRadio {
    pub name: String,
    /// This drone's radio crystal error, ppm (`clock_ppm`).
    pub clock_ppm: f64,
    /// The radios it carries.
    pub radios: Vec<Radio>,
}

/// A transmission the channel cannot accept: the world turns it into an
/// ERROR that ends the run (docs/SWARM.md §2, Failures).
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ChannelError {
    #[error("no drone with index {0} in the world")]
    UnknownDrone(usize),
    #[error("drone {drone} has no {radio} radio")]
    NoSuchRadio { drone: String, radio: Radio },
    #[error("drone {drone} has stopped: it cannot transmit any more")]
    Retired { drone: String },
    #[error("drone {drone}: a {radio} frame carries 1 to {max} bytes, got {len}")]
    BadLength {
        drone: String,
        radio: Radio,
        len: usize,
        max: usize,
    },
    #[error(
        "drone {drone}: a transmission starting at {start} ps is in the past: \
         the channel is resolved up to {resolved} ps"
    )]
    InThePast {
        drone: String,
        start: u64,
        resolved: u64,
    },
}

/// A frame on the air (sent, maybe not yet resolved).
#[derive(Clone, Debug)]
struct Frame {
    from: usize,
    /// The sender's frame number (0, 1, 2, … over both radios): with `from`
    /// it keys the frame's random draws.
    number: u64,
    radio: Radio,
    data: Arc<[u8]>,
    start: Picos,
    end: Picos,
    tx_stamp: Option<u64>,
}

/// One frame at one receiver, once resolved.
#[derive(Clone, Debug)]
struct Reception {
    frame: Arc<Frame>,
    to: usize,
    /// When the frame's start reaches the receiver (start + D/c).
    arrival: Picos,
    /// When the reception ends (RX-done): arrival + airtime.
    end: Picos,
    distance_m: f64,
    rssi_dbm: f64,
    rx_stamp: Option<u64>,
    /// In range / above sensitivity: it can be received and it interferes.
    audible: bool,
    /// Heard but too weak to be decoded (the UWB's reception edge, §16).
    faded: bool,
    /// The loss draw fell below the loss probability.
    lost: bool,
    /// Its outcome is decided (it stays a while as an interferer).
    done: bool,
}

impl Reception {
    fn overlaps(&self, start: Picos, end: Picos) -> bool {
        self.arrival < end && start < self.end
    }
}

struct Drone {
    desc: DroneRadio,
    clock_ppt: i64,
    phase: Picos,
    /// Its DW1000's antenna delays (ps): the TX stamp precedes the frame's
    /// leaving the antenna by `tx_delay`, the RX stamp follows its arrival
    /// by `rx_delay` (0 and 0 with the "ideal" profile).
    tx_delay: i64,
    rx_delay: i64,
    retired: bool,
    frames_sent: u64,
    /// Its own transmissions (for half duplex), kept while they can overlap
    /// a reception not yet decided.
    own: Vec<Arc<Frame>>,
    /// Decided receptions not yet taken, in end order.
    inbox: Vec<(Picos, RadioPacket)>,
    /// Its transmissions whose TX-done was not yet taken.
    outbox: Vec<(Picos, u64, TxDone)>,
}

/// The radio channel between the drones of one world.
pub struct Channel {
    cfg: RadioConfig,
    drones: Vec<Drone>,
    /// Sent, start not yet resolved (start ≥ `resolved`).
    pending: Vec<Arc<Frame>>,
    /// Resolved receptions: undecided ones, and decided ones that may still
    /// overlap an undecided one.
    live: Vec<Reception>,
    /// Every frame that starts before this time is resolved, and every
    /// reception that ends at or before it is decided.
    resolved: Picos,
    log: Option<RadioLog>,
    /// The world's boxes, for the UWB's line of sight ([`Channel::with_obstacles`]).
    obstacles: Vec<Obstacle>,
    /// A drone's body, for the line of sight between two others.
    body: Body,
    /// The P2P shadowing of each link (lower index first), once it has
    /// carried a packet.
    shadows: std::collections::BTreeMap<(usize, usize), LinkShadow>,
}

impl Channel {
    /// A channel for these drones (index = order of the world file). Each
    /// drone's DW1000 clock phase is drawn from `cfg.seed`. `cfg` should have
    /// passed [`RadioConfig::validate`].
    pub fn new(cfg: RadioConfig, drones: Vec<DroneRadio>) -> Channel {
        let uwb = cfg.uwb();
        let drones = drones
            .into_iter()
            .enumerate()
            .map(|(i, desc)| {
                let (tx_delay, rx_delay) = link::antenna_delays(cfg.seed, i, &uwb);
                Drone {
                    clock_ppt: ppm_to_ppt(desc.clock_ppm),
                    phase: draw::clock_phase(cfg.seed, i),
                    tx_delay,
                    rx_delay,
                    desc,
                    retired: false,
                    frames_sent: 0,
                    own: Vec::new(),
                    inbox: Vec::new(),
                    outbox: Vec::new(),
                }
            })
            .collect();
        Channel {
            cfg,
            drones,
            pending: Vec::new(),
            live: Vec::new(),
            resolved: Picos(0),
            log: None,
            obstacles: Vec::new(),
            body: Body {
                radius: crate::crazyflie::BODY_RADIUS_M,
                height: crate::crazyflie::BODY_HEIGHT_M,
            },
            shadows: Default::default(),
        }
    }

    /// The world's boxes, which block the UWB's direct path (the "dw1000"
    /// profile's NLOS, DESIGN.md §16).
    pub fn with_obstacles(mut self, obstacles: Vec<Obstacle>) -> Channel {
        self.obstacles = obstacles;
        self
    }

    /// Drone `drone`'s antenna delays (TX, RX) in ps.
    pub fn antenna_delays(&self, drone: usize) -> Option<(i64, i64)> {
        self.drones.get(drone).map(|d| (d.tx_delay, d.rx_delay))
    }

    pub fn config(&self) -> &RadioConfig {
        &self.cfg
    }

    /// Every frame starting before this time has been resolved.
    pub fn resolved_until(&self) -> Picos {
        self.resolved
    }

    /// Drone `drone`'s DW1000 clock phase (ps), drawn from the seed.
    pub fn phase(&self, drone: usize) -> Option<Picos> {
        self.drones.get(drone).map(|d| d.phase)
    }

    /// `stamp_d(t)` of DESIGN.md §8: drone `drone`'s DW1000 clock at world
    /// time `t`. An unknown drone reads 0.
    pub fn stamp(&self, drone: usize, t: Picos) -> Dw1000Ticks {
        match self.drones.get(drone) {
            Some(d) => dw1000_stamp(t, d.clock_ppt, d.phase),
            None => Dw1000Ticks(0),
        }
    }

    /// What [`Channel::send`] checks before it sends: the drone, its
    /// radio, the payload's length, a start not before what is resolved.
    /// The session asks it too, to know whether a RADIO_SEND will pass.
    pub fn check_send(
        &self,
        from: usize,
        radio: Radio,
        len: usize,
        start: Picos,
    ) -> Result<(), ChannelError> {
        let d = self
            .drones
            .get(from)
            .ok_or(ChannelError::UnknownDrone(from))?;
        let name = || d.desc.name.clone();
        if d.retired {
            return Err(ChannelError::Retired { drone: name() });
        }
        if !d.desc.radios.contains(&radio) {
            return Err(ChannelError::NoSuchRadio {
                drone: name(),
                radio,
            });
        }
        if len == 0 || len > radio.max_payload() {
            return Err(ChannelError::BadLength {
                drone: name(),
                radio,
                len,
                max: radio.max_payload(),
            });
        }
        if start < self.resolved {
            return Err(ChannelError::InThePast {
                drone: name(),
                start: start.0,
                resolved: self.resolved.0,
            });
        }
        Ok(())
    }

    /// RADIO_SEND of drone `from`: a transmission starting at world time
    /// `start`. It is resolved (positions, receptions) by the first
    /// [`Channel::resolve`] past `start`; its TX-done is ready at once.
    ///
    /// A drone may start a frame while its previous one is still on the air
    /// (the platform's peripheral forbids it; the channel just puts both on
    /// the air, where they collide at every receiver).
    pub fn send(
        &mut self,
        from: usize,
        radio: Radio,
        data: Vec<u8>,
        start: Picos,
    ) -> Result<(), ChannelError> {
        self.check_send(from, radio, data.len(), start)?;
        let d = &mut self.drones[from];
        // The chip stamps the frame when it leaves its digital part (the
        // platform's start, also a delayed TX's programmed time); the
        // antenna radiates it tx_delay later (DESIGN.md §16; 0 with the
        // "ideal" profile).
        let tx_stamp = (radio == Radio::Uwb).then(|| dw1000_stamp(start, d.clock_ppt, d.phase).0);
        let start = match radio {
            Radio::Uwb => link::shift(start, d.tx_delay),
            Radio::P2p => start,
        };
        let end = start + radio.airtime(data.len());
        let number = d.frames_sent;
        d.frames_sent += 1;
        let frame = Arc::new(Frame {
            from,
            number,
            radio,
            data: data.into(),
            start,
            end,
            tx_stamp,
        });
        d.outbox.push((
            end,
            number,
            TxDone {
                radio,
                time_ps: end.0,
                tx_stamp,
            },
        ));
        d.own.push(frame.clone());
        self.pending.push(frame);
        Ok(())
    }

    /// The physics has been simulated up to `until`: resolve every queued
    /// transmission whose start is before `until` (`position(drone, t)` is
    /// the drone's centre in metres at world time t), then decide every
    /// reception that ends at or before `until`: no frame still to come can
    /// overlap it (a later RADIO_SEND starts at `until` or after).
    pub fn resolve(&mut self, until: Picos, position: &dyn Fn(usize, Picos) -> [f64; 3]) {
        if until <= self.resolved {
            return;
        }
        let (mut now, later): (Vec<_>, Vec<_>) = std::mem::take(&mut self.pending)
            .into_iter()
            .partition(|f| f.start < until);
        self.pending = later;
        // In time order: a link's shadowing evolves from packet to packet.
        now.sort_by_key(|f| (f.start, f.from, f.number));
        for frame in now {
            self.resolve_frame(&frame, position);
        }
        self.resolved = until;
        self.decide();
        self.prune();
    }

    /// Decides every undecided reception that ends at or before `resolved`,
    /// in (end, sender, frame, receiver) order: log rows and inboxes.
    fn decide(&mut self) {
        let mut ready: Vec<usize> = (0..self.live.len())
            .filter(|&i| !self.live[i].done && self.live[i].end <= self.resolved)
            .collect();
        ready.sort_by_key(|&i| {
            let r = &self.live[i];
            (r.end, r.frame.from, r.frame.number, r.to)
        });
        for i in ready {
            let outcome = self.outcome(i);
            self.log_row(i, outcome);
            let r = &self.live[i];
            if outcome == Outcome::Received {
                let packet = RadioPacket {
                    radio: r.frame.radio,
                    from: self.drones[r.frame.from].desc.name.clone(),
                    data: r.frame.data.to_vec(),
                    time_ps: r.end.0,
                    rssi: r.rssi_dbm,
                    rx_stamp: r.rx_stamp,
                };
                self.drones[r.to].inbox.push((r.end, packet));
            }
            self.live[i].done = true;
        }
    }

    /// The outcome of reception `i`, all of whose possible interferers are
    /// known (it ends at or before `resolved`).
    /// Writes live frame `i`'s row to the radio log, if one is kept.
    fn log_row(&mut self, i: usize, outcome: Outcome) {
        let Some(log) = &mut self.log else { return };
        let r = &self.live[i];
        log.write(
            r.frame.from,
            r.to,
            &LogRow {
                start_ps: r.frame.start.0,
                end_ps: r.end.0,
                radio: r.frame.radio,
                from: &self.drones[r.frame.from].desc.name,
                to: &self.drones[r.to].desc.name,
                distance_m: r.distance_m,
                rssi_dbm: r.rssi_dbm,
                outcome,
                tx_stamp: r.frame.tx_stamp,
                rx_stamp: r.rx_stamp,
            },
        );
    }

    fn outcome(&self, i: usize) -> Outcome {
        let r = &self.live[i];
        if !r.audible || r.faded {
            return Outcome::OutOfRange;
        }
        let radio = r.frame.radio;
        let transmitting = self.drones[r.to]
            .own
            .iter()
            .any(|f| f.radio == radio && r.overlaps(f.start, f.end));
        if transmitting {
            return Outcome::HalfDuplex;
        }
        let collided = self.live.iter().enumerate().any(|(j, x)| {
            j != i
                && x.to == r.to
                && x.audible
                && x.frame.radio == radio
                && r.overlaps(x.arrival, x.end)
        });
        if collided {
            return Outcome::Collision;
        }
        if r.lost {
            return Outcome::Lost;
        }
        Outcome::Received
    }

    /// Forgets what can no longer overlap an undecided reception: one of
    /// those ends after `resolved`, so it arrived after `resolved` − the
    /// longest frame of its radio.
    fn prune(&mut self) {
        let horizon = |radio: Radio| {
            let longest = radio.airtime(radio.max_payload()).0;
            self.resolved.0.saturating_sub(longest)
        };
        let (h_uwb, h_p2p) = (horizon(Radio::Uwb), horizon(Radio::P2p));
        let keep = |radio: Radio, end: Picos| {
            end.0
                > match radio {
                    Radio::Uwb => h_uwb,
                    Radio::P2p => h_p2p,
                }
        };
        self.live.retain(|r| !r.done || keep(r.frame.radio, r.end));
        for d in &mut self.drones {
            d.own
                .retain(|f| f.start >= self.resolved || keep(f.radio, f.end));
        }
    }

    /// RADIO_RECV of `drone` at its clock `until`: every reception that
    /// ended at or before `until` (in end order, then sender, frame), each
    /// once, and its own transmissions that ended by then (TX-done). The
    /// world has resolved the channel up to `until` first; a reception that
    /// is not decided yet is kept for a later call.
    pub fn take(&mut self, drone: usize, until: Picos) -> (Vec<RadioPacket>, Vec<TxDone>) {
        let Some(d) = self.drones.get_mut(drone) else {
            return (Vec::new(), Vec::new());
        };
        let n = d.inbox.partition_point(|(end, _)| *end <= until);
        let packets = d.inbox.drain(..n).map(|(_, p)| p).collect();
        d.outbox.sort_by_key(|(end, number, _)| (*end, *number));
        let n = d.outbox.partition_point(|(end, _, _)| *end <= until);
        let tx_done = d.outbox.drain(..n).map(|(_, _, t)| t).collect();
        (packets, tx_done)
    }

    /// A drone that has stopped (STOP) or left: it neither transmits nor
    /// receives any more. Its frames already sent still go on the air (they
    /// were started before it stopped); its undecided receptions end as
    /// `retired` in the log; what it had not taken is dropped.
    pub fn retire(&mut self, drone: usize) {
        let Some(d) = self.drones.get_mut(drone) else {
            return;
        };
        if d.retired {
            return;
        }
        d.retired = true;
        d.inbox.clear();
        d.outbox.clear();
        let mut gone: Vec<usize> = (0..self.live.len())
            .filter(|&i| self.live[i].to == drone && !self.live[i].done)
            .collect();
        gone.sort_by_key(|&i| {
            let r = &self.live[i];
            (r.end, r.frame.from, r.frame.number)
        });
        for &i in &gone {
            self.log_row(i, Outcome::Retired);
        }
        self.live.retain(|r| r.to != drone);
    }

    /// Writes one CSV row per (frame, receiver) from now on (header first).
    pub fn set_log(&mut self, w: Box<dyn std::io::Write + Send>) {
        self.log.get_or_insert_with(RadioLog::default).set_csv(w);
    }

    /// Keeps every decided reception for [`Channel::take_events`] (the
    /// world's MCAP, `crate::foxglove`).
    pub fn keep_events(&mut self) {
        self.log.get_or_insert_with(RadioLog::default).keep_events();
    }

    /// The receptions decided since the last call, in log order.
    pub fn take_events(&mut self) -> Vec<RadioEvent> {
        self.log
            .as_mut()
            .map(RadioLog::take_events)
            .unwrap_or_default()
    }

    /// Flushes the log; returns the first write error met since
    /// [`Channel::set_log`], if any. Without a log it does nothing.
    pub fn flush_log(&mut self) -> std::io::Result<()> {
        match &mut self.log {
            Some(log) => log.flush(),
            None => Ok(()),
        }
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Log-distance path loss: `p_1m − 10·n·log10(d)` dBm.
pub fn log_distance(p_1m_dbm: f64, n: f64, distance_m: f64) -> f64 {
    p_1m_dbm - 10.0 * n * distance_m.max(MIN_RSSI_DISTANCE_M).log10()
}
