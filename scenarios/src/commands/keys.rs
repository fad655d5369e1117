//! `cosim keys`: the reference of every key `--set` accepts, generated from
//! the tables that declare them (`sim_core::config::RUN_KEYS`, each key's
//! one declaration, with `RunConfig::default` for the defaults,
//! `SCENARIO_KEYS`), so it cannot drift from what the checks accept.

use scenarios::scenario::SCENARIO_KEYS;
use sim_core::config::{RunConfig, FIRMWARE_KEY_PREFIX, RUN_KEYS};
use std::fmt::Write as _;
use std::process::ExitCode;

/// The reference as text: each key, its default where it has one, and its
/// description (which names the accepted values or range).
pub(crate) fn reference() -> String {
    let defaults = RunConfig::default();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Run keys: `cosim run|sweep --set KEY=VALUE`, a scenario's [run] table, \
         `sim-core --set KEY=VALUE` or `--config FILE` (TOML; `a.b` is key b of table a)."
    );
    for key in &RUN_KEYS {
        let (name, doc, default) = (key.name, key.doc, key.get(&defaults));
        let _ = writeln!(out, "  {name}  [default {default}]\n      {doc}");
    }
    let _ = writeln!(
        out,
        "  {FIRMWARE_KEY_PREFIX}NAME  [the ELF's own value]\n      \
         a firmware parameter: the initial value of the firmware's global NAME"
    );
    let _ = writeln!(
        out,
        "\nScenario keys: `cosim run|sweep --set KEY=VALUE` or the scenario file's top level \
         (defaults: the scenario file's; `cosim list` lists the scenarios)."
    );
    for (key, doc) in SCENARIO_KEYS {
        let _ = writeln!(out, "  {key}\n      {doc}");
    }
    out
}

pub(crate) fn cmd_keys() -> anyhow::Result<ExitCode> {
    print!("{}", reference());
    Ok(ExitCode::SUCCESS)
}
