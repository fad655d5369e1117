//! The radios as peripherals (DESIGN.md §8, docs/SWARM.md §4.3): the
//! DW1000 of the Loco Positioning deck ([`uwb`]) and the nRF51's P2P radio
//! ([`p2p`]). Both have the same register file (one driver shape), written
//! here once; each radio module gives its own figures (payload limit, stamps,
//! datasheet currents).
//!
//! | offset | size | name | access | meaning |
//! |---|---|---|---|---|
//! | 0x00 | u8 | CTRL | W | 1 INIT, 2 TX_START, 3 RX_ON, 4 RX_OFF, 5 SLEEP (reads the last command) |
//! | 0x01 | u8 | STATUS | R, W1C | bit0 INIT_DONE, bit1 TX_DONE, bit2 RX_DONE, bit3 RX_OVERRUN |
//! | 0x02 | u8 | IRQ_MASK | RW | STATUS bits that raise the core's external interrupt |
//! | 0x03 | u8 | STATE | R | 0 SLEEP/OFF, 1 IDLE, 2 RX, 3 TX |
//! | 0x04 | u8 | TX_LEN | RW | payload length |
//! | 0x05 | u8 | RX_LEN | R | length of the frame in RX_BUF |
//! | 0x06 | u8 | RX_PENDING | R | frames waiting behind the one in RX_BUF |
//! | 0x08 | u64 | TX_STAMP | R | 40-bit DW1000 stamp of the last finished transmission |
//! | 0x10 | u64 | RX_STAMP | R | 40-bit DW1000 stamp of the frame in RX_BUF |
//! | 0x18 | i32 | RX_RSSI | R | RSSI of the frame in RX_BUF, 1/100 dBm |
//! | 0x1C | u32 | RX_LOST | R | frames lost: receiver off when they ended, or FIFO full |
//! | 0x20 | u64 | EUI | R | the radio's identifier (run key `radio_id`) |
//! | 0x28 | u32 | TX_DELAY | RW | delay (ns) of the next TX_START; back to 0 after it |
//! | 0x40 | 128 B | TX_BUF | RW | payload to send |
//! | 0xC0 | 128 B | RX_BUF | R | payload received |
//!
//! Offsets not in the table read 0; writing them, or a read-only register,
//! is an error (so a firmware that stores a word over CTRL..STATE learns it
//! at once instead of silently clearing STATUS bits).
//!
//! **Time.** Everything the world reports is delivered at a platform time
//! (docs/SWARM.md §4.2) and becomes visible in the registers exactly then:
//! deliveries are device events of the kernel, and [`RadioDevice::stable_until`]
//! names the next one, so the ISS's idle skipping stays exact and a core
//! sleeping in `wfi` wakes when a frame arrives. A frame is received only if
//! the receiver was on (STATE = RX) at the platform time its reception ended.
//! The receiver stays on after a frame (the DW1000's RX auto re-enable) and
//! returns to RX after a transmission started from RX.
//!
//! **Delayed transmission** (the DW1000's DX_TIME with SYS_CTRL.TXDLYS,
//! DW1000 User Manual §3.3 and register 0x0A; here relative to the command,
//! in whole nanoseconds, instead of an absolute device time whose low 9 bits
//! are ignored): TX_START with TX_DELAY = d sends the frame d after the
//! command, in world time too (docs/SWARM.md §4.2); the radio is busy (STATE
//! TX, further TX_STARTs refused) from the command to the end of the airtime
//! and draws the TX current for the airtime only. TX_DELAY is one-shot: it
//! reads 0 again after the TX_START that used it, so a firmware that never
//! writes it transmits at once, as before.
//!
//! **Power.** OFF (before INIT: the radio draws nothing, so a platform that
//! never switches a radio on is electrically the thesis's), SLEEP, IDLE, RX,
//! and TX for exactly the frame's airtime (`protocol::radio::airtime`, the
//! world's own figure). A TX lasts ~0.2 ms, less than the 1 ms power sample,
//! so the power side hands the mean current over each sample interval to the
//! power network, not the state at the sample's instant ([`RadioPower`]).

pub mod p2p;
mod power;
pub mod uwb;

use std::collections::VecDeque;

use protocol::radio::{Radio as RadioKind, RadioPacket, TxDone};
use protocol::Request;

pub use power::{RadioCurrents, RadioPower, RadioPowerState};

