//! World files (TOML, `scenarios/worlds/*.toml`): the drones (a start pose,
//! or `[[drone]]` tables), ground, sky, gates and boxes (DESIGN.md §5, §7).
//!
//! A malformed file is reported with the file name, the line and column and
//! the field (`gate[3].inner`, `drone[2].carried[3]`), never with a panic.

mod drone;
mod sensors;

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::crazyflie::MotorResponse;
use crate::radio::RadioConfig;

pub use drone::{CarriedPath, DroneDesc, DEFAULT_DRONE_NAME, MAX_CLOCK_PPM, MAX_NAME_LEN};
pub use sensors::{SensorConfig, MAX_FOV_DEG, MAX_RAYS};

/// A world as read from a file, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldDesc {
    /// Free-form name, shown in logs.
    pub name: String,
    /// The first drone's start pose: `[start]`, or the first `[[drone]]`.
    /// (Kept for the tools that draw one start; the drones are in `drones`.)
    pub start: Start,
    /// Every drone in file order (the canonical order of the lockstep,
    /// docs/SWARM.md §2); one drone `"cf1"` at `[start]` when the file has no
    /// `[[drone]]` table. Never empty.
    pub drones: Vec<DroneDesc>,
    pub ground: Ground,
    pub sky: Sky,
    pub physics: PhysicsOptions,
    pub gates: Vec<Gate>,
    pub boxes: Vec<BoxDesc>,
    /// `[radio]`: the radio channel's parameters (DESIGN.md §8), checked.
    pub radio: RadioConfig,
    /// `[sensors]`: range sensors and optical flow (DESIGN.md §9); the
    /// race's four 2 m single-ray rangers when absent.
    pub sensors: SensorConfig,
}

/// A world file as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorld {
    #[serde(default)]
    name: String,
    #[serde(default)]
    start: Option<Spanned<Start>>,
    #[serde(default, rename = "drone")]
    drones: Vec<Spanned<drone::RawDrone>>,
    #[serde(default)]
    ground: Ground,
    #[serde(default)]
    sky: Sky,
    #[serde(default)]
    physics: PhysicsOptions,
    #[serde(default, rename = "gate")]
    gates: Vec<Gate>,
    #[serde(default, rename = "box")]
    boxes: Vec<BoxDesc>,
    #[serde(default)]
    radio: Option<Spanned<RadioConfig>>,
    #[serde(default)]
    sensors: Option<Spanned<sensors::RawSensors>>,
}

/// Start pose of the drone.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Start {
    /// Body origin (m). The bounding cylinder is 3 cm high, so z = 0.015 rests on the ground.
    pub position: Point3,
    /// Heading (rad, counter-clockwise from world +x).
    #[serde(default)]
    pub yaw: Finite,
}

/// The ground plane z = 0, drawn as a checkerboard.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ground {
    /// Side of one checker square (m).
    pub tile: Positive,
    pub grey_dark: u8,
    pub grey_light: u8,
}

impl Default for Ground {
    fn default() -> Self {
        Ground {
            tile: Positive(0.5),
            grey_dark: 90,
            grey_light: 140,
        }
    }
}

/// Background above the horizon.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sky {
    pub grey: u8,
}

impl Default for Sky {
    fn default() -> Self {
        Sky { grey: 200 }
    }
}

/// Optional physics settings. DESIGN.md §5: no aerodynamic drag unless the world asks.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsOptions {
    /// Linear damping of the drone body (1/s), rapier's model.
    #[serde(default)]
    pub linear_damping: NonNegative,
    /// Angular damping of the drone body (1/s).
    #[serde(default)]
    pub angular_damping: NonNegative,
    /// How the motors follow their speed targets: `"webots"` (the PROTO's
    /// acceleration limit, the thesis's) or `"crazyflie"` (a first-order
    /// lag with a real Crazyflie's time constants; DESIGN.md §20).
    #[serde(default)]
    pub motors: MotorResponse,
    /// Restitution of every contact (0: no bounce, 1: elastic); 0.5 when
    /// absent, Webots's default `bounce` and the thesis's figures' value.
    #[serde(default = "default_restitution")]
    pub restitution: UnitInterval,
}

