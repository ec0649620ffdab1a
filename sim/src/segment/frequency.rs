//! The detail frequency of one object in one image.
//!
//! **Measure** (see `docs/segmentation.md`): the radius of the disc, centred
//! on zero frequency, that holds [`FrequencyOptions::energy_share`] (75 %) of
//! the spectral energy of the object's mean-removed, windowed luminance
//! within a fixed band of [`FrequencyOptions::band`] (32) cycles per object
//! diameter, in **cycles per object diameter**.
//!
//! 1. Luminance `Y` = Rec. 709 luma of the sRGB-coded colour, over the
//!    pixels whose instance-mask label is the object's (other objects and the
//!    background are excluded).
//! 2. Window `w` = the pixel's alpha × a smoothstep taper from 0 at the
//!    silhouette to 1 at depth `taper·D` inside it (chamfer distance), so
//!    cutting the object out adds no spurious edge; the taper scales with the
//!    object, so it looks the same at any image size.
//! 3. Signal `s = w·(Y − Ȳ)`, `Ȳ` the `w`-weighted mean: the object's
//!    texture and shading, without its average brightness.
//! 4. `s` is zero-padded to a square of side `L` (the object's bounding box
//!    plus a margin, rounded up to a 2ᵃ3ᵇ5ᶜ size) and transformed with a 2-D
//!    FFT (`rustfft`). Bin (u, v) lies at radius `√(u² + v²) / L` cycles per
//!    pixel. The expected power of 8-bit rounding noise is subtracted from
//!    every bin.
//! 5. Energies `|S(u, v)|²` (zero frequency excluded) within the band —
//!    radius ≤ `band / D` cycles per pixel — are accumulated by radius; the
//!    radius where the cumulative share reaches 75 % (linearly interpolated
//!    in quarter-bin steps) is the frequency in cycles per pixel.
//! 6. It is multiplied by the object's **diameter** `D = 2·√2·r_g` pixels
//!    (`r_g` the alpha-weighted radius of gyration of the object's pixels:
//!    the diameter of the uniform disc with the same `r_g`).
//!
//! Why object units and a fixed band: resizing a capture (400 vs 800
//! pixels) or moving the camera scales cycles-per-pixel and the diameter in
//! pixels by inverse factors, so their product does not change — for detail
//! both sizes resolve. Detail near the pixel grid is what downscaling
//! removes, and it removes more of it from finely detailed objects, which
//! reorders objects. Counting only frequencies up to a fixed number of
//! cycles per diameter — a band every view resolves when the object spans
//! at least `2·band` pixels — makes the value, the ranking and a user's
//! threshold α the same at any such size. `r_g` rather than the bounding
//! box because it does not change when the object turns in the image plane.

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
    /// Width of the window's taper inside the silhouette, as a fraction of
    /// the object's diameter.
    pub taper: f64,
    /// Only frequencies up to this many cycles per object diameter count
    /// (`None`: up to the pixel grid). A fixed band in object units is what
    /// makes the measure independent of the image size: a view resolves it
    /// whenever the object spans at least `2·band` pixels.
    pub band: Option<f64>,
}

