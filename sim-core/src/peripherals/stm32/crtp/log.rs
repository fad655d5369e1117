//! Port 5, log (the firmware's `log.c`, cflib's `log.py`): channel 0 the TOC
//! ([`super::toc`]), channel 1 block control, channel 2 the periodic data.
//!
//! Control commands `[cmd, block, …]` are answered `[cmd, block, errno]`
//! (three bytes, also for RESET, as the firmware): CREATE_BLOCK_V2 (6) and
//! APPEND_BLOCK_V2 (7) take operations of three bytes each — the type byte
//! (low nibble: the log type the client wants the value in) and the 16-bit
//! TOC id; DELETE (2), START (3, with the period in 10 ms units), STOP (4),
//! RESET (5: every block deleted). Errors: ENOENT (no such block or
//! variable), EEXIST (the block exists), E2BIG (more than 26 data bytes),
//! ENOMEM (16 blocks), EINVAL (a malformed request or a memory variable,
//! which needs the firmware's address space and is not served).
//!
//! A started block is sent when its period has elapsed, at the first world
//! step at or after that time: `[block, t0, t1, t2, values…]` with the
//! firmware's 24-bit millisecond timestamp (`xTaskGetTickCount()`, here the
//! platform's simulated time).

use std::collections::BTreeMap;

use super::packet::{u16_at, MAX_DATA};
use super::telemetry::{encode, log_toc, type_size, LogGroups, LogVar, Telemetry};
use super::toc::{self, TocEntry};
use crate::units::Picos;

pub const CHAN_TOC: u8 = 0;
pub const CHAN_CONTROL: u8 = 1;
pub const CHAN_DATA: u8 = 2;

const CMD_DELETE_BLOCK: u8 = 2;
const CMD_START: u8 = 3;
const CMD_STOP: u8 = 4;
const CMD_RESET: u8 = 5;
const CMD_CREATE_BLOCK_V2: u8 = 6;
const CMD_APPEND_BLOCK_V2: u8 = 7;

/// errno values the firmware answers (newlib's).
const ENOENT: u8 = 2;
const E2BIG: u8 = 7;
const ENOMEM: u8 = 12;
const EEXIST: u8 = 17;
const EINVAL: u8 = 22;

/// The firmware's `LOG_MAX_BLOCKS` and `LOG_MAX_OPS` (sent in TOC info v2).
const MAX_BLOCKS: usize = 16;
const MAX_OPS: usize = 128;
/// Data bytes of a block: a packet's 30 minus the block id and timestamp.
const MAX_BLOCK_BYTES: usize = MAX_DATA - 4;

#[derive(Debug, Clone)]
struct Block {
    /// (TOC id, log type to send it as)
    ops: Vec<(u16, u8)>,
    period: Option<Picos>,
    next: Picos,
}

impl Block {
    fn bytes(&self) -> usize {
        self.ops.iter().filter_map(|&(_, t)| type_size(t)).sum()
    }
}

pub struct Log {
    vars: Vec<LogVar>,
    entries: Vec<TocEntry>,
    blocks: BTreeMap<u8, Block>,
}

impl Log {
    pub fn new(groups: LogGroups) -> Self {
        let vars = log_toc(groups);
        let entries = vars.iter().map(|v| v.entry.clone()).collect();
        Log {
            vars,
            entries,
            blocks: BTreeMap::new(),
        }
    }

    pub fn entries(&self) -> &[TocEntry] {
        &self.entries
    }

    pub fn toc(&self, request: &[u8]) -> Option<Vec<u8>> {
        toc::answer(&self.entries, request, &[MAX_BLOCKS as u8, MAX_OPS as u8])
    }

    fn total_ops(&self) -> usize {
        self.blocks.values().map(|b| b.ops.len()).sum()
    }

    /// Parses `[type, id_lo, id_hi]*` after the block id.
    fn ops(&self, d: &[u8]) -> Result<Vec<(u16, u8)>, u8> {
        if !d.len().is_multiple_of(3) {
            return Err(EINVAL);
        }
        d.chunks(3)
            .map(|c| {
                let ty = c[0] & 0x0F;
                let id = u16_at(c, 1).expect("3 bytes");
                if type_size(ty).is_none() {
                    return Err(EINVAL);
                }
                if id as usize >= self.vars.len() {
                    return Err(ENOENT);
                }
                Ok((id, ty))
            })
            .collect()
    }

