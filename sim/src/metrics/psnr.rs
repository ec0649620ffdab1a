//! PSNR over all RGB values of two white-composited images.

use super::{check_same_size, MetricsError, WhiteComposite};
use image::RgbaImage;

/// PSNR in dB, `10·log10(1 / MSE)` with MSE over every R, G, B value after
/// compositing over white (peak 1). Identical composites give `f64::INFINITY`.
pub fn psnr(a: &RgbaImage, b: &RgbaImage) -> Result<f64, MetricsError> {
    check_same_size(a.dimensions(), b.dimensions())?;
    psnr_composited(&WhiteComposite::new(a), &WhiteComposite::new(b))
}

/// [`psnr`] of images already composited over white.
pub fn psnr_composited(a: &WhiteComposite, b: &WhiteComposite) -> Result<f64, MetricsError> {
    check_same_size(a.dimensions(), b.dimensions())?;
    let n = a.rgb().len();
    if n == 0 {
        return Err(MetricsError::TooSmall {
            metric: "PSNR",
            min: 1,
            width: a.width(),
            height: a.height(),
        });
    }
    let sse: f64 = a
        .rgb()
        .iter()
        .zip(b.rgb())
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    let mse = sse / n as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    })
}

/// Formats a PSNR for people: two decimals, or `inf` for identical images.
pub fn format_psnr(db: f64) -> String {
    if db.is_infinite() && db > 0.0 {
        "inf".to_owned()
    } else {
        format!("{db:.2}")
    }
}
