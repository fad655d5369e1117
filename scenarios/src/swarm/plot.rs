//! The top view of a run with several drones: every drone's path in its own
//! colour (names in the legend), where each started, the gates and boxes of
//! the world, and the radio links: a line between two drones that received
//! frames from each other, thicker and darker the more frames (from the
//! world's radio log).

use std::path::Path;

use plotters::prelude::*;
use world_server::WorldDesc;

use crate::plot::{err, fonts, rect, square_view, top_chart, PlotError, FONT, PALETTE};

/// One drone's path seen from above.
#[derive(Debug, Clone)]
pub struct DronePath {
    pub name: String,
    /// (x, y) per world step.
    pub points: Vec<(f64, f64)>,
    /// Where it started (x, y).
    pub start: (f64, f64),
    pub targets: Vec<[f64; 3]>,
}

impl DronePath {
    /// Where the links of this drone are drawn: the mean of its path (its
    /// start if it has none). For a drone that stays put it is its place.
    pub fn anchor(&self) -> (f64, f64) {
        if self.points.is_empty() {
            return self.start;
        }
        let n = self.points.len() as f64;
        let (sx, sy) = self
            .points
            .iter()
            .fold((0.0, 0.0), |(a, b), p| (a + p.0, b + p.1));
        (sx / n, sy / n)
    }
}

/// Frames received between drones `a` and `b` (indices), both directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Link {
    pub a: usize,
    pub b: usize,
    pub frames: u64,
}

/// At most about `max` points of a path, evenly spaced, the last kept (a
/// path is not a signal: its extremes need no special care).
pub fn thin(points: &[(f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max || max < 2 {
        return points.to_vec();
    }
    let step = points.len().div_ceil(max - 1);
    let mut out: Vec<(f64, f64)> = points.iter().step_by(step).copied().collect();
    if out.last() != points.last() {
        out.extend(points.last());
    }
    out
}

/// The colour of the i-th drone (the same in every plot of the run).
pub fn drone_color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Draws the top view into `path`.
pub fn swarm_top_view(
    path: &Path,
    title: &str,
    drones: &[DronePath],
    links: &[Link],
    world: Option<&WorldDesc>,
) -> Result<(), PlotError> {
    fonts();
    let mut xs: Vec<f64> = Vec::new();
    let mut ys: Vec<f64> = Vec::new();
    for d in drones {
        xs.extend(d.points.iter().map(|p| p.0));
        ys.extend(d.points.iter().map(|p| p.1));
        xs.push(d.start.0);
        ys.push(d.start.1);
        for t in &d.targets {
            xs.push(t[0]);
            ys.push(t[1]);
        }
    }
    if let Some(w) = world {
        for g in &w.gates {
            xs.push(g.centre.0[0]);
            ys.push(g.centre.0[1]);
        }
    }
    // At least a metre across: drones that stay put would otherwise fill
    // the plot with a millimetre.
    let view = square_view(xs, ys, 0.15, 1.0);
    let root = BitMapBackend::new(path, (900, 900)).into_drawing_area();
    let mut chart = top_chart(&root, path, title, view)?;
    if let Some(w) = world {
        let gate_color = RGBColor(200, 160, 0);
        for g in &w.gates {
            let outer = g.inner.0 + 2.0 * g.bar.0;
            chart
                .draw_series(std::iter::once(Polygon::new(
                    rect(g.centre.0, g.bar.0.max(0.05), outer, g.yaw.0),
                    gate_color.filled(),
                )))
                .map_err(|e| err(path, e))?;
        }
        for b in &w.boxes {
            chart
                .draw_series(std::iter::once(Polygon::new(
                    rect(b.centre.0, b.size[0].0, b.size[1].0, b.yaw.0),
                    RGBColor(200, 200, 200).filled(),
                )))
                .map_err(|e| err(path, e))?;
        }
    }
    // Links under the paths, so a path stays visible across them.
    let most = links.iter().map(|l| l.frames).max().unwrap_or(0).max(1);
    let mut labels = Vec::new();
    for (k, l) in links.iter().filter(|l| l.frames > 0).enumerate() {
        let (Some(a), Some(b)) = (drones.get(l.a), drones.get(l.b)) else {
            continue;
        };
        let share = l.frames as f64 / most as f64;
        let width = 1 + (5.0 * share).round() as u32;
        let style = BLACK.mix(0.25 + 0.5 * share).stroke_width(width);
        let (pa, pb) = (a.anchor(), b.anchor());
        let drawn = chart
            .draw_series(std::iter::once(PathElement::new([pa, pb], style)))
            .map_err(|e| err(path, e))?;
        if k == 0 {
            drawn
                .label("radio link (width: frames received)")
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.5).stroke_width(3))
                });
        }
        labels.push((
            chart.backend_coord(&pa),
            chart.backend_coord(&pb),
            format!("{} frames", l.frames),
        ));
    }
    // The labels where they do not cover each other (a square swarm: the links of
    // a square of drones cross at the centre, and their mid-points with
    // them): each on its own line, at the first free place along it.
    let segments: Vec<_> = labels.iter().map(|(a, b, _)| (*a, *b)).collect();
    let sizes: Vec<_> = labels.iter().map(|(_, _, t)| label_size(t)).collect();
    let font = (FONT, 14).into_font().color(&BLACK.mix(0.8));
    for ((_, _, text), at) in labels.iter().zip(place_labels(&segments, &sizes)) {
        root.draw(&Text::new(text.clone(), at, font.clone()))
            .map_err(|e| err(path, e))?;
    }
    for (i, d) in drones.iter().enumerate() {
        let color = drone_color(i);
        chart
            .draw_series(LineSeries::new(
                d.points.iter().copied(),
                color.stroke_width(2),
            ))
            .map_err(|e| err(path, e))?
            .label(d.name.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(3)));
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(d.start)
                    + Circle::new((0, 0), 6, color.filled())
                    + Text::new(d.name.clone(), (8, 6), (FONT, 15).into_font().color(&color)),
            ))
            .map_err(|e| err(path, e))?;
        chart
            .draw_series(d.targets.iter().map(|t| {
                EmptyElement::at((t[0], t[1])) + Cross::new((0, 0), 6, color.stroke_width(2))
            }))
            .map_err(|e| err(path, e))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 14))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(|e| err(path, e))?;
    root.present().map_err(|e| err(path, e))
}

