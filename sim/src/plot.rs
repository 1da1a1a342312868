//! Charts as SVG and PNG with `plotters`: scatter plots of labelled points in series (color per
//! series, marker shape per label) with linear or logarithmic axes ([`Scatter`]), grouped or
//! stacked bar charts over categories with reference lines such as a paper's published values
//! ([`Bars`]), and line charts ([`Lines`]). Text is laid out and drawn into the PNG with
//! DejaVu Sans embedded in the binary (the `dejavu` crate; rasterized in Rust by `ab_glyph`,
//! see [`EmbeddedText`]), so charts need no system font, fontconfig or freetype; the SVG names
//! the font family only (`sans-serif`: the viewer's font).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;

mod text;
pub use text::{text_size, EmbeddedText};

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

/// The font families the charts name (plotters' default is `sans-serif`), all drawn with the
/// embedded DejaVu Sans.
const FAMILIES: [&str; 3] = ["sans-serif", "serif", "monospace"];

/// Registers the embedded font with plotters under [`FAMILIES`] (once per process); the
/// error says why the font data was refused.
pub fn register_fonts() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        // Other styles (bold, italic) fall back to this one; the charts use none.
        for family in FAMILIES {
            plotters::style::register_font(family, FontStyle::Normal, dejavu::sans::regular())
                .map_err(|_| format!("the embedded DejaVu Sans font ({family}) is not valid"))?;
        }
        Ok(())
    })
    .clone()
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

/// Reference-line colors, in order: apart from the series' so a paper's value is not read as a
/// series.
const REF_COLORS: [RGBColor; 5] = [
    RGBColor(40, 40, 40),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(150, 150, 40),
    RGBColor(127, 127, 127),
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
fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, chart: &Scatter) -> Result<(), String> {
    area.fill(&WHITE).map_err(|e| e.to_string())?;
    let points = || chart.series.iter().flat_map(|s| s.points.iter());
    let (x0, x1) = range(points().map(|p| p.x), chart.x_log);
    let (y0, y1) = range(points().map(|p| p.y), chart.y_log);
    // Room above the data for the legend (in decades on a logarithmic axis).
    let entries = chart.series.len();
    let y1 = if chart.y_log {
        let (l0, l1) = (y0.log10(), y1.log10());
        10f64.powf(with_legend_room(l0, l1, entries))
    } else {
        with_legend_room(y0, y1, entries)
    };
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

/// Draws with `draw_on` into `<stem>.svg` and `<stem>.png` (900 x 600); returns both paths.
fn write_both(
    stem: &Path,
    draw_svg: impl FnOnce(&DrawingArea<EmbeddedText<SVGBackend>, Shift>) -> Result<(), String>,
    draw_png: impl FnOnce(&DrawingArea<EmbeddedText<BitMapBackend>, Shift>) -> Result<(), String>,
) -> Result<(PathBuf, PathBuf), PlotError> {
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    let err = |path: &Path| {
        let path = path.to_path_buf();
        move |reason: String| PlotError { path, reason }
    };
    // Both backends lay text out with the registered font.
    register_fonts().map_err(err(&svg))?;
    {
        let area = EmbeddedText {
            inner: SVGBackend::new(&svg, (900, 600)),
            draw: false,
        }
        .into_drawing_area();
        draw_svg(&area).map_err(err(&svg))?;
    }
    {
        let area = EmbeddedText {
            inner: BitMapBackend::new(&png, (900, 600)),
            draw: true,
        }
        .into_drawing_area();
        draw_png(&area).map_err(err(&png))?;
    }
    Ok((svg, png))
}

/// Writes `chart` as `<stem>.svg` and `<stem>.png` (900 x 600); returns both paths.
pub fn write_scatter(stem: &Path, chart: &Scatter) -> Result<(PathBuf, PathBuf), PlotError> {
    write_both(stem, |a| draw(a, chart), |a| draw(a, chart))
}

/// A value series of a bar chart: one value per category (`None`: no bar).
#[derive(Debug, Clone, PartialEq)]
pub struct BarSeries {
    /// Legend name.
    pub name: String,
    /// Per category.
    pub values: Vec<Option<f64>>,
}

/// A horizontal reference line (e.g. a paper's published value) across a bar chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Legend name.
    pub name: String,
    /// Its value.
    pub value: f64,
}

