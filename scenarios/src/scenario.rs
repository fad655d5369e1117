//! Scenario files (`scenarios/*.toml`): what one experiment of the thesis
//! needs to run — world file, basicTimeStep, firmware, platform file, run
//! configuration — plus the targets to draw and the default sweep.
//!
//! Paths in a file are relative to the file's directory; paths given with
//! `--set` are relative to the working directory (where the user typed them).
//! Everything is checked before a process is started: a missing file, an
//! unknown key or a bad value is a one-line error.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use protocol::{TimestepError, TimestepMs};
use serde::{Deserialize, Serialize};
use sim_core::config::{run_key_names, RunConfig};
use sim_core::peripherals::stm32::crtp::CrtpSpec;

use crate::world::World;

pub(crate) use crate::run_table::{apply_run_table, is_run_key, value_text};
pub use crate::run_table::{NotAScalar, RunTableError, RunTableReason};
use crate::swarm::platforms::resolve_platforms;
pub use crate::swarm::platforms::{PlatformSpec, PlatformTable, RADIO_ID_KEY};
pub use crate::swarm::positioning_spec::PositioningSpec;

/// Why a scenario cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("cannot read scenario {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error("--set {0:?}: expected KEY=VALUE")]
    BadSet(String),
    #[error("--set {key}={value}: {reason}")]
    BadValue {
        key: String,
        value: String,
        reason: String,
    },
    #[error("unknown key {key:?} (scenario keys: {scenario}; run keys: {run})")]
    UnknownKey {
        key: String,
        scenario: String,
        run: String,
    },
    /// The world file our world server would refuse (its own message).
    #[error(transparent)]
    World(#[from] world_server::world_file::WorldFileError),
    #[error("{what} {path} does not exist")]
    Missing { what: &'static str, path: PathBuf },
    #[error("scenario {0} does not exist; `cosim list` lists the scenarios")]
    UnknownScenario(PathBuf),
    #[error("platform for drone {drone:?}: {what} {path} does not exist")]
    PlatformMissing {
        drone: String,
        what: &'static str,
        path: PathBuf,
    },
}

/// A scenario file as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// One line shown by `cosim run` and in reports.
    #[serde(default)]
    pub description: String,
    /// World file (TOML, `scenarios/worlds/`).
    pub world: PathBuf,
    /// Firmware ELF the platform runs (with `[[platform]]` tables: the
    /// default of the platforms that name none).
    #[serde(default)]
    pub firmware: Option<PathBuf>,
    /// basicTimeStep in ms (DESIGN.md §3: 8, 16, 24, 32 …).
    #[serde(default = "default_timestep")]
    pub timestep_ms: u64,
    /// Physics steps per basicTimeStep.
    #[serde(default = "default_substeps")]
    pub substeps: u32,
    /// A string: the platform file (MESSY JSON; absent = the embedded
    /// Crazyflie). An array of tables (`[[platform]]`): the platforms of a
    /// scenario with several drones ([`PlatformTable`]). TOML has one key
    /// for both; with `[[platform]]` a platform file is the run key
    /// `platform` (in `[run]` or a platform's `run` table).
    #[serde(default)]
    pub platform: Option<toml::Value>,
    /// Gives up after this many simulated seconds (a run that never ends).
    #[serde(default)]
    pub max_time_s: Option<f64>,
    /// `array` (the thesis's) or `base64`.
    #[serde(default = "default_encoding")]
    pub image_encoding: String,
    /// Write `run.mcap` (docs/FOXGLOVE.md).
    #[serde(default)]
    pub mcap: Option<bool>,
    /// Every Nth camera frame into `run.mcap` (0: none).
    #[serde(default)]
    pub mcap_image_every: Option<u64>,
    /// Every Nth 1 ms row of `power.csv` into `run.mcap` (0: none).
    #[serde(default)]
    pub mcap_power_every: Option<u64>,
    /// The firmware's targets, for the top-view plot (the firmware holds
    /// its own copy: the platform does not learn them from the scenario).
    #[serde(default)]
    pub targets: Vec<[f64; 3]>,
    /// Run-configuration keys (`sim-core --set`, see `RUN_KEYS`).
    #[serde(default)]
    pub run: BTreeMap<String, toml::Value>,
    /// Default `cosim sweep` parameters: key → values.
    #[serde(default)]
    pub sweep: BTreeMap<String, Vec<toml::Value>>,
    /// Seed 003's positioning report (tables of §7.1, whose estimates).
    #[serde(default)]
    pub positioning: Option<PositioningSpec>,
}

