//! The memory side of the ISS: RAM regions (owned here, accessed without any
//! dynamic dispatch) and the memory-mapped device window(s), reached through
//! the [`Mmio`] trait that the platform implements.
//!
//! # When an MMIO access happens
//!
//! A load or store that issues at core cycle `c` (the value of
//! [`Cpu::cycles`](super::Cpu::cycles) when the instruction starts, after any
//! load-use stall it suffers) reaches the device at simulated time
//! `(c + L) × period`, where `L` is the configurable peripheral latency
//! ([`CpuConfig::mmio_latency`](super::CpuConfig::mmio_latency)); the
//! instruction then costs its normal cycles plus `L`. The device sees that
//! time as the `now` argument and must answer as it would at that instant.
//!
//! # The idle-skip contract
//!
//! [`Mmio::stable_until`] lets a device promise that a register read at any
//! time in `[now, T)` returns the value it returns at `now` **and** that such
//! reads have no side effect (no read-to-clear, no per-read power state). The
//! ISS then skips whole iterations of a loop that only polls that register
//! (thesis Listing 4.6, `while(*status != OP);`) up to the last iteration whose
//! read happens before `T`, and lands in exactly the state a step-by-step run
//! reaches. Returning `now` (the default) promises nothing and disables
//! skipping for that register.

use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};

use thiserror::Error;

use crate::units::Picos;

use super::l1::BankArbiter;

/// Width of a memory access in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AccessSize {
    Byte = 1,
    Half = 2,
    Word = 4,
}

impl AccessSize {
    pub const fn bytes(self) -> u32 {
        self as u32
    }
}

/// Why a device refused an access.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MmioError {
    /// Nothing answers at this address (or not with this width): the core
    /// takes a load/store access-fault trap, as the hardware bus error would.
    #[error("access fault at {addr:#010x}")]
    AccessFault { addr: u32 },
    /// The device model itself failed (e.g. the world's socket closed during
    /// a blocking exchange): the run stops with this error.
    #[error("device failure at {addr:#010x}: {message}")]
    Device { addr: u32, message: String },
    /// The access cannot happen yet (a cluster core reading an event-unit
    /// register that sleeps, or any core touching state shared with
    /// another that has not caught up in simulated time): the instruction
    /// does not execute, the core stops with
    /// [`StopReason::Wait`](super::StopReason::Wait) with its pc on it, and
    /// the platform retries it later (see `crate::cluster`).
    #[error("access at {addr:#010x} must wait")]
    Wait { addr: u32 },
}

/// How a core's RAM accesses are timed beyond the instruction's own cycle:
/// the cluster's view of memory (DESIGN.md §12, `crate::cluster`). The
/// default (no extra cycles, no arbitration) is the FC of a platform
/// without a cluster.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MemTiming {
    /// L2 `(base, size)` and the extra cycles of every access to it.
    pub l2: (u32, u32),
    pub l2_extra: u64,
    /// L1 `(base, size)` and the extra cycles of every access to it.
    pub l1: (u32, u32),
    pub l1_extra: u64,
    /// The L1 arbiter's port of this core: its accesses wait for their
    /// bank ([`Memory::l1_arbiter`]); `None`: no arbitration (the FC's view).
    pub l1_port: Option<u8>,
}

impl MemTiming {
    /// Whether an access may cost more than the instruction's cycle.
    #[inline(always)]
    pub fn is_plain(&self) -> bool {
        self.l2_extra == 0 && self.l1_extra == 0 && self.l1_port.is_none()
    }

    /// Extra cycles of an access to `addr` issued at `cycle`.
    #[inline]
    pub(crate) fn extra(
        &self,
        arbiter: Option<&mut (dyn BankArbiter + 'static)>,
        addr: u32,
        cycle: u64,
    ) -> u64 {
        if addr.wrapping_sub(self.l1.0) < self.l1.1 {
            let stall = match (self.l1_port, arbiter) {
                (Some(port), Some(t)) => t.access(port, addr, cycle),
                _ => 0,
            };
            self.l1_extra + stall
        } else if addr.wrapping_sub(self.l2.0) < self.l2.1 {
            self.l2_extra
        } else {
            0
        }
    }
}

/// The device side of the bus, implemented by the platform (the peripheral
/// window at 0x2000_0000, DESIGN.md §4). Addresses are absolute; only
/// addresses inside a window registered with [`Memory::add_mmio_window`] are
/// routed here.
pub trait Mmio {
    /// A load of `size` bytes at `addr`, at simulated time `now`.
    fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError>;

