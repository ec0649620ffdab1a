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
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::time::Instant;

use super::featgrid::Taps;
use super::gbuffer::{covered, Subsamples, SUBSAMPLES};
use super::net::{self, Adam, LaneGrads, FEATURES, LANES};
use crate::prefetch::prefetch;
use nerflex_core::shader::MlpWeights;
use nerflex_core::shader::{INPUTS, OUTPUTS};

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
#[derive(Clone, Copy, PartialEq)]
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
    /// Pixels per run of the order: the shuffle permutes runs of this many
    /// consecutive training pixels (neighbours in one view's tile, which
    /// share lattice vertices and lie side by side in memory) instead of
    /// single pixels; 1: every pixel on its own (the default).
    pub run: u32,
}

impl Default for FinetuneSettings {
    fn default() -> Self {
        Self {
            // 3 until baker version 11, with one visibility round.
            epochs: 2.5,
            batch: 8192,
            // 0.03 until baker version 10 (docs/baking.md, "Session 29").
            lr_features: 0.015,
            lr_mlp: 3e-3,
            seed: 7,
            run: 1,
        }
    }
}

/// Debug as derived, `run` left out at its default 1: the bake store keys
/// trained bakes by their settings' Debug text, and those made before
/// `run` existed keep their keys.
impl std::fmt::Debug for FinetuneSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("FinetuneSettings");
        d.field("epochs", &self.epochs)
            .field("batch", &self.batch)
            .field("lr_features", &self.lr_features)
            .field("lr_mlp", &self.lr_mlp)
            .field("seed", &self.seed);
        if self.run != 1 {
            d.field("run", &self.run);
        }
        d.finish()
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

/// One vertex's Adam moments, a cache line (rarely reached vertices keep
/// their own β₁ᵗ, β₂ᵗ beside, so they are not under-corrected).
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Moments {
    m: [f32; FEATURES],
    v: [f32; FEATURES],
}

/// Pixels per parallel piece of a batch.
const CHUNK: usize = 512;
/// Bits of an [`Entry::item`] that index a chunk's items (a pixel has at
/// most [`SUBSAMPLES`] items).
const ITEM_BITS: u32 = 12;
const _: () = assert!(CHUNK * SUBSAMPLES <= 1 << ITEM_BITS);
/// The largest batch [`Entry::item`] can number.
const MAX_BATCH: usize = CHUNK << (32 - ITEM_BITS);
/// About how many vertex ranges the optimiser step is split into (each
/// range's gradients are summed and stepped on one core).
const PARTS: usize = 64;

/// One vertex's share of one item's feature gradient (an item: a shown
/// texel of a batch pixel): vertex `v` gets `w` × the item's gradient.
#[derive(Clone, Copy)]
struct Entry {
    /// Vertex slot.
    v: u32,
    /// Chunk (high bits) and item within the chunk ([`ITEM_BITS`]).
    item: u32,
    /// Trilinear weight.
    w: f32,
}

/// A chunk's working memory, kept across steps.
struct ChunkScratch {
    /// Per pixel: the quantised features.
    feats: Vec<[f32; FEATURES]>,
    /// Per item: ∂loss/∂(its features).
    df: Vec<[f32; FEATURES]>,
    /// Per vertex range: the entries of the chunk's items.
    buckets: Vec<Vec<Entry>>,
    /// The MLP gradient, summed per lane.
    lanes: Box<LaneGrads>,
    /// … and over the lanes.
    mlp: MlpWeights,
}

impl ChunkScratch {
    fn new(parts: usize) -> Self {
        Self {
            feats: Vec::with_capacity(CHUNK),
            df: Vec::with_capacity(CHUNK),
            buckets: vec![Vec::new(); parts],
            lanes: Box::default(),
            mlp: MlpWeights::ZERO,
        }
    }
}

/// What a chunk's gradient pass reads.
struct ChunkInput<'a> {
    pixels: &'a TrainPixels,
    taps: &'a [Taps],
    values: &'a [[f32; FEATURES]],
    mlp: &'a MlpWeights,
    /// ∂(mean squared error)/∂(colour) per unit of error.
    scale: f32,
    /// Vertex range of slot `v`: `v >> shift`.
    shift: u32,
}

