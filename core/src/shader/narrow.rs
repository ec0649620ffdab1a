//! The narrow shader: the same MLP with 16-bit weights and activations and
//! 32-bit accumulators — the form DSP extensions (`SMLAD`: two 16 × 16
//! multiply-adds per instruction) and SIMD units (`vpmaddwd`) run.
//!
//! ## Format
//! - Every activation is an `i16`, stored in pairs: one `u32` holds input
//!   `2p` in its low half and `2p + 1` in its high half, as `SMLAD` reads
//!   them. Weights are stored the same way, in the order the shader reads
//!   them: groups of `G` outputs, then input pairs, then the group's
//!   outputs (`w[n][p][g]` is output `n·G + g`), so a core can load a
//!   group's weights for one input pair with one `LDM` and keep `G`
//!   accumulators and one input pair in registers.
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
//! - The logits share one power-of-two scale, `2^(24 − logit_lshift)` (at
//!   most Q24), shifted left to Q24 (clamped first: a clamped logit is
//!   beyond ±64, where the 8-bit sigmoid is 0 or 255) and rounded to 8 bits
//!   by the exact threshold sigmoid (a bucketed form of the same table).
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

use super::{ViewDir, HIDDEN, OUTPUTS, THRESHOLDS_Q24};
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

/// One layer of `N · G` outputs in `N` groups of `G`: output `o = n·G + g`
/// is `bias[n][g] + Σ_p lo(x_p)·lo(w[n][p][g]) + hi(x_p)·hi(w[n][p][g])`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NarrowLayer<const P: usize, const G: usize, const N: usize> {
    /// Packed weight pairs (low half for input `2p`), group-major.
    pub w: [[[u32; G]; P]; N],
    /// Bias at the accumulator's scale, rounding offset included.
    pub bias: [[i32; G]; N],
}

/// Outputs per group of a hidden layer.
pub const GROUP: usize = 4;
/// Groups of a hidden layer.
pub const HIDDEN_GROUPS: usize = HIDDEN / GROUP;

/// The narrow MLP: plain integer tables (see [`NarrowMlp::write_rust`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NarrowMlp {
    /// 11 (6 pairs) → 16, ReLU.
    pub l0: NarrowLayer<INPUT_PAIRS, GROUP, HIDDEN_GROUPS>,
    /// 16 (8 pairs) → 16, ReLU.
    pub l1: NarrowLayer<HIDDEN_PAIRS, GROUP, HIDDEN_GROUPS>,
    /// 16 (8 pairs) → 3 (one group), sigmoid.
    pub l2: NarrowLayer<HIDDEN_PAIRS, OUTPUTS, 1>,
    /// A logit in Q24 is `acc << logit_lshift`, `acc` clamped first (one
    /// scale for all three: one clamp bound, one shift).
    pub logit_lshift: u8,
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

impl<const P: usize, const G: usize, const N: usize> NarrowLayer<P, G, N> {
    /// The accumulators of group `n` (zeros if `n` is out of range).
    #[inline(always)]
    pub fn group(&self, n: usize, x: &[u32; P]) -> [i32; G] {
        match (self.w.get(n), self.bias.get(n)) {
            (Some(w), Some(b)) => group_dot(b, w, x),
            _ => [0; G],
        }
    }
}

/// One group's accumulators: per input pair, `G` dual multiply-adds.
#[inline(always)]
fn group_dot<const P: usize, const G: usize>(
    b: &[i32; G],
    w: &[[u32; G]; P],
    x: &[u32; P],
) -> [i32; G] {
    let mut acc = *b;
    for (&xp, wp) in x.iter().zip(w.iter()) {
        for (a, &wv) in acc.iter_mut().zip(wp.iter()) {
            *a = dual_mac(*a, xp, wv);
        }
    }
    acc
}

/// ReLU of one accumulator into an activation: `clamp(acc >> 16, 0, 2¹⁵ − 1)`
/// (one `USAT` on ARMv7E-M).
#[inline(always)]
pub fn relu16(acc: i32) -> u32 {
    #[cfg(nerflex_smlad)]
    {
        usat15_asr16(acc)
    }
    #[cfg(not(nerflex_smlad))]
    {
        (acc >> 16).clamp(0, 0x7FFF) as u32
    }
}

/// `USAT rd, #15, rn, ASR #16`: the portable `relu16` in one instruction.
#[cfg(nerflex_smlad)]
#[allow(unsafe_code)]
#[inline(always)]
fn usat15_asr16(acc: i32) -> u32 {
    let out: u32;
    // SAFETY: a pure register operation, defined for every input.
    unsafe {
        core::arch::asm!(
            "usat {out}, #15, {acc}, asr #16",
            out = lateout(reg) out,
            acc = in(reg) acc,
            options(pure, nomem, nostack),
        );
    }
    out
}

