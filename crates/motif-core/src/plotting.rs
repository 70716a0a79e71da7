//! Text for the pictures Motif draws with plotters (offsets, sparsity, previews, detections,
//! evaluation curves): a drawing backend that wraps any plotters backend and lays text out with
//! `ab_glyph` itself.
//!
//! Why: plotters 0.3.7's `ab_glyph` font drops each glyph's left side bearing and truncates the
//! pen position to whole pixels, so "class" read "dass" and "bounding box" read "boun din g
//! box" in every picture (a user audit, 2026-11-29). Here each glyph is placed at its
//! fractional pen position with kerning, and drawn from its pixel bounds, so letters keep their
//! spacing. The vertical placement, the anchors and the rotations are plotters' own, so chart
//! layouts do not move. Text is DejaVu Sans (regular and bold), embedded by the `dejavu` crate:
//! pictures render the same on every machine, without system fonts.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont, point};
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind, FontStyle,
};

fn fonts() -> &'static (FontRef<'static>, FontRef<'static>) {
    static FONTS: OnceLock<(FontRef<'static>, FontRef<'static>)> = OnceLock::new();
    FONTS.get_or_init(|| {
        // The bytes are the valid TrueType fonts the `dejavu` crate ships.
        let regular = FontRef::try_from_slice(dejavu::sans::regular()).expect("DejaVu Sans parses");
        let bold = FontRef::try_from_slice(dejavu::sans::bold()).expect("DejaVu Sans Bold parses");
        (regular, bold)
    })
}

fn font_for(style: FontStyle) -> &'static FontRef<'static> {
    let (regular, bold) = fonts();
    if matches!(style, FontStyle::Bold) { bold } else { regular }
}

/// Width of `text` in pixels at `size` (advances and kerning), as plotters measures it.
pub fn text_width(text: &str, size: f64, style: FontStyle) -> f64 {
    let font = font_for(style).as_scaled(PxScale::from(size as f32));
    let mut x = 0.0f32;
    let mut prev = None;
    for c in text.chars() {
        let id = font.glyph_id(c);
        if let Some(p) = prev {
            x += font.kern(p, id);
        }
        x += font.h_advance(id);
        prev = Some(id);
    }
    x as f64
}

/// A plotters backend whose text is laid out correctly (module documentation); everything else
/// goes to the wrapped backend.
pub struct TextFix<B>(pub B);

impl<B: DrawingBackend> DrawingBackend for TextFix<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.0.get_size()
    }
    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.ensure_prepared()
    }
    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.present()
    }
    fn draw_pixel(
        &mut self,
        p: BackendCoord,
        c: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_pixel(p, c)
    }
    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_line(from, to, style)
    }
    fn draw_rect<S: BackendStyle>(
        &mut self,
        a: BackendCoord,
        b: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_rect(a, b, style, fill)
    }
    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_path(path, style)
    }
    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.fill_polygon(vert, style)
    }
    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.blit_bitmap(pos, size, src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        let size = style.size();
        Ok((text_width(text, size, style.style()).ceil() as u32, (size / 1.24) as u32))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let size = style.size();
        // The box plotters lays text out in (its ab_glyph font's): the advance width, and
        // size / 1.24 high.
        let width = text_width(text, size, style.style()) as i32;
        let height = (size / 1.24) as i32;
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
        let trans = style.transform();
        let (w, h) = self.get_size();
        let font = font_for(style.style());
        let scaled = font.as_scaled(PxScale::from(size as f32));
        let mut pen = 0.0f32;
        let mut prev = None;
        for c in text.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = prev {
                pen += scaled.kern(p, id);
            }
            prev = Some(id);
            let glyph = id.with_scale_and_position(PxScale::from(size as f32), point(pen, 0.0));
            pen += scaled.h_advance(id);
            let Some(outline) = font.outline_glyph(glyph) else { continue };
            let bounds = outline.px_bounds();
            // Baseline where plotters puts it: half the size below the text's top.
            let x0 = bounds.min.x.floor() as i32;
            let y0 = (size as f32 / 2.0 + bounds.min.y).floor() as i32;
            let mut result = Ok(());
            outline.draw(|gx, gy, coverage| {
                if result.is_err() || coverage <= 0.0 {
                    return;
                }
                let (x, y) = trans.transform(x0 + gx as i32 + dx, y0 + gy as i32 + dy);
                let (x, y) = (pos.0 + x, pos.1 + y);
                if x >= 0 && x < w as i32 && y >= 0 && y < h as i32 {
                    let c = BackendColor { alpha: color.alpha * coverage.min(1.0) as f64, rgb: color.rgb };
                    result = self.0.draw_pixel((x, y), c);
                }
            });
            result?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A backend that records where text pixels land.
    struct Canvas {
        ink: Vec<(i32, i32)>,
    }
    impl DrawingBackend for Canvas {
        type ErrorType = std::fmt::Error;
        fn get_size(&self) -> (u32, u32) {
            (400, 100)
        }
        fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            Ok(())
        }
        fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            Ok(())
        }
        fn draw_pixel(
            &mut self,
            p: BackendCoord,
            c: BackendColor,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            if c.alpha > 0.5 {
                self.ink.push(p);
            }
            Ok(())
        }
    }

    /// Columns holding ink, left to right.
    fn inked_columns(text: &str) -> Vec<i32> {
        let mut b = TextFix(Canvas { ink: Vec::new() });
        let style = plotters::style::TextStyle::from(("sans-serif", 20.0).into_font());
        b.draw_text(text, &style, (10, 10)).unwrap();
        let mut cols: Vec<i32> = b.0.ink.iter().map(|p| p.0).collect();
        cols.sort_unstable();
        cols.dedup();
        cols
    }

    use plotters::style::IntoFont;

    /// "cl" must show a gap between the c and the l (plotters' own font drew them touching, so
    /// "class" read "dass"), and "il" two separate strokes.
    #[test]
    fn letters_keep_their_side_bearings() {
        for text in ["cl", "il"] {
            let cols = inked_columns(text);
            assert!(!cols.is_empty(), "{text}: no ink");
            let gaps = cols.windows(2).filter(|w| w[1] > w[0] + 1).count();
            assert!(gaps >= 1, "{text}: the two letters touch (inked columns {cols:?})");
        }
    }

    #[test]
    fn width_grows_with_the_text_and_the_size() {
        let a = text_width("class", 12.0, FontStyle::Normal);
        let b = text_width("classes", 12.0, FontStyle::Normal);
        let c = text_width("class", 24.0, FontStyle::Normal);
        assert!(a > 0.0 && b > a && (c / a - 2.0).abs() < 0.05, "{a} {b} {c}");
    }
}
