//! The radios' register file, FIFO, W1C, interrupt request, timing and
//! power states, against the in-process [`SoloWorld`].

use protocol::radio::{Radio, RadioPacket, TxDone};
use protocol::Request;

use super::*;
use crate::peripherals::{DeviceCtx, Motors, SoloWorld, WorldSession};
use crate::sync::{SyncMode, TimeKeeper};
use crate::units::{Amps, Millis, Picos};

struct Bench {
    world: SoloWorld,
    session: WorldSession,
    time: TimeKeeper,
    motors: Motors,
    radio: RadioDevice,
}

impl Bench {
    fn new(spec: RadioSpec) -> Self {
        Bench {
            world: SoloWorld::new([0.0, 0.0, 0.015], Millis(4)),
            session: WorldSession::new(None, protocol::ImageEncoding::Array),
            time: TimeKeeper::new(SyncMode::Thesis),
            motors: Motors::default(),
            radio: RadioDevice::new(spec, 0x0102_0304_0506_0708, spec.default_currents),
        }
    }

    fn write(&mut self, offset: u32, value: u8, now: Picos) -> Result<(), DeviceError> {
        let mut sink = |_: &str| {};
        let mut ctx = DeviceCtx {
            world: &mut self.world,
            session: &mut self.session,
            time: &mut self.time,
            motors: &mut self.motors,
            battery_low: false,
            console: &mut sink,
        };
        self.radio.write(offset, value, now, &mut ctx)
    }

    fn read_u64(&mut self, offset: u32, now: Picos) -> u64 {
        (0..8).fold(0, |v, i| {
            v | (self.radio.read(offset + i, now) as u64) << (8 * i)
        })
    }

    /// INIT at 0 and everything up to the end of the alignment.
    fn init(&mut self) -> Picos {
        self.write(CTRL, CMD_INIT, Picos::ZERO).unwrap();
        let ready = self.session.ready_at();
        self.radio.apply_due(ready);
        ready
    }

    fn packet(&self, data: &[u8], time_ps: u64) -> RadioPacket {
        RadioPacket {
            radio: self.radio.spec().kind,
            from: "B".into(),
            data: data.to_vec(),
            time_ps,
            rssi: -52.345,
            rx_stamp: self.radio.spec().stamps.then_some(0x12_3456_789A),
        }
    }
}

const MS: Picos = Picos::from_ms(1);

fn ms(n: u64) -> Picos {
    Picos::from_ms(n)
}

#[test]
fn the_register_file_reads_and_refuses_what_it_should() {
    let mut b = Bench::new(uwb::SPEC);
    assert_eq!(REGISTER_MEMORY, 0x140);
    assert_eq!(b.read_u64(EUI, Picos::ZERO), 0x0102_0304_0506_0708);
    assert_eq!(b.radio.read(STATE, Picos::ZERO), STATE_SLEEP);
    // Before INIT nothing but INIT works.
    let e = b.write(CTRL, CMD_RX_ON, Picos::ZERO).unwrap_err();
    assert!(e.to_string().contains("before INIT"), "{e}");
    // Read-only registers refuse writes by name of their offset.
    let e = b.write(RX_LEN, 1, Picos::ZERO).unwrap_err();
    assert!(e.to_string().contains("0x5 is read-only"), "{e}");
    assert!(b.write(EUI + 3, 1, Picos::ZERO).is_err());
    // Unused offsets read 0.
    assert_eq!(b.radio.read(0x07, Picos::ZERO), 0);
    assert_eq!(b.radio.read(0x30, Picos::ZERO), 0);
    // TX_BUF, TX_LEN and IRQ_MASK keep what is written.
    b.write(TX_BUF + 5, 0xAB, Picos::ZERO).unwrap();
    b.write(TX_LEN, 9, Picos::ZERO).unwrap();
    b.write(IRQ_MASK, RX_DONE, Picos::ZERO).unwrap();
    assert_eq!(b.radio.read(TX_BUF + 5, Picos::ZERO), 0xAB);
    assert_eq!(b.radio.read(TX_LEN, Picos::ZERO), 9);
    assert_eq!(b.radio.read(IRQ_MASK, Picos::ZERO), RX_DONE);
    assert!(matches!(
        b.write(CTRL, 9, Picos::ZERO),
        Err(DeviceError::UnknownCommand { value: 9, .. })
    ));
}

