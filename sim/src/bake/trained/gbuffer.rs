//! Each training view rasterized once into a G-buffer of (quad, texel)
//! ids, by the phone renderer's own tile rasterizer
//! (`nerflex_core::raster::TileRenderer`): geometry and texel opacity are
//! fixed during the fine-tune, so which texel a pixel shows never changes,
//! and it is exactly the texel `nerflex render` will show there.

use rayon::prelude::*;

use super::super::atlas::AtlasLayout;
use super::super::{BakeError, BakeView};
use crate::asset::Asset;
use crate::render::{supersampled_view, view_of};
use nerflex_core::raster::{
    AlphaBits, Quad as RasterQuad, ScreenQuad, TileRenderer, View as RasterView, SUPERSAMPLE,
};

/// Tile side of the G-buffer pass: the host renderer's.
pub(super) use crate::render::TILE;

/// Subsamples of a pixel ([`nerflex_core::raster::SUPERSAMPLE`]²).
pub const SUBSAMPLES: usize = 4;

/// One covered pixel of a training view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GPixel {
    /// The texel it shows (its first covered subsample's, under
    /// supersampling): `quad · p² + y · p + x` (re-indexed to a
    /// trained-feature slot by the caller).
    pub texel: u32,
    /// The `f32` view direction the renderer feeds the MLP at this pixel.
    pub dir: [f32; 3],
    /// The training image here composited over white, in [0, 1].
    pub target: [f32; 3],
}

/// Texels of a supersampled pixel's covered subsamples, first; the rest
/// [`NO_TEXEL`].
pub type Subsamples = [u32; SUBSAMPLES];

/// An uncovered subsample.
pub const NO_TEXEL: u32 = u32::MAX;

/// The covered entries of `s`.
#[inline]
pub fn covered(s: &Subsamples) -> &[u32] {
    let n = s.iter().take_while(|&&t| t != NO_TEXEL).count();
    &s[..n]
}

/// The G-buffers of every training view.
#[derive(Debug, Clone, Default)]
pub struct GBuffers {
    /// Covered pixels of all views, view after view.
    pub pixels: Vec<GPixel>,
    /// Under supersampling, each pixel's covered subsamples' texels
    /// (parallel to `pixels`); empty with one sample per pixel, which so
    /// carries no per-subsample storage.
    pub subsamples: Vec<Subsamples>,
    /// Covered pixels per view.
    pub per_view: Vec<usize>,
    /// The texel each covered pixel of the background (object coverage
    /// below 50 %) shows: votes against the geometry there.
    pub background: Vec<u32>,
}

