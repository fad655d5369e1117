//! The plan of a sweep (DESIGN.md §11): every run numbered in one stable
//! order (the first parameter varying slowest), checked before anything
//! runs; the shards `K/N` a batch engine hands out; and the record each run
//! leaves in its directory (`sweep-run.json`) so that `cosim sweep --merge`
//! can rebuild the table from shard outputs without the scenario.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::params::{dir_name, product, Param, SweepError};
use crate::outcome::RunOutcome;
use crate::outputs::files;
use crate::scenario::Scenario;
use crate::world::World;

/// The record's file name in each run directory.
pub const RUN_RECORD: &str = "sweep-run.json";
/// Written in every record; a merge refuses any other.
pub const RECORD_FORMAT: &str = "cosim-sweep-run/1";

/// One run of the plan.
#[derive(Debug, Clone)]
pub struct PlannedRun {
    /// 0-based position in the plan (the table's `run` column is `index + 1`).
    pub index: usize,
    pub assignments: Vec<(String, String)>,
    /// The base scenario with this run's assignments applied.
    pub scenario: Scenario,
    /// Its world file, read when the plan checked the run.
    pub world: World,
}

impl PlannedRun {
    /// Run number as printed (`run` column, `run-NNN` directory): `index + 1`.
    pub fn number(&self) -> usize {
        self.index + 1
    }

    /// `run-NNN_key=value…`
    pub fn dir_name(&self) -> String {
        dir_name(self.index, &self.assignments)
    }

    /// `key=value key=value`
    pub fn settings(&self) -> String {
        self.assignments
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// What makes two shard outputs parts of one sweep: the scenario's name,
/// the swept parameters, and a fingerprint of every run's resolved settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepId {
    pub scenario: String,
    pub params: Vec<Param>,
    /// Number of runs in the whole sweep.
    pub runs: usize,
    /// SHA-256 (hex) over every planned run's settings, input files by
    /// content (see [`Plan::new`]).
    pub fingerprint: String,
}

/// Every run of a sweep, in order.
#[derive(Debug, Clone)]
pub struct Plan {
    pub id: SweepId,
    pub runs: Vec<PlannedRun>,
}

impl Plan {
    /// Builds (and so checks) every combination: a typo in the last value
    /// must not surface after an hour of runs, nor on the last host.
    ///
    /// The fingerprint covers what decides a run's result: each run's
    /// timestep, substeps, time limit, image encoding, targets and run
    /// configuration, and the world, firmware and platform files by their
    /// SHA-256 rather than their paths — two hosts with the checkout at
    /// different places agree, a host with another firmware build does not.
    pub fn new(base: &Scenario, params: &[Param]) -> Result<Plan, SweepError> {
        if params.is_empty() {
            return Err(SweepError::NoParams);
        }
        let mut runs = Vec::new();
        let mut hasher = Fingerprint::default();
        for (index, assignments) in product(params).into_iter().enumerate() {
            let label = format!("{}", index + 1);
            let mut s = base.clone();
            for (k, v) in &assignments {
                s.set(&format!("{k}={v}"))
                    .map_err(|error| SweepError::Scenario {
                        label: label.clone(),
                        error,
                    })?;
            }
            let world = s.check_files().map_err(|error| SweepError::Scenario {
                label: label.clone(),
                error,
            })?;
            hasher.run(index, &s, &world)?;
            runs.push(PlannedRun {
                index,
                assignments,
                scenario: s,
                world,
            });
        }
        Ok(Plan {
            id: SweepId {
                scenario: base.name.clone(),
                params: params.to_vec(),
                runs: runs.len(),
                fingerprint: hasher.finish(),
            },
            runs,
        })
    }

    /// The runs of one shard (all of them without a shard), in order.
    pub fn select(&self, shard: Option<Shard>) -> Vec<&PlannedRun> {
        self.runs
            .iter()
            .filter(|r| shard.is_none_or(|s| s.contains(r.number())))
            .collect()
    }

