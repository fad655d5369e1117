//! Firmware parameters (`firmware.NAME = value` run keys): written into the
//! firmware's globals by their ELF symbols before the core starts, as a
//! debugger would, so one ELF runs with a scenario's or a sweep's settings
//! (the exploration's cell size and FOV, docs/EXPLORE.md). The globals are
//! 32-bit integers; a name the ELF does not define is an error, never a
//! silent no-op.

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
        mem.write_bytes(addr, &value.to_le_bytes())
            .map_err(|e| KernelError::Config(format!("firmware.{name} at {addr:#x}: {e}")))?;
    }
    Ok(())
}
