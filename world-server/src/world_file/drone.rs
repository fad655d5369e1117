//! `[[drone]]` tables (DESIGN.md §7, docs/SWARM.md §1): the drones of a
//! world, flown by a platform each or carried along a path.

use std::collections::BTreeMap;

use protocol::Radio;
use serde::Deserialize;
use toml::Spanned;

use super::{Finite, Point3, Start};

/// The name of the one drone of a world file without `[[drone]]` tables.
pub const DEFAULT_DRONE_NAME: &str = "cf1";

/// Largest |clock_ppm| accepted. The DW1000 asks for a ±20 ppm crystal
/// (DW1000 datasheet §4.1, "crystal trimming"); 1000 ppm leaves room for
/// experiments with a badly trimmed clock while keeping the stamp arithmetic
/// of `protocol::radio::dw1000_stamp` far from overflow.
pub const MAX_CLOCK_PPM: f64 = 1000.0;

/// Longest drone name; names become directory names of `cosim` outputs.
pub const MAX_NAME_LEN: usize = 64;

/// One drone of the world, resolved and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct DroneDesc {
    /// Unique name (`[A-Za-z0-9_-]`, 1–64 characters): the key of the
    /// GET_INIT_DATA claim, of traces, trajectories and outputs.
    pub name: String,
    /// Start pose (for a carried drone: its path at t = 0).
    pub start: Start,
    /// This drone's radio crystal error (ppm, f64; DESIGN.md §8).
    pub clock_ppm: f64,
    /// `Some` for a drone carried along a path instead of flown.
    pub carried: Option<CarriedPath>,
    /// The radios it carries, in file order, no duplicates.
    pub radios: Vec<Radio>,
}

impl DroneDesc {
    /// The single drone of a world file without `[[drone]]` tables.
    pub fn single(start: Start) -> DroneDesc {
        DroneDesc {
            name: DEFAULT_DRONE_NAME.to_string(),
            start,
            clock_ppm: 0.0,
            carried: None,
            radios: Radio::ALL.to_vec(),
        }
    }

    pub fn is_carried(&self) -> bool {
        self.carried.is_some()
    }
}

/// A piecewise-linear path `[[t_s, x, y, z], …]` in world time (s, the
/// warm-up included), held at its first point before it and at its last
/// point after it. Times increase strictly.
#[derive(Debug, Clone, PartialEq)]
pub struct CarriedPath {
    points: Vec<(f64, [f64; 3])>,
}

impl CarriedPath {
    /// Checks the points: at least one, times strictly increasing.
    /// On error: the index of the offending point and the reason.
    pub fn new(points: Vec<(f64, [f64; 3])>) -> Result<CarriedPath, (usize, String)> {
        if points.is_empty() {
            return Err((0, "a carried path needs at least one point".into()));
        }
        for (i, w) in points.windows(2).enumerate() {
            if w[1].0 <= w[0].0 {
                return Err((
                    i + 1,
                    format!("times must increase: {} s comes after {} s", w[1].0, w[0].0),
                ));
            }
        }
        Ok(CarriedPath { points })
    }

    pub fn points(&self) -> &[(f64, [f64; 3])] {
        &self.points
    }

    /// Position at world time `t_s` (s).
    pub fn at(&self, t_s: f64) -> [f64; 3] {
        let p = &self.points;
        let (first, last) = (p[0], p[p.len() - 1]);
        if t_s <= first.0 {
            return first.1;
        }
        if t_s >= last.0 {
            return last.1;
        }
        // First point strictly after t_s: 1 ≤ i ≤ len − 1 here.
        let i = p.partition_point(|q| q.0 <= t_s);
        let ((t0, a), (t1, b)) = (p[i - 1], p[i]);
        let f = (t_s - t0) / (t1 - t0);
        [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * f)
    }
}

/// A `[[drone]]` table as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDrone {
    name: Spanned<String>,
    #[serde(default)]
    position: Option<Spanned<Point3>>,
    #[serde(default)]
    yaw: Finite,
    #[serde(default)]
    clock_ppm: Option<Spanned<Finite>>,
    #[serde(default)]
    carried: Option<Spanned<Vec<Spanned<[Finite; 4]>>>>,
    #[serde(default)]
    radios: Option<Spanned<Vec<Radio>>>,
}

/// A semantic error: byte offset in the file, field, message.
pub(super) type Located = (usize, String, String);

