//! Seed 003's positioning read back from a run (docs/SWARM_RESULTS.md):
//! every drone's estimates of every drone ([`console`](super::console)),
//! set against the true positions from the world's trajectory expressed in
//! the same frame (§5.3.2: origin at the first reference, +X toward the
//! second, the XY plane through the third with it on +Y, +Z toward the
//! fourth), written to `positions.csv`; with a `[positioning]` table in
//! the scenario, the tables of §7.1 (real, mean estimate, standard
//! deviation per window) beside the seed's, in `positioning.md`; with
//! `settle_s`, each drone's error (mean, p95, max) after the start-up
//! transient there too; and the plots of the estimates and their errors
//! over time. An estimate's world time is the one the firmware printed
//! (`world_us=`, flying drones) or 2 s + its core time (carried drones).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::accuracy::{error_summary, errors_markdown, observer, tables, tables_markdown};
use super::console::{self, SwarmConsole};
pub use super::positioning_spec::{BadSettle, PositionRow, PositioningSpec, TableSpec};
use super::report::DroneTrack;
use crate::outputs::files;
use crate::plot::{panels, PlotError, Series};
use crate::scenario::{Scenario, RADIO_ID_KEY};

/// `positions.csv`, `positioning.md` and the plots in the run's directory.
pub const POSITIONS_CSV: &str = "positions.csv";
pub const POSITIONING_MD: &str = "positioning.md";
pub const POSITIONS_PNG: &str = "positions.png";
pub const ERROR_PNG: &str = "position_error.png";

/// The firmware's clock starts when its radio's INIT_DONE comes: at the end
/// of the world's warm-up (docs/SWARM.md §2, §4), 2.000 s of world time.
/// A carried drone's core clock is the world's, so its estimate at firmware
/// time t is at world time 2 s + t.
pub const FIRMWARE_T0_MS: u64 = 2000;

/// World time (ms) of an estimate: the STM32's last sensor read when the
/// firmware prints it (flying drones: their core clock runs ahead of the
/// world's, docs/SWARM_RESULTS.md §5), else [`FIRMWARE_T0_MS`] + its time.
pub fn world_ms(e: &console::Estimates) -> f64 {
    match e.world_us {
        Some(us) => us as f64 / 1000.0,
        None => (FIRMWARE_T0_MS + e.t_ms) as f64,
    }
}