/// Rasterizes every view of `asset` (quads in atlas order, `layout` the
/// atlas they were laid out with; only feat0.R = 0 matters: empty texels),
/// with 2 × 2 subsamples per pixel when `supersample` (as
/// `render::RenderOptions::supersample` renders).
pub fn rasterize(
    asset: &Asset,
    layout: &AtlasLayout,
    views: &[BakeView<'_>],
    supersample: bool,
) -> Result<GBuffers, BakeError> {
    let pages: Vec<AlphaPage> = asset
        .shapes
        .par_iter()
        .map(|s| {
            let (w, h) = s.atlas.feat0().dimensions();
            (w, h, alpha_bits(s.atlas.feat0()))
        })
        .collect();
    let quads: Vec<&[RasterQuad]> = asset.shapes.iter().map(|s| &s.quads[..]).collect();
    rasterize_bits(&quads, &pages, layout, views, supersample)
}

/// An atlas page's alpha test: width, height and [`AlphaBits`]' words.
pub(super) type AlphaPage = (u32, u32, Vec<u64>);

/// [`rasterize`] of the pages' quads (`quads[i]` on page `i`) through their
/// alpha bits: the only atlas read of this pass, per fragment, and the bits
/// stay in cache where RGBA pages do not.
fn rasterize_bits(
    quads: &[&[RasterQuad]],
    pages: &[AlphaPage],
    layout: &AtlasLayout,
    views: &[BakeView<'_>],
    supersample: bool,
) -> Result<GBuffers, BakeError> {
    let masks = alpha_masks(pages)?;
    type ViewPixels = (Vec<GPixel>, Vec<Subsamples>, Vec<u32>);
    let per: Vec<Result<ViewPixels, BakeError>> = views
        .par_iter()
        .enumerate()
        .map_init(Binned::default, |binned, (vi, v)| {
            let (out_view, view, ss) = views_of(vi, v, supersample)?;
            binned.rebin(quads, &view);
            let Binned {
                projected,
                nearness,
                bins,
                tx,
            } = &*binned;
            let tx = *tx;
            let mut keyed = Vec::new();
            let t = TILE as u32;
            let mut tile = Box::new(TileRenderer::<TILE, TILE>::new());
            let mut out = Vec::new();
            let mut background = Vec::new();
            let mut subs = Vec::new();
            for (b, bin) in bins.iter().enumerate() {
                if bin.is_empty() {
                    continue;
                }
                let (bx, by) = (b as u32 % tx, b as u32 / tx);
                tile.begin(&view, bx * t, by * t);
                draw_near_first(&mut tile, bin, projected, nearness, &mut keyed, |part| {
                    masks.get(part as usize)
                });
                let (x0, y0, w, h) = tile.rect();
                for oy in 0..h / ss {
                    for ox in 0..w / ss {
                        let mut texels = [NO_TEXEL; SUBSAMPLES];
                        let mut n = 0usize;
                        for i in 0..ss * ss {
                            let s = texel_at(&tile, layout, ox * ss + i % ss, oy * ss + i / ss);
                            if let (Some(t), true) = (s, n < SUBSAMPLES) {
                                texels[n] = t;
                                n += 1;
                            }
                        }
                        if n == 0 {
                            continue;
                        }
                        let (x, y) = (x0 / ss + ox, y0 / ss + oy);
                        let Some((cov, target)) = photo_at(v, x, y) else {
                            continue;
                        };
                        // Where the image shows (mostly) background a white
                        // target would only teach a surface texel to be white
                        // (geometry is fixed here): such pixels give no target,
                        // only votes against the geometry they show.
                        if cov < 128 {
                            background.extend_from_slice(&texels[..n]);
                            continue;
                        }
                        out.push(GPixel {
                            texel: texels[0],
                            dir: out_view.pixel_dir_f32(x, y),
                            target,
                        });
                        if supersample {
                            subs.push(texels);
                        }
                    }
                }
            }
            Ok((out, subs, background))
        })
        .collect();
    let parts = per.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(GBuffers::joined(parts))
}

/// The GPixel that [`concat`] fills before copying.
const NO_PIXEL: GPixel = GPixel {
    texel: NO_TEXEL,
    dir: [0.0; 3],
    target: [0.0; 3],
};

/// `n` values of `value`, written on all cores: a large vector is fresh
/// pages, and one thread faulting them in leaves the other cores idle
/// (on lego (128, 17) the judgement's 37 M per-texel sums, written by
/// one thread, were the longest such stretch: about a second).
pub(super) fn filled<T: Send>(n: usize, value: impl Fn() -> T + Sync + Send) -> Vec<T> {
    (0..n).into_par_iter().map(|_| value()).collect()
}

/// `parts` one after the other, filled and copied on all cores. The
/// G-buffers of lego (128, 17) are about 450 MB of fresh pages; one
/// thread appending them part by part left the other core idle for a
/// third to half a second, three times a bake (a perf timeline:
/// docs/baking.md, "Session 50").
pub(super) fn concat<T: Copy + Send + Sync>(parts: &[&[T]], fill: T) -> Vec<T> {
    let total = parts.iter().map(|p| p.len()).sum();
    let mut out = filled(total, || fill);
    let mut rest = out.as_mut_slice();
    let mut dsts = Vec::with_capacity(parts.len());
    for p in parts {
        let (d, r) = rest.split_at_mut(p.len());
        dsts.push(d);
        rest = r;
    }
    dsts.into_par_iter()
        .zip(parts)
        .for_each(|(d, s)| d.copy_from_slice(s));
    out
}

impl GBuffers {
    /// The G-buffers of views whose (pixels, subsamples, background)
    /// are `parts`, view after view.
    pub(super) fn joined(parts: Vec<(Vec<GPixel>, Vec<Subsamples>, Vec<u32>)>) -> Self {
        let pixels: Vec<&[GPixel]> = parts.iter().map(|p| p.0.as_slice()).collect();
        let subs: Vec<&[Subsamples]> = parts.iter().map(|p| p.1.as_slice()).collect();
        let background: Vec<&[u32]> = parts.iter().map(|p| p.2.as_slice()).collect();
        GBuffers {
            per_view: parts.iter().map(|p| p.0.len()).collect(),
            pixels: concat(&pixels, NO_PIXEL),
            subsamples: concat(&subs, [NO_TEXEL; SUBSAMPLES]),
            background: concat(&background, NO_TEXEL),
        }
    }
}

/// The photo's object coverage (0–255) at pixel `(x, y)` of `v` and its
/// colour there composited over white in [0, 1]; `None` where another
/// object covers the pixel (it says nothing about this one).
#[inline]
pub(super) fn photo_at(v: &BakeView<'_>, x: u32, y: u32) -> Option<(u8, [f32; 3])> {
    if let super::super::Silhouette::Instance { mask, label } = v.silhouette {
        let m = mask.get_pixel(x, y).0[0];
        if m != 0 && m != label {
            return None;
        }
    }
    let cov = v.coverage(x, y);
    let px = v.image.get_pixel(x, y).0;
    let a = f32::from(cov) / 255.0;
    let c = |k: usize| f32::from(px[k]) / 255.0 * a + (1.0 - a);
    Some((cov, [c(0), c(1), c(2)]))
}

/// The alpha tests of `pages`.
pub(super) fn alpha_masks(pages: &[AlphaPage]) -> Result<Vec<AlphaBits<'_>>, BakeError> {
    pages
        .iter()
        .map(|(w, h, b)| {
            AlphaBits::new(*w, *h, b)
                .map_err(|e| BakeError::BadParam(format!("G-buffer alpha bits: {e:?}")))
        })
        .collect()
}

/// Training view `vi`'s output view, the view it is rasterized at (2 × 2
/// finer when `supersample`) and the subsamples per pixel side.
pub(super) fn views_of(
    vi: usize,
    v: &BakeView<'_>,
    supersample: bool,
) -> Result<(RasterView, RasterView, u32), BakeError> {
    let bad = |e| BakeError::BadViews(format!("view {vi}: {e:?}"));
    let out_view = view_of(&v.camera).map_err(bad)?;
    if supersample {
        Ok((
            out_view,
            supersampled_view(&v.camera).map_err(bad)?,
            SUPERSAMPLE,
        ))
    } else {
        Ok((out_view, out_view, 1))
    }
}

/// A view's projected quads (ids: their index over all pages, in page
/// order), their nearness (each one's [`ScreenQuad::nearest`] as bits
/// that sort like it) and, per [`TILE`]-sized tile, the ones
/// whose box touches it. One worker re-bins view after view into the same
/// one ([`Binned::rebin`]): its memory (lego (128, 17): 24 MB of projected
/// quads a view) is then fresh pages once per worker, not once per view.
#[derive(Default)]
pub(super) struct Binned {
    pub projected: Vec<ScreenQuad>,
    pub nearness: Vec<u32>,
    pub bins: Vec<Vec<u32>>,
    /// Tiles per row.
    pub tx: u32,
}

impl Binned {
    /// Projects `quads` (`quads[i]` on page `i`) into `view` and bins
    /// them, in place of what was here.
    pub(super) fn rebin(&mut self, quads: &[&[RasterQuad]], view: &nerflex_core::raster::View) {
        let mut id = 0u32;
        self.projected.clear();
        // At its final size from the start: grown by doubling, lego's 24
        // MB per view was copied into fresh pages up to four times a pass.
        self.projected.reserve(quads.iter().map(|p| p.len()).sum());
        for (pi, part) in quads.iter().enumerate() {
            for q in part.iter() {
                if let Some(sq) = ScreenQuad::project(view, q, pi as u16, id) {
                    self.projected.push(sq);
                }
                id += 1;
            }
        }
        crate::render::nearness_into(&self.projected, &mut self.nearness);
        self.tx = crate::render::tile_bins_into(&self.projected, view, TILE as u32, &mut self.bins);
    }
}

pub(super) use crate::render::{draw_near_first, near_first};

/// The texel (`quad · p² + y · p + x`) tile-local sample `(x, y)` of
/// `tile` shows, if covered.
#[inline]
pub(super) fn texel_at(
    tile: &TileRenderer<TILE, TILE>,
    layout: &AtlasLayout,
    x: u32,
    y: u32,
) -> Option<u32> {
    let p = layout.patch;
    let s = tile.sample(x, y)?;
    let cell = layout.cell(s.quad as usize)?;
    let (lx, ly) = (
        u32::from(s.texel[0]).wrapping_sub(cell.x),
        u32::from(s.texel[1]).wrapping_sub(cell.y),
    );
    (lx < p && ly < p).then(|| s.quad * p * p + ly * p + lx)
}

/// One bit per texel of `feat0`, set where its R is not 0 (rows of
/// [`AlphaBits::row_words`] words).
fn alpha_bits(feat0: &image::RgbaImage) -> Vec<u64> {
    let (w, h) = feat0.dimensions();
    let words = AlphaBits::row_words(w);
    let mut bits = vec![0u64; words * h as usize];
    let row_bytes = w as usize * 4;
    bits.par_chunks_mut(words.max(1))
        .zip(feat0.as_raw().par_chunks(row_bytes.max(1)))
        .for_each(|(out, row)| {
            for (x, px) in row.chunks_exact(4).enumerate() {
                out[x / 64] |= u64::from(px[0] != 0) << (x % 64);
            }
        });
    bits
}

impl GBuffers {
    /// The texels pixel `i` shows: its covered subsamples', or its one.
    #[inline]
    pub fn shown(&self, i: usize) -> &[u32] {
        match self.subsamples.get(i) {
            Some(s) => covered(s),
            None => std::slice::from_ref(&self.pixels[i].texel),
        }
    }

    /// The camera position of every covered pixel (`views` as given to
    /// [`rasterize`]).
    pub fn origins(&self, views: &[BakeView<'_>]) -> Vec<glam::Vec3> {
        self.per_view
            .iter()
            .zip(views)
            .flat_map(|(&n, v)| std::iter::repeat_n(v.camera.position(), n))
            .collect()
    }

    /// Each covered pixel, in parallel, with its ray's origin (the view's
    /// camera), its unit direction and the world point of the texel it
    /// shows in `geo` at patch `p`.
    pub fn pixel_rays<'a>(
        &'a self,
        geo: &'a super::extract::Geometry,
        p: u32,
        views: &[BakeView<'_>],
    ) -> impl IndexedParallelIterator<Item = (&'a GPixel, [glam::Vec3; 3])> + 'a {
        self.origins(views)
            .into_par_iter()
            .zip(self.pixels.par_iter())
            .map(move |(o, px)| {
                let dir = glam::Vec3::from_array(px.dir);
                (px, [o, dir, geo.texel_point(p, px.texel)])
            })
    }
}

/// The G-buffers of `geo`'s quads at patch `p` on `views`, through an
/// export whose atlas carries only the texel opacity.
pub fn of_geometry(
    geo: &super::extract::Geometry,
    p: u32,
    views: &[BakeView<'_>],
    supersample: bool,
) -> Result<GBuffers, BakeError> {
    let (layout, quads, pages) = pages_of(geo, p)?;
    let quads: Vec<&[RasterQuad]> = quads.iter().map(Vec::as_slice).collect();
    rasterize_bits(&quads, &pages, &layout, views, supersample)
}

/// `geo`'s atlas layout at patch `p`, its pages' quads and alpha bits.
pub(super) type GeometryPages = (AtlasLayout, Vec<Vec<RasterQuad>>, Vec<AlphaPage>);

/// The pages' quads and alpha bits straight from the geometry: what the
/// export of an atlas carrying only the opacity would give, without its
/// RGBA pages.
pub(super) fn pages_of(geo: &super::extract::Geometry, p: u32) -> Result<GeometryPages, BakeError> {
    let layout = AtlasLayout::new(geo.quads.len(), p);
    let (quads, pages): (Vec<Vec<RasterQuad>>, Vec<AlphaPage>) = (0..layout.pages.len())
        .into_par_iter()
        .map(|i| {
            let quads = super::super::page_quads(&geo.quads, &layout, p, i).map_err(|e| {
                BakeError::BadParam(format!("building the G-buffers' quads failed: {e}"))
            })?;
            let (w, h) = layout.page_size(i);
            Ok((quads, (w, h, opacity_bits(&layout, i, &geo.opacity))))
        })
        .collect::<Result<Vec<_>, BakeError>>()?
        .into_iter()
        .unzip();
    Ok((layout, quads, pages))
}

/// The alpha pages of `layout` for the texel opacity `opacity` (p² per
/// quad): [`pages_of`]'s pages, for another opacity of the same quads.
pub(super) fn alpha_pages(layout: &AtlasLayout, opacity: &[bool]) -> Vec<AlphaPage> {
    (0..layout.pages.len())
        .into_par_iter()
        .map(|i| {
            let (w, h) = layout.page_size(i);
            (w, h, opacity_bits(layout, i, opacity))
        })
        .collect()
}

/// [`alpha_pages`] of the texels `opacity` marks transparent: drawn as if
/// they were the opaque ones, the nearest transparent texel each pixel
/// meets (the visibility round's growing, the hole fill).
pub(super) fn transparent_pages(layout: &AtlasLayout, opacity: &[bool]) -> Vec<AlphaPage> {
    let inverted: Vec<bool> = opacity.iter().map(|&o| !o).collect();
    alpha_pages(layout, &inverted)
}

/// The alpha bits of page `page` of `layout` whose texels' opacity is
/// `opacity` (p² per quad, row-major in its cell, as `export::atlas` lays
/// texels out).
fn opacity_bits(layout: &AtlasLayout, page: usize, opacity: &[bool]) -> Vec<u64> {
    let p = layout.patch as usize;
    let pl = layout.pages[page];
    let (w, h) = layout.page_size(page);
    let words = AlphaBits::row_words(w);
    let mut bits = vec![0u64; words * h as usize];
    // One row of cells (p texel rows) at a time.
    bits.par_chunks_mut((words * p).max(1))
        .enumerate()
        .for_each(|(row, out)| {
            for (col, q) in pl.row_quads(row) {
                for ty in 0..p {
                    for tx in 0..p {
                        if opacity.get(q * p * p + ty * p + tx) == Some(&true) {
                            let x = col * p + tx;
                            out[ty * words + x / 64] |= 1 << (x % 64);
                        }
                    }
                }
            }
        });
    bits
}

/// How well a geometry's texel points carry the training images, before
/// any fitting: the field's own colour at the point of the texel each
/// covered training pixel shows, seen along the pixel's direction, against
/// the pixel (a direct measure of parallax: a texel off the surface shows
/// different surface points from different views), and how many of the
/// object's pixels the geometry covers (cracks lose pixels).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TexelProbe {
    /// PSNR (dB) of the field's colour at the texel points against the
    /// covered training pixels (object coverage ≥ 50 %).
    pub psnr: f64,
    /// The same over the pixels whose ray meets the field's inside.
    pub hit_psnr: f64,
    /// Over those pixels, the field's colour at the first inside point
    /// along each pixel's ray instead (no parallax, no texel size: the
    /// ceiling of `hit_psnr` with this field).
    pub surface_psnr: f64,
    /// Of those, pixels whose texel point lies more than a voxel from
    /// the surface point (cracks showing the far side, stray quads).
    pub far_pixels: u64,
    /// Covered training pixels.
    pub pixels: u64,
    /// Training pixels of the object (coverage ≥ 50 %).
    pub object_pixels: u64,
    /// Over the pixels whose ray reaches transmittance ½ in the field (the
    /// volume renderer's median depth): how many show a texel more than a
    /// voxel in front of that depth, within a voxel of it, and more than a
    /// voxel behind it (a crack or a missing texel lets the ray through).
    pub by_depth: [u64; 3],
    /// The texel points' PSNR over each of those three sets of pixels.
    pub by_depth_psnr: [f64; 3],
    /// The field's colour at the median-depth point itself, over all three:
    /// the ceiling of a geometry through the volume renderer's surface.
    pub median_psnr: f64,
}

/// [`TexelProbe`] of `geo` (at patch `p`) on `views`; `surf` is the
/// inside test `geo` was extracted with.
pub fn probe(
    surf: &super::extract::Surface<'_>,
    geo: &super::extract::Geometry,
    p: u32,
    views: &[BakeView<'_>],
) -> Result<TexelProbe, BakeError> {
    use glam::Vec3;
    let gb = of_geometry(geo, p, views, false)?;
    let field = surf.field;
    let step = geo.voxel / 8.0;
    let on_surface = |o: Vec3, d: Vec3| -> Option<Vec3> {
        // Entry and exit of the ray through the cube.
        let inv = d.recip();
        let (a, b) = ((geo.cube.min - o) * inv, (geo.cube.max - o) * inv);
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element();
        let mut t = t0;
        while t <= t1 {
            if surf.inside(o + t * d) {
                let (mut lo, mut hi) = ((t - step).max(t0), t);
                for _ in 0..10 {
                    let mid = 0.5 * (lo + hi);
                    if surf.inside(o + mid * d) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(o + hi * d);
            }
            t += step;
        }
        None
    };
    let err = |x: Vec3, px: &GPixel| {
        let c = field
            .color(x, Vec3::from_array(px.dir))
            .clamp(Vec3::ZERO, Vec3::ONE);
        (0..3)
            .map(|k| f64::from(c[k] - px.target[k]).powi(2))
            .sum::<f64>()
    };
    // The distance along a ray at which the field's transmittance falls to
    // ½ (half-field-cell steps, linear within the crossing step).
    let fb = field.bounds();
    let fstep = 0.5 * (fb.max - fb.min).max_element() / field.resolution().max(1) as f32;
    let median_t = |o: Vec3, d: Vec3| -> Option<f32> {
        let inv = d.recip();
        let (a, b) = ((geo.cube.min - o) * inv, (geo.cube.max - o) * inv);
        let (t0, t1) = (a.min(b).max_element().max(0.0), a.max(b).min_element());
        let mut t = t0;
        let mut od = 0.0f32;
        while t <= t1 {
            let tau = field.density(o + (t + 0.5 * fstep) * d) * fstep;
            if od + tau >= std::f32::consts::LN_2 {
                return Some(t + fstep * (std::f32::consts::LN_2 - od) / tau.max(1e-12));
            }
            od += tau;
            t += fstep;
        }
        None
    };
    #[derive(Clone, Copy, Default)]
    struct Acc {
        se: f64,
        hit_se: [f64; 2],
        hit_n: [u64; 2],
        depth_n: [u64; 3],
        depth_se: [f64; 3],
        median_se: f64,
    }
    let acc = gb
        .pixel_rays(geo, p, views)
        .map(|(px, [o, d, x])| {
            let e = err(x, px);
            let mut a = Acc {
                se: e,
                ..Acc::default()
            };
            if let Some(y) = on_surface(o, d) {
                a.hit_se = [e, err(y, px)];
                a.hit_n = [1, u64::from((x - y).length() > geo.voxel)];
            }
            if let Some(tm) = median_t(o, d) {
                let off = (x - o).dot(d) - tm;
                let k = if off < -geo.voxel {
                    0
                } else if off <= geo.voxel {
                    1
                } else {
                    2
                };
                a.depth_n[k] = 1;
                a.depth_se[k] = e;
                a.median_se = err(o + tm * d, px);
            }
            a
        })
        .reduce(Acc::default, |a, b| Acc {
            se: a.se + b.se,
            hit_se: [a.hit_se[0] + b.hit_se[0], a.hit_se[1] + b.hit_se[1]],
            hit_n: [a.hit_n[0] + b.hit_n[0], a.hit_n[1] + b.hit_n[1]],
            depth_n: std::array::from_fn(|k| a.depth_n[k] + b.depth_n[k]),
            depth_se: std::array::from_fn(|k| a.depth_se[k] + b.depth_se[k]),
            median_se: a.median_se + b.median_se,
        });
    let (se, hit_se, surface_se, hits, far) = (
        acc.se,
        acc.hit_se[0],
        acc.hit_se[1],
        acc.hit_n[0],
        acc.hit_n[1],
    );
    let object_pixels: u64 = views
        .par_iter()
        .map(|v| {
            let (w, h) = v.image.dimensions();
            let mut n = 0u64;
            for y in 0..h {
                for x in 0..w {
                    n += u64::from(v.coverage(x, y) >= 128);
                }
            }
            n
        })
        .sum();
    let n = gb.pixels.len() as u64;
    let psnr = |se: f64, n: u64| -10.0 * (se / (3 * n.max(1)) as f64).max(1e-12).log10();
    Ok(TexelProbe {
        psnr: psnr(se, n),
        hit_psnr: psnr(hit_se, hits),
        surface_psnr: psnr(surface_se, hits),
        far_pixels: far,
        pixels: n,
        object_pixels,
        by_depth: acc.depth_n,
        by_depth_psnr: std::array::from_fn(|k| psnr(acc.depth_se[k], acc.depth_n[k])),
        median_psnr: psnr(acc.median_se, acc.depth_n.iter().sum()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn joined_views_are_their_parts_in_order() {
        let px = |t: u32| GPixel {
            texel: t,
            dir: [t as f32, 0.0, 1.0],
            target: [0.5; 3],
        };
        // Sizes around rayon's splits, and empty views between.
        let sizes = [0usize, 3, 0, 70_001, 1, 0, 4096];
        let mut next = 0u32;
        let parts: Vec<(Vec<GPixel>, Vec<Subsamples>, Vec<u32>)> = sizes
            .iter()
            .map(|&n| {
                let pixels: Vec<GPixel> = (0..n)
                    .map(|_| {
                        next += 1;
                        px(next)
                    })
                    .collect();
                let subs = pixels
                    .iter()
                    .map(|p| [p.texel, NO_TEXEL, 7, p.texel])
                    .collect();
                let background = pixels.iter().map(|p| p.texel * 2).take(n / 2).collect();
                (pixels, subs, background)
            })
            .collect();
        let g = GBuffers::joined(parts.clone());
        assert_eq!(g.per_view, sizes);
        let flat = |k: usize| -> Vec<u32> {
            parts
                .iter()
                .flat_map(|p| match k {
                    0 => p.0.iter().map(|x| x.texel).collect::<Vec<_>>(),
                    1 => p.1.iter().map(|s| s[3]).collect(),
                    _ => p.2.clone(),
                })
                .collect()
        };
        assert_eq!(
            g.pixels.iter().map(|p| p.texel).collect::<Vec<_>>(),
            flat(0)
        );
        assert!(g.pixels.iter().all(|p| p.dir[0] == p.texel as f32));
        assert_eq!(
            g.subsamples.iter().map(|s| s[3]).collect::<Vec<_>>(),
            flat(1)
        );
        assert_eq!(g.background, flat(2));
        assert_eq!(g.pixels.len(), (1..=next).count());
    }

    /// The bits built from the opacity are those of the exported atlas'
    /// feat0 pages, and the quads those of the asset.
    #[test]
    fn opacity_bits_are_the_exported_atlas_bits() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for (n, p) in [(1usize, 2u32), (37, 5), (150, 17)] {
            let layout = AtlasLayout::new(n, p);
            let opacity: Vec<bool> = (0..n * (p * p) as usize)
                .map(|_| rng.random::<f32>() < 0.3)
                .collect();
            let mask: Vec<[u8; 8]> = opacity
                .iter()
                .map(|&o| [u8::from(o), 0, 0, 0, 0, 0, 0, 0])
                .collect();
            let atlas = super::super::export::atlas(&layout, &mask);
            for (i, page) in atlas.pages.iter().enumerate() {
                assert_eq!(
                    opacity_bits(&layout, i, &opacity),
                    alpha_bits(&page.feat0),
                    "n {n} p {p} page {i}"
                );
            }
        }
    }
}
