//! Analytic radiance fields: stand-ins for trained ones in tests and
//! measurements, read through the same [`RadianceField`] trait.
//!
//! Density is a thin ramp across a signed distance function's zero set
//! (σ = σ_max at `band/2` inside, 0 at `band/2` outside), so the surface the
//! baker extracts is the SDF's. The built-in objects' colour is the
//! built-in renderer's shading of the nearest surface point.

use glam::Vec3;

use super::super::Aabb;
use crate::capture::ObjectInfo;
use crate::procedural::{ObjectKind, PlacedObject, Placement, RenderOptions, SceneRenderer};
use crate::train::field::RadianceField;

/// Peak density of the analytic fields, per world unit: opaque within a
/// few thousandths of a unit.
pub const SIGMA_MAX: f32 = 1.0e4;

/// The density of a thin shell of width `band` around an SDF's zero set.
#[inline]
fn ramp(sdf: f32, band: f32) -> f32 {
    SIGMA_MAX * (0.5 - sdf / band).clamp(0.0, 1.0)
}

/// A striped sphere with a view-dependent sheen (unit tests).
#[derive(Debug, Clone, Copy)]
pub struct Sphere {
    /// Centre, world units.
    pub centre: Vec3,
    /// Radius, world units (0: an empty field).
    pub radius: f32,
}

impl Sphere {
    /// A sphere at `centre` of radius `radius` inside the NeRF-synthetic box.
    pub fn new(centre: Vec3, radius: f32) -> Self {
        Self { centre, radius }
    }

    /// Colour without the view-dependent part.
    pub fn albedo(&self, p: Vec3) -> Vec3 {
        let q = p - self.centre;
        let stripe = (6.0 * q.z / self.radius.max(1e-3)).sin();
        Vec3::new(0.55 + 0.35 * stripe, 0.35, 0.6 - 0.3 * stripe)
    }
}

impl RadianceField for Sphere {
    fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::splat(-1.5),
            max: Vec3::splat(1.5),
        }
    }

    fn resolution(&self) -> u32 {
        128
    }

    fn density(&self, p: Vec3) -> f32 {
        if self.radius <= 0.0 {
            return 0.0;
        }
        ramp((p - self.centre).length() - self.radius, 0.01)
    }

    fn color(&self, p: Vec3, dir: Vec3) -> Vec3 {
        let n = (p - self.centre).normalize_or(Vec3::Z);
        let sheen = 0.25 * (-dir.dot(n)).max(0.0).powi(8);
        (self.albedo(p) + Vec3::splat(sheen)).clamp(Vec3::ZERO, Vec3::ONE)
    }
}

/// A built-in procedural object where a capture placed it: density from
/// its SDF, colour from the built-in renderer's own shading of the nearest
/// surface point (so the field plays a well-trained one; the images differ
/// from it only by antialiasing and any lighting the capture turned off).
pub struct Builtin {
    /// Which object.
    pub kind: ObjectKind,
    /// Local → world.
    pub placement: Placement,
    /// World box the field lives in.
    pub bounds: Aabb,
    renderer: SceneRenderer,
    opts: RenderOptions,
}

impl std::fmt::Debug for Builtin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Builtin")
            .field("kind", &self.kind)
            .field("placement", &self.placement)
            .field("bounds", &self.bounds)
            .finish()
    }
}

impl Builtin {
    /// The field of an object of a built-in capture's `scene.json`; `None`
    /// if its kind is not a built-in object.
    pub fn from_info(info: &ObjectInfo) -> Option<Self> {
        let kind = ObjectKind::from_name(&info.kind)?;
        let pl = &info.placement;
        let placement = Placement {
            translation: Vec3::from_array(pl.translation.map(|v| v as f32)),
            rotation_z_deg: pl.rotation_z_deg as f32,
            scale: pl.scale as f32,
        };
        let detail = info
            .texture_frequency
            .map_or(1.0, |f| f as f32 / kind.texture_frequency());
        let (lo, hi) = (
            Vec3::from_array(info.bounds_min.map(|v| v as f32)),
            Vec3::from_array(info.bounds_max.map(|v| v as f32)),
        );
        let margin = 0.1 * (hi - lo).max_element() + 0.01;
        let placed = PlacedObject {
            name: info.name.clone(),
            kind,
            placement,
            detail,
        };
        Some(Self {
            kind,
            placement,
            bounds: Aabb { min: lo, max: hi }.grown(margin),
            renderer: SceneRenderer::new(&[placed]),
            opts: RenderOptions::default(),
        })
    }

    /// Signed distance in world units.
    #[inline]
    fn sdf(&self, p: Vec3) -> f32 {
        self.kind.sdf(self.placement.to_local(p)) * self.placement.scale
    }
}

impl RadianceField for Builtin {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn resolution(&self) -> u32 {
        256
    }

    fn density(&self, p: Vec3) -> f32 {
        let b = &self.bounds;
        if p.cmplt(b.min).any() || p.cmpgt(b.max).any() {
            return 0.0;
        }
        let edge = (b.max - b.min).max_element();
        ramp(self.sdf(p), 0.5 * edge / 256.0)
    }

    fn color(&self, p: Vec3, dir: Vec3) -> Vec3 {
        // Two Newton steps onto the surface, then the renderer's shading.
        let mut q = p;
        for _ in 0..2 {
            let h = 1e-3;
            let d = self.sdf(q);
            let grad = Vec3::new(
                self.sdf(q + Vec3::X * h) - self.sdf(q - Vec3::X * h),
                self.sdf(q + Vec3::Y * h) - self.sdf(q - Vec3::Y * h),
                self.sdf(q + Vec3::Z * h) - self.sdf(q - Vec3::Z * h),
            ) / (2.0 * h);
            if grad.length_squared() > 1e-6 {
                q -= d * grad / grad.length_squared();
            }
        }
        self.renderer
            .surface_colour(0, q, dir, &self.opts)
            .clamp(Vec3::ZERO, Vec3::ONE)
    }
}