#[test]
fn init_claims_the_world_once_and_shows_done_after_the_alignment() {
    let mut b = Bench::new(uwb::SPEC);
    b.write(CTRL, CMD_INIT, Picos::from_us(7)).unwrap();
    let ready = Picos::from_us(7) + Picos::from_ms(2000);
    assert_eq!(b.session.ready_at(), ready);
    assert_eq!(b.radio.read(STATE, Picos::from_us(8)), STATE_IDLE);
    assert_eq!(b.radio.read(STATUS, Picos::from_us(8)), 0);
    assert_eq!(b.radio.stable_until(STATUS, Picos::from_us(8)), ready);
    assert_eq!(b.radio.next_event(), Some(ready));
    assert_eq!(b.radio.read(STATUS, ready), INIT_DONE);
    // A second INIT (the other radio's, or this one again) sends nothing.
    b.write(CTRL, CMD_INIT, ready).unwrap();
    assert_eq!(b.world.requests("GET_INIT_DATA").len(), 1);
    // The world is claimed by a radio: the ticker owns the clock.
    assert_eq!(b.session.next_event(), Some(ready + Millis(4).to_picos()));
}

#[test]
fn a_transmission_is_sent_with_its_offset_lasts_its_airtime_and_completes_with_its_stamp() {
    let mut b = Bench::new(uwb::SPEC);
    let p0 = b.init();
    // Two ticks: the clock is at 2008 ms, which is platform time p0 + 8 ms.
    b.session
        .tick(p0 + ms(8), &mut b.world, &mut b.time)
        .unwrap();
    assert_eq!(b.world.clock(), Millis(2008));
    b.write(IRQ_MASK, TX_DONE, p0).unwrap();
    for i in 0..20 {
        b.write(TX_BUF + i, i as u8, p0).unwrap();
    }
    b.write(TX_LEN, 20, p0).unwrap();
    let p = p0 + ms(8) + Picos::from_us(1500);
    b.write(CTRL, CMD_TX_START, p).unwrap();
    let sent = b.world.requests("RADIO_SEND");
    let Request::RadioSend {
        radio,
        data,
        offset_ps,
    } = &sent[0].request
    else {
        unreachable!()
    };
    assert_eq!(*radio, Radio::Uwb);
    assert_eq!(data, &(0..20).collect::<Vec<u8>>());
    assert_eq!(*offset_ps, Picos::from_us(1500).0);
    let air = Picos(Radio::Uwb.airtime(20).0);
    assert_eq!(b.radio.read(STATE, p), STATE_TX);
    assert_eq!(b.radio.stable_until(STATE, p), p + air);
    assert_eq!(b.radio.read(STATE, p + air), STATE_IDLE);
    assert_eq!(b.radio.power.state_at(p + Picos(1)), RadioPowerState::Tx);
    assert_eq!(b.radio.power.state_at(p + air), RadioPowerState::Idle);
    // Busy: a second TX_START on the air is an error.
    let e = b.write(CTRL, CMD_TX_START, p + Picos(10)).unwrap_err();
    assert!(e.to_string().contains("on the air"), "{e}");
    // The world reports it finished at 2008 ms + 1.5 ms + airtime; mapped
    // back, that is exactly p + airtime.
    let end_world = Millis(2008).to_picos().0 + Picos::from_us(1500).0 + air.0;
    let t_d = b.session.world_clock(&b.time);
    let ended = platform_time_of(end_world, t_d, b.time.accounted_until());
    assert_eq!(ended, p + air);
    b.radio
        .deliver_tx_done(
            p0 + ms(12),
            ended,
            TxDone {
                radio: Radio::Uwb,
                time_ps: end_world,
                tx_stamp: Some(0xFF_0000_0001),
            },
        )
        .unwrap();
    // Delivered when the platform learns it (the next tick), not earlier.
    assert!(!b.radio.irq());
    assert_eq!(b.radio.read(STATUS, p0 + ms(12) - Picos(1)) & TX_DONE, 0);
    assert_eq!(b.radio.read(STATUS, p0 + ms(12)) & TX_DONE, TX_DONE);
    assert!(b.radio.irq());
    assert_eq!(b.read_u64(TX_STAMP, p0 + ms(12)), 0xFF_0000_0001);
    // W1C clears it and the request.
    b.write(STATUS, TX_DONE, p0 + ms(12)).unwrap();
    assert!(!b.radio.irq());
    assert_eq!(b.radio.read(STATUS, p0 + ms(12)), INIT_DONE);
}

