//! The world's true floor plan at the flight height, and the map's score
//! against it (DESIGN.md §9: `coverage_pct`, `accuracy_pct`), as the
//! firmware's self-test scores its synthetic rooms (docs/EXPLORE.md).
//!
//! The obstacles are the footprints of every static box (gate bars and
//! legs included) whose height span contains the flight height: the map is
//! a 2D slice at that height (seed 004 §4.2.1.A). A map cell is:
//! - truly free if its whole square touches no footprint and it is inside
//!   the room: connected to the take-off cell through such cells (a flood
//!   fill, so the room needs no annotation and what lies outside its walls
//!   is never counted);
//! - truly occupied if its centre lies inside a footprint;
//! - otherwise (straddling a wall's face, or outside the room) not judged.
//!
//! Coverage: the share of truly free cells the map has observed (log-odds
//! not 0). Accuracy: of the observed cells whose truth is clear-cut, the
//! share whose class (free below 0, occupied above) matches. Free
//! coverage: truly free cells mapped free.

use sim_core::map_image::MapImage;
use world_server::scene::scene_boxes;
use world_server::WorldDesc;

/// An obstacle's footprint: an oriented rectangle (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    pub centre: [f64; 2],
    pub half: [f64; 2],
    pub yaw: f64,
}

impl Footprint {
    /// The rectangle's axes (unit vectors) in the world.
    fn axes(&self) -> [[f64; 2]; 2] {
        let (s, c) = self.yaw.sin_cos();
        [[c, s], [-s, c]]
    }

    /// True when the point lies inside (or on the edge).
    pub fn contains(&self, p: [f64; 2]) -> bool {
        let d = [p[0] - self.centre[0], p[1] - self.centre[1]];
        self.axes()
            .iter()
            .zip(self.half)
            .all(|(a, h)| (d[0] * a[0] + d[1] * a[1]).abs() <= h)
    }

    /// True when the open interiors of the rectangle and the axis-aligned
    /// square `[x0, x1] x [y0, y1]` overlap (separating axes: touching
    /// edges do not count).
    pub fn overlaps_square(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> bool {
        let sq_c = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
        let sq_h = [(x1 - x0) / 2.0, (y1 - y0) / 2.0];
        let ax = self.axes();
        let d = [self.centre[0] - sq_c[0], self.centre[1] - sq_c[1]];
        let candidates = [[1.0, 0.0], [0.0, 1.0], ax[0], ax[1]];
        candidates.iter().all(|n| {
            let dist = (d[0] * n[0] + d[1] * n[1]).abs();
            let r_sq = sq_h[0] * n[0].abs() + sq_h[1] * n[1].abs();
            let r_box = self.half[0] * (ax[0][0] * n[0] + ax[0][1] * n[1]).abs()
                + self.half[1] * (ax[1][0] * n[0] + ax[1][1] * n[1]).abs();
            // 1e-9 m: rounding at shared edges (a cell edge on a wall face).
            dist < r_sq + r_box - 1e-9
        })
    }
}

/// The obstacles of a world in the horizontal slice at `height_m`.
pub fn footprints(world: &WorldDesc, height_m: f64) -> Vec<Footprint> {
    scene_boxes(world)
        .iter()
        .filter(|b| (b.centre.z - height_m).abs() < b.half.z)
        .map(|b| Footprint {
            centre: [b.centre.x, b.centre.y],
            half: [b.half.x, b.half.y],
            yaw: b.yaw,
        })
        .collect()
}

/// A cell's truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Truth {
    Free,
    Occupied,
    /// Straddles an obstacle's edge, or lies outside the room.
    Unjudged,
}

/// The truth of every cell of a map's grid, row-major like the map.
#[derive(Debug, Clone, PartialEq)]
pub struct TruePlan {
    pub width: usize,
    pub height: usize,
    pub cells: Vec<Truth>,
}

