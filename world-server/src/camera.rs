//! The drone's camera: a software renderer of the 320×320 grey image
//! (DESIGN.md §5: at (0.03, 0, 0.01) m in the body, looking along body +x,
//! horizontal field of view 0.87 rad, grey = mean of R, G, B).
//!
//! Written by hand rather than with a rendering crate because a race renders
//! about 4,200 frames and the whole race must run in seconds: one frame has a
//! budget of 0.3 ms on one core, which no general-purpose software rasteriser
//! meets. The scene is tiny — a checkered ground plane, a uniform sky and a
//! few dozen boxes — so:
//!
//! * the ground is mapped row by row: along a row the ray direction is affine
//!   in the column, so the horizon is one crossing point per row, sky pixels
//!   are a `fill`, and each ground pixel costs one division and two floors;
//! * boxes are clipped against the near plane and rasterised as convex
//!   polygons with a depth test on 1/z, which is affine in screen space for a
//!   plane (and also written by the ground, so depth ordering holds between
//!   everything);
//! * nothing is allocated per frame.
//!
//! Shading: box faces with a horizontal normal have exactly the object's grey
//! level (so a gate seen head-on shows its grey), top faces are 15 % brighter
//! and bottom faces 25 % darker, so edges stay visible. There is no lighting
//! model beyond that, and no anti-aliasing.

use std::io::BufWriter;
use std::path::Path;

use rapier3d::glamx::{DQuat, DVec3};

use crate::crazyflie::{CAMERA_FOV, CAMERA_HEIGHT, CAMERA_POSITION, CAMERA_WIDTH};
use crate::scene::SceneBox;
use crate::world_file::WorldDesc;

/// Webots Camera's default `near` (m).
const NEAR: f64 = 0.01;
/// Beyond this distance the checkerboard would alias into noise; it is drawn
/// as the mean of its two greys instead (m).
const GROUND_FAR: f32 = 60.0;
const TOP_FACE_GAIN: f32 = 1.15;
const BOTTOM_FACE_GAIN: f32 = 0.75;

/// One face of a box, world frame, corners counter-clockwise seen from outside.
#[derive(Debug, Clone, Copy)]
struct Face {
    corners: [DVec3; 4],
    normal: DVec3,
    grey: u8,
}

/// A box's faces and its bounding sphere (for frustum culling).
#[derive(Debug, Clone)]
struct Solid {
    centre: DVec3,
    radius: f64,
    faces: [Face; 6],
}

/// The camera and its scene; owns its image and depth buffers.
pub struct Camera {
    width: usize,
    height: usize,
    /// Focal length in pixels.
    focal: f64,
    solids: Vec<Solid>,
    tile: f32,
    grey_dark: u8,
    grey_light: u8,
    sky: u8,
    image: Vec<u8>,
    /// 1 / depth along the optical axis; 0 is infinitely far (sky).
    inv_depth: Vec<f32>,
}

