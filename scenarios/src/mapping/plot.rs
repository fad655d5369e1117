//! `map.png`: the firmware's map beside the world's true floor plan, on the
//! same grid and scale (seed 004 Figures 5.1-5.2 put the map beside the
//! room). Map: grey level = p(occupied) (white free, black occupied), light
//! blue never observed; the goals numbered in order, 0 the take-off point.
//! Plan: white free, black occupied, grey not judged (wall faces, outside).

use std::path::Path;

use plotters::prelude::*;
use serde::Serialize;

use super::truth::{Quality, TruePlan, Truth};
use crate::plot::{err, fonts, PlotError, FONT};
use sim_core::map_image::MapImage;

/// A frontier goal (exploration.csv row): simulated time (s) and position
/// (m, world frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Goal {
    pub time_s: f64,
    pub x: f64,
    pub y: f64,
}

const UNKNOWN: RGBColor = RGBColor(190, 215, 235);

pub(super) fn map_png(
    path: &Path,
    map: &MapImage,
    plan: &TruePlan,
    offset: [f64; 2],
    goals: &[Goal],
    start: [f64; 2],
    q: &Quality,
) -> Result<(), PlotError> {
    fonts();
    let c = map.cell_mm as f64 / 1000.0;
    let x0 = map.origin_x_mm as f64 / 1000.0 + offset[0];
    let y0 = map.origin_y_mm as f64 / 1000.0 + offset[1];
    let (x1, y1) = (x0 + map.width as f64 * c, y0 + map.height as f64 * c);
    // Each panel keeps a metre as long across as up.
    let panel_w = 800u32;
    let plot_h = ((panel_w - 70) as f64 * (y1 - y0) / (x1 - x0)).ceil() as u32;
    let height = (plot_h + 110).clamp(300, 1400);
    let root = BitMapBackend::new(path, (2 * panel_w, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(path, e))?;
    let (left, right) = root.split_horizontally(panel_w);
    let titles = [
        format!(
            "map: {} cm cells, FOV {}°, coverage {:.1} %, accuracy {:.1} %",
            map.cell_mm as f64 / 10.0,
            map.fov_cdeg as f64 / 100.0,
            q.coverage_pct(),
            q.accuracy_pct()
        ),
        "true floor plan at the flight height".to_string(),
    ];
    for (k, area) in [left, right].iter().enumerate() {
        let mut chart = ChartBuilder::on(area)
            .caption(&titles[k], (FONT, 17))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(path, e))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .draw()
            .map_err(|e| err(path, e))?;
        let cells = (0..map.height).flat_map(|iy| (0..map.width).map(move |ix| (ix, iy)));
        let colour = |ix: usize, iy: usize| -> RGBColor {
            if k == 0 {
                match map.p_occupied(ix, iy) {
                    None => UNKNOWN,
                    Some(p) => {
                        let g = (255.0 * (1.0 - p)).round() as u8;
                        RGBColor(g, g, g)
                    }
                }
            } else {
                match plan.cells[iy * plan.width + ix] {
                    Truth::Free => WHITE,
                    Truth::Occupied => BLACK,
                    Truth::Unjudged => RGBColor(160, 160, 160),
                }
            }
        };
        chart
            .draw_series(cells.map(|(ix, iy)| {
                let (a, b) = (x0 + ix as f64 * c, y0 + iy as f64 * c);
                Rectangle::new([(a, b), (a + c, b + c)], colour(ix, iy).filled())
            }))
            .map_err(|e| err(path, e))?;
        if k == 0 {
            let blue = RGBColor(20, 60, 220);
            let pts: Vec<(f64, f64)> = std::iter::once((start[0], start[1]))
                .chain(goals.iter().map(|g| (g.x, g.y)))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), blue.stroke_width(1)))
                .map_err(|e| err(path, e))?;
            chart
                .draw_series(pts.iter().enumerate().map(|(i, &(x, y))| {
                    EmptyElement::at((x, y))
                        + Circle::new((0, 0), 5, blue.filled())
                        + Text::new(i.to_string(), (6, -16), (FONT, 15).into_font().color(&blue))
                }))
                .map_err(|e| err(path, e))?;
        }
    }
    root.present().map_err(|e| err(path, e))
}
