//! The radio messages' vocabulary (DESIGN.md §8): which radio, what a
//! reception and a finished transmission look like on the wire, how long a
//! frame is on the air, and the DW1000's 40-bit clock.
//!
//! Both ends use these: the world to schedule transmissions and receptions,
//! the platform to model the radios' power (a transmitter draws its TX
//! current for exactly the airtime the world uses). Units are in the names:
//! `_ps` picoseconds of world time, stamps in DW1000 ticks.

use serde::{Deserialize, Serialize};

/// The two radios of DESIGN.md §8.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Radio {
    /// The DW1000 of the Loco Positioning deck (seed 003): timestamps.
    Uwb,
    /// The nRF51's peer-to-peer packets (seed 004): RSSI.
    P2p,
}

impl Radio {
    pub const ALL: [Radio; 2] = [Radio::Uwb, Radio::P2p];

    pub fn as_str(self) -> &'static str {
        match self {
            Radio::Uwb => "uwb",
            Radio::P2p => "p2p",
        }
    }

    /// Largest payload in one frame (DESIGN.md §8): 127 bytes for the
    /// DW1000 (an IEEE 802.15.4 PSDU), 60 for a Crazyflie P2P packet
    /// (`P2P_MAX_DATA_SIZE` of the Bitcraze firmware).
    pub const fn max_payload(self) -> usize {
        match self {
            Radio::Uwb => 127,
            Radio::P2p => 60,
        }
    }

    /// Time on the air of a frame carrying `len` payload bytes.
    pub fn airtime(self, len: usize) -> Picos {
        match self {
            Radio::Uwb => uwb_airtime(len),
            Radio::P2p => p2p_airtime(len),
        }
    }
}

impl std::fmt::Display for Radio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Radio {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "uwb" => Ok(Radio::Uwb),
            "p2p" => Ok(Radio::P2p),
            other => Err(format!(
                "unknown radio {other:?} (expected \"uwb\" or \"p2p\")"
            )),
        }
    }
}

/// World time in picoseconds (the radio's resolution; the world's steps are
/// whole milliseconds).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Picos(pub u64);

impl Picos {
    pub const PER_MS: u64 = 1_000_000_000;
    pub const fn from_ms(ms: u64) -> Picos {
        Picos(ms * Self::PER_MS)
    }
}

impl std::ops::Add for Picos {
    type Output = Picos;
    fn add(self, o: Picos) -> Picos {
        Picos(self.0 + o.0)
    }
}

/// One DW1000 clock tick: 1 / (128 · 499.2 MHz) s ≈ 15.65 ps (DW1000 User
/// Manual §3.3; DESIGN.md §8). As an exact fraction of a picosecond:
/// 1e12 / (128 · 499.2e6) = 1e6 / 63 897.6 = 15.650040064… ps.
pub const DW1000_TICKS_PER_SECOND: f64 = 128.0 * 499.2e6;
/// The DW1000's system time and stamps are 40 bits wide (wrap ≈ 17.2 s).
pub const DW1000_STAMP_MASK: u64 = (1 << 40) - 1;

/// A DW1000 timestamp: 40-bit tick count of one drone's radio clock.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Dw1000Ticks(pub u64);

impl Dw1000Ticks {
    /// `later − earlier` modulo 2^40: the interval between two stamps of one
    /// clock, correct across one wrap (seed 003 §6.4, Table 6.1).
    pub fn since(self, earlier: Dw1000Ticks) -> u64 {
        self.0.wrapping_sub(earlier.0) & DW1000_STAMP_MASK
    }
}

/// The stamp of DESIGN.md §8 for world time `t`:
/// `floor((t·(1 + ppm·1e-6) + phase) / tick) mod 2^40`, with `t` and `phase`
/// in picoseconds. Computed in integer arithmetic on a 128-bit numerator so
/// that the floor is exact at any time (a double loses the sub-tick
/// information after a few hours of picoseconds).
///
/// `ppm` is taken in units of 1e-12 (parts per trillion, exact for every
/// `clock_ppm` with at most six decimals) to keep the product integral.
pub fn dw1000_stamp(t: Picos, clock_ppt: i64, phase: Picos) -> Dw1000Ticks {
    // local time in ps·1e12 = t·(1e12 + ppt) + phase·1e12
    let local = t.0 as i128 * (1_000_000_000_000i128 + clock_ppt as i128)
        + phase.0 as i128 * 1_000_000_000_000i128;
    // ticks = local_ps / tick_ps = local_ps · 63 897.6 / 1e6
    //       = local(ps·1e12) · 638 976 / (1e7 · 1e12)
    let ticks = local.max(0) * 638_976 / 10_000_000_000_000_000_000;
    Dw1000Ticks((ticks as u64) & DW1000_STAMP_MASK)
}

/// `clock_ppm` (a world file's f64) in the integer units of [`dw1000_stamp`].
pub fn ppm_to_ppt(ppm: f64) -> i64 {
    (ppm * 1e6).round() as i64
}

