//! The MobileNeRF view-dependent MLP (11 → 16 → 16 → 3, ReLU, ReLU,
//! sigmoid) in fixed point, with an `f64` reference beside it.
//!
//! Inputs, as the MobileNeRF phone exports define them: 8 features from two
//! RGBA8 texels (RGB decoded `t/255`, alpha decoded `2·(t/255) − 1`) and the
//! unit view direction. The direction the viewer feeds is `(d.x, −d.z, d.y)`
//! of `d = normalize(surface − camera)` in the OBJ's y-up frame; the OBJ
//! frame is the world's `(x, z, −y)`, so that input is exactly the view
//! direction in the **z-up world frame** (the NeRF-synthetic camera frame).
//! [`ViewDir`] is that world-frame direction.
//!
//! ## Fixed-point scheme
//! - Activations are `i32`. The 11 inputs and the 3 output logits are Q24;
//!   each hidden layer's format Q`out_frac` (≤ 24) is the finest in which
//!   its worst-case value (bounded from the weights, for every possible
//!   input) fits in `i32`.
//! - Each layer's weights are `i32` scaled by `2^weight_frac`, its biases
//!   `i64` at the accumulator's scale; products accumulate in `i64` and one
//!   rounding right shift brings the sum to the output format.
//! - `weight_frac` is chosen per layer from that layer's own weights
//!   ([`FixedMlp::from_weights`]): the largest scale (≤ 2⁴⁰) for which every
//!   weight fits in `i32` and the worst-case accumulator fits in `i64`, so
//!   any `mlp.json` converts and no input can overflow. Weights are rejected
//!   only if non-finite or if a hidden activation could exceed 2³¹.
//! - The sigmoid is the exact 8-bit rounding of σ(z) by a threshold table
//!   ([`sigmoid_u8`]).
//!
//! The per-pixel path ([`FixedMlp::shade`]) uses integers only, no heap, and
//! wrapping arithmetic so that even a hand-made table cannot panic.

pub mod narrow;
mod sigmoid;

use core::fmt;

pub use fixed::types::I2F30;
pub use sigmoid::{sigmoid_u8, THRESHOLDS_Q24};

/// MLP inputs: 8 features + 3 direction components.
pub const INPUTS: usize = 11;
/// Width of both hidden layers.
pub const HIDDEN: usize = 16;
/// RGB outputs.
pub const OUTPUTS: usize = 3;
/// Multiply-adds per shaded pixel: 11·16 + 16·16 + 16·3 = 480.
pub const MACS_PER_PIXEL: usize = INPUTS * HIDDEN + HIDDEN * HIDDEN + HIDDEN * OUTPUTS;
/// Fractional bits of the MLP inputs and output logits (Q24); also the
/// finest hidden-activation format.
pub const ACT_FRAC: u8 = 24;
/// Largest per-layer weight scale tried (`2^40`): beyond it tiny weights gain nothing.
pub const MAX_WEIGHT_FRAC: u8 = 40;

/// The floating-point weights as `mlp.json` stores them (`W[in][out]`):
/// `h1 = relu(b0 + x·W0)`, `h2 = relu(b1 + h1·W1)`, `rgb = σ(b2 + h2·W2)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MlpWeights {
    /// `0_weights`, 11 × 16.
    pub w0: [[f32; HIDDEN]; INPUTS],
    /// `0_bias`.
    pub b0: [f32; HIDDEN],
    /// `1_weights`, 16 × 16.
    pub w1: [[f32; HIDDEN]; HIDDEN],
    /// `1_bias`.
    pub b1: [f32; HIDDEN],
    /// `2_weights`, 16 × 3.
    pub w2: [[f32; OUTPUTS]; HIDDEN],
    /// `2_bias`.
    pub b2: [f32; OUTPUTS],
}