/// A bar chart over categories: series side by side per category, or stacked.
#[derive(Debug, Clone, PartialEq)]
pub struct Bars {
    /// Title above the plot.
    pub title: String,
    /// y axis caption.
    pub y_label: String,
    /// Category names along x.
    pub categories: Vec<String>,
    /// The series.
    pub series: Vec<BarSeries>,
    /// Reference lines, dashed.
    pub references: Vec<Reference>,
    /// Stack the series instead of placing them side by side.
    pub stacked: bool,
}

/// Draws `chart` on `area`.
fn draw_bars<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    chart: &Bars,
) -> Result<(), String> {
    area.fill(&WHITE).map_err(|e| e.to_string())?;
    let n = chart.categories.len().max(1);
    let top = if chart.stacked {
        (0..n)
            .map(|i| {
                chart
                    .series
                    .iter()
                    .filter_map(|s| s.values.get(i).copied().flatten())
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    } else {
        chart
            .series
            .iter()
            .flat_map(|s| s.values.iter().flatten().copied())
            .fold(0.0, f64::max)
    };
    let top = chart
        .references
        .iter()
        .map(|r| r.value)
        .fold(top, f64::max)
        .max(1e-9);
    let top = with_legend_room(0.0, top, chart.series.len() + chart.references.len());
    let cats = chart.categories.clone();
    let mut ctx = ChartBuilder::on(area)
        .caption(&chart.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0f64..top)
        .map_err(|e| e.to_string())?;
    // Category i is centred on x = i, so the axis' whole-number ticks carry the names.
    ctx.configure_mesh()
        .disable_x_mesh()
        .x_labels(n + 1)
        .x_label_formatter(&|x: &f64| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                cats.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(chart.y_label.as_str())
        .draw()
        .map_err(|e| e.to_string())?;
    let k = chart.series.len().max(1) as f64;
    for (j, s) in chart.series.iter().enumerate() {
        let color = COLORS[j % COLORS.len()];
        let bars = s.values.iter().enumerate().filter_map(|(i, v)| {
            let v = (*v)?;
            let (x0, x1, y0) = if chart.stacked {
                let below: f64 = chart.series[..j]
                    .iter()
                    .filter_map(|t| t.values.get(i).copied().flatten())
                    .sum();
                (i as f64 - 0.35, i as f64 + 0.35, below)
            } else {
                let w = 0.8 / k;
                let x = i as f64 - 0.4 + w * j as f64;
                (x, x + w * 0.92, 0.0)
            };
            Some(Rectangle::new([(x0, y0), (x1, y0 + v)], color.filled()))
        });
        ctx.draw_series(bars)
            .map_err(|e| e.to_string())?
            .label(s.name.as_str())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], color.filled()));
    }
    references(&mut ctx, &chart.references, (-0.5, n as f64 - 0.5))?;
    finish_legend(&mut ctx)?;
    area.present().map_err(|e| e.to_string())
}

/// Writes the bar chart as `<stem>.svg` and `<stem>.png`; returns both paths.
pub fn write_bars(stem: &Path, chart: &Bars) -> Result<(PathBuf, PathBuf), PlotError> {
    write_both(stem, |a| draw_bars(a, chart), |a| draw_bars(a, chart))
}

/// The top of a y range `bottom..top` raised so that a legend of `entries` entries in the upper
/// right corner stays above the data.
fn with_legend_room(bottom: f64, top: f64, entries: usize) -> f64 {
    top + (top - bottom) * (0.08 + 0.055 * entries as f64)
}