    /// A store of the low `size` bytes of `value` at `addr`, at time `now`.
    /// The device reacts synchronously (it may block, e.g. on a socket
    /// exchange with the world) and may schedule future changes.
    fn write(
        &mut self,
        addr: u32,
        size: AccessSize,
        value: u32,
        now: Picos,
    ) -> Result<(), MmioError>;

    /// The idle-skip contract (see the module documentation): the first time
    /// at or after `now` at which a read of this register could return a
    /// different value or have a side effect. `now` means "no promise",
    /// `Picos::MAX` means "never changes by itself".
    fn stable_until(&self, _addr: u32, _size: AccessSize, now: Picos) -> Picos {
        now
    }

    /// The earliest scheduled device event, if any. The ISS asks after every
    /// MMIO access and at the start of [`Cpu::run_until`](super::Cpu::run_until),
    /// and stops with [`StopReason::Event`](super::StopReason::Event) at the
    /// first instruction boundary at or after it, so the kernel can act.
    fn next_event(&self) -> Option<Picos> {
        None
    }

    /// Asked after every MMIO access: `true` makes the ISS stop with
    /// [`StopReason::DeviceRequest`](super::StopReason::DeviceRequest) right
    /// after the current instruction retires. Implementations should clear
    /// the request when they return `true`.
    fn take_stop_request(&mut self) -> bool {
        false
    }

    /// Registers that read like memory: `(base, bytes)`, where a load of
    /// `n` bytes at `base + k` returns `bytes[k..k + n]` (little-endian)
    /// with no side effect, whatever the time, and this until the next
    /// write to any device (the only thing that may change them). The
    /// block executor then loads from them in its hot loop, charging the
    /// MMIO latency as the general path does, instead of leaving at every
    /// access: a firmware copying the camera's frame makes 25,600 word
    /// reads per frame (docs/ISS.md "Device windows"). Such reads are
    /// memory reads, not device polls: the idle detector does not count
    /// them. `None` (the default): every register goes through
    /// [`Mmio::read`].
    fn plain_window(&mut self) -> Option<(u32, &[u8])> {
        None
    }
}

/// A bus with no devices: every access faults. Used by `run-elf`.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoDevices;

impl Mmio for NoDevices {
    fn read(&mut self, addr: u32, _size: AccessSize, _now: Picos) -> Result<u32, MmioError> {
        Err(MmioError::AccessFault { addr })
    }
    fn write(
        &mut self,
        addr: u32,
        _size: AccessSize,
        _value: u32,
        _now: Picos,
    ) -> Result<(), MmioError> {
        Err(MmioError::AccessFault { addr })
    }
}

/// Errors building or loading the memory map.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MemError {
    #[error("region {base:#010x}+{size:#x} overlaps another region or window")]
    Overlap { base: u32, size: u32 },
    #[error("region {base:#010x}+{size:#x} is empty, not 4-byte aligned or wraps around 4 GiB")]
    BadRegion { base: u32, size: u32 },
    #[error("{len} bytes at {addr:#010x} do not fit in any RAM region")]
    OutOfRam { addr: u32, len: u64 },
}

/// One RAM region, and which of its bytes hold decoded code (the code
/// cache's, [`CodeCache`](super::CodeCache)): memory keeps that mark, not
/// the decoded instructions, so that a store can tell whether it
/// overwrites code without knowing the cache (QEMU's dirty bits for its
/// translated pages, kept by the memory, not by the translation cache).
pub(crate) struct Region {
    pub(crate) base: u32,
    pub(crate) size: u32,
    pub(crate) data: Vec<u8>,
    /// One bit per halfword occupied by a decoded instruction.
    code_bits: Vec<u64>,
    /// Byte offsets `[code_lo, code_hi)` that hold every decoded
    /// instruction, so a store to data (the common case) skips the bitmap
    /// entirely.
    pub(crate) code_lo: usize,
    pub(crate) code_hi: usize,
}

