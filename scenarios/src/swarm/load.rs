//! Seed 003 §7.2 and §7.4 from a run of `swarm_node.elf`: the share of the
//! core's cycles spent in the ranging and estimation (the library's calls,
//! measured with mcycle by the firmware), the received / ideal packet
//! ratio per number of neighbours, and the RAM of the context from the ELF
//! (docs/SWARM_RESULTS.md).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use object::{Object, ObjectSymbol};

use super::console::SwarmConsole;

pub const LOAD_MD: &str = "load.md";

/// The seed's received / ideal ratios (§7.4, eqs. 7.1–7.3), for 1, 2, 3
/// neighbours as we read them (the seed labels its sections "two,
/// three, four neighbours"; its ideal rates 105, 210, 315/s are its
/// transmit rate times the number of the others).
pub const SEED_RATIO: [(u64, f64); 3] = [(1, 0.71), (2, 0.66), (3, 0.66)];
/// The seed's CPU load increase per added neighbour (§7.2.1: +9, +7, +9 %
/// over 35 % with none; the whole Crazyflie firmware on an STM32F405).
pub const SEED_LOAD: [(u64, f64); 4] = [(0, 0.35), (1, 0.44), (2, 0.51), (3, 0.60)];
/// The seed's context with 16 neighbours (Code Blocks 7.1–7.2: 88 560 −
/// 78 152 bytes) and its largest neighbour count (§7.2.2).
pub const SEED_RAM_BYTES: u64 = 10_408;
pub const SEED_MAX_NEIGHBOURS: u64 = 72;

/// Per number of neighbours: seconds counted and the sums.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadRow {
    pub neighbours: u64,
    pub seconds: u64,
    pub tx_per_s: f64,
    pub rx_per_s: f64,
    /// rx / (own tx × neighbours), the seed's definition.
    pub ratio_seed: f64,
    /// rx / (what the neighbours actually sent in that second): their
    /// lines of the same firmware second. Only for carried drones, whose
    /// firmware clocks start together; `None` in flight, where a flying
    /// core's clock runs ahead of the world's by its own amount
    /// (docs/SWARM_RESULTS.md §5) and the "same second" of two drones are
    /// different seconds of the world (in flight it once read 643 %).
    pub ratio_sent: Option<f64>,
    /// Share of the core's cycles in the library (ranging + estimation).
    pub swarm_share: f64,
    /// Share in the 100 Hz output (formatting + the console write).
    pub output_share: f64,
    /// Share awake (everything but wfi).
    pub busy_share: f64,
}

/// The observer's per-second lines grouped by its neighbour count (a
/// second whose count differs from the one before is a transition, left
/// out); the neighbours' transmissions from their own lines of the same
/// second, unless a drone flies (an estimate with `world_us=`).
pub fn load_rows(observer: &SwarmConsole, others: &[&SwarmConsole]) -> Vec<LoadRow> {
    let flying = std::iter::once(observer)
        .chain(others.iter().copied())
        .any(|c| c.estimates.iter().any(|e| e.world_us.is_some()));
    let sent_at = |t: u64| -> u64 {
        others
            .iter()
            .filter_map(|c| c.load.iter().find(|l| l.get("t") == Some(&t)))
            .map(|l| l.get("tx").copied().unwrap_or(0))
            .sum()
    };
    let mut groups: BTreeMap<u64, Vec<&BTreeMap<String, u64>>> = BTreeMap::new();
    let mut prev_n = None;
    for l in &observer.load {
        let n = l.get("n").copied().unwrap_or(0);
        if prev_n == Some(n) {
            groups.entry(n).or_default().push(l);
        }
        prev_n = Some(n);
    }
    groups
        .into_iter()
        .map(|(n, ls)| {
            let s = ls.len() as f64;
            let sum = |k: &str| {
                ls.iter()
                    .map(|l| l.get(k).copied().unwrap_or(0))
                    .sum::<u64>() as f64
            };
            let cycles = sum("second_cycles").max(1.0);
            let sent: u64 = ls
                .iter()
                .map(|l| sent_at(l.get("t").copied().unwrap_or(0)))
                .sum();
            LoadRow {
                neighbours: n,
                seconds: ls.len() as u64,
                tx_per_s: sum("tx") / s,
                rx_per_s: sum("rx") / s,
                ratio_seed: if n > 0 {
                    sum("rx") / (sum("tx") * n as f64).max(1.0)
                } else {
                    0.0
                },
                ratio_sent: (!flying).then(|| {
                    if sent > 0 {
                        sum("rx") / sent as f64
                    } else {
                        0.0
                    }
                }),
                swarm_share: sum("swarm_cycles") / cycles,
                output_share: sum("output_cycles") / cycles,
                busy_share: sum("busy_cycles") / cycles,
            }
        })
        .collect()
}

/// The context's size and the RAM left in an ELF: the `ctx` symbol and
/// the unused heap (`__bss_end` … `__stack` − `__stack_size`: what the
/// static data and the 16 KiB stack leave of the data half of L2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ram {
    pub ctx_bytes: u64,
    pub free_bytes: u64,
    /// The largest neighbour count whose context fits in ctx + free, from
    /// sizeof(swarm_t) ≈ 600 + 240·N + N(N+1) (docs/SWARM_FIRMWARE.md §5);
    /// at most 255 (8-bit identifiers, §6.2).
    pub max_neighbours: u64,
    pub max_neighbours_unbounded: u64,
}