fn default_timestep() -> u64 {
    32
}
fn default_substeps() -> u32 {
    1
}
fn default_encoding() -> String {
    "array".into()
}

/// The firmware of a drone flown over CRTP (`sim-core/firmware/src/crtp/`).
pub const CRTP_FIRMWARE: &str = "crtp_host.elf";
/// The firmwares that serve the CRTP link themselves (`crtp=` keeps them):
/// the host and the host with seed 004's radar (docs/LAB.md, guide 3).
pub const CRTP_FIRMWARES: [&str; 2] = [CRTP_FIRMWARE, "crtp_radar.elf"];

/// Keys `--set` accepts besides the run keys.
pub const SCENARIO_KEYS: [(&str, &str); 12] = [
    ("world", "world file (TOML)"),
    ("firmware", "firmware ELF"),
    ("timestep_ms", "basicTimeStep in ms"),
    ("substeps", "physics steps per basicTimeStep"),
    ("platform", "platform file (MESSY JSON)"),
    ("max_time_s", "give up after this many simulated seconds"),
    ("image_encoding", "array | base64 | shm"),
    (
        "busy_poll_us",
        "µs sim-core and world-server poll for the peer's frame before sleeping (0: off; same results)",
    ),
    (
        "radio_seed",
        "the world's [radio] seed for this run (a copy of the world file in the run's directory)",
    ),
    (
        "mcap",
        "write run.mcap for Foxglove (true | false; `--no-mcap` sets false; docs/FOXGLOVE.md)",
    ),
    (
        "mcap_image_every",
        "keep every Nth camera frame in run.mcap (0: none; default 30)",
    ),
    (
        "mcap_power_every",
        "keep every Nth 1 ms power/battery row (and the last) in run.mcap (0: none; default 10)",
    ),
];

/// `scenario.toml` in a run's output directory: the scenario as it ran,
/// paths absolute, in the scenario file's own keys, written and read with
/// serde (strings escaped as TOML escapes them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResolvedScenario {
    pub description: String,
    pub world: String,
    /// A single drone's firmware (a swarm's are its platforms').
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub firmware: Option<String>,
    pub timestep_ms: u64,
    pub substeps: u32,
    pub image_encoding: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_time_s: Option<f64>,
    /// A single drone's targets (a swarm's are its platforms').
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets: Option<Vec<[f64; 3]>>,
    /// A swarm's platforms, in `[[platform]]` order; each one's run keys
    /// are in `DRONE/run.toml`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub platform: Vec<ResolvedPlatform>,
}

/// One platform of [`ResolvedScenario`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResolvedPlatform {
    pub drone: String,
    pub firmware: String,
    pub targets: Vec<[f64; 3]>,
}

impl Scenario {
    /// The scenario as it runs, paths absolute (`scenario.toml`).
    pub fn resolved(&self) -> ResolvedScenario {
        let abs = crate::outputs::abs;
        let swarm = !self.platforms.is_empty();
        ResolvedScenario {
            description: self.description.clone(),
            world: abs(&self.world),
            firmware: (!swarm).then(|| abs(&self.firmware)),
            timestep_ms: self.timestep_ms.get(),
            substeps: self.substeps,
            image_encoding: self.image_encoding.as_str().to_string(),
            max_time_s: self.max_time_s,
            targets: (!swarm).then(|| self.targets.clone()),
            platform: self
                .platforms
                .iter()
                .map(|p| ResolvedPlatform {
                    drone: p.drone.clone(),
                    firmware: abs(&p.firmware),
                    targets: p.targets.clone(),
                })
                .collect(),
        }
    }

    /// `scenario.toml`'s text: a comment naming the scenario and its
    /// overrides, then [`Scenario::resolved`].
    pub fn resolved_toml(&self) -> String {
        let resolved = self.resolved();
        let body = toml::to_string(&resolved).expect("strings, numbers and arrays serialize");
        let comment = format!(
            "# Resolved from {} {}\n",
            self.path.display(),
            self.overrides_label()
        );
        // A comment is one line: an override's value may hold a line break.
        let mut text = comment.trim_end().replace(['\n', '\r'], " ") + "\n";
        if !resolved.platform.is_empty() {
            text += "# Each platform's run keys: DRONE/run.toml\n";
        }
        text + &body
    }
}