// DW1000 PHY of the Loco Positioning deck (Bitcraze's `lpsTwrTag`/TDoA
// configuration: channel 2, 64 MHz PRF, 6.8 Mb/s, 128-symbol preamble;
// DW1000 User Manual §9.3 and Decawave APS023 for the durations):
/// Preamble symbol at 64 MHz PRF: 1017.63 ns.
const UWB_PREAMBLE_SYMBOL_PS: u64 = 1_017_630;
/// 128 preamble symbols + 8 SFD symbols (the short SFD of the 6.8 Mb/s mode).
const UWB_SHR_SYMBOLS: u64 = 128 + 8;
/// The PHY header's 21 bits go at 850 kb/s: 1025.64 ns per bit.
const UWB_PHR_PS: u64 = 21 * 1_025_641;
/// One data bit at 6.8 Mb/s: 128.205 ns.
const UWB_DATA_BIT_PS: u64 = 128_205;
/// The frame check sequence the DW1000 appends (2 bytes).
const UWB_FCS_BYTES: usize = 2;

/// Airtime of a DW1000 frame: synchronisation header, PHY header, then the
/// payload plus its FCS with 48 Reed-Solomon parity bits per 330 data bits
/// (IEEE 802.15.4a; APS023 eq. 1). A 20-byte payload takes 188.6 µs.
pub fn uwb_airtime(len: usize) -> Picos {
    let bits = 8 * (len + UWB_FCS_BYTES) as u64;
    let parity = 48 * bits.div_ceil(330);
    Picos(UWB_SHR_SYMBOLS * UWB_PREAMBLE_SYMBOL_PS + UWB_PHR_PS + (bits + parity) * UWB_DATA_BIT_PS)
}

// nRF51 Enhanced ShockBurst at 2 Mb/s, the Crazyflie's radio rate (nRF51
// Series Reference Manual §17.1): 1-byte preamble, 5-byte address, 9-bit
// packet control field, the payload (one CRTP/P2P port byte + data), 2-byte CRC.
/// One bit at 2 Mb/s: 500 ns.
const P2P_BIT_PS: u64 = 500_000;
const P2P_OVERHEAD_BITS: u64 = 8 + 40 + 9 + 8 + 16;

/// Airtime of a P2P packet: a 60-byte payload takes 276.5 µs.
pub fn p2p_airtime(len: usize) -> Picos {
    Picos((P2P_OVERHEAD_BITS + 8 * len as u64) * P2P_BIT_PS)
}

/// One reception in a `RADIO_RECV` reply (DESIGN.md §8).
#[derive(Clone, Debug, PartialEq)]
pub struct RadioPacket {
    pub radio: Radio,
    /// The sender's drone name.
    pub from: String,
    pub data: Vec<u8>,
    /// World time at which the reception ended (the RX-done event), ps.
    pub time_ps: u64,
    /// Received signal strength, dBm.
    pub rssi: f64,
    /// uwb only: the receiver's clock when the frame's start arrived.
    pub rx_stamp: Option<u64>,
}

/// One of the drone's own transmissions that has ended (the DW1000's TX-done
/// event), in a `RADIO_RECV` reply.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TxDone {
    pub radio: Radio,
    /// World time at which the transmission ended, ps.
    pub time_ps: u64,
    /// uwb only: the sender's clock when the frame started to leave.
    pub tx_stamp: Option<u64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tick_is_15_65_ps() {
        // 1 s of a perfect clock is 63 897 600 000 ticks.
        let s = dw1000_stamp(Picos(1_000_000_000_000), 0, Picos(0));
        assert_eq!(s.0, 63_897_600_000);
        // 1000 ps → floor(63.8976) ticks
        assert_eq!(dw1000_stamp(Picos(1000), 0, Picos(0)).0, 63);
    }

    #[test]
    fn stamps_wrap_at_2_pow_40() {
        let wrap_s = (1u64 << 40) as f64 / DW1000_TICKS_PER_SECOND; // ≈ 17.2 s
        assert!((wrap_s - 17.207).abs() < 1e-3, "{wrap_s}");
        let before = dw1000_stamp(Picos(17_000_000_000_000), 0, Picos(0));
        let after = dw1000_stamp(Picos(18_000_000_000_000), 0, Picos(0));
        assert!(after.0 < before.0, "wrapped");
        assert_eq!(after.since(before), 63_897_600_000);
    }

    #[test]
    fn a_fast_clock_counts_more_ticks() {
        let t = Picos(1_000_000_000_000);
        let fast = dw1000_stamp(t, ppm_to_ppt(20.0), Picos(0));
        let slow = dw1000_stamp(t, ppm_to_ppt(-20.0), Picos(0));
        // ±20 ppm of 63 897 600 000 ticks = ±1 277 952
        assert_eq!(fast.0 - 63_897_600_000, 1_277_952);
        assert_eq!(63_897_600_000 - slow.0, 1_277_952);
    }

    #[test]
    fn airtimes() {
        let a = uwb_airtime(20);
        assert!((a.0 as f64 / 1e6 - 188.6).abs() < 0.2, "{a:?}");
        assert_eq!(p2p_airtime(60).0, (81 + 480) * 500_000);
        assert!(uwb_airtime(127) > uwb_airtime(1));
    }
}
