//! Analytic radiance fields: stand-ins for trained ones in tests and
//! measurements, read through the same [`RadianceField`] trait.
//!
//! Density is a thin ramp across a signed distance function's zero set
//! (σ = σ_max at `band/2` inside, 0 at `band/2` outside), so the surface the
//! baker extracts is the SDF's. Colour is an approximation of the built-in
//! renderer's shading (albedo under a key light, a fill and an ambient
//! term, plus a Blinn–Phong highlight that moves with the view, through
//! the same display curve) — deliberately not exact: the fine-tune has to
//! close the gap against the captured images, as it must for a trained
//! field's errors.

use glam::Vec3;

use super::super::Aabb;
use crate::capture::ObjectInfo;
use crate::procedural::{render::display, ObjectKind, Placement};
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

/// A built-in procedural object where a capture placed it.
#[derive(Debug, Clone, Copy)]
pub struct Builtin {
    /// Which object.
    pub kind: ObjectKind,
    /// Local → world.
    pub placement: Placement,
    /// Texture frequency multiplier.
    pub detail: f32,
    /// World box the field lives in.
    pub bounds: Aabb,
}

/// Approximate lights (directions toward the light, world frame).
const KEY: (Vec3, Vec3) = (Vec3::new(0.478, -0.382, 0.791), Vec3::new(2.35, 2.2, 2.0));
const FILL: (Vec3, Vec3) = (Vec3::new(-0.73, 0.61, 0.31), Vec3::new(0.32, 0.38, 0.48));
const AMBIENT: Vec3 = Vec3::new(0.31, 0.33, 0.37);

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
        Some(Self {
            kind,
            placement,
            detail,
            bounds: Aabb { min: lo, max: hi }.grown(margin),
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
        let local = self.placement.to_local(p);
        let h = 2e-3;
        let k = [
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        let nl = k
            .iter()
            .fold(Vec3::ZERO, |acc, &e| acc + e * self.kind.sdf(local + e * h))
            .normalize_or(Vec3::Z);
        let m = self.kind.material(local, nl, self.detail);
        let n = self.placement.dir_to_world(nl);
        let v = -dir;
        let mut diffuse = AMBIENT * (0.75 + 0.25 * n.z);
        let mut spec = Vec3::ZERO;
        for (l, c) in [KEY, FILL] {
            let ndl = n.dot(l).max(0.0);
            diffuse += c * ndl;
            let ndh = n.dot((l + v).normalize_or_zero()).max(0.0);
            spec += c * ndl * ndh.powf(m.shininess) * (m.shininess + 8.0) / 25.0;
        }
        let spec_rgb = Vec3::splat(m.specular).lerp(m.albedo, m.metal);
        display(m.albedo * (1.0 - 0.85 * m.metal) * diffuse + spec_rgb * spec)
    }
}
