//! PNG plots of a run and of a sweep, drawn like the thesis's figures:
//! the three motor models' power over time (Fig. 5.5, top), the battery's
//! SOC and voltage (Fig. 5.5, bottom), the flight seen from above with the
//! gates and the targets, and overlays for sweeps (Figs. 5.6, 5.11, 5.17;
//! Tables 5.1–5.4 as wall time against the timestep).

use std::path::Path;
use std::sync::Once;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use world_server::WorldDesc;

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw {path}: {message}")]
pub struct PlotError {
    pub path: String,
    pub message: String,
}

/// A named series of (x, y) points.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

pub(crate) const FONT: &str = "sans-serif";

/// plotters draws text only with a registered font; the DejaVu font ships
/// in the crate so the plots look the same on every machine.
pub(crate) fn fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../assets/DejaVuSans.ttf");
        for style in [FontStyle::Normal, FontStyle::Bold] {
            if register_font(FONT, style, bytes).is_err() {
                // Cannot happen with the shipped file; plots would lack text.
                tracing::error!("the embedded DejaVuSans.ttf was refused by plotters");
            }
        }
    });
}

pub(crate) fn err(path: &Path, e: impl std::fmt::Display) -> PlotError {
    PlotError {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Keeps at most about `max` points: the minimum and the maximum of each
/// bucket, in time order, so short spikes (the D'Andrea and Stolaroff
/// transients of Fig. 5.5) stay visible after thinning 150 000 samples.
pub fn decimate(points: &[(f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max || max < 4 {
        return points.to_vec();
    }
    let per = points.len().div_ceil(max / 2);
    let mut out = Vec::with_capacity(max + 2);
    for chunk in points.chunks(per) {
        let (mut lo, mut hi) = (0, 0);
        for (i, p) in chunk.iter().enumerate() {
            if p.1 < chunk[lo].1 {
                lo = i;
            }
            if p.1 > chunk[hi].1 {
                hi = i;
            }
        }
        let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        out.push(chunk[a]);
        if b != a {
            out.push(chunk[b]);
        }
    }
    out
}

/// Range of the values with a margin (a flat series gets a visible band).
pub(crate) fn span(values: impl Iterator<Item = f64>, margin: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * margin).max(1e-3 * hi.abs().max(1.0));
    (lo - pad, hi + pad)
}

pub(crate) const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// More points than this in a chart 1000 px wide: drawn one pixel wide.
const DENSE_POINTS: usize = 1500;

/// One line chart in `area`; `y_range` fixes the y axis (points beyond it
/// are drawn at its edge), else it spans the points.
fn line_chart(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    markers: bool,
    y_range: Option<(f64, f64)>,
) -> Result<(), String> {
    let xs = span(
        series.iter().flat_map(|s| s.points.iter().map(|p| p.0)),
        0.0,
    );
    let ys = y_range.unwrap_or_else(|| {
        span(
            series.iter().flat_map(|s| s.points.iter().map(|p| p.1)),
            0.05,
        )
    });
    let clamp = |(x, y): (f64, f64)| (x, y.clamp(ys.0, ys.1));
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 20))
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(xs.0..xs.1, ys.0..ys.1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        // A series denser than the pixels (a decimated 1 ms log) zigzags
        // within a pixel column; plotters joins thick lines with miters,
        // which at such sharp turns shoot needles far off the chart (the
        // race's take-off looked like a spike off the top). One pixel wide
        // has no joins.
        let width = if s.points.len() > DENSE_POINTS { 1 } else { 2 };
        let drawn = chart
            .draw_series(LineSeries::new(
                s.points.iter().copied().map(clamp),
                color.stroke_width(width),
            ))
            .map_err(|e| e.to_string())?;
        if series.len() > 1 {
            drawn.label(s.label.clone()).legend(move |(x, y)| {
                PathElement::new([(x, y), (x + 20, y)], color.stroke_width(3))
            });
        }
        if markers {
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|&p| Circle::new(clamp(p), 4, color.filled())),
                )
                .map_err(|e| e.to_string())?;
        }
    }
    if series.len() > 1 {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT, 14))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Stacked panels, one chart each: (title, y label, series); `markers`
