//! Where a field is only haze: the optical depth of a small box of field
//! cells around each cell.
//!
//! A trained field leaves faint density where no training view needed
//! emptiness (under lego's base plate, inside concavities): its volume
//! renders show it as a barely visible veil, but a point test of density
//! turns it into opaque quads (lego's held-out side view shows a band of
//! them under the plate). A surface, however soft, has an optical depth
//! of several units across it; haze has a small one. So a point counts as
//! inside only where the density averaged over a box of `span` cells,
//! times the box's edge, reaches `-ln(1 − alpha)`: across a flat surface
//! that product is the optical depth through the sheet, whatever the
//! ramp's shape. The box average alone would dilate a sharp surface by
//! half a box, so it masks the point test ([`super::extract::Surface`]),
//! which keeps placing the surface.

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::Aabb;
use crate::train::field::RadianceField;

/// Largest lattice edge the mask samples (256³ cells: 16 M samples, 16 MiB
/// of bits as bytes).
pub const MAX_RES: u32 = 256;

/// Cells of the field's lattice whose box optical depth reaches the
/// threshold.
#[derive(Debug, Clone)]
pub struct HazeMask {
    bounds: Aabb,
    res: u32,
    solid: Vec<bool>,
}

impl HazeMask {
    /// The mask of `field` at its resolution (at most [`MAX_RES`]): boxes
    /// of `span` cells per edge (odd, ≥ 1), threshold opacity `alpha`.
    pub fn new(field: &dyn RadianceField, span: u32, alpha: f32) -> Self {
        let bounds = field.bounds();
        let res = field.resolution().clamp(1, MAX_RES);
        let n = res as usize;
        let cell = (bounds.max - bounds.min) / res as f32;
        let mut d: Vec<f32> = (0..n * n * n)
            .into_par_iter()
            .map(|i| {
                let (x, y, z) = (i % n, i / n % n, i / (n * n));
                let p = bounds.min + cell * (Vec3::new(x as f32, y as f32, z as f32) + 0.5);
                field.density(p)
            })
            .collect();
        // Separable box sum of `span` cells along x, then y, then z.
        let r = (span.max(1) / 2) as usize;
        for axis in 0..3 {
            let stride = [1, n, n * n][axis];
            d = (0..n * n * n)
                .into_par_iter()
                .map(|i| {
                    let c = i / stride % n;
                    let lo = c.saturating_sub(r);
                    let hi = (c + r).min(n - 1);
                    let base = i - c * stride;
                    (lo..=hi).map(|k| d[base + k * stride]).sum::<f32>()
                })
                .collect();
        }
        let side = (2 * r + 1) as f32;
        let edge = side * cell.max_element();
        let tau = -(1.0 - alpha.clamp(1e-4, 1.0 - 1e-4)).ln();
        let volume = side * side * side;
        let solid = d.par_iter().map(|&s| s / volume * edge >= tau).collect();
        Self { bounds, res, solid }
    }

    /// Whether the box around `p`'s cell is more than haze (points outside
    /// the bounds are not).
    #[inline]
    pub fn solid(&self, p: Vec3) -> bool {
        let u = (p - self.bounds.min) / (self.bounds.max - self.bounds.min) * self.res as f32;
        if !(u.cmpge(Vec3::ZERO).all() && u.cmplt(Vec3::splat(self.res as f32)).all()) {
            return false;
        }
        let n = self.res as usize;
        self.solid[(u.z as usize * n + u.y as usize) * n + u.x as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slab of density `solid` for |x| < 0.3 and a haze of `haze`
    /// everywhere else inside |·| < 0.9.
    struct Slab {
        solid: f32,
        haze: f32,
    }

    impl RadianceField for Slab {
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
            if p.abs().max_element() >= 0.9 {
                0.0
            } else if p.x.abs() < 0.3 {
                self.solid
            } else {
                self.haze
            }
        }
        fn color(&self, _: Vec3, _: Vec3) -> Vec3 {
            Vec3::ONE
        }
    }

    #[test]
    fn keeps_the_solid_and_drops_the_haze() {
        // Cell 1/32; a 3-cell box is 0.094 long: haze 1/unit gives an
        // optical depth of 0.09 (opacity 0.09), the solid 100/unit 9.4.
        let m = HazeMask::new(
            &Slab {
                solid: 100.0,
                haze: 1.0,
            },
            3,
            0.5,
        );
        assert!(m.solid(Vec3::new(0.0, 0.2, -0.1)));
        assert!(!m.solid(Vec3::new(0.6, 0.2, -0.1)));
        assert!(!m.solid(Vec3::splat(5.0)));
        // Denser haze (30/unit: opacity 0.94 over the box) is solid.
        let m = HazeMask::new(
            &Slab {
                solid: 100.0,
                haze: 30.0,
            },
            3,
            0.5,
        );
        assert!(m.solid(Vec3::new(0.6, 0.2, -0.1)));
    }
}
