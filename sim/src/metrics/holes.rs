//! Interior holes: pixels where the photo shows the object, well inside
//! its silhouette, and a render does not fully cover.
//!
//! The renderer writes each pixel's covered fraction as alpha (2 × 2
//! supersampling: 0, ¼, ½, ¾ or 1), and the metrics composite over white,
//! so a hole inside the object shows as a white speck. On lego's (128, 17)
//! bake they hold 12.8 % of the held-out squared error (`docs/baking.md`,
//! "Session 18"); this measure makes that figure part of every
//! `nerflex bake --measure`.

use super::{check_same_size, MetricsError, WhiteComposite};
use image::RgbaImage;

/// Photo alpha at or above which a pixel is the object.
const OBJECT_ALPHA: u8 = 128;

/// What [`interior_holes`] found in one view.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Holes {
    /// Interior object pixels of the photo (no background pixel within
    /// the margin).
    pub interior: u64,
    /// Of those, pixels the render covers less than fully.
    pub pixels: u64,
    /// … and those it does not cover at all.
    pub empty: u64,
    /// Squared error of the hole pixels, summed over pixels of the mean over
    /// R, G, B (both images composited over white, values in [0, 1]).
    pub squared_error: f64,
    /// The same over every pixel of the view.
    pub total_squared_error: f64,
}

impl std::ops::Add for Holes {
    type Output = Holes;

    /// Sums of two views' counts.
    fn add(self, o: Holes) -> Holes {
        Holes {
            interior: self.interior + o.interior,
            pixels: self.pixels + o.pixels,
            empty: self.empty + o.empty,
            squared_error: self.squared_error + o.squared_error,
            total_squared_error: self.total_squared_error + o.total_squared_error,
        }
    }
}

impl Holes {
    /// The holes' share of the squared error, percent (0 when there is
    /// none).
    pub fn error_share_percent(&self) -> f64 {
        if self.total_squared_error > 0.0 {
            100.0 * self.squared_error / self.total_squared_error
        } else {
            0.0
        }
    }
}

/// The interior holes of `render` against `photo`: pixels whose photo alpha
/// is the object's and whose `(2·margin + 1)²` window holds no background
/// pixel of the photo (so silhouette antialiasing does not count), where the
/// render's alpha is below 255.
pub fn interior_holes(
    render: &RgbaImage,
    photo: &RgbaImage,
    margin: u32,
) -> Result<Holes, MetricsError> {
    check_same_size(render.dimensions(), photo.dimensions())?;
    let (w, h) = photo.dimensions();
    let (w, h) = (w as usize, h as usize);
    // Summed-area table of the photo's background pixels.
    let mut sat = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0u32;
        for x in 0..w {
            row += u32::from(photo.get_pixel(x as u32, y as u32).0[3] < OBJECT_ALPHA);
            sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
        }
    }
    let background_in = |x0: usize, y0: usize, x1: usize, y1: usize| {
        sat[y1 * (w + 1) + x1] + sat[y0 * (w + 1) + x0]
            - sat[y0 * (w + 1) + x1]
            - sat[y1 * (w + 1) + x0]
    };
    let (a, b) = (WhiteComposite::new(render), WhiteComposite::new(photo));
    let (ra, rb) = (a.rgb(), b.rgb());
    let m = margin as usize;
    let mut out = Holes::default();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let se: f64 = (0..3)
                .map(|c| (ra[3 * i + c] - rb[3 * i + c]).powi(2))
                .sum::<f64>()
                / 3.0;
            out.total_squared_error += se;
            let inside = x >= m && y >= m && x + m < w && y + m < h;
            if !inside || background_in(x - m, y - m, x + m + 1, y + m + 1) != 0 {
                continue;
            }
            out.interior += 1;
            let alpha = render.get_pixel(x as u32, y as u32).0[3];
            if alpha < 255 {
                out.pixels += 1;
                out.empty += u64::from(alpha == 0);
                out.squared_error += se;
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgba;

    /// A 20 × 20 photo of a dark square over [4, 16)², transparent around.
    fn photo() -> RgbaImage {
        RgbaImage::from_fn(20, 20, |x, y| {
            if (4..16).contains(&x) && (4..16).contains(&y) {
                Rgba([40, 40, 40, 255])
            } else {
                Rgba([0, 0, 0, 0])
            }
        })
    }

    #[test]
    fn holes_count_only_well_inside_the_photos_object() {
        let truth = photo();
        let mut render = truth.clone();
        // Inside, 3 px from the edge: a hole at margin 2.
        render.put_pixel(7, 7, Rgba([40, 40, 40, 128]));
        // Inside, uncovered.
        render.put_pixel(10, 10, Rgba([0, 0, 0, 0]));
        // On the object's edge row: silhouette, never a hole.
        render.put_pixel(4, 9, Rgba([0, 0, 0, 0]));
        // Background left uncovered, as it should be.
        render.put_pixel(1, 1, Rgba([0, 0, 0, 0]));
        let h = interior_holes(&render, &truth, 2).unwrap();
        // Interior at margin 2: x, y in [6, 14), 8 × 8 pixels.
        assert_eq!(h.interior, 64);
        assert_eq!((h.pixels, h.empty), (2, 1));
        // The uncovered hole shows white against 40/255; the half covered
        // one blends with white by its alpha.
        let (v, a) = (40.0 / 255.0, 128.0 / 255.0);
        let d = 1.0 - v;
        let half = v * a + 1.0 - a - v;
        let expect = d * d + half * half;
        assert!((h.squared_error - expect).abs() < 1e-9, "{h:?}");
        // The silhouette pixel adds to the total only.
        assert!(h.total_squared_error > h.squared_error + 0.5 * d * d);
        assert!(h.error_share_percent() > 0.0 && h.error_share_percent() < 100.0);
        // At margin 3 the first hole is still interior; at 4 it is not.
        assert_eq!(interior_holes(&render, &truth, 3).unwrap().pixels, 2);
        assert_eq!(interior_holes(&render, &truth, 4).unwrap().pixels, 1);
    }

    #[test]
    fn a_full_render_has_no_holes_and_sizes_must_match() {
        let truth = photo();
        let h = interior_holes(&truth, &truth, 1).unwrap();
        assert_eq!((h.pixels, h.empty), (0, 0));
        assert_eq!(h.total_squared_error, 0.0);
        assert_eq!(h.error_share_percent(), 0.0);
        let small = RgbaImage::new(10, 10);
        assert!(matches!(
            interior_holes(&small, &truth, 1),
            Err(MetricsError::SizeMismatch { .. })
        ));
    }
}
