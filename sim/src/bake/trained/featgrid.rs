//! A sparse lattice of texel features, trilinearly interpolated: the
//! continuous appearance the fine-tune learns and the atlas samples.
//!
//! MobileNeRF's texels come from a continuous feature field (an MLP of
//! position) evaluated at each texel's point, so a texel no training pixel
//! shows still gets features consistent with its neighbours. Fine-tuning
//! one free feature vector per texel instead leaves most texels untrained
//! (at g = 128, p = 17 a texel is ~0.2 px at 800 px: 68 % of lego's opaque
//! texels are never shown) and each trained one sees ~3 pixels, so three
//! Adam steps an epoch. Here the features live on the vertices of a
//! lattice over the object's cube (only around texel points: 8³-vertex
//! bricks allocated on demand), a texel's features are the trilinear
//! interpolation at its point, every pixel's gradient reaches 8 vertices,
//! and the export samples every opaque texel the same way.

use crate::rounding::floor3;
use glam::Vec3;
use rayon::prelude::*;

use super::super::Aabb;
use super::net::FEATURES;

/// Vertices per brick edge.
const BRICK: u32 = 8;
const BRICK3: usize = (BRICK * BRICK * BRICK) as usize;
/// "No slot".
const NONE: u32 = u32::MAX;

/// Eight lattice vertices (slots into [`FeatureGrid::values`]) and their
/// trilinear weights: how one point reads the grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Taps {
    /// Vertex slots.
    pub slot: [u32; 8],
    /// Weights (sum 1).
    pub w: [f32; 8],
}

impl Taps {
    /// The interpolated features.
    #[inline]
    pub fn gather(&self, values: &[[f32; FEATURES]]) -> [f32; FEATURES] {
        let mut f = [0f32; FEATURES];
        for (&s, &w) in self.slot.iter().zip(&self.w) {
            let v = &values[s as usize];
            for c in 0..FEATURES {
                f[c] += w * v[c];
            }
        }
        f
    }

    /// Adds `df` (a gradient w.r.t. the interpolated features) to the
    /// vertices' gradients.
    #[inline]
    pub fn scatter(&self, df: &[f32; FEATURES], grad: &mut [[f32; FEATURES]]) {
        for (&s, &w) in self.slot.iter().zip(&self.w) {
            let g = &mut grad[s as usize];
            for c in 0..FEATURES {
                g[c] += w * df[c];
            }
        }
    }
}

/// The sparse feature lattice.
#[derive(Debug, Clone)]
pub struct FeatureGrid {
    origin: Vec3,
    /// World units per cell.
    cell: f32,
    /// Cells per edge.
    res: u32,
    /// Bricks per edge.
    bricks: u32,
    /// Per brick: its first slot-table entry / [`BRICK3`], or [`NONE`].
    brick_of: Vec<u32>,
    /// Per allocated brick, [`BRICK3`] vertex slots ([`NONE`]: unused).
    slots: Vec<u32>,
    /// Lattice coordinates of each vertex slot.
    coords: Vec<[u32; 3]>,
    /// Features per vertex slot.
    pub values: Vec<[f32; FEATURES]>,
}

impl FeatureGrid {
    /// A lattice of `res` cells per edge over `cube`, with vertices at the
    /// corners of every cell that holds one of `points` (values zero).
    pub fn new(cube: &Aabb, res: u32, points: &[Vec3]) -> Self {
        let res = res.max(1);
        let edge = (cube.max - cube.min).max_element().max(f32::MIN_POSITIVE);
        let bricks = (res + 1).div_ceil(BRICK);
        let mut g = Self {
            origin: cube.min,
            cell: edge / res as f32,
            res,
            bricks,
            brick_of: vec![NONE; (bricks as usize).pow(3)],
            slots: Vec::new(),
            coords: Vec::new(),
            values: Vec::new(),
        };
        let mut cells: Vec<u64> = points
            .par_iter()
            .map(|&x| {
                let (i, _) = g.locate(x);
                pack(i)
            })
            .collect();
        cells.par_sort_unstable();
        cells.dedup();
        for &c in &cells {
            let i = unpack(c);
            for k in 0..8u32 {
                let v = [i[0] + (k & 1), i[1] + (k >> 1 & 1), i[2] + (k >> 2)];
                g.insert(v);
            }
        }
        g.values = vec![[0.0; FEATURES]; g.coords.len()];
        g
    }

    /// Vertex slots.
    pub fn len(&self) -> usize {
        self.coords.len()
    }

    /// Cells per edge.
    pub fn res(&self) -> u32 {
        self.res
    }

