//! The platform's clock mapped to the world's, as the bookkeeping of
//! DESIGN.md §3 sees it: platform time = world time + offset, the offset
//! being `sensors_offset + sim_off_accum` as accounted so far.
//!
//! The platform's own logs (`power.csv`, the console) carry platform time,
//! which runs ahead of the world by the offsets (seconds by the end of a
//! race). [`TimeMapRecorder`] keeps the knots of the piecewise-linear map
//! platform → world, one where the bookkeeping changes it, and writes them
//! as `time_map.csv` (`platform_ps,world_ps`) so that `cosim` can put those
//! logs on the world's time base (`run.mcap`, docs/FOXGLOVE.md).
//!
//! Between knots the map is linear: over a device delay the world runs
//! with the platform (scaled by the rounding of §3 when the delay was not a
//! whole number of steps), over core time outside delays it stands still.
//! Knots on a straight line are merged, so a drone ticking its clock in
//! whole steps has a handful of rows for the whole run.

use std::io::Write;
use std::path::Path;

use protocol::series::{SeriesFormat, SeriesWriter};

use crate::units::Picos;

/// File name of the map in a platform's output directory.
pub const TIME_MAP_CSV: &str = "time_map.csv";

/// One point of the map: platform time (ps) and world time (ps).
pub type Knot = (u64, i64);

/// Collects the knots as the bookkeeping runs.
#[derive(Debug, Clone, Default)]
pub struct TimeMapRecorder {
    knots: Vec<Knot>,
    /// The last knot, still open: the bookkeeping may move its world time
    /// (a delay's rounding is applied after its platform time was counted).
    open: Option<Knot>,
}

impl TimeMapRecorder {
    /// The map at platform time `platform`: world time `world` (ps).
    pub fn note(&mut self, platform: Picos, world: i64) {
        match &mut self.open {
            Some((p, w)) if *p == platform.0 => *w = world,
            _ => {
                if let Some(k) = self.open.take() {
                    self.commit(k);
                }
                self.open = Some((platform.0, world));
            }
        }
    }

    /// Appends `k`, dropping the last knot when it lies on the straight
    /// line from the one before it to `k`.
    fn commit(&mut self, k: Knot) {
        if let [.., a, b] = self.knots[..] {
            if b != k && collinear(a, b, k) {
                self.knots.pop();
            }
        }
        if self.knots.last() != Some(&k) {
            self.knots.push(k);
        }
    }

    /// Every knot, the open one included.
    pub fn knots(&self) -> Vec<Knot> {
        let mut r = self.clone();
        if let Some(k) = r.open.take() {
            r.commit(k);
        }
        r.knots
    }

    /// Writes `time_map.csv` into `dir`, in the run's form for series
    /// (`time_map.csv.zst` compressed: the race's 22,044 knots are 0.67 MB
    /// plain, 52 kB compressed).
    pub fn write(&self, dir: &Path, form: SeriesFormat) -> std::io::Result<()> {
        let mut f = SeriesWriter::create(&dir.join(form.file_name(TIME_MAP_CSV)))?;
        writeln!(f, "platform_ps,world_ps")?;
        for (p, w) in self.knots() {
            writeln!(f, "{p},{w}")?;
        }
        f.finish()
    }
}

fn collinear(a: Knot, b: Knot, c: Knot) -> bool {
    let (dp1, dw1) = (b.0 as i128 - a.0 as i128, b.1 as i128 - a.1 as i128);
    let (dp2, dw2) = (c.0 as i128 - b.0 as i128, c.1 as i128 - b.1 as i128);
    dp1 * dw2 == dp2 * dw1 && dp1 >= 0 && dp2 >= 0
}

/// World time (ps) at platform time `p` on the map of `knots` (sorted by
/// platform time): linear between knots, the last knot's world time after
/// it, the first knot's offset before it.
pub fn world_at(knots: &[Knot], p: u64) -> i64 {
    let i = knots.partition_point(|k| k.0 <= p);
    if i == 0 {
        // Before the first knot, the first knot's offset (none: identity).
        return match knots.first() {
            Some(&(p0, w0)) => (p as i64 - p0 as i64 + w0).max(0),
            None => p as i64,
        };
    }
    let (p0, w0) = knots[i - 1];
    match knots.get(i) {
        None => w0,
        Some(&(p1, w1)) => {
            let span = (p1 - p0) as i128;
            w0 + ((p - p0) as i128 * (w1 - w0) as i128 / span) as i64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collinear_knots_merge_and_a_moved_knot_keeps_its_neighbour() {
        let mut r = TimeMapRecorder::default();
        r.note(Picos(0), 0);
        r.note(Picos(10), 10);
        r.note(Picos(20), 20);
        // The rounding takes 1 back from the knot just noted.
        r.note(Picos(20), 19);
        r.note(Picos(30), 19); // core time: the world stands
        assert_eq!(r.knots(), vec![(0, 0), (10, 10), (20, 19), (30, 19)]);
    }

    #[test]
    fn the_map_is_linear_between_knots_and_flat_after_the_last() {
        let k = [(0, 0), (10, 10), (20, 19), (30, 19)];
        assert_eq!(world_at(&k, 5), 5);
        assert_eq!(world_at(&k, 15), 14); // 10 + 5 · 9/10, rounded down
        assert_eq!(world_at(&k, 25), 19);
        assert_eq!(world_at(&k, 40), 19);
        assert_eq!(world_at(&[], 7), 7);
    }
}
