//! After a run: read the outputs sim-core and world-server wrote, draw the
//! plots and print the short summary.

use std::path::{Path, PathBuf};

use protocol::series;
use serde::de::DeserializeOwned;
use serde::Deserialize;
use sim_core::kernel::Summary;
use sim_core::power::log::{model_csv_name, POWER_CSV};
use sim_core::power::PowerModelKind;
use world_server::WorldDesc;

use crate::launch::RunStatus;
use crate::outputs::files;
use crate::plot::{self, Series};
pub use crate::rows::{ModelRow, PowerRow, TrajectoryRow};
use crate::scenario::Scenario;

/// File names of the plots of one run.
pub mod plots {
    pub const POWER: &str = "power_models.png";
    pub const BATTERY: &str = "battery.png";
    pub const TOP_VIEW: &str = "top_view.png";
}

/// Why the outputs of a run could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("cannot read {path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error(transparent)]
    Plot(#[from] plot::PlotError),
}

fn read_err(path: &Path, e: impl std::fmt::Display) -> ReportError {
    ReportError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Reads `summary.json`.
pub fn read_summary(out: &Path) -> Result<Summary, ReportError> {
    let path = out.join(files::SUMMARY);
    let text = std::fs::read_to_string(&path).map_err(|e| read_err(&path, e))?;
    serde_json::from_str(&text).map_err(|e| read_err(&path, e))
}

impl From<series::SeriesError> for ReportError {
    fn from(e: series::SeriesError) -> Self {
        read_err(&e.path, e.source)
    }
}

/// Reads every row of a series or CSV file into `T` (columns by header
/// name). `path` names the series in either form (`out/power.csv` reads
/// `out/power.csv.zst`, [`series::read`]); of a file whose writer died, the
/// valid prefix is read, with one warning saying what was dropped.
pub fn read_csv<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>, ReportError> {
    let text = series::read(path)?;
    if let Some(w) = text.warning() {
        tracing::warn!("{w}");
    }
    csv::Reader::from_reader(&text.bytes[..])
        .deserialize()
        .collect::<Result<Vec<T>, _>>()
        .map_err(|e| read_err(&text.path, e))
}

/// The first row of a series (`None`: no rows), without reading the rest:
/// a race's `power.csv` is tens of MB.
pub fn read_first<T: DeserializeOwned>(path: &Path) -> Result<Option<T>, ReportError> {
    let mut r = csv::Reader::from_reader(series::open(path)?);
    r.deserialize()
        .next()
        .transpose()
        .map_err(|e| read_err(&series::resolve(path), e))
}

/// The series a run's report reads, by their CSV names.
pub fn run_series() -> Vec<String> {
    std::iter::once(POWER_CSV.to_string())
        .chain(PowerModelKind::ALL.map(model_csv_name))
        .chain(std::iter::once(files::TRAJECTORY.to_string()))
        .collect()
}

/// One line per series of `out` whose writer stopped mid-file (a peer
/// killed mid-run): what was kept and what was dropped. Whole files cost a
/// read of their bytes, no decoding.
pub fn torn_series(out: &Path) -> Vec<String> {
    run_series()
        .iter()
        .map(|name| out.join(name))
        .filter(|p| series::exists(p) && !series::is_whole(p).unwrap_or(true))
        .filter_map(|p| series::read(&p).ok()?.warning())
        .collect()
}

/// Figures derived from a summary.
pub trait SummaryExt {
    /// Flight time extrapolated as the thesis does in §5.1 ("50 % of the
    /// charge in about 160 s ... an estimated battery life of about 330 s"):
    /// platform time / SOC used. `None` when no charge was used.
    fn flight_time_estimate_s(&self, soc_init: f64) -> Option<f64>;
}

impl SummaryExt for Summary {
    fn flight_time_estimate_s(&self, soc_init: f64) -> Option<f64> {
        let used = soc_init - self.battery.soc_end;
        (used > 1e-9).then(|| self.platform_time_s / used)
    }
}

/// The SOC at the start of the run (first row of `power.csv`), 1.0 if absent.
pub fn initial_soc(power: &[PowerRow]) -> f64 {
    power.first().map_or(1.0, |r| r.soc)
}

/// The columns of `power.csv` the battery plot uses.
#[derive(Debug, Clone, Deserialize)]
struct BatteryRow {
    time_s: f64,
    v_oc_v: f64,
    v_battery_v: f64,
    soc: f64,
}

/// The top of the power plot's shared axis: the largest power once the
/// propellers have run [`SETTLE_S`], with a margin. The take-off transient
/// before it (D'Andrea's and Stolaroff's accelerations, tens of W for a few
/// samples) would squash the flight into the bottom of the axis; it is
/// drawn at the edge and its peak named in the title.
fn power_ceiling(models: &[Vec<(f64, f64)>]) -> Option<f64> {
    let settled = models.iter().flat_map(|pts| {
        let t0 = pts.first().map_or(0.0, |p| p.0);
        pts.iter()
            .filter(move |p| p.0 >= t0 + SETTLE_S)
            .map(|p| p.1)
    });
    let top = settled.fold(f64::NEG_INFINITY, f64::max);
    (top.is_finite() && top > 0.0).then_some(top * 1.1)
}

/// Seconds of propeller time the take-off transient lasts, at most.
const SETTLE_S: f64 = 1.0;

/// The platform's two plots (Fig. 5.5): the three models' power, and the
/// battery's SOC and voltage, from the CSVs in `out`.
pub fn draw_power_plots(scenario: &Scenario, out: &Path) -> Result<[PathBuf; 2], ReportError> {
    let power: Vec<BatteryRow> = read_csv(&out.join(POWER_CSV))?;
    let mut models = Vec::new();
    for kind in PowerModelKind::ALL {
        let rows: Vec<ModelRow> = read_csv(&out.join(model_csv_name(kind)))?;
        // As the thesis's plotting script (§5.1): samples with the
        // propellers stopped are left out, they only stretch the axis.
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.mean_omega_rad_s > 0.0)
            .map(|r| (r.time_s, r.power_w))
            .collect();
        models.push((kind, pts));
    }
    let pts: Vec<Vec<(f64, f64)>> = models.iter().map(|(_, p)| p.clone()).collect();
    let peak = models
        .iter()
        .flat_map(|(k, p)| p.iter().map(move |q| (q.1, *k)))
        .fold(None, |m: Option<(f64, PowerModelKind)>, (v, k)| match m {
            Some((mv, _)) if mv >= v => m,
            _ => Some((v, k)),
        });
    let ceiling = power_ceiling(&pts);
    let factor = scenario.run.models.stolaroff_factor;
    let label = |k: PowerModelKind| match k {
        PowerModelKind::Empirical => "empirical (Eq. 3.1-3.3)".to_string(),
        PowerModelKind::DAndrea => "D'Andrea (Table 4.4)".to_string(),
        PowerModelKind::Stolaroff => {
            format!("Stolaroff (Table 4.5) x{factor} correction (sec. 5.1)")
        }
    };
    let off_scale = match (peak, ceiling) {
        (Some((p, k)), Some(c)) if p > c => {
            format!("; take-off peak {p:.1} W ({}) off the scale", k.name())
        }
        _ => String::new(),
    };
    let all: Vec<Series> = models
        .iter()
        .map(|(k, p)| Series {
            label: label(*k),
            points: plot::decimate(p, 4000),
        })
        .collect();
    let mut charts = vec![(
        format!("The three motor models on one axis{off_scale}"),
        "power (W)".to_string(),
        all.clone(),
    )];
    for s in all {
        charts.push((format!("{} model", s.label), "power (W)".into(), vec![s]));
    }
    let power_png = out.join(plots::POWER);
    plot::panels_in(
        &power_png,
        "time (s)",
        &charts,
        false,
        ceiling.map(|c| (0.0, c)),
    )?;

    let battery_png = out.join(plots::BATTERY);
    let soc: Vec<(f64, f64)> = power.iter().map(|r| (r.time_s, r.soc * 100.0)).collect();
    let volt: Vec<(f64, f64)> = power.iter().map(|r| (r.time_s, r.v_battery_v)).collect();
    let v_oc: Vec<(f64, f64)> = power.iter().map(|r| (r.time_s, r.v_oc_v)).collect();
    let model = scenario.run.get("battery").unwrap_or_default();
    // The thesis's battery (no internal resistance to speak of) follows its
    // fitted curve, which for the LiPol rises as the charge falls: said on
    // the plot, so that nobody reads it as a battery that charges itself.
    let rising = match (power.first(), power.last()) {
        (Some(a), Some(b)) => b.v_battery_v > a.v_battery_v && b.soc < a.soc,
        _ => false,
    };
    let load = scenario.run.get("battery_load").unwrap_or_default();
    let volt_title = if rising {
        format!(
            "Battery voltage: rises as the charge falls (the thesis's fitted curve; battery_load = {load})"
        )
    } else {
        format!("Battery voltage (battery_load = {load})")
    };
    let mut volt_series = vec![Series {
        label: "terminal".into(),
        points: plot::decimate(&volt, 4000),
    }];
    // The open-circuit curve too when the load visibly pulls the terminal
    // voltage under it (battery_load = sag).
    let sag = power
        .iter()
        .map(|r| r.v_oc_v - r.v_battery_v)
        .fold(0.0, f64::max);
    if sag > 0.01 {
        volt_series.push(Series {
            label: "open-circuit".into(),
            points: plot::decimate(&v_oc, 4000),
        });
    }
    plot::panels(
        &battery_png,
        "time (s)",
        &[
            (
                format!("Battery state of charge ({model})"),
                "SOC (%)".into(),
                vec![Series {
                    label: "SOC".into(),
                    points: plot::decimate(&soc, 4000),
                }],
            ),
            (volt_title, "V (V)".into(), volt_series),
        ],
        false,
    )?;
    Ok([power_png, battery_png])
}

