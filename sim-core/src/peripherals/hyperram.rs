//! The AI deck's HyperRAM (L3; the 64 Mbit HyperRAM die of its
//! S71KS512SC0 HyperFlash + HyperRAM package) behind the GAP8's µDMA (DESIGN.md §18,
//! docs/NN_ONNX.md "Memory"): 8 MiB the cores cannot address, reached
//! only by transfers to and from L2 that the FC queues and the µDMA's
//! HyperBus channel carries while the FC and the cluster go on.
//!
//! # Registers (32-bit, at [`BASE`], GAP8's µDMA address)
//! The offsets are this model's own (the runtime's `pmsis/udma_regs.h`),
//! not GAP8's channel layout: the PMSIS RAM API (`pi_ram_read`, ...) is
//! what programs use.
//!
//! | off | name | |
//! |---|---|---|
//! | 0x00 | L2_ADDR | L2 side of the next transfer |
//! | 0x04 | L3_ADDR | HyperRAM side (0 .. 8 MiB) |
//! | 0x08 | SIZE | bytes |
//! | 0x0C | CMD | write 1: L3 → L2, 2: L2 → L3; queues the transfer |
//! | 0x10 | DONE | transfers completed since reset |
//! | 0x14 | ISSUED | transfers queued since reset |
//!
//! # Timing (closed form)
//! Transfers run one after another in queue order. One queued at `t`
//! starts at `max(t, end of the previous one)` and ends `LATENCY +
//! size / BANDWIDTH` later ([`Timing`]). The bytes move at the end: the
//! ISS stops at [`Mmio::next_event`], the host calls
//! [`HyperRam::complete`] with the memory, which copies them and counts
//! the transfer DONE (a program that reads the destination before DONE
//! says so sees the old bytes, where the chip could show part of it;
//! correct programs wait).

use std::collections::VecDeque;

use crate::iss::{AccessSize, Memory, Mmio, MmioError};
use crate::units::Picos;

/// GAP8's µDMA (the SoC peripherals at 0x1A10_0000, µDMA at +0x2000).
pub const BASE: u32 = 0x1a10_2000;
/// Bytes of the register window.
pub const WINDOW: u32 = 0x1000;
/// The AI deck's HyperRAM: 64 Mbit (in the S71KS512SC0 package).
pub const SIZE_BYTES: usize = 8 << 20;

pub const L2_ADDR: u32 = 0x00;
pub const L3_ADDR: u32 = 0x04;
pub const SIZE: u32 = 0x08;
pub const CMD: u32 = 0x0C;
pub const DONE: u32 = 0x10;
pub const ISSUED: u32 = 0x14;
pub const CMD_READ: u32 = 1;
pub const CMD_WRITE: u32 = 2;

/// The channel's timing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// From the transfer's start to its first byte.
    pub latency: Picos,
    /// Bytes per second once streaming.
    pub bytes_per_s: u64,
}

impl Timing {
    /// GAP8's HyperRAM copies as measured on silicon (a GAPuino board's
    /// L3 -> L2 copies: about 6 µs per blocking copy, then 38-40 MB/s;
    /// docs/NN_SILICON.md "L3"): far below the HyperBus's 333 MB/s
    /// ceiling (2 bytes per clock at 166 MHz), which no GAP8 measurement
    /// approaches.
    pub const AI_DECK: Timing = Timing {
        latency: Picos::from_us(6),
        bytes_per_s: 40_000_000,
    };

    /// How long `bytes` take.
    pub fn duration(&self, bytes: u32) -> Picos {
        // In integers: a float quotient lands a picosecond off exact ones.
        let ps = (bytes as u128 * 1_000_000_000_000).div_ceil(self.bytes_per_s.max(1) as u128);
        Picos(self.latency.0 + ps as u64)
    }
}

#[derive(Clone, Copy, Debug)]
struct Transfer {
    l2: u32,
    l3: u32,
    size: u32,
    to_l2: bool,
    end: Picos,
}

/// The HyperRAM and its µDMA channel.
pub struct HyperRam {
    data: Vec<u8>,
    staged: [u32; 3],
    queue: VecDeque<Transfer>,
    busy_until: Picos,
    issued: u32,
    done: u32,
    timing: Timing,
    /// Bytes read from and written to the HyperRAM so far.
    pub bytes_read: u64,
    pub bytes_written: u64,
    /// Time the channel spent transferring.
    pub busy: Picos,
    /// When DONE last changed (the end of the last completed transfer).
    done_changed: Picos,
}