/// How far ahead (in pixels) the gather loop asks for a pixel's record,
/// its texel's taps and its lattice vertices: each read depends on the
/// previous one, so they are requested in stages.
const AHEAD_PIXEL: usize = 24;
const AHEAD_TAPS: usize = 12;
const AHEAD_VERTICES: usize = 6;

/// Prefetches stage `stage` (0 record, 1 taps, 2 vertices) of pixel `i`.
#[inline(always)]
fn prefetch_pixel(
    i: u32,
    stage: u8,
    pixels: &TrainPixels,
    taps: &[Taps],
    values: &[[f32; FEATURES]],
) {
    let i = i as usize;
    match stage {
        0 => {
            prefetch(&pixels.pixels[i]);
            if let Some(s) = pixels.subsamples.get(i) {
                prefetch(s);
            }
        }
        1 => prefetch(&taps[pixels.pixels[i].slot as usize]),
        _ => {
            for &v in &taps[pixels.pixels[i].slot as usize].slot {
                prefetch(&values[v as usize]);
            }
        }
    }
}

/// [`Taps::gather`] and [`net::quantise`], inlined (the same operations).
#[inline(always)]
fn gather_quantised(t: &Taps, values: &[[f32; FEATURES]]) -> [f32; FEATURES] {
    let mut f = [0f32; FEATURES];
    for (&s, &w) in t.slot.iter().zip(&t.w) {
        let v = &values[s as usize];
        for c in 0..FEATURES {
            f[c] += w * v[c];
        }
    }
    for (c, v) in f.iter_mut().enumerate() {
        *v = net::decode(c, net::encode(c, *v, true));
    }
    f
}

/// [`PixelRef::features`], inlined (the same operations).
#[inline(always)]
fn pixel_features(px: &PixelRef<'_>, taps: &[Taps], values: &[[f32; FEATURES]]) -> [f32; FEATURES] {
    let shown = px.shown();
    if let [one] = shown {
        return gather_quantised(&taps[*one as usize], values);
    }
    let mut f = [0f32; FEATURES];
    for &s in shown {
        let q = gather_quantised(&taps[s as usize], values);
        for (a, b) in f.iter_mut().zip(q) {
            *a += b;
        }
    }
    let inv = 1.0 / shown.len().max(1) as f32;
    for (c, v) in f.iter_mut().enumerate() {
        *v = net::decode(c, net::encode(c, *v * inv, true));
    }
    f
}

