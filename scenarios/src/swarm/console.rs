//! The lines `swarm_node.elf` prints (docs/SWARM_FIRMWARE.md §4, seed 003's
//! positioning on the ISS), read back from a drone's `console.log`:
//!
//! - `swarm t=2501 id=1 frame=built n=2 1=1000,500,0,57,s 2=0,0,0,8,s …` —
//!   the 100 Hz estimates (mm in this drone's frame, σ in mm, state); a
//!   flying drone (`swarm_fly.elf`) ends it with `world_us=…`, the world
//!   time of the STM32's last sensor read (EST_TIME, docs/SWARM_RESULTS.md §5);
//! - `swarm frame t=… id=… built refs=2,3,1` — the frame's references
//!   (origin, +X, XY plane, +Z side) whenever they change;
//! - `swarm load t=… id=… n=… tx=… rx=… …` — one line per second;
//! - `swarm end id=… …` — the library's counters at the end.

use std::collections::BTreeMap;

/// One node's estimate in an estimates line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeEstimate {
    pub id: u32,
    /// Position in the observer's frame (m).
    pub pos: [f64; 3],
    /// Largest position standard deviation (m); `None` before its filter starts.
    pub sigma: Option<f64>,
    /// The filter is stable (used as an anchor, §6.8.3).
    pub stable: bool,
}

/// An estimates line.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimates {
    /// Firmware time (ms since its radio's INIT_DONE).
    pub t_ms: u64,
    /// World time (µs) of the STM32's last sensor read, when the firmware
    /// prints it (`world_us=`, flying drones only).
    pub world_us: Option<u64>,
    /// The observer's identifier.
    pub id: u32,
    /// The frame is built (§5.3.2).
    pub built: bool,
    /// The observer first, then each neighbour.
    pub nodes: Vec<NodeEstimate>,
}

/// A change of the observer's frame references.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRefs {
    pub t_ms: u64,
    pub built: bool,
    /// Identifiers, in the order origin, +X, XY plane, +Z.
    pub refs: Vec<u32>,
}

/// Everything a console holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SwarmConsole {
    pub estimates: Vec<Estimates>,
    pub frames: Vec<FrameRefs>,
    /// `swarm load` lines as key → value.
    pub load: Vec<BTreeMap<String, u64>>,
    /// The `swarm end` line.
    pub end: Option<BTreeMap<String, u64>>,
}

impl SwarmConsole {
    /// The references in force at firmware time `t_ms` (the last change at
    /// or before it), if the frame was built then.
    pub fn refs_at(&self, t_ms: u64) -> Option<&[u32]> {
        let i = self.frames.partition_point(|f| f.t_ms <= t_ms);
        let f = self.frames.get(i.checked_sub(1)?)?;
        f.built.then_some(f.refs.as_slice())
    }
}

fn key_values(words: &[&str]) -> BTreeMap<String, u64> {
    words
        .iter()
        .filter_map(|w| w.split_once('='))
        .filter_map(|(k, v)| Some((k.to_string(), v.parse().ok()?)))
        .collect()
}

fn node(word: &str) -> Option<NodeEstimate> {
    let (id, rest) = word.split_once('=')?;
    let f: Vec<&str> = rest.split(',').collect();
    if f.len() != 5 {
        return None;
    }
    let mm = |s: &str| s.parse::<i64>().ok().map(|v| v as f64 / 1000.0);
    let sigma = f[3].parse::<i64>().ok()?;
    Some(NodeEstimate {
        id: id.parse().ok()?,
        pos: [mm(f[0])?, mm(f[1])?, mm(f[2])?],
        sigma: (sigma >= 0).then(|| sigma as f64 / 1000.0),
        stable: f[4] == "s",
    })
}

fn estimates(words: &[&str]) -> Option<Estimates> {
    let kv = |k: &str| {
        words
            .iter()
            .find_map(|w| w.strip_prefix(k).and_then(|v| v.strip_prefix('=')))
    };
    let world_us = match kv("world_us") {
        Some(v) => Some(v.parse().ok()?),
        None => None,
    };
    let nodes = words
        .iter()
        .skip(5)
        .filter(|w| !w.starts_with("world_us="))
        .map(|w| node(w))
        .collect::<Option<Vec<_>>>()?;
    Some(Estimates {
        t_ms: kv("t")?.parse().ok()?,
        world_us,
        id: kv("id")?.parse().ok()?,
        built: kv("frame")? == "built",
        nodes,
    })
}

