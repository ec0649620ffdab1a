//! Side-by-side pictures of bakes: the ground truth of one held-out view
//! next to the renders of several (g, p) bakes, each composited over white,
//! with a caption under each tile (`nerflex bake --compare`).

use embedded_graphics::{
    mono_font::{iso_8859_1::FONT_7X13, MonoTextStyle},
    pixelcolor::Rgb888,
    prelude::{Dimensions, DrawTarget, OriginDimensions, Point, Size},
    text::{Baseline, Text},
    Drawable, Pixel,
};
use image::{Rgba, RgbaImage};

/// `img` composited over white (opaque), optionally scaled (triangle
/// filter) so that its longer side is `size` pixels.
pub fn over_white(img: &RgbaImage, size: Option<u32>) -> RgbaImage {
    let white = RgbaImage::from_fn(img.width(), img.height(), |x, y| {
        let p = img.get_pixel(x, y).0;
        let a = u32::from(p[3]);
        let c = |v: u8| ((u32::from(v) * a + 255 * (255 - a) + 127) / 255) as u8;
        Rgba([c(p[0]), c(p[1]), c(p[2]), 255])
    });
    match size {
        Some(s) if s > 0 && s < img.width().max(img.height()) => {
            let k = f64::from(s) / f64::from(img.width().max(img.height()));
            let w = ((f64::from(img.width()) * k).round() as u32).max(1);
            let h = ((f64::from(img.height()) * k).round() as u32).max(1);
            image::imageops::resize(&white, w, h, image::imageops::FilterType::Triangle)
        }
        _ => white,
    }
}

/// One tile of a comparison strip: a picture and its caption lines.
pub struct Tile<'a> {
    /// The picture (any alpha; composited over white).
    pub image: &'a RgbaImage,
    /// Caption lines under the picture.
    pub caption: Vec<String>,
}

/// Gap between tiles and around the strip, pixels.
const GAP: u32 = 8;
/// Height of one caption line, pixels (7×13 font + spacing).
const LINE: u32 = 15;

