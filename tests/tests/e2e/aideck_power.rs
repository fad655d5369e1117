//! The AI deck draws from the battery (docs/AIDECK_POWER.md): on the short
//! nn race (nn_race_short.elf, the network on the cluster), the deck's
//! energy is the cluster's through the deck's regulators, it is part of
//! the energy the battery gave and of the charge it lost, and the printed
//! summary says so. The same platform with ideal regulators is the
//! reference: the same flight, the cluster's energy drawn as it is.

use std::path::Path;

use e2e_tests::{assert_same_files, output_text as text, repo_root, summary, CosimBins};
use serde_json::Value;

fn run(bins: &CosimBins, out: &Path, platform: &Path) -> std::process::Output {
    bins.cosim(&[
        "run",
        "short-hop",
        "--world",
        "scenarios/worlds/short-gate-displaced.toml",
        "--set",
        "firmware=sim-core/firmware/bin/nn_race_short.elf",
        "--set",
        &format!("platform={}", platform.display()),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--no-mcap",
    ])
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn nn_race_energy_includes_what_the_deck_draws() {
    let bins = CosimBins::new();
    let dir = tempfile::tempdir().unwrap();
    let aideck = repo_root().join("sim-core/platforms/crazyflie-aideck.json");
    let mut platform: Value =
        serde_json::from_str(&std::fs::read_to_string(&aideck).unwrap()).unwrap();
    let eta = f(&platform["cluster"]["converter"]["efficiency"]);
    assert!(eta > 0.5 && eta < 1.0, "the deck's regulators lose: {eta}");
    // The reference: the same deck with ideal regulators.
    platform["cluster"]["converter"]["efficiency"] = 1.0.into();
    let ideal = dir.path().join("ideal.json");
    std::fs::write(&ideal, serde_json::to_string_pretty(&platform).unwrap()).unwrap();

    let a = dir.path().join("a");
    let o = run(&bins, &a, &aideck);
    assert!(o.status.success(), "{}", text(&o));
    let b = dir.path().join("b");
    let ob = run(&bins, &b, &ideal);
    assert!(ob.status.success(), "{}", text(&ob));
    let (sa, sb) = (summary(&a), summary(&b));
    assert_eq!(sa["gates_passed"], 1, "{sa:#}");
    // The deck's draw does not touch the flight (the thesis's battery).
    assert_same_files(&a, &b, &["trajectory.csv"], "regulators or not");
    assert_eq!(sa["energy_j"]["cluster"], sb["energy_j"]["cluster"]);

    let cluster = f(&sa["energy_j"]["cluster"]);
    let (da, db) = (&sa["deck"], &sb["deck"]);
    // At the battery: the cluster's energy over the regulators' efficiency
    // (the battery's voltage moves by microvolts between the sample that
    // sets the current and the one that prices it).
    assert!(cluster > 1e-3, "{sa:#}");
    assert!(
        (f(&da["energy_j"]) - cluster / eta).abs() < 1e-3 * cluster,
        "{da:#} vs {cluster} J / {eta}"
    );
    assert!(
        (f(&db["energy_j"]) - cluster).abs() < 1e-3 * cluster,
        "{db:#}"
    );
    // ... and in what the battery gave: the runs differ by the
    // regulators' loss alone.
    let total_a = f(&sa["energy_j"]["total"]);
    let loss = f(&da["energy_j"]) - f(&db["energy_j"]);
    assert!(
        (total_a - f(&sb["energy_j"]["total"]) - loss).abs() < 0.01 * loss,
        "{} - {} vs {loss}",
        total_a,
        sb["energy_j"]["total"]
    );
    assert!(
        (f(&da["share_pct"]) - 100.0 * f(&da["energy_j"]) / total_a).abs() < 1e-9,
        "{da:#}"
    );
    // ... and in the charge: less SOC left, and the flight time without
    // the deck is longer than with it.
    assert!(
        f(&sa["battery"]["soc_end"]) < f(&sb["battery"]["soc_end"]),
        "{sa:#}"
    );
    assert!(f(&da["flight_time_without_deck_s"]) > f(&da["flight_time_s"]));

    // The printed summary's line.
    let out = String::from_utf8_lossy(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with("AI deck"))
        .unwrap_or_else(|| panic!("no AI deck line: {out}"));
    assert!(
        line.contains(&format!("{:.2} J from the battery", f(&da["energy_j"]))),
        "{line}"
    );
}

/// A platform without a cluster has no deck block and no deck line: its
/// network is the thesis's.
#[test]
fn no_cluster_no_deck_block() {
    let bins = CosimBins::new();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let o = bins.cosim(&[
        "run",
        "short-hop",
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--no-mcap",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s = summary(&out);
    assert!(s.get("deck").is_none(), "{s:#}");
    assert!(!String::from_utf8_lossy(&o.stdout).contains("AI deck"));
}