impl Default for PhysicsOptions {
    fn default() -> Self {
        PhysicsOptions {
            linear_damping: NonNegative(0.0),
            angular_damping: NonNegative(0.0),
            motors: MotorResponse::default(),
            restitution: default_restitution(),
        }
    }
}

fn default_restitution() -> UnitInterval {
    UnitInterval(0.5)
}

/// A finite number in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(try_from = "f64")]
pub struct UnitInterval(pub f64);

impl TryFrom<f64> for UnitInterval {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if (0.0..=1.0).contains(&v) {
            Ok(UnitInterval(v))
        } else {
            Err(format!("{v} must be a number in [0, 1]"))
        }
    }
}

/// A square gate: a frame of four bars with a square cross-section, standing
/// on two legs unless `legs = false`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gate {
    /// Centre of the opening (m).
    pub centre: Point3,
    /// Direction of travel through the gate (rad from world +x): the frame
    /// lies in the vertical plane perpendicular to it.
    pub yaw: Finite,
    /// Side of the square opening, inside the bars (m).
    pub inner: Positive,
    /// Width (and depth) of each bar (m).
    pub bar: Positive,
    /// Grey level of the frame (0–255).
    pub grey: u8,
    #[serde(default = "default_true")]
    pub legs: bool,
}

/// A box standing anywhere (obstacle or decoration); it collides like a gate.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxDesc {
    pub centre: Point3,
    /// Full size along its own x, y, z (m).
    pub size: [Positive; 3],
    #[serde(default)]
    pub yaw: Finite,
    pub grey: u8,
}

fn default_true() -> bool {
    true
}

/// A finite number.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(try_from = "f64")]
pub struct Finite(pub f64);

impl TryFrom<f64> for Finite {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if v.is_finite() {
            Ok(Finite(v))
        } else {
            Err(format!("{v} is not a finite number"))
        }
    }
}

/// A finite number > 0.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(try_from = "f64")]
pub struct Positive(pub f64);

impl TryFrom<f64> for Positive {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if v.is_finite() && v > 0.0 {
            Ok(Positive(v))
        } else {
            Err(format!("{v} must be a finite number > 0"))
        }
    }
}

/// A finite number ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(try_from = "f64")]
pub struct NonNegative(pub f64);

impl TryFrom<f64> for NonNegative {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if v.is_finite() && v >= 0.0 {
            Ok(NonNegative(v))
        } else {
            Err(format!("{v} must be a finite number >= 0"))
        }
    }
}

/// A point `[x, y, z]` in metres, world frame.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(from = "[Finite; 3]")]
pub struct Point3(pub [f64; 3]);

impl From<[Finite; 3]> for Point3 {
    fn from(p: [Finite; 3]) -> Self {
        Point3([p[0].0, p[1].0, p[2].0])
    }
}

/// Why a world file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum WorldFileError {
    /// The cause is in the message, and so not also a `source()`: a
    /// chain printer (`anyhow`'s `{:#}`) would print it twice.
    #[error("cannot read world file {path}: {cause}")]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("{path}:{line}:{column}: {field}: {message}")]
    Invalid {
        path: PathBuf,
        line: usize,
        column: usize,
        /// The field at fault, e.g. `gate[3].inner` (`(file)` when unknown).
        field: String,
        message: String,
    },
}

impl WorldDesc {
    /// Reads and checks a world file. A file whose first key is
    /// `base = "other.toml"` (a path relative to it) is that world with the
    /// file's own tables laid over it: a table it names replaces or extends
    /// the base's table key by key, an array of tables (`[[box]]`) it names
    /// replaces the base's. One room serves several worlds that differ in a
    /// few keys (a cflib room with the Crazyflie's motors) without a copy.
    pub fn load(path: &Path) -> Result<WorldDesc, WorldFileError> {
        let text = Self::read_text(path)?;
        Self::parse(&text, path)
    }

    /// The world's text as [`WorldDesc::load`] parses it: the file's own,
    /// or with its `base` chain merged in (one self-contained file).
    pub fn read_text(path: &Path) -> Result<String, WorldFileError> {
        Self::load_text(path, 0)
    }

