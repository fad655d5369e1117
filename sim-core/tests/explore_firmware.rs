//! The exploration firmware of seed 004 (`firmware/src/explore/`,
//! docs/EXPLORE.md) runs on the ISS: `explore_selftest.elf` checks the
//! inverse sensor model, the frontier regions, the planner and the follower
//! on hand-made cases, measures cycles (mcycle), and flies whole
//! explorations of synthetic rooms inside the firmware. Here it runs to its
//! end; then its last map (the seed room explored at 5 cm, FOV 4°) is read
//! out of the core's memory in the CFOG export format and checked against
//! the room's true plan, written again in Rust. The cycle counts and the
//! RAM taken are reported (run with `--nocapture` to see them).

mod iss_util;

use std::sync::OnceLock;

use object::{Object, ObjectSection, ObjectSymbol};
use sim_core::iss::CodeCache;
use sim_core::iss::{CpuConfig, NoDevices, StopReason};
use sim_core::map_image::{MapError, MapImage};
use sim_core::units::Picos;

/// What one run of the self-test leaves behind.
struct SelfTest {
    code: i32,
    out: String,
    /// The bytes of the map image (`explore_map_image`, `explore_map_image_len` long).
    image: Vec<u8>,
    instret: u64,
}

/// Runs a firmware to its end: exit code, console, core, memory, ELF.
fn run_to_end(
    name: &str,
) -> (
    i32,
    String,
    sim_core::iss::Cpu,
    sim_core::iss::Memory,
    sim_core::iss::LoadedElf,
) {
    let (mut cpu, mut mem, elf, console) = iss_util::load(name, CpuConfig::default(), &[]);
    let mut code = CodeCache::new();
    // About 0.5 G (self-test) and 1 G (Table 6) instructions; the limit
    // turns a hang into a failure.
    cpu.set_instruction_limit(Some(4_000_000_000));
    let code = match cpu.run_until(&mut mem, &mut code, &mut NoDevices, Picos::MAX) {
        StopReason::Exit { code } => code,
        other => panic!("{name}: unexpected stop {other:?} at pc {:#x}", cpu.pc()),
    };
    (code, console.text(), cpu, mem, elf)
}

fn selftest() -> &'static SelfTest {
    static RUN: OnceLock<SelfTest> = OnceLock::new();
    RUN.get_or_init(|| {
        let (code, out, cpu, mem, elf) = run_to_end("explore_selftest");
        let base = elf
            .symbol("explore_map_image")
            .expect("symbol explore_map_image");
        let len_at = elf
            .symbol("explore_map_image_len")
            .expect("symbol explore_map_image_len");
        let len = mem.read_u32(len_at).expect("explore_map_image_len in RAM");
        let mut image = vec![0u8; len as usize];
        mem.read_bytes(base, &mut image)
            .expect("explore_map_image in RAM");
        SelfTest {
            code,
            out,
            image,
            instret: cpu.instret(),
        }
    })
}

// ---------------------------------------------------------------------------
// The seed room of the self-test (src/explore/test/sim.c): walls 100 mm
// thick around 6.5 x 2.5 m, a divider, a box and two table legs (mm).

const SEED_ROOM: [[i32; 4]; 8] = [
    [-100, -100, 6600, 0],
    [-100, 2500, 6600, 2600],
    [-100, 0, 0, 2500],
    [6500, 0, 6600, 2500],
    [4000, 0, 4100, 1500],
    [5000, 900, 5500, 1400],
    [4600, 2000, 4640, 2040],
    [6000, 500, 6040, 540],
];
const SEED_INTERIOR: [i32; 4] = [0, 0, 6500, 2500];

/// Coverage and accuracy as DESIGN.md §9 defines them, from the true plan.
#[derive(Debug, Default, PartialEq)]
struct Quality {
    truth_free: usize,
    observed: usize,
    mapped_free: usize,
    judged: usize,
    correct: usize,
}

fn assess(map: &MapImage) -> Quality {
    let mut q = Quality::default();
    let c = map.cell_mm;
    for iy in 0..map.height {
        for ix in 0..map.width {
            let x0 = map.origin_x_mm + ix as i32 * c;
            let y0 = map.origin_y_mm + iy as i32 * c;
            let (x1, y1) = (x0 + c, y0 + c);
            let (cx, cy) = (x0 as f64 + c as f64 / 2.0, y0 as f64 + c as f64 / 2.0);
            let [ix0, iy0, ix1, iy1] = SEED_INTERIOR;
            let in_room = x0 >= ix0 && x1 <= ix1 && y0 >= iy0 && y1 <= iy1;
            // A cell is truly free if its whole square is in the room and
            // touches no obstacle; truly occupied if its centre is inside one.
            let touches = SEED_ROOM
                .iter()
                .any(|r| x0 < r[2] && x1 > r[0] && y0 < r[3] && y1 > r[1]);
            let centre_in = SEED_ROOM.iter().any(|r| {
                cx >= r[0] as f64 && cx <= r[2] as f64 && cy >= r[1] as f64 && cy <= r[3] as f64
            });
            let l = map.log_odds(ix, iy);
            let free = in_room && !touches;
            if free {
                q.truth_free += 1;
                q.observed += (l != 0) as usize;
                q.mapped_free += (l < 0) as usize;
            }
            if l != 0 && (free || centre_in) {
                q.judged += 1;
                q.correct += if free { l < 0 } else { l > 0 } as usize;
            }
        }
    }
    q
}