/// `group_dot` for groups of 4 (hidden layers): on ARMv7E-M one `LDM` of
/// the group's four weights and four `SMLAD`s per input pair.
#[inline(always)]
fn group4<const P: usize>(b: &[i32; 4], w: &[[u32; 4]; P], x: &[u32; P]) -> [i32; 4] {
    #[cfg(nerflex_smlad)]
    {
        dsp::group4(b, w, x)
    }
    #[cfg(not(nerflex_smlad))]
    {
        group_dot(b, w, x)
    }
}

/// `group_dot` for the 3 logits.
#[inline(always)]
fn group3<const P: usize>(b: &[i32; 3], w: &[[u32; 3]; P], x: &[u32; P]) -> [i32; 3] {
    #[cfg(nerflex_smlad)]
    {
        dsp::group3(b, w, x)
    }
    #[cfg(not(nerflex_smlad))]
    {
        group_dot(b, w, x)
    }
}

/// The ARMv7E-M group kernels: the compiler does not keep a group's
/// accumulators in registers while streaming its weights with `LDM`, so
/// each input pair is one small assembly block. Same sums as `group_dot`.
#[cfg(nerflex_smlad)]
#[allow(unsafe_code)]
mod dsp {
    use core::arch::asm;

    #[inline(always)]
    pub fn group4<const P: usize>(b: &[i32; 4], w: &[[u32; 4]; P], x: &[u32; P]) -> [i32; 4] {
        let [mut a0, mut a1, mut a2, mut a3] = *b;
        let mut wp = w.as_ptr().cast::<u32>();
        for &xv in x {
            // SAFETY: reads the four words at `wp` (row `p` of `w`; the
            // loop runs P times, 16 bytes each) and advances `wp` past them.
            unsafe {
                asm!(
                    "ldm {wp}!, {{r0, r1, r2, r3}}",
                    "smlad {a0}, {x}, r0, {a0}",
                    "smlad {a1}, {x}, r1, {a1}",
                    "smlad {a2}, {x}, r2, {a2}",
                    "smlad {a3}, {x}, r3, {a3}",
                    wp = inout(reg) wp,
                    x = in(reg) xv,
                    a0 = inout(reg) a0,
                    a1 = inout(reg) a1,
                    a2 = inout(reg) a2,
                    a3 = inout(reg) a3,
                    out("r0") _,
                    out("r1") _,
                    out("r2") _,
                    out("r3") _,
                    options(pure, readonly, nostack),
                );
            }
        }
        [a0, a1, a2, a3]
    }

    #[inline(always)]
    pub fn group3<const P: usize>(b: &[i32; 3], w: &[[u32; 3]; P], x: &[u32; P]) -> [i32; 3] {
        let [mut a0, mut a1, mut a2] = *b;
        let mut wp = w.as_ptr().cast::<u32>();
        for &xv in x {
            // SAFETY: reads the three words of row `p` of `w` (12 bytes,
            // P times) and advances `wp` past them.
            unsafe {
                asm!(
                    "ldm {wp}!, {{r0, r1, r2}}",
                    "smlad {a0}, {x}, r0, {a0}",
                    "smlad {a1}, {x}, r1, {a1}",
                    "smlad {a2}, {x}, r2, {a2}",
                    wp = inout(reg) wp,
                    x = in(reg) xv,
                    a0 = inout(reg) a0,
                    a1 = inout(reg) a1,
                    a2 = inout(reg) a2,
                    out("r0") _,
                    out("r1") _,
                    out("r2") _,
                    options(pure, readonly, nostack),
                );
            }
        }
        [a0, a1, a2]
    }
}

