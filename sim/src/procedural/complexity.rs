//! Geometric complexity as the NeRFlex paper measures it: the number of quad
//! faces a grid-aligned mesh of the object has at a fixed grid. The object's
//! bounds are enclosed in a cube of g³ cells; a cell is occupied when the
//! signed distance at its centre is negative; every face between an occupied
//! cell and an empty one (or the outside) is one quad — exactly the quads a
//! MobileNeRF-style baker would emit at that grid.

use super::objects::{Aabb, ObjectKind};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::OnceLock;

/// The grid of the complexity figure (cells per axis over the object's bounds).
pub const COMPLEXITY_GRID: u32 = 64;

/// An object's occupancy at one grid.
#[derive(Debug, Clone)]
pub struct Occupancy {
    /// The object.
    pub kind: ObjectKind,
    /// Cells per axis.
    pub grid: u32,
    /// Edge length of one cell, local units.
    pub voxel: f32,
    /// Boundary quads (the complexity figure).
    pub quads: u64,
    /// Occupied cells.
    pub occupied: u64,
    /// Centres of occupied cells that touch an empty one (local units).
    pub surface: Vec<Vec3>,
    /// Bounds of the occupied cells, grown by one cell (local units).
    pub tight: Aabb,
    /// Minimum corner of the grid cube (local units).
    pub origin: Vec3,
    /// Signed distance at every cell centre, x fastest, then y, then z.
    pub distances: Vec<f32>,
}

impl Occupancy {
    /// A lower bound of the object's distance function at `p` from the
    /// cached cell-centre value: the value at the centre of `p`'s cell minus
    /// the most the function can change over half a cell diagonal (its slope
    /// is at most `1 / march_step`). `None` outside the grid.
    #[inline]
    pub fn distance_bound(&self, p: Vec3) -> Option<f32> {
        let g = self.grid as usize;
        let q = (p - self.origin) / self.voxel;
        if q.min_element() < 0.0 || q.max_element() >= g as f32 {
            return None;
        }
        let (i, j, k) = (q.x as usize, q.y as usize, q.z as usize);
        let d = *self.distances.get(i + g * (j + g * k))?;
        Some(d - self.voxel * 0.866_026 / self.kind.march_step())
    }
}

/// Computes the occupancy of `kind` at `grid` cells per axis.
pub fn occupancy(kind: ObjectKind, grid: u32) -> Occupancy {
    let g = grid.max(1) as usize;
    let b = kind.bounds();
    let side = b.size().max_element();
    let voxel = side / g as f32;
    let origin = b.center() - Vec3::splat(0.5 * side);
    let centre = |i: usize, j: usize, k: usize| {
        origin + voxel * Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5)
    };
    let distances: Vec<f32> = (0..g * g * g)
        .into_par_iter()
        .map(|idx| kind.sdf(centre(idx % g, (idx / g) % g, idx / (g * g))))
        .collect();
    // Cells outside the object's own bounds are empty by construction.
    let occ: Vec<bool> = (0..g * g * g)
        .map(|idx| {
            let (i, j, k) = (idx % g, (idx / g) % g, idx / (g * g));
            distances[idx] < 0.0 && b.contains(centre(i, j, k))
        })
        .collect();
    let at = |i: isize, j: isize, k: isize| -> bool {
        if i < 0 || j < 0 || k < 0 || i >= g as isize || j >= g as isize || k >= g as isize {
            false
        } else {
            occ[i as usize + g * (j as usize + g * k as usize)]
        }
    };
    let per_slice: Vec<(u64, u64, Vec<Vec3>)> = (0..g)
        .into_par_iter()
        .map(|k| {
            let (mut quads, mut occupied, mut surface) = (0u64, 0u64, Vec::new());
            for j in 0..g {
                for i in 0..g {
                    let (ii, jj, kk) = (i as isize, j as isize, k as isize);
                    if !at(ii, jj, kk) {
                        continue;
                    }
                    occupied += 1;
                    let faces = [
                        (1, 0, 0),
                        (-1, 0, 0),
                        (0, 1, 0),
                        (0, -1, 0),
                        (0, 0, 1),
                        (0, 0, -1),
                    ]
                    .iter()
                    .filter(|(di, dj, dk)| !at(ii + di, jj + dj, kk + dk))
                    .count() as u64;
                    if faces > 0 {
                        surface.push(centre(i, j, k));
                    }
                    quads += faces;
                }
            }
            (quads, occupied, surface)
        })
        .collect();
    let mut out = Occupancy {
        kind,
        grid,
        voxel,
        quads: 0,
        occupied: 0,
        surface: Vec::new(),
        tight: Aabb::EMPTY,
        origin,
        distances,
    };
    for (q, o, s) in per_slice {
        out.quads += q;
        out.occupied += o;
        out.surface.extend(s);
    }
    for &c in &out.surface {
        out.tight = out.tight.with_point(c);
    }
    // Half a cell reaches the cell's face; one more covers surface detail
    // thinner than a cell that the centre samples missed.
    out.tight = if out.surface.is_empty() {
        b
    } else {
        out.tight.padded(1.5 * voxel)
    };
    out
}

