//! Signed-distance primitives and operators (local object units).
//!
//! Exact distances where cheap (sphere, box, capsule, torus); the others are
//! bounds whose Lipschitz constant the object's march step accounts for.

use glam::{Vec2, Vec3, Vec3Swizzles};

/// Sphere of radius `r` at the origin.
#[inline]
pub fn sphere(p: Vec3, r: f32) -> f32 {
    p.length() - r
}

/// Box with half extents `half`, edges rounded by `r`.
#[inline]
pub fn round_box(p: Vec3, half: Vec3, r: f32) -> f32 {
    let q = p.abs() - half + Vec3::splat(r);
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - r
}

/// Torus around the z axis: ring radius `big_r`, tube radius `r`.
#[inline]
pub fn torus_z(p: Vec3, big_r: f32, r: f32) -> f32 {
    Vec2::new(p.xy().length() - big_r, p.z).length() - r
}

/// Cone-like capsule from `a` (radius `ra`) to `b` (radius `rb`), linear in
/// the radius (a bound, exact when `ra == rb`).
#[inline]
pub fn tapered_capsule(p: Vec3, a: Vec3, b: Vec3, ra: f32, rb: f32) -> f32 {
    let pa = p - a;
    let ba = b - a;
    let h = (pa.dot(ba) / ba.length_squared().max(1e-12)).clamp(0.0, 1.0);
    (pa - ba * h).length() - (ra + (rb - ra) * h)
}

/// Cylinder around z: radius `r`, from `z0` to `z1`, edges rounded by `round`.
#[inline]
pub fn cylinder_z(p: Vec3, r: f32, z0: f32, z1: f32, round: f32) -> f32 {
    let zc = 0.5 * (z0 + z1);
    let hh = 0.5 * (z1 - z0);
    let d = Vec2::new(p.xy().length() - r + round, (p.z - zc).abs() - hh + round);
    d.max_element().min(0.0) + d.max(Vec2::ZERO).length() - round
}

/// Extrudes a 2-D distance `d2` along z over `[z0, z1]`.
#[inline]
pub fn extrude(d2: f32, z: f32, z0: f32, z1: f32) -> f32 {
    let dz = (z - 0.5 * (z0 + z1)).abs() - 0.5 * (z1 - z0);
    let w = Vec2::new(d2, dz);
    w.max_element().min(0.0) + w.max(Vec2::ZERO).length()
}

/// Isosceles trapezoid symmetric about the y axis: half width `r1` at
/// y = −he, `r2` at y = +he (Quílez's exact formula).
#[inline]
pub fn trapezoid(p: Vec2, r1: f32, r2: f32, he: f32) -> f32 {
    let k1 = Vec2::new(r2, he);
    let k2 = Vec2::new(r2 - r1, 2.0 * he);
    let p = Vec2::new(p.x.abs(), p.y);
    let ca = Vec2::new(
        p.x - p.x.min(if p.y < 0.0 { r1 } else { r2 }),
        p.y.abs() - he,
    );
    let cb = p - k1 + k2 * ((k1 - p).dot(k2) / k2.length_squared()).clamp(0.0, 1.0);
    let s = if cb.x < 0.0 && ca.y < 0.0 { -1.0 } else { 1.0 };
    s * ca.length_squared().min(cb.length_squared()).sqrt()
}

/// Polynomial smooth minimum with blend width `k`.
#[inline]
pub fn smin(a: f32, b: f32, k: f32) -> f32 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// Polar repetition: the angle of `q` folded into one of `n` sectors
/// centred on the +x axis; returns the folded point and the sector index.
#[inline]
pub fn polar_fold(q: Vec2, n: u32) -> (Vec2, i32) {
    let sector = std::f32::consts::TAU / n as f32;
    let a = q.y.atan2(q.x);
    let k = (a / sector).round();
    let a2 = a - k * sector;
    let r = q.length();
    (Vec2::new(r * a2.cos(), r * a2.sin()), k as i32)
}

/// A surface of revolution about z with radius profile `r(z)` and its slope
/// `dr/dz`: the radial gap divided by the profile's slope factor.
#[inline]
pub fn lathe(p: Vec3, r: f32, dr_dz: f32) -> f32 {
    (p.xy().length() - r) / (1.0 + dr_dz * dr_dz).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_have_the_right_sign_and_distance() {
        assert!((sphere(Vec3::new(2.0, 0.0, 0.0), 1.0) - 1.0).abs() < 1e-6);
        assert!((round_box(Vec3::new(0.0, 0.0, 3.0), Vec3::ONE, 0.0) - 2.0).abs() < 1e-6);
        assert!(round_box(Vec3::ZERO, Vec3::ONE, 0.1) < 0.0);
        assert!((torus_z(Vec3::new(1.0, 0.0, 0.5), 1.0, 0.25) - 0.25).abs() < 1e-6);
        assert!(
            (tapered_capsule(Vec3::new(0.0, 1.0, 0.5), Vec3::ZERO, Vec3::Z, 0.5, 0.5) - 0.5).abs()
                < 1e-6
        );
        assert!((cylinder_z(Vec3::new(0.0, 0.0, 2.0), 1.0, -1.0, 1.0, 0.0) - 1.0).abs() < 1e-6);
        assert!((trapezoid(Vec2::new(0.0, 2.0), 1.0, 0.5, 1.0) - 1.0).abs() < 1e-6);
        assert!(trapezoid(Vec2::ZERO, 1.0, 0.5, 1.0) < 0.0);
        assert!(smin(1.0, 1.0, 0.5) < 1.0);
        let (q, k) = polar_fold(Vec2::new(0.0, 1.0), 4);
        assert_eq!(k, 1);
        assert!((q - Vec2::new(1.0, 0.0)).length() < 1e-5);
    }
}
