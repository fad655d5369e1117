//! Loads and stores off the fast path: MMIO devices (their timing on the
//! bus), RAM with extra wait states, the CLINT, and the access faults.

use super::*;

impl Cpu {
    /// The cycle at which the current load/store issued: the table charges
    /// loads and stores 1 cycle, already added.
    fn issue_cycle(&self) -> u64 {
        self.cycles - 1
    }

    /// Extra cycles of a general-path RAM access (see [`MemTiming`]).
    pub(super) fn ram_extra(&self, mem: &mut Memory, addr: u32) -> u64 {
        if self.mem_timing.is_plain() {
            return 0;
        }
        self.mem_timing
            .extra(mem.l1_arbiter.as_deref_mut(), addr, self.issue_cycle())
    }

    pub(super) fn mmio_time(&self, issue: u64) -> Picos {
        Picos((issue + self.latency).saturating_mul(self.period))
    }

    /// One access to an MMIO window issued at cycle `issue`: charges the
    /// peripheral latency, performs it at its access time, then honours a
    /// stop request and picks up a newly scheduled event. `None`: the device
    /// answered with an access fault (the caller traps); `Some(Err(()))`: the
    /// device failed and the run stops.
    fn mmio_access(
        &mut self,
        dev: &mut dyn Mmio,
        issue: u64,
        access: impl FnOnce(&mut dyn Mmio, Picos) -> Result<u32, MmioError>,
    ) -> Option<Result<u32, ()>> {
        self.cycles += self.latency;
        let result = access(dev, self.mmio_time(issue));
        if dev.take_stop_request() {
            self.stop(StopReason::DeviceRequest);
        }
        self.refresh_event(dev);
        match result {
            Ok(v) => Some(Ok(v)),
            Err(MmioError::AccessFault { .. }) => None,
            Err(MmioError::Wait { .. }) => {
                self.waited = true;
                self.stop(StopReason::Wait);
                Some(Err(()))
            }
            Err(e) => {
                self.stop(StopReason::Fatal(e.into()));
                Some(Err(()))
            }
        }
    }

    #[cold]
    pub(super) fn load_slow(
        &mut self,
        mem: &mut Memory,
        dev: &mut dyn Mmio,
        addr: u32,
        size: AccessSize,
        pc: u32,
    ) -> Option<u32> {
        let issue = self.issue_cycle();
        if addr.wrapping_sub(CLINT_BASE) < CLINT_SIZE {
            self.poll.touched = true;
            self.poll.unskippable = true;
            if let Some(v) = self.clint_read(addr - CLINT_BASE, size) {
                return Some(v);
            }
        } else if mem.is_mmio(addr) {
            match self.mmio_access(dev, issue, |d, now| d.read(addr, size, now)) {
                Some(Ok(v)) => {
                    self.record_poll_read(addr, size, issue);
                    return Some(v);
                }
                Some(Err(())) => return None,
                None => {}
            }
        }
        self.trap(mem, cause::LOAD_ACCESS, addr, pc);
        None
    }

    #[cold]
    pub(super) fn store_slow(
        &mut self,
        mem: &mut Memory,
        dev: &mut dyn Mmio,
        addr: u32,
        size: AccessSize,
        value: u32,
        pc: u32,
    ) -> bool {
        let issue = self.issue_cycle();
        if mem.store_ram(addr, size, value) {
            self.cycles += self.ram_extra(mem, addr);
            self.cycles += timing::split_cost(addr, size);
            if let Some(th) = self.tohost {
                // riscv-tests: a non-zero tohost ends the test; 1 is a pass,
                // any other odd value v a failure of test v >> 1.
                match mem.read_u32(th) {
                    Some(0) | None => {}
                    Some(1) => self.stop(StopReason::Exit { code: 0 }),
                    Some(v) if v & 1 == 1 => self.stop(StopReason::Exit {
                        code: ((v >> 1) as i32).max(1),
                    }),
                    Some(v) => tracing::warn!(value = v, "even tohost value ignored"),
                }
            }
            return true;
        }
        if addr.wrapping_sub(CLINT_BASE) < CLINT_SIZE {
            if self.clint_write(addr - CLINT_BASE, size, value) {
                return true;
            }
        } else if mem.is_mmio(addr) {
            let write = |d: &mut dyn Mmio, now| d.write(addr, size, value, now).map(|()| 0);
            if let Some(r) = self.mmio_access(dev, issue, write) {
                return r.is_ok();
            }
        }
        self.trap(mem, cause::STORE_ACCESS, addr, pc);
        false
    }

    fn clint_read(&self, off: u32, size: AccessSize) -> Option<u32> {
        if size != AccessSize::Word {
            return None;
        }
        Some(match off {
            CLINT_MSIP => self.msip as u32,
            CLINT_MTIMECMP => self.mtimecmp as u32,
            o if o == CLINT_MTIMECMP + 4 => (self.mtimecmp >> 32) as u32,
            CLINT_MTIME => self.mtime() as u32,
            o if o == CLINT_MTIME + 4 => (self.mtime() >> 32) as u32,
            _ => return None,
        })
    }

    fn clint_write(&mut self, off: u32, size: AccessSize, v: u32) -> bool {
        if size != AccessSize::Word {
            return false;
        }
        let lo = |x: u64| (x & !0xffff_ffff) | v as u64;
        let hi = |x: u64| (x & 0xffff_ffff) | (v as u64) << 32;
        match off {
            CLINT_MSIP => self.msip = v & 1 != 0,
            CLINT_MTIMECMP => self.mtimecmp = lo(self.mtimecmp),
            o if o == CLINT_MTIMECMP + 4 => self.mtimecmp = hi(self.mtimecmp),
            CLINT_MTIME => self.mtime_off = lo(self.mtime()).wrapping_sub(self.cycles),
            o if o == CLINT_MTIME + 4 => {
                self.mtime_off = hi(self.mtime()).wrapping_sub(self.cycles)
            }
            _ => return false,
        }
        self.break_block();
        true
    }
}