impl Region {
    #[inline(always)]
    pub(crate) fn offset_of(&self, addr: u32, len: u32) -> Option<usize> {
        let off = addr.wrapping_sub(self.base);
        // `off + len` cannot overflow u64; compare in u64 to stay exact.
        if (off as u64) + (len as u64) <= self.size as u64 {
            Some(off as usize)
        } else {
            None
        }
    }

    /// Record that bytes `[off, off + len)` hold a decoded instruction.
    pub(crate) fn mark_code(&mut self, off: usize, len: usize) {
        for h in off >> 1..(off + len + 1) >> 1 {
            self.code_bits[h >> 6] |= 1 << (h & 63);
        }
        self.code_lo = self.code_lo.min(off);
        self.code_hi = self.code_hi.max(off + len);
    }

    /// Whether bytes `[off, off + len)` may overlap decoded code (a cheap
    /// range test; [`Region::overwrites_code`] is the exact one).
    #[inline(always)]
    pub(crate) fn near_code(&self, off: usize, len: usize) -> bool {
        off < self.code_hi && off + len > self.code_lo
    }

    /// Whether writing bytes `[off, off + len)` changes a decoded
    /// instruction.
    pub(crate) fn overwrites_code(&self, off: usize, len: usize) -> bool {
        self.near_code(off, len)
            && (off >> 1..(off + len + 1) >> 1)
                .any(|h| self.code_bits[h >> 6] & (1 << (h & 63)) != 0)
    }

    /// Forget every code mark of this region.
    fn clear_code(&mut self) {
        if self.code_lo < self.code_hi {
            let halves = self.code_lo >> 1..(self.code_hi + 1) >> 1;
            for w in &mut self.code_bits[halves.start >> 6..=(halves.end - 1) >> 6] {
                *w = 0;
            }
        }
        self.code_lo = usize::MAX;
        self.code_hi = 0;
    }
}

impl fmt::Debug for Region {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Region({:#010x}+{:#x})", self.base, self.size)
    }
}

/// A new code epoch, unique in the process (see [`Memory::code_epoch`]).
fn fresh_epoch() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// The core's view of memory: zero or more RAM regions and zero or more
/// address windows routed to the platform's [`Mmio`], and the L1 bank
/// arbiter when the platform has one. The code decoded and translated
/// from this RAM lives apart, in a [`CodeCache`](super::CodeCache) that
/// whoever owns the memory keeps beside it and hands to the cores with it.
#[derive(Debug)]
pub struct Memory {
    pub(crate) regions: Vec<Region>,
    windows: Vec<(u32, u32)>,
    /// Changes whenever decoded code is overwritten (and the code marks
    /// are dropped): a [`CodeCache`](super::CodeCache) holds the epoch its
    /// blocks were decoded under and empties itself when it differs.
    /// Unique in the process, so a cache handed another memory notices
    /// too.
    pub(crate) code_epoch: u64,
    /// The L1 bank arbiter when the platform has one (the cluster's):
    /// the cores' [`MemTiming::l1_port`] accesses go through it.
    pub l1_arbiter: Option<Box<dyn BankArbiter>>,
}

impl Default for Memory {
    fn default() -> Memory {
        Memory {
            regions: Vec::new(),
            windows: Vec::new(),
            code_epoch: fresh_epoch(),
            l1_arbiter: None,
        }
    }
}

fn check_range(base: u32, size: u32) -> Result<(), MemError> {
    if size == 0
        || !base.is_multiple_of(4)
        || !size.is_multiple_of(4)
        || base.checked_add(size - 1).is_none()
    {
        return Err(MemError::BadRegion { base, size });
    }
    Ok(())
}

fn overlaps(a: (u32, u32), b: (u32, u32)) -> bool {
    let (a0, a1) = (a.0 as u64, a.0 as u64 + a.1 as u64);
    let (b0, b1) = (b.0 as u64, b.0 as u64 + b.1 as u64);
    a0 < b1 && b0 < a1
}

impl Memory {
    pub fn new() -> Memory {
        Memory::default()
    }

