//! Texel opacity learnt from the photos: each opaque texel the training
//! views see first is kept only if the pixels that show it match their
//! photo better with it than with what lies behind it.
//!
//! MobileNeRF learns texel opacity by soft compositing every quad along a
//! ray, then binarises it. Our opacity starts binary (the field's surface),
//! so the same question is asked discretely: with the fine-tuned lattice
//! and MLP, every covered pixel of every training view is shaded twice per
//! texel it shows, as it is and with that texel transparent (the second
//! layer of a depth-peeled G-buffer, or the white background), and each
//! texel sums the change in squared error over its pixels. Texels whose
//! removal lowers the error are removed. Each texel is judged with every
//! other texel in place, so a round is exact only to first order; the
//! bake re-rasterizes and fine-tunes after each round.
//!
//! With `grow`, the question is also asked the other way: where a
//! transparent texel lies in front of what a pixel shows (a third layer,
//! the quads drawn through the inverted alpha test), each pixel is shaded
//! with that texel opaque, and texels whose addition lowers their pixels'
//! error become opaque. Soft compositing can add coverage as well as take
//! it away; a remove-only rule cannot mend an edge the field cut short.

use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};

use super::super::{BakeError, BakeView};
use super::extract::Geometry;
use super::featgrid::FeatureGrid;
use super::gbuffer::{self, Subsamples, NO_TEXEL, SUBSAMPLES, TILE};
use super::net::{self, FEATURES, LANES};
use nerflex_core::raster::{TileRenderer, TwoLayers};
use nerflex_core::shader::{MlpWeights, INPUTS};

/// One covered pixel of a training view, with two layers: per subsample
/// position (not compacted), the texel it shows and the texel behind that
/// one ([`NO_TEXEL`] where none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeelPixel {
    /// The texels shown.
    pub front: Subsamples,
    /// The texels behind them.
    pub behind: Subsamples,
    /// With `grow`: the nearest transparent texel in front of each front
    /// texel (where there is none in front, the nearest transparent one);
    /// [`NO_TEXEL`] where none or without `grow`.
    pub nearer: Subsamples,
    /// The view direction the renderer feeds the MLP here.
    pub dir: [f32; 3],
    /// The training image here composited over white, in [0, 1].
    pub target: [f32; 3],
    /// The photo's object coverage here (0–255): under 128 the pixel is
    /// background, a vote and no target for the fine-tune.
    pub cov: u8,
}

/// The two-layer G-buffers of every training view.
#[derive(Debug, Clone, Default)]
pub struct Peel {
    /// Covered pixels, one vector per view: as the views' workers made
    /// them, never concatenated (on lego (128, 17) that copy was 1.3 GB of
    /// fresh pages a round).
    pub views: Vec<Vec<PeelPixel>>,
    /// Tiles drawn, and those whose layer behind one draw could not
    /// decide and a peeling pass redrew ([`TwoLayers::resolve`]).
    pub tiles: (u64, u64),
}

/// The most visibility rounds a bake takes.
pub const MAX_ROUNDS: u32 = 8;

/// Settings of the visibility rounds.
#[derive(Clone, Copy, PartialEq)]
pub struct VisibilitySettings {
    /// Rounds of (peel, decide, re-rasterize, fine-tune); 0 = off.
    pub rounds: u32,
    /// A texel goes when its removal lowers the summed squared error (RGB
    /// in [0, 1]) of its pixels by more than this.
    pub margin: f32,
    /// Growing: a transparent texel in front of what pixels show becomes
    /// opaque when that lowers their summed squared error by more than
    /// this margin; `None`: no texel is added (and the layers skip the
    /// transparent ones).
    pub grow: Option<f32>,
    /// Texels per side of the blocks a patch is judged in: a texel flips
    /// when the summed change of the shown texels of its own state (opaque
    /// or transparent) in its block passes the margin, so each decision
    /// rests on a few pixels more than one texel's (1: texel by texel;
    /// [`AUTO_BLOCK`]: [`auto_block`] of the bake's texel size).
    pub block: u32,
    /// Epochs of each fine-tune before the last, as a share of the last
    /// one's ([`round_epochs`]; 1: `--epochs` split evenly).
    pub tune_share: f32,
    /// Keep the quads a training pixel's layer behind lies on, not only
    /// those it shows first: a held-out view sees them through the gaps
    /// between the front quads. Off by default: on gear (256, 13) it takes
    /// the held-out holes from 19.3 % to 7.9 % of the squared error (+0.27
    /// dB) for 42 % more GPU bytes (docs/baking.md, "Session 32").
    pub keep_behind: bool,
    /// Keep the quads a virtual camera between the training views shows
    /// first before the first round as well ([`super::novel`]): the quads
    /// a novel view sees through the gaps between the front planes. Gear
    /// (p = 13): +0.19 dB at g = 128 and +0.28 dB at 256 for 9 % and 10 %
    /// more GPU bytes (docs/baking.md, "Session 33").
    pub keep_novel: bool,
}

/// The epochs of round `round`'s fine-tune (0-based, `rounds` + 1 of
/// them) when `total` epochs are split so that every fine-tune before the
/// last takes `share` of the last one's. Lego, two rounds, one seed:
/// share ¼ of 2.5 epochs scored as an even split of 3 (29.99 and, by a
/// temporary switch, 30.02 dB against 30.00) in less time (docs/baking.md,
/// "Session 29").
pub fn round_epochs(total: f32, rounds: u32, share: f32, round: u32) -> f32 {
    let last = total / (1.0 + rounds as f32 * share);
    if round < rounds {
        share * last
    } else {
        last
    }
}

/// Largest [`VisibilitySettings::block`].
pub const MAX_BLOCK: u32 = 64;

/// [`VisibilitySettings::block`] chosen per bake by [`auto_block`] (the
/// default).
pub const AUTO_BLOCK: u32 = 0;

/// The widest an automatic block spans, pixels of the training views.
/// Single texels far under a pixel are seen by two or three training
/// pixels, too few to decide on; blocks up to about a pixel gain, wider
/// ones lose (lego, 1 epoch: (256, 17) +0.22 dB at B = 3; (64, 17), a
/// 0.6 px texel, −0.03 dB at B = 2; (128, 5) −0.12 dB at B = 2;
/// docs/baking.md, "Session 26").
pub const BLOCK_SPAN_PX: f32 = 1.0;

