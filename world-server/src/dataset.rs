//! Labelled camera images for training and testing a gate-finding network
//! (DESIGN.md §13): `cosim dataset WORLD --count N --seed S --out DIR`.
//!
//! Every image is rendered by [`Camera`], the in-loop camera itself, in a
//! copy of the world whose gates are displaced and turned within bounds and
//! whose greys are jittered, from a random pose in the course's volume.
//! Nothing depends on the wall clock or on the machine: one ChaCha8 stream
//! seeded with S draws everything, image after image, so the same world, N
//! and S give the same bytes.
//!
//! Output (in DIR): `img_NNNNNN.pgm` (binary PGM, `P5 320 320 255`, row-major,
//! top row first: 15 header bytes then 102,400 pixels), `labels.csv` (below),
//! `gates.csv` (every gate in front of the camera, [`GateView`]) and
//! `dataset.json` (the parameters).
//!
//! Labels (`file, gate_visible, u, v, distance_m, corners`): the nearest
//! *visible* gate, where visible means (all four):
//! * its opening's centre is in front of the camera, at most
//!   [`MAX_RANGE_M`] from the optical centre, and projects inside the image;
//! * the opening faces the camera: the ray to the centre is at most
//!   [`MAX_OBLIQUITY_RAD`] off the gate's normal (edge-on, there is no opening
//!   to see);
//! * nothing nearer covers the centre: the rendered depth at the centre's
//!   pixel is not nearer than the centre (the opening is empty, so an
//!   unoccluded centre pixel shows what lies behind the gate).
//!
//! `u, v` are the centre's projection in pixels (from the top-left corner of
//! the image, the renderer's convention), `distance_m` the distance from the
//! optical centre, `corners` the four inner corners of the opening as
//! `u0 v0 u1 v1 u2 v2 u3 v3`: top-left, top-right, bottom-right, bottom-left
//! as seen from the camera (they may lie outside the image). Without a
//! visible gate, `gate_visible` is 0 and the other fields are empty.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::glamx::{DQuat, DVec3, EulerRot};
use serde::Serialize;

use crate::camera::Camera;
use crate::crazyflie::{CAMERA_HEIGHT, CAMERA_WIDTH};
use crate::scene::{scene_boxes, SceneBox};
use crate::world_file::{Finite, Point3, WorldDesc};

/// Gates farther than this are not labelled: at 8 m the 0.8 m opening of
/// the thesis course spans 34 px of 320 (8 px in an 80×80 network input).
pub const MAX_RANGE_M: f64 = 8.0;
/// A gate seen more than 70° off its normal shows an opening at most
/// cos 70° = 34 % as wide as it is high: not labelled.
pub const MAX_OBLIQUITY_RAD: f64 = 70.0 * std::f64::consts::PI / 180.0;
/// Relative tolerance of the occlusion test (the gate's own bars, seen
/// obliquely, lie a few cm off the centre's depth).
const OCCLUSION_TOLERANCE: f64 = 0.02;

/// How the scene and the poses are drawn; every bound is a uniform draw.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetSpec {
    pub count: usize,
    pub seed: u64,
    /// Each gate moves along its opening's horizontal axis and along its
    /// normal by up to this (m), vertically by up to half of it (the frame's
    /// bottom bar kept 0.1 m above the ground, as `cosim world perturb`).
    pub gate_offset_m: f64,
    /// Each gate turns about the vertical by up to this (rad).
    pub gate_turn_rad: f64,
    /// Gate, ground and sky greys move by up to this many levels.
    pub grey_jitter: u8,
    /// Share of images aimed at a gate (the rest look anywhere).
    pub aimed_share: f64,
    /// Roll and pitch of the drone, up to (rad): a racing drone tilts.
    pub tilt_rad: f64,
}

