//! The narrow shader on [`LANES`] pixels at a time: portable, and with AVX2
//! on x86-64 (`vpmaddwd` is `SMLAD` on eight lanes). Both give exactly the
//! per-pixel [`NarrowMlp::shade`] result (same wrapping `i32` sums, same
//! shifts, the same threshold count for the sigmoid).

use super::{input_pairs, logit_q24, sigmoid_bucketed, NarrowMlp, INPUT_PAIRS};
use crate::shader::{ViewDir, OUTPUTS};

/// Pixels per batch (one AVX2 register of `i32`).
pub const LANES: usize = 8;

/// The first layer's input pairs of [`LANES`] pixels, pair-major:
/// `x[p][lane]`.
pub type BatchInput = [[u32; LANES]; INPUT_PAIRS];

/// Puts pixel `lane`'s inputs into a batch.
#[inline(always)]
pub fn set_lane(x: &mut BatchInput, lane: usize, feat0: [u8; 4], feat1: [u8; 4], dir: ViewDir) {
    for (row, v) in x.iter_mut().zip(input_pairs(feat0, feat1, dir)) {
        if let Some(slot) = row.get_mut(lane) {
            *slot = v;
        }
    }
}

/// Portable batch: the per-pixel shader on each lane.
pub fn shade_portable(m: &NarrowMlp, x: &BatchInput) -> [[u8; OUTPUTS]; LANES] {
    let mut out = [[0u8; OUTPUTS]; LANES];
    for (lane, o) in out.iter_mut().enumerate() {
        let mut xl = [0u32; INPUT_PAIRS];
        for (d, row) in xl.iter_mut().zip(x.iter()) {
            *d = row.get(lane).copied().unwrap_or(0);
        }
        let z = m.logit_acc(&xl);
        for (c, &a) in o.iter_mut().zip(z.iter()) {
            *c = sigmoid_bucketed(logit_q24(a, m.logit_lshift));
        }
    }
    out
}

/// The AVX2 batch (x86-64 only; the caller checks the CPU).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
pub mod avx2 {
    use super::{BatchInput, LANES};
    use crate::shader::narrow::{NarrowLayer, NarrowMlp, GROUP, HIDDEN_PAIRS, INPUT_PAIRS};
    use crate::shader::{HIDDEN, OUTPUTS, THRESHOLDS_Q24};
    use core::arch::x86_64::*;

    /// [`super::shade_portable`] with AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
    #[target_feature(enable = "avx2")]
    pub unsafe fn shade(m: &NarrowMlp, x: &BatchInput) -> [[u8; OUTPUTS]; LANES] {
        let mut xv = [_mm256_setzero_si256(); INPUT_PAIRS];
        for (v, row) in xv.iter_mut().zip(x.iter()) {
            // SAFETY: `row` is 32 readable bytes; unaligned load.
            *v = unsafe { _mm256_loadu_si256(row.as_ptr().cast()) };
        }
        let h1 = relu_pack(&layer::<INPUT_PAIRS, GROUP, 4, HIDDEN>(&m.l0, &xv));
        let h2 = relu_pack(&layer::<HIDDEN_PAIRS, GROUP, 4, HIDDEN>(&m.l1, &h1));
        let z = layer::<HIDDEN_PAIRS, OUTPUTS, 1, OUTPUTS>(&m.l2, &h2);
        let mut rgb = [[0u8; OUTPUTS]; LANES];
        let s = i32::from(m.logit_lshift & 31);
        let lim = _mm256_set1_epi32(i32::MAX >> s);
        let low = _mm256_set1_epi32(-(i32::MAX >> s) - 1);
        for (c, &zc) in z.iter().enumerate() {
            let clamped = _mm256_max_epi32(_mm256_min_epi32(zc, lim), low);
            let q = _mm256_sll_epi32(clamped, _mm_cvtsi32_si128(s));
            let k = sigmoid(q);
            let mut ks = [0i32; LANES];
            // SAFETY: `ks` is 32 writable bytes.
            unsafe { _mm256_storeu_si256(ks.as_mut_ptr().cast(), k) };
            for (px, kv) in rgb.iter_mut().zip(ks) {
                if let Some(slot) = px.get_mut(c) {
                    *slot = kv as u8; // a count of 0..=255 thresholds
                }
            }
        }
        rgb
    }

    #[target_feature(enable = "avx2")]
    fn layer<const P: usize, const G: usize, const N: usize, const O: usize>(
        l: &NarrowLayer<P, G, N>,
        x: &[__m256i; P],
    ) -> [__m256i; O] {
        let mut out = [_mm256_setzero_si256(); O];
        for (accs, (w, b)) in out.chunks_mut(G).zip(l.w.iter().zip(l.bias.iter())) {
            for (g, (acc, &bg)) in accs.iter_mut().zip(b.iter()).enumerate() {
                let mut a = _mm256_set1_epi32(bg);
                for (&xp, wp) in x.iter().zip(w.iter()) {
                    let wv = wp.get(g).copied().unwrap_or(0);
                    a = _mm256_add_epi32(a, _mm256_madd_epi16(xp, _mm256_set1_epi32(wv as i32)));
                }
                *acc = a;
            }
        }
        out
    }

    /// `clamp(acc >> 16, 0, 2¹⁵ − 1)` (the upper clamp never binds after
    /// an arithmetic shift by 16) and packing of pairs.
    #[target_feature(enable = "avx2")]
    fn relu_pack(acc: &[__m256i; HIDDEN]) -> [__m256i; HIDDEN_PAIRS] {
        let zero = _mm256_setzero_si256();
        let mut out = [zero; HIDDEN_PAIRS];
        for (o, pair) in out.iter_mut().zip(acc.chunks_exact(2)) {
            if let &[a, b] = pair {
                let lo = _mm256_max_epi32(_mm256_srai_epi32::<16>(a), zero);
                let hi = _mm256_max_epi32(_mm256_srai_epi32::<16>(b), zero);
                *o = _mm256_or_si256(lo, _mm256_slli_epi32::<16>(hi));
            }
        }
        out
    }

    /// The number of thresholds ≤ z per lane: a branchless binary search
    /// (the table is strictly ascending, 255 = 2⁸ − 1 entries).
    #[target_feature(enable = "avx2")]
    fn sigmoid(z: __m256i) -> __m256i {
        let mut k = _mm256_setzero_si256();
        let mut step = 128;
        while step > 0 {
            let idx = _mm256_add_epi32(k, _mm256_set1_epi32(step - 1));
            // SAFETY: k + step − 1 ≤ 254 for every lane (k ≤ 255 − 2·step),
            // inside the 255-entry table.
            let t = unsafe { _mm256_i32gather_epi32::<4>(THRESHOLDS_Q24.as_ptr(), idx) };
            let above = _mm256_cmpgt_epi32(t, z);
            k = _mm256_add_epi32(k, _mm256_andnot_si256(above, _mm256_set1_epi32(step)));
            step /= 2;
        }
        k
    }
}