/// draws the points too.
pub fn panels(
    path: &Path,
    x_label: &str,
    charts: &[(String, String, Vec<Series>)],
    markers: bool,
) -> Result<(), PlotError> {
    panels_in(path, x_label, charts, markers, None)
}

/// As [`panels`], every panel on the y range `y_range` (a shared axis, so
/// that the panels compare at a glance).
pub fn panels_in(
    path: &Path,
    x_label: &str,
    charts: &[(String, String, Vec<Series>)],
    markers: bool,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    fonts();
    let height = 300 * charts.len().max(1) as u32;
    let root = BitMapBackend::new(path, (1000, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(path, e))?;
    let areas = root.split_evenly((charts.len().max(1), 1));
    for (area, (title, y_label, series)) in areas.iter().zip(charts) {
        line_chart(area, title, x_label, y_label, series, markers, y_range)
            .map_err(|e| err(path, e))?;
    }
    root.present().map_err(|e| err(path, e))
}

/// One chart with several series (sweep overlays); `markers` draws the points.
pub fn overlay(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    markers: bool,
) -> Result<(), PlotError> {
    fonts();
    let root = BitMapBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(path, e))?;
    line_chart(&root, title, x_label, y_label, series, markers, None).map_err(|e| err(path, e))?;
    root.present().map_err(|e| err(path, e))
}

/// The four corners of a rectangle of size (sx, sy) centred at c, turned by yaw.
pub(crate) fn rect(c: [f64; 3], sx: f64, sy: f64, yaw: f64) -> Vec<(f64, f64)> {
    let (s, k) = yaw.sin_cos();
    [
        (-1.0, -1.0),
        (1.0, -1.0),
        (1.0, 1.0),
        (-1.0, 1.0),
        (-1.0, -1.0),
    ]
    .iter()
    .map(|(a, b)| {
        let (dx, dy) = (a * sx / 2.0, b * sy / 2.0);
        (c[0] + k * dx - s * dy, c[1] + s * dx + k * dy)
    })
    .collect()
}

/// The x and y ranges of a top view: the points' span with `margin` (a
/// fraction of it) on each side, widened to a square at least `min_side`
/// metres across so that a metre is as long across as up.
pub(crate) fn square_view(
    xs: Vec<f64>,
    ys: Vec<f64>,
    margin: f64,
    min_side: f64,
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (x0, x1) = span(xs.into_iter(), margin);
    let (y0, y1) = span(ys.into_iter(), margin);
    let side = (x1 - x0).max(y1 - y0).max(min_side);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    (
        cx - side / 2.0..cx + side / 2.0,
        cy - side / 2.0..cy + side / 2.0,
    )
}

/// A top view's chart: metres on both axes.
pub(crate) type TopChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A top view's chart on `root` (cleared to white): title, metre axes, mesh.
pub(crate) fn top_chart<'a, 'b: 'a>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    path: &Path,
    title: &str,
    (xr, yr): (std::ops::Range<f64>, std::ops::Range<f64>),
) -> Result<TopChart<'a, 'b>, PlotError> {
    root.fill(&WHITE).map_err(|e| err(path, e))?;
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(xr, yr)
        .map_err(|e| err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| err(path, e))?;
    Ok(chart)
}

