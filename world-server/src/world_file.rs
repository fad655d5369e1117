//! World files (TOML, `scenarios/worlds/*.toml`): start pose, ground, sky,
//! gates and boxes (DESIGN.md §5).
//!
//! A malformed file is reported with the file name, the line and column and
//! the field (`gate[3].inner`), never with a panic.

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// A world as read from a file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldDesc {
    /// Free-form name, shown in logs.
    #[serde(default)]
    pub name: String,
    pub start: Start,
    #[serde(default)]
    pub ground: Ground,
    #[serde(default)]
    pub sky: Sky,
    #[serde(default)]
    pub physics: PhysicsOptions,
    #[serde(default, rename = "gate")]
    pub gates: Vec<Gate>,
    #[serde(default, rename = "box")]
    pub boxes: Vec<BoxDesc>,
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
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PhysicsOptions {
    /// Linear damping of the drone body (1/s), rapier's model.
    #[serde(default)]
    pub linear_damping: NonNegative,
    /// Angular damping of the drone body (1/s).
    #[serde(default)]
    pub angular_damping: NonNegative,
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
    #[error("cannot read world file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
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
    /// Reads and checks a world file.
    pub fn load(path: &Path) -> Result<WorldDesc, WorldFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| WorldFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses world-file text; `path` is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<WorldDesc, WorldFileError> {
        match toml::from_str::<WorldDesc>(text) {
            Ok(desc) => Ok(desc),
            Err(e) => {
                let offset = e.span().map(|s| s.start).unwrap_or(0);
                let (line, column) = line_column(text, offset);
                Err(WorldFileError::Invalid {
                    path: path.to_path_buf(),
                    line,
                    column,
                    field: field_at(text, offset),
                    message: e.message().trim().to_string(),
                })
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
}