/// A hidden layer: each group's sums, ReLU and packing in one pass.
#[inline(always)]
fn hidden<const P: usize>(
    l: &NarrowLayer<P, GROUP, HIDDEN_GROUPS>,
    x: &[u32; P],
) -> [u32; HIDDEN_PAIRS] {
    let mut out = [0u32; HIDDEN_PAIRS];
    for (o, (w, b)) in out.chunks_exact_mut(2).zip(l.w.iter().zip(l.bias.iter())) {
        let [a0, a1, a2, a3] = group4(b, w, x);
        if let [p0, p1] = o {
            *p0 = relu16(a0) | (relu16(a1) << 16);
            *p1 = relu16(a2) | (relu16(a3) << 16);
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

/// Lower end of the bucketed sigmoid's range (Q24, −8): every threshold is above it.
const SIG_LO: i32 = -(1 << 27);
/// Bucket width (Q24): narrower than the closest two thresholds (263 177).
const SIG_BUCKET_LOG2: u32 = 18;
/// Buckets over `[−8, 8)`.
const SIG_BUCKETS: usize = 1 << (28 - SIG_BUCKET_LOG2);

/// `SIG_BASE[b]`: thresholds below bucket `b`'s start (at most one more
/// lies inside the bucket).
// Indexing in a const initialiser fails the build, never a run.
#[allow(clippy::indexing_slicing)]
const SIG_BASE: [u8; SIG_BUCKETS] = {
    let mut t = [0u8; SIG_BUCKETS];
    let (mut b, mut k) = (0usize, 0usize);
    while b < SIG_BUCKETS {
        let start = SIG_LO + ((b as i32) << SIG_BUCKET_LOG2);
        while k < THRESHOLDS_Q24.len() && THRESHOLDS_Q24[k] < start {
            k += 1;
        }
        t[b] = k as u8;
        b += 1;
    }
    t
};

/// The thresholds and a sentinel no bucketed `z` reaches.
#[allow(clippy::indexing_slicing)]
const SIG_NEXT: [i32; 256] = {
    let mut t = [i32::MAX; 256];
    let mut k = 0;
    while k < THRESHOLDS_Q24.len() {
        t[k] = THRESHOLDS_Q24[k];
        k += 1;
    }
    t
};

/// [`sigmoid_u8`](crate::shader::sigmoid_u8) in constant time: a bucket table gives the count of
/// thresholds below the bucket, one comparison adds the bucket's own.
/// Equal to `sigmoid_u8` for every `z` (checked exhaustively in the tests).
#[inline(always)]
pub fn sigmoid_bucketed(z: i32) -> u8 {
    // Below −8 every threshold is above z, from +8 on every one is below:
    // clamping there (one `SSAT` on ARM) changes no count.
    let zc = z.clamp(SIG_LO, -SIG_LO - 1);
    let bucket = ((zc >> SIG_BUCKET_LOG2) + (SIG_BUCKETS as i32 / 2)) as usize;
    let base = SIG_BASE.get(bucket).copied().unwrap_or(0);
    let next = SIG_NEXT.get(usize::from(base)).copied().unwrap_or(i32::MAX);
    base.wrapping_add(u8::from(next <= zc))
}

/// A logit accumulator in Q24: `acc << lshift`, `acc` first clamped so the
/// shift cannot overflow (a clamped logit is beyond ±64, where the 8-bit
/// sigmoid is 0 or 255). Shifts are taken mod 32 (tables from
/// `from_weights` never exceed 31).
#[inline(always)]
pub fn logit_q24(acc: i32, lshift: u8) -> i32 {
    let s = u32::from(lshift & 31);
    let lim = i32::MAX >> s;
    acc.clamp(-lim - 1, lim) << s
}

impl NarrowMlp {
    /// The logit accumulators from the first layer's input pairs.
    #[inline(always)]
    pub fn logit_acc(&self, x: &[u32; INPUT_PAIRS]) -> [i32; OUTPUTS] {
        let h1 = hidden(&self.l0, x);
        let h2 = hidden(&self.l1, &h1);
        match (self.l2.w.first(), self.l2.bias.first()) {
            (Some(w), Some(b)) => group3(b, w, &h2),
            _ => [0; OUTPUTS],
        }
    }

    /// The three output logits in Q24.
    pub fn logits_q24(&self, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [i32; OUTPUTS] {
        let z = self.logit_acc(&input_pairs(feat0, feat1, dir));
        let mut out = [0i32; OUTPUTS];
        for (o, &a) in out.iter_mut().zip(z.iter()) {
            *o = logit_q24(a, self.logit_lshift);
        }
        out
    }

    /// Shades one texel: 8-bit RGB. Integers only; never panics.
    ///
    /// Not `#[inline]`: compiled once, in this crate, at its optimisation level.
    pub fn shade(&self, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) -> [u8; 3] {
        let [r, g, b] = self.logits_q24(feat0, feat1, dir);
        [
            sigmoid_bucketed(r),
            sigmoid_bucketed(g),
            sigmoid_bucketed(b),
        ]
    }

    /// Writes `pub const NAME: NarrowMlp = NarrowMlp { … };` (paths assume
    /// `NarrowMlp` and `NarrowLayer` are in scope).
    pub fn write_rust(&self, out: &mut impl fmt::Write, name: &str) -> fmt::Result {
        writeln!(out, "pub const {name}: NarrowMlp = NarrowMlp {{")?;
        write_layer(out, "l0", &self.l0)?;
        write_layer(out, "l1", &self.l1)?;
        write_layer(out, "l2", &self.l2)?;
        writeln!(out, "    logit_lshift: {},", self.logit_lshift)?;
        writeln!(out, "    weight_max: {},", self.weight_max)?;
        writeln!(out, "}};")
    }
}

fn write_layer<const P: usize, const G: usize, const N: usize>(
    out: &mut impl fmt::Write,
    name: &str,
    l: &NarrowLayer<P, G, N>,
) -> fmt::Result {
    writeln!(out, "    {name}: NarrowLayer {{")?;
    writeln!(out, "        w: [")?;
    for group in &l.w {
        writeln!(out, "            [")?;
        for pair in group {
            write!(out, "                [")?;
            for v in pair {
                write!(out, "{v:#010x}, ")?;
            }
            writeln!(out, "],")?;
        }
        writeln!(out, "            ],")?;
    }
    writeln!(out, "        ],")?;
    write!(out, "        bias: [")?;
    for group in &l.bias {
        write!(out, "[")?;
        for v in group {
            write!(out, "{v}, ")?;
        }
        write!(out, "], ")?;
    }
    writeln!(out, "],")?;
    writeln!(out, "    }},")
}

#[cfg(test)]
mod tests;
