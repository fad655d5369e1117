//! The cluster DMA (MCHAN, docs/CLUSTER.md "DMA"): 1D and 2D copies
//! between L2 and L1, a queue of [`QUEUE_DEPTH`] commands run in order,
//! bursts of at most [`BURST_BYTES`] at [`BYTES_PER_CYCLE`] per cluster
//! cycle each way, completion as STATUS bits and event 8, while the cores
//! go on computing.
//!
//! # Timing (closed form)
//!
//! A command enqueued at `t` starts at `max(t + SETUP_CYCLES, end of the
//! previous command)` and lasts `Σ ceil(burst / 8)` cycles over its bursts
//! (a 1D copy of `n` bytes, a multiple of 8: `n / 8` cycles). Reads of
//! the source and writes of the destination are pipelined (each side moves
//! 8 B per cycle), so a burst costs its transfer cycles once.
//!
//! # When the bytes move
//!
//! The model copies a command's bytes at its completion time: from then on
//! the destination holds them (a program that reads it before waiting sees
//! the old bytes, where the hardware could show a partial copy; correct
//! programs wait).

use std::collections::VecDeque;

use super::MAX_CORES;
use crate::units::Picos;

/// Commands queued or running at once (docs/CLUSTER.md, DESIGN.md §12).
pub const QUEUE_DEPTH: usize = 16;
/// Largest burst (DESIGN.md §12: "bursts of at most 256 B").
pub const BURST_BYTES: u32 = 256;
/// Bytes per cluster cycle each way (DESIGN.md §12: 64-bit ports).
pub const BYTES_PER_CYCLE: u32 = 8;
/// Cycles from the CMD store to the first burst: the command crosses the
/// core's DMA port, the queue and the engine's address generation. An
/// assumption (no public GAP8 figure found): docs/CLUSTER.md.
pub const SETUP_CYCLES: u64 = 4;

pub const EXT: u32 = 0x00;
pub const LOC: u32 = 0x04;
pub const SIZE: u32 = 0x08;
pub const STRIDE: u32 = 0x0C;
pub const LENGTH: u32 = 0x10;
pub const CMD: u32 = 0x14;
pub const ID: u32 = 0x18;
pub const STATUS: u32 = 0x1C;

/// CMD bit 0: 1 = L1 → L2.
pub const CMD_LOC2EXT: u32 = 1;
/// CMD bit 1: 2D on the L2 side.
pub const CMD_2D: u32 = 2;

/// One core's staging registers.
#[derive(Debug, Clone, Copy, Default)]
struct Staging {
    ext: u32,
    loc: u32,
    size: u32,
    stride: u32,
    length: u32,
}

/// A queued command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Command {
    pub id: u32,
    pub core: usize,
    pub loc2ext: bool,
    pub ext: u32,
    pub loc: u32,
    pub size: u32,
    /// 2D: `(stride, length)` on the L2 side.
    pub two_d: Option<(u32, u32)>,
    pub done: Picos,
}

impl Command {
    /// The pieces `(ext, loc, bytes)` it copies: one per line (2D) or one.
    pub fn pieces(&self) -> Vec<(u32, u32, u32)> {
        match self.two_d {
            None => vec![(self.ext, self.loc, self.size)],
            Some((stride, length)) => {
                let mut v = Vec::new();
                let mut done = 0;
                let mut k = 0u32;
                while done < self.size {
                    let n = length.min(self.size - done);
                    v.push((
                        self.ext.wrapping_add(k.wrapping_mul(stride)),
                        self.loc.wrapping_add(done),
                        n,
                    ));
                    done += n;
                    k += 1;
                }
                v
            }
        }
    }

    /// Transfer cycles: every piece split into bursts of at most 256 B,
    /// each `ceil(bytes / 8)` cycles.
    pub fn cycles(&self) -> u64 {
        self.pieces()
            .iter()
            .map(|&(_, _, n)| {
                let full = (n / BURST_BYTES) as u64 * (BURST_BYTES / BYTES_PER_CYCLE) as u64;
                full + (n % BURST_BYTES).div_ceil(BYTES_PER_CYCLE) as u64
            })
            .sum()
    }
}

/// Why an access to the DMA did not complete.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DmaRefusal {
    /// The queue is full: the core sleeps until a command completes.
    Full,
    /// Not a register, or a command that does not fit L1/L2.
    Fault,
}

/// The engine.
#[derive(Debug, Clone)]
pub struct Dma {
    period: Picos,
    staging: [Staging; MAX_CORES],
    last_id: [u32; MAX_CORES],
    queue: VecDeque<Command>,
    busy_until: Picos,
    /// Bytes copied so far (the power model).
    pub bytes: u64,
    /// Transfer cycles so far (the power model: the engine is active).
    pub busy_cycles: u64,
    /// `(base, size)` of L1 and L2: a command must stay inside them.
    l1: (u32, u32),
    l2: (u32, u32),
}

fn inside(r: (u32, u32), a: u32, n: u32) -> bool {
    let off = a.wrapping_sub(r.0) as u64;
    off + n as u64 <= r.1 as u64
}

