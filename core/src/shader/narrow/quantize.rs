//! Building a [`NarrowMlp`] from float weights, and the error check that
//! decides whether a weight set may use it. Set-up code: uses `f64`.

use super::{
    NarrowLayer, NarrowMlp, GROUP, HIDDEN_GROUPS, HIDDEN_PAIRS, INPUT_PAIRS, INPUT_PAIR_INDICES,
};
use crate::shader::{
    mlp_input_f64, mlp_logits_f64, MlpWeights, Param, ShaderError, ViewDir, HIDDEN, INPUTS, OUTPUTS,
};

/// Weight width of a narrow table. Both are stored in 16-bit halves (what
/// `SMLAD` reads); `Eight` limits them to ±127 (q7 storage is possible).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightBits {
    /// |w| ≤ 127.
    Eight,
    /// |w| ≤ 32767.
    Sixteen,
}

impl WeightBits {
    /// Largest weight magnitude.
    pub fn max(self) -> i16 {
        match self {
            WeightBits::Eight => 127,
            WeightBits::Sixteen => i16::MAX,
        }
    }
}

/// Largest accumulator magnitude allowed for any input.
const ACC_LIMIT: i128 = i32::MAX as i128;
/// Scale of a feature input `t << 7` (value `t / 255`).
const FEATURE_SCALE: f64 = 255.0 * 128.0;
/// Scale of a direction input (top 16 bits of Q2.30).
const DIR_SCALE: f64 = 16384.0;

/// What a layer's quantisation needs about its inputs (integer domain).
struct LayerIn<'a, const I: usize, const P: usize> {
    /// `value = x / scale`.
    scale: &'a [f64; I],
    /// Largest `|x|`.
    bound: &'a [i64; I],
    /// Which inputs each pair carries.
    pairs: &'a [[Option<usize>; 2]; P],
}

/// A quantised layer and, per output (first `G · N` entries), its
/// accumulator scale, bound and logit shift.
struct LayerOut<const P: usize, const G: usize, const N: usize> {
    layer: NarrowLayer<P, G, N>,
    scale: [f64; HIDDEN],
    acc_bound: [i64; HIDDEN],
    shift: [u8; HIDDEN],
}

fn check_finite<const I: usize, const O: usize>(
    layer: u8,
    w: &[[f32; O]; I],
    b: &[f32; O],
) -> Result<(), ShaderError> {
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
    Ok(())
}

/// `floor(log2 s)` for a positive finite `s`.
fn floor_log2(s: f64) -> i32 {
    let mut k = 0i32;
    let mut v = s;
    while v >= 2.0 && k < 1100 {
        v /= 2.0;
        k += 1;
    }
    while v < 1.0 && k > -1100 {
        v *= 2.0;
        k -= 1;
    }
    k
}

/// Quantises one layer: weights `w[i][o]` (effective, real), bias `b[o]`.
/// `logit`: power-of-two scales and a shift to Q24 instead of the fixed
/// `>> 16` of a hidden layer.
fn quantize_layer<
    const I: usize,
    const O: usize,
    const P: usize,
    const G: usize,
    const N: usize,
