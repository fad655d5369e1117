//! Helpers of tests/tests/e2e/vision_detector.rs: the gate detector's test
//! program on the ISS, and the scenes, poses and expected answers.
#![allow(dead_code)]

use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use sim_core::iss::{load_elf, CodeCache, Cpu, CpuConfig, Memory, NoDevices, StopReason};
use sim_core::machine::run_elf::build_memory;
use sim_core::units::Picos;
use world_server::camera::Camera;
use world_server::scene::scene_boxes;
use world_server::world_file::{Finite, Point3};
use world_server::{StepConfig, World, WorldDesc};

/// Image size and focal length of the camera (DESIGN.md §5: 320 px across
/// a horizontal field of view of 0.87 rad).
pub const SIDE: usize = 320;
pub fn focal_px() -> f64 {
    160.0 / (0.87f64 / 2.0).tan()
}
/// Camera position in the body frame (DESIGN.md §5).
pub const CAMERA: [f64; 3] = [0.03, 0.0, 0.01];
/// The course's gates (scenarios/worlds/thesis-course.toml).
pub const INNER: f64 = 0.8;
pub const BAR: f64 = 0.06;
/// Core clock of the GAP8-like platform (DESIGN.md §4).
pub const CLOCK_HZ: f64 = 250e6;

/// `gate_result_t` flags (gate_detect.h).
pub const CUT_LEFT: u32 = 0x01;
pub const CUT_RIGHT: u32 = 0x02;
pub const CUT_TOP: u32 = 0x04;
pub const CUT_BOTTOM: u32 = 0x08;
pub const NO_SIZE: u32 = 0x10;

// ---------------------------------------------------------------- firmware

#[derive(Clone, Default)]
pub struct Console(Arc<Mutex<Vec<u8>>>);

impl Write for Console {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// What the firmware reports for one frame (`gate_result_t`).
#[derive(Debug, Clone, Copy)]
pub struct Detection {
    pub found: bool,
    pub flags: u32,
    pub candidates: i32,
    pub confidence: i32,
    /// Centre of the opening in the image (px, image coordinates).
    pub centre: [f64; 2],
    /// Apparent height and width of the opening (px).
    pub size: f64,
    pub width: f64,
    pub azimuth_mrad: i32,
    pub elevation_mrad: i32,
    /// Gate centre in the body frame (m).
    pub body: [f64; 3],
    pub range: f64,
    /// Detector cycles: all, and its stages (scan, components, openings).
    pub cycles: u32,
    pub stages: [u32; 3],
}

/// The test program on the ISS, stopped at its `ebreak`.
pub struct Firmware {
    cpu: Cpu,
    mem: Memory,
    code: CodeCache,
    console: Console,
    frame: u32,
    command: u32,
    result: u32,
    cycles: u32,
}

fn elf_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim-core/firmware/bin/gate_detect_test.elf")
}

impl Firmware {
    pub fn start() -> Firmware {
        let bytes =
            std::fs::read(elf_path()).expect("gate_detect_test.elf (make -C sim-core/firmware)");
        let elf = load_elf(&bytes).unwrap();
        let mut mem = build_memory(&[], elf.lowest_address()).unwrap();
        elf.load_into(&mut mem).unwrap();
        let mut cpu = Cpu::new(CpuConfig {
            ebreak_stops: true,
            ..CpuConfig::default()
        });
        cpu.set_pc(elf.entry);
        let console = Console::default();
        cpu.set_console(Box::new(console.clone()));
        let sym = |name: &str| elf.symbol(name).unwrap_or_else(|| panic!("symbol {name}"));
        let mut fw = Firmware {
            cpu,
            mem,
            code: CodeCache::new(),
            console,
            frame: sym("vision_frame"),
            command: sym("vision_command"),
            result: sym("vision_result"),
            cycles: sym("vision_cycles"),
        };
        fw.run_to_stop();
        fw
    }

    /// Runs to the next `ebreak`; returns the exit code instead if the
    /// program ends.
    fn run_to_stop(&mut self) -> Option<i32> {
        self.cpu
            .set_instruction_limit(Some(self.cpu.instret() + 50_000_000));
        match self
            .cpu
            .run_until(&mut self.mem, &mut self.code, &mut NoDevices, Picos::MAX)
        {
            StopReason::Breakpoint { .. } => None,
            StopReason::Exit { code } => Some(code),
            other => panic!(
                "gate_detect_test: unexpected stop {other:?} at pc {:#x}\n{}",
                self.cpu.pc(),
                self.console_text()
            ),
        }
    }

    fn resume(&mut self, command: u32) -> Option<i32> {
        self.mem
            .write_bytes(self.command, &command.to_le_bytes())
            .unwrap();
        // Past the 4-byte ebreak.
        let pc = self.cpu.pc();
        self.cpu.set_pc(pc + 4);
        self.run_to_stop()
    }