impl Dma {
    pub fn new(period: Picos, l1: (u32, u32), l2: (u32, u32)) -> Dma {
        Dma {
            period,
            staging: [Staging::default(); MAX_CORES],
            last_id: [0; MAX_CORES],
            queue: VecDeque::new(),
            busy_until: Picos::ZERO,
            bytes: 0,
            busy_cycles: 0,
            l1,
            l2,
        }
    }

    /// Completion time of the oldest queued command.
    pub fn next_completion(&self) -> Option<Picos> {
        self.queue.front().map(|c| c.done)
    }

    /// Remove the oldest command if it completes at or before `t`.
    pub fn pop_completed(&mut self, t: Picos) -> Option<Command> {
        if self.queue.front().is_some_and(|c| c.done <= t) {
            let c = self.queue.pop_front()?;
            self.bytes += c.size as u64;
            return Some(c);
        }
        None
    }

    pub fn read(&self, core: usize, off: u32) -> Result<u32, DmaRefusal> {
        Ok(match off {
            ID => self.last_id[core],
            STATUS => self.queue.iter().fold(0, |m, c| m | 1 << c.id),
            _ => return Err(DmaRefusal::Fault),
        })
    }

    pub fn write(&mut self, core: usize, off: u32, v: u32, t: Picos) -> Result<(), DmaRefusal> {
        let s = &mut self.staging[core];
        match off {
            EXT => s.ext = v,
            LOC => s.loc = v,
            SIZE => s.size = v,
            STRIDE => s.stride = v,
            LENGTH => s.length = v,
            CMD => return self.enqueue(core, v, t),
            _ => return Err(DmaRefusal::Fault),
        }
        Ok(())
    }

    fn enqueue(&mut self, core: usize, cmd: u32, t: Picos) -> Result<(), DmaRefusal> {
        if self.queue.len() >= QUEUE_DEPTH {
            return Err(DmaRefusal::Full);
        }
        let s = self.staging[core];
        let two_d = (cmd & CMD_2D != 0).then_some((s.stride, s.length));
        if two_d.is_some_and(|(_, len)| len == 0) {
            return Err(DmaRefusal::Fault);
        }
        let mut c = Command {
            id: 0,
            core,
            loc2ext: cmd & CMD_LOC2EXT != 0,
            ext: s.ext,
            loc: s.loc,
            size: s.size,
            two_d,
            done: Picos::ZERO,
        };
        let fits = inside(self.l1, c.loc, c.size)
            && c.pieces().iter().all(|&(e, _, n)| inside(self.l2, e, n));
        if !fits {
            return Err(DmaRefusal::Fault);
        }
        let used = self.queue.iter().fold(0u32, |m, c| m | 1 << c.id);
        c.id = (0..QUEUE_DEPTH as u32)
            .find(|i| used & (1 << i) == 0)
            .expect("a free id below the queue depth");
        let cycles = c.cycles();
        let start = (t + Picos(SETUP_CYCLES * self.period.0)).max(self.busy_until);
        c.done = start + Picos(cycles * self.period.0);
        self.busy_until = c.done;
        self.busy_cycles += cycles;
        self.last_id[core] = c.id;
        self.queue.push_back(c);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const L1: (u32, u32) = (0x1000_0000, 0x1_0000);
    const L2: (u32, u32) = (0x1c00_0000, 0x8_0000);

    #[test]
    fn closed_form_time_and_queue_order() {
        let mut d = Dma::new(Picos(10), L1, L2);
        for (o, v) in [(EXT, L2.0), (LOC, L1.0), (SIZE, 1024)] {
            d.write(0, o, v, Picos(0)).unwrap();
        }
        d.write(0, CMD, 0, Picos(100)).unwrap();
        // 100 + 4 setup cycles + 1024 / 8 cycles.
        assert_eq!(d.next_completion(), Some(Picos(100 + 40 + 1280)));
        d.write(0, CMD, 0, Picos(200)).unwrap();
        assert_eq!(d.read(0, ID), Ok(1));
        assert_eq!(d.read(0, STATUS), Ok(0b11));
        assert!(d.pop_completed(Picos(1419)).is_none());
        assert_eq!(d.pop_completed(Picos(1420)).map(|c| c.id), Some(0));
        // The second runs after the first.
        assert_eq!(d.next_completion(), Some(Picos(1420 + 1280)));
    }

    #[test]
    fn two_d_lines_and_bursts() {
        let c = Command {
            id: 0,
            core: 0,
            loc2ext: false,
            ext: L2.0,
            loc: L1.0,
            size: 100,
            two_d: Some((64, 30)),
            done: Picos::ZERO,
        };
        let p = c.pieces();
        assert_eq!(p.len(), 4);
        assert_eq!(p[3], (L2.0 + 192, L1.0 + 90, 10));
        // ceil(30/8) * 3 + ceil(10/8)
        assert_eq!(c.cycles(), 4 * 3 + 2);
        let big = Command {
            size: 600,
            two_d: None,
            ..c
        };
        // 256 + 256 + 88 bytes: 32 + 32 + 11 cycles.
        assert_eq!(big.cycles(), 75);
    }
}