>(
    layer: u8,
    w: &[[f64; O]; I],
    b: &[f64; O],
    input: &LayerIn<I, P>,
    wmax: i16,
    logit: bool,
    k_cap: i32,
) -> Result<LayerOut<P, G, N>, ShaderError> {
    let mut out = LayerOut {
        layer: NarrowLayer {
            w: [[[0u32; G]; P]; N],
            bias: [[0i32; G]; N],
        },
        scale: [0.0; HIDDEN],
        acc_bound: [0; HIDDEN],
        shift: [0; HIDDEN],
    };
    let wmax_f = f64::from(wmax);
    for o in 0..(G * N).min(O) {
        let (n, g) = (o / G, o % G);
        let col = |i: usize| w.get(i).and_then(|r| r.get(o)).copied().unwrap_or(0.0);
        let bias = b.get(o).copied().unwrap_or(0.0);
        // Largest scale the weight width allows, and the real bound of |acc / S|.
        let mut s_max = f64::INFINITY;
        let mut real_bound = libm::fabs(bias);
        for i in 0..I {
            let (wi, si) = (
                libm::fabs(col(i)),
                input.scale.get(i).copied().unwrap_or(1.0),
            );
            let bi = input.bound.get(i).copied().unwrap_or(0) as f64;
            if wi > 0.0 {
                s_max = s_max.min(wmax_f * si / wi);
                real_bound += wi * bi / si;
            }
        }
        // Headroom for the rounding offset and every weight's rounding.
        let slack = 2.0 * 32768.0 + (I as f64) * 32768.0;
        if real_bound > 0.0 {
            s_max = s_max.min((ACC_LIMIT as f64 - slack) / real_bound);
        }
        if !s_max.is_finite() {
            s_max = 16_777_216.0; // all-zero column: any scale
        }
        let mut s = s_max;
        let mut tries = 0;
        loop {
            tries += 1;
            if tries > 200 || !(s > 0.0 && s.is_finite()) {
                return Err(ShaderError::Unrepresentable {
                    layer,
                    what: "no accumulator scale keeps every 16-bit weight and the i32 accumulator in range",
                });
            }
            let mut shift = 0u8;
            let half: i64;
            if logit {
                // At most Q24 (finer gains nothing): a left shift to Q24.
                let k = floor_log2(s).min(k_cap);
                if 24 - k > 31 {
                    return Err(ShaderError::Unrepresentable {
                        layer,
                        what: "a logit can exceed 2^38",
                    });
                }
                s = libm::ldexp(1.0, k);
                shift = (24 - k) as u8;
                half = 0;
            } else {
                half = 1 << 15;
            }
            let q = |v: f64| libm::round(v);
            let bq = q(bias * s);
            if libm::fabs(bq) > ACC_LIMIT as f64 {
                s *= 0.99;
                continue;
            }
            let bias_q = bq as i64 + half;
            let mut acc_bound = i128::from(bias_q).abs();
            let mut row = [0u32; P];
            let mut ok = true;
            for (pair, idx) in row.iter_mut().zip(input.pairs.iter()) {
                let mut halves = [0u32; 2];
                for (h, slot) in halves.iter_mut().zip(idx.iter()) {
                    let Some(i) = *slot else { continue };
                    let si = input.scale.get(i).copied().unwrap_or(1.0);
                    let wq = q(col(i) * s / si);
                    if libm::fabs(wq) > wmax_f {
                        ok = false;
                    }
                    let wq = wq.clamp(-wmax_f, wmax_f) as i64;
                    acc_bound +=
                        i128::from(wq.abs()) * i128::from(input.bound.get(i).copied().unwrap_or(0));
                    *h = (wq as i16 as u16) as u32;
                }
                let [lo, hi] = halves;
                *pair = lo | (hi << 16);
            }
            if !ok || acc_bound > ACC_LIMIT {
                s *= 0.99;
                continue;
            }
            if let (Some(wn), Some(bo), Some(so), Some(ab), Some(sh)) = (
                out.layer.w.get_mut(n),
                out.layer.bias.get_mut(n).and_then(|b| b.get_mut(g)),
                out.scale.get_mut(o),
                out.acc_bound.get_mut(o),
                out.shift.get_mut(o),
            ) {
                for (dst, &v) in wn.iter_mut().zip(row.iter()) {
                    if let Some(d) = dst.get_mut(g) {
                        *d = v;
                    }
                }
                *bo = bias_q as i32; // |bias_q| ≤ acc_bound ≤ i32::MAX
                *so = s;
                *ab = acc_bound as i64;
                *sh = shift;
            }
            break;
        }
    }
    Ok(out)
}