impl Camera {
    /// A 320×320 camera seeing the static scene of `desc` (`boxes` as built by
    /// [`crate::scene::scene_boxes`]).
    pub fn new(desc: &WorldDesc, boxes: &[SceneBox]) -> Camera {
        let (width, height) = (CAMERA_WIDTH, CAMERA_HEIGHT);
        Camera {
            width,
            height,
            focal: (width as f64 / 2.0) / (CAMERA_FOV / 2.0).tan(),
            solids: boxes.iter().map(solid_of).collect(),
            tile: desc.ground.tile.0 as f32,
            grey_dark: desc.ground.grey_dark,
            grey_light: desc.ground.grey_light,
            sky: desc.sky.grey,
            image: vec![0; width * height],
            inv_depth: vec![0.0; width * height],
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The last rendered image, row-major, top row first.
    pub fn image(&self) -> &[u8] {
        &self.image
    }

    /// 1 / depth along the optical axis of the last rendered image, per pixel
    /// (0 for the sky): what is nearest along each pixel's ray.
    pub fn inv_depth(&self) -> &[f32] {
        &self.inv_depth
    }

    /// The optical centre in the world for a drone at `position`/`rotation`.
    pub fn eye(position: DVec3, rotation: DQuat) -> DVec3 {
        position + rotation * DVec3::from_array(CAMERA_POSITION)
    }

    /// Where the world point `p` appears in the image of a drone at
    /// `position`/`rotation`: `(u, v, depth)` with (u, v) in pixels from the
    /// top-left corner of the top-left pixel (the renderer's convention) and
    /// the depth along the optical axis (m); `None` behind the near plane.
    pub fn project(&self, position: DVec3, rotation: DQuat, p: DVec3) -> Option<(f64, f64, f64)> {
        let v = self.view(position, rotation);
        let c = v.to_camera(p);
        (c.z >= NEAR).then(|| {
            (
                v.half_w + v.focal * c.x / c.z,
                v.half_h - v.focal * c.y / c.z,
                c.z,
            )
        })
    }

    fn view(&self, position: DVec3, rotation: DQuat) -> View {
        View {
            eye: Camera::eye(position, rotation),
            fwd: rotation * DVec3::X,
            right: rotation * -DVec3::Y,
            up: rotation * DVec3::Z,
            focal: self.focal,
            half_w: self.width as f64 / 2.0,
            half_h: self.height as f64 / 2.0,
        }
    }

    /// Renders what the camera of a drone at `position`/`rotation` (body pose) sees.
    pub fn render(&mut self, position: DVec3, rotation: DQuat) -> &[u8] {
        let view = self.view(position, rotation);
        self.draw_ground_and_sky(&view);
        // Moved out for the loop (no allocation) so faces can be drawn into `self`.
        let solids = std::mem::take(&mut self.solids);
        for solid in &solids {
            self.draw_solid(&view, solid);
        }
        self.solids = solids;
        &self.image
    }

    fn draw_ground_and_sky(&mut self, v: &View) {
        let (w, f) = (self.width, v.focal);
        // Height above the ground; kept positive so a camera resting on the
        // ground still sees it.
        let h = v.eye.z.max(1e-4);
        let inv_tile = 1.0 / self.tile as f64;
        let mean = ((self.grey_dark as u16 + self.grey_light as u16) / 2) as u8;
        let inv_far = 1.0 / GROUND_FAR;
        let (dark, step) = (self.grey_dark, self.grey_light.wrapping_sub(self.grey_dark));
        for row in 0..self.height {
            let vv = v.half_h - (row as f64 + 0.5);
            // Ray direction for column u is a + u·right, with a = f·fwd + v·up.
            let a = v.fwd * f + v.up * vv;
            let u0 = 0.5 - v.half_w;
            let start = row * w;
            let img = &mut self.image[start..start + w];
            let dep = &mut self.inv_depth[start..start + w];
            // dz(u) = a.z + u·right.z is affine: ground where dz < 0.
            let (first, last) = ground_span(a.z + u0 * v.right.z, v.right.z, w);
            img[..first].fill(self.sky);
            dep[..first].fill(0.0);
            img[last..].fill(self.sky);
            dep[last..].fill(0.0);
            if first >= last {
                continue;
            }
            // Pixel k of the row: direction a + (u0 + k)·right. In f32 from
            // here on: the ground needs millimetres, not nanometres.
            let row = GroundRow {
                ax: a.x as f32,
                ay: a.y as f32,
                az: a.z as f32,
                rx: v.right.x as f32,
                ry: v.right.y as f32,
                rz: v.right.z as f32,
                ex: (v.eye.x * inv_tile) as f32,
                ey: (v.eye.y * inv_tile) as f32,
                // t·inv_tile = −h·inv_tile / dz
                neg_h_tiles: -(h * inv_tile) as f32,
                inv_hf: 1.0 / (h * f) as f32,
                base_u: (u0 + first as f64) as f32,
                inv_far,
                dark,
                step,
                mean,
            };
            ground_row(&row, &mut img[first..last], &mut dep[first..last]);
        }
    }

    fn draw_solid(&mut self, v: &View, solid: &Solid) {
        let c = v.to_camera(solid.centre);
        if !v.sphere_visible(c, solid.radius) {
            return;
        }
        for face in &solid.faces {
            // Back-face culling: the eye must be on the outer side.
            if (face.corners[0] - v.eye).dot(face.normal) >= 0.0 {
                continue;
            }
            let grey = shade(face.grey, face.normal.z);
            let mut poly = [DVec3::ZERO; 8];
            let n = clip_near(&face.corners.map(|p| v.to_camera(p)), &mut poly);
            if n < 3 {
                continue;
            }
            // 1/z over the screen: the face's plane n·P = d in camera space
            // gives 1/z = (n.x·u + n.y·v + n.z·f) / (f·d) for pixel (u, v).
            let nc = v.dir_to_camera(face.normal);
            let d = nc.dot(poly[0]);
            let k = 1.0 / (v.focal * d);
            let plane = [nc.x * k, nc.y * k, nc.z * v.focal * k];
            let mut screen = [(0.0f64, 0.0f64); 8];
            for (s, p) in screen.iter_mut().zip(&poly[..n]) {
                *s = (
                    v.half_w + v.focal * p.x / p.z,
                    v.half_h - v.focal * p.y / p.z,
                );
            }
            self.fill_polygon(v, &screen[..n], plane, grey);
        }
    }

    /// Fills a convex screen-space polygon with a depth test on 1/z.
    fn fill_polygon(&mut self, v: &View, pts: &[(f64, f64)], plane: [f64; 3], grey: u8) {
        let (w, hgt) = (self.width, self.height);
        let ymin = pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let ymax = pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        // Pixel rows whose centre (row + 0.5) lies in [ymin, ymax).
        let r0 = ((ymin - 0.5).ceil().max(0.0)) as usize;
        let r1 = ((ymax - 0.5).ceil().min(hgt as f64).max(0.0)) as usize;
        for row in r0..r1 {
            let y = row as f64 + 0.5;
            let (mut xl, mut xr) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..pts.len() {
                let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
                if (a.1 <= y && b.1 > y) || (b.1 <= y && a.1 > y) {
                    let x = a.0 + (y - a.1) * (b.0 - a.0) / (b.1 - a.1);
                    xl = xl.min(x);
                    xr = xr.max(x);
                }
            }
            if xl >= xr {
                continue;
            }
            let c0 = ((xl - 0.5).ceil().max(0.0)) as usize;
            let c1 = ((xr - 0.5).ceil().min(w as f64).max(0.0)) as usize;
            if c0 >= c1 {
                continue;
            }
            let vv = v.half_h - y;
            let span = FaceSpan {
                plane_u: plane[0],
                base: plane[1] * vv + plane[2],
                u0: c0 as f64 + 0.5 - v.half_w,
                grey,
            };
            let (a, b) = (row * w + c0, row * w + c1);
            face_span(&span, &mut self.image[a..b], &mut self.inv_depth[a..b]);
        }
    }
}

/// Constants of one row of a face for [`face_span`].
struct FaceSpan {
    /// d(1/z)/du on the face's plane.
    plane_u: f64,
    /// 1/z at u = 0 on this row.
    base: f64,
    /// u (pixel centre, from the image centre) of the span's first pixel.
    u0: f64,
    grey: u8,
}

/// Draws one row of a face over `img`/`dep` where it is nearer (larger 1/z)
/// than what is there.
///
/// Like [`ground_row`], compiled for the baseline and for AVX2 and chosen at
/// run time, with the same IEEE operations in the same order in both, so the
/// pixels are bit-identical either way. (`u0 + k` equals the former
/// `col + 0.5 − half_w` exactly: all are multiples of 0.5 below 2^52.)
fn face_span(s: &FaceSpan, img: &mut [u8], dep: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { face_span_avx2(s, img, dep) };
            return;
        }
    }
    face_span_body(s, img, dep);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn face_span_avx2(s: &FaceSpan, img: &mut [u8], dep: &mut [f32]) {
    face_span_body(s, img, dep);
}

/// Branch-free (a select instead of the depth test's `if`), so that it
/// vectorises; a NaN 1/z loses the test either way.
#[inline(always)]
fn face_span_body(s: &FaceSpan, img: &mut [u8], dep: &mut [f32]) {
    let n = img.len().min(dep.len());
    let (img, dep) = (&mut img[..n], &mut dep[..n]);
    for k in 0..n {
        let u = s.u0 + k as i32 as f64;
        let inv_z = (s.plane_u * u + s.base) as f32;
        let nearer = inv_z > dep[k];
        dep[k] = if nearer { inv_z } else { dep[k] };
        img[k] = if nearer { s.grey } else { img[k] };
    }
}

/// Constants of one image row for [`ground_row`].
struct GroundRow {
    ax: f32,
    ay: f32,
    az: f32,
    rx: f32,
    ry: f32,
    rz: f32,
    ex: f32,
    ey: f32,
    neg_h_tiles: f32,
    inv_hf: f32,
    base_u: f32,
    inv_far: f32,
    dark: u8,
    step: u8,
    mean: u8,
}

/// Draws the ground pixels of one row (all of `img` sees the ground).
///
/// The same code is compiled three times: for the baseline x86-64 (SSE2,
/// 4 lanes), for AVX2 (8 lanes) and for AVX-512 (16 lanes), chosen at run
/// time. Only IEEE adds, multiplies
/// and divides are used (no FMA contraction), so both give bit-identical
/// images.
fn ground_row(row: &GroundRow, img: &mut [u8], dep: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw")
        {
            // SAFETY: the CPU supports AVX-512 F and BW, checked just above.
            unsafe { ground_row_avx512(row, img, dep) };
            return;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { ground_row_avx2(row, img, dep) };
            return;
        }
    }
    ground_row_body(row, img, dep);
}

