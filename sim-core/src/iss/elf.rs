//! ELF loading with the `object` crate: 32-bit little-endian RISC-V
//! executables, their loadable segments, entry point and symbols.

use std::collections::BTreeMap;

use object::elf;
use object::read::elf::{ElfFile32, ProgramHeader};
use object::{Architecture, Endianness, Object, ObjectSymbol};
use thiserror::Error;

use super::mem::{MemError, Memory};

/// Why an ELF could not be loaded.
#[derive(Debug, Error)]
pub enum ElfError {
    // The object error is part of the message, not a `source`, so that
    // `{:#}` chains do not print it twice.
    #[error("not a valid ELF file: {0}")]
    Parse(object::Error),
    #[error("not a 32-bit RISC-V ELF (architecture {0:?})")]
    WrongArchitecture(Architecture),
    #[error("segment at {addr:#x} lies beyond the end of the file (truncated ELF?)")]
    Truncated { addr: u64 },
    #[error("segment at {addr:#x} ({len} bytes) does not fit in 32-bit addresses")]
    SegmentOutOfRange { addr: u64, len: u64 },
    #[error("segment at {addr:#010x} ({len} bytes) is outside every RAM region")]
    SegmentOutsideRam { addr: u32, len: u64 },
}

impl From<object::Error> for ElfError {
    fn from(e: object::Error) -> Self {
        ElfError::Parse(e)
    }
}

/// One loadable segment: `data` (file contents) followed by zeros up to
/// `mem_size`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    pub addr: u32,
    pub data: Vec<u8>,
    pub mem_size: u32,
}

/// A parsed executable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoadedElf {
    pub entry: u32,
    pub segments: Vec<Segment>,
    /// Defined symbols by name (for `tohost`, `begin_signature`, ...).
    pub symbols: BTreeMap<String, u32>,
}

/// Parse an ELF image.
pub fn load_elf(bytes: &[u8]) -> Result<LoadedElf, ElfError> {
    let file = object::File::parse(bytes)?;
    if file.architecture() != Architecture::Riscv32 || !file.is_little_endian() {
        return Err(ElfError::WrongArchitecture(file.architecture()));
    }
    // Segments are placed at their physical (load) address, as QEMU and
    // debug probes do for bare-metal images: a `.data` linked to run in RAM
    // but stored after the code is loaded where the start file copies it
    // from.
    let elf = ElfFile32::<Endianness>::parse(bytes)?;
    let endian = elf.endian();
    let mut segments = Vec::new();
    for ph in elf.elf_program_headers() {
        if ph.p_type(endian) != elf::PT_LOAD {
            continue;
        }
        let addr = ph.p_paddr(endian) as u64;
        let mem_size = ph.p_memsz(endian) as u64;
        if mem_size == 0 {
            continue;
        }
        let data = ph
            .data(endian, bytes)
            .map_err(|()| ElfError::Truncated { addr })?
            .to_vec();
        let fits = addr + mem_size <= 1 << 32 && (data.len() as u64) <= mem_size;
        if !fits {
            return Err(ElfError::SegmentOutOfRange {
                addr,
                len: mem_size,
            });
        }
        segments.push(Segment {
            addr: addr as u32,
            data,
            mem_size: mem_size as u32,
        });
    }
    let symbols = file
        .symbols()
        .filter(|s| s.is_definition() || s.address() != 0)
        .filter_map(|s| Some((s.name().ok()?.to_string(), s.address() as u32)))
        .filter(|(n, _)| !n.is_empty())
        .collect();
    Ok(LoadedElf {
        entry: file.entry() as u32,
        segments,
        symbols,
    })
}

impl LoadedElf {
    /// Lowest address of any segment.
    pub fn lowest_address(&self) -> Option<u32> {
        self.segments.iter().map(|s| s.addr).min()
    }

    /// Address of a symbol.
    pub fn symbol(&self, name: &str) -> Option<u32> {
        self.symbols.get(name).copied()
    }

    /// Copy every segment into RAM (zero-filling up to its memory size).
    pub fn load_into(&self, mem: &mut Memory) -> Result<(), ElfError> {
        for s in &self.segments {
            let outside = |_: MemError| ElfError::SegmentOutsideRam {
                addr: s.addr,
                len: s.mem_size as u64,
            };
            if !mem.is_ram(s.addr, s.mem_size) {
                return Err(outside(MemError::OutOfRam {
                    addr: s.addr,
                    len: s.mem_size as u64,
                }));
            }
            mem.write_bytes(s.addr, &s.data).map_err(outside)?;
            let zeros = vec![0u8; (s.mem_size as usize) - s.data.len()];
            mem.write_bytes(s.addr.wrapping_add(s.data.len() as u32), &zeros)
                .map_err(outside)?;
        }
        Ok(())
    }
}
