//! One CRTP packet (the Crazyflie Real-Time Protocol, Bitcraze's
//! "CRTP - Communicate with Crazyflie" documentation): a header byte — port
//! in bits 7..4, link bits 3..2, channel in bits 1..0 — and at most 30 data
//! bytes (`CRTP_MAX_DATA_SIZE` of the firmware's `crtp.h`). Over cflib's
//! `udp://` link one datagram carries exactly one packet.

/// The firmware's `CRTP_MAX_DATA_SIZE`.
pub const MAX_DATA: usize = 30;

/// Port numbers (the firmware's `CRTPPort` enum, `crtp.h`).
pub const PORT_CONSOLE: u8 = 0;
pub const PORT_PARAM: u8 = 2;
pub const PORT_COMMANDER: u8 = 3;
pub const PORT_MEM: u8 = 4;
pub const PORT_LOG: u8 = 5;
pub const PORT_LOCALIZATION: u8 = 6;
pub const PORT_SETPOINT_GENERIC: u8 = 7;
pub const PORT_SETPOINT_HL: u8 = 8;
pub const PORT_PLATFORM: u8 = 13;
pub const PORT_LINK: u8 = 15;

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    pub port: u8,
    pub channel: u8,
    pub data: Vec<u8>,
}

/// Why a datagram is not a CRTP packet (it is dropped, as the firmware
/// drops a malformed radio packet).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    #[error("empty datagram (no CRTP header)")]
    Empty,
    #[error("{0} data bytes (at most 30)")]
    TooLong(usize),
}

impl Packet {
    pub fn new(port: u8, channel: u8, data: Vec<u8>) -> Self {
        debug_assert!(data.len() <= MAX_DATA, "a CRTP reply over 30 bytes");
        Packet {
            port,
            channel,
            data,
        }
    }

    pub fn parse(bytes: &[u8]) -> Result<Packet, PacketError> {
        let (&h, data) = bytes.split_first().ok_or(PacketError::Empty)?;
        if data.len() > MAX_DATA {
            return Err(PacketError::TooLong(data.len()));
        }
        Ok(Packet {
            port: h >> 4,
            channel: h & 0x03,
            data: data.to_vec(),
        })
    }

    /// The header byte: the link bits (3..2) set, as the firmware sends them.
    pub fn header(&self) -> u8 {
        (self.port << 4) | 0x0C | (self.channel & 0x03)
    }

    pub fn encode(&self) -> Vec<u8> {
        let mut v = Vec::with_capacity(1 + self.data.len());
        v.push(self.header());
        v.extend_from_slice(&self.data);
        v
    }
}

/// Little-endian readers that fail (→ the packet is ignored) on a short packet.
pub fn f32_at(d: &[u8], i: usize) -> Option<f64> {
    d.get(i..i + 4)
        .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")) as f64)
}

pub fn u16_at(d: &[u8], i: usize) -> Option<u16> {
    d.get(i..i + 2)
        .map(|b| u16::from_le_bytes(b.try_into().expect("2 bytes")))
}

pub fn u32_at(d: &[u8], i: usize) -> Option<u32> {
    d.get(i..i + 4)
        .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_splits_port_and_channel() {
        let p = Packet::parse(&[0x5D, 1, 2]).unwrap();
        assert_eq!((p.port, p.channel, p.data.clone()), (5, 1, vec![1, 2]));
        assert_eq!(p.encode(), vec![0x5D, 1, 2]);
        assert_eq!(Packet::parse(&[]), Err(PacketError::Empty));
        assert_eq!(Packet::parse(&[0; 32]), Err(PacketError::TooLong(31)));
        assert_eq!(f32_at(&[0, 0, 0x80, 0x3f], 0), Some(1.0));
        assert_eq!(f32_at(&[0, 0, 0x80], 0), None);
    }
}
