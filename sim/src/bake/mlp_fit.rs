//! The MLP and feature code that make the renderer's shader reproduce the
//! baked texel colours.
//!
//! MobileNeRF's shader computes rgb = sigmoid(W2·relu(W1·relu(W0·x + b0) +
//! b1) + b2) from the 8 texel features and the view direction. The baker
//! builds that network analytically instead of training it:
//!
//! - colour channel c is stored as one byte `f` in feat0's channel c (R, G,
//!   B); every other feature and the view direction get zero weight
//!   (view-independent colour, the spare channels are left 0);
//! - per channel, the network computes a piecewise-linear N(f) with 9
//!   segments that follows logit: 5 first-layer units (f itself and 4
//!   hinges relu(f − t)) and 5 second-layer units (the first 4 hinges summed,
//!   plus 4 more hinges of f passed through) — 15 of the 16 units per layer;
//! - the knots are placed so that the output level grows by at most
//!   S ≈ 1.4 levels per byte step anywhere ([`design`]), and a per-channel
//!   table maps each wanted 8-bit level to the byte whose shaded output is
//!   closest. By construction every level 0..=255 is then reproduced within
//!   ⌊S/2 + 1/2⌋ = 1 level by exact arithmetic; the fixed-point shader adds
//!   its own rounding.
//!
//! Byte 0 is never used in feat0.R (it means "empty texel"), so an occupied
//! texel always has feat0.R ≥ 1.

/// Hidden units per layer.
pub const HIDDEN: usize = 16;
/// Inputs: 8 features + 3 direction components.
pub const INPUTS: usize = 11;

/// Weights of the 11 → 16 → 16 → 3 MLP in the export's `W[in][out]` layout.
#[derive(Debug, Clone, PartialEq)]
pub struct MlpWeights {
    /// Layer 0 weights `[in][out]`.
    pub w0: [[f32; HIDDEN]; INPUTS],
    /// Layer 0 bias.
    pub b0: [f32; HIDDEN],
    /// Layer 1 weights.
    pub w1: [[f32; HIDDEN]; HIDDEN],
    /// Layer 1 bias.
    pub b1: [f32; HIDDEN],
    /// Layer 2 weights.
    pub w2: [[f32; 3]; HIDDEN],
    /// Layer 2 bias.
    pub b2: [f32; 3],
}

impl MlpWeights {
    /// All weights zero.
    pub fn zero() -> Self {
        Self {
            w0: [[0.0; HIDDEN]; INPUTS],
            b0: [0.0; HIDDEN],
            w1: [[0.0; HIDDEN]; HIDDEN],
            b1: [0.0; HIDDEN],
            w2: [[0.0; 3]; HIDDEN],
            b2: [0.0; 3],
        }
    }

    /// The network in `f64` on decoded inputs (features in [0, 1] / [−1, 1],
    /// direction), returning rgb in [0, 1].
    pub fn eval_f64(&self, x: &[f64; INPUTS]) -> [f64; 3] {
        let mut h1 = [0f64; HIDDEN];
        for (o, h) in h1.iter_mut().enumerate() {
            let s: f64 = (0..INPUTS).map(|i| x[i] * f64::from(self.w0[i][o])).sum();
            *h = (s + f64::from(self.b0[o])).max(0.0);
        }
        let mut h2 = [0f64; HIDDEN];
        for (o, h) in h2.iter_mut().enumerate() {
            let s: f64 = (0..HIDDEN).map(|i| h1[i] * f64::from(self.w1[i][o])).sum();
            *h = (s + f64::from(self.b1[o])).max(0.0);
        }
        let mut rgb = [0f64; 3];
        for (o, c) in rgb.iter_mut().enumerate() {
            let s: f64 = (0..HIDDEN).map(|i| h2[i] * f64::from(self.w2[i][o])).sum();
            *c = 1.0 / (1.0 + (-(s + f64::from(self.b2[o]))).exp());
        }
        rgb
    }
}

/// Decodes two stored RGBA8 texels and a direction into the MLP inputs, as
/// the phone exports do: feature = byte/255, alpha = 2·(A/255) − 1.
pub fn inputs(feat0: [u8; 4], feat1: [u8; 4], dir: [f32; 3]) -> [f64; INPUTS] {
    let f = |b: u8| f64::from(b) / 255.0;
    let a = |b: u8| 2.0 * f64::from(b) / 255.0 - 1.0;
    [
        f(feat0[0]),
        f(feat0[1]),
        f(feat0[2]),
        a(feat0[3]),
        f(feat1[0]),
        f(feat1[1]),
        f(feat1[2]),
        a(feat1[3]),
        f64::from(dir[0]),
        f64::from(dir[1]),
        f64::from(dir[2]),
    ]
}