    /// Whether the grid has no vertex.
    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    /// World point of vertex slot `s`.
    pub fn vertex_point(&self, s: usize) -> Vec3 {
        let [i, j, k] = self.coords[s];
        self.origin + self.cell * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// The cell holding `x` (clamped into the lattice) and the fractional
    /// position inside it.
    #[inline]
    fn locate(&self, x: Vec3) -> ([u32; 3], Vec3) {
        let u = ((x - self.origin) / self.cell).clamp(Vec3::ZERO, Vec3::splat(self.res as f32));
        let i = floor3(u).min(Vec3::splat((self.res - 1) as f32));
        ([i.x as u32, i.y as u32, i.z as u32], u - i)
    }

    fn brick_index(&self, v: [u32; 3]) -> (usize, usize) {
        let b = [v[0] / BRICK, v[1] / BRICK, v[2] / BRICK];
        let l = [v[0] % BRICK, v[1] % BRICK, v[2] % BRICK];
        let n = self.bricks as usize;
        (
            (b[2] as usize * n + b[1] as usize) * n + b[0] as usize,
            ((l[2] * BRICK + l[1]) * BRICK + l[0]) as usize,
        )
    }

    fn insert(&mut self, v: [u32; 3]) {
        let (b, l) = self.brick_index(v);
        if self.brick_of[b] == NONE {
            self.brick_of[b] = (self.slots.len() / BRICK3) as u32;
            self.slots.resize(self.slots.len() + BRICK3, NONE);
        }
        let e = self.brick_of[b] as usize * BRICK3 + l;
        if self.slots[e] == NONE {
            self.slots[e] = self.coords.len() as u32;
            self.coords.push(v);
        }
    }

    fn slot(&self, v: [u32; 3]) -> Option<u32> {
        let (b, l) = self.brick_index(v);
        let brick = *self.brick_of.get(b)?;
        if brick == NONE {
            return None;
        }
        let s = self.slots[brick as usize * BRICK3 + l];
        (s != NONE).then_some(s)
    }

    /// How `x` reads the grid; `None` when its cell held none of the
    /// construction's points.
    #[inline]
    pub fn taps(&self, x: Vec3) -> Option<Taps> {
        let (i, f) = self.locate(x);
        let mut t = Taps {
            slot: [0; 8],
            w: [0.0; 8],
        };
        for k in 0..8u32 {
            let (bx, by, bz) = (k & 1, k >> 1 & 1, k >> 2);
            t.slot[k as usize] = self.slot([i[0] + bx, i[1] + by, i[2] + bz])?;
            let wx = if bx == 1 { f.x } else { 1.0 - f.x };
            let wy = if by == 1 { f.y } else { 1.0 - f.y };
            let wz = if bz == 1 { f.z } else { 1.0 - f.z };
            t.w[k as usize] = wx * wy * wz;
        }
        Some(t)
    }
}

#[inline]
fn pack(i: [u32; 3]) -> u64 {
    (u64::from(i[2]) << 42) | (u64::from(i[1]) << 21) | u64::from(i[0])
}

#[inline]
fn unpack(c: u64) -> [u32; 3] {
    let m = (1u64 << 21) - 1;
    [(c & m) as u32, (c >> 21 & m) as u32, (c >> 42) as u32]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Aabb {
        Aabb {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        }
    }

    #[test]
    fn interpolates_a_linear_function_exactly() {
        let pts: Vec<Vec3> = (0..200)
            .map(|i| {
                let t = i as f32 / 200.0;
                Vec3::new(t * 1.8 - 0.9, (t * 7.0).sin() * 0.8, (t * 3.0).cos() * 0.8)
            })
            .collect();
        let mut g = FeatureGrid::new(&cube(), 37, &pts);
        assert!(!g.is_empty());
        let lin = |x: Vec3| 0.3 * x.x - 0.2 * x.y + 0.1 * x.z + 0.5;
        for s in 0..g.len() {
            let x = g.vertex_point(s);
            g.values[s] = [lin(x); FEATURES];
        }
        for &x in &pts {
            let t = g.taps(x).expect("a construction point reads the grid");
            assert!((t.w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            let f = t.gather(&g.values);
            assert!((f[0] - lin(x)).abs() < 1e-5, "{} vs {}", f[0], lin(x));
        }
    }

    #[test]
    fn points_outside_the_construction_read_nothing_and_the_edges_clamp() {
        let g = FeatureGrid::new(&cube(), 16, &[Vec3::splat(0.01)]);
        assert_eq!(g.len(), 8);
        assert!(g.taps(Vec3::splat(-0.9)).is_none());
        // The cube's far corner and beyond clamp into the last cell.
        let h = FeatureGrid::new(&cube(), 16, &[Vec3::splat(1.0)]);
        assert!(h.taps(Vec3::splat(5.0)).is_some());
        // NaN clamps to the lattice's origin: no panic.
        let _ = h.taps(Vec3::splat(f32::NAN));
    }

    #[test]
    fn scatter_is_the_adjoint_of_gather() {
        let pts = [Vec3::new(0.13, -0.42, 0.77), Vec3::new(0.14, -0.40, 0.75)];
        let mut g = FeatureGrid::new(&cube(), 23, &pts);
        for (s, v) in g.values.iter_mut().enumerate() {
            *v = std::array::from_fn(|c| ((s * 7 + c * 3) % 11) as f32 / 11.0);
        }
        let t = g.taps(pts[0]).unwrap();
        let df: [f32; FEATURES] = std::array::from_fn(|c| c as f32 - 3.5);
        let mut grad = vec![[0f32; FEATURES]; g.len()];
        t.scatter(&df, &mut grad);
        // <df, gather(V)> == <scatter(df), V>
        let f = t.gather(&g.values);
        let lhs: f32 = (0..FEATURES).map(|c| df[c] * f[c]).sum();
        let rhs: f32 = grad
            .iter()
            .zip(&g.values)
            .map(|(a, b)| (0..FEATURES).map(|c| a[c] * b[c]).sum::<f32>())
            .sum();
        assert!((lhs - rhs).abs() < 1e-4, "{lhs} vs {rhs}");
    }
}
