//! `[[platform]]` tables: the platforms of a scenario with several drones
//! (DESIGN.md §7, docs/COSIM.md "Several drones") — their run keys merged
//! over the scenario's `[run]`, the radios' identifiers, `--set DRONE.KEY`,
//! and the check that they match the world file's drones one to one.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim_core::config::{run_key_names, RunConfig};

use crate::scenario::{apply_run_table, is_run_key, Scenario, ScenarioError, ScenarioFile};

/// One `[[platform]]` table: a sim-core flying one drone of the world file
/// (DESIGN.md §7, docs/SWARM.md §5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlatformTable {
    /// The drone it claims: a `name` of the world file's `[[drone]]` tables.
    pub drone: String,
    /// Firmware ELF (relative to the scenario file; default: the scenario's
    /// `firmware`).
    #[serde(default)]
    pub firmware: Option<PathBuf>,
    /// This drone's targets, for the top-view plots.
    #[serde(default)]
    pub targets: Vec<[f64; 3]>,
    /// Run keys for this platform, over the scenario's `[run]`.
    #[serde(default)]
    pub run: BTreeMap<String, toml::Value>,
}

/// One platform of a scenario with several drones, resolved and checked.
#[derive(Debug, Clone)]
pub struct PlatformSpec {
    /// The world file's drone this platform flies (`sim-core --drone`).
    pub drone: String,
    pub firmware: PathBuf,
    /// The scenario's `[run]`, then this platform's `run` table, then the
    /// `--set` overrides (written to `<drone>/run.toml`).
    pub run: RunConfig,
    pub targets: Vec<[f64; 3]>,
}

/// The run key the radios' identifier comes from (docs/SWARM.md §4.3: EUI).
pub const RADIO_ID_KEY: &str = "radio_id";

/// Why the `[[platform]]` tables cannot be resolved (`what` names the
/// table: `platform[2] (drone "B")`).
#[derive(Debug, thiserror::Error)]
pub enum PlatformTableError {
    #[error(
        "run.{RADIO_ID_KEY}: the radios' identifiers are per platform \
         (set them in [platform.run], or leave them to cosim: 1, 2, 3, ...)"
    )]
    SharedRadioId,
    #[error("platform[{0}]: drone must not be empty")]
    EmptyDrone(usize),
    #[error("{what}: a drone name cannot contain '.', '=', '/', '\\' or surrounding spaces")]
    BadDroneName { what: String },
    #[error("{what}: a second platform for the same drone")]
    SecondPlatform { what: String },
    #[error("{what}: no firmware (give `firmware` in the table or in the scenario)")]
    NoFirmware { what: String },
    #[error(transparent)]
    Run(#[from] crate::scenario::RunTableError),
    #[error("{what}: {RADIO_ID_KEY}: {source}")]
    RadioId {
        what: String,
        source: sim_core::config::ConfigError,
    },
}

/// The `[[platform]]` tables resolved: each platform's run configuration is
/// the scenario's `run` with the platform's own `run` table over it; the
/// radios' identifiers are 1, 2, 3, … in table order unless a platform sets
/// its own (applied only when sim-core knows the key).
pub(crate) fn resolve_platforms(
    tables: &[PlatformTable],
    run: &RunConfig,
    file: &ScenarioFile,
    base: &Path,
) -> Result<Vec<PlatformSpec>, PlatformTableError> {
    if !tables.is_empty() && file.run.contains_key(RADIO_ID_KEY) {
        return Err(PlatformTableError::SharedRadioId);
    }
    let mut out: Vec<PlatformSpec> = Vec::new();
    for (i, t) in tables.iter().enumerate() {
        let what = format!("platform[{}] (drone {:?})", i + 1, t.drone);
        if t.drone.trim().is_empty() {
            return Err(PlatformTableError::EmptyDrone(i + 1));
        }
        // `A.KEY=VALUE` names a platform by its drone (`--set`, sweeps).
        // Its outputs go to a directory named after it.
        if t.drone.contains(['.', '=', '/', '\\']) || t.drone.trim() != t.drone {
            return Err(PlatformTableError::BadDroneName { what });
        }
        if out.iter().any(|p| p.drone == t.drone) {
            return Err(PlatformTableError::SecondPlatform { what });
        }
        let firmware = match (&t.firmware, &file.firmware) {
            (Some(f), _) | (None, Some(f)) => base.join(f),
            (None, None) => {
                return Err(PlatformTableError::NoFirmware { what });
            }
        };
        let mut prun = run.clone();
        apply_run_table(&mut prun, &t.run, base, &format!("{what} run"))?;
        if is_run_key(RADIO_ID_KEY) && !t.run.contains_key(RADIO_ID_KEY) {
            prun.set(RADIO_ID_KEY, &(i + 1).to_string())
                .map_err(|source| PlatformTableError::RadioId {
                    what: what.clone(),
                    source,
                })?;
        }
        out.push(PlatformSpec {
            drone: t.drone.clone(),
            firmware,
            run: prun,
            targets: t.targets.clone(),
        });
    }
    Ok(out)
}

