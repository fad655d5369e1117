//! How close seed 003's estimates come to the truth
//! ([`positioning`](super::positioning)'s rows): the tables of §7.1 (real,
//! mean estimate and standard deviation per window, the seed's values
//! beside ours) and, after a start-up transient, each drone's error
//! (mean, p95, max), both as markdown for `positioning.md`.

use std::fmt::Write as _;

use serde::Serialize;

use super::positioning_spec::{PositionRow, PositioningSpec};
use super::report::mean_sd_population;
use crate::scenario::Scenario;

/// The observer whose estimates the tables and plots show.
pub fn observer(scenario: &Scenario, spec: Option<&PositioningSpec>) -> Option<String> {
    spec.and_then(|s| s.observer.clone())
        .or_else(|| scenario.platforms.first().map(|p| p.drone.clone()))
}

/// One drone's line of a table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TableRow {
    pub drone: String,
    pub samples: usize,
    pub x_real: f64,
    pub x_est: f64,
    pub y_real: f64,
    pub y_est: f64,
    pub x_sd: f64,
    pub y_sd: f64,
    /// The seed's [x real, x est, y real, y est, x std, y std].
    pub seed: Option<[f64; 6]>,
}

/// A table of §7.1 for one window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table {
    pub name: String,
    pub observer: String,
    pub rows: Vec<TableRow>,
}

pub fn tables(scenario: &Scenario, spec: &PositioningSpec, rows: &[PositionRow]) -> Vec<Table> {
    let Some(default_obs) = observer(scenario, Some(spec)) else {
        return Vec::new();
    };
    spec.table
        .iter()
        .map(|t| {
            let obs = t.observer.clone().unwrap_or_else(|| default_obs.clone());
            let rows = scenario
                .platforms
                .iter()
                .map(|p| {
                    let sel: Vec<&PositionRow> = rows
                        .iter()
                        .filter(|r| {
                            r.observer == obs
                                && r.drone == p.drone
                                && r.time_s >= t.from_s
                                && r.time_s < t.to_s
                        })
                        .collect();
                    // An empty window gives zeros; its row is dropped below.
                    let mean_sd = |f: fn(&PositionRow) -> f64| {
                        let v: Vec<f64> = sel.iter().map(|r| f(r)).collect();
                        mean_sd_population(&v).unwrap_or_default()
                    };
                    let (x_est, x_sd) = mean_sd(|r| r.est_x);
                    let (y_est, y_sd) = mean_sd(|r| r.est_y);
                    TableRow {
                        drone: p.drone.clone(),
                        samples: sel.len(),
                        x_real: mean_sd(|r| r.true_x).0,
                        x_est,
                        y_real: mean_sd(|r| r.true_y).0,
                        y_est,
                        x_sd,
                        y_sd,
                        seed: t.seed.get(&p.drone).copied(),
                    }
                })
                .filter(|r| r.samples > 0)
                .collect();
            Table {
                name: t.name.clone(),
                observer: obs.clone(),
                rows,
            }
        })
        .collect()
}

/// The tables as markdown, ours beside the seed's.
pub fn tables_markdown(tables: &[Table]) -> String {
    let mut s = String::new();
    let f = |v: f64| format!("{v:.3}");
    let seed = |r: &TableRow, i: usize| r.seed.map_or("–".into(), |v| f(v[i]));
    for t in tables {
        let _ = writeln!(s, "### {} (estimates of {})\n", t.name, t.observer);
        let _ = writeln!(
            s,
            "| drone | x real | x est. | x est. (seed) | y real | y est. | y est. (seed) | \
             x std | x std (seed) | y std | y std (seed) | samples |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|");
        for r in &t.rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.drone,
                f(r.x_real),
                f(r.x_est),
                seed(r, 1),
                f(r.y_real),
                f(r.y_est),
                seed(r, 3),
                f(r.x_sd),
                seed(r, 4),
                f(r.y_sd),
                seed(r, 5),
                r.samples
            );
        }
        s.push('\n');
    }
    s
}

/// One drone's estimation error (3D, m) after the start-up transient, as
/// one observer estimates it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorRow {
    pub drone: String,
    pub samples: usize,
    pub mean: f64,
    /// Nearest-rank 95th percentile.
    pub p95: f64,
    pub max: f64,
}

