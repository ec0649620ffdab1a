//! The starting point of the fine-tune, from the field: texel features
//! and an MLP that decodes them into the field's view-dependent colour.
//!
//! - Features: feat0.RGB = the field's colour at the texel's point seen
//!   along its quad's mean viewing direction (from the G-buffers); the
//!   five spare channels start at the middle of their range, so the
//!   fine-tune can move them either way.
//! - MLP: fitted (Adam) to map (those features, a pixel's direction) to the
//!   field's colour at the texel's point along that direction, on a random
//!   sample of G-buffer pixels: it starts as "colour out ≈ feat0.RGB" plus
//!   the field's view dependence, instead of from noise.

use glam::Vec3;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::super::quads::Quad;
use super::extract::texel_point;
use super::net::{self, Adam, FEATURES};
use crate::train::field::RadianceField;
use nerflex_core::shader::MlpWeights;

/// Initial decoded features of a texel whose field colour is `c`.
#[inline]
pub fn features_of(c: Vec3) -> [f32; FEATURES] {
    let mut f = [c.x, c.y, c.z, 0.0, 0.5, 0.5, 0.5, 0.0];
    net::clamp(&mut f);
    f
}

/// Atlas bytes (feat0 then feat1) of every texel of every quad: occupied
/// texels where `need` holds from the field's colour along `quad_dirs[q]`,
/// all others 0 (a caller fills the occupied ones it did not need).
pub fn texel_bytes(
    field: &dyn RadianceField,
    quads: &[Quad],
    opacity: &[bool],
    need: &[bool],
    p: u32,
    quad_dirs: &[Vec3],
) -> Vec<[u8; 8]> {
    let p2 = (p * p) as usize;
    let mut out = vec![[0u8; 8]; quads.len() * p2];
    out.par_chunks_mut(p2)
        .zip(opacity.par_chunks(p2).zip(need.par_chunks(p2)))
        .zip(quads.par_iter().zip(quad_dirs))
        .for_each(|((texels, (occ, need)), (q, &d))| {
            for (t, ((b, &o), &n)) in texels.iter_mut().zip(occ).zip(need).enumerate() {
                if !(o && n) {
                    continue;
                }
                let x = texel_point(q, p, t as u32 % p, t as u32 / p);
                let (f0, f1) = net::to_bytes(&features_of(field.color(x, d)), true);
                *b = [f0[0], f0[1], f0[2], f0[3], f1[0], f1[1], f1[2], f1[3]];
            }
        });
    out
}

/// Decoded features of stored bytes.
#[inline]
pub fn decode_bytes(b: &[u8; 8]) -> [f32; FEATURES] {
    std::array::from_fn(|c| net::decode(c, b[c]))
}

/// One sample of the MLP's initial fit.
#[derive(Debug, Clone, Copy)]
pub struct FitSample {
    /// Quantised features of the texel.
    pub feat: [f32; FEATURES],
    /// View direction.
    pub dir: [f32; 3],
    /// The field's colour there along `dir`.
    pub target: [f32; 3],
}

/// Settings of the MLP's initial fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitSettings {
    /// Adam steps.
    pub steps: usize,
    /// Samples per step.
    pub batch: usize,
    /// Learning rate (decays ×0.1 over the steps).
    pub lr: f32,
    /// Seed of the initial weights and the batches.
    pub seed: u64,
}

impl Default for FitSettings {
    fn default() -> Self {
        Self {
            steps: 600,
            batch: 512,
            lr: 1e-2,
            seed: 1,
        }
    }
}

/// Fits the MLP alone to `samples` from random weights; returns it and the
/// final mean squared error per channel.
pub fn fit_mlp(samples: &[FitSample], s: &FitSettings) -> (MlpWeights, f32) {
    let mut w = net::random_weights(s.seed);
    if samples.is_empty() {
        return (w, 0.0);
    }
    let mut params = net::flatten(&w);
    let mut adam = Adam::new(params.len());
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let mut order: Vec<u32> = (0..samples.len() as u32).collect();
    let mut pos = order.len();
    let mut mse = 0.0;
    for step in 0..s.steps {
        let mut g = MlpWeights::ZERO;
        let mut loss = 0.0;
        for _ in 0..s.batch {
            if pos == order.len() {
                order.shuffle(&mut rng);
                pos = 0;
            }
            let smp = &samples[order[pos] as usize];
            pos += 1;
            let a = net::forward(&w, &net::input(&smp.feat, smp.dir));
            let dy: [f32; 3] = std::array::from_fn(|k| 2.0 * (a.y[k] - smp.target[k]));
            loss += (0..3)
                .map(|k| (a.y[k] - smp.target[k]).powi(2))
                .sum::<f32>();
            net::backward(&w, &a, dy, &mut g);
        }
        mse = loss / (3 * s.batch) as f32;
        let lr = s.lr * 0.1f32.powf(step as f32 / s.steps.max(1) as f32);
        adam.step(&mut params, &net::flatten(&g), lr);
        w = net::unflatten(&params);
    }
    (w, mse)
}