    fn check_free(&self, base: u32, size: u32) -> Result<(), MemError> {
        check_range(base, size)?;
        let taken = self
            .regions
            .iter()
            .map(|r| (r.base, r.size))
            .chain(self.windows.iter().copied());
        if taken.into_iter().any(|t| overlaps(t, (base, size))) {
            return Err(MemError::Overlap { base, size });
        }
        Ok(())
    }

    /// Add a zeroed RAM region.
    pub fn add_ram(&mut self, base: u32, size: u32) -> Result<(), MemError> {
        self.check_free(base, size)?;
        self.regions.push(Region {
            base,
            size,
            data: vec![0; size as usize],
            code_bits: vec![0; (size as usize / 2).div_ceil(64)],
            code_lo: usize::MAX,
            code_hi: 0,
        });
        Ok(())
    }

    /// Route `[base, base + size)` to the platform's [`Mmio`].
    pub fn add_mmio_window(&mut self, base: u32, size: u32) -> Result<(), MemError> {
        self.check_free(base, size)?;
        self.windows.push((base, size));
        Ok(())
    }

    /// Whether `[addr, addr + len)` is RAM.
    pub fn is_ram(&self, addr: u32, len: u32) -> bool {
        self.regions
            .iter()
            .any(|r| r.offset_of(addr, len).is_some())
    }

    /// Whether `addr` is inside an MMIO window.
    pub fn is_mmio(&self, addr: u32) -> bool {
        self.windows.iter().any(|&(b, s)| addr.wrapping_sub(b) < s)
    }

    /// The RAM regions as `(base, size)`, in the order they were added.
    pub fn ram_regions(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.regions.iter().map(|r| (r.base, r.size))
    }

    #[inline(always)]
    pub(crate) fn region_index(&self, addr: u32, len: u32) -> Option<(usize, usize)> {
        find(&self.regions, addr, len)
    }

    /// Copy bytes into RAM (ELF loading, a device writing a buffer). If it
    /// overwrites decoded code, the code caches drop it
    /// ([`Memory::invalidate_code`]).
    pub fn write_bytes(&mut self, addr: u32, bytes: &[u8]) -> Result<(), MemError> {
        if bytes.is_empty() {
            return Ok(());
        }
        let len = u32::try_from(bytes.len()).map_err(|_| MemError::OutOfRam {
            addr,
            len: bytes.len() as u64,
        })?;
        let (i, off) = self.region_index(addr, len).ok_or(MemError::OutOfRam {
            addr,
            len: bytes.len() as u64,
        })?;
        let r = &mut self.regions[i];
        r.data[off..off + bytes.len()].copy_from_slice(bytes);
        if r.overwrites_code(off, bytes.len()) {
            self.invalidate_code();
        }
        Ok(())
    }

    /// Copy bytes out of RAM.
    pub fn read_bytes(&self, addr: u32, out: &mut [u8]) -> Result<(), MemError> {
        if out.is_empty() {
            return Ok(());
        }
        let err = MemError::OutOfRam {
            addr,
            len: out.len() as u64,
        };
        let len = u32::try_from(out.len()).map_err(|_| err.clone())?;
        let (i, off) = self.region_index(addr, len).ok_or(err)?;
        out.copy_from_slice(&self.regions[i].data[off..off + out.len()]);
        Ok(())
    }

    /// A little-endian word from RAM, if `[addr, addr + 4)` is RAM.
    pub fn read_u32(&self, addr: u32) -> Option<u32> {
        let mut b = [0u8; 4];
        self.read_bytes(addr, &mut b).ok()?;
        Some(u32::from_le_bytes(b))
    }

    /// RAM load used by the core's general path; `None` when not RAM.
    #[inline(always)]
    pub(crate) fn load_ram(&self, addr: u32, size: AccessSize) -> Option<u32> {
        ram_load(&self.regions, addr, size)
    }

