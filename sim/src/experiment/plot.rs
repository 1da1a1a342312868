//! Charts as SVG and PNG with `plotters`, drawn as a careful author would for print: scatter
//! plots of labelled points in series (colour per series, marker shape per label, optional 95%
//! intervals as error bars, optionally joined by lines) on linear or logarithmic axes
//! ([`Scatter`]), grouped or stacked bar charts over categories with reference lines such as a
//! paper's published values ([`Bars`]), and line charts ([`Lines`]). Every chart has its legend
//! in a band between the title and the plot, never over the data, each entry showing the mark
//! its series is drawn with; axes run between round numbers with plain tick labels (`100`,
//! `1,000`; [`axis`]), and a rate's axis can be fixed to 0-100% (`y_range`).
//!
//! Text is laid out and drawn into the PNG with DejaVu Sans embedded in the binary (the
//! `dejavu` crate; rasterized in Rust by `ab_glyph`, see [`EmbeddedText`]), so charts need no
//! system font, fontconfig or freetype; the SVG names the font family only (`sans-serif`: the
//! viewer's font).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;

pub mod axis;
mod draw;
mod frame;
pub mod legend;
mod text;
pub use axis::Axis;
pub use legend::{Entry, Shape, Swatch};
pub use text::{text_size, EmbeddedText};

/// One point of a series: its coordinates, the label its marker shape stands for and, for an
/// estimate, its interval.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// What the point is (e.g. a scene): one marker shape per distinct label.
    pub label: String,
    /// The interval of y (low, high), e.g. a 95% confidence interval, drawn as an error bar.
    pub interval: Option<(f64, f64)>,
}

/// A named set of points drawn in one colour.
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
    /// Join each series' points by lines, in order.
    pub joined: bool,
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

/// Series colours, in order (a chart of up to ten series, such as Figure 5 over every scene,
/// repeats none).
const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];

/// The colour of series `k`.
fn color(k: usize) -> RGBColor {
    COLORS[k % COLORS.len()]
}

/// Reference-line colours, in order: apart from the series' so a paper's value is not read as a
/// series.
const REF_COLORS: [RGBColor; 5] = [
    RGBColor(40, 40, 40),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(150, 150, 40),
    RGBColor(127, 127, 127),
];

/// The colour of reference line `k`.
fn ref_color(k: usize) -> RGBColor {
    REF_COLORS[k % REF_COLORS.len()]
}

/// The colour of the marker-shape key of a scatter chart (shapes standing for labels, not
/// series).
const KEY_COLOR: RGBColor = RGBColor(70, 70, 70);

/// The lowest and highest finite values of `values` (`(inf, -inf)` for none).
fn extent(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        })
}

/// The axis of `values`: logarithmic (over the positive ones) or linear, from zero.
fn auto_axis(values: impl Iterator<Item = f64>, log: bool) -> Axis {
    if log {
        let (lo, hi) = extent(values.filter(|v| *v > 0.0));
        Axis::log(lo, hi)
    } else {
        let (lo, hi) = extent(values);
        Axis::linear(lo, hi)
    }
}

impl Scatter {
    /// The labels of the points, in order of first appearance: label `i` is drawn with
    /// [`legend::shape`]`(i)`.
    pub fn labels(&self) -> Vec<&str> {
        let mut labels: Vec<&str> = Vec::new();
        for p in self.series.iter().flat_map(|s| &s.points) {
            if !labels.contains(&p.label.as_str()) {
                labels.push(&p.label);
            }
        }
        labels
    }

    /// The shape points labelled `label` are drawn with.
    pub fn shape_of(&self, label: &str) -> Shape {
        legend::shape(self.labels().iter().position(|l| *l == label).unwrap_or(0))
    }

    /// The x and y axes: they hold every point, and every interval unless it reaches further
    /// than half the points' span beyond them (a wide interval of an estimate from few
    /// replicates would flatten the rest: it runs off the plot instead).
    pub fn axes(&self) -> (Axis, Axis) {
        let points = || self.series.iter().flat_map(|s| &s.points);
        let x = auto_axis(points().map(|p| p.x), self.x_log);
        let ys = auto_axis(points().map(|p| p.y), self.y_log);
        let (lo, hi) = (ys.to(ys.lo), ys.to(ys.hi));
        let reach = 0.5 * (hi - lo);
        let within = |v: f64| ys.to(v) >= lo - reach && ys.to(v) <= hi + reach;
        let ends = points().flat_map(|p| p.interval.map(|(a, b)| [a, b]).into_iter().flatten());
        let y = auto_axis(
            points().map(|p| p.y).chain(ends.filter(|&v| within(v))),
            self.y_log,
        );
        (x, y)
    }