    pub fn detect(&mut self, frame: &[u8]) -> Detection {
        assert_eq!(frame.len(), SIDE * SIDE);
        self.mem.write_bytes(self.frame, frame).unwrap();
        assert_eq!(self.resume(1), None, "{}", self.console_text());
        let mut raw = [0u8; 24 * 4];
        self.mem.read_bytes(self.result, &mut raw).unwrap();
        let f = |i: usize| i32::from_le_bytes(raw[4 * i..4 * i + 4].try_into().unwrap());
        let q8 = |i: usize| f(i) as f64 / 256.0;
        let mm = |i: usize| f(i) as f64 / 1000.0;
        Detection {
            found: f(0) != 0,
            flags: f(1) as u32,
            candidates: f(2),
            confidence: f(3),
            centre: [q8(4), q8(5)],
            size: q8(6),
            width: q8(7),
            azimuth_mrad: f(12),
            elevation_mrad: f(13),
            body: [mm(17), mm(18), mm(19)],
            range: mm(20),
            cycles: self.mem.read_u32(self.cycles).unwrap(),
            stages: [f(21) as u32, f(22) as u32, f(23) as u32],
        }
    }

    pub fn finish(mut self) -> String {
        assert_eq!(self.resume(0), Some(0), "{}", self.console_text());
        self.console_text()
    }

    pub fn console_text(&self) -> String {
        String::from_utf8_lossy(&self.console.0.lock().unwrap()).into_owned()
    }
}

// ---------------------------------------------------------------- scenes

/// A gate of the course's kind at `centre`, its direction of travel `yaw`
/// (rad from world +x).
#[derive(Debug, Clone, Copy)]
pub struct Gate {
    pub centre: [f64; 3],
    pub yaw: f64,
}

/// A world of the thesis course's ground, sky and gate style with these
/// gates and extra TOML (boxes).
pub fn world(gates: &[Gate], extra: &str) -> WorldDesc {
    let mut toml = String::from(
        "name = \"vision\"\n[start]\nposition = [0.0, 0.0, 0.015]\n\
         [ground]\ntile = 0.5\ngrey_dark = 90\ngrey_light = 140\n[sky]\ngrey = 200\n",
    );
    for g in gates {
        let [x, y, z] = g.centre;
        writeln!(
            toml,
            "[[gate]]\ncentre = [{x}, {y}, {z}]\nyaw = {}\ninner = {INNER}\nbar = {BAR}\ngrey = 170",
            g.yaw
        )
        .unwrap();
    }
    toml.push_str(extra);
    WorldDesc::parse(&toml, Path::new("vision.toml")).unwrap()
}

/// A level drone: body origin (world, m) and heading (rad from world +x).
#[derive(Debug, Clone, Copy)]
pub struct Pose {
    pub at: [f64; 3],
    pub heading: f64,
}

impl Pose {
    /// A world point in the body frame (x forward, y left, z up).
    pub fn to_body(self, p: [f64; 3]) -> [f64; 3] {
        let (s, c) = self.heading.sin_cos();
        let d = [p[0] - self.at[0], p[1] - self.at[1], p[2] - self.at[2]];
        [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]]
    }
}

/// The frame the drone at `pose` sees. The world file's start pose is set
/// to it (and the first drone's) and `World` builds the body's rotation from it (the scene is
/// static: no physics step runs).
pub fn render(desc: &WorldDesc, pose: Pose) -> Vec<u8> {
    let mut desc = desc.clone();
    desc.start.position = Point3(pose.at);
    desc.start.yaw = Finite(pose.heading);
    // The world flies `drones` (the course's one drone starts at `[start]`).
    desc.drones[0].start = desc.start.clone();
    let world = World::new(&desc, StepConfig::default()).unwrap();
    let boxes = scene_boxes(&desc);
    let mut camera = Camera::new(&desc, &boxes);
    let frame = camera.render(world.position(0), world.rotation(0)).to_vec();
    if let Some(dir) = std::env::var_os("VISION_PNG_DIR") {
        let [x, y, z] = pose.at;
        let name = format!("{x:.3}_{y:.3}_{z:.3}_{:.3}.png", pose.heading);
        world_server::camera::write_png(&Path::new(&dir).join(name), SIDE, SIDE, &frame).unwrap();
    }
    frame
}

/// The pixel of a body-frame point (pinhole of DESIGN.md §5).
pub fn project(b: [f64; 3]) -> [f64; 2] {
    let cam = [b[0] - CAMERA[0], b[1] - CAMERA[1], b[2] - CAMERA[2]];
    let f = focal_px();
    [160.0 - f * cam[1] / cam[0], 160.0 - f * cam[2] / cam[0]]
}

/// The gate centre as the drone at `pose` should see it: body-frame
/// position (m) and image position (px).
pub fn truth(gate: [f64; 3], pose: Pose) -> ([f64; 3], [f64; 2]) {
    let b = pose.to_body(gate);
    (b, project(b))
}