/// A track's position at world time `ms`, linearly interpolated.
fn at(track: &DroneTrack, ms: f64) -> Option<[f64; 3]> {
    let p = &track.points;
    let i = p.partition_point(|(t, _)| (*t as f64) <= ms);
    match (i.checked_sub(1).map(|j| p[j]), p.get(i).copied()) {
        (Some((t0, a)), Some((t1, b))) if t1 > t0 => {
            let f = (ms - t0 as f64) / (t1 - t0) as f64;
            Some([0, 1, 2].map(|k| a[k] + f * (b[k] - a[k])))
        }
        (Some((_, a)), _) => Some(a),
        (None, Some((_, b))) => Some(b),
        (None, None) => None,
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = dot(a, a).sqrt();
    (n > 1e-9).then(|| a.map(|v| v / n))
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The frame of §5.3.2 built from the references' true positions: origin,
/// axes. With two references the Y axis is the horizontal perpendicular
/// (a 1D frame: only x is defined); with three +Y is toward the third;
/// with four +Z is toward the fourth (else world up's side).
pub fn true_frame(refs: &[[f64; 3]]) -> Option<([f64; 3], [[f64; 3]; 3])> {
    let o = *refs.first()?;
    let x = unit(sub(*refs.get(1)?, o))?;
    // The third reference fixes +Y; on the X axis (the seed's location 4,
    // where A completes the frame) it does not, and the horizontal
    // perpendicular is taken, as without a third.
    let third = refs.get(2).and_then(|p| {
        let v = sub(*p, o);
        let d = dot(v, x);
        let off = sub(v, x.map(|c| c * d));
        (dot(off, off).sqrt() > 1e-6).then(|| unit(off)).flatten()
    });
    let y = third
        .or_else(|| unit(cross([0.0, 0.0, 1.0], x)))
        .unwrap_or([0.0, 1.0, 0.0]);
    let mut z = cross(x, y);
    let side = refs.get(3).map_or(1.0, |p| dot(sub(*p, o), z));
    if side < 0.0 {
        z = z.map(|c| -c);
    }
    Some((o, [x, y, z]))
}

/// The platforms' names by identifier (§6.2, from their radio_id).
fn names_by_id(scenario: &Scenario) -> BTreeMap<u32, String> {
    scenario
        .platforms
        .iter()
        .filter_map(|p| {
            let eui: u64 = p.run.get(RADIO_ID_KEY).ok()?.parse().ok()?;
            Some((console::id_from_eui(eui), p.drone.clone()))
        })
        .collect()
}

/// Every estimate of every observer with the truth in its frame, in
/// (observer order, time) order. Estimates before the observer's frame is
/// built, and filters not started, are left out.
pub fn position_rows(
    scenario: &Scenario,
    consoles: &BTreeMap<String, SwarmConsole>,
    tracks: &BTreeMap<String, DroneTrack>,
) -> Vec<PositionRow> {
    let names = names_by_id(scenario);
    let mut rows = Vec::new();
    for p in &scenario.platforms {
        let Some(c) = consoles.get(&p.drone) else {
            continue;
        };
        for e in c.estimates.iter().filter(|e| e.built) {
            let Some(refs) = c.refs_at(e.t_ms) else {
                continue;
            };
            // With too few neighbours the observer itself completes the
            // frame (+X in 1D, +Y in 2D; docs/SWARM_FIRMWARE.md §3); its
            // references do not list it.
            let mut refs = refs.to_vec();
            if refs.len() < 3 && !refs.contains(&e.id) {
                refs.push(e.id);
            }
            let world_ms = world_ms(e);
            let pts: Option<Vec<[f64; 3]>> = refs
                .iter()
                .map(|id| at(tracks.get(names.get(id)?)?, world_ms))
                .collect();
            let Some((o, axes)) = pts.as_deref().and_then(true_frame) else {
                continue;
            };
            for n in &e.nodes {
                let (Some(sigma), Some(name)) = (n.sigma, names.get(&n.id)) else {
                    continue;
                };
                let Some(t) = tracks.get(name).and_then(|tr| at(tr, world_ms)) else {
                    continue;
                };
                let v = sub(t, o);
                let tr = axes.map(|a| dot(v, a));
                rows.push(PositionRow {
                    time_s: world_ms / 1000.0,
                    observer: p.drone.clone(),
                    drone: name.clone(),
                    est_x: n.pos[0],
                    est_y: n.pos[1],
                    est_z: n.pos[2],
                    sigma_m: sigma,
                    stable: n.stable as u8,
                    true_x: tr[0],
                    true_y: tr[1],
                    true_z: tr[2],
                });
            }
        }
    }
    rows
}

/// The estimates of one observer over time (x and y of every drone, the
/// truth beside each), and every drone's error (with `settle_s`, a second
/// panel from the observer's first estimate + `settle_s` on).
pub fn draw_plots(
    out: &Path,
    scenario: &Scenario,
    obs: &str,
    rows: &[PositionRow],
    names: (&str, &str),
    settle_s: Option<f64>,
) -> Result<Vec<PathBuf>, PlotError> {
    let mine: Vec<&PositionRow> = rows.iter().filter(|r| r.observer == obs).collect();
    if mine.is_empty() {
        return Ok(Vec::new());
    }
    let settled_from =
        settle_s.map(|s| mine.iter().map(|r| r.time_s).fold(f64::INFINITY, f64::min) + s);
    let series_from =
        |from: f64, drone: &str, label: String, f: &dyn Fn(&PositionRow) -> f64| Series {
            label,
            points: crate::plot::decimate(
                &mine
                    .iter()
                    .filter(|r| r.drone == drone && r.time_s >= from)
                    .map(|r| (r.time_s, f(r)))
                    .collect::<Vec<_>>(),
                4000,
            ),
        };
    let series = |drone: &str, label: String, f: &dyn Fn(&PositionRow) -> f64| {
        series_from(f64::NEG_INFINITY, drone, label, f)
    };
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    let mut errs = Vec::new();
    let mut settled = Vec::new();
    let seen: std::collections::BTreeSet<&str> = mine.iter().map(|r| r.drone.as_str()).collect();
    for p in scenario
        .platforms
        .iter()
        .filter(|p| seen.contains(p.drone.as_str()))
    {
        let d = p.drone.as_str();
        xs.push(series(d, format!("{d} estimated"), &|r| r.est_x));
        xs.push(series(d, format!("{d} true"), &|r| r.true_x));
        ys.push(series(d, format!("{d} estimated"), &|r| r.est_y));
        ys.push(series(d, format!("{d} true"), &|r| r.true_y));
        errs.push(series(d, d.to_string(), &|r| r.error()));
        if let Some(from) = settled_from {
            settled.push(series_from(from, d, d.to_string(), &|r| r.error()));
        }
    }
    let pos = out.join(names.0);
    panels(
        &pos,
        "world time (s)",
        &[
            (
                format!(
                    "{}: x estimated by {obs} (its frame) and true",
                    scenario.name
                ),
                "x (m)".into(),
                xs,
            ),
            (
                format!("{}: y estimated by {obs} and true", scenario.name),
                "y (m)".into(),
                ys,
            ),
        ],
        false,
    )?;
    let err = out.join(names.1);
    let mut charts = vec![(
        format!(
            "{}: position error of each drone as estimated by {obs}",
            scenario.name
        ),
        "|estimate − truth| (m)".to_string(),
        errs,
    )];
    if let (Some(from), Some(s)) = (settled_from, settle_s) {
        charts.push((
            format!("the same from {from:.2} s (after {s} s of start-up transient)"),
            "|estimate − truth| (m)".into(),
            settled,
        ));
    }
    panels(&err, "world time (s)", &charts, false)?;
    Ok(vec![pos, err])
}

/// What [`analyse`] found.
#[derive(Debug, Clone, Default)]
pub struct Positioning {
    pub plots: Vec<PathBuf>,
    /// Text for the run's report.
    pub text: String,
}

/// Why the positioning outputs cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum PositioningError {
    #[error("{}: {source}", path.display())]
    Csv { path: PathBuf, source: csv::Error },
    #[error("{}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// Reads every drone's console; if any holds estimates, writes
/// `positions.csv`, the tables (`positioning.md`) and the plots. `None`
/// when no firmware printed estimates (not a positioning run).
pub fn analyse(
    scenario: &Scenario,
    out: &Path,
    tracks: &BTreeMap<String, DroneTrack>,
    draw: bool,
) -> Result<Option<Positioning>, PositioningError> {
    let consoles: BTreeMap<String, SwarmConsole> = scenario
        .platforms
        .iter()
        .map(|p| {
            let path = crate::outputs::drone_dir(out, &p.drone).join(files::CONSOLE);
            let text = std::fs::read_to_string(path).unwrap_or_default();
            (p.drone.clone(), console::parse(&text))
        })
        .collect();
    if consoles.values().all(|c| c.estimates.is_empty()) {
        return Ok(None);
    }
    let rows = position_rows(scenario, &consoles, tracks);
    let csv_path = out.join(POSITIONS_CSV);
    let csv_err = |source| PositioningError::Csv {
        path: csv_path.clone(),
        source,
    };
    let mut w = csv::Writer::from_path(&csv_path).map_err(csv_err)?;
    for r in &rows {
        w.serialize(r).map_err(csv_err)?;
    }
    w.flush().map_err(|e| csv_err(e.into()))?;
    let spec = scenario.positioning.clone().unwrap_or_default();
    let tables = tables(scenario, &spec, &rows);
    let mut text = format!(
        "   positions      {} estimates in {}\n",
        rows.len(),
        csv_path.display()
    );
    let plotted = if spec.plot.is_empty() {
        observer(scenario, Some(&spec)).into_iter().collect()
    } else {
        spec.plot.clone()
    };
    let mut errors_md = String::new();
    if let Some(settle) = spec.settle_s {
        for obs in &plotted {
            if let Some((from, e)) = error_summary(scenario, obs, &rows, settle) {
                errors_md.push_str(&errors_markdown(obs, from, settle, &e));
            }
        }
    }
    if !tables.is_empty() || !errors_md.is_empty() {
        let md = if tables.is_empty() {
            format!("# {}: estimation error\n\n{errors_md}", scenario.name)
        } else {
            format!(
                "# {}: estimated positions (real, mean estimate, std; seed 003 §7.1)\n\n{}{errors_md}",
                scenario.name,
                tables_markdown(&tables)
            )
        };
        let p = out.join(POSITIONING_MD);
        std::fs::write(&p, &md).map_err(|source| PositioningError::Write {
            path: p.clone(),
            source,
        })?;
        text.push_str(&format!("   tables         {}\n\n{md}", p.display()));
    }
    if let Some(obs) = observer(scenario, Some(&spec)) {
        if let Some(me) = consoles.get(&obs).filter(|c| !c.load.is_empty()) {
            let others: Vec<&SwarmConsole> = consoles
                .iter()
                .filter(|(d, _)| **d != obs)
                .map(|(_, c)| c)
                .collect();
            let rows = super::load::load_rows(me, &others);
            let fw = scenario
                .platforms
                .iter()
                .find(|p| p.drone == obs)
                .map(|p| p.firmware.clone());
            let ram = fw.as_deref().and_then(super::load::ram);
            let md = super::load::load_markdown(&obs, &rows, ram);
            let p = out.join(super::load::LOAD_MD);
            std::fs::write(&p, &md).map_err(|source| PositioningError::Write {
                path: p.clone(),
                source,
            })?;
            text.push_str(&format!("   load           {}\n\n{md}\n", p.display()));
        }
    }
    let mut plots = Vec::new();
    if draw {
        for obs in &plotted {
            let names = if plotted.len() == 1 {
                (POSITIONS_PNG.to_string(), ERROR_PNG.to_string())
            } else {
                (
                    format!("positions_{obs}.png"),
                    format!("position_error_{obs}.png"),
                )
            };
            plots.extend(draw_plots(
                out,
                scenario,
                obs,
                &rows,
                (&names.0, &names.1),
                spec.settle_s,
            )?);
        }
    }
    Ok(Some(Positioning { plots, text }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_true_frame_is_the_seeds() {
        // B at (0,0), C at (1,0), A at (1,0.5), shifted and turned in the world.
        let (c, s) = (0.6f64.cos(), 0.6f64.sin());
        let w = |x: f64, y: f64| [3.0 + c * x - s * y, -1.0 + s * x + c * y, 0.8];
        let (o, axes) = true_frame(&[w(0.0, 0.0), w(1.0, 0.0), w(1.0, 0.5)]).unwrap();
        let v = sub(w(0.5, 0.25), o);
        let p = axes.map(|a| dot(v, a));
        for (got, want) in p.iter().zip([0.5, 0.25, 0.0]) {
            assert!((got - want).abs() < 1e-12, "{p:?}");
        }
        // Mirrored: the third reference on the other side flips y.
        let (o, axes) = true_frame(&[w(0.0, 0.0), w(1.0, 0.0), w(1.0, -0.5)]).unwrap();
        let p = axes.map(|a| dot(sub(w(0.5, 0.25), o), a));
        assert!((p[1] + 0.25).abs() < 1e-12);
        assert!(true_frame(&[w(0.0, 0.0), w(0.0, 0.0)]).is_none());
        // A third reference on the X axis: the horizontal perpendicular.
        let (o, axes) = true_frame(&[w(0.0, 0.0), w(1.0, 0.0), w(0.5, 0.0)]).unwrap();
        let p = axes.map(|a| dot(sub(w(0.5, 0.25), o), a));
        assert!((p[1] - 0.25).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn tracks_are_interpolated() {
        let t = DroneTrack {
            points: vec![(0, [0.0, 0.0, 0.0]), (10, [1.0, 2.0, 0.0])],
        };
        assert_eq!(at(&t, 5.0), Some([0.5, 1.0, 0.0]));
        assert_eq!(at(&t, 20.0), Some([1.0, 2.0, 0.0]));
    }

    #[test]
    fn an_estimate_is_at_its_printed_world_time_else_two_seconds_after_its_own() {
        let c = console::parse(
            "swarm t=1850 id=4 frame=built n=0 4=0,0,0,5,s world_us=9004000\n\
             swarm t=1850 id=4 frame=built n=0 4=0,0,0,5,s\n",
        );
        assert_eq!(world_ms(&c.estimates[0]), 9004.0);
        assert_eq!(world_ms(&c.estimates[1]), 3850.0);
    }
}