#[test]
fn bad_lengths_and_sleeping_radios_refuse_to_transmit() {
    let mut b = Bench::new(p2p::SPEC);
    let p0 = b.init();
    b.write(TX_LEN, 61, p0).unwrap();
    let e = b.write(CTRL, CMD_TX_START, p0).unwrap_err();
    assert!(e.to_string().contains("1 to 60 bytes"), "{e}");
    b.write(TX_LEN, 0, p0).unwrap();
    assert!(b.write(CTRL, CMD_TX_START, p0).is_err());
    b.write(CTRL, CMD_SLEEP, p0).unwrap();
    b.write(TX_LEN, 4, p0).unwrap();
    let e = b.write(CTRL, CMD_TX_START, p0).unwrap_err();
    assert!(e.to_string().contains("asleep"), "{e}");
    assert!(b.write(CTRL, CMD_RX_ON, p0).is_err());
    // INIT wakes it.
    b.write(CTRL, CMD_INIT, p0).unwrap();
    b.write(CTRL, CMD_TX_START, p0).unwrap();
    assert_eq!(b.world.requests("RADIO_SEND").len(), 1);
}

#[test]
fn the_fifo_holds_eight_frames_and_w1c_moves_the_next_in() {
    let mut b = Bench::new(uwb::SPEC);
    let p0 = b.init();
    b.write(IRQ_MASK, RX_DONE | RX_OVERRUN, p0).unwrap();
    b.write(CTRL, CMD_RX_ON, p0).unwrap();
    let at = p0 + ms(5);
    for i in 0..9u8 {
        let pkt = b.packet(&[i, i, i], 0);
        b.radio
            .deliver_packet(at, at - Picos::from_us(100), pkt)
            .unwrap();
    }
    assert_eq!(b.radio.stable_until(RX_BUF, p0), at);
    assert_eq!(b.radio.read(STATUS, at), INIT_DONE | RX_DONE | RX_OVERRUN);
    assert!(b.radio.irq());
    assert_eq!(b.radio.read(RX_PENDING, at), 7);
    assert_eq!(b.radio.read(RX_LEN, at), 3);
    let lost = (0..4).fold(0u32, |v, i| {
        v | (b.radio.read(RX_LOST + i, at) as u32) << (8 * i)
    });
    assert_eq!(lost, 1);
    let rssi = (0..4).fold(0u32, |v, i| {
        v | (b.radio.read(RX_RSSI + i, at) as u32) << (8 * i)
    });
    assert_eq!(rssi as i32, -5235);
    assert_eq!(b.read_u64(RX_STAMP, at), 0x12_3456_789A);
    for i in 0..8u8 {
        assert_eq!(b.radio.read(RX_BUF, at), i);
        assert_eq!(b.radio.read(RX_PENDING, at), 7 - i);
        b.write(STATUS, RX_DONE, at).unwrap();
    }
    // The last frame stays readable; RX_DONE is clear; the overrun flag stays
    // until it is cleared itself.
    assert_eq!(b.radio.read(RX_BUF, at), 7);
    assert_eq!(b.radio.read(STATUS, at), INIT_DONE | RX_OVERRUN);
    b.write(STATUS, RX_OVERRUN, at).unwrap();
    assert!(!b.radio.irq());
    assert_eq!(b.radio.stats.frames_received, 8);
    assert_eq!(b.radio.stats.rx_overruns, 1);
}