/// Draws `refs` as dashed horizontal lines across `x`, each with its legend entry.
fn references<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
    ctx: &mut ChartContext<'_, DB, CT>,
    refs: &[Reference],
    (x0, x1): (f64, f64),
) -> Result<(), String> {
    for (j, r) in refs.iter().enumerate() {
        let color = REF_COLORS[j % REF_COLORS.len()];
        let step = (x1 - x0) / 60.0;
        let dashes = (0..60).step_by(2).map(|q| {
            let x = x0 + q as f64 * step;
            PathElement::new(
                vec![(x, r.value), (x + step, r.value)],
                color.stroke_width(2),
            )
        });
        ctx.draw_series(dashes)
            .map_err(|e| e.to_string())?
            .label(r.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 12, y)], color.stroke_width(2))
            });
    }
    Ok(())
}

/// Draws the legend of the series labelled so far, in the upper right corner.
fn finish_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate<From = (f64, f64)>>(
    ctx: &mut ChartContext<'a, DB, CT>,
) -> Result<(), String> {
    ctx.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())
}

/// A line of a line chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Legend name.
    pub name: String,
    /// Its points, by x.
    pub points: Vec<(f64, f64)>,
}

/// A line chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Lines {
    /// Title above the plot.
    pub title: String,
    /// x axis caption.
    pub x_label: String,
    /// y axis caption.
    pub y_label: String,
    /// The lines.
    pub lines: Vec<Line>,
    /// Reference lines, dashed.
    pub references: Vec<Reference>,
}

/// Draws `chart` on `area`.
fn draw_lines<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    chart: &Lines,
) -> Result<(), String> {
    area.fill(&WHITE).map_err(|e| e.to_string())?;
    let points = || chart.lines.iter().flat_map(|l| l.points.iter());
    let (x0, x1) = range(points().map(|p| p.0), false);
    let (y0, y1) = range(
        points()
            .map(|p| p.1)
            .chain(chart.references.iter().map(|r| r.value)),
        false,
    );
    // Non-negative data from zero, with room above it for the legend.
    let y0 = if y0 >= 0.0 { 0.0 } else { y0 };
    let y1 = with_legend_room(y0, y1, chart.lines.len() + chart.references.len());
    let mut ctx = ChartBuilder::on(area)
        .caption(&chart.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    ctx.configure_mesh()
        .x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .draw()
        .map_err(|e| e.to_string())?;
    for (j, l) in chart.lines.iter().enumerate() {
        let color = COLORS[j % COLORS.len()];
        ctx.draw_series(LineSeries::new(
            l.points.iter().copied(),
            color.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?
        .label(l.name.as_str())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 12, y)], color.stroke_width(2)));
    }
    references(&mut ctx, &chart.references, (x0, x1))?;
    finish_legend(&mut ctx)?;
    area.present().map_err(|e| e.to_string())
}

/// Writes the line chart as `<stem>.svg` and `<stem>.png`; returns both paths.
pub fn write_lines(stem: &Path, chart: &Lines) -> Result<(PathBuf, PathBuf), PlotError> {
    write_both(stem, |a| draw_lines(a, chart), |a| draw_lines(a, chart))
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
        let bars = Bars {
            title: "speedup".into(),
            y_label: "x".into(),
            categories: vec!["a".into(), "b".into()],
            series: vec![
                BarSeries {
                    name: "vtq".into(),
                    values: vec![Some(1.5), Some(2.0)],
                },
                BarSeries {
                    name: "prefetch".into(),
                    values: vec![Some(1.1), None],
                },
            ],
            references: vec![Reference {
                name: "paper".into(),
                value: 1.95,
            }],
            stacked: false,
        };
        let (svg, _) = write_bars(&dir.join("bars"), &bars).unwrap();
        assert!(std::fs::read_to_string(svg).unwrap().contains("paper"));
        let lines = Lines {
            title: "miss rate over time".into(),
            x_label: "cycle".into(),
            y_label: "rate".into(),
            lines: vec![Line {
                name: "baseline".into(),
                points: vec![(0.0, 0.6), (1.0, 0.62)],
            }],
            references: vec![],
        };
        let (_, png) = write_lines(&dir.join("lines"), &lines).unwrap();
        assert!(std::fs::metadata(png).unwrap().len() > 1000);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