/// The gradient of chunk number `ci` (pixels `chunk`): the MLP's into
/// `sc.mlp`, the features' as per-item gradients and per-vertex entries.
#[inline(always)]
fn chunk_grad(ci: usize, chunk: &[u32], inp: &ChunkInput<'_>, sc: &mut ChunkScratch) {
    let ChunkInput {
        pixels,
        taps,
        values,
        mlp,
        scale,
        shift,
    } = *inp;
    sc.feats.clear();
    sc.df.clear();
    sc.buckets.iter_mut().for_each(Vec::clear);
    // Gather first: the lattice reads are cache misses, independent
    // across pixels, and overlap in a loop of their own instead of
    // waiting behind each pixel's MLP.
    let pf = |j: usize, stage: u8| {
        if let Some(&i) = chunk.get(j) {
            prefetch_pixel(i, stage, pixels, taps, values);
        }
    };
    for j in 0..AHEAD_PIXEL {
        pf(j, 0);
    }
    for j in 0..AHEAD_TAPS {
        pf(j, 1);
    }
    for j in 0..AHEAD_VERTICES {
        pf(j, 2);
    }
    let mut item = (ci as u32) << ITEM_BITS;
    for (j, &i) in chunk.iter().enumerate() {
        pf(j + AHEAD_PIXEL, 0);
        pf(j + AHEAD_TAPS, 1);
        pf(j + AHEAD_VERTICES, 2);
        let px = pixels.get(i as usize);
        sc.feats.push(pixel_features(&px, taps, values));
        for &s in px.shown() {
            let t = &taps[s as usize];
            for (&v, &w) in t.slot.iter().zip(&t.w) {
                sc.buckets[(v >> shift) as usize].push(Entry { v, item, w });
            }
            item += 1;
        }
    }
    // The MLP, LANES pixels at a time (the last group padded with zero
    // inputs and zero output gradients, which add nothing).
    for (group, feats) in chunk.chunks(LANES).zip(sc.feats.chunks(LANES)) {
        let mut x = [[0f32; LANES]; INPUTS];
        for (l, (&i, f)) in group.iter().zip(feats).enumerate() {
            let px = pixels.get(i as usize);
            for (c, &v) in f.iter().enumerate() {
                x[c][l] = v;
            }
            for (c, &d) in px.dir.iter().enumerate() {
                x[FEATURES + c][l] = d;
            }
        }
        let a = net::forward8(mlp, &x);
        let mut dy = [[0f32; LANES]; OUTPUTS];
        for (l, &i) in group.iter().enumerate() {
            let px = pixels.get(i as usize);
            let cov = px.coverage();
            for ((d, y), t) in dy.iter_mut().zip(&a.y).zip(px.target) {
                let c = y[l] * cov + (1.0 - cov);
                d[l] = scale * cov * (c - t);
            }
        }
        let dx = net::backward8(mlp, &a, &dy, &mut sc.lanes);
        for (l, &i) in group.iter().enumerate() {
            // The mean's gradient, shared by its subsamples
            // (straight-through both roundings).
            let px = pixels.get(i as usize);
            let shown = px.shown();
            let inv = 1.0 / shown.len() as f32;
            let mut df = [0f32; FEATURES];
            for (c, d) in df.iter_mut().enumerate() {
                *d = dx[c][l];
            }
            if shown.len() != 1 {
                for d in &mut df {
                    *d *= inv;
                }
            }
            for _ in shown {
                sc.df.push(df);
            }
        }
    }
    sc.mlp = MlpWeights::ZERO;
    sc.lanes.reduce_into(&mut sc.mlp);
}

/// [`chunk_grad`] compiled for AVX2 (a lane group is one register).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn chunk_grad_avx2(ci: usize, chunk: &[u32], inp: &ChunkInput<'_>, sc: &mut ChunkScratch) {
    chunk_grad(ci, chunk, inp, sc);
}

/// [`chunk_grad`] with the widest vectors the CPU has.
fn chunk_grad_best(ci: usize, chunk: &[u32], inp: &ChunkInput<'_>, sc: &mut ChunkScratch) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has the features the function is compiled for.
        unsafe { chunk_grad_avx2(ci, chunk, inp, sc) };
        return;
    }
    chunk_grad(ci, chunk, inp, sc);
}

/// Sorts `list` stably by vertex: an LSD radix sort, 8 bits a pass, on
/// each entry's slot less `base` (below `range`). A range's list holds
/// about a thousand entries a step, where one comparison sort per range and
/// step was a twentieth of a bake's CPU time.
fn sort_by_vertex(list: &mut Vec<Entry>, tmp: &mut Vec<Entry>, base: usize, range: usize) {
    let bits = usize::BITS - range.saturating_sub(1).leading_zeros();
    let mut shift = 0;
    while shift < bits {
        let mut count = [0usize; 257];
        let digit = |e: &Entry| ((e.v as usize).wrapping_sub(base) >> shift) & 0xff;
        for e in list.iter() {
            count[digit(e) + 1] += 1;
        }
        for d in 0..256 {
            count[d + 1] += count[d];
        }
        // Every slot is written below: after the first pass this only
        // matches the length (the buffers swap).
        tmp.resize(
            list.len(),
            Entry {
                v: 0,
                item: 0,
                w: 0.0,
            },
        );
        for e in list.iter() {
            let d = digit(e);
            tmp[count[d]] = *e;
            count[d] += 1;
        }
        std::mem::swap(list, tmp);
        shift += 8;
    }
}

