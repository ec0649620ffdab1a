//! Geometry from a radiance field: grid-aligned quads where the field's
//! opacity says surface, and binary texel opacity at p×p per quad.
//!
//! A point is *inside* when the field's opacity over a step of half a field
//! cell reaches `surface_alpha` (default 0.05: a trained field's surface
//! spreads over a few cells, so each half cell is only partly opaque). Voxels of the
//! g³ grid are classified at the 27 points of a half-voxel lattice, as the
//! hull baker does: all inside → full, none → empty, else *shell* (the
//! surface crosses it). Every face of every shell voxel is a quad (the
//! shell geometry of `bake::quads::shell_quads`); a texel is opaque iff its
//! point is inside. A ray through the shell then stops at the first opaque
//! texel, which is within a voxel of the field's surface and exact to a
//! texel across the view (MobileNeRF's binarised alpha on its quads).

use glam::Vec3;
use rayon::prelude::*;

use super::super::carve::{ShellGrid, VoxelClass};
use super::super::quads::{shell_quads, Quad};
use super::super::Aabb;
use crate::train::field::RadianceField;

/// Cells per edge of the coarse pass that finds the object's cube.
pub const COARSE: u32 = 96;

/// The inside test of a field.
#[derive(Clone, Copy)]
pub struct Surface<'a> {
    /// The field.
    pub field: &'a dyn RadianceField,
    /// Density σ (per world unit) at and above which a point is inside.
    pub sigma: f32,
}

impl<'a> Surface<'a> {
    /// The surface where opacity over half a field cell reaches `alpha`.
    pub fn new(field: &'a dyn RadianceField, alpha: f32) -> Self {
        let b = field.bounds();
        let edge = (b.max - b.min).max_element();
        let step = 0.5 * edge / field.resolution().max(1) as f32;
        let alpha = alpha.clamp(1e-4, 1.0 - 1e-4);
        Self {
            field,
            sigma: -(1.0 - alpha).ln() / step,
        }
    }

    /// Whether world point `p` is inside.
    #[inline]
    pub fn inside(&self, p: Vec3) -> bool {
        self.field.density(p) >= self.sigma
    }
}

/// The bounding cube of the inside points of a [`COARSE`]³ lattice over
/// the field's bounds, grown by one coarse cell (clamped to the bounds)
/// and made a cube: g then counts voxels across the object.
pub fn object_cube(s: &Surface<'_>) -> Option<Aabb> {
    let b = s.field.bounds();
    let n = COARSE;
    let cell = (b.max - b.min) / n as f32;
    let boxes: Vec<Option<(Vec3, Vec3)>> = (0..n)
        .into_par_iter()
        .map(|k| {
            let mut acc: Option<(Vec3, Vec3)> = None;
            for j in 0..n {
                for i in 0..n {
                    let p = b.min + cell * (Vec3::new(i as f32, j as f32, k as f32) + 0.5);
                    if s.inside(p) {
                        acc = Some(match acc {
                            Some((lo, hi)) => (lo.min(p), hi.max(p)),
                            None => (p, p),
                        });
                    }
                }
            }
            acc
        })
        .collect();
    let (lo, hi) = boxes
        .into_iter()
        .flatten()
        .reduce(|a, c| (a.0.min(c.0), a.1.max(c.1)))?;
    let grown = Aabb {
        min: (lo - cell).max(b.min),
        max: (hi + cell).min(b.max),
    };
    Some(grown.cube())
}

/// Classifies the `g`³ voxels of `cube` at the 27 points of each (a
/// lattice of half-voxel spacing, each point tested once).
pub fn classify(s: &Surface<'_>, cube: &Aabb, g: u32) -> ShellGrid {
    let voxel = (cube.max - cube.min).max_element() / g as f32;
    let origin = cube.min;
    let n = 2 * g as usize + 1; // lattice points per edge
    let half = 0.5 * voxel;
    // One plane of the lattice at a time (two planes per voxel layer plus
    // the shared one), in parallel within the plane.
    let plane = |kz: usize| -> Vec<bool> {
        (0..n * n)
            .into_par_iter()
            .map(|ij| {
                let (i, j) = (ij % n, ij / n);
                s.inside(origin + half * Vec3::new(i as f32, j as f32, kz as f32))
            })
            .collect()
    };
    let g_us = g as usize;
    let mut class = vec![VoxelClass::Empty; g_us * g_us * g_us];
    let mut below = plane(0);
    for k in 0..g_us {
        let mid = plane(2 * k + 1);
        let above = plane(2 * k + 2);
        let layer = &mut class[k * g_us * g_us..(k + 1) * g_us * g_us];
        layer.par_iter_mut().enumerate().for_each(|(ij, c)| {
            let (i, j) = (ij % g_us, ij / g_us);
            let mut any_in = false;
            let mut any_out = false;
            for pl in [&below, &mid, &above] {
                for dj in 0..3 {
                    for di in 0..3 {
                        let inside = pl[(2 * j + dj) * n + 2 * i + di];
                        any_in |= inside;
                        any_out |= !inside;
                    }
                }
            }
            *c = match (any_in, any_out) {
                (true, true) => VoxelClass::Shell,
                (true, false) => VoxelClass::Full,
                _ => VoxelClass::Empty,
            };
        });
        below = above;
    }
    // `class` has g³ entries by construction.
    ShellGrid::from_classes(g, origin, voxel, class).unwrap_or_else(|| unreachable!())
}

