//! Camera renderer against pinhole geometry, and the start view of the course.

use std::path::{Path, PathBuf};

use rapier3d::glamx::{DQuat, DVec3};
use world_server::camera::{write_png, Camera};
use world_server::crazyflie::{CAMERA_FOV, CAMERA_POSITION};
use world_server::scene::scene_boxes;
use world_server::WorldDesc;

fn camera_for(text: &str) -> (WorldDesc, Camera) {
    let desc = WorldDesc::parse(text, Path::new("test.toml")).unwrap();
    let cam = Camera::new(&desc, &scene_boxes(&desc));
    (desc, cam)
}

/// Pixel (column, row) where a camera-frame point (right, up, forward) lands.
fn project(right: f64, up: f64, fwd: f64) -> (usize, usize) {
    let f = 160.0 / (CAMERA_FOV / 2.0).tan();
    let col = 160.0 + f * right / fwd;
    let row = 160.0 - f * up / fwd;
    (col.floor() as usize, row.floor() as usize)
}

fn px(img: &[u8], (col, row): (usize, usize)) -> u8 {
    img[row * 320 + col]
}

const GATE_AHEAD: &str = r#"
[start]
position = [0.0, 0.0, 0.015]
[ground]
tile = 0.5
grey_dark = 90
grey_light = 140
[sky]
grey = 200
[[gate]]
centre = [3.0, 0.0, 1.0]
yaw = 0.0
inner = 0.8
bar = 0.1
grey = 170
"#;

#[test]
fn a_gate_centred_ahead_shows_its_grey_where_pinhole_geometry_puts_it() {
    let (_, mut cam) = camera_for(GATE_AHEAD);
    // Body at (0, 0, 0.99): the camera (0.03, 0, 0.01) sits at height 1.0.
    let img = cam
        .render(DVec3::new(0.0, 0.0, 0.99), DQuat::IDENTITY)
        .to_vec();
    let ex = CAMERA_POSITION[0];
    // The bars' front faces are at x = 3 − 0.05, i.e. 2.92 m ahead of the camera.
    let d = 2.95 - ex;
    // Middle of the top bar (z = 1.45), of the bottom bar (0.55), of the side
    // bars (y = ±0.45; +y is on the image's left).
    for p in [
        project(0.0, 0.45, d),
        project(0.0, -0.45, d),
        project(-0.45, 0.0, d),
        project(0.45, 0.0, d),
        project(0.3, 0.45, d),
    ] {
        assert_eq!(px(&img, p), 170, "pixel {p:?}");
    }
    // The whole bar is covered: every pixel of the top bar's middle row over
    // the opening's width.
    let (c0, row) = project(-0.4, 0.45, d);
    let (c1, _) = project(0.4, 0.45, d);
    assert!(img[row * 320 + c0..row * 320 + c1]
        .iter()
        .all(|&g| g == 170));
    // Through the opening: the horizon is the middle row, sky above and ground below.
    assert_eq!(px(&img, project(0.0, 0.2, d)), 200);
    let below = px(&img, project(0.0, -0.2, d));
    assert!([90, 140, 115].contains(&below), "{below}");
    // Just outside the frame: not the gate.
    assert_ne!(px(&img, project(0.0, 0.56, d)), 170);
    assert_ne!(px(&img, project(0.56, 0.0, d)), 170);
}

#[test]
fn the_checker_under_a_downward_camera_is_where_the_ground_says() {
    let (_, mut cam) = camera_for(GATE_AHEAD);
    // Nose down by 90°: body x points to world −z, the camera looks straight down.
    let rot = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
    // Camera above (0.25, 0.25), the middle of tile (0, 0) which is dark
    // (checker parity (0 + 0) even = dark).
    let body = DVec3::new(0.25, 0.25, 2.0) - rot * DVec3::from_array(CAMERA_POSITION)
        + DVec3::new(0.0, 0.0, 0.0);
    let img = cam.render(body, rot).to_vec();
    assert_eq!(px(&img, (160, 160)), 90);
    // Image up is body +z, which is world +x here: the tile at x in [0.5, 1)
    // (parity odd, light) is above the centre. At 2 m, 0.5 m ahead of the
    // centre lands f·0.5/2 ≈ 86 px up.
    assert_eq!(px(&img, (160, 160 - 86)), 140);
    // Image right is body −y = world −y: tile y in [−0.5, 0) is light.
    assert_eq!(px(&img, (160 + 86, 160)), 140);
    // Diagonal: dark again.
    assert_eq!(px(&img, (160 + 86, 160 - 86)), 90);
}

