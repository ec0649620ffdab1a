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

use nerflex_core::shader::{shade_f64, FixedMlp, ViewDir};
pub use nerflex_core::shader::{MlpWeights, HIDDEN, INPUTS};

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
pub const SEGMENTS: usize = 9;

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
    let mut w = MlpWeights::ZERO;
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

/// The code table of `mlp` under `shade` (feat0 → 8-bit RGB): for each
/// channel and level, the byte in 1..=255 whose shaded level is closest
/// (ties: the smaller byte).
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

/// The direction used while building the code table (the network ignores
/// the direction: its weights are zero).
const ANY_DIR: [f64; 3] = [0.0, 0.0, -1.0];

/// The baker's MLP and its colour code, built for the renderer's
/// fixed-point shader ([`FixedMlp`]); data-independent, so it costs
/// microseconds per bake.
pub fn design() -> (MlpWeights, ColourCode) {
    let mlp = network(&piecewise_logit());
    let code = match (FixedMlp::from_weights(&mlp), ViewDir::from_f64(ANY_DIR)) {
        (Ok(fixed), Some(dir)) => code_for(&mlp, |_, f0| fixed.shade(f0, [0; 4], dir)),
        // Cannot happen for these bounded weights; the f64 reference is
        // then the best available target.
        _ => code_for(&mlp, |m, f0| shade_f64(m, f0, [0; 4], ANY_DIR)),
    };
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
            let rgb = nerflex_core::shader::mlp_f64(&w, &inp);
            let want = 1.0 / (1.0 + (-pl.y[k]).exp());
            for c in rgb {
                assert!((c - want).abs() < 1e-5, "knot {k}: {c} vs {want}");
            }
        }
    }

    #[test]
    fn every_level_is_reproduced_within_one_by_both_shaders() {
        let (mlp, code) = design();
        let fixed = FixedMlp::from_weights(&mlp).unwrap();
        let dir = [0.3, -0.5, 0.81];
        let qdir = ViewDir::from_f64(dir).unwrap();
        for c in 0..3 {
            for level in 0..=255u8 {
                let mut rgb = [128u8; 3];
                rgb[c] = level;
                let (f0, f1) = code.features(rgb);
                assert!(f0[0] >= 1, "occupied texel must have R ≥ 1");
                for out in [fixed.shade(f0, f1, qdir), shade_f64(&mlp, f0, f1, dir)] {
                    assert!(
                        (i32::from(out[c]) - i32::from(level)).abs() <= 1,
                        "channel {c} level {level} → {}",
                        out[c]
                    );
                }
            }
        }
    }
}