/// A scenario ready to run: paths resolved, every value checked.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Name (the file stem, `thesis-race`).
    pub name: String,
    /// Where it was read from.
    pub path: PathBuf,
    pub description: String,
    pub world: PathBuf,
    pub firmware: PathBuf,
    pub timestep_ms: TimestepMs,
    pub substeps: u32,
    pub max_time_s: Option<f64>,
    /// Overrides the world file's `[radio] seed` (one channel draw per
    /// trial of a sweep, e.g. seed 004's radar trials, docs/SWARM.md "Radar").
    pub radio_seed: Option<u64>,
    pub image_encoding: protocol::ImageEncoding,
    /// `--busy-poll-us` of sim-core and our world-server: a host setting
    /// (how the processes wait for each other), never a simulated one.
    pub busy_poll_us: u64,
    /// Write `run.mcap` (docs/FOXGLOVE.md; a host-side output: no
    /// simulated result depends on it).
    pub mcap: bool,
    /// Every Nth camera frame served goes into `run.mcap` (0: none).
    pub mcap_image_every: u64,
    /// Every Nth 1 ms row of `power.csv` (and the last) goes into
    /// `run.mcap` (0: none).
    pub mcap_power_every: u64,
    pub targets: Vec<[f64; 3]>,
    /// The run configuration sim-core gets (written to `run.toml`).
    pub run: RunConfig,
    /// The `--set` overrides applied, in order (for reports).
    pub overrides: Vec<(String, String)>,
    /// Default sweep parameters, values in text form.
    pub sweep: Vec<(String, Vec<String>)>,
    /// `[[platform]]` tables in file order: empty for a scenario with one
    /// drone (the thesis's; then `firmware` and `run` are the platform's).
    pub platforms: Vec<PlatformSpec>,
    /// The `[positioning]` table (docs/SWARM_RESULTS.md).
    pub positioning: Option<PositioningSpec>,
}

