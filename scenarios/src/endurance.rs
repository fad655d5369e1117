//! When a hovering drone could no longer hold its height (DESIGN.md §16,
//! docs/COSIM.md "Hover until the battery cannot hold it"): with
//! `battery_load = "sag"` the motors' top speed falls with the battery's
//! terminal voltage, and near empty it falls below the hover speed. The
//! report names the instant the drone sank below 80 % of its last
//! target's height (0.8 m for hover-endurance's 1 m, the mark it is judged by),
//! having reached 95 % of it first, with the battery's state then.

use crate::rows::{PowerRow, TrajectoryRow};
use sim_core::kernel::Summary;

/// The mark: the height lost is 20 % of the target's.
const SINK_FRACTION: f64 = 0.8;
/// The drone must first have held the height (within 5 %).
const REACHED_FRACTION: f64 = 0.95;

/// The instant a drone sank below the mark, and the battery then.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightLoss {
    /// The mark, m (80 % of the target's height).
    pub mark_m: f64,
    /// World time of the first trajectory row below the mark, s.
    pub world_s: f64,
    /// The platform time of that instant, s: the world time scaled by the
    /// run's platform/world time ratio (the thesis sync's drift, §3).
    pub platform_s: f64,
    /// SOC (fraction) and terminal voltage (V) at the first power sample
    /// at or after `platform_s`.
    pub soc: f64,
    pub v_terminal: f64,
}

/// The height loss of a run that flew to `target_z`, or `None` when it
/// never reached the height or never lost it. `ratio`: the run's platform
/// time over its world time.
pub fn height_loss(
    target_z: f64,
    trajectory: &[TrajectoryRow],
    power: &[PowerRow],
    ratio: f64,
) -> Option<HeightLoss> {
    if target_z <= 0.0 {
        return None;
    }
    let mark_m = SINK_FRACTION * target_z;
    let mut reached = false;
    let row = trajectory.iter().find(|r| {
        reached |= r.z > REACHED_FRACTION * target_z;
        reached && r.z < mark_m
    })?;
    let world_s = row.time_ms as f64 / 1000.0;
    let platform_s = world_s * ratio;
    let sample = power
        .iter()
        .find(|p| p.time_s >= platform_s)
        .or(power.last())?;
    Some(HeightLoss {
        mark_m,
        world_s,
        platform_s,
        soc: sample.soc,
        v_terminal: sample.v_battery_v,
    })
}

/// The report's line for a run whose battery ran empty (`None` otherwise).
pub fn report_line(
    target_z: f64,
    trajectory: &[TrajectoryRow],
    power: &[PowerRow],
    summary: &Summary,
) -> Option<String> {
    let empty = summary.battery.empty_at_s?;
    let ratio = match summary.world_time_s {
        Some(w) if w > 0.0 => summary.platform_time_s / w,
        _ => 1.0,
    };
    let held = match height_loss(target_z, trajectory, power, ratio) {
        Some(h) => format!(
            "below {:.2} m at world {:.1} s (platform {:.1} s), SOC {:.1} %, terminal {:.2} V",
            h.mark_m,
            h.world_s,
            h.platform_s,
            h.soc * 100.0,
            h.v_terminal
        ),
        None => format!("held {:.2} m to the end", SINK_FRACTION * target_z),
    };
    Some(format!(
        "   endurance      {held}; battery empty at platform {empty:.1} s\n"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn traj(points: &[(u64, f64)]) -> Vec<TrajectoryRow> {
        points
            .iter()
            .map(|&(time_ms, z)| TrajectoryRow {
                time_ms,
                x: 0.0,
                y: 0.0,
                z,
            })
            .collect()
    }

    fn power(points: &[(f64, f64, f64)]) -> Vec<PowerRow> {
        points
            .iter()
            .map(|&(time_s, soc, v)| PowerRow {
                time_s,
                i_battery_a: 0.0,
                v_battery_v: v,
                soc,
            })
            .collect()
    }

    #[test]
    fn the_take_off_is_not_a_sink_and_the_first_row_below_the_mark_is() {
        // Climbs through 0.5 m (below the mark, not yet reached), holds,
        // sinks: the instant is the first row under 0.8 m after 0.95 m.
        let t = traj(&[
            (0, 0.0),
            (1000, 0.5),
            (2000, 0.97),
            (3000, 1.0),
            (4000, 0.85),
            (5000, 0.79),
            (6000, 0.1),
        ]);
        let p = power(&[(0.0, 1.0, 4.1), (5.0, 0.02, 2.7), (5.5, 0.019, 2.6)]);
        let h = height_loss(1.0, &t, &p, 1.0).unwrap();
        assert_eq!(h.world_s, 5.0);
        assert_eq!((h.soc, h.v_terminal), (0.02, 2.7));
        assert!((h.mark_m - 0.8).abs() < 1e-12);
    }

    #[test]
    fn platform_time_follows_the_runs_drift() {
        let t = traj(&[(0, 1.0), (4000, 0.7)]);
        let p = power(&[(4.0, 0.5, 3.9), (4.4, 0.4, 3.8)]);
        // Platform 10 % ahead of the world: world 4 s is platform 4.4 s.
        let h = height_loss(1.0, &t, &p, 1.1).unwrap();
        assert!((h.platform_s - 4.4).abs() < 1e-9);
        assert_eq!(h.soc, 0.4);
    }

    #[test]
    fn a_drone_that_never_reached_or_never_sank_has_no_height_loss() {
        let p = power(&[(0.0, 1.0, 4.1)]);
        assert_eq!(
            height_loss(1.0, &traj(&[(0, 0.0), (1000, 0.9)]), &p, 1.0),
            None
        );
        assert_eq!(
            height_loss(1.0, &traj(&[(0, 1.0), (1000, 0.9)]), &p, 1.0),
            None
        );
    }
}