    /// The legend: one entry per series with the mark it is drawn with (its marker when all its
    /// points share a label, else its colour), then, when the shapes stand for something else
    /// than the series (a label that is not its series' name), one entry per label with its
    /// shape.
    pub fn legend(&self) -> Vec<Entry> {
        let mut entries: Vec<Entry> = self
            .series
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let first = s.points.first().map(|p| p.label.as_str());
                let one_label = s.points.iter().all(|p| Some(p.label.as_str()) == first);
                let c = color(k);
                let swatch = match (one_label, self.joined) {
                    (true, false) => Swatch::Marker(self.shape_of(first.unwrap_or("")), c),
                    (true, true) => Swatch::LineMarker(self.shape_of(first.unwrap_or("")), c),
                    (false, false) => Swatch::Patch(c),
                    (false, true) => Swatch::Line(c),
                };
                Entry {
                    name: s.name.clone(),
                    swatch,
                }
            })
            .collect();
        let key = self
            .series
            .iter()
            .any(|s| s.points.iter().any(|p| p.label != s.name));
        if key {
            entries.extend(self.labels().into_iter().map(|l| Entry {
                name: l.to_string(),
                swatch: Swatch::Marker(self.shape_of(l), KEY_COLOR),
            }));
        }
        entries
    }
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
    write_both(
        stem,
        |a| draw::scatter(a, chart),
        |a| draw::scatter(a, chart),
    )
}

/// A value series of a bar chart: one value per category (`None`: no bar).
#[derive(Debug, Clone, PartialEq)]
pub struct BarSeries {
    /// Legend name.
    pub name: String,
    /// Per category.
    pub values: Vec<Option<f64>>,
    /// Per category, the 95% interval `(low, high)` of an estimate, drawn as an error bar on
    /// a side-by-side chart (not stacked ones); empty or `None`: exact, no bar.
    pub intervals: Vec<Option<(f64, f64)>>,
}

/// A horizontal reference line (e.g. a paper's published value) across a chart.
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
    /// A fixed y range (e.g. `(0.0, 100.0)` for a rate in percent) instead of one fitted to the
    /// values.
    pub y_range: Option<(f64, f64)>,
}

impl Bars {
    /// The bars' (bottom, top) per series and category (`None`: no bar).
    pub fn spans(&self) -> Vec<Vec<Option<(f64, f64)>>> {
        let n = self.categories.len();
        let mut below = vec![0.0; n];
        self.series
            .iter()
            .map(|s| {
                (0..n)
                    .map(|i| {
                        let v = s.values.get(i).copied().flatten()?;
                        if !v.is_finite() {
                            return None;
                        }
                        if self.stacked {
                            let b = below[i];
                            below[i] += v;
                            Some((b, b + v))
                        } else {
                            Some((0.0, v))
                        }
                    })
                    .collect()
            })
            .collect()
    }

    /// The y axis: the fixed range, else one holding every bar, reference and zero, and every
    /// error bar unless it reaches further than half that span beyond it (a wide interval of an
    /// estimate from few samples is then cut at the axis).
    pub fn y_axis(&self) -> Axis {
        if let Some((lo, hi)) = self.y_range {
            return Axis::fixed(lo, hi);
        }
        let bars = self.spans();
        let ends = || bars.iter().flatten().flatten().flat_map(|&(a, b)| [a, b]);
        let refs = || self.references.iter().map(|r| r.value);
        let (lo, hi) = extent(ends().chain(refs()));
        let reach = 0.5 * (hi - lo);
        let whiskers = (!self.stacked)
            .then(|| {
                self.series
                    .iter()
                    .flat_map(|s| s.intervals.iter().flatten())
            })
            .into_iter()
            .flatten()
            .flat_map(|&(a, b)| [a, b])
            .filter(|v| v.is_finite() && *v >= lo - reach && *v <= hi + reach);
        let (lo, hi) = extent(ends().chain(refs()).chain(whiskers));
        Axis::linear(lo, hi)
    }

    /// The legend: a colour patch per series, a dashed line per reference.
    pub fn legend(&self) -> Vec<Entry> {
        let series = self.series.iter().enumerate().map(|(k, s)| Entry {
            name: s.name.clone(),
            swatch: Swatch::Patch(color(k)),
        });
        series.chain(reference_entries(&self.references)).collect()
    }
}

/// The legend entries of reference lines.
fn reference_entries(refs: &[Reference]) -> impl Iterator<Item = Entry> + '_ {
    refs.iter().enumerate().map(|(k, r)| Entry {
        name: r.name.clone(),
        swatch: Swatch::Dashed(ref_color(k)),
    })
}

/// Writes the bar chart as `<stem>.svg` and `<stem>.png`; returns both paths.
pub fn write_bars(stem: &Path, chart: &Bars) -> Result<(PathBuf, PathBuf), PlotError> {
    write_both(stem, |a| draw::bars(a, chart), |a| draw::bars(a, chart))
}