/// Largest block [`auto_block`] picks.
pub const MAX_AUTO_BLOCK: u32 = 8;

/// The block side for texels `texel_px` pixels wide in the training
/// views: the most texels per side whose block spans at most
/// [`BLOCK_SPAN_PX`] (1 where a texel spans more than half a pixel, or its
/// size is unknown), at most [`MAX_AUTO_BLOCK`].
pub fn auto_block(texel_px: Option<f32>) -> u32 {
    match texel_px {
        Some(t) if t.is_finite() && t > 0.0 => {
            // `as` saturates: a tiny texel gives a huge ratio, then the cap.
            ((BLOCK_SPAN_PX / t).floor() as u32).clamp(1, MAX_AUTO_BLOCK)
        }
        _ => 1,
    }
}

impl VisibilitySettings {
    /// These settings with [`AUTO_BLOCK`] resolved for texels of a
    /// `voxel_px`-pixel voxel's `p` × `p` patch.
    pub fn resolved(&self, voxel_px: Option<f32>, p: u32) -> Self {
        let mut v = *self;
        if v.block == AUTO_BLOCK {
            v.block = auto_block(voxel_px.map(|v| v / p.max(1) as f32));
        }
        v
    }
}

/// `grow`, `block` and `keep_behind` show only when set (`block` when not automatic):
/// bake store keys are the settings' debug text (`pipeline::bakes`), and
/// bakes without them are keyed as before.
impl std::fmt::Debug for VisibilitySettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("VisibilitySettings");
        d.field("rounds", &self.rounds)
            .field("margin", &self.margin);
        if let Some(g) = self.grow {
            d.field("grow", &g);
        }
        if self.block != AUTO_BLOCK {
            d.field("block", &self.block);
        }
        if self.tune_share != 1.0 {
            d.field("tune_share", &self.tune_share);
        }
        if self.keep_behind {
            d.field("keep_behind", &true);
        }
        if self.keep_novel {
            // Session 33's pass (once, cameras deduplicated), not
            // session 32's (every round): a new key.
            d.field("keep_novel", &"first round");
        }
        d.finish()
    }
}

impl Default for VisibilitySettings {
    fn default() -> Self {
        Self {
            // 1 round, 1.0 share until baker version 11 (docs/baking.md,
            // "Session 30").
            rounds: 2,
            margin: 0.01,
            grow: None,
            block: AUTO_BLOCK,
            tune_share: 0.25,
            keep_behind: false,
            keep_novel: false,
        }
    }
}

/// What a round did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VisibilityReport {
    /// Covered pixels judged (training views, background included).
    pub pixels: u64,
    /// Distinct texels some pixel shows first.
    pub shown_texels: u64,
    /// Texels made transparent.
    pub removed_texels: u64,
    /// Transparent texels some pixel shows nearer (judged for `grow`).
    pub nearer_texels: u64,
    /// Texels made opaque (`grow`).
    pub added_texels: u64,
    /// Summed squared error of the judged pixels before, and the sum of
    /// the removed texels' (negative) changes: a first-order estimate.
    pub error_before: f64,
    /// …
    pub error_change: f64,
    /// Subsamples whose front texel and the one behind it both went: the
    /// next fine-tune counts them uncovered ([`Peel::gbuffers`]).
    pub lost_subsamples: u64,
    /// Subsamples whose layer behind lay on a quad no pixel shows first,
    /// dropped before the judgement (the first round's layers are
    /// rasterized before that drop): judged as if nothing were behind.
    pub unkept_behind: u64,
    /// Tiles of the two-layer rasterizations, and those redrawn.
    pub peel_tiles: (u64, u64),
    /// Texels per side of the blocks the rounds judged in (0: no round).
    pub block: u32,
    /// Wall time of the two-layer rasterizations, seconds.
    pub peel_s: f64,
    /// … of the judgements and the next G-buffers.
    pub judge_s: f64,
}