/// A pixel position on the drawing area.
type Px = (i32, i32);

/// The box of a link label at 14 px (DejaVu Sans: about 7.5 px a character).
fn label_size(text: &str) -> Px {
    ((text.chars().count() as f64 * 7.5).ceil() as i32, 16)
}

/// Where to put each label (its top-left corner, pixels): along its segment
/// at the first of the fractions 1/2, 1/3, 2/3, 1/4, 3/4, 1/6, 5/6 whose box,
/// centred there and lifted above the line, covers no label already placed;
/// at the middle when none is free.
fn place_labels(segments: &[(Px, Px)], sizes: &[Px]) -> Vec<Px> {
    const ALONG: [f64; 7] = [0.5, 1.0 / 3.0, 2.0 / 3.0, 0.25, 0.75, 1.0 / 6.0, 5.0 / 6.0];
    let mut placed: Vec<(Px, Px)> = Vec::new();
    for (&(a, b), &(w, h)) in segments.iter().zip(sizes) {
        let at = |f: f64| -> Px {
            let x = a.0 as f64 + f * (b.0 - a.0) as f64;
            let y = a.1 as f64 + f * (b.1 - a.1) as f64;
            (x.round() as i32 - w / 2, y.round() as i32 - h - 4)
        };
        let free = |p: Px| {
            placed.iter().all(|&(q, (qw, qh))| {
                p.0 + w <= q.0 || q.0 + qw <= p.0 || p.1 + h <= q.1 || q.1 + qh <= p.1
            })
        };
        let p = ALONG
            .iter()
            .map(|&f| at(f))
            .find(|&p| free(p))
            .unwrap_or_else(|| at(0.5));
        placed.push((p, (w, h)));
    }
    placed.into_iter().map(|(p, _)| p).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_links_get_labels_apart() {
        // A square's two diagonals and two sides through the same middle.
        let segments = [
            ((100, 100), (500, 500)),
            ((100, 500), (500, 100)),
            ((100, 300), (500, 300)),
            ((300, 100), (300, 500)),
        ];
        let sizes = [label_size("4102 frames"); 4];
        let at = place_labels(&segments, &sizes);
        for i in 0..4 {
            for j in 0..i {
                let (p, q, (w, h)) = (at[i], at[j], sizes[i]);
                let apart = p.0 + w <= q.0 || q.0 + w <= p.0 || p.1 + h <= q.1 || q.1 + h <= p.1;
                assert!(apart, "labels {i} and {j} overlap: {at:?}");
            }
        }
        // The first one is at the middle of its line, lifted above it.
        assert_eq!(at[0], (300 - sizes[0].0 / 2, 300 - 16 - 4));
    }

    #[test]
    fn a_swarm_top_view_is_a_png_and_anchors_are_means() {
        let d = |name: &str, x: f64| DronePath {
            name: name.into(),
            points: vec![(x, 0.0), (x + 0.2, 0.4)],
            start: (x, 0.0),
            targets: vec![[x, 1.0, 1.0]],
        };
        let drones = [d("A", 0.0), d("B", 1.5)];
        assert_eq!(drones[1].anchor(), (1.6, 0.2));
        let long: Vec<(f64, f64)> = (0..1001).map(|i| (i as f64, 0.0)).collect();
        let t = thin(&long, 100);
        assert!(t.len() <= 101 && t[0] == long[0] && t.last() == long.last());
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("top.png");
        let links = [Link {
            a: 0,
            b: 1,
            frames: 12,
        }];
        swarm_top_view(&p, "t", &drones, &links, None).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
    }
}