use super::{DeviceCtx, DeviceError, LinkError};
use crate::config::PlatformConfig;
use crate::units::{Nanos, Picos};

/// Register offsets within a radio.
pub const CTRL: u32 = 0x00;
pub const STATUS: u32 = 0x01;
pub const IRQ_MASK: u32 = 0x02;
pub const STATE: u32 = 0x03;
pub const TX_LEN: u32 = 0x04;
pub const RX_LEN: u32 = 0x05;
pub const RX_PENDING: u32 = 0x06;
pub const TX_STAMP: u32 = 0x08;
pub const RX_STAMP: u32 = 0x10;
pub const RX_RSSI: u32 = 0x18;
pub const RX_LOST: u32 = 0x1C;
pub const EUI: u32 = 0x20;
pub const TX_DELAY: u32 = 0x28;
pub const TX_BUF: u32 = 0x40;
pub const RX_BUF: u32 = 0xC0;
/// Bytes of one payload buffer (a DW1000 frame holds at most 127).
pub const BUF_SIZE: u32 = 128;
/// Size of a radio's register memory.
pub const REGISTER_MEMORY: u32 = RX_BUF + BUF_SIZE;

/// Commands (CTRL).
pub const CMD_INIT: u8 = 1;
pub const CMD_TX_START: u8 = 2;
pub const CMD_RX_ON: u8 = 3;
pub const CMD_RX_OFF: u8 = 4;
pub const CMD_SLEEP: u8 = 5;

/// STATUS bits.
pub const INIT_DONE: u8 = 1 << 0;
pub const TX_DONE: u8 = 1 << 1;
pub const RX_DONE: u8 = 1 << 2;
pub const RX_OVERRUN: u8 = 1 << 3;

/// STATE values.
pub const STATE_SLEEP: u8 = 0;
pub const STATE_IDLE: u8 = 1;
pub const STATE_RX: u8 = 2;
pub const STATE_TX: u8 = 3;

/// Frames the receiver holds: the one in RX_BUF and 7 behind it. A real
/// DW1000 double-buffers 2; the delivery latency of docs/SWARM.md §4.2 (up
/// to a basicTimeStep) must not turn into overruns.
pub const RX_FIFO_FRAMES: usize = 8;

/// How long the receiver's on/off history is kept behind the present: a
/// frame's end maps to a platform time at most about one device delay
/// before the poll that reports it (docs/SWARM.md §4.2), far less than this.
const RX_HISTORY: Picos = Picos::from_ms(1000);

/// What tells the two radios apart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadioSpec {
    pub kind: RadioKind,
    /// Name in errors, the platform file and the outputs.
    pub name: &'static str,
    /// The radio reports DW1000 stamps (TX_STAMP, RX_STAMP).
    pub stamps: bool,
    /// Currents when the platform file does not give them.
    pub default_currents: RadioCurrents,
}

impl RadioSpec {
    pub fn max_payload(&self) -> usize {
        self.kind.max_payload()
    }

    /// The radio's currents: the platform file's states (`tx`, `rx`,
    /// `idle`, `sleep`, mA) where given, the datasheet's otherwise; all zero
    /// for a sensor with `"power": false`.
    pub fn currents(&self, platform: &PlatformConfig) -> RadioCurrents {
        let d = self.default_currents;
        let Some(s) = platform.sensor(self.name) else {
            return d;
        };
        if !s.power {
            return RadioCurrents::ZERO;
        }
        let get = |name: &str, default| s.state(name).map_or(default, |st| st.current());
        RadioCurrents {
            tx: get("tx", d.tx),
            rx: get("rx", d.rx),
            idle: get("idle", d.idle),
            sleep: get("sleep", d.sleep),
        }
    }
}

/// The commanded state apart from a transmission in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Off,
    Sleep,
    Idle,
    Rx,
}

/// A received frame in RX_BUF or the FIFO.
#[derive(Debug, Clone, PartialEq)]
struct Frame {
    data: Vec<u8>,
    stamp: u64,
    rssi_centi_dbm: i32,
}

/// Something the world reported, due at a platform time.
#[derive(Debug, Clone, PartialEq)]
enum Delivery {
    InitDone,
    TxDone {
        stamp: u64,
    },
    /// A reception that ended at platform time `ended`.
    Frame {
        ended: Picos,
        frame: Frame,
    },
}

