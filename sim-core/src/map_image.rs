//! The occupancy-grid map image "CFOG" of the exploration firmware
//! (docs/EXPLORE.md, "Map export"): a 32-byte little-endian header, then
//! width x height int8 log-odds, row-major from the cell at the origin, x
//! fastest. The kernel copies it out of the core's memory at the end of a
//! run (`map.cfog`, see [`crate::kernel`]); `cosim` turns it into `map.csv`
//! and `map.png` (DESIGN.md §9).

/// The ELF symbols of the image and of its length (u32) in the firmware.
pub const IMAGE_SYMBOL: &str = "explore_map_image";
pub const IMAGE_LEN_SYMBOL: &str = "explore_map_image_len";
/// The largest image the kernel copies out: a 65 535-cell grid (the
/// firmware's 16-bit cell indices) and its header.
pub const MAX_IMAGE_BYTES: u32 = 32 + 65_535;

/// A map read from a CFOG image.
#[derive(Debug, Clone, PartialEq)]
pub struct MapImage {
    pub width: usize,
    pub height: usize,
    pub cell_mm: i32,
    pub fov_cdeg: u16,
    pub origin_x_mm: i32,
    pub origin_y_mm: i32,
    /// Log-odds units per nat.
    pub lo_per_nat: u8,
    pub l_min: i8,
    pub l_max: i8,
    pub cells: Vec<i8>,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MapError {
    #[error("map image: {len} bytes, shorter than its {need}-byte {what}")]
    Truncated {
        len: usize,
        need: usize,
        what: &'static str,
    },
    #[error("map image: magic {0:?} is not \"CFOG\"")]
    Magic([u8; 4]),
    #[error("map image: version {0} (this reader knows 1)")]
    Version(u16),
    #[error("map image: header length {0} (version 1 has 32)")]
    HeaderLength(u16),
    #[error("map image: {0} units per nat (must be > 0)")]
    Scale(u8),
    #[error("map image: CRC-32 of the cells is {computed:#010x}, the header says {stored:#010x}")]
    Crc { stored: u32, computed: u32 },
}

/// CRC-32 (IEEE 802.3, reflected), as the firmware's og_crc32.
pub fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = (crc >> 1) ^ (0xedb8_8320 & (crc & 1).wrapping_neg());
        }
    }
    !crc
}

impl MapImage {
    /// Bytes of the version-1 header.
    pub const HEADER: usize = 32;

    /// Reads and checks an image (header, length, CRC).
    pub fn parse(b: &[u8]) -> Result<MapImage, MapError> {
        if b.len() < Self::HEADER {
            return Err(MapError::Truncated {
                len: b.len(),
                need: Self::HEADER,
                what: "header",
            });
        }
        let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
        let i32_at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let magic = [b[0], b[1], b[2], b[3]];
        if &magic != b"CFOG" {
            return Err(MapError::Magic(magic));
        }
        if u16_at(4) != 1 {
            return Err(MapError::Version(u16_at(4)));
        }
        if u16_at(6) as usize != Self::HEADER {
            return Err(MapError::HeaderLength(u16_at(6)));
        }
        let (width, height) = (u16_at(8) as usize, u16_at(10) as usize);
        let need = Self::HEADER + width * height;
        if b.len() < need {
            return Err(MapError::Truncated {
                len: b.len(),
                need,
                what: "header and cells",
            });
        }
        if b[24] == 0 {
            return Err(MapError::Scale(b[24]));
        }
        let cells = &b[Self::HEADER..need];
        let (stored, computed) = (i32_at(28) as u32, crc32(cells));
        if stored != computed {
            return Err(MapError::Crc { stored, computed });
        }
        Ok(MapImage {
            width,
            height,
            cell_mm: u16_at(12) as i32,
            fov_cdeg: u16_at(14),
            origin_x_mm: i32_at(16),
            origin_y_mm: i32_at(20),
            lo_per_nat: b[24],
            l_min: b[25] as i8,
            l_max: b[26] as i8,
            cells: cells.iter().map(|&c| c as i8).collect(),
        })
    }

    /// The log-odds of cell (ix, iy), in 1/`lo_per_nat` nat.
    pub fn log_odds(&self, ix: usize, iy: usize) -> i8 {
        self.cells[iy * self.width + ix]
    }

    /// The occupancy probability of a cell (DESIGN.md §9's `p_occupied`),
    /// or None if it was never observed (log-odds exactly 0, the prior).
    pub fn p_occupied(&self, ix: usize, iy: usize) -> Option<f64> {
        match self.log_odds(ix, iy) {
            0 => None,
            l => Some(1.0 / (1.0 + (-(l as f64) / self.lo_per_nat as f64).exp())),
        }
    }

    /// The cell holding a point (mm).
    pub fn cell_of(&self, x_mm: i32, y_mm: i32) -> (usize, usize) {
        (
            ((x_mm - self.origin_x_mm) / self.cell_mm) as usize,
            ((y_mm - self.origin_y_mm) / self.cell_mm) as usize,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_zlibs() {
        // The check value of CRC-32/ISO-HDLC (zlib's crc32).
        assert_eq!(crc32(b"123456789"), 0xcbf4_3926);
        assert_eq!(crc32(b""), 0);
    }

    /// A 3 x 2 image with the given cells.
    pub(crate) fn image(cells: &[i8; 6]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(b"CFOG");
        for v in [1u16, 32, 3, 2, 50, 400] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&(-100i32).to_le_bytes());
        b.extend_from_slice(&(200i32).to_le_bytes());
        b.extend_from_slice(&[16, (-32i8) as u8, 56, 0]);
        let raw: Vec<u8> = cells.iter().map(|&c| c as u8).collect();
        b.extend_from_slice(&crc32(&raw).to_le_bytes());
        b.extend_from_slice(&raw);
        b
    }

    #[test]
    fn a_small_image_reads_back() {
        let m = MapImage::parse(&image(&[0, 16, -16, 56, -32, 1])).unwrap();
        assert_eq!((m.width, m.height, m.cell_mm, m.fov_cdeg), (3, 2, 50, 400));
        assert_eq!((m.origin_x_mm, m.origin_y_mm), (-100, 200));
        assert_eq!(m.p_occupied(0, 0), None);
        // l = 16 is one nat: p = 1 / (1 + e^-1).
        let p = m.p_occupied(1, 0).unwrap();
        assert!((p - 1.0 / (1.0 + (-1.0f64).exp())).abs() < 1e-12);
        assert!((m.p_occupied(2, 0).unwrap() - (1.0 - p)).abs() < 1e-12);
        assert_eq!(m.log_odds(0, 1), 56);
        assert_eq!(m.cell_of(-100 + 149, 200 + 50), (2, 1));
    }
}
