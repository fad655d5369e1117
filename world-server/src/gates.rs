//! Gates passed (DESIGN.md §10): a gate counts as passed when the drone's
//! centre crosses the gate's plane in its direction of travel (the world
//! file's `yaw`) at a point inside the square opening (`inner`, bars
//! excluded). Each gate counts once per drone, in any order: the count is the
//! number of distinct gates passed, which the STOP reply (`GATES_PASSED`),
//! the trajectory's `gates_passed` column and `summary.json` carry.
//!
//! The crossing is checked after every physics step between the centre's
//! positions before and after it (linear interpolation in between), so a
//! crossing is found at any speed.

use rapier3d::glamx::DVec3;

use crate::world_file::WorldDesc;

/// A gate's opening: its plane and extent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateOpening {
    pub centre: DVec3,
    /// Unit normal along the direction of travel.
    pub normal: DVec3,
    /// Unit horizontal vector across the opening.
    pub across: DVec3,
    /// Half the inner side (m).
    pub half: f64,
}

impl GateOpening {
    /// Whether the segment `from` → `to` crosses the opening in the
    /// direction of travel.
    pub fn crossed(&self, from: DVec3, to: DVec3) -> bool {
        let s0 = (from - self.centre).dot(self.normal);
        let s1 = (to - self.centre).dot(self.normal);
        if !(s0 < 0.0 && s1 >= 0.0) {
            return false;
        }
        let t = s0 / (s0 - s1);
        let q = from + (to - from) * t - self.centre;
        q.dot(self.across).abs() < self.half && q.z.abs() < self.half
    }
}

/// The openings of a world file's gates, in file order.
pub fn openings(desc: &WorldDesc) -> Vec<GateOpening> {
    desc.gates
        .iter()
        .map(|g| {
            let (sin, cos) = g.yaw.0.sin_cos();
            GateOpening {
                centre: DVec3::from_array(g.centre.0),
                normal: DVec3::new(cos, sin, 0.0),
                across: DVec3::new(-sin, cos, 0.0),
                half: g.inner.0 / 2.0,
            }
        })
        .collect()
}

/// Every drone's passed gates.
#[derive(Debug, Clone)]
pub struct GateTracker {
    gates: Vec<GateOpening>,
    /// Per drone: the centre after the last step, and which gates it passed.
    drones: Vec<(DVec3, Vec<bool>)>,
}

impl GateTracker {
    /// Drones start at `starts` (world-file order).
    pub fn new(gates: Vec<GateOpening>, starts: &[DVec3]) -> Self {
        let n = gates.len();
        GateTracker {
            gates,
            drones: starts.iter().map(|p| (*p, vec![false; n])).collect(),
        }
    }

    /// Drone `d` is now at `to` (after a physics step).
    pub fn moved(&mut self, d: usize, to: DVec3) {
        let (from, passed) = &mut self.drones[d];
        for (g, p) in self.gates.iter().zip(passed.iter_mut()) {
            if !*p && g.crossed(*from, to) {
                *p = true;
                tracing::debug!(drone = d, gate = ?g.centre, "gate passed");
            }
        }
        *from = to;
    }

    /// Drone `d` was placed at `at` (no crossing).
    pub fn placed(&mut self, d: usize, at: DVec3) {
        self.drones[d].0 = at;
    }

    /// Distinct gates drone `d` has passed.
    pub fn passed(&self, d: usize) -> u64 {
        self.drones[d].1.iter().filter(|p| **p).count() as u64
    }

    /// Number of gates in the world.
    pub fn total(&self) -> u64 {
        self.gates.len() as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gate() -> GateOpening {
        // Centre (1, 2, 1), travel along +y (yaw π/2), 0.8 m opening.
        GateOpening {
            centre: DVec3::new(1.0, 2.0, 1.0),
            normal: DVec3::new(0.0, 1.0, 0.0),
            across: DVec3::new(-1.0, 0.0, 0.0),
            half: 0.4,
        }
    }

    #[test]
    fn crossing_inside_the_opening_in_the_travel_direction_counts() {
        let g = gate();
        assert!(g.crossed(DVec3::new(1.0, 1.9, 1.0), DVec3::new(1.0, 2.1, 1.0)));
        // Off-centre but inside: 0.39 m across, 0.39 m up.
        assert!(g.crossed(DVec3::new(0.61, 1.5, 1.39), DVec3::new(0.61, 2.5, 1.39)));
        // Backwards, beside, above: no.
        assert!(!g.crossed(DVec3::new(1.0, 2.1, 1.0), DVec3::new(1.0, 1.9, 1.0)));
        assert!(!g.crossed(DVec3::new(1.41, 1.9, 1.0), DVec3::new(1.41, 2.1, 1.0)));
        assert!(!g.crossed(DVec3::new(1.0, 1.9, 1.41), DVec3::new(1.0, 2.1, 1.41)));
        // Not reaching the plane: no.
        assert!(!g.crossed(DVec3::new(1.0, 1.0, 1.0), DVec3::new(1.0, 1.99, 1.0)));
        // A diagonal segment whose crossing point is inside, though its
        // ends are beside the opening.
        assert!(g.crossed(DVec3::new(0.0, 1.0, 1.0), DVec3::new(2.0, 3.0, 1.0)));
    }

    #[test]
    fn each_gate_counts_once_per_drone_in_any_order() {
        let g2 = GateOpening {
            centre: DVec3::new(1.0, 4.0, 1.0),
            ..gate()
        };
        let mut t = GateTracker::new(vec![gate(), g2], &[DVec3::new(1.0, 5.0, 1.0)]);
        assert_eq!(t.total(), 2);
        // The second gate first (teleported before it), then the first,
        // then back and forth through the first again.
        t.placed(0, DVec3::new(1.0, 3.5, 1.0));
        t.moved(0, DVec3::new(1.0, 4.5, 1.0));
        assert_eq!(t.passed(0), 1);
        t.placed(0, DVec3::new(1.0, 1.5, 1.0));
        for y in [2.5, 1.5, 2.5] {
            t.moved(0, DVec3::new(1.0, y, 1.0));
        }
        assert_eq!(t.passed(0), 2);
    }
}