/// Why the plan could not be laid on the map.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TruthError {
    #[error("the take-off point ({x:.3}, {y:.3}) m is outside the map's grid")]
    StartOutside { x: f64, y: f64 },
    #[error("the take-off point ({x:.3}, {y:.3}) m is inside an obstacle at the flight height")]
    StartInObstacle { x: f64, y: f64 },
}

impl TruePlan {
    /// The plan on `map`'s grid; `start` (m) is the take-off point in the
    /// map's frame.
    pub fn new(
        map: &MapImage,
        obstacles: &[Footprint],
        start: [f64; 2],
    ) -> Result<TruePlan, TruthError> {
        let (w, h) = (map.width, map.height);
        let c = map.cell_mm as f64 / 1000.0;
        let (ox, oy) = (
            map.origin_x_mm as f64 / 1000.0,
            map.origin_y_mm as f64 / 1000.0,
        );
        let mut touches = vec![false; w * h];
        let mut centre_in = vec![false; w * h];
        for iy in 0..h {
            for ix in 0..w {
                let (x0, y0) = (ox + ix as f64 * c, oy + iy as f64 * c);
                let centre = [x0 + c / 2.0, y0 + c / 2.0];
                let i = iy * w + ix;
                touches[i] = obstacles
                    .iter()
                    .any(|o| o.overlaps_square(x0, y0, x0 + c, y0 + c));
                centre_in[i] = obstacles.iter().any(|o| o.contains(centre));
            }
        }
        let (sx, sy) = ((start[0] - ox) / c, (start[1] - oy) / c);
        if sx < 0.0 || sy < 0.0 || sx >= w as f64 || sy >= h as f64 {
            return Err(TruthError::StartOutside {
                x: start[0],
                y: start[1],
            });
        }
        let s = sy as usize * w + sx as usize;
        if centre_in[s] || obstacles.iter().any(|o| o.contains(start)) {
            return Err(TruthError::StartInObstacle {
                x: start[0],
                y: start[1],
            });
        }
        // The room: cells free of obstacles, 4-connected to the take-off
        // cell. A take-off cell that touches a wall (the drone beside it)
        // seeds the fill from its free neighbours.
        let mut inside = vec![false; w * h];
        let mut stack = vec![s];
        while let Some(i) = stack.pop() {
            if inside[i] || (touches[i] && i != s) {
                continue;
            }
            inside[i] = true;
            let (ix, iy) = (i % w, i / w);
            if ix > 0 {
                stack.push(i - 1);
            }
            if ix + 1 < w {
                stack.push(i + 1);
            }
            if iy > 0 {
                stack.push(i - w);
            }
            if iy + 1 < h {
                stack.push(i + w);
            }
        }
        let cells = (0..w * h)
            .map(|i| {
                if inside[i] && !touches[i] {
                    Truth::Free
                } else if centre_in[i] {
                    Truth::Occupied
                } else {
                    Truth::Unjudged
                }
            })
            .collect();
        Ok(TruePlan {
            width: w,
            height: h,
            cells,
        })
    }
}

/// The map's score against the plan.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Quality {
    pub truth_free: usize,
    pub observed: usize,
    pub mapped_free: usize,
    pub judged: usize,
    pub correct: usize,
}

impl Quality {
    pub fn of(map: &MapImage, plan: &TruePlan) -> Quality {
        let mut q = Quality::default();
        for (l, t) in map.cells.iter().zip(&plan.cells) {
            let l = *l;
            if *t == Truth::Free {
                q.truth_free += 1;
                q.observed += (l != 0) as usize;
                q.mapped_free += (l < 0) as usize;
            }
            if l != 0 && *t != Truth::Unjudged {
                q.judged += 1;
                q.correct += match t {
                    Truth::Free => l < 0,
                    _ => l > 0,
                } as usize;
            }
        }
        q
    }

    fn pct(a: usize, b: usize) -> f64 {
        if b == 0 {
            0.0
        } else {
            100.0 * a as f64 / b as f64
        }
    }

    pub fn coverage_pct(&self) -> f64 {
        Self::pct(self.observed, self.truth_free)
    }