impl DatasetSpec {
    /// The bounds used for the committed network (docs/NN.md): ±0.3 m,
    /// ±0.35 rad (20°), ±20 grey levels, 75 % aimed, ±0.2 rad of tilt.
    pub fn new(count: usize, seed: u64) -> DatasetSpec {
        DatasetSpec {
            count,
            seed,
            gate_offset_m: 0.3,
            gate_turn_rad: 0.35,
            grey_jitter: 20,
            aimed_share: 0.75,
            tilt_rad: 0.2,
        }
    }
}

/// The label of one image.
#[derive(Debug, Clone, PartialEq)]
pub struct Label {
    pub file: String,
    pub gate: Option<GateLabel>,
}

/// The nearest visible gate of an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateLabel {
    /// Index of the gate in the world file.
    pub index: usize,
    pub u: f64,
    pub v: f64,
    pub distance_m: f64,
    /// (u, v) of the inner corners: top-left, top-right, bottom-right, bottom-left.
    pub corners: [(f64, f64); 4],
}

/// Why a dataset cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error("--count must be at least 1")]
    NoImages,
    #[error("the world has no [[gate]] to look at")]
    NoGates,
    /// The cause is in the message, and so not also a `source()` (a chain
    /// printer would repeat it).
    #[error("{path}: {cause}")]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("no free pose found for image {0} (the course is full of boxes?)")]
    NoPose(usize),
    #[error(transparent)]
    World(#[from] crate::world_file::WorldFileError),
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |cause| DatasetError::Io {
        path: path.to_path_buf(),
        cause,
    }
}

/// One drawn scene: the world with moved gates, and the drone's pose.
struct Sample {
    world: WorldDesc,
    /// The varied world's boxes (drawn once: the pose's clearance test
    /// and the renderer both need them).
    boxes: Vec<SceneBox>,
    position: DVec3,
    rotation: DQuat,
}

/// Renders and labels `spec.count` images of `world` into `out` (created if
/// missing); returns the labels. Each image is written whole before its
/// label row; on an error the rows so far are flushed (the writer's drop),
/// so the files written stay valid and consistent.
pub fn write_dataset(
    world: &WorldDesc,
    spec: &DatasetSpec,
    out: &Path,
) -> Result<Vec<Label>, DatasetError> {
    if spec.count == 0 {
        return Err(DatasetError::NoImages);
    }
    if world.gates.is_empty() {
        return Err(DatasetError::NoGates);
    }
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let meta_path = out.join("dataset.json");
    let meta = serde_json::json!({
        "world": world.name,
        "spec": spec,
        "image": {"format": "pgm", "width": CAMERA_WIDTH, "height": CAMERA_HEIGHT},
        "max_range_m": MAX_RANGE_M,
        "max_obliquity_rad": MAX_OBLIQUITY_RAD,
    });
    std::fs::write(&meta_path, format!("{meta:#}\n")).map_err(io_err(&meta_path))?;
    let csv_path = out.join("labels.csv");
    let mut rows =
        std::io::BufWriter::new(std::fs::File::create(&csv_path).map_err(io_err(&csv_path))?);
    writeln!(rows, "file,gate_visible,u,v,distance_m,corners").map_err(io_err(&csv_path))?;
    let gates_path = out.join("gates.csv");
    let mut gate_rows =
        std::io::BufWriter::new(std::fs::File::create(&gates_path).map_err(io_err(&gates_path))?);
    writeln!(gate_rows, "{GATES_CSV_HEADER}").map_err(io_err(&gates_path))?;
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut labels = Vec::with_capacity(spec.count);
    let mut pgm = Vec::with_capacity(16 + CAMERA_WIDTH * CAMERA_HEIGHT);
    for i in 0..spec.count {
        let s = draw_sample(world, spec, &mut rng).ok_or(DatasetError::NoPose(i))?;
        let mut camera = Camera::new(&s.world, &s.boxes);
        camera.render(s.position, s.rotation);
        let file = format!("img_{i:06}.pgm");
        pgm.clear();
        write!(pgm, "P5\n{} {}\n255\n", camera.width(), camera.height()).expect("to a Vec");
        pgm.extend_from_slice(camera.image());
        let path = out.join(&file);
        std::fs::write(&path, &pgm).map_err(io_err(&path))?;
        let gates = gates_in_view(&camera, &s.world, s.position, s.rotation);
        for g in &gates {
            writeln!(gate_rows, "{}", gates_csv_row(&file, g)).map_err(io_err(&gates_path))?;
        }
        let label = Label {
            gate: nearest_visible(&gates),
            file,
        };
        writeln!(rows, "{}", csv_row(&label)).map_err(io_err(&csv_path))?;
        labels.push(label);
    }
    rows.flush().map_err(io_err(&csv_path))?;
    gate_rows.flush().map_err(io_err(&gates_path))?;
    Ok(labels)
}