/// The errors of `obs`'s estimates, per drone in platform order, from its
/// first estimate + `settle_s` on; also that start time (s).
pub fn error_summary(
    scenario: &Scenario,
    obs: &str,
    rows: &[PositionRow],
    settle_s: f64,
) -> Option<(f64, Vec<ErrorRow>)> {
    let mine: Vec<&PositionRow> = rows.iter().filter(|r| r.observer == obs).collect();
    let from = mine.iter().map(|r| r.time_s).reduce(f64::min)? + settle_s;
    let errors = scenario
        .platforms
        .iter()
        .filter_map(|p| {
            let mut e: Vec<f64> = mine
                .iter()
                .filter(|r| r.drone == p.drone && r.time_s >= from)
                .map(|r| r.error())
                .collect();
            if e.is_empty() {
                return None;
            }
            e.sort_by(f64::total_cmp);
            let n = e.len();
            Some(ErrorRow {
                drone: p.drone.clone(),
                samples: n,
                mean: e.iter().sum::<f64>() / n as f64,
                p95: e[(n * 95).div_ceil(100) - 1],
                max: e[n - 1],
            })
        })
        .collect();
    Some((from, errors))
}

/// The error summary as markdown.
pub fn errors_markdown(obs: &str, from_s: f64, settle_s: f64, rows: &[ErrorRow]) -> String {
    let mut s = format!(
        "### estimation error of {obs}'s estimates from {from_s:.3} s of world time \
         (its first estimate + {settle_s} s of start-up transient)\n\n\
         | drone | samples | mean (m) | p95 (m) | max (m) |\n|---|---|---|---|---|\n"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} | {:.3} |",
            r.drone, r.samples, r.mean, r.p95, r.max
        );
    }
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_summary_leaves_the_transient_out() {
        let scenario: Scenario = {
            let dir = tempfile::tempdir().unwrap();
            let p = dir.path().join("s.toml");
            std::fs::write(
                &p,
                "world = \"w.toml\"\nfirmware = \"f.elf\"\n[[platform]]\ndrone = \"a\"\n\
                 [[platform]]\ndrone = \"b\"\n[positioning]\nsettle_s = 1.0\n",
            )
            .unwrap();
            Scenario::load(&p).unwrap()
        };
        assert_eq!(scenario.positioning.as_ref().unwrap().settle_s, Some(1.0));
        // b's errors 0.01 .. 1.00 m at 5 s + k·10 ms; a's 5 m at first.
        let row = |t: f64, drone: &str, e: f64| PositionRow {
            time_s: t,
            observer: "a".into(),
            drone: drone.into(),
            est_x: e,
            est_y: 0.0,
            est_z: 0.0,
            sigma_m: 0.1,
            stable: 1,
            true_x: 0.0,
            true_y: 0.0,
            true_z: 0.0,
        };
        let mut rows = vec![row(4.0, "a", 5.0), row(4.5, "b", 7.0)];
        rows.extend((1..=100).map(|k| row(5.0 + k as f64 / 100.0, "b", k as f64 / 100.0)));
        let (from, e) = error_summary(&scenario, "a", &rows, 1.0).unwrap();
        assert_eq!(from, 5.0);
        assert_eq!(e.len(), 1, "a has no estimate after 5 s");
        let b = &e[0];
        assert_eq!((b.drone.as_str(), b.samples), ("b", 100));
        assert!((b.mean - 0.505).abs() < 1e-12, "{b:?}");
        assert_eq!((b.p95, b.max), (0.95, 1.0));
        assert!(errors_markdown("a", from, 1.0, &e).contains("| b | 100 | 0.505 | 0.950 | 1.000 |"));
        assert!(error_summary(&scenario, "b", &rows, 1.0).is_none());
        // A negative or non-finite settle_s is refused.
        let bad = PositioningSpec {
            settle_s: Some(-1.0),
            ..PositioningSpec::default()
        };
        assert_eq!(
            bad.validate(),
            Err(super::super::positioning_spec::BadSettle(-1.0))
        );
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("settle_s = -1"));
    }
}
