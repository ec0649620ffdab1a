//! The printed page of the `text-panel` object: lines of text drawn once
//! with `embedded-graphics`' monospace fonts into a coverage bitmap, sampled
//! bilinearly as a texture.

use embedded_graphics::mono_font::ascii::{FONT_10X20, FONT_6X10};
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::pixelcolor::BinaryColor;
use embedded_graphics::prelude::*;
use embedded_graphics::text::{Baseline, Text};
use std::convert::Infallible;
use std::sync::OnceLock;

/// Coverage bitmap (0 paper, 1 ink) and a second layer for red headline ink.
pub struct Page {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    ink: Vec<u8>,
    red: Vec<u8>,
}

struct Layer<'a> {
    w: u32,
    h: u32,
    px: &'a mut [u8],
}

impl OriginDimensions for Layer<'_> {
    fn size(&self) -> Size {
        Size::new(self.w, self.h)
    }
}

impl DrawTarget for Layer<'_> {
    type Color = BinaryColor;
    type Error = Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Infallible>
    where
        I: IntoIterator<Item = Pixel<BinaryColor>>,
    {
        for Pixel(p, c) in pixels {
            if p.x >= 0 && p.y >= 0 && (p.x as u32) < self.w && (p.y as u32) < self.h {
                self.px[(p.y as u32 * self.w + p.x as u32) as usize] = u8::from(c.is_on());
            }
        }
        Ok(())
    }
}

const HEADLINE: &str = "NeRFlex";
const BODY: [&str; 13] = [
    "Resource-aware real-time rendering",
    "of complex scenes on mobile devices.",
    "A scene is split into objects; each",
    "object earns its own baked NeRF: a",
    "quad mesh on a g^3 voxel grid, a pxp",
    "feature patch per quad and a tiny MLP",
    "(11-16-16-3) that turns features and",
    "the view direction into colour. The",
    "profiler predicts size and quality,",
    "the selector solves a multiple-choice",
    "knapsack under the device budget:",
    "iPhone 13 240 MB, Pixel 4 150 MB.",
    "0123456789 ABCDEFGHIJKLMNOPQRSTUVWXYZ",
];

/// The page, drawn on first use.
pub fn page() -> &'static Page {
    static PAGE: OnceLock<Page> = OnceLock::new();
    PAGE.get_or_init(draw_page)
}

fn draw_page() -> Page {
    let (w, h) = (240u32, 176u32);
    let mut ink = vec![0u8; (w * h) as usize];
    let mut red = vec![0u8; (w * h) as usize];
    let mut layer = Layer { w, h, px: &mut red };
    let big = MonoTextStyle::new(&FONT_10X20, BinaryColor::On);
    // Drawing into memory cannot fail (the error type is Infallible).
    let _ = Text::with_baseline(HEADLINE, Point::new(85, 4), big, Baseline::Top).draw(&mut layer);
    let mut layer = Layer { w, h, px: &mut ink };
    let small = MonoTextStyle::new(&FONT_6X10, BinaryColor::On);
    for (i, line) in BODY.iter().enumerate() {
        let y = 30 + 11 * i as i32;
        let _ = Text::with_baseline(line, Point::new(6, y), small, Baseline::Top).draw(&mut layer);
    }
    Page {
        width: w,
        height: h,
        ink,
        red,
    }
}

impl Page {
    /// Bilinear (ink, red) coverage at texture coordinates `u`, `v` in [0, 1]
    /// (v down); zero outside.
    pub fn sample(&self, u: f32, v: f32) -> (f32, f32) {
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |layer: &[u8], xi: i64, yi: i64| -> f32 {
            if xi < 0 || yi < 0 || xi >= self.width as i64 || yi >= self.height as i64 {
                0.0
            } else {
                f32::from(layer[(yi as u32 * self.width + xi as u32) as usize])
            }
        };
        let bil = |layer: &[u8]| {
            let (xi, yi) = (x0 as i64, y0 as i64);
            let a = at(layer, xi, yi) * (1.0 - fx) + at(layer, xi + 1, yi) * fx;
            let b = at(layer, xi, yi + 1) * (1.0 - fx) + at(layer, xi + 1, yi + 1) * fx;
            a * (1.0 - fy) + b * fy
        };
        (bil(&self.ink), bil(&self.red))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_has_ink_and_paper() {
        let p = page();
        let ink: u32 = p.ink.iter().map(|&v| u32::from(v)).sum();
        let red: u32 = p.red.iter().map(|&v| u32::from(v)).sum();
        let n = p.width * p.height;
        assert!(ink > n / 20 && ink < n / 2, "ink {ink} of {n}");
        assert!(red > 50);
        assert_eq!(p.sample(-1.0, 0.5), (0.0, 0.0));
    }
}