impl Scenario {
    /// Reads and checks a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses scenario text; relative paths are taken from `path`'s directory.
    pub fn parse(text: &str, path: &Path) -> Result<Scenario, ScenarioError> {
        let invalid = |message: String| ScenarioError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        let file: ScenarioFile = toml::from_str(text)
            .map_err(|e| invalid(e.to_string().trim_end().replace('\n', " ")))?;
        let base = path.parent().unwrap_or(Path::new("."));
        let mut run = RunConfig::default();
        apply_run_table(&mut run, &file.run, base, "run").map_err(|e| invalid(e.to_string()))?;
        let tables = match &file.platform {
            None => Vec::new(),
            Some(toml::Value::String(p)) => {
                run.platform = Some(base.join(p));
                Vec::new()
            }
            Some(v @ toml::Value::Array(_)) => {
                v.clone().try_into::<Vec<PlatformTable>>().map_err(|e| {
                    invalid(format!(
                        "[[platform]]: {}",
                        e.to_string().trim_end().replace('\n', " ")
                    ))
                })?
            }
            Some(other) => {
                return Err(invalid(format!(
                "platform: expected a platform file (a string) or [[platform]] tables, got a {}",
                other.type_str()
            )))
            }
        };
        let platforms = resolve_platforms(&tables, &run, &file.run, file.firmware.as_deref(), base)
            .map_err(|e| invalid(e.to_string()))?;
        let firmware = match (&file.firmware, platforms.first()) {
            (Some(f), _) => base.join(f),
            // Unused with [[platform]]: every platform has its own.
            (None, Some(p)) => p.firmware.clone(),
            (None, None) => return Err(invalid("missing field `firmware`".into())),
        };
        let mut sweep = Vec::new();
        for (key, values) in &file.sweep {
            let texts = values
                .iter()
                .map(value_text)
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| invalid(format!("sweep.{key}: {e}")))?;
            sweep.push((key.clone(), texts));
        }
        let mut s = Scenario {
            name: path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scenario".into()),
            path: path.to_path_buf(),
            description: file.description,
            world: base.join(&file.world),
            firmware,
            timestep_ms: TimestepMs::new(default_timestep()).expect("the default is in range"),
            substeps: file.substeps,
            max_time_s: file.max_time_s,
            radio_seed: None,
            image_encoding: protocol::ImageEncoding::Array,
            busy_poll_us: protocol::busy_poll::DEFAULT_US,
            mcap: file.mcap.unwrap_or(true),
            mcap_image_every: file
                .mcap_image_every
                .unwrap_or(world_server::foxglove::DEFAULT_IMAGE_EVERY),
            mcap_power_every: file
                .mcap_power_every
                .unwrap_or(crate::foxglove::DEFAULT_POWER_EVERY),
            targets: file.targets,
            run,
            overrides: Vec::new(),
            sweep,
            platforms,
            positioning: file.positioning,
        };
        s.set_scenario_key("image_encoding", &file.image_encoding)
            .and_then(|_| s.set_scenario_key("timestep_ms", &file.timestep_ms.to_string()))
            .and_then(|_| s.set_scenario_key("substeps", &file.substeps.to_string()))
            .map_err(|e| invalid(e.to_string()))?;
        if let Some(t) = file.max_time_s {
            s.set_scenario_key("max_time_s", &t.to_string())
                .map_err(|e| invalid(e.to_string()))?;
        }
        if let Some(p) = &s.positioning {
            p.validate().map_err(|e| invalid(e.to_string()))?;
        }
        for (key, _) in &s.sweep {
            let key = s.platform_key(key).map_or(key.as_str(), |(_, k)| k);
            if !is_run_key(key) && !SCENARIO_KEYS.iter().any(|(k, _)| *k == key) {
                return Err(invalid(format!("sweep.{key}: {}", unknown_key(key))));
            }
        }
        s.fly_over_crtp()
            .map_err(|e| invalid(format!("crtp: {e}")))?;
        Ok(s)
    }

    /// Applies one `KEY=VALUE` (scenario key or run key; `run.KEY` also works).
    /// With `[[platform]]` tables a run key or `firmware` applies to every
    /// platform, and `DRONE.KEY=VALUE` (or `DRONE.run.KEY`) to one.
    pub fn set(&mut self, assignment: &str) -> Result<(), ScenarioError> {
        let (key, value) = assignment
            .split_once('=')
            .ok_or_else(|| ScenarioError::BadSet(assignment.to_string()))?;
        let (key, value) = (key.trim(), value.trim());
        if let Some((i, k)) = self.platform_key(key) {
            self.set_platform_key(i, k, value)?;
            self.overrides.push((key.to_string(), value.to_string()));
            return Ok(());
        }
        let key = key.strip_prefix("run.").unwrap_or(key);
        if key.is_empty() {
            return Err(ScenarioError::BadSet(assignment.to_string()));
        }
        if key == "platform" || SCENARIO_KEYS.iter().all(|(k, _)| *k != key) {
            if !is_run_key(key) {
                return Err(unknown_key(key));
            }
            if key == RADIO_ID_KEY && !self.platforms.is_empty() {
                return Err(ScenarioError::BadValue {
                    key: key.to_string(),
                    value: value.to_string(),
                    reason:
                        "one identifier for every radio; set it per platform (DRONE.radio_id=N)"
                            .into(),
                });
            }
            let bad = |e: sim_core::config::ConfigError| ScenarioError::BadValue {
                key: key.to_string(),
                value: value.to_string(),
                reason: e.to_string(),
            };
            self.run.set(key, value).map_err(bad)?;
            for p in &mut self.platforms {
                p.run.set(key, value).map_err(bad)?;
            }
            if key == "crtp" {
                self.fly_over_crtp()
                    .map_err(|reason| ScenarioError::BadValue {
                        key: key.to_string(),
                        value: value.to_string(),
                        reason,
                    })?;
            }
        } else {
            self.set_scenario_key(key, value)?;
            if key == "firmware" {
                for p in &mut self.platforms {
                    p.firmware = PathBuf::from(value);
                }
            }
        }
        self.overrides.push((key.to_string(), value.to_string()));
        Ok(())
    }

    /// `crtp=udp:HOST:PORT` on any scenario (docs/CFLIB.md): every drone is
    /// flown by a CRTP client instead of the scenario's firmware — the
    /// platforms run `crtp_host.elf` (next to the scenario's firmware, in
    /// `sim-core/firmware/bin/`) unless theirs already serves CRTP
    /// ([`CRTP_FIRMWARES`]), and the swarm's drones listen at PORT,
    /// PORT+1, … in `[[platform]]` order.
    fn fly_over_crtp(&mut self) -> Result<(), String> {
        let Some(spec) = self.run.crtp.clone() else {
            return Ok(());
        };
        let host = |fw: &Path| {
            let serves = fw
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| CRTP_FIRMWARES.contains(&n));
            if serves {
                fw.to_path_buf()
            } else {
                fw.with_file_name(CRTP_FIRMWARE)
            }
        };
        self.firmware = host(&self.firmware);
        let several = self.platforms.len() > 1;
        for (i, p) in self.platforms.iter_mut().enumerate() {
            p.firmware = host(&p.firmware);
            if several {
                p.run.crtp = Some(spec.offset(i as u16)?);
            }
        }
        Ok(())
    }

    fn set_scenario_key(&mut self, key: &str, value: &str) -> Result<(), ScenarioError> {
        let bad = |reason: &str| ScenarioError::BadValue {
            key: key.to_string(),
            value: value.to_string(),
            reason: reason.to_string(),
        };
        match key {
            "world" => self.world = PathBuf::from(value),
            "firmware" => self.firmware = PathBuf::from(value),
            "timestep_ms" => {
                self.timestep_ms = value
                    .parse()
                    .map_err(|e: TimestepError| bad(&e.to_string()))?
            }
            "substeps" => {
                self.substeps = match value.parse::<u32>() {
                    Ok(n) if (1..=1000).contains(&n) => n,
                    _ => return Err(bad("expected a whole number in 1..=1000")),
                }
            }
            "max_time_s" => {
                self.max_time_s = match value.parse::<f64>() {
                    Ok(t) if t.is_finite() && t > 0.0 => Some(t),
                    _ => return Err(bad("expected a positive number of seconds")),
                }
            }
            "radio_seed" => {
                self.radio_seed = match value.parse::<u64>() {
                    Ok(n) => Some(n),
                    _ => return Err(bad("expected a whole number >= 0")),
                }
            }
            "image_encoding" => {
                self.image_encoding = value
                    .parse()
                    .map_err(|_| bad("expected array, base64 or shm"))?
            }
            "mcap" => {
                self.mcap = match value {
                    "true" => true,
                    "false" => false,
                    _ => return Err(bad("expected true or false")),
                }
            }
            "mcap_image_every" => {
                self.mcap_image_every = value
                    .parse::<u64>()
                    .map_err(|_| bad("expected a whole number >= 0"))?
            }
            "mcap_power_every" => {
                self.mcap_power_every = value
                    .parse::<u64>()
                    .map_err(|_| bad("expected a whole number >= 0"))?
            }
            "busy_poll_us" => {
                self.busy_poll_us = match value.parse::<u64>() {
                    Ok(us) if us <= 1_000_000 => us,
                    _ => return Err(bad("expected a whole number of µs in 0..=1000000")),
                }
            }
            _ => return Err(unknown_key(key)),
        }
        Ok(())
    }

    /// Checks, before any process starts, the rules that tie keys together
    /// (each platform's sync mode against the timestep, DESIGN.md §19) and
    /// that every file the run needs exists. With `[[platform]]` tables:
    /// every platform's firmware and platform file, and the world's drones
    /// (each claimed by exactly one platform). Returns the world file, read
    /// and parsed: the one reading of it the run is then given (DESIGN.md
    /// §19).
    pub fn check_files(&self) -> Result<World, ScenarioError> {
        self.check_timestep()?;
        let mut files = vec![("world file", &self.world)];
        if self.platforms.is_empty() {
            files.push(("firmware", &self.firmware));
            if let Some(p) = &self.run.platform {
                files.push(("platform file", p));
            }
        }
        for (what, path) in files {
            if !path.is_file() {
                return Err(ScenarioError::Missing {
                    what,
                    path: path.clone(),
                });
            }
        }
        for p in &self.platforms {
            let mut files = vec![("firmware", &p.firmware)];
            if let Some(f) = &p.run.platform {
                files.push(("platform file", f));
            }
            for (what, path) in files {
                if !path.is_file() {
                    return Err(ScenarioError::PlatformMissing {
                        drone: p.drone.clone(),
                        what,
                        path: path.clone(),
                    });
                }
            }
        }
        let world = World::load(&self.world)?;
        if !self.platforms.is_empty() {
            self.check_drones(&world)?;
        }
        Ok(world)
    }
}

