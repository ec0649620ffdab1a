//! Holes filled where the photos show the object, found at the renderer's
//! subsamples (`--fill-holes`).
//!
//! The fine-tune and the visibility rounds see one sample per pixel, at
//! its centre; the renderer takes 2 × 2 (`raster::SUPERSAMPLE`), and its
//! off-centre subsamples find transparent texels of kept quads as white
//! specks inside the object (lego (128, 17): 8.4 % of the held-out
//! squared error; `docs/baking.md`, "Session 18"). Here training views
//! are rasterized at the renderer's subsamples; where a subsample of a
//! pixel well inside the photo's object (no photo background within
//! [`MARGIN_PX`]) meets no opaque texel, the nearest transparent texel on
//! its ray is proposed: the photo says that ray ends on the object, and any
//! surface colour is nearer its pixel than the white background.

use rayon::prelude::*;
use std::time::Instant;

use super::super::{BakeError, BakeView};
use super::extract::Geometry;
use super::gbuffer::{self, TILE};
use nerflex_core::raster::TileRenderer;

/// A pixel is inside the object when no photo background (coverage under
/// 128, or another object's pixel) lies within this many pixels of it, in
/// x and in y (the `holes:` measure's margin, `metrics::interior_holes`).
pub const MARGIN_PX: usize = 3;

/// What [`find`] saw.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FillReport {
    /// Views rasterized (every `stride`-th).
    pub views: u64,
    /// Subsamples of interior object pixels that met no opaque texel.
    pub open_subsamples: u64,
    /// … of which a transparent texel lay on the ray.
    pub reachable: u64,
    /// Texels made opaque (set by the caller, which may refuse some).
    pub filled_texels: u64,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// Interior object pixels of view `v`, row-major: the object's coverage is
/// at least 128 on every pixel within [`MARGIN_PX`] in x and in y.
fn interior(v: &BakeView<'_>) -> Vec<bool> {
    let (w, h) = v.image.dimensions();
    let (w, h) = (w as usize, h as usize);
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let r = MARGIN_PX;
    let background: Vec<bool> = (0..w * h)
        .map(|i| gbuffer::photo_at(v, (i % w) as u32, (i / w) as u32).is_none_or(|(c, _)| c < 128))
        .collect();
    // The background dilated by r, rows then columns.
    let mut rows = vec![false; w * h];
    for y in 0..h {
        let row = &background[y * w..(y + 1) * w];
        for x in 0..w {
            rows[y * w + x] = row[x.saturating_sub(r)..=(x + r).min(w - 1)].contains(&true);
        }
    }
    let mut inside = vec![false; w * h];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            inside[y * w + x] = !(a..=b).any(|yy| rows[yy * w + x]);
        }
    }
    inside
}

