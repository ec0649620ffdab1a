//! The starting point of the fine-tune: lattice features from the
//! training images, and an MLP that decodes them.
//!
//! - Features: each lattice vertex takes the mean colour of the training
//!   pixels whose texels read it (weighted by the trilinear weights: a
//!   projection of the images onto the surface) in feat0.RGB; vertices no
//!   pixel reaches take the field's colour at their point (mean over the
//!   six axis directions). The five spare channels start at the middle of
//!   their range, so the fine-tune can move them either way. (The field's
//!   colour at a surface point is a poor guess of what the pixels show:
//!   20–22 dB on lego's training pixels, `nerflex bake --probe`, while the
//!   field's volume renders reach 30 dB.)
//! - MLP: fitted (Adam) to map (those features, a pixel's direction) to the
//!   pixel's colour on a sample of the training pixels, instead of
//!   starting from noise.

use glam::Vec3;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::featgrid::{FeatureGrid, Taps};
use super::finetune::TrainPixels;
use super::net::{self, Adam, FEATURES};
use crate::train::field::RadianceField;
use nerflex_core::shader::MlpWeights;

/// Initial decoded features of a texel whose colour is `c`.
#[inline]
pub fn features_of(c: Vec3) -> [f32; FEATURES] {
    let mut f = [c.x, c.y, c.z, 0.0, 0.5, 0.5, 0.5, 0.0];
    net::clamp(&mut f);
    f
}

/// Partial sums of [`splat`] (in parallel, then added in order).
const SPLAT_PARTS: usize = 2;

/// Initial lattice values (see the module's notes); returns them and how
/// many vertices the pixels reached.
pub fn splat(
    grid: &FeatureGrid,
    pixels: &TrainPixels,
    taps: &[Taps],
    field: &dyn RadianceField,
) -> (Vec<[f32; FEATURES]>, usize) {
    let n = grid.len();
    // A fixed number of partial sums, whatever the cores: the f32 sums
    // then add in the same order everywhere (one per core made a bake on
    // one core differ from the same bake on two: lego (128, 17) 30.21 dB
    // against 30.15; docs/baking.md, "Session 53"). Two is what two
    // cores did, so their bakes keep their bits.
    let chunk = pixels.len().div_ceil(SPLAT_PARTS).max(1);
    let acc = (0..pixels.len().div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let mut a = vec![[0f32; 4]; n];
            for i in c * chunk..((c + 1) * chunk).min(pixels.len()) {
                let px = pixels.get(i);
                // Edge pixels mix in the background: leave them out.
                if !px.full() {
                    continue;
                }
                let share = 1.0 / px.shown().len() as f32;
                for &slot in px.shown() {
                    let t = &taps[slot as usize];
                    for (&s, &w) in t.slot.iter().zip(&t.w) {
                        let e = &mut a[s as usize];
                        for (acc, &c) in e.iter_mut().zip(&px.target) {
                            *acc += share * w * c;
                        }
                        e[3] += share * w;
                    }
                }
            }
            a
        })
        .reduce_with(|mut a, b| {
            for (x, y) in a.iter_mut().zip(&b) {
                for k in 0..4 {
                    x[k] += y[k];
                }
            }
            a
        })
        .unwrap_or_else(|| vec![[0f32; 4]; n]);
    let reached = acc.iter().filter(|e| e[3] > 0.0).count();
    let axes = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    let values = acc
        .par_iter()
        .enumerate()
        .map(|(s, e)| {
            let c = if e[3] > 1e-6 {
                Vec3::new(e[0], e[1], e[2]) / e[3]
            } else {
                let x = grid.vertex_point(s);
                axes.iter().map(|&d| field.color(x, d)).sum::<Vec3>() / 6.0
            };
            features_of(c.clamp(Vec3::ZERO, Vec3::ONE))
        })
        .collect();
    (values, reached)
}

/// One sample of the MLP's initial fit.
#[derive(Debug, Clone, Copy)]
pub struct FitSample {
    /// Quantised features of the texel.
    pub feat: [f32; FEATURES],
    /// View direction.
    pub dir: [f32; 3],
    /// The colour to decode to.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::trained::analytic::Sphere;
    use crate::bake::trained::finetune::TrainPixel;
    use crate::bake::Aabb;

    /// The splat is the same bits on one core and on three: a bake must
    /// not depend on the machine's core count.
    #[test]
    fn the_splat_does_not_depend_on_the_cores() {
        let cube = Aabb {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        };
        let pts: Vec<Vec3> = (0..300)
            .map(|i| {
                let t = i as f32 * 0.618;
                0.6 * Vec3::new(t.sin(), (1.7 * t).cos(), (2.3 * t).sin())
            })
            .collect();
        let grid = FeatureGrid::new(&cube, 8, &pts);
        let taps: Vec<Taps> = pts.iter().map(|&p| grid.taps(p).unwrap()).collect();
        let pixels = TrainPixels {
            pixels: (0..20_000u32)
                .map(|i| TrainPixel {
                    slot: (i * 7919) % taps.len() as u32,
                    dir: [0.0, 0.0, 1.0],
                    target: [
                        (i as f32 * 0.013).sin().abs(),
                        (i as f32 * 0.029).cos().abs(),
                        0.3 + 0.1 * (i % 5) as f32,
                    ],
                })
                .collect(),
            subsamples: Vec::new(),
        };
        let field = Sphere::new(Vec3::ZERO, 0.6);
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| splat(&grid, &pixels, &taps, &field))
        };
        let (one, reached) = on(1);
        assert!(reached > 0);
        let bits = |v: &[[f32; FEATURES]]| -> Vec<u32> {
            v.iter().flatten().map(|x| x.to_bits()).collect()
        };
        for threads in [2, 3] {
            let (many, r) = on(threads);
            assert_eq!(r, reached);
            assert_eq!(bits(&many), bits(&one), "{threads} threads");
        }
    }
}
