//! Space carving by the field's own depth: a training ray that reaches a
//! texel while the field in front of it (and `margin` voxels beyond) is
//! still mostly transparent says the texel stands in front of the surface.
//!
//! The hull carve (`carve::texel_occupancy_hull`) empties texels that
//! project onto a view's background; this is its generalisation inside
//! the silhouette, with the field's transmittance in place of the mask.
//! Each covered training pixel votes on the texel it shows: *against*
//! when the optical depth from the cube's entry to the texel's depth plus
//! the margin stays below ln 2 (the volume renderer's median depth lies
//! beyond), *for* otherwise. Texels with more votes against than for are
//! emptied; the caller rasterizes again, and the rays that passed them
//! meet what lies behind.

use glam::Vec3;
use rayon::prelude::*;

use super::extract::Geometry;
use super::gbuffer::GBuffers;
use crate::bake::BakeView;
use crate::train::field::RadianceField;

/// What one round of the depth carve did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DepthCarveReport {
    /// Covered training pixels whose texel stands in front of the field's
    /// median depth by more than the margin.
    pub pixels_against: u64,
    /// Texels emptied.
    pub texels_carved: u64,
}

/// Whether the ray (`o`, unit `d`) through `geo`'s cube is still more than
/// half transparent at distance `limit` (half-field-cell steps).
fn passes(
    field: &dyn RadianceField,
    geo: &Geometry,
    step: f32,
    o: Vec3,
    d: Vec3,
    limit: f32,
) -> bool {
    let inv = d.recip();
    let (a, b) = ((geo.cube.min - o) * inv, (geo.cube.max - o) * inv);
    let (t0, t1) = (a.min(b).max_element().max(0.0), a.max(b).min_element());
    let end = limit.min(t1);
    let mut t = t0;
    let mut od = 0.0f32;
    while t < end {
        let h = step.min(end - t);
        od += field.density(o + (t + 0.5 * h) * d) * h;
        if od >= std::f32::consts::LN_2 {
            return false;
        }
        t += step;
    }
    true
}

/// Votes of `gb`'s pixels on the texels they show and empties the texels
/// voted out (`geo.opacity`, patch `p`). `margin` is in voxels.
pub fn carve(
    field: &dyn RadianceField,
    geo: &mut Geometry,
    p: u32,
    gb: &GBuffers,
    views: &[BakeView<'_>],
    margin: f32,
) -> DepthCarveReport {
    let fb = field.bounds();
    let step = 0.5 * (fb.max - fb.min).max_element() / field.resolution().max(1) as f32;
    let slack = margin * geo.voxel;
    // (texel, against) per covered pixel, then sorted by texel.
    let g: &Geometry = geo;
    let mut votes: Vec<(u32, bool)> = gb
        .pixel_rays(g, p, views)
        .map(|(px, [o, d, x])| {
            let depth = (x - o).dot(d);
            (px.texel, passes(field, g, step, o, d, depth + slack))
        })
        .collect();
    let pixels_against = votes.iter().filter(|v| v.1).count() as u64;
    votes.par_sort_unstable_by_key(|v| v.0);
    let mut texels_carved = 0u64;
    for run in votes.chunk_by(|a, b| a.0 == b.0) {
        let against = run.iter().filter(|v| v.1).count();
        if 2 * against > run.len() {
            if let Some(o) = geo.opacity.get_mut(run[0].0 as usize) {
                texels_carved += u64::from(*o);
                *o = false;
            }
        }
    }
    DepthCarveReport {
        pixels_against,
        texels_carved,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::quads::Quad;
    use crate::bake::trained::analytic::Sphere;
    use crate::bake::trained::gbuffer::GPixel;
    use crate::bake::{Aabb, Silhouette};
    use crate::camera::{Camera, Intrinsics};

    /// A camera on −y looks at a unit sphere; quad 0 sits on the sphere's
    /// near pole, quad 1 floats half a radius in front of it. Each pixel
    /// votes on the texel the ray through the quad's centre reaches: the
    /// floating quad's texel goes, the one on the surface stays.
    #[test]
    fn empties_texels_in_front_of_the_surface_and_keeps_the_surface() {
        let field = Sphere::new(Vec3::ZERO, 0.5);
        let p = 3;
        let quads = vec![
            Quad::facing_minus_y(Vec3::new(0.0, -0.5, 0.0), 0.1),
            Quad::facing_minus_y(Vec3::new(0.0, -0.75, 0.0), 0.1),
        ];
        let mut geo = Geometry {
            cube: Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            },
            voxel: 2.0 / 32.0,
            shell_voxels: 0,
            full_voxels: 0,
            quads,
            opacity: vec![true; 2 * 9],
        };
        let k = Intrinsics::from_fov_x(0.7, 16, 16);
        let cam = Camera::look_at(Vec3::new(0.0, -4.0, 0.0), Vec3::ZERO, Vec3::Z, k);
        let image = image::RgbaImage::new(16, 16);
        let views = [BakeView {
            camera: cam,
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        // Centre texel (index 4 of 3 × 3) of each quad, seen along +y.
        let pixels = [4u32, 9 + 4]
            .iter()
            .map(|&texel| GPixel {
                texel,
                dir: [0.0, 1.0, 0.0],
                target: [1.0; 3],
            })
            .collect::<Vec<_>>();
        let gb = GBuffers {
            per_view: vec![pixels.len()],
            pixels,
            subsamples: Vec::new(),
            background: Vec::new(),
        };
        let r = carve(&field, &mut geo, p, &gb, &views, 1.0);
        assert_eq!(r.pixels_against, 1);
        assert_eq!(r.texels_carved, 1);
        assert!(geo.opacity[4], "the texel on the surface stays");
        assert!(!geo.opacity[9 + 4], "the floating texel goes");
        assert_eq!(geo.opacity.iter().filter(|&&o| !o).count(), 1);
    }
}
