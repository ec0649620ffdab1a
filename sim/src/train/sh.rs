//! Real spherical harmonics up to degree 2 (the basis Plenoxels and
//! 3D-Gaussian splatting use), evaluated once per ray.

use glam::Vec3;

/// Coefficients per channel at the highest supported degree.
pub const MAX_COUNT: usize = 9;

/// Highest supported degree.
pub const MAX_DEGREE: u32 = 2;

const C0: f32 = 0.282_094_8;
const C1: f32 = 0.488_602_5;
const C2: [f32; 5] = [
    1.092_548_4,
    -1.092_548_4,
    0.315_391_57,
    -1.092_548_4,
    0.546_274_2,
];

/// Coefficients per channel of a degree: (degree + 1)².
#[inline]
pub const fn count(degree: u32) -> usize {
    ((degree + 1) * (degree + 1)) as usize
}

/// Writes the basis of `degree` for unit direction `d` into `out` and
/// returns how many values it wrote.
#[inline]
pub fn eval(degree: u32, d: Vec3, out: &mut [f32; MAX_COUNT]) -> usize {
    let (x, y, z) = (d.x, d.y, d.z);
    out[0] = C0;
    if degree >= 1 {
        out[1] = -C1 * y;
        out[2] = C1 * z;
        out[3] = -C1 * x;
    }
    if degree >= 2 {
        out[4] = C2[0] * x * y;
        out[5] = C2[1] * y * z;
        out[6] = C2[2] * (2.0 * z * z - x * x - y * y);
        out[7] = C2[3] * x * z;
        out[8] = C2[4] * (x * x - y * y);
    }
    count(degree.min(MAX_DEGREE))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The basis is orthonormal on the sphere: a Monte-Carlo check of the
    /// Gram matrix over a Fibonacci sphere.
    #[test]
    fn basis_is_orthonormal() {
        let n = 20_000;
        let mut gram = [[0.0f64; MAX_COUNT]; MAX_COUNT];
        for s in 0..n {
            let z = 1.0 - 2.0 * (s as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = s as f64 * 2.399_963_229_728_653;
            let d = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            let mut b = [0.0; MAX_COUNT];
            eval(2, d, &mut b);
            for i in 0..MAX_COUNT {
                for j in 0..MAX_COUNT {
                    gram[i][j] += f64::from(b[i] * b[j]) * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        for (i, row) in gram.iter().enumerate() {
            for (j, &g) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 2e-3, "gram[{i}][{j}] = {g}");
            }
        }
    }
}