impl Default for FrequencyOptions {
    fn default() -> Self {
        Self {
            energy_share: 0.75,
            min_pixels: 64,
            taper: 0.03,
            band: Some(32.0),
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
    /// Whether this view resolves the whole band (`D ≥ 2·band` pixels);
    /// when not, the pixel grid cut the band short and the value may be low.
    pub band_resolved: bool,
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

    // Window: the object's coverage, tapered to zero over a band of
    // `taper · D` pixels inside its silhouette (smoothstep of the distance
    // to the nearest non-object pixel), so the cut at the silhouette adds no
    // spurious high frequencies, and the band scales with the object (the
    // same at any image size).
    let (bw, bh) = (bbox.width() as usize, bbox.height() as usize);
    let inside: Vec<bool> = (0..bh)
        .flat_map(|y| (0..bw).map(move |x| (x, y)))
        .map(|(x, y)| mraw[(bbox.y0 as usize + y) * w as usize + bbox.x0 as usize + x] == label)
        .collect();
    let dist = chamfer_inside(&inside, bw, bh);
    let band = (opts.taper * diameter_px).max(1.0) as f32;
    let mut weight = vec![0.0f32; bw * bh];
    let mut lum = vec![0.0f32; bw * bh];
    let (mut sw, mut swy) = (0.0f64, 0.0f64);
    for y in 0..bh {
        for x in 0..bw {
            let j = y * bw + x;
            if !inside[j] {
                continue;
            }
            let i = (bbox.y0 as usize + y) * w as usize + bbox.x0 as usize + x;
            let p = &raw[4 * i..4 * i + 4];
            let t = (dist[j] / band).min(1.0);
            let wt = p[3] as f32 / 255.0 * t * t * (3.0 - 2.0 * t);
            weight[j] = wt;
            lum[j] = luma(p);
            sw += wt as f64;
            swy += (wt * lum[j]) as f64;
        }
    }
    if sw <= 0.0 {
        return None;
    }
    let mean = (swy / sw) as f32;

    // Square analysis box: the bounding box plus a margin of zeros so the
    // transform's periodic wrap-around does not join opposite edges.
    let side = bw.max(bh);
    let l = fft_size(side + 2 * (side / 8).max(4));
    let (ox, oy) = ((l - bw) / 2, (l - bh) / 2);
    let mut buf = vec![Complex::new(0.0f32, 0.0); l * l];
    for y in 0..bh {
        let row = (oy + y) * l + ox;
        for x in 0..bw {
            let j = y * bw + x;
            buf[row + x].re = weight[j] * (lum[j] - mean);
        }
    }
    fft_2d_power(&mut buf, l);

    // 8-bit quantisation adds white noise of variance σ² = Σcᵢ²/(12·255²)
    // to the luma; its expected power in every bin is σ²·Σw². Removing it
    // keeps a flat, featureless object from reporting its rounding noise
    // as detail.
    let sigma2 =
        (0.2126f64.powi(2) + 0.7152f64.powi(2) + 0.0722f64.powi(2)) / (12.0 * 255.0 * 255.0);
    let floor = sigma2 * weight.iter().map(|&w| (w as f64) * (w as f64)).sum::<f64>();

    // Energy histogram over radius, bins of 1/4 of the frequency spacing.
    const SUB: f64 = 4.0;
    let max_r = (2.0f64).sqrt() * (l as f64 / 2.0) + 1.0;
    let mut hist = vec![0.0f64; (max_r * SUB) as usize + 2];
    let half = l as i64 / 2;
    let mut total = 0.0f64;
    // The band: up to `band` cycles per diameter, in bins.
    let r_max = opts
        .band
        .map_or(f64::INFINITY, |b| b / diameter_px * l as f64);
    let band_resolved = opts.band.is_none_or(|b| diameter_px >= 2.0 * b);
    for v in 0..l {
        let fv = if (v as i64) > half {
            v as i64 - l as i64
        } else {
            v as i64
        };
        for u in 0..l {
            let fu = if (u as i64) > half {
                u as i64 - l as i64
            } else {
                u as i64
            };
            if fu == 0 && fv == 0 {
                continue;
            }
            let r = ((fu * fu + fv * fv) as f64).sqrt();
            if r > r_max {
                continue;
            }
            let e = (buf[v * l + u].re as f64 - floor).max(0.0);
            hist[(r * SUB) as usize] += e;
            total += e;
        }
    }
    if total <= 0.0 || !total.is_finite() {
        // A uniform object: no detail above the rounding noise.
        return Some(DetailFrequency {
            cycles_per_diameter: 0.0,
            cycles_per_pixel: 0.0,
            diameter_px,
            pixels,
            band_resolved,
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
        band_resolved,
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

/// Distance (pixels, chamfer 3-4 approximation of Euclidean) from each
/// `inside` pixel to the nearest pixel that is not inside (the box's
/// outside counts as not inside); 0 outside.
fn chamfer_inside(inside: &[bool], w: usize, h: usize) -> Vec<f32> {
    const A: f32 = 1.0; // axial step
    const D: f32 = 1.4; // diagonal step (3-4 chamfer ≈ 1 : 4/3; 1.4 is closer to √2)
    let big = (w + h) as f32 * 2.0;
    let mut d: Vec<f32> = inside.iter().map(|&i| if i { big } else { 0.0 }).collect();
    let at = |d: &Vec<f32>, x: isize, y: isize| -> f32 {
        if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
            0.0
        } else {
            d[y as usize * w + x as usize]
        }
    };
    for y in 0..h as isize {
        for x in 0..w as isize {
            let j = y as usize * w + x as usize;
            if d[j] == 0.0 {
                continue;
            }
            let v = d[j]
                .min(at(&d, x - 1, y) + A)
                .min(at(&d, x, y - 1) + A)
                .min(at(&d, x - 1, y - 1) + D)
                .min(at(&d, x + 1, y - 1) + D);
            d[j] = v;
        }
    }
    for y in (0..h as isize).rev() {
        for x in (0..w as isize).rev() {
            let j = y as usize * w + x as usize;
            if d[j] == 0.0 {
                continue;
            }
            let v = d[j]
                .min(at(&d, x + 1, y) + A)
                .min(at(&d, x, y + 1) + A)
                .min(at(&d, x + 1, y + 1) + D)
                .min(at(&d, x - 1, y + 1) + D);
            d[j] = v;
        }
    }
    // A pixel next to the outside is half a pixel from the boundary.
    d.iter()
        .map(|&v| if v > 0.0 { v - 0.5 } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{Luma, Rgba};

    /// A disc of diameter `d` pixels in an `n × n` image, textured with a
    /// sinusoid of `k` cycles per `d` pixels along x.
    fn disc(n: u32, d: f32, k: f32, contrast: f32) -> (RgbaImage, GrayImage) {
        let c = n as f32 / 2.0;
        let img = RgbaImage::from_fn(n, n, |x, y| {
            let (dx, dy) = (x as f32 + 0.5 - c, y as f32 + 0.5 - c);
            if dx * dx + dy * dy > d * d / 4.0 {
                return Rgba([0; 4]);
            }
            let v = 0.5 + contrast * 0.5 * (std::f32::consts::TAU * k * dx / d).sin();
            let q = (v * 255.0).round() as u8;
            Rgba([q, q, q, 255])
        });
        let mask = GrayImage::from_fn(n, n, |x, y| Luma([u8::from(img.get_pixel(x, y)[3] > 0)]));
        (img, mask)
    }

    #[test]
    fn fft_sizes_are_smooth_and_minimal() {
        assert_eq!(fft_size(1), 1);
        assert_eq!(fft_size(7), 8);
        assert_eq!(fft_size(481), 486);
        assert_eq!(fft_size(1000), 1000);
        for n in 1..300 {
            let m = fft_size(n);
            assert!(m >= n && (n..m).all(|k| fft_size(k) == m));
        }
    }

    #[test]
    fn a_sinusoid_is_found_at_its_frequency_in_object_units() {
        let opts = FrequencyOptions::default();
        for k in [4.0f32, 8.0, 16.0, 24.0] {
            let (img, mask) = disc(300, 240.0, k, 0.8);
            let f = detail_frequency(&img, &mask, 1, &opts).unwrap();
            // Diameter D of a uniform disc equals its geometric diameter.
            assert!((f.diameter_px - 240.0).abs() < 2.0, "{}", f.diameter_px);
            // The window widens the line a little; 75 % lies close to k.
            assert!(
                f.cycles_per_diameter > 0.85 * k as f64 && f.cycles_per_diameter < 1.2 * k as f64,
                "k = {k}: {f:?}"
            );
            assert!(f.band_resolved);
        }
        // Beyond the band the stripes do not count…
        let (img, mask) = disc(300, 240.0, 60.0, 0.8);
        let f = detail_frequency(&img, &mask, 1, &opts).unwrap();
        assert!(f.cycles_per_diameter <= 32.0, "{f:?}");
        // …and without a band they do.
        let full = FrequencyOptions { band: None, ..opts };
        let f = detail_frequency(&img, &mask, 1, &full).unwrap();
        assert!(f.cycles_per_diameter > 50.0, "{f:?}");
    }

    #[test]
    fn the_measure_does_not_depend_on_image_size() {
        let opts = FrequencyOptions::default();
        let (a, ma) = disc(400, 300.0, 12.0, 0.6);
        let (b, mb) = disc(200, 150.0, 12.0, 0.6);
        let fa = detail_frequency(&a, &ma, 1, &opts).unwrap();
        let fb = detail_frequency(&b, &mb, 1, &opts).unwrap();
        let ratio = fa.cycles_per_diameter / fb.cycles_per_diameter;
        assert!((ratio - 1.0).abs() < 0.08, "{fa:?} vs {fb:?}");
        // …while cycles per pixel halve with the doubled size.
        assert!((fb.cycles_per_pixel / fa.cycles_per_pixel - 2.0).abs() < 0.2);
    }

    #[test]
    fn flat_objects_have_no_detail_and_tiny_or_absent_ones_no_value() {
        let opts = FrequencyOptions::default();
        let (img, mask) = disc(100, 80.0, 5.0, 0.0);
        let f = detail_frequency(&img, &mask, 1, &opts).unwrap();
        assert_eq!(f.cycles_per_diameter, 0.0, "{f:?}");
        assert!(f.band_resolved);
        let (img, mask) = disc(100, 6.0, 5.0, 0.8);
        assert!(detail_frequency(&img, &mask, 1, &opts).is_none());
        assert!(detail_frequency(&img, &mask, 2, &opts).is_none());
        let wrong = GrayImage::new(50, 50);
        assert!(detail_frequency(&img, &wrong, 1, &opts).is_none());
    }

    #[test]
    fn only_the_labelled_object_counts() {
        let opts = FrequencyOptions::default();
        let (mut img, mut mask) = disc(200, 120.0, 6.0, 0.7);
        let alone = detail_frequency(&img, &mask, 1, &opts).unwrap();
        // A finely striped second object beside it changes nothing.
        for y in 0..40 {
            for x in 0..40 {
                let q = if x % 2 == 0 { 0 } else { 255 };
                img.put_pixel(x, y, Rgba([q, q, q, 255]));
                mask.put_pixel(x, y, Luma([2]));
            }
        }
        let with_other = detail_frequency(&img, &mask, 1, &opts).unwrap();
        assert_eq!(alone, with_other);
        let other = detail_frequency(&img, &mask, 2, &opts).unwrap();
        assert!(other.cycles_per_pixel > 0.3, "{other:?}");
    }

    #[test]
    fn chamfer_distance_is_close_to_euclidean() {
        let (w, h) = (41, 41);
        let inside: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 - 20.0, (i / w) as f32 - 20.0);
                x * x + y * y <= 400.0
            })
            .collect();
        let d = chamfer_inside(&inside, w, h);
        assert!((d[20 * w + 20] - 20.0).abs() < 1.5, "{}", d[20 * w + 20]);
        assert_eq!(d[0], 0.0);
    }
}