/// For each colour channel, the feature byte to store for each wanted
/// 8-bit level.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourCode {
    /// `byte[channel][level]`, every entry ≥ 1.
    pub byte: [[u8; 256]; 3],
}

impl ColourCode {
    /// The two stored texels of an occupied texel of colour `rgb`.
    #[inline]
    pub fn features(&self, rgb: [u8; 3]) -> ([u8; 4], [u8; 4]) {
        (
            [
                self.byte[0][rgb[0] as usize],
                self.byte[1][rgb[1] as usize],
                self.byte[2][rgb[2] as usize],
                0,
            ],
            [0; 4],
        )
    }
}

/// Logit value the network outputs at byte 1 (−) and 255 (+): sigmoid(7)
/// rounds to level 255, sigmoid(−7) to level 0.
const Y_END: f64 = 7.0;
/// Segments of the piecewise-linear logit (8 hinges).
const SEGMENTS: usize = 9;

/// The piecewise-linear logit: knots in feature space (x = byte/255) and
/// the network's pre-sigmoid output there.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseLogit {
    /// Knot positions, increasing, from 1/255 to 1.
    pub x: [f64; SEGMENTS + 1],
    /// Output at the knots, increasing, from −7 to 7.
    pub y: [f64; SEGMENTS + 1],
    /// Largest growth of the (unrounded) output level per byte step.
    pub max_levels_per_byte: f64,
}

fn dsigmoid(y: f64) -> f64 {
    let s = 1.0 / (1.0 + (-y).exp());
    s * (1.0 - s)
}

/// Upper Riemann sum of sigmoid′ over the segments of `y`: the total
/// "steepness budget" (levels/255) the bytes must pay for.
fn upper_sum(y: &[f64]) -> f64 {
    y.windows(2)
        .map(|w| {
            let peak = if w[0] <= 0.0 && w[1] >= 0.0 {
                0.25
            } else {
                dsigmoid(w[0]).max(dsigmoid(w[1]))
            };
            peak * (w[1] - w[0])
        })
        .sum()
}

/// Symmetric knots in logit space from the half-knots [a, b1, b2, b3].
fn y_knots(h: &[f64; 4]) -> [f64; SEGMENTS + 1] {
    [
        -Y_END, -h[3], -h[2], -h[1], -h[0], h[0], h[1], h[2], h[3], Y_END,
    ]
}

