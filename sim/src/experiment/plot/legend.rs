//! Marker shapes and legends. A legend entry shows the very mark its series is drawn with (a
//! bar's colour patch, a line, a dashed reference line, a marker of the series' shape), and the
//! legend sits in a band of its own between the title and the plot, never over the data.

use plotters::coord::{CoordTranslate, Shift};
use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::text_size;

/// A marker shape. Filled and open shapes and strokes, so that up to ten series or scenes stay
/// apart in print, in colour or not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A filled circle.
    Circle,
    /// A filled triangle pointing up.
    Triangle,
    /// A filled square.
    Square,
    /// A filled diamond.
    Diamond,
    /// A filled triangle pointing down.
    TriangleDown,
    /// An x.
    Cross,
    /// A +.
    Plus,
    /// A ring.
    OpenCircle,
    /// An open square.
    OpenSquare,
    /// An open triangle pointing up.
    OpenTriangle,
}

/// The shapes in the order they are handed out.
pub const SHAPES: [Shape; 10] = [
    Shape::Circle,
    Shape::Triangle,
    Shape::Square,
    Shape::Diamond,
    Shape::TriangleDown,
    Shape::Cross,
    Shape::Plus,
    Shape::OpenCircle,
    Shape::OpenSquare,
    Shape::OpenTriangle,
];

/// The `i`-th shape (cycling).
pub fn shape(i: usize) -> Shape {
    SHAPES[i % SHAPES.len()]
}

/// Draws a marker of `shape` in `color` centred on `at` (the area's coordinates).
pub fn draw_marker<DB: DrawingBackend, CT: CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
    shape: Shape,
    color: RGBColor,
) -> Result<(), String> {
    let fill = color.filled();
    let line = color.stroke_width(2);
    let r = 5;
    let s = r + 1;
    let up = vec![(0, -s), (s, r), (-s, r)];
    let e = EmptyElement::at(at);
    let res = match shape {
        Shape::Circle => area.draw(&(e + Circle::new((0, 0), r, fill))),
        Shape::Triangle => area.draw(&(e + Polygon::new(up, fill))),
        Shape::Square => area.draw(&(e + Rectangle::new([(1 - r, 1 - r), (r - 1, r - 1)], fill))),
        Shape::Diamond => {
            area.draw(&(e + Polygon::new(vec![(0, -s), (s, 0), (0, s), (-s, 0)], fill)))
        }
        Shape::TriangleDown => {
            area.draw(&(e + Polygon::new(vec![(0, s), (s, -r), (-s, -r)], fill)))
        }
        Shape::Cross => area.draw(
            &(e + PathElement::new(vec![(-r, -r), (r, r)], line)
                + PathElement::new(vec![(-r, r), (r, -r)], line)),
        ),
        Shape::Plus => area.draw(
            &(e + PathElement::new(vec![(-s, 0), (s, 0)], line)
                + PathElement::new(vec![(0, -s), (0, s)], line)),
        ),
        Shape::OpenCircle => area.draw(&(e + Circle::new((0, 0), r - 1, line))),
        Shape::OpenSquare => {
            area.draw(&(e + Rectangle::new([(1 - r, 1 - r), (r - 1, r - 1)], line)))
        }
        Shape::OpenTriangle => {
            let mut closed = up;
            closed.push(closed[0]);
            area.draw(&(e + PathElement::new(closed, line)))
        }
    };
    res.map_err(|e| e.to_string())
}

/// What a legend entry shows beside its name: the mark of its series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Swatch {
    /// A colour patch (bars, or a series whose points carry several shapes).
    Patch(RGBColor),
    /// A solid line.
    Line(RGBColor),
    /// A dashed line (a reference value).
    Dashed(RGBColor),
    /// A marker.
    Marker(Shape, RGBColor),
    /// A line through a marker (points joined by lines).
    LineMarker(Shape, RGBColor),
}

/// One legend entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// The series' name.
    pub name: String,
    /// Its mark.
    pub swatch: Swatch,
}