/// The flight from above: the path (x, y), the gates as seen from above
/// (a bar across the direction of travel, its opening marked), boxes,
/// the targets numbered, and the start.
pub fn top_view(
    path: &Path,
    title: &str,
    flight: &[(f64, f64)],
    world: &WorldDesc,
    targets: &[[f64; 3]],
) -> Result<(), PlotError> {
    fonts();
    let mut xs: Vec<f64> = flight.iter().map(|p| p.0).collect();
    let mut ys: Vec<f64> = flight.iter().map(|p| p.1).collect();
    for g in &world.gates {
        xs.push(g.centre.0[0]);
        ys.push(g.centre.0[1]);
    }
    for t in targets {
        xs.push(t[0]);
        ys.push(t[1]);
    }
    let start = world.start.position.0;
    xs.push(start[0]);
    ys.push(start[1]);
    let view = square_view(xs, ys, 0.08, 0.0);
    let root = BitMapBackend::new(path, (900, 900)).into_drawing_area();
    let mut chart = top_chart(&root, path, title, view)?;
    let gate_color = RGBColor(200, 160, 0);
    for (i, g) in world.gates.iter().enumerate() {
        let outer = g.inner.0 + 2.0 * g.bar.0;
        // Seen from above a gate is a bar of length `outer` across the
        // direction of travel (yaw) and `bar` deep.
        let s = chart
            .draw_series(std::iter::once(Polygon::new(
                rect(g.centre.0, g.bar.0.max(0.05), outer, g.yaw.0),
                gate_color.filled(),
            )))
            .map_err(|e| err(path, e))?;
        if i == 0 {
            s.label("gate").legend(move |(x, y)| {
                Rectangle::new([(x, y - 4), (x + 20, y + 4)], gate_color.filled())
            });
        }
    }
    for b in &world.boxes {
        chart
            .draw_series(std::iter::once(Polygon::new(
                rect(b.centre.0, b.size[0].0, b.size[1].0, b.yaw.0),
                RGBColor(120, 120, 120).filled(),
            )))
            .map_err(|e| err(path, e))?;
    }
    let blue = PALETTE[0];
    chart
        .draw_series(LineSeries::new(
            flight.iter().copied(),
            blue.stroke_width(2),
        ))
        .map_err(|e| err(path, e))?
        .label("flight")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], blue.stroke_width(3)));
    let red = PALETTE[1];
    chart
        .draw_series(targets.iter().enumerate().map(|(i, t)| {
            EmptyElement::at((t[0], t[1]))
                + Cross::new((0, 0), 7, red.stroke_width(3))
                + Text::new(
                    format!("{}", i + 1),
                    (8, -18),
                    (FONT, 15).into_font().color(&red),
                )
        }))
        .map_err(|e| err(path, e))?
        .label("target")
        .legend(move |(x, y)| Cross::new((x + 10, y), 6, red.stroke_width(3)));
    let green = PALETTE[2];
    chart
        .draw_series(std::iter::once(Circle::new(
            (start[0], start[1]),
            8,
            green.filled(),
        )))
        .map_err(|e| err(path, e))?
        .label("start")
        .legend(move |(x, y)| Circle::new((x + 10, y), 6, green.filled()));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_the_extremes_and_the_order() {
        let pts: Vec<(f64, f64)> = (0..10_000)
            .map(|i| (i as f64, if i == 4321 { 50.0 } else { (i % 7) as f64 }))
            .collect();
        let d = decimate(&pts, 500);
        assert!(d.len() <= 502, "{}", d.len());
        assert!(d.contains(&(4321.0, 50.0)));
        assert!(d.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(decimate(&pts[..10], 500).len(), 10);
    }

    #[test]
    fn rect_turns_about_its_centre() {
        let r = rect([1.0, 2.0, 0.0], 2.0, 0.0, std::f64::consts::FRAC_PI_2);
        // Length 2 along x turned by 90 degrees lies along y.
        assert!((r[0].0 - 1.0).abs() < 1e-12 && (r[0].1 - 1.0).abs() < 1e-12);
        assert!((r[1].0 - 1.0).abs() < 1e-12 && (r[1].1 - 3.0).abs() < 1e-12);
    }

    #[test]
    fn a_plot_is_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.png");
        let s = Series {
            label: "a".into(),
            points: vec![(0.0, 1.0), (1.0, 2.0)],
        };
        overlay(&p, "t", "x", "y", &[s.clone(), s], true).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
    }
}