/// The integers of a line, in order.
fn numbers(line: &str) -> Vec<u64> {
    line.split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect()
}

/// The first line of the self-test's output that starts with `prefix`.
fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line starting with {prefix:?} in:\n{out}"))
}

// ---------------------------------------------------------------------------

#[test]
fn selftest_passes_on_the_iss() {
    let st = selftest();
    assert!(
        st.out.contains("explore_selftest:") && st.out.contains(" 0 failures: PASS"),
        "{}",
        st.out
    );
    assert_eq!(st.code, 0, "{}", st.out);
    // The report: cycles, and the flights' coverage, goals and collisions.
    println!("explore_selftest: {} instructions", st.instret);
    for l in st
        .out
        .lines()
        .filter(|l| l.starts_with("cycles") || l.starts_with("flight") || l.starts_with("planner"))
    {
        println!("{l}");
    }
}

#[test]
fn every_flight_is_collision_free_and_ends() {
    let st = selftest();
    let flights: Vec<&str> = st.out.lines().filter(|l| l.starts_with("flight")).collect();
    assert_eq!(flights.len(), 6, "{}", st.out);
    for f in flights {
        assert!(f.contains(": done after "), "{f}");
        assert!(f.contains(", collisions 0,"), "{f}");
    }
}

#[test]
fn the_core_keeps_up_with_the_seeds_10_hz() {
    // At the platform's 250 MHz the seed's 100 ms period (§4.2.1.A: poses
    // and ranges logged every 100 ms) is 25 M cycles: a mapping update must
    // be a small part of it, a whole planning step on the full 8 x 8 m grid
    // at 5 cm must fit in it.
    const PERIOD_CYCLES: u64 = 25_000_000;
    let st = selftest();
    let maps: Vec<&str> = st
        .out
        .lines()
        .filter(|l| l.starts_with("cycles map:"))
        .collect();
    assert_eq!(maps.len(), 12, "{}", st.out);
    for l in maps {
        // "... ranges R mm: C per update, N cells per update"
        let n = numbers(l);
        let per_update = n[n.len() - 2];
        assert!(per_update < PERIOD_CYCLES / 20, "{l}");
    }
    let full = line(&st.out, "cycles plan: grid 160x160");
    let total = *numbers(full).last().unwrap();
    assert!(total < PERIOD_CYCLES, "{full}");
}

#[test]
fn the_map_image_reads_back_and_matches_the_room() {
    let st = selftest();
    let map = MapImage::parse(&st.image).expect("the firmware's map image");
    // The seed room's settings of sim.c: -200..6700 x -200..2700 mm at 50 mm.
    assert_eq!((map.width, map.height, map.cell_mm), (138, 58, 50));
    assert_eq!((map.origin_x_mm, map.origin_y_mm), (-200, -200));
    assert_eq!(map.fov_cdeg, 400);
    assert_eq!((map.lo_per_nat, map.l_min, map.l_max), (16, -32, 56));
    assert_eq!(st.image.len(), 32 + 138 * 58);

    // Coverage and accuracy from the true plan, in Rust, agree with the
    // firmware's own count.
    let q = assess(&map);
    // "map image: L bytes, observed X of Y free cells (Z mapped free), accuracy A of B"
    let fw = line(&st.out, "map image:");
    let n: Vec<usize> = numbers(fw).into_iter().map(|v| v as usize).collect();
    assert_eq!(n[0], st.image.len(), "{fw}");
    assert_eq!(
        (q.observed, q.truth_free, q.mapped_free, q.correct, q.judged),
        (n[1], n[2], n[3], n[4], n[5]),
        "{fw}"
    );
    // The exploration's goal: at least 90 % of the free space.
    assert!(
        q.observed * 100 >= 90 * q.truth_free,
        "coverage {} of {}",
        q.observed,
        q.truth_free
    );
    println!(
        "seed room map: coverage {:.1} %, accuracy {:.1} %, free cells mapped free {:.1} %",
        100.0 * q.observed as f64 / q.truth_free as f64,
        100.0 * q.correct as f64 / q.judged as f64,
        100.0 * q.mapped_free as f64 / q.truth_free as f64
    );

    // Spot checks through the reader: the take-off point is free, the
    // middle of the box occupied.
    let (tx, ty) = map.cell_of(500, 500);
    assert!(map.p_occupied(tx, ty).is_some_and(|p| p < 0.5));
    let (bx, by) = map.cell_of(5250, 1150);
    assert_eq!(
        map.p_occupied(bx, by),
        None,
        "the box's inside is never seen"
    );
    let (wx, wy) = map.cell_of(5250, 1425);
    let wall = (wy - 2..=wy + 2).filter_map(|y| map.p_occupied(wx, y));
    assert!(
        wall.clone().any(|p| p > 0.5),
        "the box's top face is seen occupied"
    );
}