    /// The text of `path`, its `base` chain merged in (at most
    /// [`MAX_BASE_DEPTH`] deep: a longer chain is a cycle or a mistake).
    fn load_text(path: &Path, depth: usize) -> Result<String, WorldFileError> {
        let text = std::fs::read_to_string(path).map_err(|cause| WorldFileError::Io {
            path: path.to_path_buf(),
            cause,
        })?;
        let invalid = |offset: usize, field: &str, message: String| {
            let (line, column) = line_column(&text, offset);
            WorldFileError::Invalid {
                path: path.to_path_buf(),
                line,
                column,
                field: field.to_string(),
                message,
            }
        };
        let mut own: toml::Table = toml::from_str(&text).map_err(|e| {
            let offset = e.span().map(|s| s.start).unwrap_or(0);
            invalid(
                offset,
                &field_at(&text, offset),
                e.message().trim().to_string(),
            )
        })?;
        let Some(base) = own.remove("base") else {
            return Ok(text);
        };
        let at = text.find("base").unwrap_or(0);
        let Some(base) = base.as_str() else {
            return Err(invalid(
                at,
                "base",
                "expected the path of a world file".into(),
            ));
        };
        if depth >= MAX_BASE_DEPTH {
            return Err(invalid(
                at,
                "base",
                format!("more than {MAX_BASE_DEPTH} bases deep (a cycle?)"),
            ));
        }
        let base_path = path.parent().unwrap_or(Path::new("")).join(base);
        let mut merged: toml::Table = toml::from_str(&Self::load_text(&base_path, depth + 1)?)
            .expect("a world file's merged text is TOML");
        overlay(&mut merged, own);
        Ok(toml::to_string(&merged).expect("a TOML table serializes"))
    }

    /// Parses world-file text; `path` is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<WorldDesc, WorldFileError> {
        let invalid = |offset: usize, field: String, message: String| {
            let (line, column) = line_column(text, offset);
            WorldFileError::Invalid {
                path: path.to_path_buf(),
                line,
                column,
                field,
                message,
            }
        };
        let raw = toml::from_str::<RawWorld>(text).map_err(|e| {
            let offset = e.span().map(|s| s.start).unwrap_or(0);
            invalid(
                offset,
                field_at(text, offset),
                e.message().trim().to_string(),
            )
        })?;
        let has_drones = !raw.drones.is_empty();
        let drones = drone::resolve(raw.drones).map_err(|(at, f, m)| invalid(at, f, m))?;
        let (start, drones) = match (raw.start, has_drones) {
            (Some(s), false) => {
                let s = s.into_inner();
                (s.clone(), vec![DroneDesc::single(s)])
            }
            (None, true) => (drones[0].start.clone(), drones),
            (Some(s), true) => {
                return Err(invalid(
                    s.span().start,
                    "start".into(),
                    "give either [start] (one drone) or [[drone]] tables, not both".into(),
                ))
            }
            (None, false) => {
                return Err(invalid(
                    0,
                    "(file)".into(),
                    "missing [start] (the one drone's start pose) or [[drone]] tables".into(),
                ))
            }
        };
        let radio = match raw.radio {
            Some(r) => {
                let at = r.span().start;
                let r = r.into_inner();
                r.validate().map_err(|m| invalid(at, "radio".into(), m))?;
                r
            }
            None => RadioConfig::default(),
        };
        let sensors = match raw.sensors {
            Some(r) => {
                let at = r.span().start;
                SensorConfig::try_from(r.into_inner())
                    .map_err(|m| invalid(at, "sensors".into(), m))?
            }
            None => SensorConfig::default(),
        };
        Ok(WorldDesc {
            name: raw.name,
            radio,
            sensors,
            start,
            drones,
            ground: raw.ground,
            sky: raw.sky,
            physics: raw.physics,
            gates: raw.gates,
            boxes: raw.boxes,
        })
    }

    /// True when the world has more than one drone (the multi-drone rules
    /// of DESIGN.md §7 apply: claims by name, `drone` fields in outputs).
    pub fn is_multi(&self) -> bool {
        self.drones.len() > 1
    }

    /// The index of the drone called `name`.
    pub fn drone_index(&self, name: &str) -> Option<usize> {
        self.drones.iter().position(|d| d.name == name)
    }
}