    /// `cosim sweep NAME --plan`: one line per run, `NUMBER key=value…`.
    pub fn listing(&self, shard: Option<Shard>) -> String {
        self.select(shard)
            .iter()
            .map(|r| format!("{} {}\n", r.number(), r.settings()))
            .collect()
    }
}

/// SHA-256 over the runs' canonical descriptions.
#[derive(Default)]
struct Fingerprint {
    text: String,
}

impl Fingerprint {
    fn run(&mut self, index: usize, s: &Scenario, world: &World) -> Result<(), SweepError> {
        let file = |p: &Path| -> Result<String, SweepError> {
            let bytes = std::fs::read(p)
                .map_err(|e| SweepError::Output(format!("cannot read {}: {e}", p.display())))?;
            Ok(sha256_hex(&bytes))
        };
        let mut run = s.run.clone();
        let platform = match run.platform.take() {
            Some(p) => file(&p)?,
            None => "embedded".into(),
        };
        // A scenario with several drones flies its platforms' firmware: the
        // scenario's own `firmware` is only their default (and may be absent).
        let firmware = if s.platforms.is_empty() {
            file(&s.firmware)?
        } else {
            "platforms".into()
        };
        // Debug formatting of numbers is exact and stable: a changed value
        // changes the text.
        self.text += &format!(
            "run {index}\ntimestep_ms {}\nsubsteps {}\nmax_time_s {:?}\nimage_encoding {}\ntargets {:?}\nworld {}\nfirmware {firmware}\nplatform {platform}\n[run]\n{}\n",
            s.timestep_ms,
            s.substeps,
            s.max_time_s,
            s.image_encoding.as_str(),
            s.targets,
            sha256_hex(world.text().as_bytes()),
            run.to_toml(),
        );
        for p in &s.platforms {
            let mut prun = p.run.clone();
            let pfile = match prun.platform.take() {
                Some(f) => file(&f)?,
                None => "embedded".into(),
            };
            self.text += &format!(
                "[[platform]]\ndrone {:?}\nfirmware {}\nplatform {pfile}\ntargets {:?}\n[run]\n{}\n",
                p.drone,
                file(&p.firmware)?,
                p.targets,
                prun.to_toml(),
            );
        }
        Ok(())
    }

    fn finish(self) -> String {
        sha256_hex(self.text.as_bytes())
    }
}

pub(crate) fn sha256_hex(data: &[u8]) -> String {
    protocol::sha256_hex(data)
}

/// Shard `K/N` (1 <= K <= N): the runs whose number is ≡ K (mod N). Run
/// numbers start at 1 like the table's `run` column, so shards `1/N … N/N`
/// map onto a Slurm array `--array=1-N` or `parallel … ::: $(seq N)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub k: usize,
    pub n: usize,
}

impl Shard {
    /// Whether run `number` (1-based) belongs to this shard.
    pub fn contains(&self, number: usize) -> bool {
        number % self.n == self.k % self.n
    }
}

impl FromStr for Shard {
    type Err = SweepError;
    fn from_str(s: &str) -> Result<Shard, SweepError> {
        let bad = || SweepError::BadShard(s.to_string());
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let k: usize = k.trim().parse().map_err(|_| bad())?;
        let n: usize = n.trim().parse().map_err(|_| bad())?;
        if n == 0 || k == 0 || k > n {
            return Err(bad());
        }
        Ok(Shard { k, n })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

/// `sweep-run.json`: what one run leaves for the merge. Written when the
/// run has ended (complete or failed), atomically: a run directory without
/// it is a run that did not finish.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// [`RECORD_FORMAT`].
    pub format: String,
    pub sweep: SweepId,
    /// Run number (1-based).
    pub run: usize,
    pub settings: Vec<(String, String)>,
    /// The directory's name (`run-NNN_key=value…`).
    pub dir: String,
    /// The shard that ran it (`K/N`; `1/1` for a one-machine sweep).
    pub shard: String,
    /// The row's error (None: the run completed).
    pub error: Option<String>,
    /// None when the run could not even be launched.
    pub outcome: Option<OutcomeRecord>,
}

/// The parts of a [`RunOutcome`] that are not in the run's own files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutcomeRecord {
    pub sim_core_exit: Option<i32>,
    pub world_exit: Option<i32>,
    pub launch_error: Option<String>,
    pub report_error: Option<String>,
    /// Wall time of the run (a wall-clock column: not compared).
    pub wall_s: f64,
    /// SHA-256 of `summary.json` as it was read when the run ended (None:
    /// there was no readable summary). A summary that no longer has this
    /// hash was damaged on the way to the merge.
    pub summary_sha256: Option<String>,
}

impl RunRecord {
    pub fn new(
        id: &SweepId,
        run: &PlannedRun,
        shard: Shard,
        dir: &Path,
        outcome: Option<&RunOutcome>,
        error: Option<&str>,
    ) -> RunRecord {
        let outcome = outcome.map(|o| OutcomeRecord {
            sim_core_exit: o.status.sim_core,
            world_exit: o.status.world,
            launch_error: o.status.error.clone(),
            report_error: o.report_error.clone(),
            wall_s: o.status.wall.as_secs_f64(),
            summary_sha256: o
                .summary
                .as_ref()
                .and_then(|_| std::fs::read(dir.join(files::SUMMARY)).ok())
                .map(|b| sha256_hex(&b)),
        });
        RunRecord {
            format: RECORD_FORMAT.into(),
            sweep: id.clone(),
            run: run.number(),
            settings: run.assignments.clone(),
            dir: run.dir_name(),
            shard: shard.to_string(),
            error: error.map(str::to_string),
            outcome,
        }
    }