/// The two-layer G-buffers of `geo` at patch `p` on `views` (2 × 2
/// subsamples when `supersample`), every covered pixel of the object
/// (pixels another object covers are skipped), view after view; with
/// `grow` also the transparent texels in front ([`PeelPixel::nearer`]),
/// and the pixels only those cover.
pub fn peel(
    geo: &Geometry,
    p: u32,
    views: &[BakeView<'_>],
    supersample: bool,
    grow: bool,
) -> Result<Peel, BakeError> {
    let (layout, quads, pages) = gbuffer::pages_of(geo, p)?;
    let quads: Vec<&[_]> = quads.iter().map(Vec::as_slice).collect();
    let masks = gbuffer::alpha_masks(&pages)?;
    let inv_pages = if grow {
        gbuffer::transparent_pages(&layout, &geo.opacity)
    } else {
        Vec::new()
    };
    let inv_masks = gbuffer::alpha_masks(&inv_pages)?;
    type ViewLayers = (Vec<PeelPixel>, (u64, u64));
    let per: Vec<Result<ViewLayers, BakeError>> = views
        .par_iter()
        .enumerate()
        .map_init(gbuffer::Binned::default, |binned, (vi, v)| {
            let (out_view, view, ss) = gbuffer::views_of(vi, v, supersample)?;
            binned.rebin(&quads, &view);
            let binned = &*binned;
            let mut keyed = Vec::new();
            let t = TILE as u32;
            let mut two = Box::new(TwoLayers::<TILE, TILE>::new());
            let mut near = Box::new(TileRenderer::<TILE, TILE>::new());
            let mut out = Vec::new();
            let mut tiles = (0u64, 0u64);
            for (b, bin) in binned.bins.iter().enumerate() {
                if bin.is_empty() {
                    continue;
                }
                let (bx, by) = (b as u32 % binned.tx, b as u32 / binned.tx);
                tiles.0 += 1;
                two.begin(&view, bx * t, by * t);
                let quad = |i: u32| {
                    let sq = binned.projected.get(i as usize)?;
                    masks.get(sq.part as usize).map(|m| (sq, m))
                };
                // Nearest first, each at its place in the draw order; a
                // quad behind both layers wherever it could cover is not
                // drawn.
                for (i, sq, near) in
                    gbuffer::near_first(bin, &binned.projected, &binned.nearness, &mut keyed)
                {
                    if two.hides(sq, near) {
                        continue;
                    }
                    if let Some(mask) = masks.get(sq.part as usize) {
                        two.draw_at(sq, mask, i);
                    }
                }
                // Rare: a pixel kept too little to decide what lies behind
                // (the redraw goes in the draw order).
                tiles.1 += u64::from(two.resolve(bin.iter().filter_map(|&i| quad(i))));
                if grow {
                    near.begin(&view, bx * t, by * t);
                    for &i in bin {
                        let sq = &binned.projected[i as usize];
                        if let Some(m) = inv_masks.get(sq.part as usize) {
                            near.draw(sq, m);
                        }
                    }
                }
                let (front, back) = (two.front(), two.back());
                let (x0, y0, w, h) = front.rect();
                for oy in 0..h / ss {
                    for ox in 0..w / ss {
                        let mut px_front = [NO_TEXEL; SUBSAMPLES];
                        let mut px_back = [NO_TEXEL; SUBSAMPLES];
                        let mut px_near = [NO_TEXEL; SUBSAMPLES];
                        for i in 0..(ss * ss) as usize {
                            let (sx, sy) = (ox * ss + i as u32 % ss, oy * ss + i as u32 / ss);
                            if let Some(t) = gbuffer::texel_at(front, &layout, sx, sy) {
                                px_front[i] = t;
                                px_back[i] =
                                    gbuffer::texel_at(back, &layout, sx, sy).unwrap_or(NO_TEXEL);
                            }
                            if grow && near.nearer_than(front, sx, sy) {
                                px_near[i] =
                                    gbuffer::texel_at(&near, &layout, sx, sy).unwrap_or(NO_TEXEL);
                            }
                        }
                        if px_front.iter().chain(&px_near).all(|&t| t == NO_TEXEL) {
                            continue;
                        }
                        let (x, y) = (x0 / ss + ox, y0 / ss + oy);
                        let Some((cov, target)) = gbuffer::photo_at(v, x, y) else {
                            continue;
                        };
                        out.push(PeelPixel {
                            front: px_front,
                            behind: px_back,
                            nearer: px_near,
                            dir: out_view.pixel_dir_f32(x, y),
                            target,
                            cov,
                        });
                    }
                }
            }
            Ok((out, tiles))
        })
        .collect();
    let mut all = Peel::default();
    for r in per {
        let (r, tiles) = r?;
        all.views.push(r);
        all.tiles = (all.tiles.0 + tiles.0, all.tiles.1 + tiles.1);
    }
    Ok(all)
}

impl Peel {
    /// Covered pixels of all views.
    pub fn len(&self) -> usize {
        self.views.iter().map(Vec::len).sum()
    }

    /// Whether no view has a covered pixel.
    pub fn is_empty(&self) -> bool {
        self.views.iter().all(Vec::is_empty)
    }

    /// Every covered pixel, view after view.
    pub fn pixels(&self) -> impl Iterator<Item = &PeelPixel> {
        self.views.iter().flatten()
    }

    /// The G-buffers once the texels `opacity` marks transparent are gone:
    /// where a subsample's front texel went, the texel behind it shows
    /// (exact while that one stays; where both went the subsample counts
    /// as uncovered, as the layer behind both is not kept), and where its
    /// nearer texel became opaque, that one (exact where no other
    /// transparent texel in front became opaque). Returns them and the
    /// number of subsamples that lost both layers.
    pub fn gbuffers(&self, opacity: &[bool], supersample: bool) -> (gbuffer::GBuffers, u64) {
        let opaque = |t: u32| opacity.get(t as usize) == Some(&true);
        type ViewPart = (Vec<gbuffer::GPixel>, Vec<Subsamples>, Vec<u32>, u64);
        let parts: Vec<ViewPart> = self
            .views
            .par_iter()
            .map(|view| {
                let (mut pixels, mut subs, mut background, mut lost) =
                    (Vec::new(), Vec::new(), Vec::new(), 0u64);
                for px in view {
                    let mut shown = [NO_TEXEL; SUBSAMPLES];
                    let mut k = 0;
                    for ((&f, &b), &n) in px.front.iter().zip(&px.behind).zip(&px.nearer) {
                        let t = if opaque(n) {
                            n
                        } else if opaque(f) {
                            f
                        } else if f == NO_TEXEL {
                            continue;
                        } else if opaque(b) {
                            b
                        } else if b == NO_TEXEL {
                            // Nothing behind: the background shows.
                            continue;
                        } else {
                            lost += 1;
                            continue;
                        };
                        shown[k] = t;
                        k += 1;
                    }
                    if k == 0 {
                        continue;
                    }
                    if px.cov < 128 {
                        background.extend_from_slice(&shown[..k]);
                        continue;
                    }
                    pixels.push(gbuffer::GPixel {
                        texel: shown[0],
                        dir: px.dir,
                        target: px.target,
                    });
                    if supersample {
                        subs.push(shown);
                    }
                }
                (pixels, subs, background, lost)
            })
            .collect();
        let lost = parts.iter().map(|p| p.3).sum();
        let parts = parts
            .into_iter()
            .map(|(pixels, subs, background, _)| (pixels, subs, background))
            .collect();
        (gbuffer::GBuffers::joined(parts), lost)
    }

    /// Per quad (`nq` of them, `p2` texels each), whether some pixel's
    /// layer behind lies on it.
    pub fn behind_quads(&self, nq: usize, p2: usize) -> Vec<bool> {
        let mut on = vec![false; nq];
        for &t in self.pixels().flat_map(|px| &px.behind) {
            if let Some(q) = on.get_mut(t as usize / p2.max(1)) {
                *q = true;
            }
        }
        on
    }

    /// Renumbers the texels after the quads were re-indexed (`new_index`
    /// per old quad; `u32::MAX`: dropped, its texels then none). Returns
    /// how many texels behind were on a dropped quad.
    pub fn renumber(&mut self, new_index: &[u32], p2: usize) -> u64 {
        let map = |t: &mut u32| -> u64 {
            if *t == NO_TEXEL {
                return 0;
            }
            let q = new_index.get(*t as usize / p2).copied().unwrap_or(u32::MAX);
            if q == u32::MAX {
                *t = NO_TEXEL;
                return 1;
            }
            *t = q * p2 as u32 + *t % p2 as u32;
            0
        };
        self.views
            .par_iter_mut()
            .flat_map(|v| v.par_iter_mut())
            .map(|px| {
                px.front.iter_mut().map(map).sum::<u64>();
                px.nearer.iter_mut().map(map).sum::<u64>();
                px.behind.iter_mut().map(map).sum::<u64>()
            })
            .sum()
    }
}

/// The 8-bit features of every texel of `geo` that `pixels` show, hide or
/// could show (the lattice read at its point, as the atlas will store it),
/// and whether the lattice reaches it; zeros and `false` elsewhere.
fn texel_bytes(
    geo: &Geometry,
    p: u32,
    grid: &FeatureGrid,
    views: &[Vec<PeelPixel>],
) -> (Vec<[u8; FEATURES]>, Vec<bool>) {
    let needed: Vec<AtomicBool> = gbuffer::filled(geo.opacity.len(), || AtomicBool::new(false));
    views.par_iter().flat_map(|v| v.par_iter()).for_each(|px| {
        for &t in px.front.iter().chain(&px.behind).chain(&px.nearer) {
            if let Some(n) = needed.get(t as usize) {
                n.store(true, Ordering::Relaxed);
            }
        }
    });
    (0..geo.opacity.len())
        .into_par_iter()
        .zip(&needed)
        .map(|(t, n)| {
            let Some(tp) = n
                .load(Ordering::Relaxed)
                .then(|| grid.taps(geo.texel_point(p, t as u32)))
                .flatten()
            else {
                return ([0; FEATURES], false);
            };
            let f = tp.gather(&grid.values);
            (std::array::from_fn(|c| net::encode(c, f[c], true)), true)
        })
        .unzip()
}

/// One shading of a pixel to judge: its features' bytes summed over `n`
/// covered subsamples of `samples`, and the texel whose removal (or, if
/// transparent, addition) it tests ([`NO_TEXEL`]: the pixel as it is).
#[derive(Clone, Copy)]
struct Shading {
    sum: [u32; FEATURES],
    n: u32,
    texel: u32,
}

/// The shading of a pixel showing `texels` (per subsample position,
/// [`NO_TEXEL`] uncovered).
fn shading(texels: &Subsamples, samples: usize, bytes: &[[u8; FEATURES]], texel: u32) -> Shading {
    let mut sum = [0u32; FEATURES];
    let mut n = 0u32;
    for &t in texels.iter().take(samples) {
        if let Some(b) = bytes.get(t as usize) {
            for (s, &v) in sum.iter_mut().zip(b) {
                *s += u32::from(v);
            }
            n += 1;
        }
    }
    Shading { sum, n, texel }
}

/// Squared errors (RGB in [0, 1], summed over channels) of [`LANES`]
/// shadings of pixels `px` (lane `l` of pixel `px[l]`), shaded as the
/// renderer does: the rounded byte mean of the covered texels' features
/// (`nerflex_core::raster::mean_texel`), the MLP, its 8-bit output blended
/// over white by coverage; no covered texel shows white.
// Index loops: lanes and channels index several arrays at once (structure
// of arrays), as the math reads.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn errors8(
    sh: &[Shading; LANES],
    px: &[&PeelPixel; LANES],
    samples: usize,
    mlp: &MlpWeights,
) -> [f32; LANES] {
    let mut x = [[0f32; LANES]; INPUTS];
    for l in 0..LANES {
        let n = sh[l].n.max(1);
        for c in 0..FEATURES {
            x[c][l] = net::decode(c, ((sh[l].sum[c] + n / 2) / n) as u8);
        }
        for k in 0..3 {
            x[FEATURES + k][l] = px[l].dir[k];
        }
    }
    let y = net::forward8(mlp, &x).y;
    std::array::from_fn(|l| {
        let cov = sh[l].n as f32 / samples as f32;
        (0..3)
            .map(|k| {
                let c = if sh[l].n == 0 {
                    1.0
                } else {
                    let v = (y[k][l].clamp(0.0, 1.0) * 255.0).round();
                    v / 255.0 * cov + (1.0 - cov)
                };
                (c - px[l].target[k]).powi(2)
            })
            .sum()
    })
}

