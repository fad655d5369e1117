//! A sweep of a scenario whose firmware runs the network (DESIGN.md §13,
//! docs/NN.md "nn-race"): the gates and the `nn` block as columns, and
//! the latency and energy per inference against the cluster's cores, one
//! line per cluster clock (`sweep_nn.png`).

use std::path::Path;

use super::params::SweepRow;
use crate::plot::{self, PlotError, Series};

/// The plot's file name in the sweep directory.
pub const NN_PNG: &str = "sweep_nn.png";

/// Columns added when a run of the sweep reported an `nn` block; the last
/// four are the AI deck's (`crate::deck_report::COLUMNS`: its energy and
/// share, the flight time with and without it).
pub const NN_COLUMNS: [&str; 15] = [
    "gates_passed",
    "nn_inferences",
    "nn_cores",
    "nn_cluster_mhz",
    "nn_cycles_mean",
    "nn_cycles_max",
    "nn_mac_per_cycle",
    "nn_latency_ms",
    "nn_fps",
    "nn_energy_j",
    "nn_energy_per_inference_mj",
    crate::deck_report::COLUMNS[0],
    crate::deck_report::COLUMNS[1],
    crate::deck_report::COLUMNS[2],
    crate::deck_report::COLUMNS[3],
];

fn block(row: &SweepRow) -> Option<(&sim_core::kernel::Summary, &sim_core::kernel::NnSummary)> {
    let s = row.outcome.as_ref()?.summary.as_ref()?;
    Some((s, s.nn.as_ref()?))
}

/// Whether any run has the block (then the table has its columns).
pub fn any(rows: &[SweepRow]) -> bool {
    rows.iter().any(|r| block(r).is_some())
}

/// One run's cells of [`NN_COLUMNS`].
pub fn values(row: &SweepRow) -> Vec<String> {
    let Some((s, nn)) = block(row) else {
        return vec![String::new(); NN_COLUMNS.len()];
    };
    vec![
        s.gates_passed.map_or(String::new(), |g| g.to_string()),
        nn.inferences.to_string(),
        nn.cores.to_string(),
        nn.cluster_mhz.to_string(),
        format!("{:.0}", nn.cycles_per_inference.mean),
        nn.cycles_per_inference.max.to_string(),
        format!("{:.2}", nn.mac_per_cycle),
        format!("{:.3}", nn.latency_ms),
        format!("{:.2}", nn.fps),
        format!("{:.4}", nn.energy_j),
        format!("{:.4}", nn.energy_per_inference_mj),
    ]
    .into_iter()
    .chain(crate::deck_report::values(s.deck.as_ref()))
    .collect()
}

/// `sweep_nn.png` when the runs differ in cores or clock: latency and
/// energy per inference against the cores, a line per clock.
pub fn write_plot(rows: &[SweepRow], out: &Path) -> Result<(), PlotError> {
    let blocks: Vec<_> = rows.iter().filter_map(block).map(|(_, nn)| nn).collect();
    let varies =
        |f: fn(&sim_core::kernel::NnSummary) -> u64| blocks.iter().any(|b| f(b) != f(blocks[0]));
    if blocks.is_empty() || !(varies(|b| b.cores as u64) || varies(|b| b.cluster_mhz)) {
        return Ok(());
    }
    let mut clocks: Vec<u64> = blocks.iter().map(|b| b.cluster_mhz).collect();
    clocks.sort_unstable();
    clocks.dedup();
    let line = |y: fn(&sim_core::kernel::NnSummary) -> f64| -> Vec<Series> {
        clocks
            .iter()
            .map(|&mhz| {
                let mut points: Vec<(f64, f64)> = blocks
                    .iter()
                    .filter(|b| b.cluster_mhz == mhz && b.inferences > 0)
                    .map(|b| (b.cores as f64, y(b)))
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    label: format!("cluster at {mhz} MHz"),
                    points,
                }
            })
            .collect()
    };
    plot::panels(
        &out.join(NN_PNG),
        "cluster cores",
        &[
            (
                "Latency per inference (FC: frame copy, averaging, cluster power-up, network, decoding)"
                    .into(),
                "latency (ms)".into(),
                line(|b| b.latency_ms),
            ),
            (
                "Cluster energy per inference (its run energy / inferences)".into(),
                "energy (mJ)".into(),
                line(|b| b.energy_per_inference_mj),
            ),
        ],
        true,
    )
}
