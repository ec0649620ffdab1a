//! Fine-tuning texel features and the MLP against the training images
//! through the renderer's deferred shading, as MobileNeRF's last stage does.
//!
//! Every training pixel the geometry covers shows one texel per covered
//! subsample (the G-buffer, [`super::gbuffer`]; 2 × 2 subsamples under
//! supersampling); a texel's features are the feature lattice read at its
//! point ([`super::featgrid`]), quantised to 8 bits as the atlas stores
//! them; the pixel's colour is the MLP of the subsamples' mean features
//! (rounded to 8 bits as the renderer's resolve does; straight-through:
//! the gradient passes the roundings unchanged) and the pixel's direction,
//! blended over white by coverage. The loss is the mean squared error
//! against the image composited over white. Adam updates the MLP every batch and each
//! lattice vertex whenever the batch reaches it (per-vertex step counts for
//! the bias correction, so rarely reached vertices are not
//! under-corrected). Batches are split over the cores with rayon.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::time::Instant;

use super::featgrid::Taps;
use super::gbuffer::{covered, Subsamples};
use super::net::{self, Adam, FEATURES};
use nerflex_core::shader::MlpWeights;

/// A training pixel: the texel it shows (its first subsample's under
/// supersampling), its direction and its target colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainPixel {
    /// Index into the shown texels' [`Taps`].
    pub slot: u32,
    /// View direction the renderer feeds the MLP here.
    pub dir: [f32; 3],
    /// Target colour in [0, 1].
    pub target: [f32; 3],
}

/// The training pixels, and under supersampling each one's covered
/// subsamples' slots (`gbuffer::NO_TEXEL` where uncovered; empty with one
/// sample per pixel, which so pays nothing for them).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrainPixels {
    /// The pixels.
    pub pixels: Vec<TrainPixel>,
    /// Parallel to `pixels` when supersampled, else empty.
    pub subsamples: Vec<Subsamples>,
}

impl TrainPixels {
    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.pixels.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    /// Pixel `i` (`i < len()`).
    #[inline]
    pub fn get(&self, i: usize) -> PixelRef<'_> {
        PixelRef {
            px: &self.pixels[i],
            subs: self.subsamples.get(i),
        }
    }
}

/// One training pixel with its subsamples, if supersampled.
#[derive(Debug, Clone, Copy)]
pub struct PixelRef<'a> {
    px: &'a TrainPixel,
    subs: Option<&'a Subsamples>,
}

impl std::ops::Deref for PixelRef<'_> {
    type Target = TrainPixel;
    fn deref(&self) -> &TrainPixel {
        self.px
    }
}

impl PixelRef<'_> {
    /// The slots of its covered subsamples (its one slot unsupersampled).
    #[inline]
    pub fn shown(&self) -> &[u32] {
        match self.subs {
            Some(s) => covered(s),
            None => std::slice::from_ref(&self.px.slot),
        }
    }

    /// The fraction of the pixel its subsamples cover.
    #[inline]
    pub fn coverage(&self) -> f32 {
        match self.subs {
            Some(s) => covered(s).len() as f32 / s.len() as f32,
            None => 1.0,
        }
    }

    /// Whether every subsample is covered.
    #[inline]
    pub fn full(&self) -> bool {
        self.subs.is_none_or(|s| covered(s).len() == s.len())
    }

    /// The quantised features the renderer's MLP reads here: the mean of
    /// the covered subsamples' 8-bit texels, itself rounded to 8 bits
    /// (`nerflex_core::raster::mean_texel`).
    #[inline]
    pub fn features(&self, taps: &[Taps], values: &[[f32; FEATURES]]) -> [f32; FEATURES] {
        let shown = self.shown();
        if let [one] = shown {
            return net::quantise(&taps[*one as usize].gather(values));
        }
        let mut f = [0f32; FEATURES];
        for &s in shown {
            let q = net::quantise(&taps[s as usize].gather(values));
            for (a, b) in f.iter_mut().zip(q) {
                *a += b;
            }
        }
        let inv = 1.0 / shown.len().max(1) as f32;
        net::quantise(&f.map(|v| v * inv))
    }

    /// The pixel's colour for MLP output `y` (blended over white by
    /// coverage).
    #[inline]
    pub fn blend(&self, y: [f32; 3]) -> [f32; 3] {
        let c = self.coverage();
        y.map(|v| v * c + (1.0 - c))
    }
}

