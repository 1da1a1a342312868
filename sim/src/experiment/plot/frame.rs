//! The frame every chart shares: the title on top, the legend in a band under it, then the
//! plot with its axes, a light grid at the ticks (and the logarithmic axes' minor lines, lighter
//! still) and plain tick labels ([`Axis`]).

use std::ops::Range;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::Axis;
use super::legend::{self, Entry};

/// One axis of a chart in plotters' terms: linear in axis space ([`Axis::to`]), the axis'
/// ticks as its key points and its minor lines as its light points.
pub struct Positions {
    /// The positions of the ends.
    span: (f64, f64),
    /// The ticks' positions.
    ticks: Vec<f64>,
    /// The minor lines' positions.
    minor: Vec<f64>,
}

impl Positions {
    /// The positions of `axis`.
    fn of(axis: &Axis) -> Positions {
        Positions {
            span: axis.span(),
            ticks: axis.ticks.iter().map(|&t| axis.to(t)).collect(),
            minor: axis.minor.iter().map(|&t| axis.to(t)).collect(),
        }
    }
}

impl Ranged for Positions {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        RangedCoordf64::from(self.span.0..self.span.1).map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.span.0..self.span.1
    }
}

/// The coordinates of a chart.
pub type Coords = Cartesian2d<Positions, Positions>;

/// Font size of the title.
const TITLE_FONT: f64 = 20.0;
/// Font size of tick labels.
const TICK_FONT: f64 = 14.0;
/// Font size of the axis captions.
const DESC_FONT: f64 = 15.0;
/// Space around the chart.
const MARGIN: i32 = 14;
/// Grid lines at the ticks.
const GRID: RGBColor = RGBColor(222, 222, 222);
/// Minor grid lines.
const MINOR: RGBColor = RGBColor(240, 240, 240);

/// What the frame of a chart shows.
pub struct Frame<'a> {
    /// The title.
    pub title: &'a str,
    /// The x axis' caption.
    pub x_desc: &'a str,
    /// The y axis' caption.
    pub y_desc: &'a str,
    /// The x axis (positions of categories `0..n` for a bar chart: see `categories`).
    pub x: &'a Axis,
    /// The y axis.
    pub y: &'a Axis,
    /// Category names of a bar chart, at x = 0, 1, ... (the x axis' ticks then name them and
    /// draw no vertical grid lines).
    pub categories: Option<&'a [String]>,
    /// The legend.
    pub legend: &'a [Entry],
}

/// Draws the frame on `area` (title, legend, axes, grid) and returns the chart to draw the data
/// in, in axis space.
pub fn draw<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    f: &Frame<'_>,
) -> Result<ChartContext<'a, DB, Coords>, String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    area.fill(&WHITE).map_err(err)?;
    let (width, _) = area.dim_in_pixel();
    // Centred by its anchor, so the SVG's title is centred in the viewer's font too.
    let title = ("sans-serif", TITLE_FONT)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    area.draw_text(f.title, &title, (width as i32 / 2, MARGIN - 4))
        .map_err(err)?;
    let title_h = MARGIN + 30;
    let legend_h = legend::height(f.legend, width as i32 - 2 * MARGIN)?;
    let (_, below) = area.split_vertically(title_h);
    let (band, _) = below.split_vertically(legend_h);
    legend::draw(&band.margin(0, 0, MARGIN, MARGIN), f.legend)?;

    // The plot under the title and the legend (a chart built on a sub-area could not outlive
    // this function).
    let mut ctx = ChartBuilder::on(area)
        .margin_left(MARGIN)
        .margin_right(MARGIN + 10)
        .margin_top(title_h + legend_h + 8)
        .margin_bottom(MARGIN / 2)
        .x_label_area_size(52)
        .y_label_area_size(78)
        .build_cartesian_2d(Positions::of(f.x), Positions::of(f.y))
        .map_err(err)?;
    let x_label = |p: &f64| match f.categories {
        Some(names) => {
            let i = p.round();
            if (p - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        }
        None => f.x.label_at(*p),
    };
    let y_label = |p: &f64| f.y.label_at(*p);
    let mut mesh = ctx.configure_mesh();
    mesh.bold_line_style(GRID)
        .light_line_style(MINOR)
        .axis_style(BLACK.stroke_width(1))
        .set_all_tick_mark_size(5)
        .label_style(("sans-serif", TICK_FONT))
        .axis_desc_style(("sans-serif", DESC_FONT))
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .x_desc(f.x_desc)
        .y_desc(f.y_desc);
    if f.categories.is_some() {
        mesh.disable_x_mesh();
    }
    mesh.draw().map_err(err)?;
    Ok(ctx)
}
