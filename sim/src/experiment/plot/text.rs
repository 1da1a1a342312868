//! Chart text from the embedded DejaVu Sans, rasterized in Rust (`ab_glyph`), laid out and
//! placed as plotters' `ttf` feature did with a system font: an em of `size / 1.24` pixels,
//! the baseline `0.76` em below the text's top, advances and kerning from the font. So the
//! PNG charts look as they did with fontconfig and freetype, and need neither.
//!
//! [`EmbeddedText`] wraps a plotters backend: text size estimates (the chart layout) come from
//! the font for every backend; the bitmap backend also draws its text with it, while the SVG
//! backend keeps writing `<text>` elements for the viewer's font.

use ab_glyph::{point, Font, FontRef, GlyphId, PxScale, ScaleFont};
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};
use std::sync::OnceLock;

/// The embedded font, parsed once.
fn font() -> Result<&'static FontRef<'static>, String> {
    static FONT: OnceLock<Result<FontRef<'static>, String>> = OnceLock::new();
    FONT.get_or_init(|| {
        FontRef::try_from_slice(dejavu::sans::regular())
            .map_err(|e| format!("the embedded DejaVu Sans font is not valid: {e}"))
    })
    .as_ref()
    .map_err(Clone::clone)
}

/// The pixels per em of text of `size` (plotters' convention for a font size).
fn em(size: f64) -> f32 {
    (size / 1.24) as f32
}

/// Pen advances of `text`'s glyphs at `em` pixels per em: each glyph with its x offset.
fn layout(font: &FontRef<'static>, em: f32, text: &str) -> (Vec<(GlyphId, f32)>, f32) {
    let scaled = font.as_scaled(px_scale(font, em));
    let mut x = 0.0;
    let mut prev: Option<GlyphId> = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = prev {
            x += scaled.kern(p, id);
        }
        glyphs.push((id, x));
        x += scaled.h_advance(id);
        prev = Some(id);
    }
    (glyphs, x)
}

/// ab_glyph's scale (the font's ascent-to-descent height in pixels) for `em` pixels per em.
fn px_scale(font: &FontRef<'static>, em: f32) -> PxScale {
    let units_per_em = font.units_per_em().unwrap_or(2048.0);
    PxScale::from(em * font.height_unscaled() / units_per_em)
}

/// The size in pixels of `text` at font size `size`: its advance and one em.
pub fn text_size(text: &str, size: f64) -> Result<(u32, u32), String> {
    let em = em(size);
    let (_, width) = layout(font()?, em, text);
    Ok((width.max(0.0) as u32, em as u32))
}

/// Draws `text` with its top-left corner at `(0, 0)` through `pixel(x, y, coverage)`.
fn rasterize(text: &str, size: f64, mut pixel: impl FnMut(i32, i32, f32)) -> Result<(), String> {
    let font = font()?;
    let em = em(size);
    let scale = px_scale(font, em);
    let baseline = 0.76 * em;
    let (glyphs, _) = layout(font, em, text);
    for (id, x) in glyphs {
        let glyph = id.with_scale_and_position(scale, point(x.trunc(), baseline));
        if let Some(outline) = font.outline_glyph(glyph) {
            let bounds = outline.px_bounds();
            outline.draw(|gx, gy, c| {
                pixel(
                    bounds.min.x as i32 + gx as i32,
                    bounds.min.y as i32 + gy as i32,
                    c,
                );
            });
        }
    }
    Ok(())
}

/// A plotters backend whose text is measured (and, with `draw`, drawn) with the embedded font.
pub struct EmbeddedText<B> {
    /// The wrapped backend.
    pub inner: B,
    /// Rasterize text here (bitmaps) instead of passing it to the backend (SVG).
    pub draw: bool,
}

/// A font error as plotters reports it.
fn font_error<E: std::error::Error + Send + Sync>(e: String) -> DrawingErrorKind<E> {
    DrawingErrorKind::FontError(e.into())
}

impl<B: DrawingBackend> DrawingBackend for EmbeddedText<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_path(path, style)
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.blit_bitmap(pos, size, src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        text_size(text, style.size()).map_err(font_error)
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        if !self.draw {
            return self.inner.draw_text(text, style, pos);
        }
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        // Anchored and turned as plotters' own text drawing does.
        let (width, height) = text_size(text, style.size()).map_err(font_error)?;
        let (width, height) = (width as i32, height as i32);
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -width,
            HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        let transform = style.transform();
        let (w, h) = self.get_size();
        let mut result = Ok(());
        rasterize(text, style.size(), |x, y, coverage| {
            if result.is_err() || coverage <= 0.0 {
                return;
            }
            let (x, y) = transform.transform(x + dx, y + dy);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if x >= 0 && x < w as i32 && y >= 0 && y < h as i32 {
                let c = BackendColor {
                    alpha: color.alpha * f64::from(coverage.min(1.0)),
                    rgb: color.rgb,
                };
                result = self.inner.draw_pixel((x, y), c);
            }
        })
        .map_err(font_error)?;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_measured_and_drawn() {
        let (w, h) = text_size("speedup", 20.0).unwrap();
        assert_eq!(h, 16, "an em of 20 / 1.24 pixels");
        assert!((50..90).contains(&w), "{w}");
        assert!(text_size("speedup x", 20.0).unwrap().0 > w);
        let mut covered = 0;
        let (mut max_x, mut max_y) = (0, 0);
        rasterize("Hg", 20.0, |x, y, c| {
            if c > 0.5 {
                covered += 1;
                max_x = max_x.max(x);
                max_y = max_y.max(y);
            }
        })
        .unwrap();
        assert!(covered > 30, "{covered}");
        // The descender of `g` reaches below the baseline, inside a 20-pixel line.
        assert!(max_y > 13 && max_y < 20, "{max_y}");
        assert!(max_x < 30, "{max_x}");
    }
}
