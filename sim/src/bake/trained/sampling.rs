//! How many samples per training pixel the fine-tune takes: one, or the
//! renderer's 2 × 2 (every covered subsample's texel, their mean features
//! through the MLP, partly covered pixels blended with white).
//!
//! The renderer always supersamples. Training as it renders gains at any
//! g (lego and chair (128, 17): +0.25 dB) but costs 1.5–2× the bake time,
//! and the 60 s bake is at g = 128. The loss from one sample per
//! pixel grows as voxels shrink: once a voxel spans fewer than
//! [`SUPERSAMPLE_BELOW_PX`] pixels, a pixel's subsamples often fall on
//! different quads, so one sample per pixel trains features the renderer
//! never shows alone and drops quads only subsamples show (holes). Chair
//! (256, 17) scored below (128, 17) for that reason (`docs/baking.md`,
//! "Session 20"). So the default supersamples there, where the bake is
//! past the 60 s anyway.

use super::super::{Aabb, BakeView};

/// A voxel narrower than this (pixels, as the training views see it)
/// makes [`FinetuneSampling::Auto`] supersample. Chair's voxel is 4.5 px
/// at g = 128 (supersampling: +0.25 dB, 90 s against 42 s) and 3.0 px at
/// g = 192 (one sample per pixel already below g = 128); lego's 5.1 px and
/// 2.6 px at 128 and 256 (`docs/baking.md`, "Session 20").
pub const SUPERSAMPLE_BELOW_PX: f32 = 4.0;

/// The fine-tune's samples per training pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FinetuneSampling {
    /// 2 × 2 when a voxel spans fewer than [`SUPERSAMPLE_BELOW_PX`] pixels.
    #[default]
    Auto,
    /// Always 2 × 2 (`--train-supersample`).
    Supersampled,
    /// Always one (`--no-train-supersample`).
    OnePerPixel,
}

impl FinetuneSampling {
    /// Whether the fine-tune supersamples, given the voxel's edge in
    /// pixels (`None`: unknown, no view sees the cube; one sample then).
    pub fn supersampled(self, voxel_px: Option<f32>) -> bool {
        match self {
            FinetuneSampling::Auto => voxel_px.is_some_and(|v| v < SUPERSAMPLE_BELOW_PX),
            FinetuneSampling::Supersampled => true,
            FinetuneSampling::OnePerPixel => false,
        }
    }
}

/// The edge of `cube` in pixels as the training views see it: the median
/// over views of the edge's length at the cube centre's depth (`None`
/// when no view is in front of the centre).
pub fn cube_px(cube: &Aabb, views: &[BakeView<'_>]) -> Option<f32> {
    let centre = 0.5 * (cube.min + cube.max);
    let edge = (cube.max - cube.min).max_element();
    let mut px: Vec<f32> = views
        .iter()
        .filter_map(|v| {
            let depth = (centre - v.camera.position()).length();
            let px = edge * v.camera.intrinsics.fx / depth;
            (depth > 1e-6 && px.is_finite()).then_some(px)
        })
        .collect();
    if px.is_empty() {
        return None;
    }
    let mid = px.len() / 2;
    let (_, m, _) = px.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*m)
}

/// The voxel's edge in pixels at grid `g` over `cube`.
pub fn voxel_px(cube: &Aabb, views: &[BakeView<'_>], g: u32) -> Option<f32> {
    cube_px(cube, views).map(|e| e / g.max(1) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Intrinsics};
    use glam::Vec3;
    use image::RgbaImage;

    fn unit_cube() -> Aabb {
        Aabb {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        }
    }

    fn view_at(image: &RgbaImage, distance: f32, fx: f32) -> BakeView<'_> {
        let camera = Camera::look_at(
            Vec3::new(0.0, -distance, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            Intrinsics {
                fx,
                fy: fx,
                cx: 32.0,
                cy: 32.0,
                width: 64,
                height: 64,
            },
        );
        BakeView {
            camera,
            image,
            silhouette: super::super::super::Silhouette::Alpha,
        }
    }

    #[test]
    fn the_cube_edge_is_the_median_view_s() {
        let img = RgbaImage::new(64, 64);
        // Edge 1 at distance 2 with fx 100: 50 px; at 4: 25 px; at 1: 100.
        let views = [
            view_at(&img, 2.0, 100.0),
            view_at(&img, 4.0, 100.0),
            view_at(&img, 1.0, 100.0),
        ];
        let e = cube_px(&unit_cube(), &views).unwrap();
        assert!((e - 50.0).abs() < 1e-3, "{e}");
        let v = voxel_px(&unit_cube(), &views, 25).unwrap();
        assert!((v - 2.0).abs() < 1e-4, "{v}");
        assert_eq!(cube_px(&unit_cube(), &[]), None);
    }

    #[test]
    fn auto_supersamples_below_the_threshold_only() {
        let auto = FinetuneSampling::default();
        assert_eq!(auto, FinetuneSampling::Auto);
        assert!(auto.supersampled(Some(SUPERSAMPLE_BELOW_PX - 0.01)));
        assert!(!auto.supersampled(Some(SUPERSAMPLE_BELOW_PX)));
        assert!(!auto.supersampled(Some(f32::INFINITY)));
        assert!(!auto.supersampled(None));
        assert!(FinetuneSampling::Supersampled.supersampled(Some(100.0)));
        assert!(FinetuneSampling::Supersampled.supersampled(None));
        assert!(!FinetuneSampling::OnePerPixel.supersampled(Some(0.5)));
    }
}
