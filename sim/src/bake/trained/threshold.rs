//! The surface's density threshold, checked against the photos.
//!
//! The extraction calls a point inside where the field's density reaches
//! σ, the density whose opacity over half a field cell is the bake's
//! `surface_alpha`. A finer field's half cell is shorter, so the same α
//! asks for a higher density: a 384³ field needs three times a 128³
//! field's. Lego's and chair's 384³ fields reach it on every surface, but
//! gear's, trained from the evaluation's 50 views, draws parts of its hub
//! with a softer ramp whose peak stays below it: the extraction found no
//! surface there and holes were 54 % of the bake's squared error
//! (docs/baking.md, "Session 27").
//!
//! So σ is checked against the photos: the ray of every pixel a photo
//! shows as wholly object must meet the inside at the surface the field
//! shows there, before the ray is half opaque (a denser surface further
//! back would give the pixel the wrong one). Along a sample of those rays
//! the field's peak density up to that point is found (marched at the
//! same half cell), and σ is lowered to the peak that all but a share
//! `miss` of them reach, never below [`MIN_SIGMA_SHARE`] of α's.

use glam::Vec3;
use rayon::prelude::*;

use super::super::BakeView;
use crate::train::field::RadianceField;

/// The lowest σ the check may choose, as a share of α's σ: a guard
/// against turning the field's haze into surface (chosen, not measured;
/// gear's default field needed 44 %).
pub const MIN_SIGMA_SHARE: f32 = 0.25;

/// Object rays sampled per bake, at most (spread evenly over the views).
pub const MAX_RAYS: usize = 32_768;

/// What the check found.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ThresholdReport {
    /// σ from `surface_alpha` over half a field cell, per world unit.
    pub sigma_alpha: f32,
    /// σ the extraction uses.
    pub sigma: f32,
    /// Object rays marched.
    pub rays: u64,
    /// Of those, the ones whose peak density stays below `sigma_alpha`.
    pub below: u64,
    /// Wall time of the check, seconds.
    pub seconds: f64,
}

impl ThresholdReport {
    /// Whether the check lowered σ.
    pub fn lowered(&self) -> bool {
        self.sigma < self.sigma_alpha
    }
}

/// σ whose opacity over half a cell of `field` is `alpha`.
pub fn sigma_of_alpha(field: &dyn RadianceField, alpha: f32) -> f32 {
    let b = field.bounds();
    let edge = (b.max - b.min).max_element();
    let step = 0.5 * edge / field.resolution().max(1) as f32;
    let alpha = alpha.clamp(1e-4, 1.0 - 1e-4);
    -(1.0 - alpha).ln() / step
}

