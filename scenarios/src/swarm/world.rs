//! The drones of a world file (DESIGN.md §7, docs/SWARM.md §1), read by the
//! launcher before anything starts: their names (to check the
//! `[[platform]]` tables against them) and where they start (for plots and
//! the true distances of the report). The world server reads the rest.

use std::path::Path;

/// The drone of a world file without `[[drone]]` tables (DESIGN.md §7).
pub const SINGLE_DRONE: &str = "cf1";

/// One `[[drone]]` table, as far as the launcher needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldDrone {
    pub name: String,
    /// Start position (m): `position`, or the first point of `carried`.
    pub start: [f64; 3],
    /// Whether the drone is carried along a path instead of flown.
    pub carried: bool,
}

/// The drones of a world file, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldDrones(pub Vec<WorldDrone>);

/// Why the drones of a world file cannot be read (`what` names the table
/// and key, `drone[2].position`).
#[derive(Debug, thiserror::Error)]
pub enum WorldDronesError {
    #[error("cannot read the world file: {0}")]
    Read(#[from] std::io::Error),
    /// Malformed TOML (the parser's message on one line).
    #[error("{0}")]
    Toml(String),
    #[error("no [[drone]] tables and no [start] position")]
    NoStart,
    #[error("drone: expected [[drone]] tables")]
    NotTables,
    #[error("drone: no [[drone]] tables")]
    NoDrones,
    #[error("{what}: no name")]
    NoName { what: String },
    #[error("{what}: no position")]
    NoPosition { what: String },
    #[error("{what}: expected [x, y, z]")]
    NotAPoint { what: String },
    #[error("{what}: expected numbers")]
    NotNumbers { what: String },
    #[error("{what}.carried: expected [t, x, y, z] points")]
    NotCarriedPoints { what: String },
}

fn point(v: &toml::Value, what: &str) -> Result<[f64; 3], WorldDronesError> {
    let what = || what.to_string();
    let a = v
        .as_array()
        .filter(|a| a.len() >= 3)
        .ok_or_else(|| WorldDronesError::NotAPoint { what: what() })?;
    let n = |i: usize| -> Result<f64, WorldDronesError> {
        a[i].as_float()
            .or_else(|| a[i].as_integer().map(|i| i as f64))
            .ok_or_else(|| WorldDronesError::NotNumbers { what: what() })
    };
    Ok([n(0)?, n(1)?, n(2)?])
}

impl WorldDrones {
    /// Reads the drones of a world file (a one-line error if it cannot).
    pub fn load(path: &Path) -> Result<WorldDrones, WorldDronesError> {
        let text = std::fs::read_to_string(path)?;
        Self::parse(&text)
    }

    pub fn parse(text: &str) -> Result<WorldDrones, WorldDronesError> {
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            WorldDronesError::Toml(e.to_string().trim_end().replace('\n', " "))
        })?;
        let Some(drones) = table.get("drone") else {
            let start = table
                .get("start")
                .and_then(|s| s.get("position"))
                .ok_or(WorldDronesError::NoStart)?;
            return Ok(WorldDrones(vec![WorldDrone {
                name: SINGLE_DRONE.into(),
                start: point(start, "start.position")?,
                carried: false,
            }]));
        };
        let drones = drones.as_array().ok_or(WorldDronesError::NotTables)?;
        let mut out = Vec::new();
        for (i, d) in drones.iter().enumerate() {
            let what = format!("drone[{}]", i + 1);
            let name = d
                .get("name")
                .and_then(toml::Value::as_str)
                .ok_or_else(|| WorldDronesError::NoName { what: what.clone() })?;
            let carried = d.get("carried").and_then(toml::Value::as_array);
            let start = match carried.and_then(|c| c.first()) {
                Some(p) => {
                    let a = p
                        .as_array()
                        .filter(|a| a.len() == 4)
                        .ok_or_else(|| WorldDronesError::NotCarriedPoints { what: what.clone() })?;
                    let rest = toml::Value::Array(a[1..].to_vec());
                    point(&rest, &format!("{what}.carried"))?
                }
                None => point(
                    d.get("position")
                        .ok_or_else(|| WorldDronesError::NoPosition { what: what.clone() })?,
                    &format!("{what}.position"),
                )?,
            };
            out.push(WorldDrone {
                name: name.to_string(),
                start,
                carried: carried.is_some(),
            });
        }
        if out.is_empty() {
            return Err(WorldDronesError::NoDrones);
        }
        Ok(WorldDrones(out))
    }

    pub fn names(&self) -> Vec<&str> {
        self.0.iter().map(|d| d.name.as_str()).collect()
    }

    pub fn get(&self, name: &str) -> Option<&WorldDrone> {
        self.0.iter().find(|d| d.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drones_in_file_order_with_their_start() {
        let w = WorldDrones::parse(
            r#"
            name = "two"
            [[drone]]
            name = "B"
            position = [1, 0.0, 0.015]
            [[drone]]
            name = "A"
            position = [0.0, 0.0, 0.015]
            carried = [[0.0, 0.5, 0.25, 0.0], [12.0, 1.0, 0.0, 0.0]]
            "#,
        )
        .unwrap();
        assert_eq!(w.names(), ["B", "A"]);
        assert_eq!(w.0[0].start, [1.0, 0.0, 0.015]);
        assert_eq!(w.get("A").unwrap().start, [0.5, 0.25, 0.0]);
        assert!(w.get("A").unwrap().carried && !w.0[0].carried);
    }

    #[test]
    fn a_world_without_drone_tables_has_cf1() {
        let w = WorldDrones::parse("[start]\nposition = [-2.6, 0.0, 0.015]\n").unwrap();
        assert_eq!(w.names(), [SINGLE_DRONE]);
        assert!(matches!(
            WorldDrones::parse("name = 'x'"),
            Err(WorldDronesError::NoStart)
        ));
        let e = WorldDrones::parse("[[drone]]\nposition = [0,0,0]\n").unwrap_err();
        assert_eq!(e.to_string(), "drone[1]: no name");
        let e = WorldDrones::parse("[[drone]]\nname = 'A'\nposition = [0, 'x', 0]\n").unwrap_err();
        assert_eq!(e.to_string(), "drone[1].position: expected numbers");
    }
}
