//! The quads a novel view can see: cameras between the training views.
//!
//! A bake keeps only the quads some training pixel shows first. Where the
//! planes stack (a voxel's quads behind its neighbours'), a view between
//! the training views sees through the gaps between the front planes onto
//! quads every training view has hidden; dropped, they are white holes in
//! every novel view (gear (256, 13): a fifth of the held-out squared
//! error, the cause of its fall from g = 128; docs/baking.md, "Session
//! 32"). Rasterizing the quads from virtual cameras between the training
//! views (no photo needed: only which quad shows) finds the ones worth
//! keeping without keeping every hidden one.

use glam::Vec3;
use rayon::prelude::*;

use super::super::{BakeError, BakeView};
use super::extract::Geometry;
use super::gbuffer::{alpha_masks, draw_near_first, pages_of, Binned, TILE};
use crate::camera::Camera;
use crate::render::{supersampled_view, view_of};
use nerflex_core::raster::{Quad as RasterQuad, TileRenderer};

/// The virtual cameras' pass of a bake.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NovelReport {
    /// Virtual cameras rasterized.
    pub cameras: u32,
    /// Quads some virtual camera shows first (many a training pixel shows
    /// as well).
    pub quads: u64,
    /// Wall time of the pass.
    pub seconds: f64,
}

/// One virtual camera per training view: at the angular midpoint (about
/// `centre`) between it and the training camera nearest in angle, at their
/// mean distance, looking at `centre` with the view's own up and
/// intrinsics. A pair of views each the other's nearest gives one camera
/// (a third of lego's 90); views with no other view, or opposite their
/// nearest, give none.
pub fn virtual_cameras(views: &[BakeView<'_>], centre: Vec3) -> Vec<Camera> {
    let eyes: Vec<Vec3> = views.iter().map(|v| v.camera.position() - centre).collect();
    let dirs: Vec<Vec3> = eyes.iter().map(|e| e.normalize_or_zero()).collect();
    let mut pairs = std::collections::HashSet::new();
    views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| {
            let (j, _) = dirs
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .max_by(|a, b| a.1.dot(dirs[i]).total_cmp(&b.1.dot(dirs[i])))?;
            // Two views each the other's nearest share one midpoint.
            if !pairs.insert((i.min(j), i.max(j))) {
                return None;
            }
            let dir = (dirs[i] + dirs[j]).normalize_or_zero();
            if dir == Vec3::ZERO {
                return None;
            }
            let eye = centre + dir * (0.5 * (eyes[i].length() + eyes[j].length()));
            let up = v.camera.c2w.y_axis.truncate();
            Some(Camera::look_at(eye, centre, up, v.camera.intrinsics))
        })
        .collect()
}

/// Per quad of `geo` (at patch `p`, its texel opacity), whether some
/// pixel of `cameras` shows it first (at 2 × 2 subsamples when
/// `supersample`, as the renderer draws). A camera the rasterizer
/// rejects shows nothing.
pub fn shown_from(
    geo: &Geometry,
    p: u32,
    cameras: &[Camera],
    supersample: bool,
) -> Result<Vec<bool>, BakeError> {
    let (_, quads, pages) = pages_of(geo, p)?;
    let quads: Vec<&[RasterQuad]> = quads.iter().map(Vec::as_slice).collect();
    let masks = alpha_masks(&pages)?;
    let nq = geo.quads.len();
    let t = TILE as u32;
    let shown = cameras
        .par_iter()
        .fold(
            || (vec![false; nq], Binned::default()),
            |(mut on, mut binned), c| {
                let view = match supersample {
                    true => supersampled_view(c),
                    false => view_of(c),
                };
                let Ok(view) = view else {
                    return (on, binned);
                };
                binned.rebin(&quads, &view);
                let Binned {
                    projected,
                    nearness,
                    bins,
                    tx,
                } = &binned;
                let mut keyed = Vec::new();
                let mut tile = Box::new(TileRenderer::<TILE, TILE>::new());
                for (b, bin) in bins.iter().enumerate() {
                    if bin.is_empty() {
                        continue;
                    }
                    tile.begin(&view, (b as u32 % tx) * t, (b as u32 / tx) * t);
                    draw_near_first(&mut tile, bin, projected, nearness, &mut keyed, |part| {
                        masks.get(part as usize)
                    });
                    let (_, _, w, h) = tile.rect();
                    for y in 0..h {
                        for x in 0..w {
                            let s = tile.sample(x, y);
                            if let Some(q) = s.and_then(|s| on.get_mut(s.quad as usize)) {
                                *q = true;
                            }
                        }
                    }
                }
                (on, binned)
            },
        )
        .map(|(on, _)| on)
        .reduce(
            || vec![false; nq],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x |= y);
                a
            },
        );
    Ok(shown)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::quads::Quad;
    use crate::bake::Silhouette;
    use crate::camera::Intrinsics;

    /// Two wings in front (y = −0.3) with a slit between them, and a small
    /// quad behind the slit (y = 0): hidden from 60° either side, seen
    /// head-on through the slit.
    fn slit() -> Geometry {
        let facing = Quad::facing_minus_y;
        Geometry::in_cube(
            vec![
                facing(Vec3::new(-0.325, -0.3, 0.0), 0.55),
                facing(Vec3::new(0.325, -0.3, 0.0), 0.55),
                facing(Vec3::ZERO, 0.1),
            ],
            vec![true; 27],
        )
    }

    fn camera_at(azimuth_deg: f32) -> Camera {
        let k = Intrinsics::from_fov_x(0.7, 128, 128);
        Camera::orbit(azimuth_deg, 0.0, 4.0, Vec3::ZERO, k)
    }

    #[test]
    fn a_quad_hidden_from_every_training_view_shows_between_them() {
        let image = image::RgbaImage::from_pixel(128, 128, image::Rgba([0, 0, 0, 255]));
        let cams = [camera_at(-60.0), camera_at(60.0)];
        let views: Vec<BakeView<'_>> = cams
            .iter()
            .map(|&camera| BakeView {
                camera,
                image: &image,
                silhouette: Silhouette::Alpha,
            })
            .collect();
        let between = virtual_cameras(&views, Vec3::ZERO);
        // Each view is the other's nearest: one midpoint, one camera.
        assert_eq!(between.len(), 1);
        for c in &between {
            // Head-on, at the training views' distance, looking at the
            // centre.
            assert!((c.position() - Vec3::new(0.0, -4.0, 0.0)).length() < 1e-4);
            let (x, y, _) = c.project(Vec3::ZERO).unwrap();
            assert!((x - 64.0).abs() < 1e-3 && (y - 64.0).abs() < 1e-3);
        }
        let geo = slit();
        for supersample in [false, true] {
            let seen = shown_from(&geo, 3, &cams, supersample).unwrap();
            assert_eq!(seen, [true, true, false], "supersample {supersample}");
            let seen = shown_from(&geo, 3, &between, supersample).unwrap();
            assert_eq!(seen, [true, true, true], "supersample {supersample}");
        }
        // A lone view has no neighbour to go between.
        assert!(virtual_cameras(&views[..1], Vec3::ZERO).is_empty());
    }
}
