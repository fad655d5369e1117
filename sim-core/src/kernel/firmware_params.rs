//! Firmware parameters (`firmware.NAME = value` run keys): written into the
//! firmware's globals by their ELF symbols before the core starts, as a
//! debugger would, so one ELF runs with the settings of a scenario or a
//! sweep (the exploration's cell size and FOV, docs/EXPLORE.md). The
//! globals are 32-bit integers; a name the ELF does not define is an
//! error, never a silent no-op. An initialised global lives twice: at its
//! run address in `.data` and in the load image that the start file copies
//! there (`__data_source` → `__data_start`, `start.S`); both are written.
//! A global in `.bss` would be zeroed by the start file after the write:
//! setting one is an error (initialise it to a non-zero value, or place it
//! in `.data`).

use std::collections::BTreeMap;

use super::KernelError;
use crate::iss::{LoadedElf, Memory};

pub fn apply(
    elf: &LoadedElf,
    mem: &mut Memory,
    params: &BTreeMap<String, i32>,
) -> Result<(), KernelError> {
    for (name, value) in params {
        let addr = elf.symbol(name).ok_or_else(|| {
            KernelError::Config(format!(
                "firmware.{name}: the firmware has no global named {name}"
            ))
        })?;
        if in_bss(elf, addr) {
            return Err(KernelError::Config(format!(
                "firmware.{name}: {name} is in .bss, which the start file clears: \
                 the firmware must initialise it or place it in .data"
            )));
        }
        let mut write = |at: u32| {
            mem.write_bytes(at, &value.to_le_bytes())
                .map_err(|e| KernelError::Config(format!("firmware.{name} at {at:#x}: {e}")))
        };
        write(addr)?;
        if let Some(load) = load_address(elf, addr) {
            write(load)?;
        }
    }
    Ok(())
}

/// Whether an address lies in `.bss` (`start.S` zeroes `__bss_size` bytes
/// from `__bss_start`).
fn in_bss(elf: &LoadedElf, addr: u32) -> bool {
    match (elf.symbol("__bss_start"), elf.symbol("__bss_size")) {
        (Some(start), Some(size)) => addr.wrapping_sub(start) < size,
        _ => false,
    }
}

/// Where the start file copies an address of `.data` from.
fn load_address(elf: &LoadedElf, addr: u32) -> Option<u32> {
    let start = elf.symbol("__data_start")?;
    let source = elf.symbol("__data_source")?;
    let size = elf.symbol("__data_size")?;
    let offset = addr.checked_sub(start).filter(|&o| o < size)?;
    (source != start).then(|| source + offset)
}
