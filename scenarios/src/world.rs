//! A run's world file, read and parsed once (DESIGN.md §19): the scenario's
//! checks, the launch (the gates' count for `summary.json`, the
//! `radio_seed` copy), the map's score and every plot are given this one
//! [`World`], never the path to read again. The world server, a process of
//! its own, reads the file it is given itself.

use std::path::{Path, PathBuf};

use world_server::world_file::WorldFileError;
use world_server::WorldDesc;

/// The world file of a run: its path, its text and the world server's own
/// reading of it (so what cosim checks and draws is what the world flies).
#[derive(Debug, Clone)]
pub struct World {
    /// The file as the scenario names it.
    pub path: PathBuf,
    /// Its text (with its `base` merged in), kept for the `radio_seed` copy, which edits it as TOML,
    /// and a sweep's fingerprint of its inputs.
    text: String,
    /// The world as the world server reads it.
    pub desc: WorldDesc,
}

/// Why `radio_seed`'s copy of the world file cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum WorldCopyError {
    #[error("{}: {source}", path.display())]
    Toml {
        path: PathBuf,
        source: toml::de::Error,
    },
    #[error("radio_seed {0}: too large")]
    SeedTooLarge(u64),
    #[error("{}: radio is not a table", path.display())]
    RadioNotATable { path: PathBuf },
    #[error(transparent)]
    Serialize(#[from] toml::ser::Error),
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl World {
    /// Reads and parses the world file: the one place a run reads it.
    pub fn load(path: &Path) -> Result<World, WorldFileError> {
        World::parse(WorldDesc::read_text(path)?, path)
    }

    /// A world from its text (`path` names it in messages).
    pub fn parse(text: String, path: &Path) -> Result<World, WorldFileError> {
        let desc = WorldDesc::parse(&text, path)?;
        Ok(World {
            path: path.to_path_buf(),
            text,
            desc,
        })
    }

    /// The file's text, as read.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The drones' names, in file order (`cf1` for a file without
    /// `[[drone]]` tables).
    pub fn drone_names(&self) -> Vec<&str> {
        self.desc.drones.iter().map(|d| d.name.as_str()).collect()
    }

    /// Where drone `name` starts (m): its `position`, or the first point
    /// of the path it is carried along.
    pub fn start_of(&self, name: &str) -> Option<[f64; 3]> {
        let d = self.desc.drones.iter().find(|d| d.name == name)?;
        Some(match &d.carried {
            Some(path) => path.points()[0].1,
            None => d.start.position.0,
        })
    }

    /// The world file the world-server of a run in `out` reads: this one,
    /// or with `radio_seed` set a copy of it in `out` (`world.toml`) whose
    /// `[radio] seed` is that value.
    pub fn file_for_run(
        &self,
        radio_seed: Option<u64>,
        out: &Path,
    ) -> Result<PathBuf, WorldCopyError> {
        let Some(seed) = radio_seed else {
            return Ok(self.path.clone());
        };
        let mut doc: toml::Table =
            toml::from_str(&self.text).map_err(|source| WorldCopyError::Toml {
                path: self.path.clone(),
                source,
            })?;
        let seed = i64::try_from(seed).map_err(|_| WorldCopyError::SeedTooLarge(seed))?;
        let radio = doc
            .entry("radio")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let toml::Value::Table(radio) = radio else {
            return Err(WorldCopyError::RadioNotATable {
                path: self.path.clone(),
            });
        };
        radio.insert("seed".into(), toml::Value::Integer(seed));
        let path = out.join("world.toml");
        let body = toml::to_string(&doc)?;
        std::fs::write(
            &path,
            format!(
                "# {} with [radio] seed = {seed} (cosim radio_seed)\n{body}",
                self.path.display()
            ),
        )
        .map_err(|source| WorldCopyError::Write {
            path: path.clone(),
            source,
        })?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(text: &str) -> World {
        World::parse(text.into(), Path::new("w.toml")).unwrap()
    }

    #[test]
    fn drones_in_file_order_with_their_start() {
        let w = world(
            r#"
            name = "two"
            [[drone]]
            name = "B"
            position = [1, 0.0, 0.015]
            [[drone]]
            name = "A"
            carried = [[0.0, 0.5, 0.25, 0.0], [12.0, 1.0, 0.0, 0.0]]
            "#,
        );
        assert_eq!(w.drone_names(), ["B", "A"]);
        assert_eq!(w.start_of("B"), Some([1.0, 0.0, 0.015]));
        assert_eq!(w.start_of("A"), Some([0.5, 0.25, 0.0]));
        assert_eq!(w.start_of("C"), None);
    }

    #[test]
    fn a_world_without_drone_tables_has_cf1() {
        let w = world("[start]\nposition = [-2.6, 0.0, 0.015]\n");
        assert_eq!(
            w.drone_names(),
            [world_server::world_file::DEFAULT_DRONE_NAME]
        );
        assert_eq!(w.start_of("cf1"), Some([-2.6, 0.0, 0.015]));
    }

    #[test]
    fn radio_seed_writes_a_copy_with_the_seed() {
        let dir = tempfile::tempdir().unwrap();
        let w = world("[start]\nposition = [0.0, 0.0, 0.015]\n");
        assert_eq!(w.file_for_run(None, dir.path()).unwrap(), w.path);
        let copy = w.file_for_run(Some(7), dir.path()).unwrap();
        let again = World::load(&copy).unwrap();
        assert_eq!(again.desc.radio.seed, 7);
        assert_eq!(again.desc.start, w.desc.start);
    }
}
