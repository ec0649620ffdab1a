//! The narrow shader: the same MLP with 16-bit weights and activations and
//! 32-bit accumulators — the form DSP extensions (`SMLAD`: two 16 × 16
//! multiply-adds per instruction) and SIMD units (`vpmaddwd`) run.
//!
//! ## Format
//! - Every activation is an `i16`, stored in pairs: one `u32` holds input
//!   `2p` in its low half and `2p + 1` in its high half, as `SMLAD` reads
//!   them. Weights are stored the same way, output-major (`w[o][p]`).
//! - Inputs: a feature byte `t` enters as `t << 7` (exact; the alpha
//!   decoding `2t/255 − 1` is folded into the weights and the bias), a
//!   direction component as the top 16 bits of its Q2.30 value.
//! - Each output `o` of a layer has its own accumulator scale `S_o`
//!   (any real number, not a power of two): weights are
//!   `round(W · S_o / s_in)`, the bias `round(b · S_o) + 2¹⁵`, and a hidden
//!   activation is `clamp(acc >> 16, 0, 2¹⁵ − 1)` (ReLU and rounding in one
//!   `USAT`); its scale is `S_o / 2¹⁶`. `S_o` is the largest scale for which
//!   every weight fits the chosen width and the accumulator cannot exceed
//!   `i32` for any input, so nothing saturates or wraps.
//! - The logits' scales are powers of two, `2^(24 + logit_shift)`, shifted
//!   to Q24 and rounded to 8 bits by the exact threshold sigmoid.
//!
//! Every accumulation is `wrapping` `i32` arithmetic, which is what `SMLAD`
//! and `vpmaddwd` + `vpaddd` compute; sums mod 2³² do not depend on order,
//! so the portable code, the `SMLAD` path and the batched SIMD path
//! ([`batch`]) give bit-identical results on every target.
//!
//! Whether a weight set may use this shader is decided by measuring its
//! error against the `f64` reference ([`NarrowMlp::choose`]): the same
//! criterion as the accuracy test (≥ 99.9 % of outputs within one 8-bit
//! step, none beyond two).

pub mod batch;
mod quantize;

use super::{sigmoid_u8, ViewDir, HIDDEN, OUTPUTS};
use core::fmt;

pub use quantize::{check_samples, ErrorHistogram, WeightBits};

/// Input pairs of the first layer: features (r, b), (g, a) of each texel,
/// then (dx, dy) and (dz, 0).
pub const INPUT_PAIRS: usize = 6;
/// Pairs of a hidden layer's 16 activations.
pub const HIDDEN_PAIRS: usize = HIDDEN / 2;
/// The inputs (indices into the 11-vector) each input pair carries.
pub const INPUT_PAIR_INDICES: [[Option<usize>; 2]; INPUT_PAIRS] = [
    [Some(0), Some(2)],
    [Some(1), Some(3)],
    [Some(4), Some(6)],
    [Some(5), Some(7)],
    [Some(8), Some(9)],
    [Some(10), None],
];
/// Multiply-adds the narrow shader executes per pixel, padding included:
/// 2 · (6·16 + 8·16 + 8·3) = 496 (480 of them useful).
pub const NARROW_MACS_PER_PIXEL: usize =
    2 * (INPUT_PAIRS * HIDDEN + HIDDEN_PAIRS * HIDDEN + HIDDEN_PAIRS * OUTPUTS);

/// One layer: `acc[o] = bias[o] + Σ_p lo(x_p)·lo(w[o][p]) + hi(x_p)·hi(w[o][p])`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NarrowLayer<const P: usize, const O: usize> {
    /// Packed weight pairs, output-major: low half for input `2p`.
    pub w: [[u32; P]; O],
    /// Bias at the accumulator's scale, rounding offset included.
    pub bias: [i32; O],
}

/// The narrow MLP: plain integer tables (see [`NarrowMlp::write_rust`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NarrowMlp {
    /// 11 (6 pairs) → 16, ReLU.
    pub l0: NarrowLayer<INPUT_PAIRS, HIDDEN>,
    /// 16 (8 pairs) → 16, ReLU.
    pub l1: NarrowLayer<HIDDEN_PAIRS, HIDDEN>,
    /// 16 (8 pairs) → 3, sigmoid.
    pub l2: NarrowLayer<HIDDEN_PAIRS, OUTPUTS>,
    /// Logit `o` is `acc >> logit_shift[o]` in Q24 (a negative value
    /// shifts left, saturating).
    pub logit_shift: [i8; OUTPUTS],
    /// Largest weight magnitude allowed when the tables were built (127 or 32767).
    pub weight_max: i16,
}

/// `acc + lo(x)·lo(w) + hi(x)·hi(w)` on signed 16-bit halves, mod 2³².
///
/// On ARMv7E-M this is one `SMLAD`; elsewhere [`dual_mac_portable`].
#[inline(always)]
pub fn dual_mac(acc: i32, x: u32, w: u32) -> i32 {
    #[cfg(nerflex_smlad)]
    {
        smlad(acc, x, w)
    }
    #[cfg(not(nerflex_smlad))]
    {
        dual_mac_portable(acc, x, w)
    }
}

/// The portable definition of [`dual_mac`] (what `SMLAD` computes).
#[inline(always)]
pub fn dual_mac_portable(acc: i32, x: u32, w: u32) -> i32 {
    let lo = i32::from(x as u16 as i16) * i32::from(w as u16 as i16);
    let hi = i32::from((x >> 16) as u16 as i16) * i32::from((w >> 16) as u16 as i16);
    acc.wrapping_add(lo).wrapping_add(hi)
}

