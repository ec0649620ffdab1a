//! The training pixels: every training view's colours composited over
//! white, which pixels are known, and random ray batches drawn from them.
//!
//! A pixel of the object, or of the background, is known (the background
//! is white, as NeRF papers composite it). A pixel of *another* object
//! (an instance-mask value other than 0 and the object's label, e.g. 255
//! in segmentation's group folders) is unknown: the object may continue
//! behind it, so it is never drawn.

use glam::Vec3;
use rand::Rng;

use crate::bake::sweep::TrainView;
use crate::camera::Camera;

/// One training view, ready for sampling.
pub struct PixelView {
    /// The camera.
    pub camera: Camera,
    /// Width, pixels.
    pub width: u32,
    /// Colours over white, 8 bits, RGB, row-major.
    pub rgb: Vec<[u8; 3]>,
    /// Whether each pixel is known.
    pub known: Vec<bool>,
    /// The rectangle rays are drawn from: (x0, y0, x1, y1), pixels.
    pub rect: (u32, u32, u32, u32),
}

/// All training views and the cumulative areas used to draw from them.
pub struct PixelSet {
    /// The views.
    pub views: Vec<PixelView>,
    cumulative: Vec<u64>,
}

/// One drawn ray: camera, pixel centre and target colour.
#[derive(Debug, Clone, Copy)]
pub struct PixelRay {
    /// World origin.
    pub origin: Vec3,
    /// World unit direction.
    pub dir: Vec3,
    /// Target colour in [0, 1].
    pub target: Vec3,
}

impl PixelSet {
    /// Prepares the views; `bounds` (world corners of the object's box)
    /// limits each view's rectangle to where the box projects, plus a
    /// margin of 2 pixels.
    pub fn new(train: &[TrainView], bounds: &[Vec3; 8]) -> Self {
        let views: Vec<PixelView> = train
            .iter()
            .map(|(camera, image, mask)| {
                let (w, h) = image.dimensions();
                let mut rgb = Vec::with_capacity((w * h) as usize);
                let mut known = Vec::with_capacity((w * h) as usize);
                for (n, px) in image.pixels().enumerate() {
                    let [r, g, b, a] = px.0;
                    let label = mask.as_ref().map(|(m, l)| (m.as_raw()[n], *l));
                    let (is_known, is_object) = match label {
                        None => (true, true),
                        Some((v, l)) => (v == 0 || v == l, v == l),
                    };
                    known.push(is_known);
                    rgb.push(if is_object {
                        over_white([r, g, b], a)
                    } else {
                        [255; 3]
                    });
                }
                let rect = project_rect(camera, bounds, w, h);
                PixelView {
                    camera: *camera,
                    width: w,
                    rgb,
                    known,
                    rect,
                }
            })
            .collect();
        let mut cumulative = Vec::with_capacity(views.len());
        let mut total = 0u64;
        for v in &views {
            let (x0, y0, x1, y1) = v.rect;
            total += u64::from(x1 - x0) * u64::from(y1 - y0);
            cumulative.push(total);
        }
        PixelSet { views, cumulative }
    }

    /// Pixels rays can be drawn from.
    pub fn area(&self) -> u64 {
        self.cumulative.last().copied().unwrap_or(0)
    }

    /// Draws a `side`×`side` patch of pixels at a uniformly random place
    /// of the views' rectangles and appends its known pixels' rays to
    /// `out`. Neighbouring rays cross the same cells, so a batch of patches
    /// gathers and scatters through far fewer cache lines than as many
    /// independent pixels (the trainer is memory-latency bound).
    pub fn draw_patch(&self, rng: &mut impl Rng, side: u32, out: &mut Vec<PixelRay>) {
        let area = self.area();
        if area == 0 {
            return;
        }
        let r = rng.random_range(0..area);
        let vi = self.cumulative.partition_point(|&c| c <= r);
        let Some(v) = self.views.get(vi) else { return };
        let (x0, y0, x1, y1) = v.rect;
        let x = rng.random_range(x0..x1);
        let y = rng.random_range(y0..y1);
        let height = (v.known.len() / v.width.max(1) as usize) as u32;
        for py in y..(y + side).min(height) {
            for px in x..(x + side).min(v.width) {
                let n = (py * v.width + px) as usize;
                if !v.known[n] {
                    continue;
                }
                let (origin, dir) = v.camera.ray(px as f32 + 0.5, py as f32 + 0.5);
                let c = v.rgb[n];
                out.push(PixelRay {
                    origin,
                    dir,
                    target: Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) / 255.0,
                });
            }
        }
    }
}

/// An 8-bit colour with coverage `a` composited over white.
#[inline]
pub fn over_white(rgb: [u8; 3], a: u8) -> [u8; 3] {
    let a = u32::from(a);
    rgb.map(|c| ((u32::from(c) * a + 255 * (255 - a) + 127) / 255) as u8)
}

/// The pixel rectangle covering the projections of the box corners, or
/// the whole image when some corner is behind the camera.
fn project_rect(camera: &Camera, corners: &[Vec3; 8], w: u32, h: u32) -> (u32, u32, u32, u32) {
    let mut lo = (f32::MAX, f32::MAX);
    let mut hi = (f32::MIN, f32::MIN);
    for &c in corners {
        let Some((x, y, _)) = camera.project(c) else {
            return (0, 0, w, h);
        };
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    let clamp = |v: f32, max: u32| (v.max(0.0) as u32).min(max);
    let (x0, y0) = (clamp(lo.0 - 2.0, w), clamp(lo.1 - 2.0, h));
    let (x1, y1) = (clamp(hi.0 + 3.0, w), clamp(hi.1 + 3.0, h));
    if x1 <= x0 || y1 <= y0 {
        (0, 0, 0, 0)
    } else {
        (x0, y0, x1, y1)
    }
}

/// The eight corners of a box.
pub fn box_corners(min: Vec3, max: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|n| {
        Vec3::new(
            if n & 1 == 0 { min.x } else { max.x },
            if n & 2 == 0 { min.y } else { max.y },
            if n & 4 == 0 { min.z } else { max.z },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compositing_over_white() {
        assert_eq!(over_white([0, 0, 0], 255), [0, 0, 0]);
        assert_eq!(over_white([0, 0, 0], 0), [255, 255, 255]);
        assert_eq!(over_white([100, 200, 50], 128), [177, 227, 152]);
    }
}