/// Draws the three plots of a run in `world` into `out`; returns their paths.
pub fn draw_run_plots(
    scenario: &Scenario,
    world: &WorldDesc,
    out: &Path,
) -> Result<Vec<PathBuf>, ReportError> {
    let [power_png, battery_png] = draw_power_plots(scenario, out)?;

    let traj_path = out.join(files::TRAJECTORY);
    if !series::exists(&traj_path) {
        // Another world server (`--world-cmd`) writes no trajectory.
        tracing::warn!("no {}: no top view", traj_path.display());
        return Ok(vec![power_png, battery_png]);
    }
    let traj: Vec<TrajectoryRow> = read_csv(&traj_path)?;
    let flight: Vec<(f64, f64)> = traj.iter().map(|r| (r.x, r.y)).collect();
    let top_png = out.join(plots::TOP_VIEW);
    plot::top_view(
        &top_png,
        &format!("{}: flight seen from above", scenario.name),
        &flight,
        world,
        &scenario.targets,
    )?;
    Ok(vec![power_png, battery_png, top_png])
}

fn opt_s(v: Option<f64>) -> String {
    v.map_or("n/a".into(), |v| format!("{v:.3} s"))
}

/// The short human-readable summary printed at the end of `cosim run`.
pub fn summary_text(
    scenario: &Scenario,
    s: &Summary,
    status: &RunStatus,
    soc_init: f64,
    out: &Path,
    plots: &[PathBuf],
) -> String {
    let mut t = String::new();
    let result = match (&status.error, s.completed) {
        (None, true) => "completed".to_string(),
        (None, false) => "did not complete".to_string(),
        (Some(e), _) => format!("FAILED: {e}"),
    };
    t += &format!(
        "== {} ({}) — {result}\n",
        scenario.name, scenario.description
    );
    if !scenario.overrides.is_empty() {
        t += &format!("   overrides      {}\n", scenario.overrides_label());
    }
    t += &format!(
        "   setup          {} ms timestep, {} model, battery {}, sync {}\n",
        s.timestep_ms, s.power_model, s.battery.model, s.sync
    );
    // The world's gate count first: it is the race's result. The targets
    // are the firmware's SET_TARGETs; a firmware that moves its target
    // before reaching it (vision_race: standoff points, the seen gate) has
    // them counted as replaced, so the four add up to the total: a passing
    // race may reach few of them.
    if let Some(total) = s.gates_total {
        t += &format!(
            "   gates          {}/{total} passed (the world's count at STOP, DESIGN.md §10)\n",
            s.gates_passed.map_or("?".into(), |g| g.to_string())
        );
    }
    if s.targets_replaced > 0 {
        t += &format!(
            "   targets        {} set by the firmware: {} reached, {} moved on before reached (the firmware re-aimed), {} bypassed (UNLOCK_CYCLES), {} skipped (low battery)\n",
            s.targets_total,
            s.targets_reached,
            s.targets_replaced,
            s.targets_bypassed,
            s.targets_skipped_low_battery
        );
    } else {
        t += &format!(
            "   targets        {}/{} reached, {} bypassed (UNLOCK_CYCLES), {} skipped (low battery)\n",
            s.targets_reached, s.targets_total, s.targets_bypassed, s.targets_skipped_low_battery
        );
    }
    t += &format!(
        "   time           platform {:.3} s | world {} | world estimate {:.3} s | offset error {}\n",
        s.platform_time_s,
        opt_s(s.world_time_s),
        s.world_time_estimate_s,
        s.estimate_error_pct
            .map_or("n/a".into(), |e| format!("{e:.4} %")),
    );
    t += &format!(
        "   energy         empirical {:.1} J | D'Andrea {:.1} J | Stolaroff {:.1} J | from battery {:.1} J\n",
        s.energy_j.empirical, s.energy_j.dandrea, s.energy_j.stolaroff, s.energy_j.total
    );
    let flight = s
        .flight_time_estimate_s(soc_init)
        .map_or("n/a".into(), |f| format!("{f:.0} s"));
    t += &format!(
        "   battery        SOC {:.1} % -> {:.1} %{} | estimated flight time {flight}\n",
        soc_init * 100.0,
        s.battery.soc_end * 100.0,
        if s.battery.low_battery {
            " (LOW BATTERY)"
        } else {
            ""
        },
    );
    if let Some(d) = &s.deck {
        t += &crate::deck_report::line(d);
    }
    if let (Some(_), Some(target)) = (s.battery.empty_at_s, scenario.targets.last()) {
        // Unreadable CSVs (another world server writes no trajectory)
        // leave the line out; the summary above stands.
        let trajectory: Vec<TrajectoryRow> =
            read_csv(&out.join(files::TRAJECTORY)).unwrap_or_default();
        let power: Vec<PowerRow> = read_csv(&out.join(POWER_CSV)).unwrap_or_default();
        if let Some(line) = crate::endurance::report_line(target[2], &trajectory, &power, s) {
            t += &line;
        }
    }
    t += &format!(
        "   cost           {:.2} s wall, {:.2}x real time, {} instructions, {} messages, {} collisions\n",
        status.wall.as_secs_f64(),
        s.realtime_factor,
        s.instructions,
        s.messages,
        s.collisions.map_or("?".into(), |c| c.to_string()),
    );
    if let Some(p) = &s.pacing {
        t += &format!(
            "   pacing         pace {} asked, {:.3}x achieved over {:.1} s wall ({} steps) | lag behind the wall clock: worst {:.1} ms at {:.1} s, mean {:.2} ms\n",
            p.pace, p.achieved_pace, p.wall_s, p.steps, p.worst_lag_ms, p.worst_lag_at_s, p.mean_lag_ms
        );
        if let Some(w) = p.warning() {
            t += &format!("   WARNING        {w}\n");
        }
    }
    if let Some(d) = &s.flow_drift {
        t += &format!(
            "   flow drift     estimate - GPS: final {:.3} m, max {:.3} m, mean {:.3} m\n",
            d.final_m, d.max_m, d.mean_m
        );
    }
    if let Some(nn) = &s.nn {
        t += &format!(
            "   nn             {} inferences on {} cores at {} MHz: {:.0} cluster cycles (max {}), {:.2} MAC/cycle, latency {:.2} ms, {:.1} fps, cluster {:.3} J ({:.3} mJ per inference)\n",
            nn.inferences,
            nn.cores,
            nn.cluster_mhz,
            nn.cycles_per_inference.mean,
            nn.cycles_per_inference.max,
            nn.mac_per_cycle,
            nn.latency_ms,
            nn.fps,
            nn.energy_j,
            nn.energy_per_inference_mj,
        );
    }
    t += &format!("   outputs        {}\n", out.display());
    for p in plots {
        t += &format!("   plot           {}\n", p.display());
    }
    t
}
