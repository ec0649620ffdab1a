//! The host renderer: the core's tile rasterizer and fixed-point shader,
//! tiles in parallel (rayon), into an `RgbaImage` composited over white.
//!
//! Per frame: every quad is projected once ([`ScreenQuad::project`]) and
//! binned to the 32 × 32 tiles its box touches; each tile then runs the same
//! [`TileRenderer`] a microcontroller runs, drawing its quads nearest
//! first and skipping those already hidden (`near_first`,
//! [`TileRenderer::draw_by_id`]): the samples of drawing them in asset
//! order, so results equal [`nerflex_core::raster::render_frame`]'s, with
//! fewer alpha tests (the tile counters differ). It then shades its covered
//! pixels once. `--float` shades the same G-buffer with
//! the `f32` MLP ([`shade_f32`]) instead.
//!
//! [`try_render_scene_narrow`] shades with the core's narrow shader
//! instead (16-bit weights and activations, [`nerflex_core::shader::narrow`]),
//! eight pixels at a time: AVX2 when the CPU has it (run-time detection),
//! else the portable batch — bit-identical to each other and to the narrow
//! shader's per-pixel path. Objects whose weights fail the narrow shader's
//! accuracy check ([`narrow_tables`]) keep the exact shader.
//!
//! By default ([`RenderOptions::supersample`]) a frame is rasterized at
//! twice the side and resolved 2 × 2, as MobileNeRF's viewer renders (its
//! G-buffer at twice the canvas, linearly filtered before the MLP pass):
//! per pixel and object, the covered subsamples' texel bytes are averaged
//! and shaded once. Binary texel opacity then gives anti-aliased edges; on
//! lego's held-out views it is worth about 1 dB (`docs/baking.md`,
//! "Session 6"). The device model is unchanged by it: it counts set-up
//! quads and shaded pixels (one MLP per pixel either way), and its
//! throughput factor is calibrated against the paper's FPS, which were
//! measured on MobileNeRF's viewer, supersampling included.
//!
//! Output: `alpha` = the covered fraction of the pixel (255 or 0 with one
//! sample per pixel) and `rgb` the objects' colour, straight (not
//! premultiplied): composited over white, as the metrics do, a partly
//! covered pixel blends with the white background (MobileNeRF's viewer
//! convention).

use crate::asset::Asset;
use crate::camera::Camera;
use crate::prefetch::prefetch;
use image::{Rgba, RgbaImage};
use nerflex_core::raster::{
    mean_texel, AlphaTest, Part, RasterError, Sample, ScreenQuad, TileRenderer, TileStats, View,
    BACKGROUND, SUPERSAMPLE,
};
use nerflex_core::shader::narrow::batch::{self, BatchInput, LANES};
use nerflex_core::shader::narrow::{check_samples, NarrowMlp, INPUT_PAIRS};
use nerflex_core::shader::{shade_f32, MlpWeights, ShaderError};
/// Re-exported: renders run on the current rayon pool, so a caller can
/// pick the thread count with `rayon::ThreadPool::install` (e.g. one core).
pub use rayon;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// Tile side in pixels.
pub const TILE: usize = 32;

/// How to render (default: fixed-point shader, 2 × 2 supersampling).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderOptions {
    /// Shade with the `f32` MLP instead of the fixed-point one.
    pub float: bool,
    /// 2 × 2 supersampling, as MobileNeRF's viewer renders: the G-buffer at
    /// twice the side, each pixel's covered subsamples' texel bytes
    /// averaged per object ([`nerflex_core::raster::mean_texel`]), the MLP
    /// once per pixel and object, blended over white by coverage
    /// (the output's alpha is the covered fraction, its colour straight).
    /// Binary texel opacity then gives anti-aliased edges. The rasterizer's
    /// side limit then applies to the doubled view: a camera over 8192
    /// pixels a side is rejected (`RasterError::BadView`).
    pub supersample: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            float: false,
            supersample: true,
        }
    }
}