/// The extraction's σ for `field` at `alpha`, lowered so that all but a
/// share `miss` of the sampled object rays of `views` reach it (`miss` 0
/// or no object pixel: α's σ unchanged).
pub fn surface_sigma(
    field: &dyn RadianceField,
    views: &[BakeView<'_>],
    alpha: f32,
    miss: f32,
) -> ThresholdReport {
    let t0 = std::time::Instant::now();
    let sigma_alpha = sigma_of_alpha(field, alpha);
    let mut report = ThresholdReport {
        sigma_alpha,
        sigma: sigma_alpha,
        ..Default::default()
    };
    if !(miss > 0.0 && miss < 1.0) || views.is_empty() {
        return report;
    }
    let rays = object_rays(views, MAX_RAYS);
    let b = field.bounds();
    let step = 0.5 * (b.max - b.min).max_element() / field.resolution().max(1) as f32;
    // Peaks are capped at α's σ: a ray that reaches it stops there.
    let mut peaks: Vec<f32> = rays
        .par_iter()
        .map(|&(o, d)| peak_density(field, o, d, step, sigma_alpha))
        .collect();
    if peaks.is_empty() {
        return report;
    }
    peaks.sort_by(f32::total_cmp);
    report.rays = peaks.len() as u64;
    report.below = peaks.iter().filter(|&&s| s < sigma_alpha).count() as u64;
    let k = ((miss * peaks.len() as f32) as usize).min(peaks.len() - 1);
    report.sigma = peaks[k].clamp(MIN_SIGMA_SHARE * sigma_alpha, sigma_alpha);
    report.seconds = t0.elapsed().as_secs_f64();
    report
}

/// Up to `max` rays (origin, unit direction) through pixel centres the
/// photos show as wholly this object, spread evenly over `views`.
fn object_rays(views: &[BakeView<'_>], max: usize) -> Vec<(Vec3, Vec3)> {
    let per_view = (max / views.len()).max(1);
    views
        .par_iter()
        .flat_map_iter(|v| {
            let (w, h) = v.image.dimensions();
            let object: Vec<(u32, u32)> = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| v.coverage(x, y) == u8::MAX)
                .collect();
            let stride = object.len().div_ceil(per_view).max(1);
            object
                .into_iter()
                .step_by(stride)
                .map(|(x, y)| v.camera.ray(x as f32 + 0.5, y as f32 + 0.5))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// The largest density along the ray inside the field's bounds, sampled
/// every `step`, up to where the ray's transmittance falls below ½ (the
/// surface the photo shows: a denser one further back must not count),
/// or `cap` as soon as a sample reaches it.
fn peak_density(field: &dyn RadianceField, o: Vec3, d: Vec3, step: f32, cap: f32) -> f32 {
    let b = field.bounds();
    let inv = d.recip();
    let (ta, tb) = ((b.min - o) * inv, (b.max - o) * inv);
    let t0 = ta.min(tb).max_element().max(0.0);
    let t1 = ta.max(tb).min_element();
    if !(t0 < t1 && t0.is_finite() && t1.is_finite() && step > 0.0) {
        return 0.0;
    }
    let n = ((t1 - t0) / step).ceil() as usize;
    let mut peak = 0f32;
    let mut tau = 0f32;
    for i in 0..n {
        let s = field.density(o + d * (t0 + (i as f32 + 0.5) * step));
        if s >= cap {
            return cap;
        }
        peak = peak.max(s);
        tau += s * step;
        if tau > std::f32::consts::LN_2 {
            break;
        }
    }
    peak
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{Aabb, Silhouette};
    use crate::camera::{Camera, Intrinsics};

    /// A ball of radius 0.5 whose density is `core` inside radius 0.25
    /// and `rim` in the shell beyond (a soft surface), in a 64³ field.
    struct Ball {
        core: f32,
        rim: f32,
    }

    impl RadianceField for Ball {
        fn bounds(&self) -> Aabb {
            Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            }
        }
        fn resolution(&self) -> u32 {
            64
        }
        fn density(&self, p: Vec3) -> f32 {
            match p.length() {
                r if r < 0.25 => self.core,
                r if r < 0.5 => self.rim,
                _ => 0.0,
            }
        }
        fn color(&self, _: Vec3, _: Vec3) -> Vec3 {
            Vec3::ONE
        }
    }

    /// A 32 × 32 photo from −z in which the disc of radius 0.5 is object.
    fn view(image: &mut image::RgbaImage) -> Camera {
        let k = Intrinsics::from_fov_x(0.5, 32, 32);
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, -4.0), Vec3::ZERO, Vec3::Y, k);
        for (x, y, px) in image.enumerate_pixels_mut() {
            let (o, d) = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            // Distance of the ray from the centre.
            let r = (o - d * o.dot(d)).length();
            px.0 = if r < 0.5 {
                [200, 200, 200, 255]
            } else {
                [0; 4]
            };
        }
        cam
    }

    #[test]
    fn sigma_is_lowered_only_where_object_rays_miss_it() {
        let mut image = image::RgbaImage::new(32, 32);
        let camera = view(&mut image);
        let views = [BakeView {
            camera,
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        let dense = Ball {
            core: 1e4,
            rim: 1e4,
        };
        let s_alpha = sigma_of_alpha(&dense, 0.05);
        // Every ray meets a density above α's σ: nothing changes.
        let r = surface_sigma(&dense, &views, 0.05, 0.01);
        assert!(r.rays > 100, "{r:?}");
        assert_eq!((r.below, r.sigma, r.lowered()), (0, s_alpha, false));
        // A rim at half α's σ: the rays through the rim only (most of the
        // disc) peak there, so σ comes down to it.
        let soft = Ball {
            core: 1e4,
            rim: 0.5 * s_alpha,
        };
        let r = surface_sigma(&soft, &views, 0.05, 0.01);
        assert!(r.below > r.rays / 2, "{r:?}");
        assert!(
            r.lowered() && (r.sigma - 0.5 * s_alpha).abs() < 1e-3 * s_alpha,
            "{r:?}"
        );
        // Never below the floor, and off at a share of 0.
        let faint = Ball {
            core: 1e4,
            rim: 0.01 * s_alpha,
        };
        let r = surface_sigma(&faint, &views, 0.05, 0.01);
        assert_eq!(r.sigma, MIN_SIGMA_SHARE * s_alpha);
        let r = surface_sigma(&faint, &views, 0.05, 0.0);
        assert_eq!((r.rays, r.sigma), (0, s_alpha));
    }

    /// A soft slab (z in [−0.8, −0.2], density `soft`) in front of a
    /// dense wall (z in [0.2, 0.4]), every pixel object.
    struct Slabs {
        soft: f32,
    }

    impl RadianceField for Slabs {
        fn bounds(&self) -> Aabb {
            Ball {
                core: 0.0,
                rim: 0.0,
            }
            .bounds()
        }
        fn resolution(&self) -> u32 {
            64
        }
        fn density(&self, p: Vec3) -> f32 {
            match p.z {
                z if (-0.8..-0.2).contains(&z) => self.soft,
                z if (0.2..0.4).contains(&z) => 1e4,
                _ => 0.0,
            }
        }
        fn color(&self, _: Vec3, _: Vec3) -> Vec3 {
            Vec3::ONE
        }
    }

    #[test]
    fn a_denser_surface_behind_the_shown_one_does_not_count() {
        let image = image::RgbaImage::from_pixel(16, 16, image::Rgba([9, 9, 9, 255]));
        let k = Intrinsics::from_fov_x(0.3, 16, 16);
        let views = [BakeView {
            camera: Camera::look_at(Vec3::new(0.0, 0.0, -4.0), Vec3::ZERO, Vec3::Y, k),
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        let s_alpha = sigma_of_alpha(&Slabs { soft: 0.0 }, 0.05);
        // The soft slab alone makes a ray more than half opaque (its
        // optical depth 0.6 · 0.5 · σ ≈ 1 > ln 2): it is the surface the
        // photo shows, and the wall behind it does not lift its peak.
        let r = surface_sigma(
            &Slabs {
                soft: 0.5 * s_alpha,
            },
            &views,
            0.05,
            0.02,
        );
        assert_eq!(r.below, r.rays, "{r:?}");
        assert!((r.sigma - 0.5 * s_alpha).abs() < 1e-3 * s_alpha, "{r:?}");
        // A faint haze in front (optical depth far under ln 2) is seen
        // through: the wall is the surface, and σ stays.
        let r = surface_sigma(
            &Slabs {
                soft: 0.05 * s_alpha,
            },
            &views,
            0.05,
            0.02,
        );
        assert_eq!((r.below, r.sigma), (0, s_alpha), "{r:?}");
    }

    #[test]
    fn a_photo_without_object_pixels_keeps_alphas_sigma() {
        let image = image::RgbaImage::new(16, 16);
        let k = Intrinsics::from_fov_x(0.5, 16, 16);
        let views = [BakeView {
            camera: Camera::look_at(Vec3::new(0.0, 0.0, -4.0), Vec3::ZERO, Vec3::Y, k),
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        let f = Ball {
            core: 1.0,
            rim: 1.0,
        };
        let r = surface_sigma(&f, &views, 0.05, 0.01);
        assert_eq!((r.rays, r.sigma), (0, sigma_of_alpha(&f, 0.05)));
    }
}