pub fn ram(elf: &Path) -> Option<Ram> {
    let bytes = std::fs::read(elf).ok()?;
    let file = object::File::parse(&*bytes).ok()?;
    let sym = |name: &str| file.symbols().find(|s| s.name() == Ok(name));
    let ctx = sym("ctx")?.size();
    // The heap: from the end of .bss to the stack's bottom (gap8.ld: the
    // upper 256 KiB of L2 hold data, bss, heap and the stack).
    let heap_end = sym("__stack")?
        .address()
        .checked_sub(sym("__stack_size")?.address())?;
    let free = heap_end.checked_sub(sym("__bss_end")?.address())?;
    let size = |n: u64| 600 + 240 * n + n * (n + 1);
    let mut n = 0;
    while size(n + 1) <= ctx + free {
        n += 1;
    }
    Some(Ram {
        ctx_bytes: ctx,
        free_bytes: free,
        max_neighbours: n.min(255),
        max_neighbours_unbounded: n,
    })
}

pub fn load_markdown(observer: &str, rows: &[LoadRow], ram: Option<Ram>) -> String {
    let mut s = String::new();
    let pct = |v: f64| format!("{:.1} %", 100.0 * v);
    let seed = |table: &[(u64, f64)], n: u64| {
        table
            .iter()
            .find(|(k, _)| *k == n)
            .map_or("–".to_string(), |(_, v)| format!("{:.0} %", 100.0 * v))
    };
    let _ = writeln!(
        s,
        "### CPU and packets (seed 003 §7.2.1, §7.4), seen by {observer}\n\n\
         | neighbours | seconds | tx/s | rx/s | rx / (tx × n) | seed | rx / sent by the others | \
         core in ranging + estimation | output | awake | seed's whole-firmware load |\n\
         |---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {} | {} | {} | {} | {} | {} | {} |",
            r.neighbours,
            r.seconds,
            r.tx_per_s,
            r.rx_per_s,
            if r.neighbours > 0 {
                pct(r.ratio_seed)
            } else {
                "–".into()
            },
            seed(&SEED_RATIO, r.neighbours),
            match r.ratio_sent {
                Some(v) if r.neighbours > 0 => pct(v),
                _ => "–".into(),
            },
            pct(r.swarm_share),
            pct(r.output_share),
            pct(r.busy_share),
            seed(&SEED_LOAD, r.neighbours),
        );
    }
    if let Some(m) = ram {
        let _ = writeln!(
            s,
            "\n### RAM (seed 003 §7.2.2)\n\n\
             | | ours | seed |\n|---|---|---|\n\
             | context with 16 neighbours (bytes) | {} | {SEED_RAM_BYTES} |\n\
             | RAM left unused by the image (bytes) | {} | – |\n\
             | largest neighbour count that fits | {} (8-bit identifiers; {} without that limit) | {SEED_MAX_NEIGHBOURS} |",
            m.ctx_bytes, m.free_bytes, m.max_neighbours, m.max_neighbours_unbounded
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::swarm::console::parse;

    #[test]
    fn seconds_are_grouped_by_neighbours_without_transitions() {
        let a = parse(
            "swarm load t=1000 id=1 n=0 tx=50 rx=0 swarm_cycles=10 output_cycles=5 busy_cycles=20 second_cycles=100\n\
             swarm load t=2000 id=1 n=0 tx=50 rx=0 swarm_cycles=10 output_cycles=5 busy_cycles=20 second_cycles=100\n\
             swarm load t=3000 id=1 n=1 tx=80 rx=30 swarm_cycles=30 output_cycles=5 busy_cycles=40 second_cycles=100\n\
             swarm load t=4000 id=1 n=1 tx=100 rx=60 swarm_cycles=30 output_cycles=5 busy_cycles=40 second_cycles=100\n",
        );
        let b = parse("swarm load t=4000 id=2 n=1 tx=80 rx=60\n");
        let rows = load_rows(&a, &[&b]);
        assert_eq!(rows.len(), 2);
        assert_eq!((rows[0].neighbours, rows[0].seconds), (0, 1));
        assert_eq!((rows[1].neighbours, rows[1].seconds), (1, 1));
        assert!((rows[1].ratio_seed - 0.6).abs() < 1e-12);
        assert!((rows[1].ratio_sent.unwrap() - 0.75).abs() < 1e-12);
        assert!((rows[1].swarm_share - 0.3).abs() < 1e-12);
    }

    #[test]
    fn in_flight_the_sent_ratio_is_a_dash() {
        // A flying drone prints world_us=: the firmware seconds of two
        // drones are not the same world second.
        let a = parse(
            "swarm t=500 id=1 frame=built n=1 1=0,0,0,5,s world_us=2600000
             swarm load t=1000 id=1 n=1 tx=50 rx=40 swarm_cycles=10 output_cycles=5 busy_cycles=20 second_cycles=100
             swarm load t=2000 id=1 n=1 tx=50 rx=40 swarm_cycles=10 output_cycles=5 busy_cycles=20 second_cycles=100
",
        );
        let b = parse(
            "swarm load t=2000 id=2 n=1 tx=5 rx=60
",
        );
        let rows = load_rows(&a, &[&b]);
        assert_eq!(rows[0].ratio_sent, None);
        let md = load_markdown("a", &rows, None);
        let row = md.lines().find(|l| l.starts_with("| 1 |")).unwrap();
        // columns: n, seconds, tx/s, rx/s, rx/(tx n), seed, rx/sent
        assert_eq!(row.split('|').nth(7).unwrap().trim(), "–", "{row}");
    }
}