impl MlpWeights {
    /// All-zero weights (every pixel shades to σ(0) = 128), a starting point
    /// for code that fills the arrays.
    pub const ZERO: Self = Self {
        w0: [[0.0; HIDDEN]; INPUTS],
        b0: [0.0; HIDDEN],
        w1: [[0.0; HIDDEN]; HIDDEN],
        b1: [0.0; HIDDEN],
        w2: [[0.0; OUTPUTS]; HIDDEN],
        b2: [0.0; OUTPUTS],
    };
}

/// A view direction in the z-up world frame, each component Q2.30
/// (`bits / 2³⁰`, range [−2, 2)); normally of unit length.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ViewDir(pub [I2F30; 3]);

/// `1.0` in a [`ViewDir`] component.
pub const DIR_ONE: i32 = 1 << 30;

impl ViewDir {
    /// From raw Q2.30 bits.
    pub const fn from_bits(bits: [i32; 3]) -> Self {
        Self([
            I2F30::from_bits(bits[0]),
            I2F30::from_bits(bits[1]),
            I2F30::from_bits(bits[2]),
        ])
    }

    /// The raw Q2.30 bits.
    pub fn bits(&self) -> [i32; 3] {
        [
            self.0[0].to_bits(),
            self.0[1].to_bits(),
            self.0[2].to_bits(),
        ]
    }

    /// Normalises `d` and rounds it to Q2.30; `None` if `d` is zero or not
    /// finite. (Set-up code only: uses floats.)
    pub fn from_f64(d: [f64; 3]) -> Option<Self> {
        let len = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if !(len.is_finite() && len > 0.0) {
            return None;
        }
        let q = |v: f64| libm::round(v / len * DIR_ONE as f64) as i32; // |v/len| ≤ 1: fits
        Some(Self::from_bits([q(d[0]), q(d[1]), q(d[2])]))
    }

    /// The direction as `f64` (not renormalised).
    pub fn to_f64(&self) -> [f64; 3] {
        self.bits().map(|b| b as f64 / DIR_ONE as f64)
    }
}

/// One layer in fixed point: `out = (bias + Σ in·weights) >> shift`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FixedLayer<const I: usize, const O: usize> {
    /// `round(W[in][out] · 2^weight_frac)`.
    pub weights: [[i32; O]; I],
    /// `round(b[out] · 2^(in_frac + weight_frac))`.
    pub bias: [i64; O],
    /// Fractional bits of the weights.
    pub weight_frac: u8,
    /// Fractional bits of the outputs (Q`out_frac`).
    pub out_frac: u8,
    /// Rounding right shift of the accumulator: `in_frac + weight_frac − out_frac`.
    pub shift: u8,
}

/// What [`FixedLayer::quantize`] needs to know about a layer's inputs.
struct Inputs<'a, const I: usize> {
    frac: u8,
    /// Bound of `|input i|` in Q`frac`, for every possible input.
    bound: &'a [i64; I],
}

impl<const I: usize, const O: usize> FixedLayer<I, O> {
    /// Accumulates `bias + Σ x·W` and shifts to the output format with rounding.
    #[inline(always)]
    fn forward(&self, x: &[i32; I]) -> [i64; O] {
        let mut acc = self.bias;
        for (&xi, row) in x.iter().zip(self.weights.iter()) {
            let xi = xi as i64;
            for (a, &w) in acc.iter_mut().zip(row.iter()) {
                *a = a.wrapping_add(xi.wrapping_mul(w as i64));
            }
        }
        let s = u32::from(self.shift.min(62));
        let half = (1i64 << s) >> 1;
        acc.map(|a| a.wrapping_add(half) >> s)
    }