    pub fn accuracy_pct(&self) -> f64 {
        Self::pct(self.correct, self.judged)
    }

    pub fn free_coverage_pct(&self) -> f64 {
        Self::pct(self.mapped_free, self.truth_free)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(c: [f64; 2], half: f64, yaw: f64) -> Footprint {
        Footprint {
            centre: c,
            half: [half, half],
            yaw,
        }
    }

    #[test]
    fn overlap_by_separating_axes() {
        let b = square([0.0, 0.0], 0.5, 0.0);
        assert!(b.overlaps_square(0.4, 0.4, 0.6, 0.6));
        // Touching an edge is not overlapping.
        assert!(!b.overlaps_square(0.5, 0.0, 0.6, 0.1));
        // Turned 45°: its corner reaches 0.707 along x.
        let d = square([0.0, 0.0], 0.5, std::f64::consts::FRAC_PI_4);
        assert!(d.overlaps_square(0.65, -0.01, 0.7, 0.01));
        assert!(!d.overlaps_square(0.72, -0.01, 0.8, 0.01));
        // The square's corner near the diamond's edge, but outside it.
        assert!(!d.overlaps_square(0.4, 0.4, 0.5, 0.5));
        assert!(d.contains([0.7, 0.0]) && !d.contains([0.5, 0.5]));
    }

    /// A map of `w` x `h` cells of 100 mm from (−0.1, −0.1) m, all `l`.
    fn map(w: usize, h: usize, l: i8) -> MapImage {
        MapImage {
            width: w,
            height: h,
            cell_mm: 100,
            fov_cdeg: 400,
            origin_x_mm: -100,
            origin_y_mm: -100,
            lo_per_nat: 16,
            l_min: -32,
            l_max: 56,
            cells: vec![l; w * h],
        }
    }

    /// A room with its inside at [0.2, 1.0]² and walls 0.2 m thick.
    fn room() -> Vec<Footprint> {
        let wall = |c: [f64; 2], hx: f64, hy: f64| Footprint {
            centre: c,
            half: [hx, hy],
            yaw: 0.0,
        };
        vec![
            wall([0.6, 0.1], 0.55, 0.1),
            wall([0.6, 1.1], 0.55, 0.1),
            wall([0.1, 0.6], 0.1, 0.55),
            wall([1.1, 0.6], 0.1, 0.55),
        ]
    }

    #[test]
    fn the_room_is_flood_filled_from_the_start() {
        let m = map(12, 12, 0);
        let plan = TruePlan::new(&m, &room(), [0.55, 0.55]).unwrap();
        // Inside the walls: x, y in [0.2, 1.0]: 8 x 8 cells.
        let free = plan.cells.iter().filter(|t| **t == Truth::Free).count();
        assert_eq!(free, 64);
        assert_eq!(plan.cells[0], Truth::Unjudged); // outside the room
        assert_eq!(plan.cells[12 + 1], Truth::Occupied); // a wall's centre cell
                                                         // Scores: all observed free → coverage 100 %, and every judged
                                                         // wall cell mapped free is wrong.
        let q = Quality::of(&map(12, 12, -10), &plan);
        assert_eq!((q.truth_free, q.observed, q.mapped_free), (64, 64, 64));
        let walls = plan.cells.iter().filter(|t| **t == Truth::Occupied).count();
        assert_eq!((q.judged, q.correct), (64 + walls, 64));
        assert_eq!(Quality::of(&map(14, 14, 0), &plan).coverage_pct(), 0.0);
        assert_eq!(q.coverage_pct(), 100.0);
    }

    #[test]
    fn a_start_outside_or_in_an_obstacle_is_refused() {
        let m = map(14, 14, 0);
        assert!(matches!(
            TruePlan::new(&m, &room(), [5.0, 0.5]),
            Err(TruthError::StartOutside { .. })
        ));
        let e = TruePlan::new(&m, &room(), [0.1, 0.6]).unwrap_err();
        assert!(e.to_string().contains("inside an obstacle"), "{e}");
    }
}
