//! SSIM exactly as scikit-image's `structural_similarity` with
//! `gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
//! data_range=1.0, channel_axis=2`.
//!
//! scikit-image filters the five moment images (x, y, x², y², xy) with
//! `scipy.ndimage.gaussian_filter(sigma=1.5, truncate=3.5, mode='reflect')`
//! (an 11-tap kernel, radius `int(3.5·1.5 + 0.5) = 5`), builds the SSIM map,
//! then crops `(win_size − 1) / 2 = 5` pixels from every side before taking
//! the mean. Because the crop equals the kernel radius, every kept pixel's
//! window lies inside the image: the reflected border never reaches the mean.
//! So we compute only that "valid" region, which is exact, not an
//! approximation.

use super::{check_same_size, MetricsError, WhiteComposite};
use image::RgbaImage;
use rayon::prelude::*;

/// Side of the Gaussian window (pixels); images must be at least this big.
pub const SSIM_WINDOW: u32 = 2 * RADIUS as u32 + 1;

const SIGMA: f64 = 1.5;
/// `int(truncate · sigma + 0.5)` with scikit-image's `truncate = 3.5`.
const RADIUS: usize = 5;
const TAPS: usize = 2 * RADIUS + 1;
const K1: f64 = 0.01;
const K2: f64 = 0.03;
/// `data_range`: composited values lie in [0, 1].
const DATA_RANGE: f64 = 1.0;

/// Mean SSIM over R, G, B of two images composited over white.
pub fn ssim(a: &RgbaImage, b: &RgbaImage) -> Result<f64, MetricsError> {
    check_same_size(a.dimensions(), b.dimensions())?;
    ssim_composited(&WhiteComposite::new(a), &WhiteComposite::new(b))
}

/// [`ssim`] of images already composited over white.
pub fn ssim_composited(a: &WhiteComposite, b: &WhiteComposite) -> Result<f64, MetricsError> {
    check_same_size(a.dimensions(), b.dimensions())?;
    let (w, h) = a.dimensions();
    if w < SSIM_WINDOW || h < SSIM_WINDOW {
        return Err(MetricsError::TooSmall {
            metric: "SSIM",
            min: SSIM_WINDOW,
            width: w,
            height: h,
        });
    }
    let kernel = gaussian_kernel();
    let (w, h) = (w as usize, h as usize);
    let per_channel: Vec<f64> = (0..3)
        .into_par_iter()
        .map(|c| channel_ssim(a.rgb(), b.rgb(), c, w, h, &kernel))
        .collect();
    Ok(per_channel.iter().sum::<f64>() / 3.0)
}

/// scipy's `_gaussian_kernel1d`: `exp(−x²/(2σ²))` for x in −r..=r, normalised.
fn gaussian_kernel() -> [f64; TAPS] {
    let mut k = [0.0; TAPS];
    for (i, v) in k.iter_mut().enumerate() {
        let x = i as f64 - RADIUS as f64;
        *v = (-0.5 * x * x / (SIGMA * SIGMA)).exp();
    }
    let sum: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    k
}

/// The five local moments E[x], E[y], E[x²], E[y²], E[xy].
type Moments = [f64; 5];

/// Mean of the cropped SSIM map of channel `c`.
fn channel_ssim(a: &[f64], b: &[f64], c: usize, w: usize, h: usize, kernel: &[f64; TAPS]) -> f64 {
    let vw = w - 2 * RADIUS; // width of the kept (valid) region
    let vh = h - 2 * RADIUS;

    // Horizontal pass over every row, only at the kept columns.
    let mut horiz: Vec<Moments> = vec![[0.0; 5]; h * vw];
    horiz.par_chunks_mut(vw).enumerate().for_each(|(y, out)| {
        let row = y * w;
        for (xo, m) in out.iter_mut().enumerate() {
            let mut acc = [0.0; 5];
            for (k, &wk) in kernel.iter().enumerate() {
                let i = (row + xo + k) * 3 + c;
                let (p, q) = (a[i], b[i]);
                acc[0] += wk * p;
                acc[1] += wk * q;
                acc[2] += wk * p * p;
                acc[3] += wk * q * q;
                acc[4] += wk * p * q;
            }
            *m = acc;
        }
    });

    // Vertical pass at the kept rows, then the SSIM formula, summed per row.
    let c1 = (K1 * DATA_RANGE).powi(2);
    let c2 = (K2 * DATA_RANGE).powi(2);
    let total: f64 = (0..vh)
        .into_par_iter()
        .map(|yo| {
            let mut row_sum = 0.0;
            for xo in 0..vw {
                let mut m = [0.0; 5];
                for (k, &wk) in kernel.iter().enumerate() {
                    let src = &horiz[(yo + k) * vw + xo];
                    for (acc, s) in m.iter_mut().zip(src) {
                        *acc += wk * s;
                    }
                }
                let [ux, uy, uxx, uyy, uxy] = m;
                // use_sample_covariance=False: population (co)variances.
                let vx = uxx - ux * ux;
                let vy = uyy - uy * uy;
                let vxy = uxy - ux * uy;
                let num = (2.0 * ux * uy + c1) * (2.0 * vxy + c2);
                let den = (ux * ux + uy * uy + c1) * (vx + vy + c2);
                row_sum += num / den;
            }
            row_sum
        })
        .collect::<Vec<f64>>()
        // Summed in row order: a parallel float sum's grouping depends on
        // work stealing, and the same images must give the same SSIM bits.
        .iter()
        .sum();
    total / (vw * vh) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_matches_scipy() {
        let k = gaussian_kernel();
        // scipy.ndimage._gaussian_kernel1d(1.5, 0, 5), centre and edge taps.
        assert!((k[RADIUS] - 0.266_011_724_9).abs() < 1e-9, "{}", k[RADIUS]);
        assert!((k[0] - 0.001_028_380_1).abs() < 1e-9, "{}", k[0]);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}