    /// Quantises one layer. `out_frac`: wanted output format (≤ 24); for a
    /// hidden layer (`saturate == false`) it is lowered until the worst-case
    /// output fits `i32`. Returns the layer and the Q`out_frac` bound of each
    /// output.
    fn quantize(
        layer: u8,
        w: &[[f32; O]; I],
        b: &[f32; O],
        input: Inputs<I>,
        out_frac: u8,
        saturate: bool,
    ) -> Result<(Self, [i64; O]), ShaderError> {
        for (i, row) in w.iter().enumerate() {
            for (o, v) in row.iter().enumerate() {
                if !v.is_finite() {
                    return Err(ShaderError::NonFinite {
                        layer,
                        param: Param::Weight { row: i, col: o },
                    });
                }
            }
        }
        for (o, v) in b.iter().enumerate() {
            if !v.is_finite() {
                return Err(ShaderError::NonFinite {
                    layer,
                    param: Param::Bias { index: o },
                });
            }
        }
        const ACC_LIMIT: i128 = 1 << 62; // leaves room for the rounding add
        'scale: for frac in (0..=MAX_WEIGHT_FRAC).rev() {
            let acc_frac = i32::from(frac) + i32::from(input.frac);
            let scale = libm::ldexp(1.0, i32::from(frac));
            let bias_scale = libm::ldexp(1.0, acc_frac);
            let mut weights = [[0i32; O]; I];
            for (qrow, row) in weights.iter_mut().zip(w.iter()) {
                for (q, &v) in qrow.iter_mut().zip(row.iter()) {
                    let r = libm::round(v as f64 * scale);
                    if r.abs() > i32::MAX as f64 {
                        continue 'scale;
                    }
                    *q = r as i32;
                }
            }
            let mut bias = [0i64; O];
            for (q, &v) in bias.iter_mut().zip(b.iter()) {
                let r = libm::round(v as f64 * bias_scale);
                if r.abs() >= ACC_LIMIT as f64 {
                    continue 'scale;
                }
                *q = r as i64;
            }
            // Worst-case |accumulator| of each output over all inputs.
            let mut acc_bound = [0i128; O];
            for (o, ab) in acc_bound.iter_mut().enumerate() {
                let mut s = bias.get(o).map_or(0, |v| i128::from(*v).abs());
                for (row, &xb) in weights.iter().zip(input.bound.iter()) {
                    let wv = row.get(o).map_or(0, |v| i128::from(*v).abs());
                    s += wv * i128::from(xb);
                }
                if s >= ACC_LIMIT {
                    continue 'scale;
                }
                *ab = s;
            }
            let max_acc = acc_bound.iter().copied().max().unwrap_or(0);
            // Finest output format ≤ out_frac (and ≤ the accumulator's) whose
            // worst case fits i32; the logits may saturate instead.
            let mut of = out_frac.min(acc_frac as u8);
            let bound_at = |of: u8| (max_acc >> (acc_frac - i32::from(of))) + 1;
            while !saturate && bound_at(of) > i32::MAX as i128 {
                if of == 0 {
                    return Err(ShaderError::Unrepresentable {
                        layer,
                        what: "a hidden activation can exceed 2^31",
                    });
                }
                of -= 1;
            }
            let shift = (acc_frac - i32::from(of)) as u8;
            if shift > 62 {
                continue 'scale; // keep the rounding shift within i64
            }
            let out_bound = acc_bound.map(|a| ((a >> shift) + 1).min(i64::MAX as i128) as i64);
            let layer = Self {
                weights,
                bias,
                weight_frac: frac,
                out_frac: of,
                shift,
            };
            return Ok((layer, out_bound));
        }
        Err(ShaderError::Unrepresentable {
            layer,
            what: "no weight scale keeps every weight in i32 and the accumulator in i64",
        })
    }
}

/// Which parameter of a layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// `W[row][col]`.
    Weight {
        /// Input index.
        row: usize,
        /// Output index.
        col: usize,
    },
    /// `b[index]`.
    Bias {
        /// Output index.
        index: usize,
    },
}

/// Why a weight set cannot be converted to fixed point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShaderError {
    /// A weight or bias is NaN or infinite.
    NonFinite {
        /// Layer 0, 1 or 2.
        layer: u8,
        /// Which value.
        param: Param,
    },
    /// The weights are too large for the fixed-point format.
    Unrepresentable {
        /// Layer 0, 1 or 2.
        layer: u8,
        /// What does not fit.
        what: &'static str,
    },
}