/// A line of a line chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Legend name.
    pub name: String,
    /// Its points, by x.
    pub points: Vec<(f64, f64)>,
}

/// A line chart: each line with a marker of its own shape at every point.
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
    /// A fixed x range instead of one fitted to the points.
    pub x_range: Option<(f64, f64)>,
    /// A fixed y range (e.g. `(0.0, 100.0)` for a rate in percent).
    pub y_range: Option<(f64, f64)>,
}

impl Lines {
    /// The x and y axes: the fixed ranges, else ones holding every point (and reference).
    pub fn axes(&self) -> (Axis, Axis) {
        let points = || self.lines.iter().flat_map(|l| &l.points);
        let fit = |range: Option<(f64, f64)>, values: Vec<f64>| match range {
            Some((lo, hi)) => Axis::fixed(lo, hi),
            None => {
                let (lo, hi) = extent(values.into_iter());
                Axis::linear(lo, hi)
            }
        };
        let refs = self.references.iter().map(|r| r.value);
        (
            fit(self.x_range, points().map(|p| p.0).collect()),
            fit(self.y_range, points().map(|p| p.1).chain(refs).collect()),
        )
    }

    /// The legend: each line with its marker, then a dashed line per reference.
    pub fn legend(&self) -> Vec<Entry> {
        let lines = self.lines.iter().enumerate().map(|(k, l)| Entry {
            name: l.name.clone(),
            swatch: Swatch::LineMarker(legend::shape(k), color(k)),
        });
        lines.chain(reference_entries(&self.references)).collect()
    }
}

