//! The phone's deferred shading in `f32`, differentiable: 8-bit feature
//! quantisation (straight-through) and the 11→16→16→3 MLP with a
//! hand-written backward pass.
//!
//! The forward pass repeats `nerflex_core::shader::shade_f32` operation for
//! operation (same decoding, same accumulation order), so what the
//! fine-tune optimises is what `nerflex render --float` shows, and the
//! fixed-point renderer is within a level of it.

use nerflex_core::shader::{MlpWeights, HIDDEN, INPUTS, OUTPUTS};

/// Feature channels per texel (feat0 RGBA, feat1 RGBA).
pub const FEATURES: usize = 8;

/// Whether feature channel `c` is an alpha channel (decoded `2·t/255 − 1`,
/// range [−1, 1]); the others decode `t/255`, range [0, 1].
#[inline(always)]
pub fn is_alpha(c: usize) -> bool {
    c == 3 || c == 7
}

/// The byte the atlas stores for decoded feature value `v` of channel `c`
/// (nearest; clamped to the channel's range). Channel 0 of an occupied
/// texel must be ≥ 1 (0 means "empty"): pass `occupied`.
#[inline(always)]
pub fn encode(c: usize, v: f32, occupied: bool) -> u8 {
    let t = if is_alpha(c) {
        ((v + 1.0) * 0.5 * 255.0).round()
    } else {
        (v * 255.0).round()
    };
    let lo = if c == 0 && occupied { 1.0 } else { 0.0 };
    t.clamp(lo, 255.0) as u8
}

/// The decoded value of byte `t` in channel `c`, exactly as the shader
/// decodes it.
#[inline(always)]
pub fn decode(c: usize, t: u8) -> f32 {
    if is_alpha(c) {
        t as f32 * (2.0 / 255.0) - 1.0
    } else {
        t as f32 * (1.0 / 255.0)
    }
}

/// A texel's features as the atlas stores them (feat0, feat1).
#[inline]
pub fn to_bytes(f: &[f32; FEATURES], occupied: bool) -> ([u8; 4], [u8; 4]) {
    let b = |c: usize| encode(c, f[c], occupied);
    ([b(0), b(1), b(2), b(3)], [b(4), b(5), b(6), b(7)])
}

/// Forward quantisation (what the atlas stores, decoded back); the
/// backward pass treats it as the identity (straight-through).
#[inline(always)]
pub fn quantise(f: &[f32; FEATURES]) -> [f32; FEATURES] {
    std::array::from_fn(|c| decode(c, encode(c, f[c], true)))
}

/// Clamps a feature vector to the range its bytes can represent (after an
/// optimiser step), keeping channel 0 of an occupied texel above "empty".
#[inline]
pub fn clamp(f: &mut [f32; FEATURES]) {
    for (c, v) in f.iter_mut().enumerate() {
        let (lo, hi) = if is_alpha(c) {
            (-1.0, 1.0)
        } else if c == 0 {
            (0.5 / 255.0, 1.0)
        } else {
            (0.0, 1.0)
        };
        *v = v.clamp(lo, hi);
    }
}

/// The MLP's input: quantised features and the unit view direction.
#[inline]
pub fn input(feat_q: &[f32; FEATURES], dir: [f32; 3]) -> [f32; INPUTS] {
    let mut x = [0f32; INPUTS];
    x[..FEATURES].copy_from_slice(feat_q);
    x[FEATURES..].copy_from_slice(&dir);
    x
}

/// Activations of one forward pass, kept for the backward pass.
#[derive(Debug, Clone, Copy)]
pub struct Activations {
    /// Input.
    pub x: [f32; INPUTS],
    /// First hidden layer after ReLU.
    pub h1: [f32; HIDDEN],
    /// Second hidden layer after ReLU.
    pub h2: [f32; HIDDEN],
    /// Output in [0, 1] (sigmoid), before 8-bit rounding.
    pub y: [f32; OUTPUTS],
}