impl fmt::Display for ShaderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ShaderError::NonFinite {
                layer,
                param: Param::Weight { row, col },
            } => write!(f, "{layer}_weights[{row}][{col}] is not finite"),
            ShaderError::NonFinite {
                layer,
                param: Param::Bias { index },
            } => write!(f, "{layer}_bias[{index}] is not finite"),
            ShaderError::Unrepresentable { layer, what } => {
                write!(
                    f,
                    "layer {layer} ({layer}_weights, {layer}_bias) is not representable in fixed point: {what}"
                )
            }
        }
    }
}

impl core::error::Error for ShaderError {}

/// The fixed-point MLP: plain integer tables, so firmware can embed one as
/// a `const` (see [`FixedMlp::write_rust`]). Inputs Q24, logits Q24.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FixedMlp {
    /// 11 → 16, ReLU.
    pub l0: FixedLayer<INPUTS, HIDDEN>,
    /// 16 → 16, ReLU.
    pub l1: FixedLayer<HIDDEN, HIDDEN>,
    /// 16 → 3, sigmoid.
    pub l2: FixedLayer<HIDDEN, OUTPUTS>,
}

/// `round(n · 2²⁴ / 255)` for `n` in 0..=510 (exact: 255 is odd, no ties).
#[inline(always)]
fn q24_of_255ths(n: u32) -> i32 {
    ((u64::from(n) * (1 << 24) + 127) / 255) as i32
}

