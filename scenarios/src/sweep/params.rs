//! What a sweep is made of: its parameters, their product, its rows and
//! their directories' names, its errors: the pieces the sweep's runner,
//! its plan, its merge and its tables share, below all of them.

use std::path::PathBuf;

use crate::outcome::RunOutcome;
use crate::scenario::ScenarioError;

/// File names of a sweep's outputs.
pub mod files {
    pub const CSV: &str = "sweep.csv";
    pub const MARKDOWN: &str = "sweep.md";
    pub const SOC_PNG: &str = "sweep_soc.png";
    pub const TIMESTEP_PNG: &str = "sweep_timestep.png";
}

/// Why a sweep could not start.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("--param {0:?}: expected KEY=V1,V2,...")]
    BadParam(String),
    // The scenario error is in the message, not chained as a source: the
    // launcher prints the chain, and the line would say it twice.
    #[error("run {label}: {error}")]
    Scenario { label: String, error: ScenarioError },
    #[error("no parameters: give --param KEY=V1,V2,... (or a [sweep] table in the scenario)")]
    NoParams,
    #[error("--shard {0:?}: expected K/N with 1 <= K <= N (run numbers ≡ K mod N)")]
    BadShard(String),
    #[error("{0}")]
    Output(String),
    /// A merge refused: missing, duplicate or foreign runs, a corrupt record
    /// or summary (one line that names the run and the file).
    #[error("merge refused: {0}")]
    Merge(String),
}

/// One swept parameter.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Param {
    pub key: String,
    pub values: Vec<String>,
}

impl std::str::FromStr for Param {
    type Err = SweepError;
    fn from_str(s: &str) -> Result<Param, SweepError> {
        let (key, values) = s
            .split_once('=')
            .ok_or_else(|| SweepError::BadParam(s.into()))?;
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if key.trim().is_empty() || values.is_empty() {
            return Err(SweepError::BadParam(s.into()));
        }
        Ok(Param {
            key: key.trim().to_string(),
            values,
        })
    }
}

/// Every combination, the first parameter varying slowest.
pub fn product(params: &[Param]) -> Vec<Vec<(String, String)>> {
    let mut combos: Vec<Vec<(String, String)>> = vec![Vec::new()];
    for p in params {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                p.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((p.key.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    combos
}

/// One row of the sweep table.
#[derive(Debug)]
pub struct SweepRow {
    pub index: usize,
    pub assignments: Vec<(String, String)>,
    pub dir: PathBuf,
    /// The run (None if it could not even be launched).
    pub outcome: Option<RunOutcome>,
    /// Why the run failed (None: it completed).
    pub error: Option<String>,
}

impl SweepRow {
    pub fn label(&self) -> String {
        self.assignments
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

pub(super) fn dir_name(index: usize, assignments: &[(String, String)]) -> String {
    let mut name = format!("run-{:03}", index + 1);
    for (k, v) in assignments {
        name.push('_');
        name.push_str(k);
        name.push('=');
        // Path separators and the like would nest or break the directory.
        name.extend(v.chars().map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        }));
    }
    name
}