/// What a frame cost.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderStats {
    /// Quads (and lone triangles) in the scene.
    pub quads_total: u32,
    /// Quads with at least one triangle projected onto the image.
    pub quads_drawn: u32,
    /// Distinct quads owning at least one final pixel.
    pub quads_visible: u32,
    /// Covered pixels, each shaded exactly once.
    pub pixels_shaded: u64,
    /// Per-tile raster counters, summed.
    pub tiles: TileStats,
    /// Wall time of projection, rasterization and shading.
    pub time: Duration,
    /// Set when the camera was rejected and nothing was drawn.
    pub camera_error: Option<RasterError>,
}

/// The core rasterizer's view of a camera.
pub fn view_of(camera: &Camera) -> Result<View, RasterError> {
    let k = &camera.intrinsics;
    View::new(camera.c2w, k.fx, k.fy, k.cx, k.cy, k.width, k.height)
}

/// One part per shape of each asset, with its MLP's float weights.
fn parts<'a>(assets: &[&'a Asset]) -> (Vec<Part<'a>>, Vec<&'a MlpWeights>) {
    let mut parts = Vec::new();
    let mut weights = Vec::new();
    for a in assets {
        for s in &a.shapes {
            parts.push(Part {
                quads: &s.quads,
                atlas: s.atlas.atlas(),
                mlp: a.mlp.fixed(),
            });
            weights.push(a.mlp.weights());
        }
    }
    (parts, weights)
}

/// Result of one tile: its pixels (RGBA, row-major), counters and the ids
/// of the quads it shows.
struct TileOut {
    rect: (u32, u32, u32, u32),
    pixels: Vec<[u8; 4]>,
    covered: u64,
    stats: TileStats,
    visible: Vec<u32>,
}

/// Each quad's [`ScreenQuad::nearest`] `1/w`, as bits that sort like it
/// (it is never negative): the key [`near_first`] sorts on.
pub(crate) fn nearness(projected: &[ScreenQuad]) -> Vec<u32> {
    let mut out = Vec::new();
    nearness_into(projected, &mut out);
    out
}

/// [`nearness`] into `out` (cleared first), keeping its memory.
pub(crate) fn nearness_into(projected: &[ScreenQuad], out: &mut Vec<u32>) {
    out.clear();
    out.extend(projected.iter().map(|sq| sq.nearest().to_bits()));
}

/// Quads ahead [`near_first`] asks the cache for.
const PREFETCH_AHEAD: usize = 8;

