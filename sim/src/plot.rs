//! Charts as SVG and PNG with `plotters`: scatter plots of labelled points in series (color per
//! series, marker shape per label), with linear or logarithmic axes. Text in the PNG needs a
//! system font (fontconfig; Debian's `fonts-dejavu-core`); the SVG names the font family only.

use std::path::{Path, PathBuf};

use plotters::coord::CoordTranslate;
use plotters::prelude::*;

/// One point of a series: its coordinates and the label its marker shape stands for.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// What the point is (e.g. a scene): one marker shape per distinct label.
    pub label: String,
}

/// A named set of points drawn in one color.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend name.
    pub name: String,
    /// Its points.
    pub points: Vec<Point>,
}

/// A scatter chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Scatter {
    /// Title above the plot.
    pub title: String,
    /// x axis caption.
    pub x_label: String,
    /// y axis caption.
    pub y_label: String,
    /// Logarithmic x axis.
    pub x_log: bool,
    /// Logarithmic y axis.
    pub y_log: bool,
    /// The series.
    pub series: Vec<Series>,
}

/// Why a chart could not be written.
#[derive(Debug, thiserror::Error)]
#[error("drawing {path}: {reason}")]
pub struct PlotError {
    /// The file being written.
    pub path: PathBuf,
    /// What went wrong.
    pub reason: String,
}

/// Series colors, in order.
const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

/// Marker shapes, one per label in order of first appearance.
const SHAPES: usize = 5;

/// Draws a marker of shape `shape` at `(x, y)`.
fn marker<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'_, DB, CT>,
    x: f64,
    y: f64,
    shape: usize,
    color: RGBColor,
) -> Result<(), String> {
    let style = color.filled();
    let r = 5;
    let res = match shape % SHAPES {
        0 => chart.draw_series(std::iter::once(Circle::new((x, y), r, style))),
        1 => chart.draw_series(std::iter::once(TriangleMarker::new((x, y), r + 1, style))),
        2 => chart.draw_series(std::iter::once(Cross::new(
            (x, y),
            r,
            color.stroke_width(2),
        ))),
        3 => chart.draw_series(std::iter::once(
            EmptyElement::at((x, y)) + Rectangle::new([(-r, -r), (r, r)], style),
        )),
        _ => chart.draw_series(std::iter::once(Circle::new(
            (x, y),
            r,
            color.stroke_width(2),
        ))),
    };
    res.map(|_| ()).map_err(|e| e.to_string())
}

/// The axis range of `values` (padded; positive for a log axis).
fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        (lo, hi) = if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.5, hi * 1.5)
    } else {
        let pad = ((hi - lo) * 0.08).max(1e-9);
        (if lo >= 0.0 { 0.0 } else { lo - pad }, hi + pad)
    }
}

/// Draws `chart` on `area`.
fn draw<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    chart: &Scatter,
) -> Result<(), String> {
    area.fill(&WHITE).map_err(|e| e.to_string())?;
    let points = || chart.series.iter().flat_map(|s| s.points.iter());
    let (x0, x1) = range(points().map(|p| p.x), chart.x_log);
    let (y0, y1) = range(points().map(|p| p.y), chart.y_log);
    let mut labels: Vec<&str> = Vec::new();
    for p in points() {
        if !labels.contains(&p.label.as_str()) {
            labels.push(&p.label);
        }
    }
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&chart.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60);
    macro_rules! finish {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            ctx.configure_mesh()
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .draw()
                .map_err(|e| e.to_string())?;
            for (k, s) in chart.series.iter().enumerate() {
                let color = COLORS[k % COLORS.len()];
                for p in &s.points {
                    let shape = labels.iter().position(|l| *l == p.label).unwrap_or(0);
                    if p.x.is_finite() && p.y.is_finite() {
                        marker(&mut ctx, p.x, p.y, shape, color)?;
                    }
                }
                ctx.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                    .map_err(|e| e.to_string())?
                    .label(s.name.as_str())
                    .legend(move |(x, y)| Circle::new((x, y), 5, color.filled()));
            }
            ctx.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    match (chart.x_log, chart.y_log) {
        (true, true) => finish!(builder
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(|e| e.to_string())?),
        (true, false) => finish!(builder
            .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
            .map_err(|e| e.to_string())?),
        (false, true) => finish!(builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(|e| e.to_string())?),
        (false, false) => finish!(builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?),
    }
    // The marker shapes' key, under the plot.
    let key: Vec<String> = labels
        .iter()
        .enumerate()
        .map(|(i, l)| format!("{} {l}", ["o", "^", "x", "[]", "()"][i % SHAPES]))
        .collect();
    area.draw_text(
        &format!("markers: {}", key.join("  ")),
        &("sans-serif", 13).into_font().color(&BLACK),
        (70, area.dim_in_pixel().1 as i32 - 16),
    )
    .map_err(|e| e.to_string())?;
    area.present().map_err(|e| e.to_string())
}

/// Writes `chart` as `<stem>.svg` and `<stem>.png` (900 x 600); returns both paths.
pub fn write_scatter(stem: &Path, chart: &Scatter) -> Result<(PathBuf, PathBuf), PlotError> {
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    let err = |path: &Path| {
        let path = path.to_path_buf();
        move |reason: String| PlotError { path, reason }
    };
    {
        let area = SVGBackend::new(&svg, (900, 600)).into_drawing_area();
        draw(&area, chart).map_err(err(&svg))?;
    }
    {
        let area = BitMapBackend::new(&png, (900, 600)).into_drawing_area();
        draw(&area, chart).map_err(err(&png))?;
    }
    Ok((svg, png))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_an_svg_and_a_png() {
        let dir = std::env::temp_dir().join(format!("vtq-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let chart = Scatter {
            title: "run time against error".into(),
            x_label: "wall s".into(),
            y_label: "|error| %".into(),
            x_log: true,
            y_log: false,
            series: vec![
                Series {
                    name: "sampled".into(),
                    points: vec![
                        Point {
                            x: 0.5,
                            y: 1.2,
                            label: "wknd".into(),
                        },
                        Point {
                            x: 2.0,
                            y: 0.4,
                            label: "sponza".into(),
                        },
                    ],
                },
                Series {
                    name: "analytical".into(),
                    points: vec![Point {
                        x: 0.1,
                        y: 20.0,
                        label: "wknd".into(),
                    }],
                },
            ],
        };
        let (svg, png) = write_scatter(&dir.join("chart"), &chart).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("<svg") && text.contains("run time against error"));
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