/// Counters for `summary.json`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RadioStats {
    pub frames_sent: u64,
    pub frames_received: u64,
    /// Frames that ended while the receiver was off.
    pub frames_missed: u64,
    /// Frames lost because the FIFO was full.
    pub rx_overruns: u64,
}

/// One radio: its register file, receive FIFO, deliveries and power side.
#[derive(Debug, Clone)]
pub struct RadioDevice {
    spec: RadioSpec,
    eui: u64,
    control: u8,
    status: u8,
    irq_mask: u8,
    mode: Mode,
    /// The radio has been switched on (INIT) at least once.
    switched_on: bool,
    /// A transmission is on the air until this platform time.
    tx_until: Picos,
    tx_len: u8,
    /// TX_DELAY: the delay of the next TX_START (one-shot).
    tx_delay: Nanos,
    tx_buf: [u8; BUF_SIZE as usize],
    tx_stamp: u64,
    /// The frame in RX_BUF (kept after RX_DONE is cleared, until the next).
    rx_frame: Option<Frame>,
    fifo: VecDeque<Frame>,
    rx_lost: u32,
    /// Deliveries in time order (never earlier than the previous one, so
    /// frames keep the order in which they ended).
    pending: VecDeque<(Picos, Delivery)>,
    /// Receiver on/off changes (platform time, on).
    rx_log: Vec<(Picos, bool)>,
    /// World time (ps) at which this radio's last transmission ends.
    world_tx_end: u64,
    pub power: RadioPower,
    pub stats: RadioStats,
}

impl RadioDevice {
    pub fn new(spec: RadioSpec, eui: u64, currents: RadioCurrents) -> Self {
        RadioDevice {
            spec,
            eui,
            control: 0,
            status: 0,
            irq_mask: 0,
            mode: Mode::Off,
            switched_on: false,
            tx_until: Picos::ZERO,
            tx_len: 0,
            tx_delay: Nanos(0),
            tx_buf: [0; BUF_SIZE as usize],
            tx_stamp: 0,
            rx_frame: None,
            fifo: VecDeque::new(),
            rx_lost: 0,
            pending: VecDeque::new(),
            rx_log: Vec::new(),
            world_tx_end: 0,
            power: RadioPower::new(currents),
            stats: RadioStats::default(),
        }
    }

    pub fn spec(&self) -> &RadioSpec {
        &self.spec
    }

    /// INIT has been executed at least once: the platform then polls the
    /// world for this drone's receptions after every advance of its clock.
    pub fn switched_on(&self) -> bool {
        self.switched_on
    }

    /// The radio's interrupt request: `STATUS & IRQ_MASK` is not zero.
    pub fn irq(&self) -> bool {
        self.status & self.irq_mask != 0
    }

    /// The next delivery, a device event of the kernel.
    pub fn next_event(&self) -> Option<Picos> {
        self.pending.front().map(|(t, _)| *t)
    }

    /// Makes every delivery due at `now` visible.
    pub fn apply_due(&mut self, now: Picos) {
        while let Some((t, _)) = self.pending.front() {
            if *t > now {
                break;
            }
            let (_, delivery) = self.pending.pop_front().expect("front exists");
            match delivery {
                Delivery::InitDone => self.status |= INIT_DONE,
                Delivery::TxDone { stamp } => {
                    self.tx_stamp = stamp;
                    self.status |= TX_DONE;
                }
                Delivery::Frame { ended, frame } => self.receive(ended, frame),
            }
        }
    }

    fn receive(&mut self, ended: Picos, frame: Frame) {
        if !self.rx_on_at(ended) {
            self.rx_lost = self.rx_lost.saturating_add(1);
            self.stats.frames_missed += 1;
            return;
        }
        if self.status & RX_DONE == 0 {
            self.rx_frame = Some(frame);
            self.status |= RX_DONE;
        } else if self.fifo.len() + 1 < RX_FIFO_FRAMES {
            self.fifo.push_back(frame);
        } else {
            self.status |= RX_OVERRUN;
            self.rx_lost = self.rx_lost.saturating_add(1);
            self.stats.rx_overruns += 1;
            return;
        }
        self.stats.frames_received += 1;
    }

    /// Whether the receiver was on at platform time `t`.
    fn rx_on_at(&self, t: Picos) -> bool {
        self.rx_log
            .iter()
            .rev()
            .find(|(at, _)| *at <= t)
            .is_some_and(|(_, on)| *on)
    }