/// `SMLAD`: stable inline assembly (the `core::arch::arm` intrinsic is
/// unstable). Reads and writes registers only.
#[cfg(nerflex_smlad)]
#[allow(unsafe_code)]
#[inline(always)]
fn smlad(acc: i32, x: u32, w: u32) -> i32 {
    let out: i32;
    // SAFETY: a pure register operation, defined for every input; it sets
    // only the Q flag, which nothing reads.
    unsafe {
        core::arch::asm!(
            "smlad {out}, {x}, {w}, {acc}",
            out = lateout(reg) out,
            x = in(reg) x,
            w = in(reg) w,
            acc = in(reg) acc,
            options(pure, nomem, nostack),
        );
    }
    out
}

impl<const P: usize, const O: usize> NarrowLayer<P, O> {
    /// The accumulators.
    #[inline(always)]
    pub fn accumulate(&self, x: &[u32; P]) -> [i32; O] {
        let mut out = self.bias;
        for (a, row) in out.iter_mut().zip(self.w.iter()) {
            let mut s = *a;
            for (&xp, &wp) in x.iter().zip(row.iter()) {
                s = dual_mac(s, xp, wp);
            }
            *a = s;
        }
        out
    }
}

/// ReLU of one accumulator into an activation: `clamp(acc >> 16, 0, 2¹⁵ − 1)`.
#[inline(always)]
pub fn relu16(acc: i32) -> u32 {
    (acc >> 16).clamp(0, 0x7FFF) as u32
}

/// ReLU and packing of a hidden layer's accumulators into pairs.
#[inline(always)]
fn relu_pack(acc: &[i32; HIDDEN]) -> [u32; HIDDEN_PAIRS] {
    let mut out = [0u32; HIDDEN_PAIRS];
    for (o, pair) in out.iter_mut().zip(acc.chunks_exact(2)) {
        if let &[a, b] = pair {
            *o = relu16(a) | (relu16(b) << 16);
        }
    }
    out
}

/// The first layer's input pairs (see the module documentation).
#[inline(always)]
pub fn input_pairs(feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [u32; INPUT_PAIRS] {
    let f0 = u32::from_le_bytes(feat0);
    let f1 = u32::from_le_bytes(feat1);
    // Bytes 0 and 2 (r, b), then 1 and 3 (g, a), each `t << 7` in its half.
    let even = |f: u32| (f & 0x00FF_00FF) << 7;
    let odd = |f: u32| ((f >> 8) & 0x00FF_00FF) << 7;
    let [dx, dy, dz] = dir.bits();
    [
        even(f0),
        odd(f0),
        even(f1),
        odd(f1),
        ((dx as u32) >> 16) | ((dy as u32) & 0xFFFF_0000),
        (dz as u32) >> 16,
    ]
}

/// A logit accumulator in Q24: `acc >> shift`, or a saturating left shift.
#[inline(always)]
pub fn logit_q24(acc: i32, shift: i8) -> i32 {
    if shift >= 0 {
        acc >> shift.unsigned_abs().min(31)
    } else {
        let s = u32::from(shift.unsigned_abs().min(31));
        (i64::from(acc) << s).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
    }
}

impl NarrowMlp {
    /// The logit accumulators from the first layer's input pairs.
    #[inline(always)]
    pub fn logit_acc(&self, x: &[u32; INPUT_PAIRS]) -> [i32; OUTPUTS] {
        let h1 = relu_pack(&self.l0.accumulate(x));
        let h2 = relu_pack(&self.l1.accumulate(&h1));
        self.l2.accumulate(&h2)
    }

    /// The three output logits in Q24.
    pub fn logits_q24(&self, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [i32; OUTPUTS] {
        let z = self.logit_acc(&input_pairs(feat0, feat1, dir));
        let mut out = [0i32; OUTPUTS];
        for ((o, &a), &s) in out.iter_mut().zip(z.iter()).zip(self.logit_shift.iter()) {
            *o = logit_q24(a, s);
        }
        out
    }

    /// Shades one texel: 8-bit RGB. Integers only; never panics.
    ///
    /// Not `#[inline]`: compiled once, in this crate, at its optimisation level.
    pub fn shade(&self, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [u8; 3] {
        self.logits_q24(feat0, feat1, dir).map(sigmoid_u8)
    }

    /// Writes `pub const NAME: NarrowMlp = NarrowMlp { … };` (paths assume
    /// `NarrowMlp` and `NarrowLayer` are in scope).
    pub fn write_rust(&self, out: &mut impl fmt::Write, name: &str) -> fmt::Result {
        writeln!(out, "pub const {name}: NarrowMlp = NarrowMlp {{")?;
        write_layer(out, "l0", &self.l0)?;
        write_layer(out, "l1", &self.l1)?;
        write_layer(out, "l2", &self.l2)?;
        let [a, b, c] = self.logit_shift;
        writeln!(out, "    logit_shift: [{a}, {b}, {c}],")?;
        writeln!(out, "    weight_max: {},", self.weight_max)?;
        writeln!(out, "}};")
    }
}

fn write_layer<const P: usize, const O: usize>(
    out: &mut impl fmt::Write,
    name: &str,
    l: &NarrowLayer<P, O>,
) -> fmt::Result {
    writeln!(out, "    {name}: NarrowLayer {{")?;
    writeln!(out, "        w: [")?;
    for row in &l.w {
        write!(out, "            [")?;
        for v in row {
            write!(out, "{v:#010x}, ")?;
        }
        writeln!(out, "],")?;
    }
    writeln!(out, "        ],")?;
    write!(out, "        bias: [")?;
    for v in &l.bias {
        write!(out, "{v}, ")?;
    }
    writeln!(out, "],")?;
    writeln!(out, "    }},")
}

#[cfg(test)]
mod tests;