/// Sums the entries of one vertex range (`list`, from every chunk; the
/// range starts at slot `base`) per vertex and takes each reached vertex's
/// Adam step.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn range_step_body(
    list: &mut Vec<Entry>,
    tmp: &mut Vec<Entry>,
    scratch: &[ChunkScratch],
    part: usize,
    base: usize,
    vals: &mut [[f32; FEATURES]],
    moments: &mut [Moments],
    bt: &mut [[f32; 2]],
    lr: f32,
) {
    list.clear();
    for sc in scratch {
        list.extend_from_slice(&sc.buckets[part]);
    }
    // By vertex, then in batch order (the order a serial scatter adds in):
    // the chunks' entries arrive in batch order, so a stable sort by
    // vertex gives it.
    sort_by_vertex(list, tmp, base, vals.len());
    let mask = (1u32 << ITEM_BITS) - 1;
    let mut at = 0;
    while at < list.len() {
        if let Some(e) = list.get(at + 16) {
            let k = e.v as usize - base;
            prefetch(&moments[k]);
            prefetch(&vals[k]);
        }
        let v = list[at].v;
        let mut gk = [0f32; FEATURES];
        while at < list.len() && list[at].v == v {
            let e = list[at];
            let df = &scratch[(e.item >> ITEM_BITS) as usize].df[(e.item & mask) as usize];
            for c in 0..FEATURES {
                gk[c] += e.w * df[c];
            }
            at += 1;
        }
        let k = v as usize - base;
        let [b1t, b2t] = &mut bt[k];
        *b1t *= net::BETA1;
        *b2t *= net::BETA2;
        let (c1, c2) = (1.0 - *b1t, 1.0 - *b2t);
        let a = &mut moments[k];
        let f = &mut vals[k];
        for c in 0..FEATURES {
            a.m[c] = net::BETA1 * a.m[c] + (1.0 - net::BETA1) * gk[c];
            a.v[c] = net::BETA2 * a.v[c] + (1.0 - net::BETA2) * gk[c] * gk[c];
            f[c] -= lr * (a.m[c] / c1) / ((a.v[c] / c2).sqrt() + net::EPS);
        }
        net::clamp(f);
    }
}

/// [`range_step_body`] compiled for AVX2: a vertex's eight features are
/// one register through the Adam step's divisions and square roots (exact
/// operations, and no multiply-add is fused, so the results are the same
/// bits). The arguments stay separate here and in [`range_step`]: passed
/// through a struct they cost the fine-tune 7 % of the whole lego
/// (128, 17) command (paired), the `&mut` fields no longer known apart.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn range_step_avx2(
    list: &mut Vec<Entry>,
    tmp: &mut Vec<Entry>,
    scratch: &[ChunkScratch],
    part: usize,
    base: usize,
    vals: &mut [[f32; FEATURES]],
    moments: &mut [Moments],
    bt: &mut [[f32; 2]],
    lr: f32,
) {
    range_step_body(list, tmp, scratch, part, base, vals, moments, bt, lr);
}

/// [`range_step_body`] with the widest vectors the CPU has.
#[allow(clippy::too_many_arguments)]
fn range_step(
    list: &mut Vec<Entry>,
    tmp: &mut Vec<Entry>,
    scratch: &[ChunkScratch],
    part: usize,
    base: usize,
    vals: &mut [[f32; FEATURES]],
    moments: &mut [Moments],
    bt: &mut [[f32; 2]],
    lr: f32,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has the features the function is compiled for.
        unsafe { range_step_avx2(list, tmp, scratch, part, base, vals, moments, bt, lr) };
        return;
    }
    range_step_body(list, tmp, scratch, part, base, vals, moments, bt, lr);
}

/// Buckets of [`shuffle`]: lego at 800 px puts about 270 k pixels (1 MiB)
/// in each, which shuffles in cache.
const SHUFFLE_BUCKETS: usize = 64;

