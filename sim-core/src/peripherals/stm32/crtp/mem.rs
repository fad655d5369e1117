//! Port 4, memories: the decks' 1-wire EEPROMs (the firmware's
//! `mem.c` / `deck_info.c`, cflib's `mem/__init__.py` and `ow_element.py`).
//!
//! A Crazyflie deck carries a 1-wire EEPROM that says what it is: the
//! firmware lists one memory of type 1-WIRE per deck found, and answers
//! reads of its contents; cflib lists them at every connection and
//! cfclient's *About* box shows each deck's board name from them. Here each
//! deck the drone carries (the same as the `deck.bc…` parameters: Flow deck
//! v2, Multi-ranger, AI deck) is such a memory with the contents its
//! EEPROM has:
//!
//! | bytes | field |
//! |---|---|
//! | 0 | header magic 0xEB |
//! | 1..5 | used pins (u32 LE: `deck_core.h`'s `DECK_USING_*` bits of the deck's driver) |
//! | 5, 6 | vendor id (0xBC, Bitcraze), product id |
//! | 7 | CRC-32 (IEEE) of bytes 0..7, low byte |
//! | 8, 9 | elements version 0, length N |
//! | 10..10+N | elements: id, length, text (1 = board name) |
//! | 10+N | CRC-32 of bytes 8..10+N, low byte |
//!
//! then 0xFF (erased) up to the EEPROM's 112 bytes.
//!
//! | channel | command | answer |
//! |---|---|---|
//! | 0 info | 1 GET_NUMBER_OF_MEMORIES | `[1, count]` |
//! | 0 info | 2 GET_DETAILS `[id]` | `[2, id, type 1, size u32, 1-wire address (8 bytes)]`; unknown id: `[2]` |
//! | 1 read | `[id, address u32, length ≤ 24]` | `[id, address, status 0, data…]`; out of range: status EIO, no data |
//! | 2 write | `[id, address u32, data…]` | `[id, address, status EIO]`: the EEPROMs are read-only here |
//!
//! No other memory (the EEPROM of the Crazyflie itself, the LED ring,
//! trajectory or lighthouse memories) is served.

use super::param::Decks;

pub const CHAN_INFO: u8 = 0;
pub const CHAN_READ: u8 = 1;
pub const CHAN_WRITE: u8 = 2;
const CMD_INFO_NBR: u8 = 1;
const CMD_INFO_DETAILS: u8 = 2;
/// cflib's `MemoryElement.TYPE_1W`.
const TYPE_1W: u8 = 1;
/// The decks' EEPROM size as the firmware reports it (`OW_MAX_SIZE`; cflib's
/// `OWElement.erase` writes 112 bytes).
const OW_SIZE: usize = 112;
/// cflib's `_ReadRequest.MAX_DATA_LENGTH`: the longest read a packet answers.
const MAX_READ: usize = 24;
/// The firmware's error for a read or write it cannot do (`errno.h` EIO).
const EIO: u8 = 5;
const HEADER_MAGIC: u8 = 0xEB;
/// Bitcraze's vendor id on its decks.
const VID_BITCRAZE: u8 = 0xBC;
/// The element id of the board name (cflib's `OWElement.element_mapping`).
const ELEMENT_BOARD_NAME: u8 = 1;
/// The 1-wire family code of the decks' DS28E05 EEPROM (Maxim datasheet,
/// "64-bit ROM": family code 0Dh).
const FAMILY_DS28E05: u8 = 0x0D;

/// A deck this drone carries: its driver's name, product id and pins (the
/// firmware's deck drivers, `flowdeck_v1v2.c`, `multiranger.c`, `aideck.c`:
/// `usedGpio | usedPeriph`, the pin bits of `deck_core.h`), which is what
/// its EEPROM's used-pins field describes.
struct Deck {
    name: &'static str,
    pid: u8,
    pins: u32,
}

