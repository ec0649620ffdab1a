//! Samples generated from known model parameters plus Gaussian noise: the
//! fitter's ground truth in tests and benchmarks (never reported as
//! measurements).

use super::samples::Sample;
use nerflex_core::profiler::Params;
use nerflex_core::units::Bytes;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Noise added to the model values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    /// Standard deviation of the size noise, relative to the size.
    pub size_rel: f64,
    /// Standard deviation of the SSIM noise (absolute).
    pub ssim_abs: f64,
}

impl Noise {
    /// No noise.
    pub const NONE: Noise = Noise {
        size_rel: 0.0,
        ssim_abs: 0.0,
    };
}

/// One standard normal draw (Box–Muller).
fn normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Samples of `object` at every (g, p) of `grids × patches`: size from
/// `size` (bytes, rounded, at least 1), SSIM from `quality` (clamped to
/// `[0, 1]`), each with noise; deterministic for a `seed`.
pub fn samples(
    object: &str,
    size: &Params,
    quality: &Params,
    grids: &[u32],
    patches: &[u32],
    noise: Noise,
    seed: u64,
) -> Vec<Sample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(grids.len() * patches.len());
    for &g in grids {
        for &p in patches {
            let s = size.size_f64(g as f64, p as f64) * (1.0 + noise.size_rel * normal(&mut rng));
            let q = quality.quality_f64(g as f64, p as f64) + noise.ssim_abs * normal(&mut rng);
            out.push(Sample {
                object: object.to_string(),
                g,
                p,
                size: Bytes(s.round().max(1.0) as u64),
                gpu: None,
                quads: None,
                ssim: q.clamp(0.0, 1.0),
                psnr: None,
                lpips: None,
                line: 0,
            });
        }
    }
    out
}