/// A uniformly random permutation of `order`, in parallel (Sanders, "Random
/// permutations on distributed, external and hierarchical memory", 1998):
/// each item goes to one of [`SHUFFLE_BUCKETS`] buckets at random, each
/// bucket is shuffled on its own, and the buckets are laid end to end.
/// One Fisher–Yates pass over lego's 17.5 M pixels was 0.25–0.5 s of serial
/// cache misses per epoch. Deterministic for a given `rng` state: each
/// part and each bucket draws from its own stream, seeded from `rng`.
fn shuffle(order: &mut Vec<u32>, scratch: &mut Vec<u32>, rng: &mut ChaCha8Rng) {
    const B: usize = SHUFFLE_BUCKETS;
    let n = order.len();
    let seeds: [u64; 2 * B] = std::array::from_fn(|_| rng.random());
    // Each part of the input, in order, deals its items to its own buckets.
    let dealt: Vec<Vec<Vec<u32>>> = order
        .par_chunks(n.div_ceil(B).max(1))
        .zip(seeds[..B].par_iter())
        .map(|(part, &seed)| {
            let mut r = ChaCha8Rng::seed_from_u64(seed);
            let mut buckets: Vec<Vec<u32>> = (0..B)
                .map(|_| Vec::with_capacity(part.len() / B + 16))
                .collect();
            for &i in part {
                // The top 6 bits: exactly uniform over the 64 buckets.
                buckets[(r.next_u32() >> (32 - B.trailing_zeros())) as usize].push(i);
            }
            buckets
        })
        .collect();
    // Bucket b is every part's bucket b, in part order, then shuffled.
    scratch.resize(n, 0);
    let mut rest = &mut scratch[..];
    let mut slices = Vec::with_capacity(B);
    for b in 0..B {
        let len = dealt.iter().map(|d| d[b].len()).sum();
        let (head, tail) = rest.split_at_mut(len);
        slices.push(head);
        rest = tail;
    }
    slices
        .into_par_iter()
        .zip(seeds[B..].par_iter())
        .enumerate()
        .for_each(|(b, (out, &seed))| {
            let mut at = 0;
            for d in &dealt {
                out[at..at + d[b].len()].copy_from_slice(&d[b]);
                at += d[b].len();
            }
            out.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        });
    std::mem::swap(order, scratch);
}

/// `order` ← the pixels of runs `runs` (run `r`: pixels `r·run ..
/// (r+1)·run`, the last one cut at `order.len()`), run after run.
fn expand_runs(runs: &[u32], run: usize, order: &mut [u32]) {
    let n = order.len();
    let mut at = 0;
    for &r in runs {
        let start = r as usize * run;
        for (o, i) in order[at..].iter_mut().zip(start..(start + run).min(n)) {
            *o = i as u32;
            at += 1;
        }
    }
}

/// Which training PSNRs [`finetune`] measures (each reads a million
/// pixels): the visibility rounds' fine-tunes report only the first one's
/// before and the last one's after.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PsnrAt {
    /// Before the first step.
    pub before: bool,
    /// After the last step.
    pub after: bool,
}

