//! The detail frequency of one object in one image.
//!
//! **Measure** (see `docs/segmentation.md`): the radius of the disc, centred
//! on zero frequency, that holds [`FrequencyOptions::energy_share`] (90 %) of
//! the spectral energy of the object's image, in **cycles per object
//! diameter**.
//!
//! 1. The object is cut out with its instance mask (other objects and the
//!    background removed) and composited over white, as a NeRF of it is
//!    trained: luminance `c = a·Y + (1 − a)`, `Y` the Rec. 709 luma of the
//!    sRGB-coded colour, `a` = alpha where the mask names the object, else 0.
//! 2. The signal is `s = c − 1 = a·(Y − 1)`: zero wherever the object is
//!    absent, so the analysis box needs no window (its borders are zero) and
//!    both kinds of detail count — texture (variation of `Y`) and shape
//!    (the silhouette against the white background: gear teeth, lattices).
//! 3. `s` is zero-padded to a square of side `L` (the object's bounding box
//!    plus a margin, rounded up to a 2ᵃ3ᵇ5ᶜ size) and transformed with a 2-D
//!    FFT (`rustfft`). Frequency bin (u, v) lies at radius
//!    `√(u² + v²) / L` cycles per pixel.
//! 4. Energies `|S(u, v)|²` (zero frequency excluded: it is the object's mean
//!    darkness, not detail) are accumulated by radius; the radius where the
//!    cumulative share reaches 90 % (linearly interpolated inside a
//!    histogram bin) is the frequency in cycles per pixel.
//! 5. It is multiplied by the object's **diameter** `D = 2·√2·r_g` pixels
//!    (`r_g` the alpha-weighted radius of gyration of the object's pixels:
//!    the diameter of the uniform disc with the same `r_g`), giving cycles
//!    per object diameter.
//!
//! Why cycles per object diameter: resizing a capture (400 vs 800 pixels)
//! or moving the camera scales cycles-per-pixel and the diameter in pixels by
//! inverse factors, so the product — and hence the ranking of objects and a
//! user's threshold α — does not depend on the image size or the camera
//! distance; it only changes where detail falls below the pixel grid.
//! `r_g` rather than the bounding box because it does not change when the
//! object turns in the image plane.

use image::{GrayImage, RgbaImage};
use rustfft::{num_complex::Complex, FftPlanner};
use std::cell::RefCell;

/// Settings of the frequency measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrequencyOptions {
    /// Share of the spectral energy below the reported frequency, in (0, 1).
    pub energy_share: f64,
    /// Views where the object covers fewer pixels than this give no value
    /// (too small to say anything about its detail).
    pub min_pixels: u32,
}

impl Default for FrequencyOptions {
    fn default() -> Self {
        Self {
            energy_share: 0.9,
            min_pixels: 64,
        }
    }
}

/// The detail frequency of one object in one image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetailFrequency {
    /// The measure: cycles per object diameter (see the module docs).
    pub cycles_per_diameter: f64,
    /// The same frequency in cycles per pixel of this image.
    pub cycles_per_pixel: f64,
    /// The object's diameter `2·√2·r_g`, pixels.
    pub diameter_px: f64,
    /// Pixels under the object's mask.
    pub pixels: u32,
}

/// A pixel box `[x0, x1) × [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelBox {
    /// Left edge, inclusive.
    pub x0: u32,
    /// Top edge, inclusive.
    pub y0: u32,
    /// Right edge, exclusive.
    pub x1: u32,
    /// Bottom edge, exclusive.
    pub y1: u32,
}

impl PixelBox {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
}

/// The tight bounding box of the pixels whose mask value is `label`, and
/// their count; `None` when there are none.
pub fn mask_bbox(mask: &GrayImage, label: u8) -> Option<(PixelBox, u32)> {
    let (w, _) = mask.dimensions();
    let (mut x0, mut y0, mut x1, mut y1, mut n) = (u32::MAX, u32::MAX, 0, 0, 0u32);
    for (i, v) in mask.as_raw().iter().enumerate() {
        if *v == label {
            let (x, y) = (i as u32 % w, i as u32 / w);
            x0 = x0.min(x);
            x1 = x1.max(x + 1);
            y0 = y0.min(y);
            y1 = y1.max(y + 1);
            n += 1;
        }
    }
    (n > 0).then_some((PixelBox { x0, y0, x1, y1 }, n))
}

/// Rec. 709 luma of sRGB-coded 8-bit values, in [0, 1].
fn luma(p: &[u8]) -> f32 {
    (0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32) / 255.0
}