/// Checks the `[[drone]]` tables (`tables` with the span of each) and
/// resolves them.
pub(super) fn resolve(tables: Vec<Spanned<RawDrone>>) -> Result<Vec<DroneDesc>, Located> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = Vec::with_capacity(tables.len());
    for (i, table) in tables.into_iter().enumerate() {
        let here = format!("drone[{}]", i + 1);
        let table_at = table.span().start;
        let raw = table.into_inner();
        let name_at = raw.name.span().start;
        let name = raw.name.into_inner();
        check_name(&name).map_err(|m| (name_at, format!("{here}.name"), m))?;
        if let Some(first) = seen.insert(name.clone(), i + 1) {
            return Err((
                name_at,
                format!("{here}.name"),
                format!("drone name {name:?} is already used by drone[{first}]"),
            ));
        }
        let clock_ppm = match raw.clock_ppm {
            Some(c) => {
                let v = c.get_ref().0;
                if v.abs() > MAX_CLOCK_PPM {
                    return Err((
                        c.span().start,
                        format!("{here}.clock_ppm"),
                        format!("{v} is outside ±{MAX_CLOCK_PPM} ppm"),
                    ));
                }
                v
            }
            None => 0.0,
        };
        let radios = match raw.radios {
            Some(r) => {
                let at = r.span().start;
                let list = r.into_inner();
                for (k, radio) in list.iter().enumerate() {
                    if list[..k].contains(radio) {
                        return Err((
                            at,
                            format!("{here}.radios"),
                            format!("radio \"{radio}\" is listed twice"),
                        ));
                    }
                }
                list
            }
            None => Radio::ALL.to_vec(),
        };
        let carried = match raw.carried {
            Some(c) => {
                let at = c.span().start;
                let spanned: Vec<Spanned<[Finite; 4]>> = c.into_inner();
                let starts: Vec<usize> = spanned.iter().map(|p| p.span().start).collect();
                let points = spanned
                    .into_iter()
                    .map(|p| {
                        let [t, x, y, z] = p.into_inner();
                        (t.0, [x.0, y.0, z.0])
                    })
                    .collect();
                let path = CarriedPath::new(points).map_err(|(k, m)| {
                    (
                        starts.get(k).copied().unwrap_or(at),
                        format!("{here}.carried[{}]", k + 1),
                        m,
                    )
                })?;
                Some(path)
            }
            None => None,
        };
        let yaw = raw.yaw;
        let position = match (&carried, raw.position) {
            (Some(path), Some(p)) => {
                let from_path = path.at(0.0);
                if p.get_ref().0 != from_path {
                    return Err((
                        p.span().start,
                        format!("{here}.position"),
                        format!(
                            "{:?} differs from the carried path at 0 s, {from_path:?} \
                             (a carried drone starts on its path: leave `position` out)",
                            p.get_ref().0
                        ),
                    ));
                }
                from_path
            }
            (Some(path), None) => path.at(0.0),
            (None, Some(p)) => p.into_inner().0,
            (None, None) => {
                return Err((
                    table_at,
                    here,
                    "missing field `position` (a flown drone needs its start position)".into(),
                ))
            }
        };
        out.push(DroneDesc {
            name,
            start: Start {
                position: Point3(position),
                yaw,
            },
            clock_ppm,
            carried,
            radios,
        });
    }
    Ok(out)
}

fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty() || name.len() > MAX_NAME_LEN {
        return Err(format!(
            "a drone name has 1 to {MAX_NAME_LEN} characters, not {}",
            name.len()
        ));
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
    {
        return Err(format!(
            "{name:?}: a drone name is made of A-Z, a-z, 0-9, '_' and '-' \
             (it names output directories), not {c:?}"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_held_before_and_after_and_linear_between() {
        let p = CarriedPath::new(vec![
            (1.0, [0.0, 0.0, 0.0]),
            (3.0, [2.0, -4.0, 1.0]),
            (4.0, [2.0, -4.0, 3.0]),
        ])
        .unwrap();
        assert_eq!(p.at(0.0), [0.0, 0.0, 0.0]);
        assert_eq!(p.at(1.0), [0.0, 0.0, 0.0]);
        assert_eq!(p.at(2.0), [1.0, -2.0, 0.5]);
        assert_eq!(p.at(3.0), [2.0, -4.0, 1.0]);
        assert_eq!(p.at(3.5), [2.0, -4.0, 2.0]);
        assert_eq!(p.at(9.0), [2.0, -4.0, 3.0]);
    }

    #[test]
    fn a_path_needs_points_in_increasing_time() {
        assert!(CarriedPath::new(vec![]).is_err());
        let e = CarriedPath::new(vec![(0.0, [0.0; 3]), (2.0, [0.0; 3]), (2.0, [1.0; 3])]);
        assert_eq!(e.unwrap_err().0, 2);
        assert!(CarriedPath::new(vec![(5.0, [1.0; 3])]).is_ok());
    }

    #[test]
    fn names_are_checked() {
        assert!(check_name("cf1").is_ok());
        assert!(check_name("anchor-3_b").is_ok());
        assert!(check_name("").is_err());
        assert!(check_name("a b").is_err());
        assert!(check_name("../x").is_err());
        assert!(check_name(&"x".repeat(65)).is_err());
    }
}