/// [`errors8`] of every shading `jobs` lists (with the index of its pixel
/// in `pixels`), into `errors`.
#[inline(always)]
fn job_errors(
    jobs: &[(Shading, usize)],
    pixels: &[PeelPixel],
    samples: usize,
    mlp: &MlpWeights,
    errors: &mut [f32],
) {
    for (js, es) in jobs.chunks(LANES).zip(errors.chunks_mut(LANES)) {
        let sh: [Shading; LANES] = std::array::from_fn(|l| js[l.min(js.len() - 1)].0);
        let px: [&PeelPixel; LANES] = std::array::from_fn(|l| &pixels[js[l.min(js.len() - 1)].1]);
        let e = errors8(&sh, &px, samples, mlp);
        es.copy_from_slice(&e[..es.len()]);
    }
}

/// [`job_errors`] compiled for AVX2: a lane group is one register and
/// rounding one instruction. Rust never fuses a multiply and an add, so
/// the results are bit for bit the same.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn job_errors_avx2(
    jobs: &[(Shading, usize)],
    pixels: &[PeelPixel],
    samples: usize,
    mlp: &MlpWeights,
    errors: &mut [f32],
) {
    job_errors(jobs, pixels, samples, mlp, errors);
}

/// [`job_errors`] with the widest vectors the CPU has.
fn job_errors_best(
    jobs: &[(Shading, usize)],
    pixels: &[PeelPixel],
    samples: usize,
    mlp: &MlpWeights,
    errors: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has the feature the function is compiled for.
        unsafe { job_errors_avx2(jobs, pixels, samples, mlp, errors) };
        return;
    }
    job_errors(jobs, pixels, samples, mlp, errors);
}