/// Settings of the fine-tune.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinetuneSettings {
    /// Passes over the training pixels (fractions allowed).
    pub epochs: f32,
    /// Pixels per Adam step.
    pub batch: usize,
    /// Learning rate of the lattice's features (decays ×0.1 over the run).
    pub lr_features: f32,
    /// Learning rate of the MLP (decays ×0.1 over the run).
    pub lr_mlp: f32,
    /// Seed of the pixel order.
    pub seed: u64,
}

impl Default for FinetuneSettings {
    fn default() -> Self {
        Self {
            epochs: 3.0,
            batch: 8192,
            lr_features: 0.03,
            lr_mlp: 3e-3,
            seed: 7,
        }
    }
}

/// What the fine-tune did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FinetuneReport {
    /// Adam steps taken.
    pub steps: usize,
    /// Pixel evaluations (forward + backward).
    pub pixel_steps: u64,
    /// PSNR (dB) of the quantised model on the training pixels before.
    pub psnr_before: f64,
    /// … and after.
    pub psnr_after: f64,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// PSNR (dB) of the 8-bit output of the `f32` shader over the training
/// pixels (every `stride`-th), as the renderer would show them.
pub fn train_psnr(
    pixels: &TrainPixels,
    taps: &[Taps],
    values: &[[f32; FEATURES]],
    mlp: &MlpWeights,
    stride: usize,
) -> f64 {
    let (se, n) = (0..pixels.len())
        .into_par_iter()
        .step_by(stride.max(1))
        .map(|i| {
            let px = pixels.get(i);
            let x = net::input(&px.features(taps, values), px.dir);
            let y = net::to_u8(net::forward(mlp, &x).y).map(|v| f32::from(v) / 255.0);
            let c = px.blend(y);
            let se: f64 = (0..3)
                .map(|k| (f64::from(c[k] - px.target[k]) * 255.0).powi(2))
                .sum();
            (se, 3u64)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if n == 0 {
        return f64::INFINITY;
    }
    let mse = se / n as f64;
    10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
}

/// One vertex's Adam state: moments and β₁ᵗ, β₂ᵗ of its own step count
/// (rarely reached vertices are not under-corrected).
#[derive(Clone, Copy)]
struct VertexAdam {
    m: [f32; FEATURES],
    v: [f32; FEATURES],
    b1t: f32,
    b2t: f32,
}

/// Vertices per block of the parallel optimiser step.
const BLOCK: usize = 4096;

/// Gradient of a batch: MLP and (slot, feature gradient) pairs.
struct BatchGrad {
    mlp: MlpWeights,
    feats: Vec<(u32, [f32; FEATURES])>,
}

fn batch_grad(
    batch: &[u32],
    pixels: &TrainPixels,
    taps: &[Taps],
    values: &[[f32; FEATURES]],
    mlp: &MlpWeights,
) -> BatchGrad {
    let scale = 2.0 / (3 * batch.len()) as f32;
    batch
        .par_chunks(512)
        .map(|chunk| {
            let mut g = BatchGrad {
                mlp: MlpWeights::ZERO,
                feats: Vec::with_capacity(chunk.len()),
            };
            // Gather first: the lattice reads are cache misses, independent
            // across pixels, and overlap in a loop of their own instead of
            // waiting behind each pixel's MLP.
            let features: Vec<[f32; FEATURES]> = chunk
                .iter()
                .map(|&i| pixels.get(i as usize).features(taps, values))
                .collect();
            for (&i, f) in chunk.iter().zip(&features) {
                let px = pixels.get(i as usize);
                let x = net::input(f, px.dir);
                let a = net::forward(mlp, &x);
                let c = px.blend(a.y);
                let cov = px.coverage();
                let dy = std::array::from_fn(|k| scale * cov * (c[k] - px.target[k]));
                let df = net::backward(mlp, &a, dy, &mut g.mlp);
                // The mean's gradient, shared by its subsamples
                // (straight-through both roundings).
                let shown = px.shown();
                let inv = 1.0 / shown.len() as f32;
                for &s in shown {
                    g.feats.push((s, df.map(|v| v * inv)));
                }
            }
            g
        })
        .reduce(
            || BatchGrad {
                mlp: MlpWeights::ZERO,
                feats: Vec::new(),
            },
            |mut a, b| {
                net::add_into(&mut a.mlp, &b.mlp);
                a.feats.extend(b.feats);
                a
            },
        )
}

/// Fine-tunes the lattice's `values` (which the shown texels read through
/// `taps`) and `mlp` on `pixels`.
pub fn finetune(
    pixels: &TrainPixels,
    taps: &[Taps],
    values: &mut [[f32; FEATURES]],
    mlp: &mut MlpWeights,
    s: &FinetuneSettings,
) -> FinetuneReport {
    let t0 = Instant::now();
    let stride = (pixels.len() / 1_000_000).max(1);
    let psnr_before = train_psnr(pixels, taps, values, mlp, stride);
    let n = pixels.len();
    let batch = s.batch.max(1);
    let total = (s.epochs.max(0.0) as f64 * n as f64).round() as u64;
    let steps = total.div_ceil(batch as u64) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut pos = n;
    let mut params = net::flatten(mlp);
    let mut adam = Adam::new(params.len());
    let slots = values.len();
    let mut st = vec![
        VertexAdam {
            m: [0.0; FEATURES],
            v: [0.0; FEATURES],
            b1t: 1.0,
            b2t: 1.0,
        };
        slots
    ];
    let mut grad = vec![[0f32; FEATURES]; slots];
    // The step (+1) in which each vertex was last touched.
    let mut stamp = vec![0u32; slots];
    // Touched vertices, by block: each block's Adam steps run on one core.
    let mut touched: Vec<Vec<u32>> = vec![Vec::new(); slots.div_ceil(BLOCK)];
    let mut idx: Vec<u32> = Vec::with_capacity(batch);
    let mut pixel_steps = 0u64;
    for step in 0..steps {
        idx.clear();
        while idx.len() < batch && n > 0 {
            if pos == n {
                order.shuffle(&mut rng);
                pos = 0;
            }
            let take = (batch - idx.len()).min(n - pos);
            idx.extend_from_slice(&order[pos..pos + take]);
            pos += take;
        }
        pixel_steps += idx.len() as u64;
        let g = batch_grad(&idx, pixels, taps, values, mlp);
        let decay = 0.1f32.powf(step as f32 / steps.max(1) as f32);
        // MLP.
        adam.step(&mut params, &net::flatten(&g.mlp), s.lr_mlp * decay);
        *mlp = net::unflatten(&params);
        // Features: sum per vertex, then one Adam step per touched vertex.
        for (slot, df) in &g.feats {
            let t = &taps[*slot as usize];
            for &v in &t.slot {
                if stamp[v as usize] != step as u32 + 1 {
                    stamp[v as usize] = step as u32 + 1;
                    touched[v as usize / BLOCK].push(v);
                }
            }
            t.scatter(df, &mut grad);
        }
        let lr = s.lr_features * decay;
        values
            .par_chunks_mut(BLOCK)
            .zip(st.par_chunks_mut(BLOCK))
            .zip(grad.par_chunks_mut(BLOCK))
            .zip(touched.par_iter_mut())
            .enumerate()
            .for_each(|(b, (((vals, sts), grads), list))| {
                for &slot in list.iter() {
                    let k = slot as usize - b * BLOCK;
                    let gk = std::mem::replace(&mut grads[k], [0.0; FEATURES]);
                    let a = &mut sts[k];
                    a.b1t *= net::BETA1;
                    a.b2t *= net::BETA2;
                    let (c1, c2) = (1.0 - a.b1t, 1.0 - a.b2t);
                    let f = &mut vals[k];
                    for c in 0..FEATURES {
                        a.m[c] = net::BETA1 * a.m[c] + (1.0 - net::BETA1) * gk[c];
                        a.v[c] = net::BETA2 * a.v[c] + (1.0 - net::BETA2) * gk[c] * gk[c];
                        f[c] -= lr * (a.m[c] / c1) / ((a.v[c] / c2).sqrt() + net::EPS);
                    }
                    net::clamp(f);
                }
                list.clear();
            });
    }
    let psnr_after = train_psnr(pixels, taps, values, mlp, stride);
    FinetuneReport {
        steps,
        pixel_steps,
        psnr_before,
        psnr_after,
        seconds: t0.elapsed().as_secs_f64(),
    }
}