/// `deck_core.h`'s pin bits.
const PC11: u32 = 1 << 0;
const PC10: u32 = 1 << 1;
const PB7: u32 = 1 << 2;
const PB6: u32 = 1 << 3;
const IO_3: u32 = 1 << 6;
const IO_4: u32 = 1 << 7;
const PA5: u32 = 1 << 10;
const PA6: u32 = 1 << 11;
const PA7: u32 = 1 << 12;
const I2C: u32 = PB6 | PB7;
const SPI: u32 = PA5 | PA6 | PA7;
const UART1: u32 = PC10 | PC11;

const FLOW2: Deck = Deck {
    name: "bcFlow2",
    pid: 0x0F,
    pins: IO_3 | I2C | SPI,
};
const MULTIRANGER: Deck = Deck {
    name: "bcMultiranger",
    pid: 0x0C,
    pins: I2C,
};
const AI: Deck = Deck {
    name: "bcAI",
    pid: 0x12,
    pins: IO_4 | UART1,
};

/// The memories of one drone's decks.
pub struct Memories {
    /// Each deck's EEPROM image and its 1-wire address.
    eeproms: Vec<([u8; OW_SIZE], [u8; 8])>,
}

impl Memories {
    pub fn new(decks: &Decks) -> Memories {
        let carried = [
            (decks.flow2, &FLOW2),
            (decks.multiranger, &MULTIRANGER),
            (decks.ai, &AI),
        ];
        let eeproms = carried
            .into_iter()
            .filter(|(on, _)| *on)
            .enumerate()
            .map(|(i, (_, d))| (eeprom(d), ow_address(d, i as u8)))
            .collect();
        Memories { eeproms }
    }

    pub fn count(&self) -> usize {
        self.eeproms.len()
    }

    /// Channel 0.
    pub fn info(&self, d: &[u8]) -> Option<Vec<u8>> {
        match *d {
            [CMD_INFO_NBR, ..] => Some(vec![CMD_INFO_NBR, self.count() as u8]),
            [CMD_INFO_DETAILS, id, ..] => Some(match self.eeproms.get(usize::from(id)) {
                Some((_, addr)) => {
                    let mut v = vec![CMD_INFO_DETAILS, id, TYPE_1W];
                    v.extend_from_slice(&(OW_SIZE as u32).to_le_bytes());
                    v.extend_from_slice(addr);
                    v
                }
                // The firmware's answer to an id it has no memory for: the
                // command alone (cflib then stops listing).
                None => vec![CMD_INFO_DETAILS],
            }),
            _ => None,
        }
    }

    /// Channel 1: `[id, address, length]`.
    pub fn read(&self, d: &[u8]) -> Option<Vec<u8>> {
        let (id, addr, len) = match d {
            [id, a0, a1, a2, a3, len, ..] => (*id, [*a0, *a1, *a2, *a3], usize::from(*len)),
            _ => return None,
        };
        let mut v = vec![id];
        v.extend_from_slice(&addr);
        let start = u32::from_le_bytes(addr) as usize;
        match self.eeproms.get(usize::from(id)) {
            Some((image, _)) if len <= MAX_READ && start + len <= OW_SIZE => {
                v.push(0);
                v.extend_from_slice(&image[start..start + len]);
            }
            _ => v.push(EIO),
        }
        Some(v)
    }

    /// Channel 2: `[id, address, data…]`, refused.
    pub fn write(&self, d: &[u8]) -> Option<Vec<u8>> {
        (d.len() >= 5).then(|| {
            let mut v = d[..5].to_vec();
            v.push(EIO);
            v
        })
    }
}

fn crc_low(bytes: &[u8]) -> u8 {
    (crc32fast::hash(bytes) & 0xFF) as u8
}