    /// RAM store used by the core's general path; `false` when not RAM.
    /// Invalidates the decoded code if it overwrites one of its
    /// instructions.
    #[inline(always)]
    pub(crate) fn store_ram(&mut self, addr: u32, size: AccessSize, value: u32) -> bool {
        let n = size.bytes();
        let Some((i, off)) = self.region_index(addr, n) else {
            return false;
        };
        let r = &mut self.regions[i];
        let bytes = value.to_le_bytes();
        r.data[off..off + n as usize].copy_from_slice(&bytes[..n as usize]);
        if r.overwrites_code(off, n as usize) {
            self.invalidate_code();
        }
        true
    }

    /// Every decoded instruction is stale: drop the code marks and start a
    /// new code epoch, so that every [`CodeCache`](super::CodeCache) of
    /// this memory empties itself before its next use. Stores that
    /// overwrite decoded code call it (which is what makes `fence.i`
    /// free); a platform that changes RAM behind the core's back may too.
    pub fn invalidate_code(&mut self) {
        for r in &mut self.regions {
            r.clear_code();
        }
        self.code_epoch = fresh_epoch();
    }
}

/// The region holding `[addr, addr + len)` and the offset there.
#[inline(always)]
fn find(regions: &[Region], addr: u32, len: u32) -> Option<(usize, usize)> {
    regions
        .iter()
        .enumerate()
        .find_map(|(i, r)| r.offset_of(addr, len).map(|off| (i, off)))
}

/// A little-endian load from RAM; `None` when not RAM. (The core's block
/// loop calls it with the regions borrowed on their own.)
#[inline(always)]
pub(crate) fn ram_load(regions: &[Region], addr: u32, size: AccessSize) -> Option<u32> {
    let (i, off) = find(regions, addr, size.bytes())?;
    let d = &regions[i].data;
    Some(match size {
        AccessSize::Byte => d[off] as u32,
        AccessSize::Half => u16::from_le_bytes([d[off], d[off + 1]]) as u32,
        AccessSize::Word => u32::from_le_bytes([d[off], d[off + 1], d[off + 2], d[off + 3]]),
    })
}

/// A store to RAM that is not near decoded code; `false` otherwise (not
/// RAM, or possibly code: the core's general path then does it and keeps
/// the code caches coherent).
#[inline(always)]
pub(crate) fn ram_store_data(
    regions: &mut [Region],
    addr: u32,
    size: AccessSize,
    value: u32,
) -> bool {
    let n = size.bytes();
    let Some((i, off)) = find(regions, addr, n) else {
        return false;
    };
    let r = &mut regions[i];
    if r.near_code(off, n as usize) {
        return false;
    }
    let bytes = value.to_le_bytes();
    r.data[off..off + n as usize].copy_from_slice(&bytes[..n as usize]);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_reject_overlap_and_bad_shapes() {
        let mut m = Memory::new();
        m.add_ram(0x1000, 0x1000).unwrap();
        assert_eq!(
            m.add_ram(0x1800, 0x1000),
            Err(MemError::Overlap {
                base: 0x1800,
                size: 0x1000
            })
        );
        assert!(m.add_mmio_window(0x1ffc, 8).is_err());
        assert!(m.add_ram(0xffff_f000, 0x2000).is_err());
        assert!(m.add_ram(0x3000, 0).is_err());
        m.add_mmio_window(0x2000, 0x100).unwrap();
        assert!(m.is_mmio(0x20ff) && !m.is_mmio(0x2100));
    }

    #[test]
    fn bytes_round_trip_and_bounds() {
        let mut m = Memory::new();
        m.add_ram(0x1000, 0x100).unwrap();
        m.write_bytes(0x10fc, &[1, 2, 3, 4]).unwrap();
        assert_eq!(m.read_u32(0x10fc), Some(0x0403_0201));
        assert!(m.write_bytes(0x10fd, &[1, 2, 3, 4]).is_err());
        assert_eq!(m.load_ram(0x10fe, AccessSize::Half), Some(0x0403));
        assert_eq!(m.load_ram(0x10ff, AccessSize::Half), None);
    }
}