/// `dataset WORLD --count N --seed S --out DIR`, the command of both
/// `cosim` and `world-server`: loads the world file, writes the dataset and
/// returns the line to print (the count, the images with a gate, the rate
/// in wall time).
pub fn dataset_command(
    world: &Path,
    count: usize,
    seed: u64,
    out: &Path,
) -> Result<String, DatasetError> {
    let desc = WorldDesc::load(world)?;
    let start = std::time::Instant::now();
    let labels = write_dataset(&desc, &DatasetSpec::new(count, seed), out)?;
    let secs = start.elapsed().as_secs_f64();
    let visible = labels.iter().filter(|l| l.gate.is_some()).count();
    Ok(format!(
        "{count} images ({visible} with a gate) -> {} in {secs:.1} s ({:.0} images/min)",
        out.display(),
        count as f64 / secs.max(1e-9) * 60.0
    ))
}

/// One `labels.csv` row (no newline). Pixels with 3 decimals, metres with 4.
pub fn csv_row(l: &Label) -> String {
    match &l.gate {
        None => format!("{},0,,,,", l.file),
        Some(g) => format!(
            "{},1,{:.3},{:.3},{:.4},{}",
            l.file,
            g.u,
            g.v,
            g.distance_m,
            corners_field(&g.corners)
        ),
    }
}

/// A gate in front of the camera, as `gates.csv` lists it: every gate whose
/// opening's centre is in front of the camera and, when it projects inside
/// the image, not covered by something nearer (outside the image the
/// renderer's depth cannot tell, so those are listed). `visible` is the
/// module's strict verdict (the labels' rules); the rest lets a trainer
/// see the gates near the rules' lines (the range, the image's edge, the
/// angle off the normal), which a strict yes/no labels arbitrarily.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateView {
    /// Index of the gate in the world file.
    pub index: usize,
    pub u: f64,
    pub v: f64,
    pub distance_m: f64,
    /// The angle between the ray to the centre and the gate's normal (either
    /// side), 0 to 90°.
    pub off_normal_rad: f64,
    /// The centre projects inside the image.
    pub in_image: bool,
    /// The inner corners (as [`GateLabel::corners`]); `None` when one lies
    /// behind the camera (the gate is too close to label its corners).
    pub corners: Option<[(f64, f64); 4]>,
    /// Visible by the module's rules (the labels' verdict).
    pub visible: bool,
}