/// How many `base` files a world may stand on.
pub const MAX_BASE_DEPTH: usize = 4;

/// `over`'s keys laid over `under`: tables merge key by key, anything else
/// (values, arrays of tables) replaces.
fn overlay(under: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (under.get_mut(&k), v) {
            (Some(toml::Value::Table(u)), toml::Value::Table(o)) => overlay(u, o),
            (_, v) => {
                under.insert(k, v);
            }
        }
    }
}

/// 1-based line and column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The dotted path of the field at `offset`: the last table header before it
/// (with its index for arrays of tables, counted from 1) and the key on the line.
fn field_at(text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let line = text[line_start..line_end].trim();
    let mut table = String::new();
    let mut counts: Vec<(String, usize)> = Vec::new();
    for l in text[..line_start].lines().map(str::trim) {
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
            let name = name.trim().to_string();
            let n = match counts.iter_mut().find(|(k, _)| *k == name) {
                Some((_, n)) => {
                    *n += 1;
                    *n
                }
                None => {
                    counts.push((name.clone(), 1));
                    1
                }
            };
            table = format!("{name}[{n}]");
        } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.split(']').next()) {
            table = name.trim().to_string();
        }
    }
    let key = line
        .split_once('=')
        .map(|(k, _)| k.trim())
        .filter(|k| !k.is_empty() && !k.starts_with('#') && !k.starts_with('['));
    match (table.is_empty(), key) {
        (true, Some(k)) => k.to_string(),
        (false, Some(k)) => format!("{table}.{k}"),
        (false, None) => table,
        (true, None) => "(file)".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "t"
[start]
position = [-2.6, 0.0, 0.015]
yaw = 1.5707963267948966

[[gate]]
centre = [0.0, 1.0, 1.0]
yaw = 0.5
inner = 0.8
bar = 0.06
grey = 170

[[gate]]
centre = [3.0, 1.0, 1.0]
yaw = 0.0
inner = 0.8
bar = 0.06
grey = 170
legs = false

[[box]]
centre = [1.0, 1.0, 0.25]
size = [0.5, 0.5, 0.5]
grey = 60
"#;

    #[test]
    fn a_good_file_parses_with_defaults() {
        let w = WorldDesc::parse(GOOD, Path::new("good.toml")).unwrap();
        assert_eq!(w.start.position, Point3([-2.6, 0.0, 0.015]));
        assert_eq!(w.gates.len(), 2);
        assert!(w.gates[0].legs);
        assert!(!w.gates[1].legs);
        assert_eq!(w.boxes[0].yaw, Finite(0.0));
        assert_eq!(w.ground, Ground::default());
        assert_eq!(w.physics.linear_damping, NonNegative(0.0));
    }

    fn error_of(text: &str) -> String {
        WorldDesc::parse(text, Path::new("w.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn a_bad_value_names_file_line_and_field() {
        let bad = GOOD.replacen("inner = 0.8", "inner = -0.8", 2);
        let bad = bad.replacen("inner = -0.8", "inner = 0.8", 1);
        let e = error_of(&bad);
        // The second gate's `inner` is on line 17.
        assert!(e.starts_with("w.toml:17:"), "{e}");
        assert!(e.contains("gate[2].inner"), "{e}");
        assert!(e.contains("> 0"), "{e}");
    }

    #[test]
    fn grey_out_of_range_is_reported() {
        let e = error_of(&GOOD.replace("grey = 60", "grey = 300"));
        assert!(e.contains("box[1].grey"), "{e}");
        assert!(e.starts_with("w.toml:25:"), "{e}");
    }

    #[test]
    fn missing_and_unknown_fields_are_reported() {
        let e = error_of(&GOOD.replacen("bar = 0.06\n", "", 1));
        assert!(e.contains("missing field `bar`"), "{e}");
        let e = error_of(&GOOD.replace("legs = false", "lgs = false"));
        assert!(e.contains("unknown field `lgs`"), "{e}");
        assert!(e.contains("gate[2].lgs"), "{e}");
    }

    #[test]
    fn syntax_errors_are_reported_with_position() {
        let e = error_of("[start]\nposition = [1, 2\n");
        assert!(e.starts_with("w.toml:"), "{e}");
        let e = error_of("[start]\nposition = [1.0, 2.0]\n");
        assert!(e.contains("start.position"), "{e}");
    }

    #[test]
    fn a_missing_file_is_an_io_error() {
        let e = WorldDesc::load(Path::new("/nonexistent/world.toml")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/world.toml"));
    }

    const TWO: &str = r#"
name = "two"

[[drone]]
name = "A"
position = [0.0, 0.0, 0.015]
yaw = 1.5
clock_ppm = 20.0
radios = ["uwb"]

[[drone]]
name = "B"
clock_ppm = -20.0
carried = [[0.0, 1.0, 0.0, 0.5], [12.0, 1.0, 0.0, 0.5],
           [14.0, 0.5, 0.25, 0.5]]
"#;

    #[test]
    fn drone_tables_parse_with_defaults() {
        let w = WorldDesc::parse(TWO, Path::new("two.toml")).unwrap();
        assert!(w.is_multi());
        assert_eq!(w.drones.len(), 2);
        let (a, b) = (&w.drones[0], &w.drones[1]);
        assert_eq!(a.name, "A");
        assert_eq!(a.start.yaw, Finite(1.5));
        assert_eq!(a.clock_ppm, 20.0);
        assert_eq!(a.radios, vec![protocol::Radio::Uwb]);
        assert!(!a.is_carried());
        assert_eq!(b.radios, protocol::Radio::ALL.to_vec());
        assert_eq!(b.start.position, Point3([1.0, 0.0, 0.5]));
        assert_eq!(b.start.yaw, Finite(0.0));
        assert_eq!(b.carried.as_ref().unwrap().at(13.0), [0.75, 0.125, 0.5]);
        // `start` is the first drone's pose; indices follow the file.
        assert_eq!(w.start, a.start);
        assert_eq!(w.drone_index("B"), Some(1));
        assert_eq!(w.drone_index("C"), None);
    }

    #[test]
    fn without_drone_tables_there_is_one_drone_cf1_at_start() {
        let w = WorldDesc::parse(GOOD, Path::new("good.toml")).unwrap();
        assert!(!w.is_multi());
        assert_eq!(w.drones.len(), 1);
        let d = &w.drones[0];
        assert_eq!(d.name, "cf1");
        assert_eq!(d.start, w.start);
        assert_eq!(d.clock_ppm, 0.0);
        assert!(d.carried.is_none());
        assert_eq!(d.radios, protocol::Radio::ALL.to_vec());
    }

    #[test]
    fn drone_errors_name_file_line_and_field() {
        let e = error_of(&TWO.replace("name = \"B\"", "name = \"A\""));
        assert!(e.starts_with("w.toml:12:8: drone[2].name:"), "{e}");
        assert!(e.contains("already used by drone[1]"), "{e}");
        let e = error_of(&TWO.replace("[14.0,", "[12.0,"));
        assert!(e.starts_with("w.toml:15:12: drone[2].carried[3]:"), "{e}");
        assert!(e.contains("times must increase"), "{e}");
        let e = error_of(&TWO.replace(
            "carried = [[0.0, 1.0, 0.0, 0.5], ",
            "carried = [[0.0, 1.0],",
        ));
        assert!(e.starts_with("w.toml:14:"), "{e}");
        let e = error_of(&TWO.replace("position = [0.0, 0.0, 0.015]\n", ""));
        assert!(e.starts_with("w.toml:4:1: drone[1]:"), "{e}");
        assert!(e.contains("missing field `position`"), "{e}");
        let e = error_of(&TWO.replace("radios = [\"uwb\"]", "radios = [\"uwb\", \"uwb\"]"));
        assert!(e.contains("drone[1].radios") && e.contains("twice"), "{e}");
        let e = error_of(&TWO.replace("radios = [\"uwb\"]", "radios = [\"wifi\"]"));
        assert!(e.contains("drone[1].radios") && e.contains("wifi"), "{e}");
        let e = error_of(&TWO.replace("clock_ppm = 20.0", "clock_ppm = 2e4"));
        assert!(e.starts_with("w.toml:8:13: drone[1].clock_ppm:"), "{e}");
        let e = error_of(&TWO.replace("name = \"A\"", "name = \"a/b\""));
        assert!(
            e.contains("drone[1].name") && e.contains("output directories"),
            "{e}"
        );
        let e = error_of(&TWO.replace("yaw = 1.5", "yaw = 1.5\nspeed = 3"));
        assert!(
            e.contains("unknown field `speed`") && e.contains("drone[1].speed"),
            "{e}"
        );
        // A carried drone may repeat its path's start, not contradict it.
        let ok = TWO.replace(
            "clock_ppm = -20.0",
            "clock_ppm = -20.0\nposition = [1.0, 0.0, 0.5]",
        );
        assert!(WorldDesc::parse(&ok, Path::new("w.toml")).is_ok());
        let e = error_of(&TWO.replace(
            "clock_ppm = -20.0",
            "clock_ppm = -20.0\nposition = [1.0, 0.0, 0.015]",
        ));
        assert!(
            e.contains("drone[2].position") && e.contains("carried path"),
            "{e}"
        );
    }

    #[test]
    fn the_radio_table_is_read_and_checked() {
        let w = WorldDesc::parse(TWO, Path::new("w.toml")).unwrap();
        assert_eq!(w.radio, RadioConfig::default());
        let text = format!("{TWO}\n[radio]\nseed = 7\nuwb_noise_m = 0.0\n");
        let w = WorldDesc::parse(&text, Path::new("w.toml")).unwrap();
        assert_eq!((w.radio.seed, w.radio.uwb_noise_m), (7, 0.0));
        assert_eq!(
            w.radio.uwb_max_range_m,
            RadioConfig::default().uwb_max_range_m
        );
        let e = error_of(&format!("{TWO}\n[radio]\nuwb_loss = 2.0\n"));
        assert!(e.starts_with("w.toml:17:") && e.contains("uwb_loss"), "{e}");
        let e = error_of(&format!("{TWO}\n[radio]\nuwb_nosie_m = 2.0\n"));
        assert!(
            e.contains("radio.uwb_nosie_m") && e.contains("unknown field"),
            "{e}"
        );
    }

    #[test]
    fn start_and_drones_exclude_each_other() {
        let e = error_of(&format!("{TWO}\n[start]\nposition = [0.0, 0.0, 0.015]\n"));
        assert!(e.starts_with("w.toml:17:"), "{e}");
        assert!(e.contains("either [start]") && e.contains("start"), "{e}");
        let e = error_of("name = \"nothing\"\n");
        assert!(e.contains("missing [start]"), "{e}");
    }

    #[test]
    fn a_world_on_a_base_is_the_base_with_its_own_tables_laid_over() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("room.toml"), GOOD).unwrap();
        let child = dir.path().join("cf.toml");
        std::fs::write(
            &child,
            "base = \"room.toml\"\nname = \"cf\"\n[physics]\nmotors = \"crazyflie\"\nrestitution = 0.0\n",
        )
        .unwrap();
        let base = WorldDesc::parse(GOOD, Path::new("room.toml")).unwrap();
        let w = WorldDesc::load(&child).unwrap();
        assert_eq!(w.name, "cf");
        assert_eq!(w.physics.motors, MotorResponse::Crazyflie);
        assert_eq!(w.physics.restitution, UnitInterval(0.0));
        assert_eq!(
            (w.gates, w.boxes, w.start),
            (base.gates, base.boxes, base.start)
        );
        assert_eq!(base.physics.restitution, UnitInterval(0.5));
        assert_eq!(base.physics.motors, MotorResponse::Webots);
        // A file that is its own base is refused, not a stack overflow.
        std::fs::write(&child, "base = \"cf.toml\"\n").unwrap();
        let e = WorldDesc::load(&child).unwrap_err().to_string();
        assert!(e.contains("bases deep"), "{e}");
        // An unknown motor model names the choices.
        std::fs::write(
            &child,
            "base = \"room.toml\"\n[physics]\nmotors = \"brushless\"\n",
        )
        .unwrap();
        let e = WorldDesc::load(&child).unwrap_err().to_string();
        assert!(e.contains("webots") && e.contains("crazyflie"), "{e}");
    }
}
