//! The `run` tables of a scenario file (the scenario's own and each
//! `[[platform]]`'s) applied to a run configuration: a leaf below the
//! scenario and its platforms, which both apply them.

use std::collections::BTreeMap;
use std::path::Path;

use sim_core::config::{run_key, RunConfig};

/// A value of a `[run]` or `[sweep]` table that has no text form.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("expected a string or a number, got a {0}")]
pub struct NotAScalar(pub &'static str);

pub(crate) fn value_text(v: &toml::Value) -> Result<String, NotAScalar> {
    match v {
        toml::Value::String(s) => Ok(s.clone()),
        toml::Value::Integer(i) => Ok(i.to_string()),
        toml::Value::Float(f) => Ok(f.to_string()),
        toml::Value::Boolean(b) => Ok(b.to_string()),
        other => Err(NotAScalar(other.type_str())),
    }
}

/// A key of a `run` table of the file that cannot be applied (`what.key:
/// reason`).
#[derive(Debug, thiserror::Error)]
#[error("{what}.{key}: {reason}")]
pub struct RunTableError {
    pub what: String,
    pub key: String,
    pub reason: RunTableReason,
}

/// Why a `run` table's key cannot be applied.
#[derive(Debug, thiserror::Error)]
pub enum RunTableReason {
    #[error(transparent)]
    NotAScalar(#[from] NotAScalar),
    #[error(transparent)]
    Config(#[from] sim_core::config::ConfigError),
}

pub(crate) fn is_run_key(key: &str) -> bool {
    run_key(key).is_some() || key.starts_with(sim_core::config::FIRMWARE_KEY_PREFIX)
}

/// Applies a `run` table of the file (`what` names it in errors); a
/// `platform` file is relative to the scenario file like the other paths.
pub(crate) fn apply_run_table(
    run: &mut RunConfig,
    table: &BTreeMap<String, toml::Value>,
    base: &Path,
    what: &str,
) -> Result<(), RunTableError> {
    let table: toml::Table = table.clone().into_iter().collect();
    for (key, value) in &sim_core::config::flatten_run_table(&table) {
        let err = |reason: RunTableReason| RunTableError {
            what: what.to_string(),
            key: key.clone(),
            reason,
        };
        let text = value_text(value).map_err(|e| err(e.into()))?;
        let text = if key == "platform" {
            base.join(&text).display().to_string()
        } else {
            text
        };
        run.set(key, &text).map_err(|e| err(e.into()))?;
    }
    Ok(())
}