#[test]
fn a_frame_counts_only_if_the_receiver_was_on_when_it_ended() {
    let mut b = Bench::new(p2p::SPEC);
    let p0 = b.init();
    b.write(CTRL, CMD_RX_ON, p0 + MS).unwrap();
    b.write(CTRL, CMD_RX_OFF, p0 + ms(3)).unwrap();
    b.write(CTRL, CMD_RX_ON, p0 + ms(5)).unwrap();
    // Ended while off (4 ms), delivered while on again (6 ms): missed.
    let pkt = b.packet(b"off", 0);
    b.radio.deliver_packet(p0 + ms(6), p0 + ms(4), pkt).unwrap();
    // Ended while on (2 ms), delivered while off would not matter either.
    let pkt = b.packet(b"on", 0);
    b.radio.deliver_packet(p0 + ms(6), p0 + ms(2), pkt).unwrap();
    b.radio.apply_due(p0 + ms(6));
    assert_eq!(b.radio.stats.frames_missed, 1);
    assert_eq!(b.radio.stats.frames_received, 1);
    assert_eq!(b.radio.read(RX_LEN, p0 + ms(6)), 2);
    // P2P has no stamps.
    assert_eq!(b.read_u64(RX_STAMP, p0 + ms(6)), 0);
}

#[test]
fn frames_keep_their_order_and_are_never_delivered_in_the_past() {
    let mut b = Bench::new(uwb::SPEC);
    let p0 = b.init();
    b.write(CTRL, CMD_RX_ON, p0).unwrap();
    let now = p0 + ms(10);
    // A frame that ended before now shows at now.
    let pkt = b.packet(b"a", 0);
    b.radio.deliver_packet(now, p0 + ms(9), pkt).unwrap();
    assert_eq!(b.radio.next_event(), Some(now));
    // A later report cannot overtake it.
    let pkt = b.packet(b"b", 0);
    b.radio.deliver_packet(p0, p0 + ms(5), pkt).unwrap();
    b.radio.apply_due(now);
    assert_eq!(b.radio.read(RX_BUF, now), b'a');
    b.write(STATUS, RX_DONE, now).unwrap();
    assert_eq!(b.radio.read(RX_BUF, now), b'b');
}

#[test]
fn a_uwb_frame_without_a_stamp_is_a_world_error() {
    let mut b = Bench::new(uwb::SPEC);
    b.init();
    let mut pkt = b.packet(b"x", 0);
    pkt.rx_stamp = None;
    assert!(b
        .radio
        .deliver_packet(Picos::ZERO, Picos::ZERO, pkt)
        .is_err());
    let pkt = b.packet(&[0; 128], 0);
    assert!(b
        .radio
        .deliver_packet(Picos::ZERO, Picos::ZERO, pkt)
        .is_err());
}

#[test]
fn power_follows_the_states_with_the_datasheet_currents() {
    let mut b = Bench::new(uwb::SPEC);
    // Off draws nothing.
    assert_eq!(b.radio.power.take_mean(MS), Amps(0.0));
    b.write(CTRL, CMD_INIT, MS).unwrap();
    assert!((b.radio.power.take_mean(ms(2)).0 - 0.012).abs() < 1e-15);
    b.write(CTRL, CMD_RX_ON, ms(2)).unwrap();
    assert!((b.radio.power.take_mean(ms(3)).0 - 0.064).abs() < 1e-15);
    b.write(CTRL, CMD_SLEEP, ms(3)).unwrap();
    assert!((b.radio.power.take_mean(ms(4)).0 - 0.000_001).abs() < 1e-18);
}

