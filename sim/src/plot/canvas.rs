//! Drawing primitives over a tiny-skia `Pixmap`: anti-aliased shapes through
//! tiny-skia, text through embedded-graphics (the `DrawTarget` impls below).

use super::Rgb;
use embedded_graphics::{
    mono_font::{iso_8859_1 as fonts, MonoFont, MonoTextStyle},
    pixelcolor::Rgb888,
    prelude::{Dimensions, DrawTarget, OriginDimensions, Point, RgbColor, Size},
    primitives::Rectangle,
    text::{Baseline, Text},
    Drawable, Pixel,
};
use tiny_skia::{
    FillRule, LineCap, LineJoin, Mask, Paint, PathBuilder, Pixmap, PremultipliedColorU8, Rect,
    Stroke, StrokeDash, Transform,
};

/// The fonts of one chart, chosen by picture size.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fonts {
    pub title: &'static MonoFont<'static>,
    pub label: &'static MonoFont<'static>,
    pub tick: &'static MonoFont<'static>,
    pub small: &'static MonoFont<'static>,
}

impl Fonts {
    pub fn for_size(width: u32, height: u32) -> Self {
        if width.min(height) >= 400 {
            Fonts {
                title: &fonts::FONT_10X20,
                label: &fonts::FONT_9X15,
                tick: &fonts::FONT_7X13,
                small: &fonts::FONT_6X10,
            }
        } else {
            Fonts {
                title: &fonts::FONT_9X15_BOLD,
                label: &fonts::FONT_7X13,
                tick: &fonts::FONT_6X10,
                small: &fonts::FONT_5X8,
            }
        }
    }
}

/// Width of `s` in `font` (pixels).
pub(crate) fn text_width(font: &MonoFont<'_>, s: &str) -> f32 {
    let n = s.chars().count() as u32;
    if n == 0 {
        return 0.0;
    }
    (n * font.character_size.width + (n - 1) * font.character_spacing) as f32
}

/// Height of a line of `font` (pixels).
pub(crate) fn text_height(font: &MonoFont<'_>) -> f32 {
    font.character_size.height as f32
}

/// Horizontal anchor of a text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum HAlign {
    Left,
    Center,
    Right,
}

/// Vertical anchor of a text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum VAlign {
    Top,
    Middle,
    Bottom,
}

/// A pixmap being drawn on.
pub(crate) struct Canvas<'a> {
    pub pixmap: &'a mut Pixmap,
}

fn paint(color: Rgb) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(color.0, color.1, color.2, 255);
    p.anti_alias = true;
    p
}

impl<'a> Canvas<'a> {
    pub fn new(pixmap: &'a mut Pixmap) -> Self {
        Self { pixmap }
    }