/// The 11 Q24 inputs of the MLP.
#[inline(always)]
fn fixed_inputs(feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [i32; INPUTS] {
    let rgb = |t: u8| q24_of_255ths(u32::from(t));
    let alpha = |t: u8| q24_of_255ths(2 * u32::from(t)) - (1 << 24);
    // Q30 → Q24 with rounding.
    let d = dir.bits().map(|b| (b >> 6) + ((b >> 5) & 1));
    [
        rgb(feat0[0]),
        rgb(feat0[1]),
        rgb(feat0[2]),
        alpha(feat0[3]),
        rgb(feat1[0]),
        rgb(feat1[1]),
        rgb(feat1[2]),
        alpha(feat1[3]),
        d[0],
        d[1],
        d[2],
    ]
}

#[inline(always)]
fn relu<const N: usize>(z: [i64; N]) -> [i32; N] {
    // Clamping is a no-op for weights built by `from_weights` (bounded).
    z.map(|v| v.clamp(0, i32::MAX as i64) as i32)
}

impl FixedMlp {
    /// Quantises a weight set, choosing each layer's scales from its weights.
    ///
    /// Errors for non-finite weights and for weights whose hidden
    /// activations could exceed 2³¹ for some input.
    pub fn from_weights(w: &MlpWeights) -> Result<Self, ShaderError> {
        // Features decode to [−1, 1]; a ViewDir component is below 2 in
        // magnitude whatever its bits (Q2.30).
        let one = 1i64 << ACT_FRAC;
        let mut in0 = [one; INPUTS];
        for v in in0.iter_mut().skip(8) {
            *v = 2 * one;
        }
        let input = Inputs {
            frac: ACT_FRAC,
            bound: &in0,
        };
        let (l0, b1) = FixedLayer::quantize(0, &w.w0, &w.b0, input, ACT_FRAC, false)?;
        let input = Inputs {
            frac: l0.out_frac,
            bound: &b1,
        };
        let (l1, b2) = FixedLayer::quantize(1, &w.w1, &w.b1, input, ACT_FRAC, false)?;
        let input = Inputs {
            frac: l1.out_frac,
            bound: &b2,
        };
        let (l2, _) = FixedLayer::quantize(2, &w.w2, &w.b2, input, ACT_FRAC, true)?;
        Ok(Self { l0, l1, l2 })
    }

    /// The three output logits in Q24 (before the sigmoid), saturated to `i32`.
    pub fn logits_q24(&self, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [i32; 3] {
        let x = fixed_inputs(feat0, feat1, dir);
        let h1 = relu(self.l0.forward(&x));
        let h2 = relu(self.l1.forward(&h1));
        self.l2
            .forward(&h2)
            .map(|v| v.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
    }

    /// Shades one texel: 8-bit RGB from the two feature texels and the
    /// world-frame view direction. Integers only; never panics.
    ///
    /// Not `#[inline]` on purpose: it is compiled once, in this crate, at
    /// its optimisation level, whatever the caller's profile.
    pub fn shade(&self, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [u8; 3] {
        self.logits_q24(feat0, feat1, dir).map(sigmoid_u8)
    }

    /// Writes `pub const NAME: FixedMlp = FixedMlp { … };` — Rust source a
    /// firmware build script can emit (paths assume `FixedMlp` and
    /// `FixedLayer` are in scope).
    pub fn write_rust(&self, out: &mut impl fmt::Write, name: &str) -> fmt::Result {
        writeln!(out, "pub const {name}: FixedMlp = FixedMlp {{")?;
        write_layer(out, "l0", &self.l0)?;
        write_layer(out, "l1", &self.l1)?;
        write_layer(out, "l2", &self.l2)?;
        writeln!(out, "}};")
    }
}

fn write_layer<const I: usize, const O: usize>(
    out: &mut impl fmt::Write,
    name: &str,
    l: &FixedLayer<I, O>,
) -> fmt::Result {
    writeln!(out, "    {name}: FixedLayer {{")?;
    writeln!(out, "        weights: [")?;
    for row in &l.weights {
        write!(out, "            [")?;
        for v in row {
            write!(out, "{v}, ")?;
        }
        writeln!(out, "],")?;
    }
    writeln!(out, "        ],")?;
    write!(out, "        bias: [")?;
    for v in &l.bias {
        write!(out, "{v}, ")?;
    }
    writeln!(out, "],")?;
    writeln!(out, "        weight_frac: {},", l.weight_frac)?;
    writeln!(out, "        out_frac: {},", l.out_frac)?;
    writeln!(out, "        shift: {},", l.shift)?;
    writeln!(out, "    }},")
}

// ---------------------------------------------------------------------------
// Floating-point reference and the float renderer's shader.

/// The 8 decoded features: RGB `t/255`, alpha `2·(t/255) − 1`.
pub fn decode_features(feat0: [u8; 4], feat1: [u8; 4]) -> [f64; 8] {
    let c = |t: u8| t as f64 / 255.0;
    let a = |t: u8| 2.0 * (t as f64 / 255.0) - 1.0;
    [
        c(feat0[0]),
        c(feat0[1]),
        c(feat0[2]),
        a(feat0[3]),
        c(feat1[0]),
        c(feat1[1]),
        c(feat1[2]),
        a(feat1[3]),
    ]
}

/// The MLP's input vector: decoded features then the world-frame direction.
pub fn mlp_input_f64(feat0: [u8; 4], feat1: [u8; 4], dir: [f64; 3]) -> [f64; INPUTS] {
    let f = decode_features(feat0, feat1);
    [
        f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], dir[0], dir[1], dir[2],
    ]
}

fn dense_f64<const I: usize, const O: usize>(
    x: &[f64; I],
    w: &[[f32; O]; I],
    b: &[f32; O],
) -> [f64; O] {
    let mut acc = b.map(|v| v as f64);
    for (&xi, row) in x.iter().zip(w.iter()) {
        for (a, &wv) in acc.iter_mut().zip(row.iter()) {
            *a += xi * wv as f64;
        }
    }
    acc
}

/// Reference MLP in `f64` up to the output pre-activations (logits).
pub fn mlp_logits_f64(w: &MlpWeights, x: &[f64; INPUTS]) -> [f64; OUTPUTS] {
    let h1 = dense_f64(x, &w.w0, &w.b0).map(|v| v.max(0.0));
    let h2 = dense_f64(&h1, &w.w1, &w.b1).map(|v| v.max(0.0));
    dense_f64(&h2, &w.w2, &w.b2)
}

/// Reference MLP in `f64`: RGB in [0, 1].
pub fn mlp_f64(w: &MlpWeights, x: &[f64; INPUTS]) -> [f64; OUTPUTS] {
    mlp_logits_f64(w, x).map(|z| 1.0 / (1.0 + libm::exp(-z)))
}

/// `round(255 · y)` of a value in [0, 1] (clamped; NaN gives 0).
pub fn unit_to_u8(y: f64) -> u8 {
    libm::round(y.clamp(0.0, 1.0) * 255.0) as u8
}

/// The reference shade: [`mlp_f64`] rounded to 8 bits. `dir` need not be
/// normalised (it is, here).
pub fn shade_f64(w: &MlpWeights, feat0: [u8; 4], feat1: [u8; 4], dir: [f64; 3]) -> [u8; 3] {
    let len = libm::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    let d = if len > 0.0 {
        [dir[0] / len, dir[1] / len, dir[2] / len]
    } else {
        dir
    };
    mlp_f64(w, &mlp_input_f64(feat0, feat1, d)).map(unit_to_u8)
}

fn dense_f32<const I: usize, const O: usize>(
    x: &[f32; I],
    w: &[[f32; O]; I],
    b: &[f32; O],
) -> [f32; O] {
    let mut acc = *b;
    for (&xi, row) in x.iter().zip(w.iter()) {
        for (a, &wv) in acc.iter_mut().zip(row.iter()) {
            *a += xi * wv;
        }
    }
    acc
}

/// The MLP in `f32` (what a GPU computes), from 8-bit texels and a unit
/// world-frame direction; 8-bit RGB.
pub fn shade_f32(w: &MlpWeights, feat0: [u8; 4], feat1: [u8; 4], dir: [f32; 3]) -> [u8; 3] {
    let c = |t: u8| t as f32 * (1.0 / 255.0);
    let a = |t: u8| t as f32 * (2.0 / 255.0) - 1.0;
    let x = [
        c(feat0[0]),
        c(feat0[1]),
        c(feat0[2]),
        a(feat0[3]),
        c(feat1[0]),
        c(feat1[1]),
        c(feat1[2]),
        a(feat1[3]),
        dir[0],
        dir[1],
        dir[2],
    ];
    let h1 = dense_f32(&x, &w.w0, &w.b0).map(|v| v.max(0.0));
    let h2 = dense_f32(&h1, &w.w1, &w.b1).map(|v| v.max(0.0));
    dense_f32(&h2, &w.w2, &w.b2).map(|z| {
        let y = 1.0 / (1.0 + libm::expf(-z));
        libm::roundf(y.clamp(0.0, 1.0) * 255.0) as u8
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random weight set with weights in ±`scale`.
    fn weights(seed: u64, scale: f32) -> MlpWeights {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
        };
        let mut w = MlpWeights::ZERO;
        w.w0.iter_mut().flatten().for_each(|v| *v = next());
        w.b0.iter_mut().for_each(|v| *v = next() * 0.3);
        w.w1.iter_mut().flatten().for_each(|v| *v = next());
        w.b1.iter_mut().for_each(|v| *v = next() * 0.3);
        w.w2.iter_mut().flatten().for_each(|v| *v = next());
        w.b2.iter_mut().for_each(|v| *v = next() * 0.3);
        w
    }

    #[test]
    fn fixed_matches_f64_reference() {
        let w = weights(7, 1.5);
        let m = FixedMlp::from_weights(&w).unwrap();
        let mut worst = 0.0f64;
        for i in 0..4000u32 {
            let f0 = [
                (i * 37 % 255 + 1) as u8,
                (i * 11) as u8,
                (i * 7) as u8,
                (i * 3) as u8,
            ];
            let f1 = [
                (i * 5) as u8,
                (i * 13) as u8,
                (i * 17) as u8,
                (i * 19) as u8,
            ];
            let th = i as f64 * 0.37;
            let ph = i as f64 * 0.11;
            let d = [th.cos() * ph.sin(), th.sin() * ph.sin(), ph.cos()];
            let dir = ViewDir::from_f64(d).unwrap();
            let x = mlp_input_f64(f0, f1, dir.to_f64());
            let logits = m.logits_q24(f0, f1, dir);
            // Pre-activation logits: compare in f64.
            let h1 = dense_f64(&x, &w.w0, &w.b0).map(|v| v.max(0.0));
            let h2 = dense_f64(&h1, &w.w1, &w.b1).map(|v| v.max(0.0));
            let z = dense_f64(&h2, &w.w2, &w.b2);
            for (l, zf) in logits.iter().zip(z) {
                worst = worst.max((*l as f64 / 16777216.0 - zf).abs());
            }
            let got = m.shade(f0, f1, dir);
            let want = shade_f64(&w, f0, f1, d);
            for (g, r) in got.iter().zip(want) {
                assert!((*g as i32 - r as i32).abs() <= 1, "{got:?} {want:?}");
            }
        }
        // Q24-ish activations: the logits are within ~1e-6 of f64.
        assert!(worst < 1e-5, "worst logit error {worst}");
    }

    #[test]
    fn bad_weights_are_rejected_not_panicking() {
        let mut w = weights(1, 1.0);
        w.w1[3][4] = f32::NAN;
        assert_eq!(
            FixedMlp::from_weights(&w),
            Err(ShaderError::NonFinite {
                layer: 1,
                param: Param::Weight { row: 3, col: 4 }
            })
        );
        let mut w = weights(1, 1.0);
        w.b2[2] = f32::INFINITY;
        let e = FixedMlp::from_weights(&w).unwrap_err();
        assert_eq!(e.to_string(), "2_bias[2] is not finite");
        // Hidden activations that can exceed 2^31 do not fit an i32.
        let w = weights(2, 1.0e5);
        assert!(matches!(
            FixedMlp::from_weights(&w),
            Err(ShaderError::Unrepresentable { .. })
        ));
        // Huge output-layer weights are fine: the logits saturate.
        let mut w = weights(3, 1.0);
        w.w2.iter_mut().flatten().for_each(|v| *v *= 1.0e6);
        let m = FixedMlp::from_weights(&w).unwrap();
        let _ = m.shade([255; 4], [255; 4], ViewDir::from_bits([i32::MIN; 3]));
    }

    #[test]
    fn arbitrary_tables_never_panic() {
        let mut m = FixedMlp::from_weights(&weights(5, 1.0)).unwrap();
        m.l0.weights
            .iter_mut()
            .flatten()
            .for_each(|v| *v = i32::MAX);
        m.l1.bias.iter_mut().for_each(|v| *v = i64::MIN);
        m.l2.weight_frac = 255;
        let _ = m.shade(
            [255; 4],
            [0; 4],
            ViewDir::from_bits([i32::MAX, i32::MIN, 0]),
        );
    }

    #[test]
    fn zero_weights_give_mid_grey_and_rust_source_lists_tables() {
        let m = FixedMlp::from_weights(&MlpWeights::ZERO).unwrap();
        assert_eq!(
            m.shade([1, 2, 3, 4], [5, 6, 7, 8], ViewDir::default()),
            [128; 3]
        );
        let mut s = std::string::String::new();
        m.write_rust(&mut s, "MLP").unwrap();
        assert!(s.starts_with("pub const MLP: FixedMlp = FixedMlp {"));
        assert_eq!(s.matches("weight_frac: 40,").count(), 3);
    }

    #[test]
    fn f32_and_f64_agree() {
        let w = weights(9, 1.2);
        for i in 0..500u32 {
            let f0 = [
                (i % 255 + 1) as u8,
                (i * 3) as u8,
                (i * 7) as u8,
                (i * 5) as u8,
            ];
            let f1 = [(i * 9) as u8, (i * 2) as u8, (i * 4) as u8, (i * 6) as u8];
            let d = [0.6f32, -0.64, 0.48];
            let a = shade_f32(&w, f0, f1, d);
            let b = shade_f64(&w, f0, f1, [0.6, -0.64, 0.48]);
            for (x, y) in a.iter().zip(b) {
                assert!((*x as i32 - y as i32).abs() <= 1);
            }
        }
    }
}
