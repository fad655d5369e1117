//! The DW1000 UWB transceiver of the Loco Positioning deck (seed 003; DESIGN.md
//! §8): 40-bit timestamps of its own clock (TX_STAMP, RX_STAMP), frames of up
//! to 127 bytes at 6.8 Mb/s.
//!
//! Currents (VCC bus, 3.0 V), from the DW1000 Datasheet (Decawave, v2.09),
//! §4.2 "Operational currents" / the front page's power figures:
//! - TX 31 mA: mean transmit current at 6.8 Mb/s, 64 MHz PRF, channel 2
//!   (the deck's configuration);
//! - RX 64 mA: mean receive current in the same mode (preamble hunt and data);
//! - IDLE 12 mA: IDLE state, PLL and the 125 MHz system clock running (what
//!   the LPS deck's firmware keeps between frames);
//! - SLEEP 1 µA: SLEEP state (the datasheet's "SLEEP current 1 µA";
//!   DEEPSLEEP would be 50 nA).

use super::{RadioCurrents, RadioSpec};
use crate::units::Amps;

pub const SPEC: RadioSpec = RadioSpec {
    kind: protocol::radio::Radio::Uwb,
    name: "uwb",
    stamps: true,
    default_currents: RadioCurrents {
        tx: Amps(0.031),
        rx: Amps(0.064),
        idle: Amps(0.012),
        sleep: Amps(0.000_001),
    },
};
