//! Port 2, parameters (the firmware's `param.c`, cflib's `param.py`):
//! channel 0 the TOC ([`super::toc`]), channel 1 read `[id u16]` →
//! `[id u16, 0, value]` (an unknown id → `[id u16, ENOENT]`), channel 2
//! write `[id u16, value]` → `[id u16, value]` (the value the parameter
//! holds afterwards; an unknown id or a read-only parameter gets no answer,
//! as from the firmware). Channel 3 (misc: set by name, persistent storage,
//! extended types, defaults) is not served.
//!
//! Type bytes as `param.h`: bit 3 unsigned, bits 0..1 the size (0 = 1 byte,
//! 2 = 4 bytes), 0x06 float, bit 6 read-only.

use super::packet::u16_at;
use super::toc::{self, TocEntry};

pub const CHAN_TOC: u8 = 0;
pub const CHAN_READ: u8 = 1;
pub const CHAN_WRITE: u8 = 2;

pub const PARAM_UINT8: u8 = 0x08;
pub const PARAM_FLOAT: u8 = 0x06;
pub const PARAM_RONLY: u8 = 0x40;
const ENOENT: u8 = 2;

/// The firmware's `stabilizer.controller` value of the PID controller
/// (`controller.h`: ControllerTypePID = 1); the only one flown here.
pub const CONTROLLER_PID: f64 = 1.0;

/// The decks the world gives this drone.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Decks {
    pub flow2: bool,
    pub multiranger: bool,
    pub ai: bool,
}

/// Parameters the STM32 acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Known {
    FlowDeck,
    MultirangerDeck,
    AiDeck,
    EnHighLevel,
    ResetEstimation,
    Controller,
}

struct Param {
    entry: TocEntry,
    known: Known,
    value: f64,
}

pub struct Params {
    params: Vec<Param>,
    entries: Vec<TocEntry>,
    /// Writes of `kalman.resetEstimation` = 1 (counted: see `set`).
    pub resets: u64,
}

impl Params {
    pub fn new(decks: Decks) -> Self {
        let b = |v: bool| if v { 1.0 } else { 0.0 };
        let p = |ty: u8, group: &'static str, name: &'static str, known: Known, value: f64| Param {
            entry: TocEntry { ty, group, name },
            known,
            value,
        };
        let ro = PARAM_UINT8 | PARAM_RONLY;
        let params = vec![
            p(ro, "deck", "bcFlow2", Known::FlowDeck, b(decks.flow2)),
            p(ro, "deck", "bcMultiranger", Known::MultirangerDeck, b(decks.multiranger)),
            p(ro, "deck", "bcAI", Known::AiDeck, b(decks.ai)),
            p(PARAM_UINT8, "commander", "enHighLevel", Known::EnHighLevel, 1.0),
            p(PARAM_UINT8, "kalman", "resetEstimation", Known::ResetEstimation, 0.0),
            p(PARAM_UINT8, "stabilizer", "controller", Known::Controller, CONTROLLER_PID),
        ];
        let entries = params.iter().map(|p| p.entry.clone()).collect();
        Params {
            params,
            entries,
            resets: 0,
        }
    }

    pub fn entries(&self) -> &[TocEntry] {
        &self.entries
    }

    pub fn toc(&self, request: &[u8]) -> Option<Vec<u8>> {
        toc::answer(&self.entries, request, &[])
    }

    pub fn get(&self, k: Known) -> f64 {
        self.params
            .iter()
            .find(|p| p.known == k)
            .map_or(0.0, |p| p.value)
    }

    fn encode(p: &Param) -> Vec<u8> {
        if p.entry.ty & 0x0F == PARAM_FLOAT {
            (p.value as f32).to_le_bytes().to_vec()
        } else {
            vec![p.value as u8]
        }
    }

    pub fn read(&self, d: &[u8]) -> Option<Vec<u8>> {
        let id = u16_at(d, 0)?;
        let mut out = id.to_le_bytes().to_vec();
        match self.params.get(id as usize) {
            Some(p) => {
                out.push(0);
                out.extend(Self::encode(p));
            }
            None => out.push(ENOENT),
        }
        Some(out)
    }

    /// A write: the answer and the parameter written.
    pub fn write(&mut self, d: &[u8]) -> Option<(Vec<u8>, Known)> {
        let id = u16_at(d, 0)?;
        let p = self.params.get_mut(id as usize)?;
        if p.entry.ty & PARAM_RONLY != 0 {
            return None;
        }
        let raw = &d[2..];
        let v = if p.entry.ty & 0x0F == PARAM_FLOAT {
            super::packet::f32_at(raw, 0)?
        } else {
            f64::from(*raw.first()?)
        };
        p.value = match p.known {
            // One controller is flown (the Bitcraze PID of DESIGN.md §4):
            // the parameter keeps saying so, and the answer shows it.
            Known::Controller => CONTROLLER_PID,
            _ => v,
        };
        if p.known == Known::ResetEstimation && p.value != 0.0 {
            self.resets += 1;
        }
        let mut out = id.to_le_bytes().to_vec();
        out.extend(Self::encode(p));
        Some((out, p.known))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_writes_and_refusals_follow_param_c() {
        let mut p = Params::new(
            Decks {
                flow2: true,
                multiranger: true,
                ai: false,
            },
        );
        let flow = toc::find(p.entries(), "deck.bcFlow2").unwrap();
        let ai = toc::find(p.entries(), "deck.bcAI").unwrap();
        let hl = toc::find(p.entries(), "commander.enHighLevel").unwrap();
        let ctl = toc::find(p.entries(), "stabilizer.controller").unwrap();
        assert_eq!(p.read(&flow.to_le_bytes()), Some(vec![flow as u8, 0, 0, 1]));
        assert_eq!(p.read(&ai.to_le_bytes()), Some(vec![ai as u8, 0, 0, 0]));
        assert_eq!(p.read(&[200, 0]), Some(vec![200, 0, ENOENT]));
        assert_eq!(p.read(&[1]), None);
        // Read-only and unknown: no answer.
        assert_eq!(p.write(&[flow as u8, 0, 0]), None);
        assert_eq!(p.write(&[200, 0, 1]), None);
        let (ans, k) = p.write(&[hl as u8, 0, 0]).unwrap();
        assert_eq!((ans, k), (vec![hl as u8, 0, 0], Known::EnHighLevel));
        assert_eq!(p.get(Known::EnHighLevel), 0.0);
        let (ans, _) = p.write(&[ctl as u8, 0, 2]).unwrap();
        assert_eq!(ans, vec![ctl as u8, 0, 1]);
    }
}
