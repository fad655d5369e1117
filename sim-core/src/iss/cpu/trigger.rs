//! The CV32E40P's debug trigger CSRs as machine mode sees them.
//!
//! The core has one trigger, an instruction-address match whose action is
//! to enter debug mode (CV32E40P user manual v1.0, "Control and Status
//! Registers": tselect 0x7A0, tdata1 0x7A1 reset 0x2800_1040, tdata2
//! 0x7A2, tdata3 0x7A3, tinfo 0x7A4). tdata1's `dmode` is hard-wired to 1,
//! so by the RISC-V debug specification (0.13, §5.2) only debug mode may
//! write the trigger; machine mode reads the reset values and its writes
//! are ignored (Imperas' CV32E40P model does the same). We model no debug
//! mode, so the trigger never fires: these CSRs exist so that software
//! probing them (the riscv-tests' `breakpoint`, a debugger's stub) sees
//! the core's registers instead of an illegal instruction.

const TSELECT: u16 = 0x7a0;
const TDATA1: u16 = 0x7a1;
const TDATA2: u16 = 0x7a2;
const TDATA3: u16 = 0x7a3;
const TINFO: u16 = 0x7a4;

/// tdata1: type 2 (address/data match), dmode 1, action 1 (enter debug
/// mode), m 1 (matches in machine mode), execute 0.
const TDATA1_RESET: u32 = 0x2800_1040;
/// tinfo: bit 2, the one trigger type supported (2).
const TINFO_TYPES: u32 = 1 << 2;

/// The value machine mode reads, `None` for a CSR outside the trigger
/// module. Writes are ignored (see above), so there is no write side.
pub(super) fn read(csr: u16) -> Option<u32> {
    Some(match csr {
        TSELECT | TDATA2 | TDATA3 => 0,
        TDATA1 => TDATA1_RESET,
        TINFO => TINFO_TYPES,
        _ => return None,
    })
}