impl Scenario {
    /// The busy-poll budget the processes are started with: the
    /// scenario's, but 0 when a platform serves a live CRTP link paced to
    /// the wall clock. Such a run waits for the clock anyway, and on a
    /// host busy with other work the polling only takes the CPU the peer
    /// needs: a cflib flight at 2 ms steps beside two CPU-bound processes
    /// kept 0.67 of the wall clock with 200 µs of polling and 1.00 without
    /// (docs/notes/2026-12-07-flight-stack.md).
    pub fn busy_poll_us(&self) -> u64 {
        let runs = std::iter::once(&self.run)
            .filter(|_| self.platforms.is_empty())
            .chain(self.platforms.iter().map(|p| &p.run));
        let paced = runs
            .into_iter()
            .any(|r| matches!(r.crtp, Some(CrtpSpec::Udp(_))) && r.pace > 0.0);
        if paced {
            0
        } else {
            self.busy_poll_us
        }
    }

    /// The timestep under every platform's sync mode and controller (the
    /// same checks sim-core makes when the world reports its timestep).
    pub fn check_timestep(&self) -> Result<(), ScenarioError> {
        let runs = std::iter::once(&self.run)
            .filter(|_| self.platforms.is_empty())
            .chain(self.platforms.iter().map(|p| &p.run));
        let invalid = |message: String| ScenarioError::Invalid {
            path: self.path.clone(),
            message,
        };
        let ms = self.timestep_ms.get();
        for run in runs {
            sim_core::sync::check_timestep(ms, run.sync).map_err(|e| invalid(e.to_string()))?;
            if run.controller == sim_core::peripherals::stm32::Controller::Pid {
                sim_core::peripherals::stm32::cascade::check_timestep(ms).map_err(invalid)?;
            }
        }
        Ok(())
    }
}