#[test]
fn world_times_map_to_platform_times() {
    let t_d = Picos::from_ms(2008);
    let p_d = Picos::from_ms(2009);
    assert_eq!(
        platform_time_of(Picos::from_ms(2007).0, t_d, p_d),
        Picos::from_ms(2008)
    );
    // Before the platform's time 0 (never happens; clamped).
    assert_eq!(platform_time_of(0, t_d, Picos::from_ms(5)), Picos::ZERO);
}

/// The offset_ps of the `i`-th RADIO_SEND.
fn sent_offset(b: &Bench, i: usize) -> u64 {
    match &b.world.requests("RADIO_SEND")[i].request {
        Request::RadioSend { offset_ps, .. } => *offset_ps,
        _ => unreachable!(),
    }
}

#[test]
fn a_delayed_transmission_leaves_its_delay_after_the_command() {
    let mut b = Bench::new(uwb::SPEC);
    let p0 = b.init();
    b.session
        .tick(p0 + ms(8), &mut b.world, &mut b.time)
        .unwrap();
    b.write(CTRL, CMD_RX_ON, p0 + ms(8)).unwrap();
    b.write(TX_BUF, 0x55, p0).unwrap();
    b.write(TX_LEN, 20, p0).unwrap();
    // TX_DELAY = 2_345_678 ns, written byte by byte (little endian).
    let d_ns: u32 = 2_345_678;
    for (i, byte) in d_ns.to_le_bytes().into_iter().enumerate() {
        b.write(TX_DELAY + i as u32, byte, p0).unwrap();
    }
    assert_eq!(b.radio.read(TX_DELAY + 1, p0), d_ns.to_le_bytes()[1]);
    assert_eq!(b.radio.stable_until(TX_DELAY, p0), Picos::MAX);
    // The command at p_d + 1.5 ms: offset = 1.5 ms + d.
    let p = p0 + ms(8) + Picos::from_us(1500);
    let d = Picos::from_ns(u64::from(d_ns));
    b.write(CTRL, CMD_TX_START, p).unwrap();
    assert_eq!(sent_offset(&b, 0), Picos::from_us(1500).0 + d.0);
    // One-shot: TX_DELAY reads 0 again.
    assert_eq!((0..4).map(|i| b.radio.read(TX_DELAY + i, p)).max(), Some(0));
    // Busy from the command to the end of the airtime; TX current for the
    // airtime only, the commanded state (RX) during the wait.
    let air = Picos(Radio::Uwb.airtime(20).0);
    assert_eq!(b.radio.read(STATE, p), STATE_TX);
    assert_eq!(b.radio.stable_until(STATE, p), p + d + air);
    let e = b.write(CTRL, CMD_TX_START, p + d).unwrap_err();
    assert!(e.to_string().contains("on the air"), "{e}");
    assert_eq!(b.radio.read(STATE, p + d + air), STATE_RX);
    assert_eq!(
        b.radio.power.state_at(p + d - Picos(1)),
        RadioPowerState::Rx
    );
    assert_eq!(b.radio.power.state_at(p + d), RadioPowerState::Tx);
    assert_eq!(
        b.radio.power.state_at(p + d + air - Picos(1)),
        RadioPowerState::Tx
    );
    assert_eq!(b.radio.power.state_at(p + d + air), RadioPowerState::Rx);
    // The world's end of that frame maps back to p + d + airtime.
    let end_world = Millis(2008).to_picos().0 + sent_offset(&b, 0) + air.0;
    let t_d = b.session.world_clock(&b.time);
    assert_eq!(
        platform_time_of(end_world, t_d, b.time.accounted_until()),
        p + d + air
    );
    // The next TX_START (no delay written) leaves at once.
    let q = p + d + air;
    b.write(CTRL, CMD_TX_START, q).unwrap();
    assert_eq!(sent_offset(&b, 1), (q - (p0 + ms(8))).0);
}