/// 16 lanes; the same operations, so the same pixels.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
unsafe fn ground_row_avx512(row: &GroundRow, img: &mut [u8], dep: &mut [f32]) {
    ground_row_body(row, img, dep);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ground_row_avx2(row: &GroundRow, img: &mut [u8], dep: &mut [f32]) {
    ground_row_body(row, img, dep);
}

/// Branch-free and within exact-length slices, so that it vectorises.
#[inline(always)]
fn ground_row_body(r: &GroundRow, img: &mut [u8], dep: &mut [f32]) {
    let n = img.len().min(dep.len());
    let (img, dep) = (&mut img[..n], &mut dep[..n]);
    for k in 0..n {
        // Through i32 (exact: a row has 320 pixels): the vector conversion
        // `cvtdq2ps`, where `usize as f32` is a scalar conversion per lane.
        let u = r.base_u + k as i32 as f32;
        let dz = r.az + u * r.rz;
        let s = r.neg_h_tiles / dz;
        let gx = r.ex + s * (r.ax + u * r.rx);
        let gy = r.ey + s * (r.ay + u * r.ry);
        let inv_z = -dz * r.inv_hf;
        // floor() by the i32 conversion of a shifted positive value (the
        // shift is even, so the checker parity is unchanged; 4096 tiles keep
        // f32 precision under a millimetre, and beyond GROUND_FAR the mean
        // grey is drawn anyway).
        // Clamped first, so the conversion is in range and needs none of
        // `as`'s saturation fix-ups (3x faster). max/min rather than clamp:
        // they turn a NaN (a ray grazing the horizon) into a bound, clamp
        // would keep it.
        #[allow(clippy::manual_clamp)]
        let cx = (gx + 4096.0).max(0.0).min(8192.0);
        #[allow(clippy::manual_clamp)]
        let cy = (gy + 4096.0).max(0.0).min(8192.0);
        // SAFETY: cx and cy are finite and within [0, 8192].
        let (cx, cy) = unsafe { (cx.to_int_unchecked::<i32>(), cy.to_int_unchecked::<i32>()) };
        let odd = ((cx ^ cy) & 1) as u8;
        let checker = r.dark.wrapping_add(odd.wrapping_mul(r.step));
        img[k] = if inv_z < r.inv_far { r.mean } else { checker };
        dep[k] = inv_z;
    }
}

/// The columns `[first, last)` of a row whose rays go down (dz < 0), for
/// dz(k) = dz0 + k·slope at pixel k.
fn ground_span(dz0: f64, slope: f64, w: usize) -> (usize, usize) {
    // A tiny margin keeps rays grazing the horizon (t → ∞) in the sky.
    let limit = -1e-9;
    if slope == 0.0 {
        return if dz0 < limit { (0, w) } else { (0, 0) };
    }
    let k = (limit - dz0) / slope; // dz(k) == limit
    if slope > 0.0 {
        // dz grows with k: ground left of k.
        let last = k.ceil().clamp(0.0, w as f64) as usize;
        (0, last)
    } else {
        let first = (k.floor() + 1.0).clamp(0.0, w as f64) as usize;
        (first, w)
    }
}

fn shade(grey: u8, normal_z: f64) -> u8 {
    let gain = if normal_z > 0.5 {
        TOP_FACE_GAIN
    } else if normal_z < -0.5 {
        BOTTOM_FACE_GAIN
    } else {
        1.0
    };
    (grey as f32 * gain).round().min(255.0) as u8
}

/// Camera axes and intrinsics for one frame.
struct View {
    eye: DVec3,
    fwd: DVec3,
    right: DVec3,
    up: DVec3,
    focal: f64,
    half_w: f64,
    half_h: f64,
}

impl View {
    /// World point to camera coordinates (x right, y up, z along the optical axis).
    fn to_camera(&self, p: DVec3) -> DVec3 {
        self.dir_to_camera(p - self.eye)
    }

    fn dir_to_camera(&self, d: DVec3) -> DVec3 {
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.fwd))
    }

    /// False when the sphere is certainly outside the view frustum.
    fn sphere_visible(&self, c: DVec3, r: f64) -> bool {
        if c.z + r < NEAR {
            return false;
        }
        let (f, hw, hh) = (self.focal, self.half_w, self.half_h);
        let planes = [
            DVec3::new(f, 0.0, -hw),
            DVec3::new(-f, 0.0, -hw),
            DVec3::new(0.0, f, -hh),
            DVec3::new(0.0, -f, -hh),
        ];
        planes.iter().all(|n| n.dot(c) <= r * n.length())
    }
}