/// The EEPROM's contents (the module's table).
fn eeprom(d: &Deck) -> [u8; OW_SIZE] {
    let mut v = vec![HEADER_MAGIC];
    v.extend_from_slice(&d.pins.to_le_bytes());
    v.extend_from_slice(&[VID_BITCRAZE, d.pid]);
    v.push(crc_low(&v));
    let mut elements = vec![ELEMENT_BOARD_NAME, d.name.len() as u8];
    elements.extend_from_slice(d.name.as_bytes());
    let start = v.len();
    v.extend_from_slice(&[0, elements.len() as u8]);
    v.extend_from_slice(&elements);
    v.push(crc_low(&v[start..]));
    let mut image = [0xFF; OW_SIZE];
    image[..v.len()].copy_from_slice(&v);
    image
}

/// A 1-wire ROM address: family code, a serial (here the deck's vendor and
/// product ids and its slot: fixed, so a run is the same every time), and
/// the Maxim CRC-8 of the first 7 bytes.
fn ow_address(d: &Deck, slot: u8) -> [u8; 8] {
    let mut a = [FAMILY_DS28E05, d.pid, VID_BITCRAZE, slot, 0, 0, 0, 0];
    a[7] = crc8_maxim(&a[..7]);
    a
}

/// The 1-wire ROM's CRC-8 (x⁸ + x⁵ + x⁴ + 1, reflected: 0x8C).
fn crc8_maxim(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        let mut x = b;
        for _ in 0..8 {
            let mix = (crc ^ x) & 1;
            crc >>= 1;
            if mix != 0 {
                crc ^= 0x8C;
            }
            x >>= 1;
        }
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> Memories {
        Memories::new(&Decks {
            flow2: true,
            multiranger: true,
            ai: false,
        })
    }

    #[test]
    fn each_carried_deck_is_a_1wire_memory_with_its_eeprom() {
        let m = all();
        assert_eq!(m.info(&[1]), Some(vec![1, 2]));
        let d = m.info(&[2, 1]).unwrap();
        assert_eq!(&d[..3], &[2, 1, TYPE_1W]);
        assert_eq!(u32::from_le_bytes(d[3..7].try_into().unwrap()), 112);
        assert_eq!(d[7], FAMILY_DS28E05);
        assert_eq!(crc8_maxim(&d[7..15]), 0, "a ROM with its CRC checks to 0");
        assert_eq!(m.info(&[2, 2]), Some(vec![2]));
        // The header and elements as cflib's OWElement parses them.
        let r = m.read(&[1, 0, 0, 0, 0, 24]).unwrap();
        assert_eq!(&r[..6], &[1, 0, 0, 0, 0, 0]);
        let more = m.read(&[1, 24, 0, 0, 0, 24]).unwrap();
        assert_eq!(&more[..6], &[1, 24, 0, 0, 0, 0]);
        let img = [&r[6..], &more[6..]].concat();
        assert_eq!(img[0], 0xEB);
        assert_eq!(&img[5..7], &[0xBC, 0x0C]);
        assert_eq!(img[7], crc_low(&img[..7]));
        let n = usize::from(img[9]);
        assert_eq!(&img[10..12], &[1, 13]);
        assert_eq!(&img[12..10 + n], b"bcMultiranger");
        assert_eq!(img[10 + n], crc_low(&img[8..10 + n]));
    }

    #[test]
    fn bad_reads_and_writes_get_the_firmwares_error() {
        let m = all();
        assert_eq!(m.read(&[0, 100, 0, 0, 0, 24]).unwrap()[5], EIO); // past the end
        assert_eq!(m.read(&[0, 0, 0, 0, 0, 30]).unwrap()[5], EIO); // longer than a packet
        assert_eq!(m.read(&[7, 0, 0, 0, 0, 1]).unwrap()[5], EIO); // no such memory
        assert_eq!(m.read(&[0, 0, 0]), None);
        assert_eq!(
            m.write(&[0, 0, 0, 0, 0, 1, 2]),
            Some(vec![0, 0, 0, 0, 0, EIO])
        );
        assert_eq!(m.info(&[9]), None);
        assert_eq!(
            Memories::new(&Decks::default()).info(&[1]),
            Some(vec![1, 0])
        );
    }
}
