//! The time-against-error chart: one series per method, one line per shape joining its sizes.

use super::contenders::Family;
use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

/// One method on one mesh.
pub struct Point {
    pub method: &'static str,
    pub family: Family,
    pub size_label: String,
    pub time_ms: f64,
    pub mean_error_degrees: f64,
}

/// Colours by method, in the order methods first appear in the points.
const COLORS: [RGBColor; 8] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
];

/// Smallest error drawn: a log axis cannot show zero.
const ERROR_FLOOR: f64 = 1e-6;

/// Powers of ten enclosing all values (log axes read best on decade bounds), with some room so
/// that no point sits on the frame.
fn decade_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() || !hi.is_finite() || lo <= 0.0 {
        return 0.1..10.0;
    }
    let lo = 10f64.powf((lo.log10() - 0.2).floor());
    let hi = 10f64.powf((hi.log10() + 0.2).ceil());
    if hi > lo { lo..hi } else { lo..lo * 10.0 }
}

/// Draws the chart as SVG. `labelled_method` gets its sphere points annotated with the mesh
/// size; more labels would only clutter the picture, and every line runs from small to large.
pub fn draw(path: &Path, points: &[Point], labelled_method: &str) -> Result<(), Box<dyn Error>> {
    let mut methods: Vec<&'static str> = Vec::new();
    for p in points {
        if !methods.contains(&p.method) {
            methods.push(p.method);
        }
    }
    let x_range = decade_range(points.iter().map(|p| p.time_ms));
    let y_range = decade_range(points.iter().map(|p| p.mean_error_degrees.max(ERROR_FLOOR)));

    let root = SVGBackend::new(path, (1100, 750)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Tangent error against time, single thread (circles: UV sphere, triangles: torus)",
            ("sans-serif", 22),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x_range.log_scale(), y_range.log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time per mesh, ms (median; lines join 20k, 200k and 2M triangles)")
        .y_desc("mean angle to exact dP/du, degrees")
        .x_label_formatter(&|v| format!("{v}"))
        .y_label_formatter(&|v| format!("{v:e}"))
        .draw()?;

    for (i, &method) in methods.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let mut in_legend = false;
        for family in [Family::Sphere, Family::Torus] {
            let mut line: Vec<&Point> = points
                .iter()
                .filter(|p| p.method == method && p.family == family)
                .collect();
            if line.is_empty() {
                continue;
            }
            line.sort_by(|a, b| a.time_ms.total_cmp(&b.time_ms));
            let xy = |p: &Point| (p.time_ms, p.mean_error_degrees.max(ERROR_FLOOR));
            let series = chart.draw_series(LineSeries::new(
                line.iter().map(|p| xy(p)),
                color.stroke_width(2),
            ))?;
            // One legend entry per method, whichever shape comes first.
            if !in_legend {
                in_legend = true;
                series.label(method).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            }
            for p in &line {
                match family {
                    Family::Torus => {
                        chart.draw_series(std::iter::once(TriangleMarker::new(
                            xy(p),
                            6,
                            color.filled(),
                        )))?;
                    }
                    _ => {
                        chart.draw_series(std::iter::once(Circle::new(
                            xy(p),
                            5,
                            color.filled(),
                        )))?;
                    }
                }
                // Sphere and torus of one size land close together: label one of them.
                if method == labelled_method && family == Family::Sphere {
                    chart.draw_series(std::iter::once(
                        EmptyElement::at(xy(p))
                            + Text::new(p.size_label.clone(), (6, -16), ("sans-serif", 13)),
                    ))?;
                }
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