impl NarrowMlp {
    /// Quantises a weight set with the given weight width. Errors for
    /// non-finite weights and for weights no scale can represent.
    pub fn from_weights(w: &MlpWeights, bits: WeightBits) -> Result<Self, ShaderError> {
        check_finite(0, &w.w0, &w.b0)?;
        check_finite(1, &w.w1, &w.b1)?;
        check_finite(2, &w.w2, &w.b2)?;
        let wmax = bits.max();
        // Layer 0: features enter as t << 7 (value t/255); alpha decodes as
        // 2t/255 − 1, folded into a doubled weight and the bias.
        let mut w0 = [[0f64; HIDDEN]; INPUTS];
        for (dst, src) in w0.iter_mut().zip(w.w0.iter()) {
            for (d, &s) in dst.iter_mut().zip(src.iter()) {
                *d = f64::from(s);
            }
        }
        let mut b0 = w.b0.map(f64::from);
        for alpha in [3usize, 7] {
            if let Some(row) = w0.get_mut(alpha) {
                for (wv, bv) in row.iter_mut().zip(b0.iter_mut()) {
                    *bv -= *wv;
                    *wv *= 2.0;
                }
            }
        }
        let mut scale0 = [FEATURE_SCALE; INPUTS];
        let mut bound0 = [(255 << 7) as i64; INPUTS];
        for (s, b) in scale0.iter_mut().zip(bound0.iter_mut()).skip(8) {
            *s = DIR_SCALE;
            *b = 32768; // any Q2.30 bits: |top 16 bits| ≤ 2^15
        }
        let l0 = quantize_layer::<INPUTS, HIDDEN, INPUT_PAIRS, GROUP, HIDDEN_GROUPS>(
            0,
            &w0,
            &b0,
            &LayerIn {
                scale: &scale0,
                bound: &bound0,
                pairs: &INPUT_PAIR_INDICES,
            },
            wmax,
            false,
            24,
        )?;
        let hidden_pairs = hidden_pair_indices();
        let (s1, b1) = hidden_inputs(&l0);
        let l1 = quantize_layer::<HIDDEN, HIDDEN, HIDDEN_PAIRS, GROUP, HIDDEN_GROUPS>(
            1,
            &w.w1.map(|r| r.map(f64::from)),
            &w.b1.map(f64::from),
            &LayerIn {
                scale: &s1,
                bound: &b1,
                pairs: &hidden_pairs,
            },
            wmax,
            false,
            24,
        )?;
        let (s2, b2) = hidden_inputs(&l1);
        // The logits share one scale (one clamp and shift for all three):
        // the coarsest any of them needs.
        let logit_in = LayerIn {
            scale: &s2,
            bound: &b2,
            pairs: &hidden_pairs,
        };
        let (w2, b2q) = (w.w2.map(|r| r.map(f64::from)), w.b2.map(f64::from));
        let l2 = quantize_layer::<HIDDEN, OUTPUTS, HIDDEN_PAIRS, OUTPUTS, 1>(
            2, &w2, &b2q, &logit_in, wmax, true, 24,
        )?;
        let lshift = l2.shift.iter().take(OUTPUTS).copied().max().unwrap_or(0);
        let l2 = quantize_layer::<HIDDEN, OUTPUTS, HIDDEN_PAIRS, OUTPUTS, 1>(
            2,
            &w2,
            &b2q,
            &logit_in,
            wmax,
            true,
            24 - i32::from(lshift),
        )?;
        Ok(Self {
            l0: l0.layer,
            l1: l1.layer,
            l2: l2.layer,
            logit_lshift: l2.shift.iter().take(OUTPUTS).copied().max().unwrap_or(0),
            weight_max: wmax,
        })
    }

    /// The narrow tables for `w` if their error on `samples` passes the
    /// accuracy criterion ([`ErrorHistogram::passes`]): 8-bit weights if
    /// those pass, else 16-bit; `Ok(None)` if neither does (use the exact
    /// shader). `samples` is called once per width.
    pub fn choose<S>(
        w: &MlpWeights,
        samples: impl Fn() -> S,
    ) -> Result<Option<(Self, ErrorHistogram)>, ShaderError>
    where
        S: Iterator<Item = ([u8; 4], [u8; 4], ViewDir)>,
    {
        for bits in [WeightBits::Eight, WeightBits::Sixteen] {
            let m = Self::from_weights(w, bits)?;
            let h = m.error_histogram(w, samples());
            if h.passes() {
                return Ok(Some((m, h)));
            }
        }
        Ok(None)
    }