    /// A control request; the answer's data (always three bytes).
    pub fn control(&mut self, d: &[u8], now: Picos) -> Option<Vec<u8>> {
        let cmd = *d.first()?;
        let id = d.get(1).copied().unwrap_or(0);
        let err = match cmd {
            CMD_RESET => {
                self.blocks.clear();
                0
            }
            _ if d.len() < 2 => EINVAL,
            CMD_CREATE_BLOCK_V2 => {
                if self.blocks.contains_key(&id) {
                    EEXIST
                } else if self.blocks.len() >= MAX_BLOCKS {
                    ENOMEM
                } else {
                    match self.ops(&d[2..]) {
                        Ok(ops) => self.add(id, Vec::new(), ops),
                        Err(e) => e,
                    }
                }
            }
            CMD_APPEND_BLOCK_V2 => match self.blocks.get(&id) {
                None => ENOENT,
                Some(b) => match self.ops(&d[2..]) {
                    Ok(ops) => self.add(id, b.ops.clone(), ops),
                    Err(e) => e,
                },
            },
            CMD_DELETE_BLOCK => match self.blocks.remove(&id) {
                Some(_) => 0,
                None => ENOENT,
            },
            CMD_START => match (self.blocks.get_mut(&id), d.get(2)) {
                (None, _) => ENOENT,
                (Some(_), None) | (Some(_), Some(0)) => EINVAL,
                (Some(b), Some(&p)) => {
                    let period = Picos::from_ms(10 * u64::from(p));
                    b.period = Some(period);
                    b.next = now;
                    0
                }
            },
            CMD_STOP => match self.blocks.get_mut(&id) {
                Some(b) => {
                    b.period = None;
                    0
                }
                None => ENOENT,
            },
            // The v1 commands (0, 1) address 8-bit ids: a v2 client
            // (protocol version ≥ 4, which we announce) never sends them.
            _ => EINVAL,
        };
        Some(vec![cmd, id, err])
    }

    fn add(&mut self, id: u8, mut ops: Vec<(u16, u8)>, more: Vec<(u16, u8)>) -> u8 {
        let added = more.len();
        ops.extend(more);
        let block = Block {
            ops,
            period: self.blocks.get(&id).and_then(|b| b.period),
            next: self.blocks.get(&id).map_or(Picos::ZERO, |b| b.next),
        };
        if block.bytes() > MAX_BLOCK_BYTES {
            return E2BIG;
        }
        if self.total_ops() + added > MAX_OPS {
            return ENOMEM;
        }
        self.blocks.insert(id, block);
        0
    }

    /// The data packets due at `now`.
    pub fn due(&mut self, now: Picos, t: &Telemetry) -> Vec<Vec<u8>> {
        let ms = (now.0 / Picos::PER_MS) as u32;
        let mut out = Vec::new();
        for (&id, b) in self.blocks.iter_mut() {
            let Some(period) = b.period else { continue };
            if now < b.next {
                continue;
            }
            while b.next <= now {
                b.next += period;
            }
            let mut d = vec![id];
            d.extend_from_slice(&ms.to_le_bytes()[..3]);
            for &(var, ty) in &b.ops {
                encode(ty, (self.vars[var as usize].get)(t), &mut d);
            }
            out.push(d);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_created_started_sent_and_refused_as_the_firmware() {
        let mut log = Log::new(LogGroups::default());
        let x = toc::find(log.entries(), "stateEstimate.x").unwrap();
        let v = toc::find(log.entries(), "pm.vbat").unwrap();
        let [xl, xh] = x.to_le_bytes();
        let [vl, vh] = v.to_le_bytes();
        let now = Picos::from_ms(2000);
        assert_eq!(log.control(&[6, 1, 7, xl, xh], now), Some(vec![6, 1, 0]));
        assert_eq!(
            log.control(&[6, 1, 7, xl, xh], now),
            Some(vec![6, 1, EEXIST])
        );
        assert_eq!(log.control(&[7, 1, 7, vl, vh], now), Some(vec![7, 1, 0]));
        assert_eq!(
            log.control(&[6, 2, 7, 0xFF, 0x7F], now),
            Some(vec![6, 2, ENOENT])
        );
        assert_eq!(log.control(&[6, 2, 7, 0], now), Some(vec![6, 2, EINVAL]));
        assert_eq!(log.control(&[3, 9, 10], now), Some(vec![3, 9, ENOENT]));
        // Seven floats are 28 bytes: more than a packet holds.
        let big: Vec<u8> = [6u8, 7].into_iter().chain([7, xl, xh].repeat(7)).collect();
        assert_eq!(log.control(&big, now), Some(vec![6, 7, E2BIG]));
        assert_eq!(log.control(&[3, 1, 10], now), Some(vec![3, 1, 0]));
        let t = Telemetry {
            pos: [1.5, 0.0, 0.0],
            power: super::super::telemetry::PowerTelemetry {
                vbat: 4.0,
                ..Default::default()
            },
            ..Default::default()
        };
        let sent = log.due(now, &t);
        assert_eq!(sent.len(), 1);
        let d = &sent[0];
        assert_eq!(d[0], 1);
        assert_eq!(u32::from_le_bytes([d[1], d[2], d[3], 0]), 2000);
        assert_eq!(f32::from_le_bytes(d[4..8].try_into().unwrap()), 1.5);
        assert_eq!(f32::from_le_bytes(d[8..12].try_into().unwrap()), 4.0);
        // Not again before the 100 ms period is over.
        assert!(log.due(now + Picos::from_ms(99), &t).is_empty());
        assert_eq!(log.due(now + Picos::from_ms(100), &t).len(), 1);
        assert_eq!(log.control(&[4, 1], now), Some(vec![4, 1, 0]));
        assert!(log.due(now + Picos::from_ms(500), &t).is_empty());
        assert_eq!(log.control(&[5], now), Some(vec![5, 0, 0]));
        assert_eq!(log.control(&[2, 1], now), Some(vec![2, 1, ENOENT]));
        assert_eq!(log.control(&[], now), None);
    }
}
