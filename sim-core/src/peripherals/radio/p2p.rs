//! The nRF51822's 2.4 GHz radio as the Crazyflie's peer-to-peer link (seed
//! 004; DESIGN.md §8): packets of up to 60 bytes with the received signal
//! strength (RX_RSSI), no timestamps (TX_STAMP and RX_STAMP read 0).
//!
//! Currents (VCC bus, 3.0 V), from the nRF51822 Product Specification v3.1
//! (Nordic Semiconductor), LDO mode, the Crazyflie's supply:
//! - TX 10.5 mA: Table 36 "Radio current consumption", I_TX,0dBm (the
//!   Crazyflie transmits at 0 dBm);
//! - RX 13.4 mA: Table 36, I_RX,2M (receiving at 2 Mb/s, the Crazyflie's
//!   rate);
//! - IDLE 2.6 µA: Table 32, I_ON (System ON, radio disabled, waiting for an
//!   event);
//! - SLEEP 0.6 µA: Table 32, I_OFF (System OFF).

use super::{RadioCurrents, RadioSpec};
use crate::units::Amps;

pub const SPEC: RadioSpec = RadioSpec {
    kind: protocol::radio::Radio::P2p,
    name: "p2p",
    stamps: false,
    default_currents: RadioCurrents {
        tx: Amps(0.0105),
        rx: Amps(0.0134),
        idle: Amps(0.000_002_6),
        sleep: Amps(0.000_000_6),
    },
};