/// The box (x, y, w, h) of the pixels with any coverage in any of the
/// images (all the same size), grown by `margin` pixels; `None` if the
/// sizes differ or nothing is covered.
fn covered_box(images: &[&RgbaImage], margin: u32) -> Option<(u32, u32, u32, u32)> {
    let (w, h) = images.first()?.dimensions();
    if images.iter().any(|i| i.dimensions() != (w, h)) {
        return None;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for img in images {
        for (x, y, p) in img.enumerate_pixels() {
            if p.0[3] > 0 {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
        }
    }
    (x0 < x1).then(|| {
        let (x0, y0) = (x0.saturating_sub(margin), y0.saturating_sub(margin));
        let (x1, y1) = ((x1 + margin).min(w), (y1 + margin).min(h));
        (x0, y0, x1 - x0, y1 - y0)
    })
}

/// The tiles side by side, cropped alike to what any of them covers (plus
/// a margin), each scaled by the factor that makes a full image's longer
/// side `size` pixels (`None`: full size), captions underneath, on white.
pub fn strip(tiles: &[Tile<'_>], size: Option<u32>) -> RgbaImage {
    let images: Vec<&RgbaImage> = tiles.iter().map(|t| t.image).collect();
    let full = images.first().map_or(0, |i| i.width().max(i.height()));
    let pics: Vec<RgbaImage> = match covered_box(&images, full / 50) {
        Some((x, y, w, h)) => {
            let side = size.map(|s| {
                // Same scale as the uncropped image scaled to `s`.
                let k = f64::from(s) / f64::from(full.max(1));
                (f64::from(w.max(h)) * k).round().max(1.0) as u32
            });
            images
                .iter()
                .map(|i| over_white(&image::imageops::crop_imm(*i, x, y, w, h).to_image(), side))
                .collect()
        }
        None => images.iter().map(|i| over_white(i, size)).collect(),
    };
    let lines = tiles.iter().map(|t| t.caption.len()).max().unwrap_or(0) as u32;
    let tile_h = pics.iter().map(|p| p.height()).max().unwrap_or(0);
    let width = pics.iter().map(|p| p.width() + GAP).sum::<u32>() + GAP;
    let height = GAP + tile_h + GAP / 2 + lines * LINE + GAP;
    let mut out = RgbaImage::from_pixel(width, height, Rgba([255, 255, 255, 255]));
    let mut x = GAP;
    for (pic, tile) in pics.iter().zip(tiles) {
        image::imageops::replace(&mut out, pic, i64::from(x), i64::from(GAP));
        let mut target = ImageTarget(&mut out);
        let style = MonoTextStyle::new(&FONT_7X13, Rgb888::new(0x33, 0x33, 0x33));
        for (i, line) in tile.caption.iter().enumerate() {
            let y = GAP + tile_h + GAP / 2 + i as u32 * LINE;
            // Drawing into an in-memory image cannot fail (Infallible).
            let _ = Text::with_baseline(line, Point::new(x as i32, y as i32), style, Baseline::Top)
                .draw(&mut target);
        }
        x += pic.width() + GAP;
    }
    out
}

/// An `RgbaImage` as an embedded-graphics draw target (for captions);
/// pixels outside the image are ignored.
struct ImageTarget<'a>(&'a mut RgbaImage);

impl OriginDimensions for ImageTarget<'_> {
    fn size(&self) -> Size {
        Size::new(self.0.width(), self.0.height())
    }
}

impl DrawTarget for ImageTarget<'_> {
    type Color = Rgb888;
    type Error = core::convert::Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = Pixel<Self::Color>>,
    {
        let area = self.bounding_box();
        for Pixel(p, c) in pixels {
            if area.contains(p) {
                use embedded_graphics::pixelcolor::RgbColor as _;
                self.0
                    .put_pixel(p.x as u32, p.y as u32, Rgba([c.r(), c.g(), c.b(), 255]));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strip_places_tiles_side_by_side_over_white() {
        let red = RgbaImage::from_pixel(20, 10, Rgba([255, 0, 0, 255]));
        let clear = RgbaImage::from_pixel(20, 10, Rgba([0, 0, 255, 0]));
        let s = strip(
            &[
                Tile {
                    image: &red,
                    caption: vec!["a".into()],
                },
                Tile {
                    image: &clear,
                    caption: vec!["b".into(), "c".into()],
                },
            ],
            None,
        );
        assert_eq!(s.width(), GAP + 20 + GAP + 20 + GAP);
        assert_eq!(s.height(), GAP + 10 + GAP / 2 + 2 * LINE + GAP);
        assert_eq!(s.get_pixel(GAP + 5, GAP + 5).0, [255, 0, 0, 255]);
        // Fully transparent pixels become white.
        assert_eq!(s.get_pixel(2 * GAP + 25, GAP + 5).0, [255, 255, 255, 255]);
        // Some caption pixel is dark.
        let dark = (GAP + 10..s.height())
            .flat_map(|y| (0..s.width()).map(move |x| (x, y)))
            .any(|(x, y)| s.get_pixel(x, y).0[0] < 128);
        assert!(dark);
    }

    #[test]
    fn strip_crops_to_the_covered_box() {
        let mut a = RgbaImage::from_pixel(100, 100, Rgba([0, 0, 0, 0]));
        a.put_pixel(10, 20, Rgba([0, 0, 0, 255]));
        let mut b = a.clone();
        b.put_pixel(30, 25, Rgba([0, 0, 0, 255]));
        let t = |i| Tile {
            image: i,
            caption: vec![],
        };
        // Box x 10..31, y 20..26, grown by 2: 25 × 10.
        let s = strip(&[t(&a), t(&b)], None);
        assert_eq!(s.width(), GAP + 25 + GAP + 25 + GAP);
        assert_eq!(s.height(), GAP + 10 + GAP / 2 + GAP);
        assert_eq!(s.get_pixel(GAP + 2, GAP + 2).0, [0, 0, 0, 255]);
    }

    #[test]
    fn over_white_scales_the_longer_side() {
        let img = RgbaImage::from_pixel(80, 40, Rgba([0, 0, 0, 128]));
        let w = over_white(&img, Some(20));
        assert_eq!(w.dimensions(), (20, 10));
        let p = w.get_pixel(10, 5).0;
        assert!((126..=128).contains(&p[0]), "{p:?}");
        assert_eq!(p[3], 255);
    }
}
