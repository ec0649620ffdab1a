//! Deterministic procedural noise: integer hashing, value noise, fBm and
//! cellular (Worley) noise. No global state, the same on every machine.

use glam::{IVec3, Vec3};

/// A well-mixed 32-bit hash (Wellons' `lowbias32`).
#[inline]
pub fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Hash of a lattice point.
#[inline]
pub fn hash3(i: IVec3) -> u32 {
    hash_u32(
        (i.x as u32) ^ hash_u32((i.y as u32) ^ hash_u32((i.z as u32).wrapping_add(0x9e37_79b9))),
    )
}

/// Hash of a lattice point as a float in [0, 1).
#[inline]
pub fn hash3f(i: IVec3) -> f32 {
    (hash3(i) >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Smooth value noise in [0, 1], one feature per unit.
#[inline]
pub fn value(p: Vec3) -> f32 {
    let i = p.floor();
    let f = p - i;
    let u = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let i = i.as_ivec3();
    let h = |dx, dy, dz| hash3f(i + IVec3::new(dx, dy, dz));
    let x00 = h(0, 0, 0) + (h(1, 0, 0) - h(0, 0, 0)) * u.x;
    let x10 = h(0, 1, 0) + (h(1, 1, 0) - h(0, 1, 0)) * u.x;
    let x01 = h(0, 0, 1) + (h(1, 0, 1) - h(0, 0, 1)) * u.x;
    let x11 = h(0, 1, 1) + (h(1, 1, 1) - h(0, 1, 1)) * u.x;
    let y0 = x00 + (x10 - x00) * u.y;
    let y1 = x01 + (x11 - x01) * u.y;
    y0 + (y1 - y0) * u.z
}

/// Fractal sum of `octaves` value-noise octaves (lacunarity 2, gain 0.5),
/// normalised to [0, 1].
#[inline]
pub fn fbm(p: Vec3, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 0.5, 0.0, p);
    for _ in 0..octaves {
        sum += amp * value(q);
        norm += amp;
        amp *= 0.5;
        q = q * 2.03 + Vec3::new(17.1, -3.7, 5.3);
    }
    sum / norm
}

/// Cellular noise: distance to the nearest jittered feature point (one per
/// unit cell) and that cell's hash.
#[inline]
pub fn cellular(p: Vec3) -> (f32, u32) {
    let i = p.floor().as_ivec3();
    let mut best = (f32::MAX, 0u32);
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                let c = i + IVec3::new(dx, dy, dz);
                let h = hash3(c);
                let jitter = Vec3::new(
                    (h & 0xff) as f32 / 255.0,
                    ((h >> 8) & 0xff) as f32 / 255.0,
                    ((h >> 16) & 0xff) as f32 / 255.0,
                );
                let d = (c.as_vec3() + 0.15 + 0.7 * jitter - p).length_squared();
                if d < best.0 {
                    best = (d, h);
                }
            }
        }
    }
    (best.0.sqrt(), best.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_bounded_deterministic_and_continuous() {
        for k in 0..200 {
            let p = Vec3::new(k as f32 * 0.37, k as f32 * -0.11, k as f32 * 0.05);
            let v = value(p);
            assert!((0.0..=1.0).contains(&v));
            assert_eq!(v, value(p));
            assert!((value(p) - value(p + Vec3::splat(1e-4))).abs() < 1e-2);
            let f = fbm(p, 4);
            assert!((0.0..=1.0).contains(&f));
        }
        let (d, _) = cellular(Vec3::new(0.3, 0.2, 0.9));
        assert!(d < 1.8);
    }
}