impl Default for HyperRam {
    fn default() -> Self {
        Self::new(Timing::AI_DECK)
    }
}

impl HyperRam {
    pub fn new(timing: Timing) -> Self {
        HyperRam {
            data: vec![0; SIZE_BYTES],
            staged: [0; 3],
            queue: VecDeque::new(),
            busy_until: Picos(0),
            issued: 0,
            done: 0,
            timing,
            bytes_read: 0,
            bytes_written: 0,
            busy: Picos(0),
            done_changed: Picos(0),
        }
    }

    /// Fills the HyperRAM from address 0 (what a loader or the flash
    /// would have put there before the program runs).
    pub fn load(&mut self, bytes: &[u8]) -> Result<(), String> {
        if bytes.len() > SIZE_BYTES {
            return Err(format!(
                "{} B do not fit the {SIZE_BYTES} B HyperRAM",
                bytes.len()
            ));
        }
        self.data[..bytes.len()].copy_from_slice(bytes);
        Ok(())
    }

    /// The channel's state in words, for a run that stopped waiting.
    pub fn describe(&self) -> String {
        format!(
            "HyperRAM: {} transfers queued, {} done, next end {:?}",
            self.issued,
            self.done,
            self.queue.front().map(|t| t.end)
        )
    }

    /// Copies every transfer that has ended by `now` and counts it done.
    pub fn complete(&mut self, now: Picos, mem: &mut Memory) -> Result<(), String> {
        while let Some(t) = self.queue.front().copied() {
            if t.end > now {
                break;
            }
            self.queue.pop_front();
            let (a, n) = (t.l3 as usize, t.size as usize);
            if t.to_l2 {
                mem.write_bytes(t.l2, &self.data[a..a + n])
                    .map_err(|e| format!("HyperRAM read into L2 {:#010x}: {e}", t.l2))?;
                self.bytes_read += n as u64;
            } else {
                mem.read_bytes(t.l2, &mut self.data[a..a + n])
                    .map_err(|e| format!("HyperRAM write from L2 {:#010x}: {e}", t.l2))?;
                self.bytes_written += n as u64;
            }
            self.done = self.done.wrapping_add(1);
            self.done_changed = self.done_changed.max(t.end);
        }
        Ok(())
    }

    fn queue_transfer(&mut self, cmd: u32, now: Picos) -> Result<(), MmioError> {
        let [l2, l3, size] = self.staged;
        let to_l2 = match cmd {
            CMD_READ => true,
            CMD_WRITE => false,
            _ => return Err(MmioError::AccessFault { addr: BASE + CMD }),
        };
        // A transfer beyond L3 faults the CMD store (the program's error).
        if (l3 as u64 + size as u64) > SIZE_BYTES as u64 {
            return Err(MmioError::AccessFault { addr: BASE + CMD });
        }
        let start = now.max(self.busy_until);
        let d = self.timing.duration(size);
        let end = Picos(start.0 + d.0);
        self.busy = Picos(self.busy.0 + d.0);
        self.busy_until = end;
        self.queue.push_back(Transfer {
            l2,
            l3,
            size,
            to_l2,
            end,
        });
        self.issued = self.issued.wrapping_add(1);
        Ok(())
    }
}

impl Mmio for HyperRam {
    fn read(&mut self, addr: u32, _size: AccessSize, _now: Picos) -> Result<u32, MmioError> {
        match addr.wrapping_sub(BASE) {
            L2_ADDR => Ok(self.staged[0]),
            L3_ADDR => Ok(self.staged[1]),
            SIZE => Ok(self.staged[2]),
            DONE => Ok(self.done),
            ISSUED => Ok(self.issued),
            _ => Err(MmioError::AccessFault { addr }),
        }
    }

    fn write(&mut self, addr: u32, _size: AccessSize, v: u32, now: Picos) -> Result<(), MmioError> {
        match addr.wrapping_sub(BASE) {
            L2_ADDR => self.staged[0] = v,
            L3_ADDR => self.staged[1] = v,
            SIZE => self.staged[2] = v,
            CMD => self.queue_transfer(v, now)?,
            _ => return Err(MmioError::AccessFault { addr }),
        }
        Ok(())
    }