/// Clips a camera-space quad against z ≥ NEAR (Sutherland–Hodgman); returns
/// the number of vertices written to `out` (at most 5).
fn clip_near(quad: &[DVec3; 4], out: &mut [DVec3; 8]) -> usize {
    let mut n = 0;
    for i in 0..4 {
        let (a, b) = (quad[i], quad[(i + 1) % 4]);
        let (ina, inb) = (a.z >= NEAR, b.z >= NEAR);
        if ina {
            out[n] = a;
            n += 1;
        }
        if ina != inb {
            let t = (NEAR - a.z) / (b.z - a.z);
            out[n] = a + (b - a) * t;
            n += 1;
        }
    }
    n
}

/// The six faces of an oriented box.
fn solid_of(b: &SceneBox) -> Solid {
    let rot = DQuat::from_rotation_z(b.yaw);
    let ax = [rot * DVec3::X, rot * DVec3::Y, DVec3::Z];
    let h = [b.half.x, b.half.y, b.half.z];
    let corner = |sx: f64, sy: f64, sz: f64| {
        b.centre + ax[0] * (sx * h[0]) + ax[1] * (sy * h[1]) + ax[2] * (sz * h[2])
    };
    let face = |axis: usize, sign: f64| {
        // Two in-face axes (u, v) with u × v = outward normal.
        let (u, v) = match axis {
            0 => (1, 2),
            1 => (2, 0),
            _ => (0, 1),
        };
        let (u, v) = if sign > 0.0 { (u, v) } else { (v, u) };
        let mut s = [0.0; 3];
        s[axis] = sign;
        let mut corners = [DVec3::ZERO; 4];
        for (k, (su, sv)) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .into_iter()
            .enumerate()
        {
            let mut p = s;
            p[u] = su;
            p[v] = sv;
            corners[k] = corner(p[0], p[1], p[2]);
        }
        Face {
            corners,
            normal: ax[axis] * sign,
            grey: b.grey,
        }
    };
    Solid {
        centre: b.centre,
        radius: b.half.length(),
        faces: [
            face(0, 1.0),
            face(0, -1.0),
            face(1, 1.0),
            face(1, -1.0),
            face(2, 1.0),
            face(2, -1.0),
        ],
    }
}