/// Places the knots: logit-space knots minimising the upper Riemann sum of
/// sigmoid′ (coordinate descent from a geometric start), then byte-space
/// widths proportional to each segment's steepness so that every segment
/// reaches the same largest level step per byte.
pub fn piecewise_logit() -> PiecewiseLogit {
    let mut h = [0.8, 2.0, 3.3, 4.9];
    let valid =
        |h: &[f64; 4]| 0.0 < h[0] && h[0] < h[1] && h[1] < h[2] && h[2] < h[3] && h[3] < Y_END;
    let mut best = upper_sum(&y_knots(&h));
    let mut step = 0.25;
    while step > 1e-4 {
        let mut improved = false;
        for i in 0..4 {
            for d in [-step, step] {
                let mut t = h;
                t[i] += d;
                if valid(&t) {
                    let s = upper_sum(&y_knots(&t));
                    if s < best {
                        best = s;
                        h = t;
                        improved = true;
                    }
                }
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    let y = y_knots(&h);
    let (x_lo, x_hi) = (1.0 / 255.0, 1.0);
    let widths: Vec<f64> = y
        .windows(2)
        .map(|w| {
            let peak = if w[0] <= 0.0 && w[1] >= 0.0 {
                0.25
            } else {
                dsigmoid(w[0]).max(dsigmoid(w[1]))
            };
            peak * (w[1] - w[0])
        })
        .collect();
    let total: f64 = widths.iter().sum();
    let mut x = [0f64; SEGMENTS + 1];
    x[0] = x_lo;
    for k in 0..SEGMENTS {
        x[k + 1] = x[k] + (x_hi - x_lo) * widths[k] / total;
    }
    x[SEGMENTS] = x_hi;
    // Level step per byte on the steepest point of a segment:
    // 255·σ′max·Δy / (Δx·255) = σ′max·Δy/Δx; equal on all segments.
    let max_levels_per_byte = total / (x_hi - x_lo);
    PiecewiseLogit {
        x,
        y,
        max_levels_per_byte,
    }
}

/// The analytic MLP realising `pl` on each of feat0's R, G, B.
pub fn network(pl: &PiecewiseLogit) -> MlpWeights {
    let slope: Vec<f64> = (0..SEGMENTS)
        .map(|k| (pl.y[k + 1] - pl.y[k]) / (pl.x[k + 1] - pl.x[k]))
        .collect();
    let mut w = MlpWeights::zero();
    for c in 0..3 {
        let base = 5 * c;
        // Layer 0: u0 = f, u_k = relu(f − x_k), k = 1..4.
        for k in 0..5 {
            w.w0[c][base + k] = 1.0;
            w.b0[base + k] = if k == 0 { 0.0 } else { -pl.x[k] as f32 };
        }
        // Layer 1: v0 = the first four hinges' sum, shifted to be ≥ 0 for
        // f ≥ 1/255: m0·(f − x0) + Σ_{k=1..4} (m_k − m_{k−1})·u_k.
        w.w1[base][base] = slope[0] as f32;
        for k in 1..5 {
            w.w1[base + k][base] = (slope[k] - slope[k - 1]) as f32;
        }
        w.b1[base] = (-slope[0] * pl.x[0]) as f32;
        // v_j = relu(f − x_{4+j}), j = 1..4, from u0 = f.
        for j in 1..5 {
            w.w1[base][base + j] = 1.0;
            w.b1[base + j] = -pl.x[4 + j] as f32;
        }
        // Output: y0 + v0 + Σ_j (m_{4+j} − m_{3+j})·v_j.
        w.w2[base][c] = 1.0;
        for j in 1..5 {
            w.w2[base + j][c] = (slope[4 + j] - slope[3 + j]) as f32;
        }
        w.b2[c] = pl.y[0] as f32;
    }
    w
}

/// The 8-bit colour the shader produces for a texel: the renderer's
/// fixed-point path rounds like this reference to within its stated error.
pub fn shade_reference(mlp: &MlpWeights, feat0: [u8; 4], feat1: [u8; 4], dir: [f32; 3]) -> [u8; 3] {
    let rgb = mlp.eval_f64(&inputs(feat0, feat1, dir));
    rgb.map(|c| (255.0 * c).round().clamp(0.0, 255.0) as u8)
}

/// The code table of `mlp` under `shade`: for each channel and level, the
/// byte in 1..=255 whose shaded level is closest (ties: the smaller byte).
pub fn code_for(mlp: &MlpWeights, shade: impl Fn(&MlpWeights, [u8; 4]) -> [u8; 3]) -> ColourCode {
    let mut out = [[0u8; 256]; 3];
    let mut byte = [[1u8; 256]; 3];
    for b in 1..=255u8 {
        let lv = shade(mlp, [b, b, b, 0]);
        for c in 0..3 {
            out[c][b as usize] = lv[c];
        }
    }
    for (c, table) in byte.iter_mut().enumerate() {
        for (level, slot) in table.iter_mut().enumerate() {
            let mut best = (i32::MAX, 1u8);
            for b in 1..=255u8 {
                let e = (i32::from(out[c][b as usize]) - level as i32).abs();
                if e < best.0 {
                    best = (e, b);
                }
            }
            *slot = best.1;
        }
    }
    ColourCode { byte }
}

/// The baker's MLP and its colour code (data-independent, so it is built
/// once per bake in microseconds).
pub fn design() -> (MlpWeights, ColourCode) {
    let mlp = network(&piecewise_logit());
    let code = code_for(&mlp, |m, f0| {
        shade_reference(m, f0, [0; 4], [0.0, 0.0, 1.0])
    });
    (mlp, code)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_are_increasing_and_steepness_is_bounded() {
        let pl = piecewise_logit();
        assert!(pl.x.windows(2).all(|w| w[0] < w[1]), "{:?}", pl.x);
        assert!(pl.y.windows(2).all(|w| w[0] < w[1]), "{:?}", pl.y);
        // < 3 levels per byte means every level is within 1 of a byte's output.
        assert!(pl.max_levels_per_byte < 2.0, "{}", pl.max_levels_per_byte);
    }

    #[test]
    fn network_follows_the_piecewise_logit() {
        let pl = piecewise_logit();
        let w = network(&pl);
        for k in 0..=SEGMENTS {
            let x = pl.x[k];
            let mut inp = [0f64; INPUTS];
            inp[0] = x;
            inp[1] = x;
            inp[2] = x;
            let rgb = w.eval_f64(&inp);
            let want = 1.0 / (1.0 + (-pl.y[k]).exp());
            for c in rgb {
                assert!((c - want).abs() < 1e-5, "knot {k}: {c} vs {want}");
            }
        }
    }

    #[test]
    fn every_level_is_reproduced_within_one() {
        let (mlp, code) = design();
        for c in 0..3 {
            for level in 0..=255u8 {
                let mut rgb = [128u8; 3];
                rgb[c] = level;
                let (f0, f1) = code.features(rgb);
                assert!(f0[0] >= 1, "occupied texel must have R ≥ 1");
                let out = shade_reference(&mlp, f0, f1, [0.3, -0.5, 0.81]);
                assert!(
                    (i32::from(out[c]) - i32::from(level)).abs() <= 1,
                    "channel {c} level {level} → {}",
                    out[c]
                );
            }
        }
    }
}
