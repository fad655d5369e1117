//! The register-protocol test device shared by the idle-skipping tests and
//! the ISS benchmark.

use sim_core::iss::{AccessSize, Mmio, MmioError};
use sim_core::units::Picos;

pub const CTRL: u32 = 0x2000_0000;
pub const STAT: u32 = 0x2000_0001;

/// A device in the style of the thesis's sensors: writing an opcode to the
/// control register starts an operation that completes `delay(op)` later,
/// when the status register shows the opcode (DESIGN.md §4, "a completed
/// operation shows its own code in the status register at the time the
/// operation completes").
#[derive(Debug, Default, Clone)]
pub struct OpDevice {
    ctrl: u8,
    status: u8,
    pending: Option<(u8, Picos)>,
    /// Report completions as kernel events (the kernel then calls `tick`).
    pub eventful: bool,
    /// Every write, with the time the device saw it.
    pub writes: Vec<(u32, u32, Picos)>,
    /// Reads that returned a completed status, with their time.
    pub completions_seen: Vec<(u8, Picos)>,
}

impl OpDevice {
    pub fn delay(op: u8) -> Picos {
        // Not multiples of the 4 ns clock period, to exercise rounding.
        Picos(op as u64 * 1_000_000_000 + 1_234_567)
    }

    /// Lazily complete the pending operation once its time has come.
    pub fn settle(&mut self, now: Picos) {
        if let Some((op, at)) = self.pending {
            if now >= at {
                self.status = op;
                self.pending = None;
            }
        }
    }
}

impl Mmio for OpDevice {
    fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError> {
        self.settle(now);
        let v = match (addr, size) {
            (CTRL, AccessSize::Byte) => self.ctrl as u32,
            (STAT, AccessSize::Byte) => self.status as u32,
            (CTRL, AccessSize::Word) => self.ctrl as u32 | (self.status as u32) << 8,
            _ => return Err(MmioError::AccessFault { addr }),
        };
        if self.status != 0 && self.completions_seen.last().map(|c| c.0) != Some(self.status) {
            self.completions_seen.push((self.status, now));
        }
        Ok(v)
    }

    fn write(
        &mut self,
        addr: u32,
        size: AccessSize,
        value: u32,
        now: Picos,
    ) -> Result<(), MmioError> {
        self.settle(now);
        self.writes.push((addr, value, now));
        match (addr, size) {
            (CTRL, AccessSize::Byte) => {
                self.ctrl = value as u8;
                if value != 0 {
                    self.pending = Some((value as u8, now + Self::delay(value as u8)));
                }
            }
            (STAT, AccessSize::Byte) => self.status = value as u8,
            _ => return Err(MmioError::AccessFault { addr }),
        }
        Ok(())
    }

    fn stable_until(&self, _addr: u32, _size: AccessSize, now: Picos) -> Picos {
        match self.pending {
            Some((_, at)) if at > now => at,
            Some(_) => now,
            None => Picos::MAX,
        }
    }

    fn next_event(&self) -> Option<Picos> {
        if self.eventful {
            self.pending.map(|(_, at)| at)
        } else {
            None
        }
    }
}