    fn set_mode(&mut self, now: Picos, mode: Mode) {
        let was_rx = self.mode == Mode::Rx;
        self.mode = mode;
        if was_rx != (mode == Mode::Rx) {
            self.rx_log.push((now, mode == Mode::Rx));
            // Keep the last change before the history window (it gives the
            // state at the window's start) and everything after it.
            let cut = now.saturating_sub(RX_HISTORY);
            let keep_from = self.rx_log.iter().rposition(|(t, _)| *t <= cut);
            if let Some(i) = keep_from {
                self.rx_log.drain(..i);
            }
        }
        self.power.set(
            now,
            match mode {
                Mode::Off => RadioPowerState::Off,
                Mode::Sleep => RadioPowerState::Sleep,
                Mode::Idle => RadioPowerState::Idle,
                Mode::Rx => RadioPowerState::Rx,
            },
        );
    }

    fn state_reg(&self, now: Picos) -> u8 {
        if now < self.tx_until {
            return STATE_TX;
        }
        match self.mode {
            Mode::Off | Mode::Sleep => STATE_SLEEP,
            Mode::Idle => STATE_IDLE,
            Mode::Rx => STATE_RX,
        }
    }

    /// A read of the byte at `offset` at time `now`.
    pub fn read(&mut self, offset: u32, now: Picos) -> u8 {
        self.apply_due(now);
        let byte = |v: u64, base: u32| (v >> (8 * (offset - base))) as u8;
        let frame = self.rx_frame.as_ref();
        match offset {
            CTRL => self.control,
            STATUS => self.status,
            IRQ_MASK => self.irq_mask,
            STATE => self.state_reg(now),
            TX_LEN => self.tx_len,
            RX_LEN => frame.map_or(0, |f| f.data.len() as u8),
            RX_PENDING => self.fifo.len() as u8,
            o if (TX_STAMP..TX_STAMP + 8).contains(&o) => byte(self.tx_stamp, TX_STAMP),
            o if (RX_STAMP..RX_STAMP + 8).contains(&o) => {
                byte(frame.map_or(0, |f| f.stamp), RX_STAMP)
            }
            o if (RX_RSSI..RX_RSSI + 4).contains(&o) => {
                byte(frame.map_or(0, |f| f.rssi_centi_dbm as u32 as u64), RX_RSSI)
            }
            o if (RX_LOST..RX_LOST + 4).contains(&o) => byte(u64::from(self.rx_lost), RX_LOST),
            o if (EUI..EUI + 8).contains(&o) => byte(self.eui, EUI),
            o if (TX_DELAY..TX_DELAY + 4).contains(&o) => {
                byte(u64::from(self.tx_delay.0), TX_DELAY)
            }
            o if (TX_BUF..TX_BUF + BUF_SIZE).contains(&o) => self.tx_buf[(o - TX_BUF) as usize],
            o if (RX_BUF..RX_BUF + BUF_SIZE).contains(&o) => frame
                .and_then(|f| f.data.get((o - RX_BUF) as usize).copied())
                .unwrap_or(0),
            _ => 0,
        }
    }

    /// The idle-skip contract: when a read of `offset` could next differ.
    pub fn stable_until(&self, offset: u32, now: Picos) -> Picos {
        let next = match self.next_event() {
            Some(t) if t <= now => return now, // due: applied by the read itself
            Some(t) => t,
            None => Picos::MAX,
        };
        match offset {
            STATE if self.tx_until > now => next.min(self.tx_until),
            CTRL | IRQ_MASK | TX_LEN => Picos::MAX,
            o if (EUI..EUI + 8).contains(&o)
                || (TX_DELAY..TX_DELAY + 4).contains(&o)
                || (TX_BUF..TX_BUF + BUF_SIZE).contains(&o) =>
            {
                Picos::MAX
            }
            _ => next,
        }
    }