#[inline]
fn dense<const I: usize, const O: usize>(
    x: &[f32; I],
    w: &[[f32; O]; I],
    b: &[f32; O],
) -> [f32; O] {
    // Same order as the core's `dense_f32`.
    let mut acc = *b;
    for (&xi, row) in x.iter().zip(w.iter()) {
        for (a, &wv) in acc.iter_mut().zip(row.iter()) {
            *a += xi * wv;
        }
    }
    acc
}

/// The forward pass.
#[inline]
pub fn forward(w: &MlpWeights, x: &[f32; INPUTS]) -> Activations {
    let h1 = dense(x, &w.w0, &w.b0).map(|v| v.max(0.0));
    let h2 = dense(&h1, &w.w1, &w.b1).map(|v| v.max(0.0));
    let y = dense(&h2, &w.w2, &w.b2).map(|z| 1.0 / (1.0 + (-z).exp()));
    Activations { x: *x, h1, h2, y }
}

/// The 8-bit colour the `f32` shader shows for output `y`.
#[inline]
pub fn to_u8(y: [f32; OUTPUTS]) -> [u8; 3] {
    y.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// Backward pass for output gradient `dy` (∂loss/∂y): adds the weight
/// gradients into `g` and returns ∂loss/∂(the 8 features).
#[inline]
// Index loops: each index runs over several arrays at once, as the math reads.
#[allow(clippy::needless_range_loop)]
pub fn backward(
    w: &MlpWeights,
    a: &Activations,
    dy: [f32; OUTPUTS],
    g: &mut MlpWeights,
) -> [f32; FEATURES] {
    let dz: [f32; OUTPUTS] = std::array::from_fn(|k| dy[k] * a.y[k] * (1.0 - a.y[k]));
    for (k, d) in dz.iter().enumerate() {
        g.b2[k] += d;
    }
    let mut dh2 = [0f32; HIDDEN];
    for j in 0..HIDDEN {
        let mut s = 0.0;
        for k in 0..OUTPUTS {
            g.w2[j][k] += a.h2[j] * dz[k];
            s += w.w2[j][k] * dz[k];
        }
        dh2[j] = if a.h2[j] > 0.0 { s } else { 0.0 };
    }
    let mut dh1 = [0f32; HIDDEN];
    for i in 0..HIDDEN {
        let hi = a.h1[i];
        let row = &w.w1[i];
        let grow = &mut g.w1[i];
        let mut s = 0.0;
        for j in 0..HIDDEN {
            grow[j] += hi * dh2[j];
            s += row[j] * dh2[j];
        }
        dh1[i] = if hi > 0.0 { s } else { 0.0 };
    }
    for (b, d) in g.b1.iter_mut().zip(&dh2) {
        *b += d;
    }
    for (b, d) in g.b0.iter_mut().zip(&dh1) {
        *b += d;
    }
    let mut dx = [0f32; FEATURES];
    for i in 0..INPUTS {
        let xi = a.x[i];
        let row = &w.w0[i];
        let grow = &mut g.w0[i];
        let mut s = 0.0;
        for j in 0..HIDDEN {
            grow[j] += xi * dh1[j];
            s += row[j] * dh1[j];
        }
        if i < FEATURES {
            dx[i] = s;
        }
    }
    dx
}

/// Pixels the batched passes ([`forward8`], [`backward8`]) run side by
/// side: one value per lane, so each weight is one broadcast and every
/// layer is a loop over lanes the compiler vectorises (one AVX register).
pub const LANES: usize = 8;

/// One value per lane.
pub type Lanes = [f32; LANES];

/// [`Activations`] of [`LANES`] pixels, structure of arrays.
#[derive(Debug, Clone, Copy)]
pub struct Activations8 {
    /// Input.
    pub x: [Lanes; INPUTS],
    /// First hidden layer after ReLU.
    pub h1: [Lanes; HIDDEN],
    /// Second hidden layer after ReLU.
    pub h2: [Lanes; HIDDEN],
    /// Output (sigmoid).
    pub y: [Lanes; OUTPUTS],
}

/// Weight gradients summed per lane ([`backward8`] adds into them); the
/// lanes are added up by [`LaneGrads::reduce_into`].
#[derive(Debug, Clone)]
pub struct LaneGrads {
    w0: [[Lanes; HIDDEN]; INPUTS],
    b0: [Lanes; HIDDEN],
    w1: [[Lanes; HIDDEN]; HIDDEN],
    b1: [Lanes; HIDDEN],
    w2: [[Lanes; OUTPUTS]; HIDDEN],
    b2: [Lanes; OUTPUTS],
}

impl Default for LaneGrads {
    fn default() -> Self {
        Self {
            w0: [[[0.0; LANES]; HIDDEN]; INPUTS],
            b0: [[0.0; LANES]; HIDDEN],
            w1: [[[0.0; LANES]; HIDDEN]; HIDDEN],
            b1: [[0.0; LANES]; HIDDEN],
            w2: [[[0.0; LANES]; OUTPUTS]; HIDDEN],
            b2: [[0.0; LANES]; OUTPUTS],
        }
    }
}

impl LaneGrads {
    /// Adds the lanes' sums into `g` and zeroes them.
    pub fn reduce_into(&mut self, g: &mut MlpWeights) {
        fn sum(l: &mut Lanes) -> f32 {
            let s = l.iter().sum();
            *l = [0.0; LANES];
            s
        }
        let pairs =
            g.w0.iter_mut()
                .flatten()
                .zip(self.w0.iter_mut().flatten())
                .chain(g.b0.iter_mut().zip(&mut self.b0))
                .chain(g.w1.iter_mut().flatten().zip(self.w1.iter_mut().flatten()))
                .chain(g.b1.iter_mut().zip(&mut self.b1))
                .chain(g.w2.iter_mut().flatten().zip(self.w2.iter_mut().flatten()))
                .chain(g.b2.iter_mut().zip(&mut self.b2));
        for (a, l) in pairs {
            *a += sum(l);
        }
    }
}

/// `acc[l] += x[l] · w` over the lanes.
#[inline(always)]
fn axpy(acc: &mut Lanes, x: &Lanes, w: f32) {
    for (a, &v) in acc.iter_mut().zip(x) {
        *a += v * w;
    }
}

/// `acc[l] += x[l] · y[l]` over the lanes.
#[inline(always)]
fn fma_lanes(acc: &mut Lanes, x: &Lanes, y: &Lanes) {
    // Through a local copy: summed in place, the lanes stayed scalar once
    // inlined into the fine-tune (eight loads, multiplies, adds and stores
    // per weight, 6 % of a lego bake's CPU); the same operations per lane.
    let mut s = *acc;
    for ((a, &u), &v) in s.iter_mut().zip(x).zip(y) {
        *a += u * v;
    }
    *acc = s;
}

/// [`dense`] of each lane, in its order of operations.
#[inline(always)]
fn dense8<const I: usize, const O: usize>(
    x: &[Lanes; I],
    w: &[[f32; O]; I],
    b: &[f32; O],
) -> [Lanes; O] {
    // Plain loops (no array `map`/`from_fn`, which may stay calls outside
    // the caller's vector features).
    let mut out = [[0f32; LANES]; O];
    for (o, acc) in out.iter_mut().enumerate() {
        *acc = [b[o]; LANES];
        for (xi, row) in x.iter().zip(w.iter()) {
            axpy(acc, xi, row[o]);
        }
    }
    out
}

/// `max(v, 0)` of every value.
#[inline(always)]
fn relu8<const O: usize>(h: &mut [Lanes; O]) {
    for v in h.iter_mut().flatten() {
        *v = v.max(0.0);
    }
}

/// [`forward`] of [`LANES`] pixels at once, lane for lane the same
/// operations (so bit for bit the same results).
#[inline(always)]
pub fn forward8(w: &MlpWeights, x: &[Lanes; INPUTS]) -> Activations8 {
    let mut h1 = dense8(x, &w.w0, &w.b0);
    relu8(&mut h1);
    let mut h2 = dense8(&h1, &w.w1, &w.b1);
    relu8(&mut h2);
    let mut y = dense8(&h2, &w.w2, &w.b2);
    for v in y.iter_mut().flatten() {
        *v = 1.0 / (1.0 + (-*v).exp());
    }
    Activations8 { x: *x, h1, h2, y }
}

/// [`backward`] of [`LANES`] pixels at once: the same operations per lane
/// for ∂loss/∂(features), returned per lane; the weight gradients are
/// summed per lane into `g` (so their sums differ from [`backward`]'s only
/// by the order of additions).
#[inline(always)]
// Index loops: each index runs over several arrays at once, as the math reads.
#[allow(clippy::needless_range_loop)]
pub fn backward8(
    w: &MlpWeights,
    a: &Activations8,
    dy: &[Lanes; OUTPUTS],
    g: &mut LaneGrads,
) -> [Lanes; FEATURES] {
    let mut dz = [[0f32; LANES]; OUTPUTS];
    for k in 0..OUTPUTS {
        for l in 0..LANES {
            dz[k][l] = dy[k][l] * a.y[k][l] * (1.0 - a.y[k][l]);
            g.b2[k][l] += dz[k][l];
        }
    }
    let mut dh2 = [[0f32; LANES]; HIDDEN];
    for j in 0..HIDDEN {
        let mut s = [0f32; LANES];
        for k in 0..OUTPUTS {
            fma_lanes(&mut g.w2[j][k], &a.h2[j], &dz[k]);
            axpy(&mut s, &dz[k], w.w2[j][k]);
        }
        for l in 0..LANES {
            dh2[j][l] = if a.h2[j][l] > 0.0 { s[l] } else { 0.0 };
        }
    }
    let mut dh1 = [[0f32; LANES]; HIDDEN];
    for i in 0..HIDDEN {
        let hi = &a.h1[i];
        let mut s = [0f32; LANES];
        for j in 0..HIDDEN {
            fma_lanes(&mut g.w1[i][j], hi, &dh2[j]);
            axpy(&mut s, &dh2[j], w.w1[i][j]);
        }
        for l in 0..LANES {
            dh1[i][l] = if hi[l] > 0.0 { s[l] } else { 0.0 };
        }
    }
    for j in 0..HIDDEN {
        for l in 0..LANES {
            g.b1[j][l] += dh2[j][l];
            g.b0[j][l] += dh1[j][l];
        }
    }
    let mut dx = [[0f32; LANES]; FEATURES];
    for i in 0..INPUTS {
        let xi = &a.x[i];
        for j in 0..HIDDEN {
            fma_lanes(&mut g.w0[i][j], xi, &dh1[j]);
        }
        if i < FEATURES {
            let mut s = [0f32; LANES];
            for j in 0..HIDDEN {
                axpy(&mut s, &dh1[j], w.w0[i][j]);
            }
            dx[i] = s;
        }
    }
    dx
}

/// Number of MLP parameters (11·16 + 16 + 16·16 + 16 + 16·3 + 3 = 515).
pub const PARAMS: usize =
    INPUTS * HIDDEN + HIDDEN + HIDDEN * HIDDEN + HIDDEN + HIDDEN * OUTPUTS + OUTPUTS;

/// The parameters as one flat vector (for the optimiser), in a fixed order.
pub fn flatten(w: &MlpWeights) -> Vec<f32> {
    let mut v = Vec::with_capacity(PARAMS);
    flatten_into(w, &mut v);
    v
}

/// [`flatten`] into `v` (cleared first), reusing its allocation.
pub fn flatten_into(w: &MlpWeights, v: &mut Vec<f32>) {
    v.clear();
    w.w0.iter().for_each(|r| v.extend_from_slice(r));
    v.extend_from_slice(&w.b0);
    w.w1.iter().for_each(|r| v.extend_from_slice(r));
    v.extend_from_slice(&w.b1);
    w.w2.iter().for_each(|r| v.extend_from_slice(r));
    v.extend_from_slice(&w.b2);
}

/// The inverse of [`flatten`]; `v` must hold [`PARAMS`] values.
pub fn unflatten(v: &[f32]) -> MlpWeights {
    let mut w = MlpWeights::ZERO;
    let mut it = v.iter().copied();
    let mut next = || it.next().unwrap_or(0.0);
    w.w0.iter_mut().flatten().for_each(|x| *x = next());
    w.b0.iter_mut().for_each(|x| *x = next());
    w.w1.iter_mut().flatten().for_each(|x| *x = next());
    w.b1.iter_mut().for_each(|x| *x = next());
    w.w2.iter_mut().flatten().for_each(|x| *x = next());
    w.b2.iter_mut().for_each(|x| *x = next());
    w
}

/// Element-wise `a += b` of two weight sets (gradient reduction).
pub fn add_into(a: &mut MlpWeights, b: &MlpWeights) {
    let pairs =
        a.w0.iter_mut()
            .flatten()
            .zip(b.w0.iter().flatten())
            .chain(a.b0.iter_mut().zip(&b.b0))
            .chain(a.w1.iter_mut().flatten().zip(b.w1.iter().flatten()))
            .chain(a.b1.iter_mut().zip(&b.b1))
            .chain(a.w2.iter_mut().flatten().zip(b.w2.iter().flatten()))
            .chain(a.b2.iter_mut().zip(&b.b2));
    for (x, y) in pairs {
        *x += y;
    }
}

/// Deterministic small random weights (He-style scale per layer), biases
/// zero: the starting point before [`super::init`] fits the network.
pub fn random_weights(seed: u64) -> MlpWeights {
    let mut s = seed ^ 0x9e37_79b9_7f4a_7c15;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    let mut w = MlpWeights::ZERO;
    let s0 = (6.0 / INPUTS as f32).sqrt();
    let s1 = (6.0 / HIDDEN as f32).sqrt();
    w.w0.iter_mut().flatten().for_each(|v| *v = next() * s0);
    w.w1.iter_mut().flatten().for_each(|v| *v = next() * s1);
    w.w2.iter_mut().flatten().for_each(|v| *v = next() * s1);
    w
}

/// Adam over a flat parameter vector.
#[derive(Debug, Clone)]
pub struct Adam {
    m: Vec<f32>,
    v: Vec<f32>,
    t: i32,
}

/// Adam's moment decay rates.
pub const BETA1: f32 = 0.9;
/// Second-moment decay.
pub const BETA2: f32 = 0.999;
/// Adam's ε.
pub const EPS: f32 = 1e-8;

impl Adam {
    /// State for `n` parameters.
    pub fn new(n: usize) -> Self {
        Self {
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// One step of size `lr` along gradient `g`.
    pub fn step(&mut self, p: &mut [f32], g: &[f32], lr: f32) {
        self.t += 1;
        let c1 = 1.0 - BETA1.powi(self.t);
        let c2 = 1.0 - BETA2.powi(self.t);
        for (((p, g), m), v) in p.iter_mut().zip(g).zip(&mut self.m).zip(&mut self.v) {
            *m = BETA1 * *m + (1.0 - BETA1) * g;
            *v = BETA2 * *v + (1.0 - BETA2) * g * g;
            *p -= lr * (*m / c1) / ((*v / c2).sqrt() + EPS);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nerflex_core::shader::shade_f32;

    fn sample_input(k: u32) -> ([f32; FEATURES], [f32; 3]) {
        let f = std::array::from_fn(|c| {
            let v = ((k * 37 + c as u32 * 101) % 255) as f32 / 255.0;
            if is_alpha(c) {
                2.0 * v - 1.0
            } else {
                v
            }
        });
        let d = glam::Vec3::new(0.3 + k as f32 * 0.1, -0.5, 0.8).normalize();
        (f, d.to_array())
    }

    #[test]
    fn encode_decode_round_trips_every_byte() {
        for c in 0..FEATURES {
            for t in 0..=255u8 {
                let occupied = !(c == 0 && t == 0);
                assert_eq!(encode(c, decode(c, t), occupied), t, "channel {c} byte {t}");
            }
        }
        assert_eq!(
            encode(0, 0.0, true),
            1,
            "an occupied texel never encodes as empty"
        );
    }

    #[test]
    fn forward_matches_the_core_f32_shader() {
        let w = random_weights(3);
        for k in 0..200 {
            let (f, d) = sample_input(k);
            let (f0, f1) = to_bytes(&f, true);
            let x = input(&quantise(&f), d);
            assert_eq!(
                to_u8(forward(&w, &x).y),
                shade_f32(&w, f0, f1, d),
                "sample {k}"
            );
        }
    }

    /// Loss = Σ_k (y_k − t_k)², checked against central differences in f64
    /// terms of the f32 network (step large enough for f32).
    #[test]
    fn backward_matches_finite_differences() {
        let mut w = random_weights(11);
        // Non-zero biases so every unit's gradient path is exercised.
        w.b0.iter_mut()
            .enumerate()
            .for_each(|(i, b)| *b = 0.05 * (i as f32 - 7.0));
        w.b1.iter_mut()
            .enumerate()
            .for_each(|(i, b)| *b = 0.03 * (i as f32 - 5.0));
        let target = [0.2f32, 0.7, 0.4];
        // The same network in f64 over the flat parameters (the order of
        // `flatten`), so central differences with a step small enough never
        // to cross a ReLU kink are free of f32 noise.
        let loss = |p: &[f64], x: &[f64; INPUTS]| -> f64 {
            let mut at = 0;
            let mut dense = |x: &[f64], o: usize, relu: bool| -> Vec<f64> {
                let w = &p[at..at + x.len() * o];
                let b = &p[at + x.len() * o..at + x.len() * o + o];
                at += x.len() * o + o;
                (0..o)
                    .map(|j| {
                        let v = b[j] + (0..x.len()).map(|i| x[i] * w[i * o + j]).sum::<f64>();
                        if relu {
                            v.max(0.0)
                        } else {
                            v
                        }
                    })
                    .collect()
            };
            let h1 = dense(x, HIDDEN, true);
            let h2 = dense(&h1, HIDDEN, true);
            let z = dense(&h2, OUTPUTS, false);
            (0..3)
                .map(|k| (1.0 / (1.0 + (-z[k]).exp()) - f64::from(target[k])).powi(2))
                .sum()
        };
        for k in 0..6 {
            let (f, d) = sample_input(k);
            let x = input(&f, d);
            let a = forward(&w, &x);
            let dy = std::array::from_fn(|c| 2.0 * (a.y[c] - target[c]));
            let mut g = MlpWeights::ZERO;
            let dx = backward(&w, &a, dy, &mut g);
            // Inputs.
            let x64 = x.map(f64::from);
            let p64: Vec<f64> = flatten(&w).iter().map(|&v| f64::from(v)).collect();
            let h = 1e-6f64;
            for i in 0..FEATURES {
                let (mut xp, mut xm) = (x64, x64);
                xp[i] += h;
                xm[i] -= h;
                let num = (loss(&p64, &xp) - loss(&p64, &xm)) / (2.0 * h);
                let err = (num - f64::from(dx[i])).abs();
                assert!(err < 1e-5 + 1e-3 * num.abs(), "dx[{i}]: {} vs {num}", dx[i]);
            }
            // Every weight and bias.
            let gp = flatten(&g);
            for j in 0..PARAMS {
                let (mut pp, mut pm) = (p64.clone(), p64.clone());
                pp[j] += h;
                pm[j] -= h;
                let num = (loss(&pp, &x64) - loss(&pm, &x64)) / (2.0 * h);
                let err = (num - f64::from(gp[j])).abs();
                assert!(
                    err < 1e-5 + 1e-3 * num.abs(),
                    "param {j}: {} vs {num}",
                    gp[j]
                );
            }
        }
    }

    /// The batched passes against the scalar ones on random inputs: the
    /// activations and feature gradients bit for bit, the weight gradients
    /// (summed in another order) to rounding.
    #[test]
    fn batched_passes_match_the_scalar_ones() {
        let mut w = random_weights(17);
        w.b0.iter_mut()
            .enumerate()
            .for_each(|(i, b)| *b = 0.07 * (i as f32 - 8.0));
        w.b1.iter_mut()
            .enumerate()
            .for_each(|(i, b)| *b = 0.04 * (i as f32 - 6.0));
        w.b2 = [0.1, -0.2, 0.3];
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut lane_g = LaneGrads::default();
        let mut g_scalar = MlpWeights::ZERO;
        for _ in 0..40 {
            let xs: [[f32; INPUTS]; LANES] = std::array::from_fn(|_| {
                let f: [f32; FEATURES] = std::array::from_fn(|c| {
                    if is_alpha(c) {
                        2.0 * rnd() - 1.0
                    } else {
                        rnd()
                    }
                });
                let d = glam::Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
                input(&quantise(&f), d.to_array())
            });
            let dys: [[f32; OUTPUTS]; LANES] =
                std::array::from_fn(|_| std::array::from_fn(|_| rnd() - 0.5));
            let x8: [Lanes; INPUTS] = std::array::from_fn(|i| std::array::from_fn(|l| xs[l][i]));
            let dy8: [Lanes; OUTPUTS] = std::array::from_fn(|k| std::array::from_fn(|l| dys[l][k]));
            let a8 = forward8(&w, &x8);
            let dx8 = backward8(&w, &a8, &dy8, &mut lane_g);
            for l in 0..LANES {
                let a = forward(&w, &xs[l]);
                assert!((0..HIDDEN).all(|j| a.h1[j].to_bits() == a8.h1[j][l].to_bits()));
                assert!((0..HIDDEN).all(|j| a.h2[j].to_bits() == a8.h2[j][l].to_bits()));
                assert!((0..OUTPUTS).all(|k| a.y[k].to_bits() == a8.y[k][l].to_bits()));
                let dx = backward(&w, &a, dys[l], &mut g_scalar);
                assert!((0..FEATURES).all(|i| dx[i].to_bits() == dx8[i][l].to_bits()));
            }
        }
        let mut g_batched = MlpWeights::ZERO;
        lane_g.reduce_into(&mut g_batched);
        let (gs, gb) = (flatten(&g_scalar), flatten(&g_batched));
        assert!(gs.iter().any(|&v| v != 0.0));
        for (j, (a, b)) in gs.iter().zip(&gb).enumerate() {
            assert!(
                (a - b).abs() <= 1e-5 * (1.0 + a.abs()),
                "param {j}: {a} vs {b}"
            );
        }
        // Reducing zeroes the lanes.
        let mut again = MlpWeights::ZERO;
        lane_g.reduce_into(&mut again);
        assert_eq!(again, MlpWeights::ZERO);
    }

    #[test]
    fn flatten_round_trips() {
        let w = random_weights(5);
        assert_eq!(unflatten(&flatten(&w)), w);
        assert_eq!(flatten(&w).len(), PARAMS);
    }
}