/// Every gate in front of the camera that is not occluded (see [`GateView`]),
/// in the world file's order, for the image just rendered by `camera`.
pub fn gates_in_view(
    camera: &Camera,
    world: &WorldDesc,
    position: DVec3,
    rotation: DQuat,
) -> Vec<GateView> {
    let eye = Camera::eye(position, rotation);
    let (w, h) = (camera.width(), camera.height());
    let right = rotation * -DVec3::Y;
    let mut out = Vec::new();
    for (index, g) in world.gates.iter().enumerate() {
        let c = DVec3::from_array(g.centre.0);
        let distance_m = (c - eye).length();
        let Some((u, v, depth)) = camera.project(position, rotation, c) else {
            continue;
        };
        let in_image = (0.0..w as f64).contains(&u) && (0.0..h as f64).contains(&v);
        if in_image {
            let pixel = (v as usize) * w + u as usize;
            let seen = camera.inv_depth()[pixel] as f64;
            if seen > (1.0 + OCCLUSION_TOLERANCE) / depth {
                continue;
            }
        }
        let (sin, cos) = g.yaw.0.sin_cos();
        let normal = DVec3::new(cos, sin, 0.0);
        let facing = ((c - eye).normalize().dot(normal)).abs();
        // The opening's horizontal axis, pointing to the image's right.
        let mut across = DVec3::new(-sin, cos, 0.0);
        if across.dot(right) < 0.0 {
            across = -across;
        }
        let half = g.inner.0 / 2.0;
        let corner = |a: f64, z: f64| {
            camera
                .project(
                    position,
                    rotation,
                    c + across * (a * half) + DVec3::Z * (z * half),
                )
                .map(|(u, v, _)| (u, v))
        };
        let corners = match (
            corner(-1.0, 1.0),
            corner(1.0, 1.0),
            corner(1.0, -1.0),
            corner(-1.0, -1.0),
        ) {
            (Some(c0), Some(c1), Some(c2), Some(c3)) => Some([c0, c1, c2, c3]),
            _ => None,
        };
        out.push(GateView {
            index,
            u,
            v,
            distance_m,
            off_normal_rad: facing.min(1.0).acos(),
            in_image,
            corners,
            visible: distance_m <= MAX_RANGE_M
                && in_image
                && facing >= MAX_OBLIQUITY_RAD.cos()
                && corners.is_some(),
        });
    }
    out
}

/// The nearest of the visible gates `gates_in_view` found (the first in
/// the world file's order on a tie): the image's label.
pub fn nearest_visible(gates: &[GateView]) -> Option<GateLabel> {
    let mut best: Option<&GateView> = None;
    for g in gates.iter().filter(|g| g.visible) {
        if best.is_none_or(|b| g.distance_m < b.distance_m) {
            best = Some(g);
        }
    }
    best.map(|g| GateLabel {
        index: g.index,
        u: g.u,
        v: g.v,
        distance_m: g.distance_m,
        corners: g.corners.expect("a visible gate has its corners"),
    })
}

/// The nearest gate that is visible in the image just rendered by `camera`
/// (the module's rules).
pub fn nearest_visible_gate(
    camera: &Camera,
    world: &WorldDesc,
    position: DVec3,
    rotation: DQuat,
) -> Option<GateLabel> {
    nearest_visible(&gates_in_view(camera, world, position, rotation))
}

/// `u0 v0 u1 v1 u2 v2 u3 v3` with 3 decimals.
fn corners_field(corners: &[(f64, f64); 4]) -> String {
    let mut s = String::new();
    for (k, (u, v)) in corners.iter().enumerate() {
        let sep = if k == 0 { "" } else { " " };
        write!(s, "{sep}{u:.3} {v:.3}").expect("to a String");
    }
    s
}

/// `gates.csv`'s header.
pub const GATES_CSV_HEADER: &str =
    "file,gate,u,v,distance_m,off_normal_deg,in_image,visible,corners";

/// One `gates.csv` row (no newline): pixels with 3 decimals, metres with 4
/// (as `labels.csv`), the angle in degrees with 3; `corners` empty when one
/// lies behind the camera.
pub fn gates_csv_row(file: &str, g: &GateView) -> String {
    format!(
        "{file},{},{:.3},{:.3},{:.4},{:.3},{},{},{}",
        g.index,
        g.u,
        g.v,
        g.distance_m,
        g.off_normal_rad.to_degrees(),
        u8::from(g.in_image),
        u8::from(g.visible),
        g.corners.as_ref().map(corners_field).unwrap_or_default()
    )
}

