//! The AI deck's line in the printed summary and its columns in a sweep's
//! table (`summary.json`'s `deck` block, docs/AIDECK_POWER.md).

use sim_core::power::deck::DeckSummary;

/// The summary's `deck` line: the deck's energy and share, and the flight
/// time with and without it.
pub fn line(d: &DeckSummary) -> String {
    let s = |v: Option<f64>| v.map_or("n/a".into(), |f| format!("{f:.0} s"));
    format!(
        "   AI deck        {:.2} J from the battery ({:.2} % of it), {:.1} mW mean, {:.2} mAh | flight time {} ({} without the deck)\n",
        d.energy_j,
        d.share_pct,
        d.mean_power_w * 1e3,
        d.charge_mah,
        s(d.flight_time_s),
        s(d.flight_time_without_deck_s),
    )
}

/// Columns a sweep's table gets when a run reported a `deck` block.
pub const COLUMNS: [&str; 4] = [
    "deck_energy_j",
    "deck_share_pct",
    "flight_time_s",
    "flight_time_without_deck_s",
];

/// One run's cells of [`COLUMNS`] (empty without a block).
pub fn values(d: Option<&DeckSummary>) -> Vec<String> {
    let Some(d) = d else {
        return vec![String::new(); COLUMNS.len()];
    };
    let s = |v: Option<f64>| v.map_or(String::new(), |f| format!("{f:.1}"));
    vec![
        format!("{:.4}", d.energy_j),
        format!("{:.3}", d.share_pct),
        s(d.flight_time_s),
        s(d.flight_time_without_deck_s),
    ]
}