/// Font size of legend text.
const FONT: f64 = 14.0;
/// Width of a swatch.
const SWATCH: i32 = 26;
/// Gap between a swatch and its name.
const GAP: i32 = 6;
/// Space after an entry.
const SPACING: i32 = 22;
/// Height of a legend row.
const ROW: i32 = 21;

/// Dash and gap length of a dashed reference line, in pixels.
pub const DASH: (u32, u32) = (7, 4);

/// The width of each entry (swatch, gap, name) at the legend's font.
fn widths(entries: &[Entry]) -> Result<Vec<i32>, String> {
    entries
        .iter()
        .map(|e| Ok(SWATCH + GAP + text_size(&e.name, FONT)?.0 as i32))
        .collect()
}

/// The rows of a legend whose entries are `widths` wide, in order, within `width` pixels: each
/// row as many entries as fit (at least one).
pub fn rows(widths: &[i32], width: i32) -> Vec<Vec<usize>> {
    let mut rows: Vec<Vec<usize>> = Vec::new();
    let mut used = 0;
    for (i, w) in widths.iter().enumerate() {
        match rows.last_mut() {
            Some(row) if used + SPACING + w <= width => {
                row.push(i);
                used += SPACING + w;
            }
            _ => {
                rows.push(vec![i]);
                used = *w;
            }
        }
    }
    rows
}

/// The height in pixels of the legend of `entries` laid out within `width` (0 without
/// entries).
pub fn height(entries: &[Entry], width: i32) -> Result<i32, String> {
    Ok(rows(&widths(entries)?, width).len() as i32 * ROW)
}

/// Draws the legend of `entries` on `area` in centred rows, from its top.
pub fn draw<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
) -> Result<(), String> {
    let width = area.dim_in_pixel().0 as i32;
    let widths = widths(entries)?;
    let font = ("sans-serif", FONT).into_font().color(&BLACK);
    for (r, row) in rows(&widths, width).iter().enumerate() {
        let total: i32 =
            row.iter().map(|&i| widths[i]).sum::<i32>() + SPACING * (row.len() as i32 - 1);
        let mut x = (width - total).max(0) / 2;
        let y = r as i32 * ROW + ROW / 2;
        for &i in row {
            swatch(area, (x, y), entries[i].swatch)?;
            let text_h = text_size(&entries[i].name, FONT)?.1 as i32;
            area.draw_text(
                &entries[i].name,
                &font,
                (x + SWATCH + GAP, y - text_h / 2 - 1),
            )
            .map_err(|e| e.to_string())?;
            x += widths[i] + SPACING;
        }
    }
    Ok(())
}

/// Draws `swatch` with its left end at `(x, y)`, centred on `y`.
fn swatch<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    swatch: Swatch,
) -> Result<(), String> {
    let line = |c: RGBColor| PathElement::new(vec![(x, y), (x + SWATCH, y)], c.stroke_width(2));
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let mid = (x + SWATCH / 2, y);
    match swatch {
        Swatch::Patch(c) => area
            .draw(&Rectangle::new(
                [(x + 3, y - 6), (x + SWATCH - 3, y + 6)],
                c.filled(),
            ))
            .map_err(err),
        Swatch::Line(c) => area.draw(&line(c)).map_err(err),
        Swatch::Dashed(c) => area
            .draw(&DashedPathElement::new(
                vec![(x, y), (x + SWATCH, y)],
                DASH.0,
                DASH.1,
                c.stroke_width(2),
            ))
            .map_err(err),
        Swatch::Marker(s, c) => draw_marker(area, mid, s, c),
        Swatch::LineMarker(s, c) => {
            area.draw(&line(c)).map_err(err)?;
            draw_marker(area, mid, s, c)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_rows_fill_the_width_in_order() {
        assert_eq!(rows(&[100, 100, 100], 400), vec![vec![0, 1, 2]]);
        assert_eq!(rows(&[100, 100, 100], 250), vec![vec![0, 1], vec![2]]);
        // An entry wider than the band gets a row of its own.
        assert_eq!(rows(&[500, 50], 300), vec![vec![0], vec![1]]);
        assert!(rows(&[], 300).is_empty());
        assert_eq!(shape(0), Shape::Circle);
        assert_eq!(shape(SHAPES.len() + 1), Shape::Triangle);
    }
}