/// The occupancy at [`COMPLEXITY_GRID`], computed once per process.
pub fn stats(kind: ObjectKind) -> &'static Occupancy {
    static CACHE: OnceLock<Vec<Occupancy>> = OnceLock::new();
    let all = CACHE.get_or_init(|| {
        ObjectKind::ALL
            .par_iter()
            .map(|&k| occupancy(k, COMPLEXITY_GRID))
            .collect()
    });
    // ALL lists every kind, so the search always finds it.
    let i = ObjectKind::ALL.iter().position(|&k| k == kind).unwrap_or(0);
    &all[i]
}

/// Quad faces at [`COMPLEXITY_GRID`]: the complexity figure.
pub fn complexity_quads(kind: ObjectKind) -> u64 {
    stats(kind).quads
}

/// Every object with its complexity, least complex first (ties by name).
pub fn ranked() -> Vec<(ObjectKind, u64)> {
    let mut v: Vec<(ObjectKind, u64)> = ObjectKind::ALL
        .iter()
        .map(|&k| (k, complexity_quads(k)))
        .collect();
    v.sort_by(|a, b| a.1.cmp(&b.1).then(a.0.name().cmp(b.0.name())));
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_count_the_boundary_faces() {
        // The box fills almost its whole bounding cube: about 6·(cells across)² faces.
        let o = occupancy(ObjectKind::Box, 16);
        assert!(
            o.quads > 0 && o.quads % 2 == 0,
            "a closed surface has paired faces: {}",
            o.quads
        );
        let across = (o.tight.size() / o.voxel).round();
        assert!(
            o.quads as f32
                <= 2.0 * (across.x * across.y + across.y * across.z + across.x * across.z)
        );
        // Finer grids find more faces.
        assert!(occupancy(ObjectKind::Gear, 32).quads > occupancy(ObjectKind::Gear, 16).quads);
    }

    #[test]
    fn cached_bounds_never_exceed_the_distance() {
        for kind in ObjectKind::ALL {
            let o = stats(kind);
            let b = kind.bounds();
            let mut n = 0;
            for i in 0..4000u32 {
                let h = |s: u32| {
                    ((i.wrapping_mul(2_654_435_761).wrapping_add(s * 97)) % 10_007) as f32
                        / 10_007.0
                };
                let p = b.min + b.size() * Vec3::new(h(1), h(2), h(3));
                if let Some(lb) = o.distance_bound(p) {
                    let d = kind.sdf(p);
                    assert!(
                        lb <= d + 1e-4,
                        "{kind}: bound {lb} above distance {d} at {p}"
                    );
                    n += 1;
                }
            }
            assert!(n > 3000);
        }
    }

    #[test]
    fn complexity_spans_simple_to_intricate() {
        let r = ranked();
        let pos = |k| r.iter().position(|(x, _)| *x == k).unwrap();
        assert!(pos(ObjectKind::Ball) < pos(ObjectKind::Gear));
        assert!(pos(ObjectKind::Vase) < pos(ObjectKind::Lattice));
        assert!(pos(ObjectKind::Box) < pos(ObjectKind::Sponge));
        assert!(r.last().unwrap().1 > 3 * r[0].1, "{r:?}");
    }
}
