//! What stands between two antennas (DESIGN.md §16): the world's boxes and
//! the other drones' bodies. A UWB frame whose direct path crosses one is
//! received over a non-line-of-sight path (its stamp later and noisier,
//! [`super::profile`]).

/// A box of the world (`[[box]]`, DESIGN.md §5): centre, full size along its
/// own axes, yaw about z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obstacle {
    pub centre: [f64; 3],
    pub size: [f64; 3],
    pub yaw: f64,
}

impl From<&crate::world_file::BoxDesc> for Obstacle {
    fn from(b: &crate::world_file::BoxDesc) -> Obstacle {
        Obstacle {
            centre: b.centre.0,
            size: [b.size[0].0, b.size[1].0, b.size[2].0],
            yaw: b.yaw.0,
        }
    }
}

/// A Crazyflie's body as the channel sees it: a vertical cylinder of the
/// PROTO's radius and height (`crate::crazyflie::BODY_RADIUS_M`, `_HEIGHT_M`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    pub radius: f64,
    pub height: f64,
}

/// The part `[t0, t1]` of `[0, 1]` where `p + t·d` lies in the slab
/// `lo ≤ x ≤ hi`, intersected with `(t0, t1)`; `None` when empty.
fn clip(p: f64, d: f64, lo: f64, hi: f64, (t0, t1): (f64, f64)) -> Option<(f64, f64)> {
    if d.abs() < 1e-15 {
        return (lo..=hi).contains(&p).then_some((t0, t1));
    }
    let (a, b) = ((lo - p) / d, (hi - p) / d);
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    let (t0, t1) = (t0.max(a), t1.min(b));
    (t0 <= t1).then_some((t0, t1))
}

impl Obstacle {
    /// Whether the segment from `a` to `b` passes through the box (slab
    /// method in the box's frame). A segment that starts inside counts.
    pub fn crosses(&self, a: [f64; 3], b: [f64; 3]) -> bool {
        let (s, c) = (-self.yaw).sin_cos();
        let local = |p: [f64; 3]| {
            let (x, y) = (p[0] - self.centre[0], p[1] - self.centre[1]);
            [c * x - s * y, s * x + c * y, p[2] - self.centre[2]]
        };
        let (pa, pb) = (local(a), local(b));
        let mut t = Some((0.0, 1.0));
        for k in 0..3 {
            let h = self.size[k] / 2.0;
            t = t.and_then(|t| clip(pa[k], pb[k] - pa[k], -h, h, t));
        }
        t.is_some()
    }
}

impl Body {
    /// Whether the segment from `a` to `b` passes through this body centred
    /// at `at`: clipped to the body's height, its horizontal distance to the
    /// axis is within the radius.
    pub fn crosses(&self, at: [f64; 3], a: [f64; 3], b: [f64; 3]) -> bool {
        let h = self.height / 2.0;
        let Some((t0, t1)) = clip(a[2], b[2] - a[2], at[2] - h, at[2] + h, (0.0, 1.0)) else {
            return false;
        };
        // The horizontal segment between t0 and t1, closest to the axis.
        let p = |t: f64| {
            [
                a[0] + t * (b[0] - a[0]) - at[0],
                a[1] + t * (b[1] - a[1]) - at[1],
            ]
        };
        let (p0, p1) = (p(t0), p(t1));
        let d = [p1[0] - p0[0], p1[1] - p0[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let u = if len2 > 0.0 {
            (-(p0[0] * d[0] + p0[1] * d[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [p0[0] + u * d[0], p0[1] + u * d[1]];
        q[0] * q[0] + q[1] * q[1] <= self.radius * self.radius
    }
}

/// Whether the direct path from drone `from` at `a` to drone `to` at `b`
/// crosses a box or the body of a third drone (`others`: every drone's
/// centre, by index).
pub fn blocked(
    boxes: &[Obstacle],
    body: Body,
    others: &[[f64; 3]],
    from: usize,
    to: usize,
    a: [f64; 3],
    b: [f64; 3],
) -> bool {
    boxes.iter().any(|o| o.crosses(a, b))
        || others
            .iter()
            .enumerate()
            .any(|(i, &c)| i != from && i != to && body.crosses(c, a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    const CF: Body = Body {
        radius: 0.05,
        height: 0.03,
    };

    #[test]
    fn a_box_blocks_only_the_segments_through_it() {
        // 1 m cube at (2, 0, 0.5), turned 45°.
        let o = Obstacle {
            centre: [2.0, 0.0, 0.5],
            size: [1.0; 3],
            yaw: std::f64::consts::FRAC_PI_4,
        };
        assert!(o.crosses([0.0, 0.0, 0.5], [4.0, 0.0, 0.5]));
        // Above it.
        assert!(!o.crosses([0.0, 0.0, 1.1], [4.0, 0.0, 1.1]));
        // Stops short of it: the turned cube reaches x = 2 − 0.707.
        assert!(!o.crosses([0.0, 0.0, 0.5], [1.25, 0.0, 0.5]));
        assert!(o.crosses([0.0, 0.0, 0.5], [1.35, 0.0, 0.5]));
        // Beside it: the corner reaches y = 0.707 at x = 2.
        assert!(!o.crosses([0.0, 0.75, 0.5], [4.0, 0.75, 0.5]));
        assert!(o.crosses([0.0, 0.65, 0.5], [4.0, 0.65, 0.5]));
    }

    #[test]
    fn a_drone_blocks_the_line_through_its_body() {
        let (a, b) = ([0.0, 0.0, 1.0], [2.0, 0.0, 1.0]);
        assert!(CF.crosses([1.0, 0.0, 1.0], a, b));
        assert!(CF.crosses([1.0, 0.049, 1.0], a, b));
        assert!(!CF.crosses([1.0, 0.051, 1.0], a, b));
        // Below the path by more than half its height.
        assert!(!CF.crosses([1.0, 0.0, 0.98], a, b));
        assert!(CF.crosses([1.0, 0.0, 0.99], a, b));
        // Behind the receiver.
        assert!(!CF.crosses([2.5, 0.0, 1.0], a, b));
        // A vertical path through it.
        assert!(CF.crosses([0.0, 0.0, 0.5], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]));
    }

    #[test]
    fn the_two_ends_do_not_block_themselves() {
        let pos = [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [1.0, 0.0, 1.0]];
        assert!(blocked(&[], CF, &pos, 0, 1, pos[0], pos[1]));
        assert!(!blocked(&[], CF, &pos[..2], 0, 1, pos[0], pos[1]));
        let off = [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [1.0, 0.3, 1.0]];
        assert!(!blocked(&[], CF, &off, 0, 1, off[0], off[1]));
    }
}