/// Draws one scene and pose; `None` if no free pose was found in 1000 tries.
fn draw_sample(world: &WorldDesc, spec: &DatasetSpec, rng: &mut ChaCha8Rng) -> Option<Sample> {
    let mut w = world.clone();
    let jitter = |rng: &mut ChaCha8Rng, grey: u8| {
        let j = spec.grey_jitter as i32;
        (grey as i32 + rng.random_range(-j..=j)).clamp(0, 255) as u8
    };
    for g in &mut w.gates {
        let (sin, cos) = g.yaw.0.sin_cos();
        let (along, across) = (DVec3::new(cos, sin, 0.0), DVec3::new(-sin, cos, 0.0));
        let d = spec.gate_offset_m;
        let mut c = DVec3::from_array(g.centre.0)
            + across * rng.random_range(-d..=d)
            + along * rng.random_range(-d..=d);
        let lowest = 0.1 + g.inner.0 / 2.0 + g.bar.0;
        c.z = (c.z + rng.random_range(-d / 2.0..=d / 2.0)).max(lowest);
        g.centre = Point3(c.to_array());
        g.yaw = Finite(g.yaw.0 + rng.random_range(-spec.gate_turn_rad..=spec.gate_turn_rad));
        g.grey = jitter(rng, g.grey);
    }
    w.ground.grey_dark = jitter(rng, w.ground.grey_dark);
    w.ground.grey_light = jitter(rng, w.ground.grey_light);
    w.sky.grey = jitter(rng, w.sky.grey);
    // The course's volume: the gates' box, 2 m around horizontally, from
    // 0.2 m to 1 m above the highest gate.
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for g in &w.gates {
        lo = lo.min(DVec3::from_array(g.centre.0));
        hi = hi.max(DVec3::from_array(g.centre.0));
    }
    let (lo, hi) = (
        DVec3::new(lo.x - 2.0, lo.y - 2.0, 0.2),
        DVec3::new(hi.x + 2.0, hi.y + 2.0, hi.z + 1.0),
    );
    let boxes = scene_boxes(&w);
    for _ in 0..1000 {
        let (position, yaw) = if rng.random_bool(spec.aimed_share) {
            // In front of (or behind) a gate, up to 60° off its normal,
            // 0.8–7 m away, looking at it within ±0.55 rad (beyond the
            // half field of view 0.435 rad, so some aimed images miss it).
            let g = &w.gates[rng.random_range(0..w.gates.len())];
            let c = DVec3::from_array(g.centre.0);
            let side = if rng.random_bool(0.5) {
                0.0
            } else {
                std::f64::consts::PI
            };
            let bearing = g.yaw.0 + side + rng.random_range(-1.05..=1.05);
            let r = rng.random_range(0.8..=7.0);
            let mut p = c + DVec3::new(bearing.cos(), bearing.sin(), 0.0) * r;
            p.z = (c.z + rng.random_range(-0.6..=0.6)).max(0.2);
            let to_gate = c - p;
            let yaw = to_gate.y.atan2(to_gate.x) + rng.random_range(-0.55..=0.55);
            (p, yaw)
        } else {
            let p = DVec3::new(
                rng.random_range(lo.x..=hi.x),
                rng.random_range(lo.y..=hi.y),
                rng.random_range(lo.z..=hi.z),
            );
            (
                p,
                rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            )
        };
        let t = spec.tilt_rad;
        let (roll, pitch) = (rng.random_range(-t..=t), rng.random_range(-t..=t));
        let rotation = DQuat::from_euler(EulerRot::ZYX, yaw, pitch, roll);
        // Not inside (or within 5 cm of) a bar, a leg or a box.
        let eye = Camera::eye(position, rotation);
        let free = boxes.iter().all(|b| {
            let local = DQuat::from_rotation_z(-b.yaw) * (eye - b.centre);
            (local.abs() - b.half).max_element() > 0.05
        });
        if free {
            return Some(Sample {
                world: w,
                boxes,
                position,
                rotation,
            });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_gate() -> WorldDesc {
        WorldDesc::parse(
            "[start]\nposition=[0.0,0.0,0.015]\n[[gate]]\ncentre=[3.0,0.0,1.0]\nyaw=0.0\ninner=0.8\nbar=0.06\ngrey=170\n",
            Path::new("t.toml"),
        )
        .unwrap()
    }

    /// A gate straight ahead: centre on the optical axis, corners at
    /// ±f·0.4/d px, distance d (closed form of the pinhole camera).
    #[test]
    fn a_gate_ahead_is_labelled_by_the_pinhole_model() {
        let w = one_gate();
        let mut cam = Camera::new(&w, &scene_boxes(&w));
        // Eye at (0.03, 0, 1.0): the body 1 cm lower.
        let (pos, rot) = (DVec3::new(0.0, 0.0, 0.99), DQuat::IDENTITY);
        cam.render(pos, rot);
        let l = nearest_visible_gate(&cam, &w, pos, rot).expect("visible");
        let d = 3.0 - 0.03;
        let f = 160.0 / (crate::crazyflie::CAMERA_FOV / 2.0).tan();
        assert!((l.u - 160.0).abs() < 1e-9 && (l.v - 160.0).abs() < 1e-9);
        assert!((l.distance_m - d).abs() < 1e-12);
        let e = f * 0.4 / d;
        let want = [(-e, -e), (e, -e), (e, e), (-e, e)];
        for (got, want) in l.corners.iter().zip(want) {
            assert!((got.0 - 160.0 - want.0).abs() < 1e-9, "{got:?}");
            assert!((got.1 - 160.0 - want.1).abs() < 1e-9, "{got:?}");
        }
        // Turned away: nothing.
        let back = DQuat::from_rotation_z(std::f64::consts::PI);
        cam.render(pos, back);
        assert_eq!(nearest_visible_gate(&cam, &w, pos, back), None);
    }

    /// gates.csv's view of a gate: straight ahead 0° off its normal; turned
    /// 80° listed but not visible (beyond the 70° rule), at 80°; hidden by
    /// a box not listed at all.
    #[test]
    fn gates_in_view_lists_oblique_gates_with_their_angle() {
        let mut w = one_gate();
        let (pos, rot) = (DVec3::new(0.0, 0.0, 0.99), DQuat::IDENTITY);
        let mut cam = Camera::new(&w, &scene_boxes(&w));
        cam.render(pos, rot);
        let g = gates_in_view(&cam, &w, pos, rot);
        assert_eq!(g.len(), 1);
        assert!(g[0].visible && g[0].in_image && g[0].off_normal_rad.abs() < 1e-9);
        assert_eq!(nearest_visible(&g).map(|l| l.index), Some(0));
        w.gates[0].yaw = Finite(80f64.to_radians());
        let mut cam = Camera::new(&w, &scene_boxes(&w));
        cam.render(pos, rot);
        let g = gates_in_view(&cam, &w, pos, rot);
        assert_eq!(g.len(), 1);
        assert!(!g[0].visible && g[0].in_image);
        assert!(
            (g[0].off_normal_rad.to_degrees() - 80.0).abs() < 0.5,
            "{g:?}"
        );
        assert_eq!(nearest_visible(&g), None);
        let row = gates_csv_row("x.pgm", &g[0]);
        assert!(row.starts_with("x.pgm,0,160.000,"), "{row}");
        assert!(row.contains(",1,0,"), "{row}");
    }

    /// A box between the camera and the gate hides it.
    #[test]
    fn an_occluded_gate_is_not_visible() {
        let mut w = one_gate();
        w.boxes.push(
            WorldDesc::parse(
                "[start]\nposition=[0.0,0.0,0.015]\n[[box]]\ncentre=[1.5,0.0,1.0]\nsize=[0.2,0.3,0.3]\ngrey=60\n",
                Path::new("t.toml"),
            )
            .unwrap()
            .boxes[0]
                .clone(),
        );
        let mut cam = Camera::new(&w, &scene_boxes(&w));
        let (pos, rot) = (DVec3::new(0.0, 0.0, 0.99), DQuat::IDENTITY);
        cam.render(pos, rot);
        assert_eq!(nearest_visible_gate(&cam, &w, pos, rot), None);
        assert!(gates_in_view(&cam, &w, pos, rot).is_empty());
    }
}