/// Reads the swarm lines of a console; other lines (and malformed ones)
/// are skipped.
pub fn parse(console: &str) -> SwarmConsole {
    let mut c = SwarmConsole::default();
    for line in console.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["swarm", "frame", rest @ ..] => {
                let kv = key_values(rest);
                let refs = rest
                    .iter()
                    .find_map(|w| w.strip_prefix("refs="))
                    .map(|r| r.split(',').filter_map(|v| v.parse().ok()).collect());
                if let (Some(&t_ms), Some(refs)) = (kv.get("t"), refs) {
                    c.frames.push(FrameRefs {
                        t_ms,
                        built: rest.contains(&"built"),
                        refs,
                    });
                }
            }
            ["swarm", "load", rest @ ..] => c.load.push(key_values(rest)),
            ["swarm", "end", rest @ ..] => c.end = Some(key_values(rest)),
            ["swarm", w, ..] if w.starts_with("t=") => {
                if let Some(e) = estimates(&words) {
                    c.estimates.push(e);
                }
            }
            _ => {}
        }
    }
    c
}

/// The identifier seed 003 §6.2 derives from a radio's EUI (its 8 bytes
/// xor-folded, `swarm_id_from_eui`): cosim's EUIs 1, 2, 3 give 1, 2, 3.
pub fn id_from_eui(eui: u64) -> u32 {
    eui.to_le_bytes().iter().fold(0u8, |a, b| a ^ b) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_every_kind_of_line() {
        let text = "hello\n\
            swarm frame t=10 id=1 building refs=2\n\
            swarm t=10 id=1 frame=building n=1 1=0,0,0,-1,- 2=0,0,0,10,u\n\
            swarm frame t=20 id=1 built refs=2,3,1\n\
            swarm t=20 id=1 frame=built n=2 1=1000,-500,0,57,s 2=0,0,0,8,s 3=990,0,0,12,s\n\
            swarm load t=1000 id=1 n=2 tx=100 rx=150 bad=0 swarm_cycles=5\n\
            swarm t=30 id=1 frame=built n=2 1=garbage\n\
            swarm end id=1 tx_built=5200\n";
        let c = parse(text);
        assert_eq!(c.estimates.len(), 2, "the malformed line is skipped");
        let e = &c.estimates[1];
        assert_eq!((e.t_ms, e.id, e.built), (20, 1, true));
        assert_eq!(e.nodes[0].pos, [1.0, -0.5, 0.0]);
        assert_eq!(e.nodes[0].sigma, Some(0.057));
        assert!(e.nodes[2].stable);
        assert_eq!(c.estimates[0].nodes[0].sigma, None);
        assert_eq!(c.refs_at(15), None, "building");
        assert_eq!(c.refs_at(25), Some(&[2, 3, 1][..]));
        assert_eq!(c.refs_at(5), None);
        assert_eq!(c.load[0]["rx"], 150);
        assert_eq!(c.end.as_ref().unwrap()["tx_built"], 5200);
        assert_eq!(e.world_us, None, "a carried drone's line");
    }

    #[test]
    fn a_flying_drones_line_carries_the_world_time() {
        let c = parse(
            "swarm t=1850 id=4 frame=built n=3 4=0,0,0,5,s 1=2000,0,0,9,s world_us=9004000\n\
             swarm t=1860 id=4 frame=built n=3 4=0,0,0,5,s world_us=x\n",
        );
        assert_eq!(c.estimates.len(), 1, "a malformed world time is skipped");
        let e = &c.estimates[0];
        assert_eq!((e.t_ms, e.world_us), (1850, Some(9_004_000)));
        assert_eq!(e.nodes.len(), 2);
        assert_eq!(e.nodes[1].pos, [2.0, 0.0, 0.0]);
    }

    #[test]
    fn identifiers_fold_the_eui() {
        assert_eq!(id_from_eui(1), 1);
        assert_eq!(id_from_eui(3), 3);
        assert_eq!(id_from_eui(0x0102), 3);
    }
}