#[test]
fn nearer_objects_hide_farther_ones() {
    let world = format!(
        "{GATE_AHEAD}\n[[box]]\ncentre = [1.5, 0.0, 1.45]\nsize = [0.1, 0.3, 0.1]\ngrey = 30\n"
    );
    let (_, mut cam) = camera_for(&world);
    let img = cam
        .render(DVec3::new(0.0, 0.0, 0.99), DQuat::IDENTITY)
        .to_vec();
    // The box (front face at x = 1.45) covers the middle of the top bar…
    let d_box = 1.45 - CAMERA_POSITION[0];
    assert_eq!(px(&img, project(0.0, 0.45, d_box)), 30);
    // …but not the top bar's ends.
    let d_gate = 2.95 - CAMERA_POSITION[0];
    assert_eq!(px(&img, project(0.4, 0.45, d_gate)), 170);
    // Seen from behind the gate, the gate hides the box — the order of the
    // scene list does not matter.
    let from_behind = DQuat::from_rotation_z(std::f64::consts::PI);
    let img = cam
        .render(DVec3::new(4.53, 0.0, 0.99), from_behind)
        .to_vec();
    // Camera at x = 4.5 looking along −x; the gate's back face at x = 3.05.
    assert_eq!(px(&img, project(0.0, 0.45, 4.5 - 3.05)), 170);
}

#[test]
fn a_camera_behind_an_object_does_not_see_it() {
    let (_, mut cam) = camera_for(GATE_AHEAD);
    let turned = DQuat::from_rotation_z(std::f64::consts::PI);
    let img = cam.render(DVec3::new(0.0, 0.0, 0.99), turned).to_vec();
    assert!(!img.contains(&170));
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn start_view_of_the_course_is_written_as_png() {
    let path = repo_root().join("scenarios/worlds/thesis-course.toml");
    let desc = WorldDesc::load(&path).unwrap();
    let mut cam = Camera::new(&desc, &scene_boxes(&desc));
    let start = DVec3::from_array(desc.start.position.0);
    let rot = DQuat::from_rotation_z(desc.start.yaw.0);
    let img = cam.render(start, rot).to_vec();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("start-view.png");
    write_png(&png, 320, 320, &img).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (320, 320));
    assert_eq!(&buf[..info.buffer_size()], &img[..]);
    // Level camera 2.5 cm above the ground: sky on top, ground below.
    assert_eq!(img[0], 200);
    assert!([90, 140, 115].contains(&img[319 * 320]));

    // Copies for the docs: the start view, and the view from the start at 1 m
    // turned towards gate 1 (the race itself always faces +y).
    let docs = repo_root().join("docs/img");
    if std::fs::create_dir_all(&docs).is_ok() {
        write_png(&docs.join("start-view.png"), 320, 320, &img).unwrap();
        let g1 = DVec3::from_array(desc.gates[0].centre.0);
        let eye = DVec3::new(start.x, start.y, 1.0);
        let towards = (g1 - eye).truncate();
        let yaw = towards.y.atan2(towards.x);
        let img = cam
            .render(
                eye - DVec3::new(0.0, 0.0, 0.01),
                DQuat::from_rotation_z(yaw),
            )
            .to_vec();
        assert!(img.contains(&170), "gate 1 must be in view");
        write_png(&docs.join("gate1-view.png"), 320, 320, &img).unwrap();
    }
}