pub(crate) fn unknown_key(key: &str) -> ScenarioError {
    ScenarioError::UnknownKey {
        key: key.to_string(),
        scenario: SCENARIO_KEYS.map(|(k, _)| k).join(", "),
        run: run_key_names(),
    }
}

/// Finds a file shipped in the repository (e.g. `scenarios/thesis-race.toml`)
/// from the working directory, the executable's ancestors (target/<profile>/
/// cosim → repository root) or the source tree this binary was built from.
pub fn find_repo_file(rel: &str) -> Option<PathBuf> {
    let mut candidates = vec![PathBuf::from(rel)];
    if let Ok(exe) = std::env::current_exe() {
        candidates.extend(exe.ancestors().skip(1).map(|d| d.join(rel)));
    }
    candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel));
    candidates.into_iter().find(|p| p.is_file())
}

/// Resolves a scenario argument: a path, or a name in `scenarios/`
/// (`thesis-race` → `scenarios/thesis-race.toml`).
pub fn resolve_scenario(arg: Option<&str>) -> Result<PathBuf, ScenarioError> {
    let arg = arg.unwrap_or("thesis-race");
    let p = PathBuf::from(arg);
    if p.is_file() {
        return Ok(p);
    }
    let looks_like_name = !arg.contains('/') && !arg.ends_with(".toml");
    if looks_like_name {
        if let Some(found) = find_repo_file(&format!("scenarios/{arg}.toml")) {
            return Ok(found);
        }
    }
    Err(ScenarioError::UnknownScenario(p))
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
    pub(crate) fn check_drones(&self, world: &World) -> Result<(), ScenarioError> {
        let names = world.drone_names();
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

    const MIN: &str = r#"
        world = "worlds/empty.toml"
        firmware = "fw.elf"
        targets = [[1.0, 2.0, 1.0]]
        [run]
        battery = "ufx250"
        [sweep]
        timestep_ms = [16, 32]
    "#;

    fn parse(text: &str) -> Result<Scenario, ScenarioError> {
        Scenario::parse(text, Path::new("/x/scenarios/s.toml"))
    }

    #[test]
    fn paths_are_relative_to_the_file_and_defaults_are_the_thesis() {
        let s = parse(MIN).unwrap();
        assert_eq!(s.name, "s");
        assert_eq!(s.world, Path::new("/x/scenarios/worlds/empty.toml"));
        assert_eq!(s.firmware, Path::new("/x/scenarios/fw.elf"));
        assert_eq!(s.timestep_ms.get(), 32);
        assert_eq!(s.run.get("battery").unwrap(), "ufx250");
        assert_eq!(s.run.get("power_model").unwrap(), "empirical");
        assert_eq!(
            s.sweep,
            vec![("timestep_ms".to_string(), vec!["16".into(), "32".into()])]
        );
    }

    #[test]
    fn unknown_keys_and_bad_values_are_refused() {
        let e = parse(&format!("{MIN}\nfoo = 1\n")).unwrap_err().to_string();
        assert!(e.contains("foo"), "{e}");
        let e = parse(&MIN.replace("ufx250", "aaa"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("run.battery"), "{e}");
        let e = parse(&MIN.replace("timestep_ms = [16, 32]", "nope = [1]"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("sweep.nope"), "{e}");
        let e = parse(&MIN.replace("[run]", "timestep_ms = 0\n[run]"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("timestep_ms"), "{e}");
    }

    #[test]
    fn set_routes_keys_and_checks_values() {
        let mut s = parse(MIN).unwrap();
        s.set("timestep_ms=16").unwrap();
        s.set("run.power_model=stolaroff").unwrap();
        s.set("battery = lipol350").unwrap();
        assert_eq!(s.timestep_ms.get(), 16);
        assert_eq!(s.run.get("power_model").unwrap(), "stolaroff");
        assert_eq!(s.run.get("battery").unwrap(), "lipol350");
        assert_eq!(
            s.overrides_label(),
            "timestep_ms=16 power_model=stolaroff battery=lipol350"
        );
        for bad in [
            "timestep_ms=abc",
            "battery=nine",
            "tolerance=-1",
            "nokey",
            "zzz=1",
            "=3",
        ] {
            assert!(s.set(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn the_timestep_is_checked_against_the_sync_mode_with_sim_cores_message() {
        let mut s = parse(MIN).unwrap();
        // In range: accepted as a key, refused with the thesis's sync.
        s.set("timestep_ms=2").unwrap();
        let e = s.check_files().unwrap_err().to_string();
        let sim_core = sim_core::sync::check_timestep(2, sim_core::sync::SyncMode::Thesis)
            .unwrap_err()
            .to_string();
        assert!(e.ends_with(&sim_core), "{e}");
        assert_eq!(e.lines().count(), 1, "{e}");
        s.set("sync=bounded").unwrap();
        s.check_timestep().unwrap();
        // Out of range: the message world-server gives for --timestep.
        for bad in ["0", "1001", "abc"] {
            let e = s
                .set(&format!("timestep_ms={bad}"))
                .unwrap_err()
                .to_string();
            let range = TimestepError::Range(bad.into()).to_string();
            assert!(e.ends_with(&range), "{e}");
        }
        assert_eq!(s.timestep_ms.get(), 2, "a refused value changes nothing");
    }

    #[test]
    fn scenario_toml_reads_back_as_the_same_scenario() {
        let mut s = parse(MIN).unwrap();
        // Quotes, a backslash, a line break and a control character (which
        // Rust's Debug would escape as `\u{1b}`, not TOML).
        s.description = "a \"race\" \\ two\nlines \u{1b} §".into();
        s.set("max_time_s=12.5").unwrap();
        s.set("timestep_ms=16").unwrap();
        s.set("image_encoding=base64").unwrap();
        let text = s.resolved_toml();
        assert!(text.starts_with("# Resolved from /x/scenarios/s.toml max_time_s=12.5 "));
        let back: ResolvedScenario = toml::from_str(&text).unwrap();
        assert_eq!(back, s.resolved());
        // It is a scenario file: it runs again as it ran.
        let again = Scenario::parse(&text, Path::new("/elsewhere/scenario.toml")).unwrap();
        assert_eq!(again.description, s.description);
        assert_eq!((&again.world, &again.firmware), (&s.world, &s.firmware));
        assert_eq!(again.timestep_ms, s.timestep_ms);
        assert_eq!(again.substeps, s.substeps);
        assert_eq!(again.max_time_s, Some(12.5));
        assert_eq!(again.image_encoding, s.image_encoding);
        assert_eq!(again.targets, s.targets);
    }

    #[test]
    fn missing_files_are_named() {
        let s = parse(MIN).unwrap();
        let e = s.check_files().unwrap_err().to_string();
        assert!(e.contains("world file") && e.contains("empty.toml"), "{e}");
    }
}

#[cfg(test)]
mod platform_tests {
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
        let back: ResolvedScenario = toml::from_str(&text).unwrap();
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