    /// Writes `dir/sweep-run.json` (via a temporary file and a rename, so a
    /// killed shard never leaves half a record).
    pub fn write(&self, dir: &Path) -> Result<(), SweepError> {
        let oerr = |e: &dyn fmt::Display| {
            SweepError::Output(format!(
                "cannot write {}: {e}",
                dir.join(RUN_RECORD).display()
            ))
        };
        std::fs::create_dir_all(dir).map_err(|e| oerr(&e))?;
        let text = serde_json::to_string_pretty(self).map_err(|e| oerr(&e))? + "\n";
        let tmp = dir.join(format!(".{RUN_RECORD}.tmp"));
        std::fs::write(&tmp, text).map_err(|e| oerr(&e))?;
        std::fs::rename(&tmp, dir.join(RUN_RECORD)).map_err(|e| oerr(&e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scenario in its own directory, with a world file and a firmware
    /// of the given bytes.
    fn scenario_in(dir: &Path, firmware: &[u8]) -> Scenario {
        std::fs::write(
            dir.join("w.toml"),
            "# a world\n[start]\nposition = [0.0, 0.0, 0.015]\n",
        )
        .unwrap();
        std::fs::write(dir.join("fw.elf"), firmware).unwrap();
        let path = dir.join("s.toml");
        std::fs::write(&path, "world = \"w.toml\"\nfirmware = \"fw.elf\"\n").unwrap();
        Scenario::load(&path).unwrap()
    }

    fn fingerprint(s: &Scenario) -> String {
        let params = [Param {
            key: "battery".into(),
            values: vec!["lipol250".into(), "ufx250".into()],
        }];
        Plan::new(s, &params).unwrap().id.fingerprint
    }

    #[test]
    fn the_fingerprint_follows_settings_and_file_contents_not_paths() {
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let sa = scenario_in(a.path(), b"firmware 1");
        let sb = scenario_in(b.path(), b"firmware 1");
        assert_ne!(sa.firmware, sb.firmware);
        assert_eq!(fingerprint(&sa), fingerprint(&sb), "same files elsewhere");
        let mut set = sb.clone();
        set.set("tolerance=0.2").unwrap();
        assert_ne!(fingerprint(&sa), fingerprint(&set), "another --set");
        let mut ts = sb.clone();
        ts.set("timestep_ms=16").unwrap();
        assert_ne!(fingerprint(&sa), fingerprint(&ts), "another timestep");
        let sb = scenario_in(b.path(), b"firmware 2");
        assert_ne!(fingerprint(&sa), fingerprint(&sb), "another firmware build");
    }

    #[test]
    fn the_plan_lists_runs_in_the_sweep_order() {
        let d = tempfile::tempdir().unwrap();
        let s = scenario_in(d.path(), b"fw");
        let params = [
            "timestep_ms=16,32".parse::<Param>().unwrap(),
            "battery=lipol250,ufx250".parse().unwrap(),
        ];
        let plan = Plan::new(&s, &params).unwrap();
        assert_eq!(
            plan.listing(None),
            "1 timestep_ms=16 battery=lipol250\n2 timestep_ms=16 battery=ufx250\n\
             3 timestep_ms=32 battery=lipol250\n4 timestep_ms=32 battery=ufx250\n"
        );
        assert_eq!(
            plan.listing(Some(Shard { k: 2, n: 3 })),
            "2 timestep_ms=16 battery=ufx250\n"
        );
        assert_eq!(
            plan.runs[3].dir_name(),
            "run-004_timestep_ms=32_battery=ufx250"
        );
        let bad = ["timestep_ms=16,0".parse::<Param>().unwrap()];
        let e = Plan::new(&s, &bad).unwrap_err().to_string();
        assert!(e.starts_with("run 2: ") && e.contains("timestep_ms"), "{e}");
    }

    #[test]
    fn shards_partition_the_runs() {
        for n in 1..=5 {
            let shards: Vec<Shard> = (1..=n).map(|k| Shard { k, n }).collect();
            for number in 1..=13 {
                let owners = shards.iter().filter(|s| s.contains(number)).count();
                assert_eq!(owners, 1, "run {number} with {n} shards");
            }
        }
        let s: Shard = "2/3".parse().unwrap();
        assert!(s.contains(2) && s.contains(5) && !s.contains(3));
        assert_eq!(s.to_string(), "2/3");
        assert!("3/3".parse::<Shard>().unwrap().contains(6));
        for bad in ["0/2", "3/2", "1/0", "1", "a/b", "1/2/3", "-1/2", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