    /// A clip mask that keeps drawing inside the rectangle (plot area).
    pub fn clip(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> Option<Mask> {
        let mut mask = Mask::new(self.pixmap.width(), self.pixmap.height())?;
        let path = PathBuilder::from_rect(Rect::from_ltrb(x0, y0, x1, y1)?);
        mask.fill_path(&path, FillRule::Winding, false, Transform::identity());
        Some(mask)
    }

    /// A polyline; `dash` in multiples of the width (on, off), if dashed.
    pub fn polyline(
        &mut self,
        pts: &[(f32, f32)],
        color: Rgb,
        width: f32,
        dashed: bool,
        clip: Option<&Mask>,
    ) {
        let mut pb = PathBuilder::new();
        let mut iter = pts.iter();
        let Some(&(x, y)) = iter.next() else { return };
        pb.move_to(x, y);
        for &(x, y) in iter {
            pb.line_to(x, y);
        }
        let Some(path) = pb.finish() else { return };
        let stroke = Stroke {
            width,
            line_cap: if dashed {
                LineCap::Butt
            } else {
                LineCap::Round
            },
            line_join: LineJoin::Round,
            dash: if dashed {
                StrokeDash::new(vec![4.0 * width.max(1.5), 2.5 * width.max(1.5)], 0.0)
            } else {
                None
            },
            ..Stroke::default()
        };
        self.pixmap
            .stroke_path(&path, &paint(color), &stroke, Transform::identity(), clip);
    }

    /// A crisp 1-pixel horizontal or vertical line (for axes, grid, ticks):
    /// coordinates are snapped to pixel centres so it is not blurred.
    pub fn hairline(&mut self, x0: f32, y0: f32, x1: f32, y1: f32, color: Rgb) {
        let snap = |v: f32| v.floor() + 0.5;
        let (x0, x1) = if x0 == x1 {
            (snap(x0), snap(x1))
        } else {
            (x0, x1)
        };
        let (y0, y1) = if y0 == y1 {
            (snap(y0), snap(y1))
        } else {
            (y0, y1)
        };
        let mut pb = PathBuilder::new();
        pb.move_to(x0, y0);
        pb.line_to(x1, y1);
        let Some(path) = pb.finish() else { return };
        let stroke = Stroke {
            width: 1.0,
            ..Stroke::default()
        };
        let mut p = paint(color);
        p.anti_alias = false;
        self.pixmap
            .stroke_path(&path, &p, &stroke, Transform::identity(), None);
    }

    /// A filled rectangle.
    pub fn rect(&mut self, x0: f32, y0: f32, x1: f32, y1: f32, color: Rgb, clip: Option<&Mask>) {
        if let Some(r) = Rect::from_ltrb(x0.min(x1), y0.min(y1), x0.max(x1), y0.max(y1)) {
            let mut p = paint(color);
            p.anti_alias = false;
            self.pixmap.fill_rect(r, &p, Transform::identity(), clip);
        }
    }

    /// A rectangle outline (1 pixel, crisp).
    pub fn rect_outline(&mut self, x0: f32, y0: f32, x1: f32, y1: f32, color: Rgb) {
        self.hairline(x0, y0, x1, y0, color);
        self.hairline(x0, y1, x1, y1, color);
        self.hairline(x0, y0, x0, y1, color);
        self.hairline(x1, y0, x1, y1, color);
    }

    /// A filled circle with a thin white ring, so markers stay visible over
    /// lines of other series.
    pub fn marker(&mut self, x: f32, y: f32, r: f32, color: Rgb, clip: Option<&Mask>) {
        if let Some(path) = PathBuilder::from_circle(x, y, r + 1.0) {
            self.pixmap.fill_path(
                &path,
                &paint(Rgb::WHITE),
                FillRule::Winding,
                Transform::identity(),
                clip,
            );
        }
        if let Some(path) = PathBuilder::from_circle(x, y, r) {
            self.pixmap.fill_path(
                &path,
                &paint(color),
                FillRule::Winding,
                Transform::identity(),
                clip,
            );
        }
    }

    /// Text anchored at `(x, y)` by `(h, v)`.
    pub fn text(
        &mut self,
        s: &str,
        font: &MonoFont<'_>,
        (x, y): (f32, f32),
        (h, v): (HAlign, VAlign),
        color: Rgb,
    ) {
        let (left, top) = anchor(font, s, x, y, h, v);
        draw_text(self, s, font, left, top, color);
    }

    /// Text turned 90° counter-clockwise (reads bottom to top), centred on
    /// (cx, cy): for the y axis title.
    pub fn text_vertical(&mut self, s: &str, font: &MonoFont<'_>, cx: f32, cy: f32, color: Rgb) {
        let len = text_width(font, s);
        let h = text_height(font);
        let mut rotated = Rotated {
            canvas: self,
            ox: (cx - h / 2.0).round() as i32,
            oy: (cy + len / 2.0).round() as i32,
        };
        draw_text(&mut rotated, s, font, 0, 0, color);
    }
}

/// Top-left corner of `s` anchored at (x, y).
fn anchor(font: &MonoFont<'_>, s: &str, x: f32, y: f32, h: HAlign, v: VAlign) -> (i32, i32) {
    let w = text_width(font, s);
    let ht = text_height(font);
    let left = match h {
        HAlign::Left => x,
        HAlign::Center => x - w / 2.0,
        HAlign::Right => x - w,
    };
    let top = match v {
        VAlign::Top => y,
        VAlign::Middle => y - ht / 2.0,
        VAlign::Bottom => y - ht,
    };
    (left.round() as i32, top.round() as i32)
}

fn draw_text<D: DrawTarget<Color = Rgb888>>(
    target: &mut D,
    s: &str,
    font: &MonoFont<'_>,
    left: i32,
    top: i32,
    color: Rgb,
) {
    let style = MonoTextStyle::new(font, Rgb888::new(color.0, color.1, color.2));
    // Drawing into a pixmap cannot fail (errors are Infallible).
    let _ = Text::with_baseline(s, Point::new(left, top), style, Baseline::Top).draw(target);
}

impl OriginDimensions for Canvas<'_> {
    fn size(&self) -> Size {
        Size::new(self.pixmap.width(), self.pixmap.height())
    }
}

impl DrawTarget for Canvas<'_> {
    type Color = Rgb888;
    type Error = core::convert::Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = Pixel<Self::Color>>,
    {
        let (w, h) = (self.pixmap.width() as i32, self.pixmap.height() as i32);
        let data = self.pixmap.pixels_mut();
        for Pixel(p, c) in pixels {
            if p.x < 0 || p.y < 0 || p.x >= w || p.y >= h {
                continue;
            }
            if let Some(px) = PremultipliedColorU8::from_rgba(c.r(), c.g(), c.b(), 255) {
                data[(p.y * w + p.x) as usize] = px;
            }
        }
        Ok(())
    }
}

/// A draw target that turns everything drawn on it 90° counter-clockwise
/// around (ox, oy): text-space (u, v) lands at (ox + v, oy − u).
struct Rotated<'c, 'a> {
    canvas: &'c mut Canvas<'a>,
    ox: i32,
    oy: i32,
}

impl Dimensions for Rotated<'_, '_> {
    fn bounding_box(&self) -> Rectangle {
        // Text space is unbounded; the canvas clips.
        Rectangle::new(Point::new(-100_000, -100_000), Size::new(200_000, 200_000))
    }
}

impl DrawTarget for Rotated<'_, '_> {
    type Color = Rgb888;
    type Error = core::convert::Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = Pixel<Self::Color>>,
    {
        let (ox, oy) = (self.ox, self.oy);
        self.canvas.draw_iter(
            pixels
                .into_iter()
                .map(|Pixel(p, c)| Pixel(Point::new(ox + p.y, oy - p.x), c)),
        )
    }
}
