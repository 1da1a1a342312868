//! Drawing each kind of chart into its [`frame`]: the data in axis space, clipped to the axes'
//! ranges.

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::axis::Axis;
use super::frame::{self, Coords, Frame};
use super::legend::{self, draw_marker, Entry, DASH};
use super::{color, ref_color, Bars, Lines, Reference, Scatter};

/// A plotters error as text.
fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// The position of `v` on `axis`, clamped to the axis' range.
fn clamped(axis: &Axis, v: f64) -> f64 {
    let (lo, hi) = axis.span();
    axis.to(v).clamp(lo, hi)
}

/// Whether `v` can be drawn on `axis` (finite, and positive on a logarithmic axis).
fn shown(axis: &Axis, v: f64) -> bool {
    v.is_finite() && (!axis.log || v > 0.0)
}

/// Draws the frame of a chart over two numeric axes (a scatter or line chart: no categories),
/// with `title`, x caption and y caption in `labels`, and returns the chart to draw the data in.
fn xy_frame<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    [title, x_desc, y_desc]: [&str; 3],
    (x, y): (&Axis, &Axis),
    legend: &[Entry],
) -> Result<ChartContext<'a, DB, Coords>, String> {
    frame::draw(
        area,
        &Frame {
            title,
            x_desc,
            y_desc,
            x,
            y,
            categories: None,
            legend,
        },
    )
}

/// Draws `chart` on `area`.
pub fn scatter<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    chart: &Scatter,
) -> Result<(), String> {
    let (x, y) = chart.axes();
    let legend = chart.legend();
    let labels = [chart.title.as_str(), &chart.x_label, &chart.y_label];
    let ctx = xy_frame(area, labels, (&x, &y), &legend)?;
    let plot = ctx.plotting_area();
    for (k, s) in chart.series.iter().enumerate() {
        let c = color(k);
        let points: Vec<_> = s
            .points
            .iter()
            .filter(|p| shown(&x, p.x) && shown(&y, p.y))
            .collect();
        if chart.joined {
            let path: Vec<(f64, f64)> = points.iter().map(|p| (x.to(p.x), y.to(p.y))).collect();
            plot.draw(&PathElement::new(path, c.stroke_width(2)))
                .map_err(err)?;
        }
        for p in &points {
            let px = x.to(p.x);
            if let Some(interval) = p.interval {
                error_bar(plot, &y, px, interval, c)?;
            }
            draw_marker(plot, (px, y.to(p.y)), chart.shape_of(&p.label), c)?;
        }
    }
    area.present().map_err(err)
}

/// Draws the interval `(lo, hi)` of y at position `px` as an error bar in `c`: capped ends, or
/// an arrowhead where it runs off the axis.
fn error_bar<DB: DrawingBackend>(
    plot: &DrawingArea<DB, Coords>,
    y: &Axis,
    px: f64,
    (lo, hi): (f64, f64),
    c: RGBColor,
) -> Result<(), String> {
    if !(shown(y, lo) && shown(y, hi)) {
        return Ok(());
    }
    let (bottom, top) = y.span();
    let bar = c.stroke_width(1);
    let (a, b) = (clamped(y, lo), clamped(y, hi));
    plot.draw(&PathElement::new(vec![(px, a), (px, b)], bar))
        .map_err(err)?;
    // Pixels grow downwards: the top end's arrowhead points up (negative y).
    for (end, off, dir) in [(a, y.to(lo) < bottom, 1), (b, y.to(hi) > top, -1)] {
        let mark = if off {
            vec![(-4, 6 * dir), (0, 0), (4, 6 * dir)]
        } else {
            vec![(-4, 0), (4, 0)]
        };
        plot.draw(&(EmptyElement::at((px, end)) + PathElement::new(mark, bar)))
            .map_err(err)?;
    }
    Ok(())
}

/// Draws `chart` on `area`.
pub fn bars<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, chart: &Bars) -> Result<(), String> {
    let x = Axis::categories(chart.categories.len());
    let y = chart.y_axis();
    let legend = chart.legend();
    let mut ctx = frame::draw(
        area,
        &Frame {
            title: &chart.title,
            x_desc: "",
            y_desc: &chart.y_label,
            x: &x,
            y: &y,
            categories: Some(&chart.categories),
            legend: &legend,
        },
    )?;
    let k = chart.series.len().max(1) as f64;
    for (j, spans) in chart.spans().iter().enumerate() {
        let c = color(j);
        let rects = spans.iter().enumerate().filter_map(|(i, span)| {
            let (bottom, top) = (*span)?;
            let (x0, x1) = if chart.stacked {
                (i as f64 - 0.35, i as f64 + 0.35)
            } else {
                let w = 0.8 / k;
                let x0 = i as f64 - 0.4 + w * j as f64;
                (x0, x0 + w * 0.92)
            };
            let (b, t) = (clamped(&y, bottom), clamped(&y, top));
            Some(Rectangle::new([(x0, b), (x1, t)], c.filled()))
        });
        ctx.draw_series(rects).map_err(err)?;
    }
    if !chart.stacked {
        // Estimates' intervals over the middle of their bars.
        for (j, s) in chart.series.iter().enumerate() {
            let w = 0.8 / k;
            for (i, interval) in s.intervals.iter().enumerate() {
                if let Some(interval) = *interval {
                    let px = i as f64 - 0.4 + w * j as f64 + w * 0.46;
                    error_bar(ctx.plotting_area(), &y, px, interval, BLACK)?;
                }
            }
        }
    }
    references(ctx.plotting_area(), &chart.references, &y, x.span())?;
    area.present().map_err(err)
}

/// Draws `chart` on `area`.
pub fn lines<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    chart: &Lines,
) -> Result<(), String> {
    let (x, y) = chart.axes();
    let legend = chart.legend();
    let labels = [chart.title.as_str(), &chart.x_label, &chart.y_label];
    let ctx = xy_frame(area, labels, (&x, &y), &legend)?;
    let plot = ctx.plotting_area();
    for (j, l) in chart.lines.iter().enumerate() {
        let c = color(j);
        let points: Vec<(f64, f64)> = l
            .points
            .iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .map(|&(px, py)| (clamped(&x, px), clamped(&y, py)))
            .collect();
        plot.draw(&PathElement::new(points.clone(), c.stroke_width(2)))
            .map_err(err)?;
        for p in points {
            draw_marker(plot, p, legend::shape(j), c)?;
        }
    }
    references(plot, &chart.references, &y, x.span())?;
    area.present().map_err(err)
}

/// Draws `refs` as dashed horizontal lines across `x0..x1` (positions).
fn references<DB: DrawingBackend>(
    plot: &DrawingArea<DB, Coords>,
    refs: &[Reference],
    y: &Axis,
    (x0, x1): (f64, f64),
) -> Result<(), String> {
    for (k, r) in refs.iter().enumerate() {
        if !shown(y, r.value) {
            continue;
        }
        let v = y.to(r.value);
        let (lo, hi) = y.span();
        if v < lo || v > hi {
            continue;
        }
        plot.draw(&DashedPathElement::new(
            vec![(x0, v), (x1, v)],
            DASH.0,
            DASH.1,
            ref_color(k).stroke_width(2),
        ))
        .map_err(err)?;
    }
    Ok(())
}