/// Writes a grey image as an 8-bit greyscale PNG.
pub fn write_png(path: &Path, width: usize, height: usize, data: &[u8]) -> std::io::Result<()> {
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(BufWriter::new(file), width as u32, height as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(std::io::Error::other)?;
    writer
        .write_image_data(data)
        .map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)
}

#[cfg(test)]
mod tests {
    //! The rows compiled for each instruction set give the same pixels and
    //! depths bit for bit (an image's hash is in every trace).

    use super::*;
    use proptest::prelude::*;

    type RowFn = fn(&GroundRow, &mut [u8], &mut [f32]);
    type SpanFn = fn(&FaceSpan, &mut [u8], &mut [f32]);

    /// Every compiled ground-row path this CPU can run, the portable one first.
    fn ground_paths() -> Vec<(&'static str, RowFn)> {
        let mut paths: Vec<(&'static str, RowFn)> = vec![("portable", ground_row_body)];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY (of the call): only used on a CPU with AVX2.
                paths.push(("avx2", |r, i, d| unsafe { ground_row_avx2(r, i, d) }));
            }
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512bw")
            {
                // SAFETY (of the call): only used on a CPU with AVX-512 F, BW.
                paths.push(("avx512", |r, i, d| unsafe { ground_row_avx512(r, i, d) }));
            }
        }
        paths
    }

    fn span_paths() -> Vec<(&'static str, SpanFn)> {
        let mut paths: Vec<(&'static str, SpanFn)> = vec![("portable", face_span_body)];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY (of the call): only used on a CPU with AVX2.
            paths.push(("avx2", |s, i, d| unsafe { face_span_avx2(s, i, d) }));
        }
        paths
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn ground_rows_agree(
            a in (-500.0f32..500.0, -500.0f32..500.0, -500.0f32..0.0),
            r in (-1.0f32..1.0, -1.0f32..1.0, -0.2f32..0.2),
            e in (-100.0f32..100.0, -100.0f32..100.0),
            h in 0.0001f32..20.0,
            base_u in -160.0f32..160.0,
            n in 1usize..330,
        ) {
            let row = GroundRow {
                ax: a.0, ay: a.1, az: a.2, rx: r.0, ry: r.1, rz: r.2, ex: e.0, ey: e.1,
                neg_h_tiles: -h,
                inv_hf: 1.0 / (h * 344.0),
                base_u: base_u.round() + 0.5,
                inv_far: 1.0 / GROUND_FAR,
                dark: 90,
                step: 200 - 90,
                mean: 145,
            };
            let mut first: Option<(Vec<u8>, Vec<f32>)> = None;
            for (name, f) in ground_paths() {
                let (mut img, mut dep) = (vec![0u8; n], vec![0f32; n]);
                f(&row, &mut img, &mut dep);
                let bits: Vec<u32> = dep.iter().map(|x| x.to_bits()).collect();
                match &first {
                    None => first = Some((img, dep)),
                    Some((i0, d0)) => {
                        prop_assert_eq!(&img, i0, "{} pixels", name);
                        let bits0: Vec<u32> = d0.iter().map(|x| x.to_bits()).collect();
                        prop_assert_eq!(bits, bits0, "{} depths", name);
                    }
                }
            }
        }

        #[test]
        fn face_spans_agree(
            plane_u in -0.01f64..0.01,
            base in -1.0f64..5.0,
            c0 in 0usize..320,
            n in 1usize..320,
            depths in proptest::collection::vec(0.0f32..5.0, 320),
        ) {
            let span = FaceSpan { plane_u, base, u0: c0 as f64 + 0.5 - 160.0, grey: 77 };
            let mut first: Option<(Vec<u8>, Vec<f32>)> = None;
            for (name, f) in span_paths() {
                let mut img: Vec<u8> = (0..n).map(|k| k as u8).collect();
                let mut dep = depths[..n].to_vec();
                f(&span, &mut img, &mut dep);
                match &first {
                    None => first = Some((img, dep)),
                    Some((i0, d0)) => {
                        prop_assert_eq!(&img, i0, "{} pixels", name);
                        prop_assert_eq!(&dep, d0, "{} depths", name);
                    }
                }
            }
        }
    }
}