/// Fixed-point units of the per-texel error sums (exact, so their sum
/// does not depend on the order the threads add in).
const DELTA_UNIT: f64 = (1u64 << 32) as f64;

/// One round: judges every texel the pixels of `views` show first and
/// makes the ones whose removal lowers their pixels' error transparent in
/// `geo`; with
/// `settings.grow`, also every transparent texel they show nearer, and
/// makes the ones whose addition lowers the error by more than its margin
/// opaque.
pub fn prune(
    geo: &mut Geometry,
    p: u32,
    views: &[Vec<PeelPixel>],
    grid: &FeatureGrid,
    mlp: &MlpWeights,
    supersample: bool,
    settings: &VisibilitySettings,
) -> VisibilityReport {
    let samples = if supersample { SUBSAMPLES } else { 1 };
    let (bytes, readable) = texel_bytes(geo, p, grid, views);
    // Per texel: the summed change of squared error, and whether a pixel
    // shows it.
    let delta: Vec<AtomicI64> = gbuffer::filled(geo.opacity.len(), || AtomicI64::new(0));
    let shown: Vec<AtomicBool> = gbuffer::filled(geo.opacity.len(), || AtomicBool::new(false));
    let before: f64 = views
        .par_iter()
        .flat_map(|v| v.par_chunks(1024))
        .map(|chunk| {
            // Every shading of the chunk's pixels: the pixel as it is,
            // then once per texel it shows, without it.
            let mut jobs: Vec<(Shading, usize)> = Vec::with_capacity(chunk.len() * 2);
            for (i, px) in chunk.iter().enumerate() {
                jobs.push((shading(&px.front, samples, &bytes, NO_TEXEL), i));
                let mut done = [NO_TEXEL; SUBSAMPLES];
                for (k, &t) in px.front.iter().take(samples).enumerate() {
                    if t == NO_TEXEL || done.contains(&t) {
                        continue;
                    }
                    done[k] = t;
                    let mut without = px.front;
                    for (w, &b) in without.iter_mut().zip(&px.behind) {
                        if *w == t {
                            *w = b;
                        }
                    }
                    jobs.push((shading(&without, samples, &bytes, t), i));
                }
                // With each transparent texel in front made opaque (one
                // the lattice does not reach cannot be).
                let mut done = [NO_TEXEL; SUBSAMPLES];
                for (k, &t) in px.nearer.iter().take(samples).enumerate() {
                    if t == NO_TEXEL || done.contains(&t) || readable.get(t as usize) != Some(&true)
                    {
                        continue;
                    }
                    done[k] = t;
                    let mut with = px.front;
                    for (w, &n) in with.iter_mut().zip(&px.nearer) {
                        if n == t {
                            *w = t;
                        }
                    }
                    jobs.push((shading(&with, samples, &bytes, t), i));
                }
            }
            let mut errors = vec![0f32; jobs.len()];
            job_errors_best(&jobs, chunk, samples, mlp, &mut errors);
            let mut sum = 0f64;
            let mut e0 = 0f32;
            for ((sh, _), &e) in jobs.iter().zip(&errors) {
                if sh.texel == NO_TEXEL {
                    e0 = e;
                    sum += f64::from(e);
                    continue;
                }
                let t = sh.texel as usize;
                if let (Some(d), Some(s)) = (delta.get(t), shown.get(t)) {
                    d.fetch_add((f64::from(e - e0) * DELTA_UNIT) as i64, Ordering::Relaxed);
                    s.store(true, Ordering::Relaxed);
                }
            }
            sum
        })
        .sum();
    let raw = |t: usize| delta.get(t).map_or(0, |d| d.load(Ordering::Relaxed));
    let own = |t: usize| raw(t) as f64 / DELTA_UNIT;
    let is_shown = |t: usize| shown.get(t).is_some_and(|s| s.load(Ordering::Relaxed));
    // Quad by quad on all cores: a block lies inside its quad's patch, so
    // each quad decides on a copy of its own opacity as it was, exactly
    // what judging every texel before changing any gives.
    let (pu, b) = (p.max(1) as usize, settings.block.max(1) as usize);
    let p2 = pu * pu;
    let (counts, change) = geo
        .opacity
        .par_chunks_mut(p2)
        .enumerate()
        .fold(
            || ([0u64; 4], 0i64, Vec::new()),
            |(mut counts, mut change, mut old), (q, patch)| {
                old.clear();
                old.extend_from_slice(patch);
                let base = q * p2;
                for (i, o) in patch.iter_mut().enumerate() {
                    let t = base + i;
                    if !is_shown(t) {
                        continue;
                    }
                    let d = if b > 1 {
                        block_sum(&old, base, i, pu, b, own, is_shown)
                    } else {
                        own(t)
                    };
                    let opaque = old[i];
                    counts[usize::from(!opaque)] += 1;
                    let margin = if opaque {
                        settings.margin
                    } else {
                        settings.grow.unwrap_or(f32::INFINITY)
                    };
                    if d < -f64::from(margin) {
                        *o = !opaque;
                        counts[2 + usize::from(!opaque)] += 1;
                        // The texel's own first-order change (its block's
                        // is shared), summed exactly.
                        change += raw(t);
                    }
                }
                (counts, change, old)
            },
        )
        .map(|(counts, change, _)| (counts, change))
        .reduce(
            || ([0u64; 4], 0i64),
            |(a, x), (b, y)| (std::array::from_fn(|k| a[k] + b[k]), x + y),
        );
    let [shown_texels, nearer_texels, removed_texels, added_texels] = counts;
    VisibilityReport {
        pixels: views.iter().map(|v| v.len() as u64).sum(),
        error_before: before,
        shown_texels,
        nearer_texels,
        removed_texels,
        added_texels,
        error_change: change as f64 / DELTA_UNIT,
        ..Default::default()
    }
}

