//! The map out of the platform (DESIGN.md §9, docs/EXPLORE.md "Map
//! export"): a firmware that defines the symbols `explore_map_image` and
//! `explore_map_image_len` leaves its occupancy grid there, in the CFOG
//! format; at the end of the run the kernel copies those bytes out of the
//! core's memory into `map.cfog` beside `summary.json`. No device, no
//! firmware cost: the platform reads what the firmware already keeps
//! (a debugger's memory dump), and nothing else changes for firmware
//! without the symbols.

use std::path::Path;

use super::KernelError;
use crate::iss::{LoadedElf, Memory};
use crate::map_image::{IMAGE_LEN_SYMBOL, IMAGE_SYMBOL, MAX_IMAGE_BYTES};

/// The name of the dump in the output directory.
pub const MAP_FILE: &str = "map.cfog";

/// Where the image and its length live, if the firmware has them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapSymbols {
    image: u32,
    len: u32,
}

impl MapSymbols {
    pub fn find(elf: &LoadedElf) -> Option<MapSymbols> {
        Some(MapSymbols {
            image: elf.symbol(IMAGE_SYMBOL)?,
            len: elf.symbol(IMAGE_LEN_SYMBOL)?,
        })
    }

    /// The image's bytes as the firmware left them.
    pub fn read(&self, mem: &Memory) -> Result<Vec<u8>, KernelError> {
        let len = mem.read_u32(self.len).ok_or_else(|| {
            KernelError::Core(format!(
                "{IMAGE_LEN_SYMBOL} at {:#x} is not in RAM",
                self.len
            ))
        })?;
        if len > MAX_IMAGE_BYTES {
            return Err(KernelError::Core(format!(
                "{IMAGE_LEN_SYMBOL} = {len} bytes, more than a CFOG image can hold ({MAX_IMAGE_BYTES})"
            )));
        }
        let mut bytes = vec![0u8; len as usize];
        mem.read_bytes(self.image, &mut bytes).map_err(|e| {
            KernelError::Core(format!(
                "{IMAGE_SYMBOL} ({len} bytes at {:#x}): {e}",
                self.image
            ))
        })?;
        Ok(bytes)
    }

    /// Writes `map.cfog` into `dir` (even an empty image: a firmware that
    /// never exported says so by a zero length).
    pub fn dump(&self, mem: &Memory, dir: &Path) -> Result<(), KernelError> {
        let bytes = self.read(mem)?;
        std::fs::write(dir.join(MAP_FILE), bytes).map_err(|e| {
            KernelError::Io(std::io::Error::new(
                e.kind(),
                format!("cannot write {}: {e}", dir.join(MAP_FILE).display()),
            ))
        })
    }
}