/// The smallest `n' ≥ n` of the form 2ᵃ3ᵇ5ᶜ (fast sizes for `rustfft`).
pub fn fft_size(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r % p == 0 {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}

thread_local! {
    // Planning is cached per size; one planner per rayon worker thread.
    static PLANNER: RefCell<FftPlanner<f32>> = RefCell::new(FftPlanner::new());
}

/// The detail frequency of the object labelled `label` in `mask` (instance
/// mask: 0 background, k = object index + 1) within `image`; `None` when the
/// object covers fewer than `opts.min_pixels` pixels or the sizes differ.
pub fn detail_frequency(
    image: &RgbaImage,
    mask: &GrayImage,
    label: u8,
    opts: &FrequencyOptions,
) -> Option<DetailFrequency> {
    if image.dimensions() != mask.dimensions() {
        return None;
    }
    let (bbox, pixels) = mask_bbox(mask, label)?;
    if pixels < opts.min_pixels.max(1) {
        return None;
    }
    let (w, _) = image.dimensions();
    let raw = image.as_raw();
    let mraw = mask.as_raw();

    // Alpha-weighted centroid and radius of gyration of the object's pixels.
    let (mut sa, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
    for y in bbox.y0..bbox.y1 {
        for x in bbox.x0..bbox.x1 {
            let i = (y * w + x) as usize;
            if mraw[i] == label {
                let a = raw[4 * i + 3] as f64 / 255.0;
                sa += a;
                sx += a * (x as f64 + 0.5);
                sy += a * (y as f64 + 0.5);
            }
        }
    }
    if sa <= 0.0 {
        return None;
    }
    let (mx, my) = (sx / sa, sy / sa);
    let mut sr2 = 0.0f64;
    for y in bbox.y0..bbox.y1 {
        for x in bbox.x0..bbox.x1 {
            let i = (y * w + x) as usize;
            if mraw[i] == label {
                let a = raw[4 * i + 3] as f64 / 255.0;
                let (dx, dy) = (x as f64 + 0.5 - mx, y as f64 + 0.5 - my);
                sr2 += a * (dx * dx + dy * dy);
            }
        }
    }
    let diameter_px = 2.0 * (2.0 * sr2 / sa).sqrt();

    // Square analysis box: the bounding box plus a margin of zeros so the
    // transform's periodic wrap-around does not join opposite edges.
    let side = bbox.width().max(bbox.height()) as usize;
    let l = fft_size(side + 2 * (side / 8).max(4));
    let (ox, oy) = ((l - bbox.width() as usize) / 2, (l - bbox.height() as usize) / 2);
    let mut buf = vec![Complex::new(0.0f32, 0.0); l * l];
    for y in bbox.y0..bbox.y1 {
        let row = (oy + (y - bbox.y0) as usize) * l + ox;
        for x in bbox.x0..bbox.x1 {
            let i = (y * w + x) as usize;
            if mraw[i] == label {
                let p = &raw[4 * i..4 * i + 4];
                let a = p[3] as f32 / 255.0;
                buf[row + (x - bbox.x0) as usize].re = a * (luma(p) - 1.0);
            }
        }
    }
    fft_2d_power(&mut buf, l);

    // Energy histogram over radius, bins of 1/4 of the frequency spacing.
    const SUB: f64 = 4.0;
    let max_r = (2.0f64).sqrt() * (l as f64 / 2.0) + 1.0;
    let mut hist = vec![0.0f64; (max_r * SUB) as usize + 2];
    let half = l as i64 / 2;
    let mut total = 0.0f64;
    for v in 0..l {
        let fv = if (v as i64) > half { v as i64 - l as i64 } else { v as i64 };
        for u in 0..l {
            let fu = if (u as i64) > half { u as i64 - l as i64 } else { u as i64 };
            if fu == 0 && fv == 0 {
                continue;
            }
            let e = buf[v * l + u].re as f64;
            let r = ((fu * fu + fv * fv) as f64).sqrt();
            hist[(r * SUB) as usize] += e;
            total += e;
        }
    }
    if total <= 0.0 || !total.is_finite() {
        // A uniformly white object: no detail at all.
        return Some(DetailFrequency {
            cycles_per_diameter: 0.0,
            cycles_per_pixel: 0.0,
            diameter_px,
            pixels,
        });
    }
    let target = opts.energy_share.clamp(0.0, 1.0) * total;
    let mut cum = 0.0f64;
    let mut radius_bins = (hist.len() - 1) as f64;
    for (i, e) in hist.iter().enumerate() {
        if cum + e >= target {
            let frac = if *e > 0.0 { (target - cum) / e } else { 0.0 };
            radius_bins = i as f64 + frac;
            break;
        }
        cum += e;
    }
    let cycles_per_pixel = radius_bins / SUB / l as f64;
    Some(DetailFrequency {
        cycles_per_diameter: cycles_per_pixel * diameter_px,
        cycles_per_pixel,
        diameter_px,
        pixels,
    })
}

/// In-place 2-D FFT of an `l × l` row-major buffer; afterwards `re` holds
/// the power `|S|²` of each bin (transposed, which does not matter for a
/// radial measure).
fn fft_2d_power(buf: &mut [Complex<f32>], l: usize) {
    PLANNER.with(|p| {
        let fft = p.borrow_mut().plan_fft_forward(l);
        let mut scratch = vec![Complex::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        fft.process_with_scratch(buf, &mut scratch);
        transpose_square(buf, l);
        fft.process_with_scratch(buf, &mut scratch);
    });
    for c in buf.iter_mut() {
        *c = Complex::new(c.norm_sqr(), 0.0);
    }
}

fn transpose_square(buf: &mut [Complex<f32>], l: usize) {
    for y in 0..l {
        for x in (y + 1)..l {
            buf.swap(y * l + x, x * l + y);
        }
    }
}