/// The summed error change (`delta`, by texel) of the shown texels of the
/// same state as texel `i` of a quad (its `p²` texels' opacity `patch`,
/// row-major, `pu` = p per side, the first one texel `base`) in its
/// `b` × `b` block of the patch. With `b` 1 it is the texel's own change.
fn block_sum(
    patch: &[bool],
    base: usize,
    i: usize,
    pu: usize,
    b: usize,
    delta: impl Fn(usize) -> f64,
    shown: impl Fn(usize) -> bool,
) -> f64 {
    let (bx, by) = (i % pu / b * b, i / pu / b * b);
    let state = patch.get(i).copied();
    let mut sum = 0.0;
    for y in by..(by + b).min(pu) {
        for x in bx..(bx + b).min(pu) {
            let j = y * pu + x;
            if patch.get(j).copied() == state && shown(base + j) {
                sum += delta(base + j);
            }
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::quads::Quad;
    use crate::bake::Aabb;
    use glam::Vec3;

    /// A 2 × 2-texel quad in the plane z = `z`, x ∈ [x0, x0 + 0.2].
    fn quad(x0: f32, z: f32) -> Quad {
        Quad {
            origin: Vec3::new(x0, 0.1, z),
            u: Vec3::new(0.2, 0.0, 0.0),
            v: Vec3::new(0.0, 0.2, 0.0),
            normal: Vec3::Z,
            voxel: [0; 3],
            twist: Vec3::ZERO,
        }
    }

    /// Colour σ(8·f₀ − 4) in every channel: feature 0 decides it.
    fn mlp() -> MlpWeights {
        let mut w = MlpWeights::ZERO;
        w.w0[0][0] = 1.0;
        w.w1[0][0] = 1.0;
        for k in 0..3 {
            w.w2[0][k] = 8.0;
            w.b2[k] = -4.0;
        }
        w
    }

    /// A camera on −y looks at a small quad (3 × 3 texels) in front of a
    /// larger one. Once some texels go, the G-buffers the two layers give
    /// are the ones a new rasterization gives, but for the subsamples that
    /// lost both layers, which are counted.
    #[test]
    fn the_layers_give_the_next_gbuffers() {
        use crate::bake::Silhouette;
        use crate::camera::{Camera, Intrinsics};
        let facing = Quad::facing_minus_y;
        let p = 3;
        let geo = Geometry::in_cube(
            vec![
                facing(Vec3::new(0.0, -0.5, 0.0), 0.6),
                facing(Vec3::new(0.0, 0.0, 0.0), 1.0),
            ],
            vec![true; 18],
        );
        let k = Intrinsics::from_fov_x(0.7, 24, 24);
        let cam = Camera::look_at(Vec3::new(0.0, -4.0, 0.0), Vec3::ZERO, Vec3::Z, k);
        let image = image::RgbaImage::from_pixel(24, 24, image::Rgba([90, 140, 200, 255]));
        let views = [BakeView {
            camera: cam,
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        for supersample in [false, true] {
            let peeled = peel(&geo, p, &views, supersample, false).unwrap();
            assert!(peeled
                .pixels()
                .any(|px| px.front[0] < 9 && px.behind[0] >= 9));
            // Front texels 0 and 4 go: exact. Then also the back quad's
            // centre, behind them: lost where both go.
            let mut pruned = geo.clone();
            pruned.opacity[0] = false;
            pruned.opacity[4] = false;
            let (derived, lost) = peeled.gbuffers(&pruned.opacity, supersample);
            let fresh = gbuffer::of_geometry(&pruned, p, &views, supersample).unwrap();
            assert_eq!(lost, 0);
            assert_eq!(derived.pixels, fresh.pixels, "supersample {supersample}");
            assert_eq!(derived.subsamples, fresh.subsamples);
            assert_eq!(derived.per_view, fresh.per_view);
            pruned.opacity[9 + 4] = false;
            let (_, lost) = peeled.gbuffers(&pruned.opacity, supersample);
            assert!(lost > 0, "supersample {supersample}");
            // Growing: the front quad's centre and a corner start
            // transparent; the layers find them nearer than the back quad,
            // and once they are opaque again the G-buffers the layers give
            // are a new rasterization's.
            let mut holed = geo.clone();
            holed.opacity[4] = false;
            holed.opacity[0] = false;
            let peeled = peel(&holed, p, &views, supersample, true).unwrap();
            assert!(peeled.pixels().any(|px| px.nearer.contains(&4)));
            assert!(peeled.pixels().all(|px| px
                .nearer
                .iter()
                .all(|&t| t == NO_TEXEL || !holed.opacity[t as usize])));
            let (derived, lost) = peeled.gbuffers(&geo.opacity, supersample);
            let fresh = gbuffer::of_geometry(&geo, p, &views, supersample).unwrap();
            assert_eq!(lost, 0);
            assert_eq!(derived.pixels, fresh.pixels, "supersample {supersample}");
            assert_eq!(derived.subsamples, fresh.subsamples);
            // Without growing, no nearer texels.
            let plain = peel(&holed, p, &views, supersample, false).unwrap();
            assert!(plain
                .pixels()
                .all(|px| px.nearer.iter().all(|&t| t == NO_TEXEL)));
        }
    }

    /// Quad 0 (dark, f₀ = 0.1) in front of quad 1 (light, f₀ = 0.9), 2 × 2
    /// texels each with `opacity`, far apart in the lattice so their
    /// vertices are their own; and that lattice.
    /// A covered one-sample pixel showing texel `front`, `behind` behind
    /// it, nothing nearer, with photo colour `target`.
    fn removal_pixel(front: u32, behind: u32, target: [f32; 3]) -> PeelPixel {
        PeelPixel {
            front: [front, NO_TEXEL, NO_TEXEL, NO_TEXEL],
            behind: [behind, NO_TEXEL, NO_TEXEL, NO_TEXEL],
            nearer: [NO_TEXEL; SUBSAMPLES],
            dir: [0.0, 0.0, 1.0],
            target,
            cov: 255,
        }
    }

    fn dark_before_light(opacity: Vec<bool>) -> (Geometry, FeatureGrid) {
        let p = 2;
        let geo = Geometry {
            cube: Aabb {
                min: Vec3::ZERO,
                max: Vec3::ONE,
            },
            voxel: 0.25,
            shell_voxels: 2,
            full_voxels: 0,
            quads: vec![quad(0.0, 0.1), quad(0.7, 0.9)],
            opacity,
        };
        let points: Vec<Vec3> = (0..8).map(|t| geo.texel_point(p, t)).collect();
        let mut grid = FeatureGrid::new(&geo.cube, 4, &points);
        for (t, x) in points.iter().enumerate() {
            let f0 = if t < 4 { 0.1 } else { 0.9 };
            for &s in &grid.taps(*x).unwrap().slot {
                grid.values[s as usize] = [f0, 0.5, 0.5, 0.0, 0.5, 0.5, 0.5, 0.0];
            }
        }
        (geo, grid)
    }

    #[test]
    fn the_settings_text_names_the_optional_settings_only_when_set() {
        let mut v = VisibilitySettings {
            tune_share: 1.0,
            ..Default::default()
        };
        assert_eq!(
            format!("{v:?}"),
            "VisibilitySettings { rounds: 2, margin: 0.01 }"
        );
        v.grow = Some(0.4);
        assert!(format!("{v:?}").ends_with("grow: 0.4 }"), "{v:?}");
        v.block = 2;
        assert!(format!("{v:?}").ends_with("grow: 0.4, block: 2 }"), "{v:?}");
        v.block = 1;
        assert!(format!("{v:?}").ends_with("grow: 0.4, block: 1 }"), "{v:?}");
        v.tune_share = 0.25;
        assert!(
            format!("{v:?}").ends_with("block: 1, tune_share: 0.25 }"),
            "{v:?}"
        );
        v.keep_behind = true;
        assert!(
            format!("{v:?}").ends_with("tune_share: 0.25, keep_behind: true }"),
            "{v:?}"
        );
        v.keep_novel = true;
        assert!(
            format!("{v:?}").ends_with("keep_behind: true, keep_novel: \"first round\" }"),
            "{v:?}"
        );
    }

    #[test]
    fn the_quads_behind_are_those_some_layer_behind_lies_on() {
        // p = 2: texels 0–3 on quad 0, 4–7 on quad 1, 8–11 on quad 2.
        let peel = Peel {
            views: vec![
                vec![
                    removal_pixel(0, 9, [1.0; 3]),
                    removal_pixel(1, NO_TEXEL, [1.0; 3]),
                ],
                vec![removal_pixel(5, 11, [1.0; 3])],
            ],
            tiles: (1, 0),
        };
        assert_eq!((peel.len(), peel.is_empty()), (3, false));
        assert_eq!(peel.behind_quads(4, 4), [false, false, true, false]);
        // A texel past the quads counted is ignored.
        assert_eq!(peel.behind_quads(2, 4), [false, false]);
    }

    #[test]
    fn the_rounds_epochs_add_up_and_split_evenly_at_share_one() {
        for (total, rounds, share) in [
            (3.0f32, 2u32, 1.0f32),
            (2.5, 2, 0.25),
            (1.0, 1, 0.5),
            (3.0, 0, 0.5),
        ] {
            let e: Vec<f32> = (0..=rounds)
                .map(|r| round_epochs(total, rounds, share, r))
                .collect();
            assert!((e.iter().sum::<f32>() - total).abs() < 1e-5, "{e:?}");
            for &x in &e[..rounds as usize] {
                assert!((x - share * e[rounds as usize]).abs() < 1e-6, "{e:?}");
            }
        }
        // Share 1 is the even split the rounds had before, to the bit.
        assert_eq!(round_epochs(3.0, 2, 1.0, 0), 3.0 / 3.0);
        assert_eq!(round_epochs(3.0, 1, 1.0, 1), 3.0 / 2.0);
    }

    #[test]
    fn an_automatic_block_spans_at_most_a_pixel() {
        // Lego's voxel spans 5.1 px at g = 128 and 2.6 px at g = 256.
        let b = |voxel_px: f32, p: u32| {
            VisibilitySettings::default()
                .resolved(Some(voxel_px), p)
                .block
        };
        assert_eq!(b(5.1, 17), 3);
        assert_eq!(b(5.1, 13), 2);
        assert_eq!(b(5.1, 9), 1);
        assert_eq!(b(5.1, 5), 1);
        assert_eq!(b(2.6, 17), 6);
        assert_eq!(b(10.2, 17), 1);
        // Texel-sized blocks never wider than a pixel, whatever p.
        for p in 1..=64 {
            for voxel_px in [0.5f32, 1.0, 2.6, 5.1, 20.0] {
                let block = b(voxel_px, p);
                assert!((1..=MAX_AUTO_BLOCK).contains(&block));
                if block > 1 {
                    assert!(block as f32 * voxel_px / p as f32 <= BLOCK_SPAN_PX * (1.0 + 1e-5));
                }
            }
        }
        // Unknown, degenerate or tiny sizes.
        let auto = VisibilitySettings::default();
        assert_eq!(auto.resolved(None, 17).block, 1);
        assert_eq!(auto.resolved(Some(f32::NAN), 17).block, 1);
        assert_eq!(auto.resolved(Some(0.0), 17).block, 1);
        assert_eq!(auto.resolved(Some(1e-30), 17).block, MAX_AUTO_BLOCK);
        // A block told stays.
        let told = VisibilitySettings { block: 2, ..auto };
        assert_eq!(told.resolved(Some(5.1), 17).block, 2);
    }

    #[test]
    fn a_transparent_texel_comes_only_where_the_photos_show_it() {
        let p = 2;
        // Quad 0 transparent in front of quad 1.
        let (mut geo, grid) =
            dark_before_light(vec![false, false, false, false, true, true, true, true]);
        let (dark, light) = ([0.02f32; 3], [0.98f32; 3]);
        let one = |t: u32| [t, NO_TEXEL, NO_TEXEL, NO_TEXEL];
        let px = |front: u32, nearer: u32, target: [f32; 3], cov: u8| PeelPixel {
            front: one(front),
            behind: one(NO_TEXEL),
            nearer: one(nearer),
            dir: [0.0, 0.0, 1.0],
            target,
            cov,
        };
        let pixels = [
            // Texel 0: the photos show it, not the light quad: it comes.
            px(4, 0, dark, 255),
            px(5, 0, dark, 255),
            // Texel 1: the photos show the light quad: it stays out.
            px(6, 1, light, 255),
            // Texel 2: in front of nothing, where the photos show
            // background: it stays out.
            px(NO_TEXEL, 2, [1.0; 3], 0),
            // Texel 3: seen nowhere nearer: not judged.
            px(7, NO_TEXEL, light, 255),
        ];
        let settings = VisibilitySettings {
            rounds: 1,
            margin: 0.0,
            grow: Some(0.0),
            block: 1,
            tune_share: 1.0,
            keep_behind: false,
            keep_novel: false,
        };
        let r = prune(
            &mut geo,
            p,
            &[pixels.to_vec()],
            &grid,
            &mlp(),
            false,
            &settings,
        );
        assert_eq!((r.nearer_texels, r.added_texels), (3, 1), "{r:?}");
        assert_eq!(
            geo.opacity,
            [true, false, false, false, true, true, true, true],
            "{r:?}"
        );
        assert_eq!(r.removed_texels, 0);
        assert!(r.error_change < 0.0);
    }

    #[test]
    fn a_texel_goes_only_where_what_lies_behind_it_matches_the_photos_better() {
        let p = 2;
        let (mut geo, grid) = dark_before_light(vec![true; 8]);
        let mlp = mlp();
        let every = [PeelPixel {
            front: [0, 1, 2, 3],
            behind: [4, 5, 6, 7],
            nearer: [NO_TEXEL; SUBSAMPLES],
            dir: [0.0, 0.0, 1.0],
            target: [0.0; 3],
            cov: 255,
        }];
        let shade = |t: u32| {
            let (b, _) = texel_bytes(&geo, p, &grid, &[every.to_vec()]);
            let f = std::array::from_fn(|c| net::decode(c, b[t as usize][c]));
            let y = net::to_u8(net::forward(&mlp, &net::input(&f, [0.0, 0.0, 1.0])).y);
            y.map(|v| f32::from(v) / 255.0)
        };
        let (dark, light) = (shade(0), shade(4));
        assert!(dark[0] < 0.1 && light[0] > 0.9, "{dark:?} {light:?}");
        let px = removal_pixel;
        let pixels = [
            // Texel 0: the photos show the light quad behind it: it goes.
            px(0, 4, light),
            px(0, 4, light),
            // Texel 1: the photos show it: it stays.
            px(1, 5, dark),
            // Texel 2: the photos show background where nothing is behind.
            px(2, NO_TEXEL, [1.0; 3]),
            // Texel 3: one pixel each way, the dark one exact: it stays.
            px(3, 7, dark),
            px(3, 7, [0.6; 3]),
        ];
        let mut settings = VisibilitySettings {
            margin: 0.0,
            ..Default::default()
        };
        let mut g = geo.clone();
        let r = prune(&mut g, p, &[pixels.to_vec()], &grid, &mlp, false, &settings);
        assert_eq!(r.pixels, 6);
        assert_eq!(r.shown_texels, 4);
        assert_eq!(
            g.opacity,
            [false, true, false, true, true, true, true, true],
            "{r:?}"
        );
        assert!(r.error_change < 0.0);
        // A margin above a texel's gain keeps it.
        settings.margin = 10.0;
        let r = prune(
            &mut geo,
            p,
            &[pixels.to_vec()],
            &grid,
            &mlp,
            false,
            &settings,
        );
        assert_eq!(r.removed_texels, 0);
        assert!(geo.opacity.iter().all(|&o| o));
    }

    /// Two texels of one 2 × 2 block each lower their pixels' error by
    /// less than the margin: texel by texel both stay, judged as a block
    /// both go (and its unshown texels stay). A shown texel the photos
    /// confirm, in the same block, pulls the block's sum back.
    #[test]
    fn a_block_decides_what_its_texels_alone_cannot() {
        let p = 2;
        let (geo, grid) = dark_before_light(vec![true; 8]);
        let (dark, light) = ([0.02f32; 3], [0.98f32; 3]);
        let px = removal_pixel;
        // Texels 0 and 1 (quad 0's block) hide the light quad the photos
        // show: each gains about 3 × 0.9² ≈ 2.5 when it goes.
        let hiding = [px(0, 4, light), px(1, 5, light)];
        let mut settings = VisibilitySettings {
            margin: 3.0,
            ..Default::default()
        };
        let mut alone = geo.clone();
        let r = prune(
            &mut alone,
            p,
            &[hiding.to_vec()],
            &grid,
            &mlp(),
            false,
            &settings,
        );
        assert_eq!(r.removed_texels, 0, "{r:?}");
        settings.block = 2;
        let mut blocked = geo.clone();
        let r = prune(
            &mut blocked,
            p,
            &[hiding.to_vec()],
            &grid,
            &mlp(),
            false,
            &settings,
        );
        assert_eq!(r.removed_texels, 2, "{r:?}");
        assert_eq!(
            blocked.opacity,
            [false, false, true, true, true, true, true, true]
        );
        // Texel 2, in the same block, is what the photos show there.
        let mixed = [hiding[0], hiding[1], px(2, 6, dark)];
        let mut kept = geo.clone();
        let r = prune(
            &mut kept,
            p,
            &[mixed.to_vec()],
            &grid,
            &mlp(),
            false,
            &settings,
        );
        assert_eq!(r.removed_texels, 0, "{r:?}");
        // The sums themselves: same state and shown only, per block.
        let d = [-1.0, -2.0, 4.0, 8.0, 16.0, 0.0, 0.0, 0.0];
        let shown = [true, true, true, true, true, false, false, false];
        let opacity = [true, true, false, true, true, true, true, true];
        let sums = |block| -> Vec<f64> {
            (0..8)
                .map(|t| {
                    let base = t / 4 * 4;
                    let patch = &opacity[base..base + 4];
                    match shown[t] {
                        true => block_sum(patch, base, t % 4, 2, block, |u| d[u], |u| shown[u]),
                        false => 0.0,
                    }
                })
                .collect()
        };
        assert_eq!(sums(2), vec![5.0, 5.0, 4.0, 5.0, 16.0, 0.0, 0.0, 0.0]);
        assert_eq!(sums(1), vec![-1.0, -2.0, 4.0, 8.0, 16.0, 0.0, 0.0, 0.0]);
    }
}
