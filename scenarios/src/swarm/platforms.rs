//! `[[platform]]` tables: the platforms of a scenario with several drones
//! (DESIGN.md §7, docs/COSIM.md "Several drones") — their run keys merged
//! over the scenario's `[run]`, the radios' identifiers, `--set DRONE.KEY`,
//! and the check that they match the world file's drones one to one.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim_core::config::RunConfig;

use crate::run_table::{apply_run_table, is_run_key};

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
    Run(#[from] crate::run_table::RunTableError),
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
    shared_run: &BTreeMap<String, toml::Value>,
    shared_firmware: Option<&Path>,
    base: &Path,
) -> Result<Vec<PlatformSpec>, PlatformTableError> {
    if !tables.is_empty() && shared_run.contains_key(RADIO_ID_KEY) {
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
        let firmware = match (t.firmware.as_deref(), shared_firmware) {
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