    /// A write of `value` to the byte at `offset` at time `now`.
    pub fn write(
        &mut self,
        offset: u32,
        value: u8,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        self.apply_due(now);
        match offset {
            CTRL => {
                self.control = value;
                self.command(value, now, ctx)
            }
            STATUS => {
                self.clear_status(value);
                Ok(())
            }
            IRQ_MASK => {
                self.irq_mask = value;
                Ok(())
            }
            TX_LEN => {
                self.tx_len = value;
                Ok(())
            }
            o if (TX_BUF..TX_BUF + BUF_SIZE).contains(&o) => {
                self.tx_buf[(o - TX_BUF) as usize] = value;
                Ok(())
            }
            o if (TX_DELAY..TX_DELAY + 4).contains(&o) => {
                let shift = 8 * (o - TX_DELAY);
                self.tx_delay =
                    Nanos(self.tx_delay.0 & !(0xFF << shift) | u32::from(value) << shift);
                Ok(())
            }
            o => Err(self.invalid(format!(
                "the register at offset {o:#x} is read-only (write {value:#04x}); \
                 write CTRL, STATUS, IRQ_MASK, TX_LEN and TX_DELAY with byte stores"
            ))),
        }
    }

    /// W1C: clearing RX_DONE moves the next frame of the FIFO into RX_BUF.
    fn clear_status(&mut self, bits: u8) {
        self.status &= !bits;
        if bits & RX_DONE != 0 {
            if let Some(next) = self.fifo.pop_front() {
                self.rx_frame = Some(next);
                self.status |= RX_DONE;
            }
        }
    }

    fn command(
        &mut self,
        value: u8,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        if value > CMD_SLEEP {
            return Err(DeviceError::UnknownCommand {
                device: self.spec.name,
                value,
            });
        }
        if !matches!(value, 0 | CMD_INIT) && !self.switched_on {
            return Err(self.invalid(format!(
                "command {value} before INIT: switch the radio on first"
            )));
        }
        match value {
            0 => Ok(()),
            CMD_INIT => self.init(now, ctx),
            CMD_TX_START => self.transmit(now, ctx),
            CMD_RX_ON | CMD_RX_OFF => {
                if self.mode == Mode::Sleep {
                    return Err(self.invalid(format!(
                        "command {value} while asleep: INIT wakes the radio"
                    )));
                }
                let mode = if value == CMD_RX_ON {
                    Mode::Rx
                } else {
                    Mode::Idle
                };
                self.set_mode(now, mode);
                Ok(())
            }
            CMD_SLEEP => {
                self.set_mode(now, Mode::Sleep);
                Ok(())
            }
            _ => unreachable!("checked above"),
        }
    }

    /// INIT: claims the world if no device has (GET_INIT_DATA and the
    /// start-up alignment); the platform's ticker then moves the drone's
    /// clock unless the STM32 does (docs/SWARM.md §4.1). INIT_DONE shows
    /// when the alignment is over (at once if it is).
    fn init(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        let name = self.spec.name;
        ctx.session
            .open(now, ctx.world, ctx.time)
            .map_err(|e| match e {
                super::world_session::SessionError::World(error) => DeviceError::World {
                    device: name,
                    error,
                },
                super::world_session::SessionError::Invalid(message) => DeviceError::Invalid {
                    device: name,
                    message,
                },
            })?;
        if ctx.session.is_stopped() {
            return Err(self.invalid("INIT after STOP: the world session is over".into()));
        }
        ctx.session.start_ticker();
        self.switched_on = true;
        self.set_mode(now, Mode::Idle);
        let at = now.max(ctx.session.ready_at());
        self.schedule(now, at, Delivery::InitDone);
        Ok(())
    }