/// Image bounding box (x0, y0, x1, y1) of the square of half side `half`
/// (m) in the front face of gate `g`, seen from `pose`.
pub fn projected_box(g: Gate, half: f64, pose: Pose) -> [f64; 4] {
    let (sin, cos) = g.yaw.sin_cos();
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for (sa, sz) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        // Across the opening (-sin, cos, 0), up, and half a bar back along
        // the direction of travel (cos, sin, 0), towards a drone that comes
        // through it the right way.
        let p = [
            g.centre[0] - sin * sa * half - cos * BAR / 2.0,
            g.centre[1] + cos * sa * half - sin * BAR / 2.0,
            g.centre[2] + sz * half,
        ];
        let [x, y] = project(pose.to_body(p));
        b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
    }
    b
}

/// Errors allowed for a gate at `g` seen from `pose` when each edge of the
/// opening is known to within `edge_px` (1 px when seen: a centre is a mean
/// of two edges, ±0.5 px, a height their difference, ±1 px).
#[derive(Debug, Clone, Copy)]
pub struct Bounds {
    pub px: f64,
    pub m: [f64; 3],
}

pub fn bounds(g: Gate, pose: Pose, edge_px: f64) -> Bounds {
    let f = focal_px();
    let (b, px) = truth(g.centre, pose);
    let depth = b[0] - CAMERA[0];
    let front = depth - BAR / 2.0;
    let (sin, cos) = (g.yaw - pose.heading).sin_cos();
    // Depth from height: dZ = Z² / (f s) per pixel of height, plus the
    // millimetre rounding, plus the half bar by which the front face (where
    // the top and bottom edges are seen) lies before the centre along the
    // gate's normal, of which the detector corrects the part along the axis.
    let x = front * front / (f * INNER) * edge_px + 0.005 + BAR / 2.0 * (1.0 - cos.abs());
    // Side and height: the centre pixel's error at that depth, the depth
    // error's share through the bearing, and the half bar across the axis
    // for an oblique gate.
    let lat = b[1].abs();
    let vert = (b[2] - CAMERA[2]).abs();
    let y = edge_px * depth / f + lat / depth * x + BAR / 2.0 * sin.abs();
    let z = edge_px * depth / f + vert / depth * x;
    // In the image: the opening seen is the front face's, whose projection
    // is displaced from the centre's by the bars' half depth.
    let off = (px[0] - 160.0).abs().max((px[1] - 160.0).abs());
    let px = edge_px + off * BAR / (2.0 * depth) + BAR / 2.0 * sin.abs() * f / depth;
    Bounds { px, m: [x, y, z] }
}

/// One pose and what the detector reported, against the truth.
pub struct Outcome {
    pub name: String,
    pub det: Detection,
    pub want_body: [f64; 3],
    pub want_px: [f64; 2],
    pub bounds: Bounds,
}

impl Outcome {
    pub fn centre_err_px(&self) -> f64 {
        (self.det.centre[0] - self.want_px[0]).hypot(self.det.centre[1] - self.want_px[1])
    }

    pub fn err_m(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.det.body[i] - self.want_body[i])
    }

    pub fn within_bounds(&self) -> bool {
        let e = self.err_m();
        self.centre_err_px() <= self.bounds.px && (0..3).all(|i| e[i].abs() <= self.bounds.m[i])
    }

    pub fn row(&self) -> String {
        let d = &self.det;
        let e = self.err_m();
        let b = self.bounds;
        format!(
            "| {:<30} | {:<3} | {:#04x} | {:>3} | {:>6.1} {:>6.1} | {:>4.2} ({:.1}) | {:>5.1} | {:>+6.3} {:>+6.3} {:>+6.3} ({:.3} {:.3} {:.3}) | {:>4} {:>4} | {:>4.2} |",
            self.name,
            if d.found { "yes" } else { "no" },
            d.flags,
            d.confidence,
            d.centre[0],
            d.centre[1],
            self.centre_err_px(),
            b.px,
            d.size,
            e[0],
            e[1],
            e[2],
            b.m[0],
            b.m[1],
            b.m[2],
            d.azimuth_mrad,
            d.elevation_mrad,
            d.cycles as f64 / CLOCK_HZ * 1e3,
        )
    }
}

pub const HEADER: &str = "| pose | found | flags | conf | centre (px) | error px (bound) | size px | error x y z, m (bounds) | az el mrad | ms |";

/// Runs the detector on the frame of `desc` seen from `pose`, expecting
/// gate `want`.
pub fn look_at(
    fw: &mut Firmware,
    name: &str,
    desc: &WorldDesc,
    want: Gate,
    pose: Pose,
    edge_px: f64,
) -> Outcome {
    let det = fw.detect(&render(desc, pose));
    let (want_body, want_px) = truth(want.centre, pose);
    Outcome {
        name: name.into(),
        det,
        want_body,
        want_px,
        bounds: bounds(want, pose, edge_px),
    }
}

pub fn print_table(title: &str, rows: &[Outcome]) {
    println!("\n{title}\n{HEADER}");
    for o in rows {
        println!("{}", o.row());
    }
}