/// A bin's quads (indices into `projected`, each with its `nearness`)
/// nearest first, ties to the lower index, sorted in `keyed` (scratch):
/// for [`TileRenderer::draw_by_id`] (frames and the bake's G-buffers) and
/// [`TwoLayers::draw_at`](nerflex_core::raster::TwoLayers::draw_at).
/// Drawn near first, most fragments lie behind what is drawn already and
/// skip their alpha test, and whole
/// quads can be skipped ([`TileRenderer::hides`]); a lego bake's views
/// are otherwise mostly drawn back to front (two thirds of the two-layer
/// draw's fragments came nearer than the front). Only the bin is sorted,
/// not the quads, so a tile reads the same quads' memory as in index
/// order, if not in its order: the quads a few turns ahead are
/// prefetched.
pub(crate) fn near_first<'a>(
    bin: &[u32],
    projected: &'a [ScreenQuad],
    nearness: &[u32],
    keyed: &'a mut Vec<u64>,
) -> impl Iterator<Item = (u32, &'a ScreenQuad, f32)> + 'a {
    // `1/w ≥ 0`, so its bits sort as it does; complemented: nearest first.
    keyed.clear();
    keyed.extend(bin.iter().map(|&i| {
        let near = nearness.get(i as usize).copied().unwrap_or(0);
        (u64::from(!near) << 32) | u64::from(i)
    }));
    keyed.sort_unstable();
    let keyed: &'a [u64] = keyed;
    keyed.iter().enumerate().filter_map(move |(j, &k)| {
        if let Some(sq) = keyed
            .get(j + PREFETCH_AHEAD)
            .and_then(|&a| projected.get(a as u32 as usize))
        {
            prefetch(sq);
        }
        let i = k as u32;
        let near = f32::from_bits(!((k >> 32) as u32));
        projected.get(i as usize).map(|sq| (i, sq, near))
    })
}

/// Draws a bin's quads into `tile` (begun) nearest first (ids ascend with
/// the index), the hidden ones skipped: the samples of drawing them all
/// in order ([`near_first`], [`TileRenderer::draw_by_id`]); `alpha` gives
/// a part's alpha test.
pub(crate) fn draw_near_first<'p, A: AlphaTest + ?Sized + 'p>(
    tile: &mut TileRenderer<TILE, TILE>,
    bin: &[u32],
    projected: &[ScreenQuad],
    nearness: &[u32],
    keyed: &mut Vec<u64>,
    alpha: impl Fn(u16) -> Option<&'p A>,
) {
    for (_, sq, near) in near_first(bin, projected, nearness, keyed) {
        if tile.hides(sq, near) {
            continue;
        }
        if let Some(a) = alpha(sq.part) {
            tile.draw_by_id(sq, a);
        }
    }
}

/// Projects, bins and rasterizes; `shade` turns each finished tile into its output.
fn run_tiles<F>(
    view: &View,
    parts: &[Part],
    shade: F,
) -> Result<(Vec<TileOut>, u32, u32), RasterError>
where
    F: Fn(&TileRenderer<TILE, TILE>) -> Vec<[u8; 4]> + Sync,
{
    // Flatten (part, quad) with frame-wide ids.
    let mut list: Vec<(u16, &nerflex_core::raster::Quad)> = Vec::new();
    for (pi, p) in parts.iter().enumerate() {
        let pi = u16::try_from(pi).map_err(|_| RasterError::TooManyQuads)?;
        list.extend(p.quads.iter().map(|q| (pi, q)));
    }
    let total = u32::try_from(list.len()).map_err(|_| RasterError::TooManyQuads)?;
    let projected: Vec<ScreenQuad> = list
        .par_iter()
        .enumerate()
        .filter_map(|(id, (pi, q))| ScreenQuad::project(view, q, *pi, id as u32))
        .collect();
    let drawn = projected.len() as u32;
    let t = TILE as u32;
    let (bins, tx) = tile_bins(&projected, view, t);
    let nearness = nearness(&projected);
    // One task per row of tiles, each with one renderer (16 KiB) reused
    // across its tiles: enough tasks to balance, few set-ups.
    let tiles: Vec<TileOut> = bins
        .par_chunks(tx as usize)
        .enumerate()
        .flat_map_iter(|(row, bins_row)| {
            let mut tile = Box::new(TileRenderer::<TILE, TILE>::new());
            let mut keyed = Vec::new();
            let mut out = Vec::with_capacity(bins_row.len());
            for (col, bin) in bins_row.iter().enumerate() {
                tile.begin(view, col as u32 * t, row as u32 * t);
                if bin.is_empty() {
                    // Nothing touches this tile: background, no per-pixel work.
                    let (_, _, w, h) = tile.rect();
                    out.push(TileOut {
                        rect: tile.rect(),
                        pixels: vec![px(None); (w * h) as usize],
                        covered: 0,
                        stats: TileStats::default(),
                        visible: Vec::new(),
                    });
                    continue;
                }
                draw_near_first(&mut tile, bin, &projected, &nearness, &mut keyed, |part| {
                    parts.get(part as usize).map(|p| &p.atlas)
                });
                let mut visible = Vec::new();
                tile.for_each_sample(|_, _, s| {
                    if let Some(s) = s {
                        visible.push(s.quad);
                    }
                });
                out.push(TileOut {
                    rect: tile.rect(),
                    pixels: shade(&tile),
                    covered: u64::from(tile.covered()),
                    stats: tile.stats(),
                    visible,
                });
            }
            out
        })
        .collect();
    Ok((tiles, total, drawn))
}

fn px(rgb: Option<[u8; 3]>) -> [u8; 4] {
    match rgb {
        Some([r, g, b]) => [r, g, b, 255],
        None => [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 0],
    }
}

/// Renders several assets (objects) together, each with its own MLP.
pub fn try_render_scene(
    assets: &[&Asset],
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(RgbaImage, RenderStats), RasterError> {
    render_with(assets, camera, opts, None)
}

/// The narrow shader's tables for each asset, `None` where its weights fail
/// the accuracy check (`NarrowMlp::choose` on `check_samples(2048, 8)`: the
/// firmware build's check).
pub fn narrow_tables(assets: &[&Asset]) -> Result<Vec<Option<NarrowMlp>>, ShaderError> {
    assets
        .iter()
        .map(|a| Ok(NarrowMlp::choose(a.mlp.weights(), || check_samples(2048, 8))?.map(|(m, _)| m)))
        .collect()
}

/// [`try_render_scene`] with the narrow shader, batched (see the module
/// docs); `narrow[i]` are asset `i`'s tables from [`narrow_tables`]
/// (missing or `None`: the exact shader). `opts.float` still selects `f32`.
pub fn try_render_scene_narrow(
    assets: &[&Asset],
    camera: &Camera,
    opts: &RenderOptions,
    narrow: &[Option<NarrowMlp>],
) -> Result<(RgbaImage, RenderStats), RasterError> {
    render_with(assets, camera, opts, Some(narrow))
}

/// Whether the batched narrow shader may use AVX2 on this CPU.
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Shades one batch (lanes `0..slots.len()` of `x`) into `out[slot]`.
fn flush_batch(m: &NarrowMlp, x: &BatchInput, slots: &[usize], out: &mut [[u8; 4]], avx2: bool) {
    #[cfg(target_arch = "x86_64")]
    let rgb = if avx2 {
        // SAFETY: `avx2` is true only when the CPU reports AVX2.
        #[allow(unsafe_code)]
        unsafe {
            batch::avx2::shade(m, x)
        }
    } else {
        batch::shade_portable(m, x)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let rgb = {
        let _ = avx2;
        batch::shade_portable(m, x)
    };
    for (&i, c) in slots.iter().zip(rgb) {
        if let Some(p) = out.get_mut(i) {
            *p = px(Some(c));
        }
    }
}

/// A tile shaded by the narrow shader in batches of [`LANES`] pixels of the
/// same MLP; parts without narrow tables take the exact per-pixel path.
fn shade_tile_narrow(
    tile: &TileRenderer<TILE, TILE>,
    view: &View,
    parts: &[Part],
    narrow: &[Option<&NarrowMlp>],
    avx2: bool,
) -> Vec<[u8; 4]> {
    let (x0, y0, w, h) = tile.rect();
    let mut out = vec![px(None); (w * h) as usize];
    let mut x: BatchInput = [[0; LANES]; INPUT_PAIRS];
    let mut slots = [0usize; LANES];
    let mut n = 0;
    let mut cur: Option<&NarrowMlp> = None;
    for ty in 0..h {
        for tx in 0..w {
            let Some(s) = tile.sample(tx, ty) else {
                continue;
            };
            let i = (ty * w + tx) as usize;
            let (Some(part), m) = (
                parts.get(s.part as usize),
                narrow.get(s.part as usize).copied().flatten(),
            ) else {
                continue;
            };
            let Some(m) = m else {
                out[i] = px(tile.shade_pixel(view, parts, tx, ty));
                continue;
            };
            if let Some(c) = cur.filter(|c| !std::ptr::eq(*c, m)) {
                flush_batch(c, &x, &slots[..n], &mut out, avx2);
                n = 0;
            }
            cur = Some(m);
            let (f0, f1) = part
                .atlas
                .texel(u32::from(s.texel[0]), u32::from(s.texel[1]));
            batch::set_lane(&mut x, n, f0, f1, view.pixel_dir(x0 + tx, y0 + ty));
            slots[n] = i;
            n += 1;
            if n == LANES {
                flush_batch(m, &x, &slots, &mut out, avx2);
                n = 0;
            }
        }
    }
    if let (Some(m), true) = (cur, n > 0) {
        // Lanes n.. hold stale inputs; their results are dropped.
        flush_batch(m, &x, &slots[..n], &mut out, avx2);
    }
    out
}

fn render_with(
    assets: &[&Asset],
    camera: &Camera,
    opts: &RenderOptions,
    narrow: Option<&[Option<NarrowMlp>]>,
) -> Result<(RgbaImage, RenderStats), RasterError> {
    // The narrow shader's batches have no supersampled path: it renders
    // one sample per pixel.
    if opts.supersample && narrow.is_none() {
        return render_supersampled(assets, camera, opts);
    }
    let start = Instant::now();
    let view = view_of(camera)?;
    let (parts, weights) = parts(assets);
    // Narrow tables per part (each shape of asset i uses asset i's).
    let narrow_parts: Option<Vec<Option<&NarrowMlp>>> = narrow.map(|n| {
        assets
            .iter()
            .enumerate()
            .flat_map(|(i, a)| {
                let m = n.get(i).and_then(|m| m.as_ref());
                a.shapes.iter().map(move |_| m)
            })
            .collect()
    });
    let avx2 = avx2();
    let shade = |tile: &TileRenderer<TILE, TILE>| -> Vec<[u8; 4]> {
        let (_, _, w, h) = tile.rect();
        if let (false, Some(np)) = (opts.float, &narrow_parts) {
            return shade_tile_narrow(tile, &view, &parts, np, avx2);
        }
        let mut out = Vec::with_capacity((w * h) as usize);
        if opts.float {
            tile.for_each_sample(|x, y, s: Option<Sample>| {
                let rgb = s.and_then(|s| {
                    let part = parts.get(s.part as usize)?;
                    let w = weights.get(s.part as usize)?;
                    let (f0, f1) = part
                        .atlas
                        .texel(u32::from(s.texel[0]), u32::from(s.texel[1]));
                    Some(shade_f32(w, f0, f1, view.pixel_dir_f32(x, y)))
                });
                out.push(px(rgb));
            });
        } else {
            for y in 0..h {
                for x in 0..w {
                    out.push(px(tile.shade_pixel(&view, &parts, x, y)));
                }
            }
        }
        out
    };
    let (tiles, total, drawn) = run_tiles(&view, &parts, shade)?;
    Ok(assemble(&view, &tiles, (total, drawn), 1, start))
}

/// The image and counters of a frame's shaded tiles; `ss` subsamples per
/// pixel side (tile rectangles are in subsample coordinates).
fn assemble(
    view: &View,
    tiles: &[TileOut],
    (total, drawn): (u32, u32),
    ss: u32,
    start: Instant,
) -> (RgbaImage, RenderStats) {
    let mut img = RgbaImage::new(view.width(), view.height());
    let mut stats = RenderStats {
        quads_total: total,
        quads_drawn: drawn,
        ..Default::default()
    };
    let mut seen = vec![0u32; (total as usize).div_ceil(32)];
    for t in tiles {
        let (x0, y0, w, _) = t.rect;
        let (x0, y0, w) = (x0 / ss, y0 / ss, (w / ss).max(1));
        for (i, p) in t.pixels.iter().enumerate() {
            let (x, y) = (x0 + i as u32 % w, y0 + i as u32 / w);
            if x < img.width() && y < img.height() {
                img.put_pixel(x, y, Rgba(*p));
            }
        }
        // Shaded pixels: covered ones (one sample), or any subsample covered.
        stats.pixels_shaded += if ss == 1 {
            t.covered
        } else {
            t.pixels.iter().filter(|p| p[3] > 0).count() as u64
        };
        stats.tiles.add(&t.stats);
        for &q in &t.visible {
            if let Some(word) = seen.get_mut((q / 32) as usize) {
                *word |= 1 << (q % 32);
            }
        }
    }
    stats.quads_visible = seen.iter().map(|w| w.count_ones()).sum();
    stats.time = start.elapsed();
    (img, stats)
}

/// The view at [`SUPERSAMPLE`] times the side: subsample `(sx, sy)` lies
/// at `((sx + ½)/2, (sy + ½)/2)` in the output's pixel coordinates.
pub fn supersampled_view(camera: &Camera) -> Result<View, RasterError> {
    let k = &camera.intrinsics;
    let f = SUPERSAMPLE as f32;
    View::new(
        camera.c2w,
        k.fx * f,
        k.fy * f,
        k.cx * f,
        k.cy * f,
        k.width.saturating_mul(SUPERSAMPLE),
        k.height.saturating_mul(SUPERSAMPLE),
    )
}

/// A texel's two RGBA8 feature bytes.
type Texel = ([u8; 4], [u8; 4]);

/// [`render_with`] under [`RenderOptions::supersample`]: tiles of the
/// doubled view, each resolved to its quarter of output pixels.
fn render_supersampled(
    assets: &[&Asset],
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(RgbaImage, RenderStats), RasterError> {
    let start = Instant::now();
    let view = view_of(camera)?;
    let big = supersampled_view(camera)?;
    let (parts, weights) = parts(assets);
    let ss = SUPERSAMPLE;
    let shade = |tile: &TileRenderer<TILE, TILE>| -> Vec<[u8; 4]> {
        let (x0, y0, w, h) = tile.rect();
        let (ow, oh) = (w / ss, h / ss);
        let mut out = Vec::with_capacity((ow * oh) as usize);
        // (part, texel bytes) of the covered subsamples of one pixel.
        let mut subs: Vec<(u16, Texel)> = Vec::with_capacity(4);
        let mut group: Vec<Texel> = Vec::with_capacity(4);
        for oy in 0..oh {
            for ox in 0..ow {
                subs.clear();
                for dy in 0..ss {
                    for dx in 0..ss {
                        let Some(s) = tile.sample(ox * ss + dx, oy * ss + dy) else {
                            continue;
                        };
                        let Some(part) = parts.get(s.part as usize) else {
                            continue;
                        };
                        let t = part
                            .atlas
                            .texel(u32::from(s.texel[0]), u32::from(s.texel[1]));
                        subs.push((s.part, t));
                    }
                }
                if subs.is_empty() {
                    out.push(px(None));
                    continue;
                }
                let (x, y) = (x0 / ss + ox, y0 / ss + oy);
                let covered = subs.len() as u32;
                let mut weighted = [0u32; 3];
                // One MLP per object the pixel shows (objects differ in MLPs).
                while let Some(&(part, _)) = subs.first() {
                    group.clear();
                    group.extend(subs.iter().filter(|s| s.0 == part).map(|s| s.1));
                    let (f0, f1) = mean_texel(&group);
                    let rgb = if opts.float {
                        weights
                            .get(part as usize)
                            .map(|w| shade_f32(w, f0, f1, view.pixel_dir_f32(x, y)))
                    } else {
                        parts
                            .get(part as usize)
                            .map(|p| p.mlp.shade(f0, f1, view.pixel_dir(x, y)))
                    }
                    .unwrap_or(BACKGROUND);
                    for (acc, c) in weighted.iter_mut().zip(rgb) {
                        *acc += group.len() as u32 * u32::from(c);
                    }
                    subs.retain(|s| s.0 != part);
                }
                // Straight (not premultiplied) colour, alpha = coverage:
                // composited over white it is the coverage-weighted blend.
                let rgb = weighted.map(|v| ((2 * v + covered) / (2 * covered)).min(255) as u8);
                let a = ((covered * 255 + ss * ss / 2) / (ss * ss)) as u8;
                out.push([rgb[0], rgb[1], rgb[2], a]);
            }
        }
        out
    };
    let (tiles, total, drawn) = run_tiles(&big, &parts, shade)?;
    Ok(assemble(&view, &tiles, (total, drawn), ss, start))
}

/// Renders one asset (see [`try_render_scene`]). A camera the rasterizer
/// rejects (image side 0 or above 16384, non-positive focal length, a
/// non-invertible pose) draws nothing: the image is background and
/// `stats.camera_error` says why.
pub fn render(asset: &Asset, camera: &Camera, opts: &RenderOptions) -> (RgbaImage, RenderStats) {
    render_scene(&[asset], camera, opts)
}

/// [`render`] for several objects.
pub fn render_scene(
    assets: &[&Asset],
    camera: &Camera,
    opts: &RenderOptions,
) -> (RgbaImage, RenderStats) {
    match try_render_scene(assets, camera, opts) {
        Ok(r) => r,
        Err(e) => {
            let k = &camera.intrinsics;
            let (w, h) = (k.width.min(16384), k.height.min(16384));
            let img = RgbaImage::from_pixel(w, h, Rgba(px(None)));
            let stats = RenderStats {
                camera_error: Some(e),
                ..Default::default()
            };
            (img, stats)
        }
    }
}

/// Coverage of a view without shading: what the device simulator needs
/// per frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoverageStats {
    /// Quads in the scene.
    pub quads_total: u32,
    /// Quads with at least one triangle projected onto the image.
    pub quads_drawn: u32,
    /// Distinct quads owning at least one final pixel.
    pub quads_visible: u32,
    /// Covered pixels (= pixels shaded by the deferred renderer).
    pub pixels_covered: u64,
    /// Per-tile raster counters, summed.
    pub tiles: TileStats,
}

/// Coverage-only pass over several objects (parallel tiles, no shading).
pub fn coverage_scene(assets: &[&Asset], camera: &Camera) -> Result<CoverageStats, RasterError> {
    let view = view_of(camera)?;
    let (parts, _) = parts(assets);
    let (tiles, total, drawn) = run_tiles(&view, &parts, |_| Vec::new())?;
    let mut out = CoverageStats {
        quads_total: total,
        quads_drawn: drawn,
        ..Default::default()
    };
    let mut seen = vec![0u32; (total as usize).div_ceil(32)];
    for t in &tiles {
        out.pixels_covered += t.covered;
        out.tiles.add(&t.stats);
        for &q in &t.visible {
            if let Some(word) = seen.get_mut((q / 32) as usize) {
                *word |= 1 << (q % 32);
            }
        }
    }
    out.quads_visible = seen.iter().map(|w| w.count_ones()).sum();
    Ok(out)
}

/// [`coverage_scene`] for one asset.
pub fn coverage(asset: &Asset, camera: &Camera) -> Result<CoverageStats, RasterError> {
    coverage_scene(&[asset], camera)
}

/// Per `t`-pixel tile of `view` (row-major), the indices of the projected
/// quads whose box touches it, and the tiles per row.
pub(crate) fn tile_bins(projected: &[ScreenQuad], view: &View, t: u32) -> (Vec<Vec<u32>>, u32) {
    let mut bins = Vec::new();
    let tx = tile_bins_into(projected, view, t, &mut bins);
    (bins, tx)
}

/// [`tile_bins`] into `bins`, whose vectors keep their memory (a worker
/// binning view after view allocates once).
pub(crate) fn tile_bins_into(
    projected: &[ScreenQuad],
    view: &View,
    t: u32,
    bins: &mut Vec<Vec<u32>>,
) -> u32 {
    let (tx, ty) = (view.width().div_ceil(t), view.height().div_ceil(t));
    bins.iter_mut().for_each(Vec::clear);
    bins.resize_with((tx * ty) as usize, Vec::new);
    for (i, sq) in projected.iter().enumerate() {
        let [x0, y0, x1, y1] = sq.bbox;
        for by in y0 / t..=y1 / t {
            for bx in x0 / t..=x1 / t {
                bins[(by * tx + bx) as usize].push(i as u32);
            }
        }
    }
    tx
}