/// The nearest transparent texel of every subsample (2 × 2 per pixel) of
/// an interior object pixel of every `stride`-th view of `views` that meets
/// no opaque texel of `geo` at patch `p` (sorted, without repeats).
pub fn find(
    geo: &Geometry,
    p: u32,
    views: &[BakeView<'_>],
    stride: usize,
) -> Result<(Vec<u32>, FillReport), BakeError> {
    let t0 = Instant::now();
    let stride = stride.max(1);
    let (layout, quads, pages) = gbuffer::pages_of(geo, p)?;
    let quads: Vec<&[_]> = quads.iter().map(Vec::as_slice).collect();
    let masks = gbuffer::alpha_masks(&pages)?;
    let inv_pages = gbuffer::transparent_pages(&layout, &geo.opacity);
    let inv_masks = gbuffer::alpha_masks(&inv_pages)?;
    type Seen = (Vec<u32>, u64, u64);
    let per: Vec<Result<Seen, BakeError>> = views
        .par_iter()
        .enumerate()
        .step_by(stride)
        .map_init(gbuffer::Binned::default, |binned, (vi, v)| {
            let (_, view, ss) = gbuffer::views_of(vi, v, true)?;
            let inside = interior(v);
            let w = v.image.width() as usize;
            binned.rebin(&quads, &view);
            let binned = &*binned;
            let t = TILE as u32;
            let mut front = Box::new(TileRenderer::<TILE, TILE>::new());
            let mut near = Box::new(TileRenderer::<TILE, TILE>::new());
            let (mut found, mut open, mut reachable) = (Vec::new(), 0u64, 0u64);
            for (b, bin) in binned.bins.iter().enumerate() {
                if bin.is_empty() {
                    continue;
                }
                let (bx, by) = (b as u32 % binned.tx, b as u32 / binned.tx);
                front.begin(&view, bx * t, by * t);
                near.begin(&view, bx * t, by * t);
                for &i in bin {
                    let sq = &binned.projected[i as usize];
                    if let Some(m) = masks.get(sq.part as usize) {
                        front.draw(sq, m);
                    }
                    if let Some(m) = inv_masks.get(sq.part as usize) {
                        near.draw(sq, m);
                    }
                }
                let (x0, y0, tw, th) = front.rect();
                for sy in 0..th {
                    for sx in 0..tw {
                        let (x, y) = (((x0 + sx) / ss) as usize, ((y0 + sy) / ss) as usize);
                        if inside.get(y * w + x) != Some(&true)
                            || gbuffer::texel_at(&front, &layout, sx, sy).is_some()
                        {
                            continue;
                        }
                        open += 1;
                        if let Some(texel) = gbuffer::texel_at(&near, &layout, sx, sy) {
                            reachable += 1;
                            found.push(texel);
                        }
                    }
                }
            }
            Ok((found, open, reachable))
        })
        .collect();
    let mut report = FillReport::default();
    let mut all = Vec::new();
    for r in per {
        let (found, open, reachable) = r?;
        report.views += 1;
        report.open_subsamples += open;
        report.reachable += reachable;
        all.extend(found);
    }
    all.par_sort_unstable();
    all.dedup();
    report.seconds = t0.elapsed().as_secs_f64();
    Ok((all, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::quads::Quad;
    use crate::bake::Silhouette;
    use crate::camera::{Camera, Intrinsics};
    use glam::Vec3;

    /// A 3 × 3-texel quad facing the camera on −y, in front of a larger one
    /// (`back`), seen from −y in a 24 px view; texel 4 is the front quad's
    /// centre.
    fn scene(back: bool) -> Geometry {
        let mut quads = vec![Quad::facing_minus_y(Vec3::new(0.0, -0.5, 0.0), 0.6)];
        if back {
            quads.push(Quad::facing_minus_y(Vec3::ZERO, 1.0));
        }
        let n = quads.len() * 9;
        let mut opacity = vec![true; n];
        opacity[4] = false;
        Geometry::in_cube(quads, opacity)
    }

    fn found(geo: &Geometry, alpha: u8, stride: usize) -> (Vec<u32>, FillReport) {
        let k = Intrinsics::from_fov_x(0.7, 24, 24);
        let cam = Camera::look_at(Vec3::new(0.0, -4.0, 0.0), Vec3::ZERO, Vec3::Z, k);
        let image = image::RgbaImage::from_pixel(24, 24, image::Rgba([90, 140, 200, alpha]));
        let views = [BakeView {
            camera: cam,
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        find(geo, 3, &views, stride).unwrap()
    }

    /// The photo shows the object everywhere: the front quad's transparent
    /// centre is proposed, and nothing else; pixels no quad reaches are
    /// open but cannot be filled.
    #[test]
    fn a_hole_the_photo_calls_object_is_proposed() {
        let (texels, r) = found(&scene(false), 255, 1);
        assert_eq!(texels, vec![4]);
        assert_eq!(r.views, 1);
        assert!(r.reachable > 0 && r.open_subsamples > r.reachable, "{r:?}");
    }

    /// Where an opaque texel lies behind the hole, or the photo shows
    /// background, nothing is proposed.
    #[test]
    fn no_hole_is_proposed_behind_cover_or_over_background() {
        let (texels, r) = found(&scene(true), 255, 1);
        assert!(texels.is_empty(), "{texels:?}");
        assert_eq!(r.reachable, 0);
        let (texels, r) = found(&scene(false), 0, 1);
        assert!(texels.is_empty() && r.open_subsamples == 0, "{r:?}");
    }

    /// A stride past the only view still reads view 0.
    #[test]
    fn the_stride_keeps_the_first_view() {
        let (texels, r) = found(&scene(false), 255, 5);
        assert_eq!((texels, r.views), (vec![4], 1));
    }

    /// The interior stops `MARGIN_PX` short of the background.
    #[test]
    fn the_interior_keeps_its_margin() {
        let mut image = image::RgbaImage::from_pixel(16, 16, image::Rgba([0, 0, 0, 255]));
        image.put_pixel(0, 8, image::Rgba([0, 0, 0, 0]));
        let k = Intrinsics::from_fov_x(0.7, 16, 16);
        let v = BakeView {
            camera: Camera::look_at(Vec3::new(0.0, -4.0, 0.0), Vec3::ZERO, Vec3::Z, k),
            image: &image,
            silhouette: Silhouette::Alpha,
        };
        let inside = interior(&v);
        assert!(!inside[8 * 16 + MARGIN_PX] && inside[8 * 16 + MARGIN_PX + 1]);
        assert!(!inside[(8 + MARGIN_PX) * 16] && inside[(9 + MARGIN_PX) * 16]);
        assert_eq!(
            inside.iter().filter(|&&i| !i).count(),
            (MARGIN_PX + 1) * (2 * MARGIN_PX + 1)
        );
    }
}