/// Fine-tunes the lattice's `values` (which the shown texels read through
/// `taps`) and `mlp` on `pixels`; the report's PSNRs not asked for by
/// `psnr` are NaN.
pub fn finetune(
    pixels: &TrainPixels,
    taps: &[Taps],
    values: &mut [[f32; FEATURES]],
    mlp: &mut MlpWeights,
    s: &FinetuneSettings,
    psnr: PsnrAt,
) -> FinetuneReport {
    let t0 = Instant::now();
    let stride = (pixels.len() / 1_000_000).max(1);
    let measure = |on: bool, values: &[[f32; FEATURES]], mlp: &MlpWeights| {
        if on {
            train_psnr(pixels, taps, values, mlp, stride)
        } else {
            f64::NAN
        }
    };
    let psnr_before = measure(psnr.before, values, mlp);
    let n = pixels.len();
    let batch = s.batch.clamp(1, MAX_BATCH);
    let total = (s.epochs.max(0.0) as f64 * n as f64).round() as u64;
    let steps = total.div_ceil(batch as u64) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let run = s.run.max(1) as usize;
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut order_scratch = Vec::new();
    // With runs: the shuffled run numbers, expanded into `order` per epoch.
    let mut runs: Vec<u32> = if run > 1 {
        (0..n.div_ceil(run) as u32).collect()
    } else {
        Vec::new()
    };
    let mut pos = n;
    let mut params = net::flatten(mlp);
    let mut flat_grad = Vec::with_capacity(params.len());
    let mut adam = Adam::new(params.len());
    let slots = values.len();
    // Vertex ranges of 2^shift slots.
    let shift = slots
        .div_ceil(PARTS)
        .max(1)
        .next_power_of_two()
        .trailing_zeros();
    let range = 1usize << shift;
    let parts = slots.div_ceil(range);
    let mut moments = vec![
        Moments {
            m: [0.0; FEATURES],
            v: [0.0; FEATURES],
        };
        slots
    ];
    let mut bt = vec![[1f32; 2]; slots];
    let mut scratch: Vec<ChunkScratch> = (0..batch.div_ceil(CHUNK))
        .map(|_| ChunkScratch::new(parts))
        .collect();
    let mut lists: Vec<Vec<Entry>> = vec![Vec::new(); parts];
    let mut tmps: Vec<Vec<Entry>> = vec![Vec::new(); parts];
    let mut idx: Vec<u32> = Vec::with_capacity(batch);
    let mut pixel_steps = 0u64;
    for step in 0..steps {
        idx.clear();
        while idx.len() < batch && n > 0 {
            if pos == n {
                if run > 1 {
                    shuffle(&mut runs, &mut order_scratch, &mut rng);
                    expand_runs(&runs, run, &mut order);
                } else {
                    shuffle(&mut order, &mut order_scratch, &mut rng);
                }
                pos = 0;
            }
            let take = (batch - idx.len()).min(n - pos);
            idx.extend_from_slice(&order[pos..pos + take]);
            pos += take;
        }
        pixel_steps += idx.len() as u64;
        let inp = ChunkInput {
            pixels,
            taps,
            values,
            mlp,
            scale: 2.0 / (3 * idx.len()) as f32,
            shift,
        };
        idx.par_chunks(CHUNK)
            .zip(scratch.par_iter_mut())
            .enumerate()
            .for_each(|(ci, (chunk, sc))| chunk_grad_best(ci, chunk, &inp, sc));
        let used = &scratch[..idx.len().div_ceil(CHUNK)];
        let decay = 0.1f32.powf(step as f32 / steps.max(1) as f32);
        // MLP.
        let mut g = MlpWeights::ZERO;
        for sc in used {
            net::add_into(&mut g, &sc.mlp);
        }
        net::flatten_into(&g, &mut flat_grad);
        adam.step(&mut params, &flat_grad, s.lr_mlp * decay);
        *mlp = net::unflatten(&params);
        // Features: per vertex range, sum each reached vertex's entries and
        // take its Adam step.
        let lr = s.lr_features * decay;
        values
            .par_chunks_mut(range)
            .zip(moments.par_chunks_mut(range))
            .zip(bt.par_chunks_mut(range))
            .zip(lists.par_iter_mut())
            .zip(tmps.par_iter_mut())
            .enumerate()
            .for_each(|(p, ((((vals, mom), bts), list), tmp))| {
                range_step(list, tmp, used, p, p * range, vals, mom, bts, lr);
            });
    }
    let psnr_after = measure(psnr.after, values, mlp);
    FinetuneReport {
        steps,
        pixel_steps,
        psnr_before,
        psnr_after,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default settings print as they did before `run` (store keys).
    #[test]
    fn debug_leaves_out_the_default_run() {
        let s = FinetuneSettings::default();
        assert_eq!(
            format!("{s:?}"),
            "FinetuneSettings { epochs: 2.5, batch: 8192, lr_features: 0.015, lr_mlp: 0.003, seed: 7 }"
        );
        let r = FinetuneSettings { run: 8, ..s };
        assert!(format!("{r:?}").ends_with("seed: 7, run: 8 }"));
    }

    /// Runs expand into every pixel once, each run's pixels consecutive.
    #[test]
    fn runs_expand_into_a_permutation_of_consecutive_pixels() {
        for (n, run) in [
            (0usize, 4usize),
            (1, 4),
            (10, 4),
            (12, 4),
            (13, 1),
            (1000, 7),
        ] {
            let mut runs: Vec<u32> = (0..n.div_ceil(run) as u32).collect();
            let mut scratch = Vec::new();
            shuffle(&mut runs, &mut scratch, &mut ChaCha8Rng::seed_from_u64(3));
            let mut order = vec![u32::MAX; n];
            expand_runs(&runs, run, &mut order);
            let mut sorted = order.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..n as u32).collect::<Vec<_>>(), "n {n} run {run}");
            // Where a run starts, its pixels follow it in order.
            for w in order.windows(2) {
                if w[1] as usize % run != 0 {
                    assert_eq!(w[1], w[0] + 1, "n {n} run {run}: {order:?}");
                }
            }
        }
    }

    /// The parallel shuffle is a permutation, the same for the same seed,
    /// and puts each item in each place about equally often.
    #[test]
    fn the_shuffle_permutes_uniformly() {
        for n in [0usize, 1, 5, 63, 64, 1000, 100_000] {
            let mut order: Vec<u32> = (0..n as u32).collect();
            let (mut a, mut b) = (Vec::new(), Vec::new());
            shuffle(&mut order, &mut a, &mut ChaCha8Rng::seed_from_u64(9));
            let mut again: Vec<u32> = (0..n as u32).collect();
            shuffle(&mut again, &mut b, &mut ChaCha8Rng::seed_from_u64(9));
            assert_eq!(order, again, "n {n}");
            let mut sorted = order.clone();
            sorted.sort_unstable();
            assert!(
                sorted.iter().enumerate().all(|(i, &x)| x as usize == i),
                "n {n}"
            );
            if n >= 1000 {
                assert_ne!(order, sorted, "n {n}");
            }
        }
        // 6 items, 60 000 shuffles: each (item, place) pair expects 10 000;
        // the largest of 36 deviations stays within about 4.5 sigma (95).
        let n = 6;
        let mut counts = [[0u32; 6]; 6];
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let (mut order, mut scratch): (Vec<u32>, Vec<u32>) = ((0..n).collect(), Vec::new());
        for _ in 0..60_000 {
            shuffle(&mut order, &mut scratch, &mut rng);
            for (place, &item) in order.iter().enumerate() {
                counts[item as usize][place] += 1;
            }
        }
        for row in counts {
            for c in row {
                assert!((c as i64 - 10_000).abs() < 420, "{counts:?}");
            }
        }
    }

    /// The radix sort orders by vertex and keeps batch order within a
    /// vertex: the order of the comparison sort by (vertex, item) it
    /// replaced, on entries that arrive in item order.
    #[test]
    fn the_vertex_sort_is_the_comparison_sort_it_replaced() {
        use rand::Rng;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (base, range, n) in [
            (0usize, 1usize, 5usize),
            (4096, 300, 2000),
            (1 << 20, 1 << 17, 5000),
            (7, 256, 0),
        ] {
            let mut list: Vec<Entry> = (0..n as u32)
                .map(|item| Entry {
                    v: (base + rng.random_range(0..range)) as u32,
                    item,
                    w: rng.random::<f32>(),
                })
                .collect();
            let mut want = list.clone();
            want.sort_unstable_by_key(|e| (u64::from(e.v) << 32) | u64::from(e.item));
            let mut tmp = Vec::new();
            sort_by_vertex(&mut list, &mut tmp, base, range);
            let key = |l: &[Entry]| {
                l.iter()
                    .map(|e| (e.v, e.item, e.w.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(key(&list), key(&want), "base {base} range {range}");
        }
    }
}