impl Scenario {
    /// `DRONE.KEY` (or `DRONE.run.KEY`) of a scenario with platforms: the
    /// platform's index and the key. None for any other key.
    pub fn platform_key<'k>(&self, key: &'k str) -> Option<(usize, &'k str)> {
        let key = key.strip_prefix("run.").unwrap_or(key);
        let (drone, k) = key.split_once('.')?;
        let k = k.strip_prefix("run.").unwrap_or(k);
        let i = self.platforms.iter().position(|p| p.drone == drone)?;
        Some((i, k))
    }

    pub(crate) fn set_platform_key(
        &mut self,
        i: usize,
        key: &str,
        value: &str,
    ) -> Result<(), ScenarioError> {
        let drone = self.platforms[i].drone.clone();
        let p = &mut self.platforms[i];
        if key == "firmware" {
            p.firmware = PathBuf::from(value);
            return Ok(());
        }
        if !is_run_key(key) {
            return Err(ScenarioError::BadValue {
                key: format!("{drone}.{key}"),
                value: value.to_string(),
                reason: format!(
                    "a platform takes `firmware` and the run keys ({})",
                    run_key_names()
                ),
            });
        }
        p.run.set(key, value).map_err(|e| ScenarioError::BadValue {
            key: format!("{drone}.{key}"),
            value: value.to_string(),
            reason: e.to_string(),
        })
    }

    /// Every drone of the world file has exactly one platform and every
    /// platform names a drone of the world file: otherwise the world would
    /// wait for a claim that never comes (docs/SWARM.md §2).
    pub(crate) fn check_drones(&self) -> Result<(), ScenarioError> {
        let world = crate::swarm::world::WorldDrones::load(&self.world).map_err(|e| {
            ScenarioError::Invalid {
                path: self.world.clone(),
                message: e.to_string(),
            }
        })?;
        let names = world.names();
        let invalid = |message: String| ScenarioError::Invalid {
            path: self.path.clone(),
            message,
        };
        for p in &self.platforms {
            if !names.contains(&p.drone.as_str()) {
                return Err(invalid(format!(
                    "platform for drone {:?}: the world {} has no such drone (its drones: {})",
                    p.drone,
                    self.world.display(),
                    names.join(", ")
                )));
            }
        }
        let unclaimed: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| self.platforms.iter().all(|p| p.drone != *n))
            .collect();
        if !unclaimed.is_empty() {
            return Err(invalid(format!(
                "the world {} has drones without a [[platform]]: {}",
                self.world.display(),
                unclaimed.join(", ")
            )));
        }
        Ok(())
    }

    /// A short label of the overrides (`battery=ufx250 timestep_ms=16`).
    pub fn overrides_label(&self) -> String {
        self.overrides
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Scenario, ScenarioError> {
        Scenario::parse(text, Path::new("/x/scenarios/s.toml"))
    }

    const MIN: &str = r#"
        world = "worlds/empty.toml"
        firmware = "fw.elf"
        [sweep]
        timestep_ms = [16, 32]
    "#;

    const SWARM: &str = r#"
        world = "worlds/two.toml"
        firmware = "fw.elf"
        timestep_ms = 4
        [run]
        battery = "ufx250"
        [[platform]]
        drone = "A"
        targets = [[0.0, 1.0, 1.0]]
        [platform.run]
        power_model = "stolaroff"
        [[platform]]
        drone = "B"
        firmware = "other.elf"
    "#;

    #[test]
    fn platforms_merge_their_run_over_the_scenario() {
        let s = parse(SWARM).unwrap();
        assert_eq!(s.platforms.len(), 2);
        let (a, b) = (&s.platforms[0], &s.platforms[1]);
        assert_eq!((a.drone.as_str(), b.drone.as_str()), ("A", "B"));
        assert_eq!(a.firmware, Path::new("/x/scenarios/fw.elf"));
        assert_eq!(b.firmware, Path::new("/x/scenarios/other.elf"));
        assert_eq!(a.run.get("power_model").unwrap(), "stolaroff");
        assert_eq!(b.run.get("power_model").unwrap(), "empirical");
        assert_eq!(a.run.get("battery").unwrap(), "ufx250");
        assert_eq!(b.run.get("battery").unwrap(), "ufx250");
        assert_eq!(a.targets, [[0.0, 1.0, 1.0]]);
        if is_run_key(RADIO_ID_KEY) {
            assert_eq!(a.run.get(RADIO_ID_KEY).unwrap(), "1");
            assert_eq!(b.run.get(RADIO_ID_KEY).unwrap(), "2");
        }
        // A scenario without [[platform]] has none, and a platform file
        // is still a string.
        let one = parse(&format!("platform = \"p.json\"\n{MIN}")).unwrap();
        assert!(one.platforms.is_empty());
        assert_eq!(
            one.run.platform.as_deref(),
            Some(Path::new("/x/scenarios/p.json"))
        );
    }

    #[test]
    fn set_reaches_every_platform_or_one() {
        let mut s = parse(SWARM).unwrap();
        s.set("battery=lipol350").unwrap();
        assert!(s
            .platforms
            .iter()
            .all(|p| p.run.get("battery").unwrap() == "lipol350"));
        s.set("B.battery=cyclone300").unwrap();
        s.set("A.run.power_model=dandrea").unwrap();
        s.set("A.firmware=/tmp/a.elf").unwrap();
        assert_eq!(s.platforms[0].run.get("battery").unwrap(), "lipol350");
        assert_eq!(s.platforms[1].run.get("battery").unwrap(), "cyclone300");
        assert_eq!(s.platforms[0].run.get("power_model").unwrap(), "dandrea");
        assert_eq!(s.platforms[0].firmware, Path::new("/tmp/a.elf"));
        s.set("firmware=/tmp/all.elf").unwrap();
        assert!(s
            .platforms
            .iter()
            .all(|p| p.firmware == Path::new("/tmp/all.elf")));
        for bad in [
            "A.battery=nine",
            "A.timestep_ms=8",
            "C.battery=ufx250",
            "A.zzz=1",
        ] {
            assert!(s.set(bad).is_err(), "{bad} accepted");
        }
        assert!(s.overrides_label().contains("B.battery=cyclone300"));
    }

    #[test]
    fn every_platforms_sync_is_checked_against_the_timestep() {
        let mut s = parse(SWARM).unwrap();
        s.set("sync=bounded").unwrap();
        s.set("timestep_ms=2").unwrap();
        s.check_timestep().unwrap();
        // One platform back to the thesis's bookkeeping: refused.
        s.set("B.sync=thesis").unwrap();
        let e = s.check_timestep().unwrap_err().to_string();
        assert!(e.contains("too small for the thesis"), "{e}");
    }

    #[test]
    fn a_swarms_scenario_toml_reads_back() {
        let s = parse(SWARM).unwrap();
        let text = s.resolved_toml();
        let back: crate::scenario::ResolvedScenario = toml::from_str(&text).unwrap();
        assert_eq!(back, s.resolved());
        assert_eq!(back.platform.len(), 2);
        assert_eq!(back.platform[0].targets, [[0.0, 1.0, 1.0]]);
        assert!(back.firmware.is_none() && back.targets.is_none());
    }

    #[test]
    fn bad_platform_tables_are_refused() {
        let e = parse(&SWARM.replace("drone = \"B\"", "drone = \"A\""))
            .unwrap_err()
            .to_string();
        assert!(e.contains("second platform"), "{e}");
        let e = parse(&SWARM.replace("drone = \"B\"", "drone = \"B\"\nfoo = 1"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("foo"), "{e}");
        let e = parse(&SWARM.replace("firmware = \"fw.elf\"\n", ""))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no firmware") && e.contains("\"A\""), "{e}");
        let e = parse(&SWARM.replace("drone = \"B\"", "drone = \"B.1\""))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot contain"), "{e}");
        let e = parse(&SWARM.replace("power_model = \"stolaroff\"", "power_model = \"x\""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("platform[1]") && e.contains("power_model"),
            "{e}"
        );
    }

    #[test]
    fn platforms_must_match_the_worlds_drones() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("worlds")).unwrap();
        for f in ["fw.elf", "other.elf"] {
            std::fs::write(d.join(f), b"\x7fELF").unwrap();
        }
        let world = |names: &[&str]| {
            let mut w = String::new();
            for (i, n) in names.iter().enumerate() {
                w += &format!("[[drone]]\nname = \"{n}\"\nposition = [{i}.0, 0.0, 0.015]\n");
            }
            std::fs::write(d.join("worlds/two.toml"), w).unwrap();
        };
        let s = Scenario::parse(SWARM, &d.join("s.toml")).unwrap();
        world(&["A", "B"]);
        s.check_files().unwrap();
        world(&["A", "C"]);
        let e = s.check_files().unwrap_err().to_string();
        assert!(
            e.contains("\"B\"") && e.contains("no such drone") && e.contains("A, C"),
            "{e}"
        );
        world(&["A", "B", "C"]);
        let e = s.check_files().unwrap_err().to_string();
        assert!(e.contains("without a [[platform]]: C"), "{e}");
        world(&["A", "B"]);
        std::fs::remove_file(d.join("other.elf")).unwrap();
        let e = s.check_files().unwrap_err().to_string();
        assert!(e.contains("drone \"B\"") && e.contains("other.elf"), "{e}");
    }
}