    /// DONE changes only when the host completes a transfer, at the
    /// queue's first end; the other registers only on writes. The ISS may
    /// ask about a read it made before a completion (a polling loop's
    /// iteration that straddled the stop): then the value it read has
    /// changed since, at `done_changed`, and no iteration may be skipped.
    fn stable_until(&self, addr: u32, _size: AccessSize, now: Picos) -> Picos {
        match addr.wrapping_sub(BASE) {
            DONE if now < self.done_changed => now,
            DONE => self.queue.front().map_or(Picos::MAX, |t| t.end).max(now),
            _ => Picos::MAX,
        }
    }

    fn next_event(&self) -> Option<Picos> {
        self.queue.front().map(|t| t.end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transfers_queue_in_order_and_copy_at_their_end() {
        let t = Timing {
            latency: Picos::from_ns(100),
            bytes_per_s: 1_000_000_000,
        };
        let mut h = HyperRam::new(t);
        let mut mem = Memory::new();
        mem.add_ram(0x1c00_0000, 0x1000).unwrap();
        h.load(&[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        let w =
            |h: &mut HyperRam, off, v| h.write(BASE + off, AccessSize::Word, v, Picos(0)).unwrap();
        w(&mut h, L2_ADDR, 0x1c00_0010);
        w(&mut h, L3_ADDR, 2);
        w(&mut h, SIZE, 4);
        w(&mut h, CMD, CMD_READ);
        w(&mut h, L2_ADDR, 0x1c00_0020);
        w(&mut h, CMD, CMD_READ);
        // 100 ns + 4 ns each, the second after the first.
        assert_eq!(h.next_event(), Some(Picos::from_ns(104)));
        h.complete(Picos::from_ns(103), &mut mem).unwrap();
        assert_eq!(h.read(BASE + DONE, AccessSize::Word, Picos(0)).unwrap(), 0);
        h.complete(Picos::from_ns(104), &mut mem).unwrap();
        assert_eq!(h.read(BASE + DONE, AccessSize::Word, Picos(0)).unwrap(), 1);
        assert_eq!(h.next_event(), Some(Picos::from_ns(208)));
        h.complete(Picos::from_ns(208), &mut mem).unwrap();
        let mut b = [0u8; 4];
        mem.read_bytes(0x1c00_0020, &mut b).unwrap();
        assert_eq!(b, [3, 4, 5, 6]);
        assert_eq!(
            h.read(BASE + ISSUED, AccessSize::Word, Picos(0)).unwrap(),
            2
        );
        assert_eq!(h.bytes_read, 8);
    }

    /// A read of DONE made before a completion is not promised stable
    /// after it (the ISS asks when it verifies a polling iteration that
    /// straddled the completion's stop).
    #[test]
    fn a_read_before_a_completion_gets_no_promise() {
        let mut h = HyperRam::new(Timing {
            latency: Picos::from_ns(100),
            bytes_per_s: 1_000_000_000,
        });
        let mut mem = Memory::new();
        mem.add_ram(0x1c00_0000, 0x1000).unwrap();
        for (off, v) in [(L2_ADDR, 0x1c00_0000), (SIZE, 4), (CMD, CMD_READ)] {
            h.write(BASE + off, AccessSize::Word, v, Picos(0)).unwrap();
        }
        let before = Picos::from_ns(50);
        assert_eq!(
            h.stable_until(BASE + DONE, AccessSize::Word, before),
            Picos::from_ns(104)
        );
        h.complete(Picos::from_ns(110), &mut mem).unwrap();
        assert_eq!(
            h.stable_until(BASE + DONE, AccessSize::Word, before),
            before
        );
        let after = Picos::from_ns(120);
        assert_eq!(
            h.stable_until(BASE + DONE, AccessSize::Word, after),
            Picos::MAX
        );
    }

    #[test]
    fn a_transfer_beyond_8_mib_faults() {
        let mut h = HyperRam::default();
        h.write(
            BASE + L3_ADDR,
            AccessSize::Word,
            SIZE_BYTES as u32 - 2,
            Picos(0),
        )
        .unwrap();
        h.write(BASE + SIZE, AccessSize::Word, 4, Picos(0)).unwrap();
        assert!(h
            .write(BASE + CMD, AccessSize::Word, CMD_READ, Picos(0))
            .is_err());
    }
}
