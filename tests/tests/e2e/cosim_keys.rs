//! `cosim keys`, the generated reference of every key `--set` accepts:
//! every run key and scenario key is listed with its description, and the
//! default it prints for a run key is a value the checks accept (`cosim
//! sweep --plan` checks each run's settings before anything starts).

use e2e_tests::{output_text as text, CosimBins as Bins};
use scenarios::scenario::SCENARIO_KEYS;
use sim_core::config::RUN_KEYS;

#[test]
fn keys_lists_every_key_and_its_defaults_are_accepted() {
    let b = Bins::new();
    let o = b.cosim(&["keys"]);
    assert!(o.status.success(), "{}", text(&o));
    let listing = String::from_utf8_lossy(&o.stdout).to_string();
    let lines: Vec<&str> = listing.lines().collect();
    // "  KEY  [default VALUE]" then the description, indented, on the next line.
    let entry = |key: &str| -> (usize, &str) {
        let i = lines
            .iter()
            .position(|l| l.split_whitespace().next() == Some(key))
            .unwrap_or_else(|| panic!("{key} missing from:\n{listing}"));
        let doc = lines.get(i + 1).map_or("", |l| l.trim());
        assert!(!doc.is_empty(), "{key} has no description:\n{listing}");
        (i, lines[i])
    };
    for key in RUN_KEYS.iter().map(|k| k.name) {
        let (_, line) = entry(key);
        let default = line
            .split_once("[default ")
            .and_then(|(_, rest)| rest.strip_suffix(']'))
            .unwrap_or_else(|| panic!("{key}: no default in {line:?}"));
        // The embedded platform has no file to name.
        if key == "platform" {
            continue;
        }
        let param = format!("{key}={default}");
        let o = b.cosim(&["sweep", "short-hop", "--param", &param, "--plan"]);
        assert!(o.status.success(), "{param} refused: {}", text(&o));
    }
    for (key, _) in SCENARIO_KEYS {
        entry(key);
    }
}