#[test]
fn the_map_reader_refuses_bad_images() {
    let st = selftest();
    let good = &st.image;
    assert_eq!(
        MapImage::parse(&good[..20]),
        Err(MapError::Truncated {
            len: 20,
            need: 32,
            what: "header"
        })
    );
    assert!(matches!(
        MapImage::parse(&good[..good.len() - 1]),
        Err(MapError::Truncated { .. })
    ));
    let mut bad = good.clone();
    bad[0] = b'X';
    assert_eq!(MapImage::parse(&bad), Err(MapError::Magic(*b"XFOG")));
    let mut bad = good.clone();
    bad[4] = 2;
    assert_eq!(MapImage::parse(&bad), Err(MapError::Version(2)));
    let mut bad = good.clone();
    bad[100] ^= 1;
    let err = MapImage::parse(&bad).unwrap_err();
    assert!(matches!(err, MapError::Crc { .. }), "{err}");
    assert!(err.to_string().starts_with("map image: CRC-32"), "{err}");
}

/// Sizes of named symbols of the ELF.
fn symbol_sizes(elf: &object::File, names: &[&str]) -> Vec<u64> {
    names
        .iter()
        .map(|n| {
            elf.symbols()
                .find(|s| s.name() == Ok(n))
                .unwrap_or_else(|| panic!("no symbol {n}"))
                .size()
        })
        .collect()
}

#[test]
fn the_firmware_fits_the_gap8_data_region() {
    let bytes = std::fs::read(iss_util::firmware("explore_selftest")).unwrap();
    let elf = object::File::parse(&*bytes).unwrap();
    // gap8.ld: data, bss and a 16 KiB stack in the second 256 KiB of L2.
    let ram: u64 = elf
        .sections()
        .filter(|s| (0x1c04_0000..0x1c08_0000).contains(&s.address()))
        .map(|s| s.size())
        .sum();
    assert!(ram <= 256 * 1024, "{ram} bytes of RAM");
    // The algorithm's own static memory: the grid image, the planner's four
    // per-cell arrays, and the explorer's state.
    let names = [
        "explore_map_image",
        "pl_cost",
        "pl_flags",
        "pl_queue",
        "pl_aux",
        "explorer",
    ];
    let sizes = symbol_sizes(&elf, &names);
    let cells = 25_600u64; // EXPLORE_MAX_CELLS: 8 x 8 m at 5 cm
    assert_eq!(sizes[0], 32 + cells);
    assert_eq!(&sizes[1..5], &[2 * cells, cells, 2 * cells, 2 * cells]);
    let code: u64 = elf
        .sections()
        .filter(|s| s.address() >= 0x1c00_0000 && s.address() < 0x1c04_0000)
        .map(|s| s.size())
        .sum();
    println!(
        "RAM: {ram} bytes in all (data, bss, 16 KiB stack) of 256 KiB; the algorithm {} \
         ({}); code {code} bytes (with the self-test and picolibc)",
        sizes.iter().sum::<u64>(),
        names
            .iter()
            .zip(&sizes)
            .map(|(n, s)| format!("{n} {s}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

#[test]
fn table_6_round_flights() {
    // Seed §5.1, Table 6: the round flight at 2, 5, 8 cm and 2, 5, 10°.
    let (code, out, _, _, _) = run_to_end("explore_table6");
    assert!(
        out.contains("explore_table6:") && out.contains(" 0 failures: PASS"),
        "{out}"
    );
    assert_eq!(code, 0, "{out}");
    // 2 cm cells: the seed room does not fit the memory budget, and says so.
    let too_big: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("table6: cell 20 mm"))
        .collect();
    assert_eq!(too_big.len(), 3, "{out}");
    for l in &too_big {
        assert!(
            l.ends_with("grid 345 x 145 = 50025 cells exceeds the budget of 25600 cells (EXPLORE_MAX_CELLS)"),
            "{l}"
        );
    }
    let flights: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("flight table6"))
        .collect();
    assert_eq!(flights.len(), 6, "{out}");
    for l in out
        .lines()
        .filter(|l| l.starts_with("flight") || l.starts_with("cycles") || l.starts_with("table6"))
    {
        println!("{l}");
    }
}