/// Writes the line chart as `<stem>.svg` and `<stem>.png`; returns both paths.
pub fn write_lines(stem: &Path, chart: &Lines) -> Result<(PathBuf, PathBuf), PlotError> {
    write_both(stem, |a| draw::lines(a, chart), |a| draw::lines(a, chart))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(x: f64, y: f64, label: &str) -> Point {
        Point {
            x,
            y,
            label: label.into(),
            interval: None,
        }
    }

    /// A scatter chart whose series each carry one label: its own name.
    fn per_scene() -> Scatter {
        let series = |name: &str, ys: [f64; 3]| Series {
            name: name.into(),
            points: [32.0, 1024.0, 65536.0]
                .iter()
                .zip(ys)
                .map(|(&x, y)| point(x, y, name))
                .collect(),
        };
        Scatter {
            title: "potential speedup".into(),
            x_label: "concurrent rays".into(),
            y_label: "speedup".into(),
            x_log: true,
            y_log: true,
            joined: false,
            series: vec![
                series("WKND", [2.0, 30.0, 150.0]),
                series("SHIP", [1.8, 13.0, 50.0]),
            ],
        }
    }

    #[test]
    fn writes_an_svg_and_a_png() {
        let dir = std::env::temp_dir().join(format!("vtq-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let chart = Scatter {
            title: "run time against error".into(),
            x_label: "wall s".into(),
            y_label: "error %".into(),
            x_log: true,
            y_log: false,
            joined: false,
            series: vec![
                Series {
                    name: "sampled".into(),
                    points: vec![
                        Point {
                            interval: Some((-0.3, 2.7)),
                            ..point(0.5, 1.2, "wknd")
                        },
                        point(2.0, -0.4, "sponza"),
                    ],
                },
                Series {
                    name: "one replicate".into(),
                    points: vec![point(0.1, 20.0, "wknd")],
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
                    intervals: Vec::new(),
                    name: "vtq".into(),
                    values: vec![Some(1.5), Some(2.0)],
                },
                BarSeries {
                    intervals: Vec::new(),
                    name: "prefetch".into(),
                    values: vec![Some(1.1), None],
                },
            ],
            references: vec![Reference {
                name: "paper".into(),
                value: 1.95,
            }],
            stacked: false,
            y_range: None,
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
            x_range: None,
            y_range: None,
        };
        let (_, png) = write_lines(&dir.join("lines"), &lines).unwrap();
        assert!(std::fs::metadata(png).unwrap().len() > 1000);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn legend_markers_are_the_series_markers() {
        let chart = per_scene();
        let legend = chart.legend();
        // One entry per series, no separate shape key: each series is one scene.
        assert_eq!(legend.len(), 2);
        for (k, s) in chart.series.iter().enumerate() {
            let shape = chart.shape_of(&s.points[0].label);
            assert_eq!(legend[k].swatch, Swatch::Marker(shape, color(k)));
        }
        assert_eq!(legend[1].swatch, Swatch::Marker(Shape::Triangle, color(1)));
        let joined = Scatter {
            joined: true,
            ..chart.clone()
        };
        assert_eq!(
            joined.legend()[1].swatch,
            Swatch::LineMarker(Shape::Triangle, color(1))
        );
        // In the drawing: the first series' circles and its legend circle, no circle for the
        // triangles' legend entry.
        let dir = std::env::temp_dir().join(format!("vtq-plot-legend-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (svg, _) = write_scatter(&dir.join("fig5"), &chart).unwrap();
        let text = std::fs::read_to_string(svg).unwrap();
        assert_eq!(text.matches("<circle").count(), 3 + 1, "{text}");
        let _ = std::fs::remove_dir_all(&dir);
        // Series of several labels: a colour patch each, then the shapes' key.
        let mixed = Scatter {
            series: vec![Series {
                name: "sampled".into(),
                points: vec![point(1.0, 1.0, "WKND"), point(2.0, 2.0, "SHIP")],
            }],
            ..chart
        };
        let legend = mixed.legend();
        assert_eq!(legend[0].swatch, Swatch::Patch(color(0)));
        assert_eq!(legend[1].name, "WKND");
        assert_eq!(legend[2].swatch, Swatch::Marker(Shape::Triangle, KEY_COLOR));
    }

    #[test]
    fn rate_axes_end_at_100_percent_and_others_fit_the_data() {
        let bars = Bars {
            title: "miss rate".into(),
            y_label: "%".into(),
            categories: vec!["a".into(), "b".into()],
            series: vec![BarSeries {
                intervals: Vec::new(),
                name: "vtq".into(),
                values: vec![Some(52.7), Some(98.0)],
            }],
            references: vec![Reference {
                name: "paper".into(),
                value: 70.0,
            }],
            stacked: false,
            y_range: Some((0.0, 100.0)),
        };
        let y = bars.y_axis();
        assert_eq!((y.lo, y.hi), (0.0, 100.0));
        assert_eq!(y.ticks.last(), Some(&100.0));
        // Without a fixed range: zero to the first tick above the highest bar or reference.
        let fitted = Bars {
            y_range: None,
            ..bars.clone()
        };
        let y = fitted.y_axis();
        assert_eq!(y.lo, 0.0);
        assert!(y.hi >= 98.0 && y.hi <= 120.0, "{}", y.hi);
        // An estimate's error bar above its bar widens the axis to hold it, unless it reaches
        // further than half the span beyond it.
        let with_interval = |high: f64| Bars {
            series: vec![BarSeries {
                intervals: vec![Some((0.9, high)), None],
                name: "sampled".into(),
                values: vec![Some(1.08), Some(1.13)],
            }],
            references: Vec::new(),
            y_range: None,
            stacked: false,
            ..bars.clone()
        };
        assert!(with_interval(1.0).y_axis().hi < 1.3);
        assert!(with_interval(1.45).y_axis().hi >= 1.45);
        assert!(
            with_interval(9.0).y_axis().hi < 2.0,
            "a wild interval is cut"
        );
        // Stacked shares sum to 100: the axis is 0..=100.
        let stacked = Bars {
            series: vec![
                BarSeries {
                    intervals: Vec::new(),
                    name: "a".into(),
                    values: vec![Some(30.0), Some(60.0)],
                },
                BarSeries {
                    intervals: Vec::new(),
                    name: "b".into(),
                    values: vec![Some(70.0), Some(40.0)],
                },
            ],
            stacked: true,
            ..bars
        };
        assert_eq!(stacked.spans()[1][0], Some((30.0, 100.0)));
        let y = stacked.y_axis();
        assert_eq!((y.lo, y.hi), (0.0, 100.0));
        // A negative bar (a design faster than its reference): the axis goes below zero.
        let negative = Bars {
            series: vec![BarSeries {
                intervals: Vec::new(),
                name: "overhead".into(),
                values: vec![Some(-3.0), Some(10.4)],
            }],
            y_range: None,
            stacked: false,
            references: vec![],
            ..stacked
        };
        let y = negative.y_axis();
        assert!(y.lo <= -3.0 && y.hi >= 10.4);
        let lines = Lines {
            title: "miss rate over the run".into(),
            x_label: "%".into(),
            y_label: "%".into(),
            lines: vec![Line {
                name: "baseline".into(),
                points: vec![(5.0, 22.0), (95.0, 99.5)],
            }],
            references: vec![],
            x_range: Some((0.0, 100.0)),
            y_range: Some((0.0, 100.0)),
        };
        let (x, y) = lines.axes();
        assert_eq!((x.lo, x.hi, y.lo, y.hi), (0.0, 100.0, 0.0, 100.0));
    }

    #[test]
    fn log_axes_of_a_scatter_hold_its_points() {
        let (x, y) = per_scene().axes();
        assert!(x.log && y.log);
        assert!(x.lo <= 32.0 && x.hi >= 65536.0);
        assert!(y.lo <= 1.8 && y.hi >= 150.0);
        assert!(x.ticks.contains(&1000.0));
    }
}