/// Texel (x, y) of a p×p patch is the quad point (x/(p−1), y/(p−1)).
#[inline]
pub fn texel_point(q: &Quad, p: u32, x: u32, y: u32) -> Vec3 {
    let last = (p - 1) as f32;
    q.point(x as f32 / last, y as f32 / last)
}

/// Binary opacity of every texel of every quad (p² per quad, row-major).
pub fn texel_opacity(s: &Surface<'_>, quads: &[Quad], p: u32) -> Vec<bool> {
    let p2 = (p * p) as usize;
    let mut out = vec![false; quads.len() * p2];
    out.par_chunks_mut(p2).zip(quads).for_each(|(occ, q)| {
        for (t, o) in occ.iter_mut().enumerate() {
            *o = s.inside(texel_point(q, p, t as u32 % p, t as u32 / p));
        }
    });
    out
}

/// The extracted geometry.
#[derive(Debug, Clone)]
pub struct Geometry {
    /// The cube the grid spans.
    pub cube: Aabb,
    /// Voxel edge, world units.
    pub voxel: f32,
    /// Shell voxels (the surface crosses them) and full voxels.
    pub shell_voxels: u64,
    /// Full voxels.
    pub full_voxels: u64,
    /// Quads with at least one opaque texel, in voxel scan order.
    pub quads: Vec<Quad>,
    /// p² opacities per quad.
    pub opacity: Vec<bool>,
}

/// Quads and texel opacity of the field at (g, p); `None` when no point
/// of the field is inside.
pub fn extract(s: &Surface<'_>, g: u32, p: u32) -> Option<Geometry> {
    let cube = object_cube(s)?;
    let grid = classify(s, &cube, g);
    let all = shell_quads(&grid);
    let opacity = texel_opacity(s, &all, p);
    let p2 = (p * p) as usize;
    let mut quads = Vec::with_capacity(all.len());
    let mut kept = Vec::with_capacity(opacity.len());
    for (q, occ) in all.iter().zip(opacity.chunks(p2)) {
        if occ.iter().any(|&o| o) {
            quads.push(*q);
            kept.extend_from_slice(occ);
        }
    }
    Some(Geometry {
        cube,
        voxel: grid.voxel,
        shell_voxels: grid.count(VoxelClass::Shell),
        full_voxels: grid.count(VoxelClass::Full),
        quads,
        opacity: kept,
    })
}

#[cfg(test)]
mod tests {
    use super::super::analytic::Sphere;
    use super::*;

    #[test]
    fn a_sphere_gives_a_closed_shell_whose_texels_follow_it() {
        let f = Sphere::new(Vec3::new(0.1, -0.05, 0.0), 0.6);
        let s = Surface::new(&f, 0.5);
        let g = extract(&s, 16, 5).expect("a sphere has an inside");
        // The cube hugs the sphere (within a coarse cell or two).
        let edge = (g.cube.max - g.cube.min).max_element();
        assert!(
            edge > 1.2 && edge < 1.2 + 4.0 * 3.0 / COARSE as f32,
            "cube edge {edge}"
        );
        assert!(g.shell_voxels > 0 && g.full_voxels > 0);
        // Every opaque texel is inside, and within a voxel of the surface.
        for (q, occ) in g.quads.iter().zip(g.opacity.chunks(25)) {
            for (t, &o) in occ.iter().enumerate() {
                let x = texel_point(q, 5, t as u32 % 5, t as u32 / 5);
                let r = (x - f.centre).length();
                if o {
                    // The field's surface: half its 0.01 density ramp out.
                    assert!(r <= 0.6 + 0.005, "opaque texel outside: r = {r}");
                    assert!(
                        r >= 0.6 - 2.0 * g.voxel,
                        "opaque texel deep inside: r = {r}"
                    );
                }
            }
        }
    }

    #[test]
    fn an_empty_field_has_no_geometry() {
        let f = Sphere::new(Vec3::ZERO, 0.0);
        assert!(extract(&Surface::new(&f, 0.5), 8, 3).is_none());
    }
}
