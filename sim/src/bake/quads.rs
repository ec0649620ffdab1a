//! Boundary faces of the carved grid as axis-aligned quads.
//!
//! Every face between an occupied voxel and an empty one (or the grid's
//! outside) becomes one quad, facing the empty side, like MobileNeRF's
//! grid-aligned quads. Faces between two occupied voxels are never seen and
//! are not emitted.

use glam::Vec3;

use super::carve::{Grid, ShellGrid, VoxelClass};

/// One quad: a face of a voxel, a tilted plane, or (with a `twist`) a
/// quad of MobileNeRF's mesh whose four corners need not be coplanar.
///
/// Corner order follows the MobileNeRF export: corners 0, 1, 2, 3 are the
/// patch texels (0, 0), (0, p−1), (p−1, 0), (p−1, p−1) (x along the atlas
/// row, y down the atlas), and the triangles (0, 1, 3), (0, 3, 2) are
/// counter-clockwise seen from the outside. The renderer maps each
/// triangle's texels affinely, so quad point (s, t) is
/// `origin + s·u + t·v + min(s, t)·twist` (see [`Quad::point`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quad {
    /// Corner at texel (0, 0), world units.
    pub origin: Vec3,
    /// Edge from texel (0, 0) to texel (p−1, 0) (along the atlas x axis).
    pub u: Vec3,
    /// Edge from texel (0, 0) to texel (0, p−1) (along the atlas y axis).
    pub v: Vec3,
    /// Outward unit normal (an axis direction); `u × v = −normal`.
    pub normal: Vec3,
    /// The occupied voxel the face belongs to.
    pub voxel: [u32; 3],
    /// Corner 3 minus the parallelogram's fourth corner (`origin + u +
    /// v`): zero for planar parallelograms, the bend of a mesh quad.
    pub twist: Vec3,
}

#[cfg(test)]
impl Quad {
    /// A square of edge `e` centred at `c` in the plane y = c.y, facing −y
    /// (the trained baker's tests stack these in front of a camera on −y).
    pub(crate) fn facing_minus_y(c: Vec3, e: f32) -> Self {
        Quad {
            origin: c - Vec3::new(0.5 * e, 0.0, 0.5 * e),
            u: Vec3::new(e, 0.0, 0.0),
            v: Vec3::new(0.0, 0.0, e),
            normal: -Vec3::Y,
            voxel: [0; 3],
            twist: Vec3::ZERO,
        }
    }
}

impl Quad {
    /// The four corners in export order (see the type's docs).
    pub fn corners(&self) -> [Vec3; 4] {
        [
            self.origin,
            self.origin + self.v,
            self.origin + self.u,
            self.origin + self.u + self.v + self.twist,
        ]
    }

    /// The world point of quad coordinates (s, t) ∈ [0, 1]² (s along `u`)
    /// as the renderer maps it: affine on each triangle, triangle (0, 1,
    /// 3) where t ≥ s and (0, 3, 2) where s ≥ t, so the twist enters as
    /// `min(s, t)` (both forms agree on the diagonal s = t).
    #[inline]
    pub fn point(&self, s: f32, t: f32) -> Vec3 {
        self.origin + s * self.u + t * self.v + s.min(t) * self.twist
    }
}

/// The six face directions: (axis, sign).
const FACES: [(usize, i64); 6] = [(0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1)];

/// All boundary quads of `grid`, in voxel scan order (z, then y, then x,
/// then the six directions), so neighbouring quads sit in neighbouring
/// atlas cells.
pub fn boundary_quads(grid: &Grid) -> Vec<Quad> {
    let g = grid.g;
    let h = grid.voxel;
    let mut out = Vec::new();
    for k in 0..g {
        for j in 0..g {
            for i in 0..g {
                let (ii, jj, kk) = (i as i64, j as i64, k as i64);
                if !grid.occupied(ii, jj, kk) {
                    continue;
                }
                let lo = grid.corner(i, j, k);
                for &(axis, sign) in &FACES {
                    let mut n = [ii, jj, kk];
                    n[axis] += sign;
                    if grid.occupied(n[0], n[1], n[2]) {
                        continue;
                    }
                    out.push(face(lo, h, axis, sign, [i, j, k]));
                }
            }
        }
    }
    out
}

/// The quad of one face of the voxel with lower corner `lo` and edge `h`.
fn face(lo: Vec3, h: f32, axis: usize, sign: i64, voxel: [u32; 3]) -> Quad {
    let (x, y, z) = (Vec3::X * h, Vec3::Y * h, Vec3::Z * h);
    // (offset of the origin, u, v) chosen so that u × v = −normal, which
    // makes the export's triangles counter-clockwise from outside.
    let (off, u, v) = match (axis, sign > 0) {
        (0, true) => (x, z, y),
        (0, false) => (Vec3::ZERO, y, z),
        (1, true) => (y, x, z),
        (1, false) => (Vec3::ZERO, z, x),
        (2, true) => (z, y, x),
        _ => (Vec3::ZERO, x, y),
    };
    let mut normal = Vec3::ZERO;
    normal[axis] = if sign > 0 { 1.0 } else { -1.0 };
    Quad {
        origin: lo + off,
        u,
        v,
        normal,
        voxel,
        twist: Vec3::ZERO,
    }
}

/// All faces of the shell voxels of `grid` (each face once), for the
/// [`super::Geometry::Shell`] geometry: texel alpha then carves the hull's
/// shape out of these layers of quads. A face between a shell voxel and a
/// full one faces the shell voxel; a face between two shell voxels faces
/// +axis (the texel pass weighs views on both sides of a quad alike).
pub fn shell_quads(grid: &ShellGrid) -> Vec<Quad> {
    let g = grid.g;
    let h = grid.voxel;
    let mut out = Vec::new();
    for k in 0..g {
        for j in 0..g {
            for i in 0..g {
                let (ii, jj, kk) = (i as i64, j as i64, k as i64);
                if grid.class(ii, jj, kk) != VoxelClass::Shell {
                    continue;
                }
                let lo = grid.corner(i, j, k);
                for &(axis, sign) in &FACES {
                    let mut n = [ii, jj, kk];
                    n[axis] += sign;
                    let other = grid.class(n[0], n[1], n[2]);
                    // A face between two shell voxels is emitted once, by
                    // the lower one; faces toward full voxels are emitted
                    // facing away from them.
                    if other == VoxelClass::Shell && sign < 0 {
                        continue;
                    }
                    if other == VoxelClass::Full {
                        // The same face seen as the full voxel's, facing out of it.
                        let mut d = Vec3::ZERO;
                        d[axis] = sign as f32 * h;
                        out.push(face(lo + d, h, axis, -sign, [i, j, k]));
                    } else {
                        out.push(face(lo, h, axis, sign, [i, j, k]));
                    }
                }
            }
        }
    }
    out
}