    /// TX_START: RADIO_SEND now, with the offset of docs/SWARM.md §4.2 plus
    /// TX_DELAY; the radio is busy from now to the end of the frame, in TX
    /// (power) for its airtime from now + TX_DELAY; TX_DONE (with TX_STAMP)
    /// comes when the world reports the transmission finished.
    fn transmit(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        if self.mode == Mode::Sleep {
            return Err(self.invalid("TX_START while asleep: INIT wakes the radio".into()));
        }
        if now < self.tx_until {
            return Err(self.invalid(format!(
                "TX_START while a transmission is on the air (until {})",
                self.tx_until
            )));
        }
        let len = usize::from(self.tx_len);
        if len == 0 || len > self.spec.max_payload() {
            return Err(self.invalid(format!(
                "TX_LEN {len} is not a payload length (1 to {} bytes)",
                self.spec.max_payload()
            )));
        }
        if ctx.session.is_stopped() {
            // The platform ended the world session by itself (the CRTP
            // link closed, the battery's end): the firmware, which only
            // looks at that between two transmissions, may start one more.
            // It goes into a world that no longer listens: nothing is
            // sent, no TX_DONE comes, the run is ending. (An error here
            // failed 1 in 5 lab-delivery runs, by the wall clock's timing.)
            tracing::debug!(device = %self.spec.name, "TX_START after the world session ended: not sent");
            return Ok(());
        }
        if !ctx.session.is_live() {
            return Err(self.invalid("TX_START before the world session opened".into()));
        }
        // p − p_d, but never before the drone's clock nor before the end of
        // this radio's previous transmission in world time (a flying
        // firmware's transmissions during one device delay all map to the
        // delay's end; they must not overlap there); then TX_DELAY later.
        let p_d = ctx.time.accounted_until();
        let t_d = ctx.session.world_clock(ctx.time).0;
        let delay = std::mem::take(&mut self.tx_delay).to_picos();
        let offset_ps = now
            .0
            .saturating_sub(p_d.0)
            .max(self.world_tx_end.saturating_sub(t_d))
            + delay.0;
        let airtime = self.spec.kind.airtime(len);
        self.world_tx_end = t_d + offset_ps + airtime.0;
        let request = Request::RadioSend {
            radio: self.spec.kind,
            data: self.tx_buf[..len].to_vec(),
            offset_ps,
        };
        ctx.world
            .send(&request, now)
            .map_err(|error| self.world_err(error))?;
        self.tx_until = now + delay + Picos(airtime.0);
        self.power.transmit(now + delay, self.tx_until);
        self.stats.frames_sent += 1;
        Ok(())
    }

    fn schedule(&mut self, now: Picos, at: Picos, d: Delivery) {
        let last = self.pending.back().map_or(Picos::ZERO, |(t, _)| *t);
        self.pending.push_back((at.max(now).max(last), d));
    }

    /// Hands a reception of this radio to the receiver: it ended at world
    /// time `t`, which is platform time `ended`; it shows at `max(now, ended)`.
    pub fn deliver_packet(
        &mut self,
        now: Picos,
        ended: Picos,
        p: RadioPacket,
    ) -> Result<(), DeviceError> {
        if p.data.is_empty() || p.data.len() > self.spec.max_payload() {
            return Err(self.invalid(format!(
                "the world delivered a {}-byte frame from {} (1 to {} bytes)",
                p.data.len(),
                p.from,
                self.spec.max_payload()
            )));
        }
        let stamp = match (self.spec.stamps, p.rx_stamp) {
            (true, Some(s)) => s & protocol::radio::DW1000_STAMP_MASK,
            (true, None) => {
                return Err(self.invalid(format!(
                    "the world delivered a frame from {} without rx_stamp",
                    p.from
                )))
            }
            (false, _) => 0,
        };
        let rssi = (p.rssi * 100.0).round();
        let rssi_centi_dbm = if rssi.is_finite() {
            rssi.clamp(i32::MIN as f64, i32::MAX as f64) as i32
        } else {
            i32::MIN
        };
        let frame = Frame {
            data: p.data,
            stamp,
            rssi_centi_dbm,
        };
        self.schedule(now, ended, Delivery::Frame { ended, frame });
        Ok(())
    }

    /// Hands the end of one of this radio's transmissions (platform time
    /// `ended`) to it: TX_DONE and TX_STAMP at `max(now, ended)`.
    pub fn deliver_tx_done(
        &mut self,
        now: Picos,
        ended: Picos,
        d: TxDone,
    ) -> Result<(), DeviceError> {
        let stamp = match (self.spec.stamps, d.tx_stamp) {
            (true, Some(s)) => s & protocol::radio::DW1000_STAMP_MASK,
            (true, None) => {
                return Err(self
                    .invalid("the world reported a finished transmission without tx_stamp".into()))
            }
            (false, _) => 0,
        };
        self.schedule(now, ended, Delivery::TxDone { stamp });
        Ok(())
    }

    fn invalid(&self, message: String) -> DeviceError {
        DeviceError::Invalid {
            device: self.spec.name,
            message,
        }
    }

    fn world_err(&self, error: LinkError) -> DeviceError {
        DeviceError::World {
            device: self.spec.name,
            error,
        }
    }
}

/// The platform time of world time `t` (ps): `p_d + (t − t_d)`
/// (docs/SWARM.md §4.2), never before 0.
pub fn platform_time_of(t_world: u64, t_d: Picos, p_d: Picos) -> Picos {
    let p = i128::from(p_d.0) + i128::from(t_world) - i128::from(t_d.0);
    Picos(p.clamp(0, i128::from(u64::MAX)) as u64)
}

#[cfg(test)]
mod tests;