    /// |narrow − `f64` reference| (max over RGB, 8-bit steps) over `samples`;
    /// the reference sees the same quantised direction.
    pub fn error_histogram(
        &self,
        w: &MlpWeights,
        samples: impl Iterator<Item = ([u8; 4], [u8; 4], ViewDir)>,
    ) -> ErrorHistogram {
        let mut h = ErrorHistogram::default();
        for (f0, f1, d) in samples {
            let want = mlp_logits_f64(w, &mlp_input_f64(f0, f1, d.to_f64()))
                .map(|z| libm::round(255.0 / (1.0 + libm::exp(-z))) as i32);
            let got = self.shade(f0, f1, d);
            let e = got
                .iter()
                .zip(want.iter())
                .map(|(&a, &b)| (i32::from(a) - b).unsigned_abs())
                .max()
                .unwrap_or(0);
            h.add(e, 1);
        }
        h
    }
}

fn hidden_pair_indices() -> [[Option<usize>; 2]; 8] {
    let mut p = [[None; 2]; 8];
    for (k, v) in p.iter_mut().enumerate() {
        *v = [Some(2 * k), Some(2 * k + 1)];
    }
    p
}

/// Scales and bounds of a hidden layer's outputs (`acc >> 16`, ReLU).
fn hidden_inputs<const P: usize, const G: usize, const N: usize>(
    l: &LayerOut<P, G, N>,
) -> ([f64; HIDDEN], [i64; HIDDEN]) {
    (
        l.scale.map(|s| s / 65536.0),
        l.acc_bound.map(|a| (a >> 16).min(0x7FFF)),
    )
}

/// Errors in 8-bit steps: `counts[k]` samples were `k` steps off
/// (`counts[3]`: three or more).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ErrorHistogram {
    /// Exact, 1, 2, ≥ 3 steps.
    pub counts: [u64; 4],
}

impl ErrorHistogram {
    /// Counts `n` samples with error `e` steps.
    pub fn add(&mut self, e: u32, n: u64) {
        if let Some(c) = self.counts.get_mut((e as usize).min(3)) {
            *c += n;
        }
    }

    /// Adds another histogram.
    pub fn merge(&mut self, o: &ErrorHistogram) {
        for (a, b) in self.counts.iter_mut().zip(o.counts.iter()) {
            *a += b;
        }
    }

    /// Samples counted.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// Fraction within one step.
    pub fn within_one(&self) -> f64 {
        let [a, b, _, _] = self.counts;
        (a + b) as f64 / self.total().max(1) as f64
    }

    /// The accuracy criterion: ≥ 99.9 % within one step, none beyond two.
    pub fn passes(&self) -> bool {
        let [a, b, _, far] = self.counts;
        self.total() > 0 && 1000 * (a + b) >= 999 * self.total() && far == 0
    }
}

/// A deterministic check set for [`NarrowMlp::choose`] when no real atlas
/// is at hand: `texels` pseudo-random occupied texel pairs (feat0.R ≠ 0),
/// each under `dirs` directions of a Fibonacci sphere.
pub fn check_samples(texels: u32, dirs: u32) -> impl Iterator<Item = ([u8; 4], [u8; 4], ViewDir)> {
    (0..texels).flat_map(move |t| {
        let mut s = u64::from(t).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5_DEEC_E66D;
        for _ in 0..3 {
            s ^= s >> 29;
            s = s.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        }
        let [b0, b1, b2, b3, b4, b5, b6, b7] = s.to_le_bytes();
        let f0 = [b0 | 1, b1, b2, b3];
        let f1 = [b4, b5, b6, b7];
        (0..dirs).map(move |i| {
            let n = f64::from(dirs.max(1));
            let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / n;
            let r = libm::sqrt((1.0 - z * z).max(0.0));
            let a = 2.399_963_229_728_653 * f64::from(i + t);
            let d = ViewDir::from_f64([r * libm::cos(a), r * libm::sin(a), z]).unwrap_or_default();
            (f0, f1, d)
        })
    })
}
