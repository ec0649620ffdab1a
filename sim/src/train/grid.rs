//! The trained field: a sparse voxel grid of density and spherical-harmonic
//! colour, trilinearly interpolated (Plenoxels' representation).
//!
//! Values live on the vertices of an `R`³-cell lattice over a cube. Only the
//! vertices near the object are stored: `index` maps every lattice vertex to
//! a slot of `values` (`EMPTY` where nothing is stored, read as all zeros).
//! A slot holds one record — raw density, then the `K` SH coefficients of
//! red, green and blue, padded with zeros to 4, 16 or 32 floats (degree 0,
//! 1, 2) — so a degree-1 record is one 64-byte cache line and the eight
//! corner gathers of a sample touch eight lines.

use glam::Vec3;

use super::adam::prefetch;
use super::field::{InsideThreshold, RadianceField};
use super::sh;
use crate::bake::Aabb;

/// Longest record (SH degree 2, padded).
pub const MAX_RECORD: usize = 32;

/// Index value of a vertex that stores nothing.
pub const EMPTY: u32 = u32::MAX;

/// Raw density below which a sample is skipped (σ is then negligible).
const DENSITY_FLOOR: f32 = 0.0;

/// Shift of the density activation: `σ·edge/256 = softplus(raw − SHIFT)`,
/// so a fresh vertex at raw 0 is nearly transparent (DVGO's trick, which
/// keeps gradients alive where ReLU would kill them).
pub const DENSITY_SHIFT: f32 = 4.0;

/// The sparse grid.
#[derive(Debug, Clone, PartialEq)]
pub struct SparseGrid {
    /// Cells per edge (`R`); the lattice has `R + 1` vertices per edge.
    pub res: u32,
    /// The cube the grid spans (world units).
    pub cube: Aabb,
    /// SH degree (0, 1 or 2): `K = (degree + 1)²` coefficients per channel.
    pub sh_degree: u32,
    /// Vertex → slot, `(R + 1)³` entries, x fastest.
    pub index: Vec<u32>,
    /// Slot → vertex (linear lattice index), the inverse of `index`.
    pub vertex: Vec<u32>,
    /// Records, `slots × record_len()` floats.
    pub values: Vec<f32>,
    /// One bit per cell (`R`³): whether any of its corners is stored.
    pub cell_bits: Vec<u64>,
}

/// The eight corners of a sample: slots (or `EMPTY`) and trilinear weights.
#[derive(Debug, Clone, Copy, Default)]
pub struct Corners {
    /// Slot of each corner, `EMPTY` for a vertex without storage.
    pub slot: [u32; 8],
    /// Trilinear weight of each corner (they sum to 1).
    pub weight: [f32; 8],
}

impl SparseGrid {
    /// A grid over `cube` with `res` cells per edge storing the vertices
    /// for which `keep(i, j, k)` holds, all records zero.
    pub fn new(res: u32, cube: Aabb, sh_degree: u32, keep: impl Fn(u32, u32, u32) -> bool) -> Self {
        let n = res + 1;
        let mut index = vec![EMPTY; (n as usize).pow(3)];
        let mut vertex = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    if keep(i, j, k) {
                        let v = ((k * n + j) * n + i) as usize;
                        index[v] = vertex.len() as u32;
                        vertex.push(v as u32);
                    }
                }
            }
        }
        let len = record_len(sh_degree);
        let mut grid = SparseGrid {
            res,
            cube,
            sh_degree,
            index,
            values: vec![0.0; vertex.len() * len],
            vertex,
            cell_bits: Vec::new(),
        };
        grid.rebuild_cells();
        grid
    }

    /// Floats per (padded) record.
    #[inline]
    pub fn record_len(&self) -> usize {
        record_len(self.sh_degree)
    }

    /// SH coefficients per channel.
    #[inline]
    pub fn sh_count(&self) -> usize {
        sh::count(self.sh_degree)
    }

    /// Number of stored vertices.
    pub fn slots(&self) -> usize {
        self.vertex.len()
    }

    /// Edge length of a cell, world units.
    #[inline]
    pub fn voxel(&self) -> f32 {
        (self.cube.max.x - self.cube.min.x) / self.res as f32
    }

    /// σ per world unit for activated raw density 1: `256 / edge`, so
    /// densities keep their meaning when the grid is refined.
    #[inline]
    pub fn density_scale(&self) -> f32 {
        256.0 / (self.cube.max.x - self.cube.min.x)
    }

    /// Lattice coordinates (i, j, k) of a linear vertex index.
    #[inline]
    pub fn vertex_ijk(&self, v: u32) -> (u32, u32, u32) {
        let n = self.res + 1;
        (v % n, (v / n) % n, v / (n * n))
    }

    /// Recomputes the per-cell occupancy bits from `index`.
    pub fn rebuild_cells(&mut self) {
        let r = self.res as usize;
        let n = r + 1;
        let mut bits = vec![0u64; (r * r * r).div_ceil(64)];
        for (&v, _) in self.vertex.iter().zip(0..) {
            let v = v as usize;
            let (i, j, k) = (v % n, (v / n) % n, v / (n * n));
            // The (up to) eight cells this vertex is a corner of.
            for dk in 0..2 {
                for dj in 0..2 {
                    for di in 0..2 {
                        let (ci, cj, ck) = (i + di, j + dj, k + dk);
                        if ci == 0 || cj == 0 || ck == 0 || ci > r || cj > r || ck > r {
                            continue;
                        }
                        let c = ((ck - 1) * r + (cj - 1)) * r + (ci - 1);
                        bits[c / 64] |= 1 << (c % 64);
                    }
                }
            }
        }
        self.cell_bits = bits;
    }

    /// Clears the occupancy bit of every cell whose eight corners are all
    /// so thin that the cell's opacity stays below `alpha` (the densest
    /// corner decides): the march then skips it without a gather. A pruned
    /// cell gets no gradient again, so this is for space the optimisation
    /// has already emptied (DVGO's mask cache, Plenoxels' pruning).
    /// Returns the cells cleared.
    pub fn prune_cells(&mut self, alpha: f32) -> usize {
        let r = self.res as usize;
        let n = r + 1;
        let len = self.record_len();
        let tau_cell = self.density_scale() * self.voxel();
        // raw below which a corner's opacity over one cell stays under alpha.
        let tau_max = -(1.0 - alpha.clamp(0.0, 0.999_999)).ln() / tau_cell;
        let (index, values) = (&self.index, &self.values);
        let raw = |v: usize| match index.get(v) {
            Some(&s) if s != EMPTY => values.get(s as usize * len).copied(),
            _ => None,
        };
        use rayon::prelude::*;
        let cleared: usize = self
            .cell_bits
            .par_iter_mut()
            .enumerate()
            .map(|(w, bits)| {
                let mut out = 0;
                let mut b = *bits;
                while b != 0 {
                    let bit = b.trailing_zeros() as usize;
                    b &= b - 1;
                    let c = w * 64 + bit;
                    let (i, j, k) = (c % r, (c / r) % r, c / (r * r));
                    let base = (k * n + j) * n + i;
                    let offs = [0, 1, n, n + 1, n * n, n * n + 1, n * n + n, n * n + n + 1];
                    let thin = offs
                        .iter()
                        .all(|o| raw(base + o).is_none_or(|x| activate_density(x).0 < tau_max));
                    if thin {
                        *bits &= !(1u64 << bit);
                        out += 1;
                    }
                }
                out
            })
            .sum();
        cleared
    }

    /// Cells whose occupancy bit is set.
    pub fn occupied_cells(&self) -> usize {
        self.cell_bits.iter().map(|b| b.count_ones() as usize).sum()
    }

    /// Grid coordinates of a world point (cells; the cube spans [0, R]).
    #[inline]
    pub fn to_grid(&self, p: Vec3) -> Vec3 {
        (p - self.cube.min) * (self.res as f32 / (self.cube.max.x - self.cube.min.x))
    }

    /// The cell (i, j, k) holding grid coordinates `u`, or `None` outside
    /// the grid (the far faces belong to the last cell).
    #[inline(always)]
    fn cell_of(&self, u: Vec3) -> Option<(u32, u32, u32)> {
        let r = self.res as f32;
        if !(u.x >= 0.0 && u.y >= 0.0 && u.z >= 0.0 && u.x <= r && u.y <= r && u.z <= r) {
            return None;
        }
        let rm = self.res - 1;
        Some((
            (u.x as u32).min(rm),
            (u.y as u32).min(rm),
            (u.z as u32).min(rm),
        ))
    }

    /// The corners of the sample at grid coordinates `u`, or `None` when
    /// `u` is outside the grid or its cell stores nothing.
    #[inline(always)]
    pub fn corners(&self, u: Vec3) -> Option<Corners> {
        let (i, j, k) = self.cell_of(u)?;
        let res = self.res as usize;
        let c = (k as usize * res + j as usize) * res + i as usize;
        if self
            .cell_bits
            .get(c / 64)
            .is_none_or(|b| b & (1 << (c % 64)) == 0)
        {
            return None;
        }
        Some(self.corners_in(u, i, j, k))
    }

    /// Asks for the lines a sample at `u` will read first: its cell's
    /// occupancy word and the four lattice-index rows of its corners. The
    /// march calls it a few samples ahead, so the misses of a 384³ grid
    /// (a 228 MB index, read at random) overlap the work between.
    #[inline(always)]
    pub fn prefetch_cell(&self, u: Vec3) {
        let Some((i, j, k)) = self.cell_of(u) else {
            return;
        };
        let res = self.res as usize;
        let c = (k as usize * res + j as usize) * res + i as usize;
        prefetch(self.cell_bits.get(c / 64..c / 64 + 1));
        let n = res + 1;
        let base = (k as usize * n + j as usize) * n + i as usize;
        for off in [0, n, n * n, n * n + n] {
            prefetch(self.index.get(base + off..base + off + 2));
        }
    }

    /// Asks for the records of `corners`, for a record length known at
    /// compile time.
    #[inline(always)]
    pub fn prefetch_records<const S: usize>(&self, corners: &Corners) {
        for &s in &corners.slot {
            if s != EMPTY {
                let at = s as usize * S;
                prefetch(self.values.get(at..at + S));
            }
        }
    }

    /// The corners at `u` whatever the cell's occupancy bit says (`None`
    /// only outside the grid): resampling reads pruned cells too.
    pub fn corners_any(&self, u: Vec3) -> Option<Corners> {
        let (i, j, k) = self.cell_of(u)?;
        Some(self.corners_in(u, i, j, k))
    }

    #[inline(always)]
    fn corners_in(&self, u: Vec3, i: u32, j: u32, k: u32) -> Corners {
        let (fx, fy, fz) = (u.x - i as f32, u.y - j as f32, u.z - k as f32);
        let n = self.res as usize + 1;
        let base = (k as usize * n + j as usize) * n + i as usize;
        let mut out = Corners::default();
        let offs = [0, 1, n, n + 1, n * n, n * n + 1, n * n + n, n * n + n + 1];
        let wx = [1.0 - fx, fx];
        let wy = [1.0 - fy, fy];
        let wz = [1.0 - fz, fz];
        for (c, off) in offs.iter().enumerate() {
            out.slot[c] = self.index.get(base + off).copied().unwrap_or(EMPTY);
            out.weight[c] = wx[c & 1] * wy[(c >> 1) & 1] * wz[c >> 2];
        }
        out
    }

    /// The interpolated record at the corners, for a record length known
    /// at compile time (the hot path).
    #[inline(always)]
    pub fn gather<const S: usize>(&self, corners: &Corners) -> [f32; S] {
        let mut out = [0.0; S];
        for c in 0..8 {
            let at = corners.slot[c] as usize * S;
            let rec = self
                .values
                .get(at..at + S)
                .and_then(|r| <&[f32; S]>::try_from(r).ok());
            if let Some(rec) = rec {
                let w = corners.weight[c];
                for i in 0..S {
                    out[i] += w * rec[i];
                }
            }
        }
        out
    }

    /// The interpolated record at the corners into `out` (`record_len()`).
    #[inline]
    pub fn interpolate(&self, corners: &Corners, out: &mut [f32]) {
        let len = self.record_len();
        out.iter_mut().for_each(|o| *o = 0.0);
        for c in 0..8 {
            let s = corners.slot[c];
            if s == EMPTY {
                continue;
            }
            let w = corners.weight[c];
            let rec = &self.values[s as usize * len..(s as usize + 1) * len];
            for (o, &v) in out.iter_mut().zip(rec) {
                *o += w * v;
            }
        }
    }
}

impl SparseGrid {
    /// The interpolated raw density at world point `p` (`None` outside
    /// the grid or in a cell storing nothing): float 0 of the records
    /// only, summed as [`SparseGrid::interpolate`] sums it, so the same
    /// bits as its `out[0]`.
    #[inline]
    pub fn raw_density(&self, p: Vec3) -> Option<f32> {
        let len = self.record_len();
        self.raw_density_from(p, |s| self.values[s as usize * len])
    }

    /// [`SparseGrid::raw_density`] with slot `s`'s raw density read by
    /// `raw(s)`.
    #[inline(always)]
    fn raw_density_from(&self, p: Vec3, raw_of: impl Fn(u32) -> f32) -> Option<f32> {
        let c = self.corners(self.to_grid(p))?;
        let mut raw = 0.0f32;
        for (&s, &w) in c.slot.iter().zip(&c.weight) {
            if s == EMPTY {
                continue;
            }
            raw += w * raw_of(s);
        }
        Some(raw)
    }

    /// The inside test on an interpolated raw density (`None`: no stored
    /// corner).
    #[inline(always)]
    fn is_inside_raw(&self, raw: Option<f32>, t: &InsideThreshold) -> bool {
        let Some(raw) = raw else {
            return 0.0 >= t.sigma;
        };
        if raw < t.lo {
            false
        } else if raw > t.hi {
            true
        } else {
            self.density_of_raw(raw) >= t.sigma
        }
    }

    /// σ (per world unit) of an interpolated raw density.
    #[inline]
    fn density_of_raw(&self, raw: f32) -> f32 {
        if raw <= DENSITY_FLOOR {
            return 0.0;
        }
        activate_density(raw).0 * self.density_scale()
    }
}

/// Floats per (padded) record of an SH degree: 4, 16 or 32.
#[inline]
pub fn record_len(sh_degree: u32) -> usize {
    match sh_degree {
        0 => 4,
        1 => 16,
        _ => 32,
    }
}

/// The density activation: softplus(raw − SHIFT) and its derivative.
#[inline]
pub fn activate_density(raw: f32) -> (f32, f32) {
    let x = raw - DENSITY_SHIFT;
    if x > 15.0 {
        (x, 1.0)
    } else {
        let e = x.exp();
        ((1.0 + e).ln(), e / (1.0 + e))
    }
}

/// The logistic function.
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

impl RadianceField for SparseGrid {
    fn bounds(&self) -> Aabb {
        self.cube
    }

    fn resolution(&self) -> u32 {
        self.res
    }

    fn density(&self, p: Vec3) -> f32 {
        match self.raw_density(p) {
            Some(raw) => self.density_of_raw(raw),
            None => 0.0,
        }
    }

    fn inside_threshold(&self, sigma_min: f32) -> InsideThreshold {
        // softplus(raw − SHIFT)·scale ≥ σ ⇔ raw ≥ SHIFT + ln(exp(σ/scale) − 1)
        // in exact arithmetic; in f32 the two sides can disagree only next
        // to that raw, so a band around it is left to the density. The
        // band's half-width (1e-3 relative) dwarfs the activation's f32
        // error (a few ulps, ~1e-6 relative in σ) where its slope
        // d ln σ / d raw ≥ 1/(1 + |x|); below x = −5, `ln(1 + e)` loses
        // digits to the rounding of 1 + e, and the density always decides.
        let y = f64::from(sigma_min) / f64::from(self.density_scale());
        let x = y.exp_m1().ln();
        if !(sigma_min > 0.0 && x.is_finite() && x >= -5.0) {
            return InsideThreshold::exact(sigma_min);
        }
        let raw = x + f64::from(DENSITY_SHIFT);
        let half = 1e-3 * (1.0 + x.abs());
        InsideThreshold {
            sigma: sigma_min,
            lo: (raw - half).max(f64::from(DENSITY_FLOOR)) as f32,
            hi: (raw + half) as f32,
        }
    }

    fn is_inside(&self, p: Vec3, t: &InsideThreshold) -> bool {
        self.is_inside_raw(self.raw_density(p), t)
    }

    fn for_point_queries(&self) -> Option<Box<dyn RadianceField + '_>> {
        // Without room for the copy, the grid answers the queries itself.
        DensityCopy::try_new(self).map(|c| Box::new(c) as Box<dyn RadianceField + '_>)
    }

    fn color(&self, p: Vec3, dir: Vec3) -> Vec3 {
        let Some(c) = self.corners(self.to_grid(p)) else {
            return Vec3::ZERO;
        };
        let mut buf = [0.0; MAX_RECORD];
        let rec = &mut buf[..self.record_len()];
        self.interpolate(&c, rec);
        let mut basis = [0.0; sh::MAX_COUNT];
        let k = sh::eval(self.sh_degree, dir, &mut basis);
        let mut rgb = [0.0; 3];
        for (ch, out) in rgb.iter_mut().enumerate() {
            let coeffs = &rec[1 + ch * k..1 + (ch + 1) * k];
            let s: f32 = coeffs.iter().zip(&basis[..k]).map(|(a, b)| a * b).sum();
            *out = sigmoid(s);
        }
        Vec3::from_array(rgb)
    }
}

/// A sparse grid with its raw densities copied out of the records onto
/// its whole vertex lattice: the same field, answering density and inside
/// queries with the same bits, but each corner's density is read straight
/// from its vertex, 4 bytes beside its x-neighbour's, instead of through
/// the index into one cache line of a 64- or 128-byte record (lego's 509
/// MB field at 384³: a 228 MB lattice, for the extraction only). The
/// bake's extraction asks the inside test at some 150 M points.
pub struct DensityCopy<'a> {
    grid: &'a SparseGrid,
    /// The raw density at every lattice vertex ((res + 1)³, x fastest, as
    /// the grid's index), 0 where the grid stores none.
    raw: Vec<f32>,
}

impl<'a> DensityCopy<'a> {
    /// Copies `grid`'s raw densities onto its whole vertex lattice; `None`
    /// when that lattice cannot be allocated (a huge resolution).
    pub fn try_new(grid: &'a SparseGrid) -> Option<Self> {
        let n = grid.res as usize + 1;
        let len = grid.record_len();
        let cells = n.checked_mul(n)?.checked_mul(n)?;
        let mut raw = Vec::new();
        raw.try_reserve_exact(cells).ok()?;
        raw.resize(cells, 0.0f32);
        // Slots are numbered cell by cell in z-major order, so these
        // writes walk the lattice nearly in order.
        for (s, &v) in grid.vertex.iter().enumerate() {
            if let (Some(r), Some(&d)) = (raw.get_mut(v as usize), grid.values.get(s * len)) {
                *r = d;
            }
        }
        Some(Self { grid, raw })
    }

    /// [`SparseGrid::raw_density`] read from the lattice copy: the same
    /// corners and weights, summed in the same order. A vertex the grid
    /// stores nothing at adds w · 0 = +0 where the grid's sum skips it,
    /// which leaves the sum's bits as they are (w ≥ 0, and a sum that
    /// starts at +0 never becomes −0 under round-to-nearest).
    #[inline(always)]
    fn raw_density(&self, p: Vec3) -> Option<f32> {
        let g = self.grid;
        let u = g.to_grid(p);
        let (i, j, k) = g.cell_of(u)?;
        let res = g.res as usize;
        let c = (k as usize * res + j as usize) * res + i as usize;
        if g.cell_bits
            .get(c / 64)
            .is_none_or(|b| b & (1 << (c % 64)) == 0)
        {
            return None;
        }
        let (fx, fy, fz) = (u.x - i as f32, u.y - j as f32, u.z - k as f32);
        let n = res + 1;
        let base = (k as usize * n + j as usize) * n + i as usize;
        let offs = [0, 1, n, n + 1, n * n, n * n + 1, n * n + n, n * n + n + 1];
        let wx = [1.0 - fx, fx];
        let wy = [1.0 - fy, fy];
        let wz = [1.0 - fz, fz];
        let mut raw = 0.0f32;
        for (c, off) in offs.iter().enumerate() {
            let w = wx[c & 1] * wy[(c >> 1) & 1] * wz[c >> 2];
            raw += w * self.raw.get(base + off).copied().unwrap_or(0.0);
        }
        Some(raw)
    }
}

impl RadianceField for DensityCopy<'_> {
    fn bounds(&self) -> Aabb {
        self.grid.bounds()
    }

    fn resolution(&self) -> u32 {
        self.grid.resolution()
    }

    fn density(&self, p: Vec3) -> f32 {
        match self.raw_density(p) {
            Some(raw) => self.grid.density_of_raw(raw),
            None => 0.0,
        }
    }

    fn inside_threshold(&self, sigma_min: f32) -> InsideThreshold {
        self.grid.inside_threshold(sigma_min)
    }

    fn is_inside(&self, p: Vec3, t: &InsideThreshold) -> bool {
        self.grid.is_inside_raw(self.raw_density(p), t)
    }

    fn color(&self, p: Vec3, dir: Vec3) -> Vec3 {
        self.grid.color(p, dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Aabb {
        Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        }
    }

    /// Pruning clears exactly the cells whose corners are all thin, and
    /// the interpolation that ignores the bits still reads them.
    #[test]
    fn pruning_clears_only_thin_cells() {
        let mut g = SparseGrid::new(4, unit(), 0, |_, _, _| true);
        let len = g.record_len();
        // Everything thin except vertex (2, 2, 2).
        for s in 0..g.slots() {
            g.values[s * len] = -20.0;
        }
        let thick = g.index[(2 * 5 + 2) * 5 + 2] as usize;
        g.values[thick * len] = 10.0;
        assert_eq!(g.occupied_cells(), 64);
        let cleared = g.prune_cells(1e-3);
        // The eight cells around (2, 2, 2) keep their bits.
        assert_eq!(cleared, 56);
        assert_eq!(g.occupied_cells(), 8);
        let inside = Vec3::splat(1.5);
        let far = Vec3::splat(0.5);
        assert!(g.corners(inside).is_some());
        assert!(g.corners(far).is_none());
        assert!(g.corners_any(far).is_some());
    }

    #[test]
    fn weights_sum_to_one_and_pick_the_right_cell() {
        let g = SparseGrid::new(4, unit(), 0, |_, _, _| true);
        let c = g.corners(Vec3::new(1.25, 2.5, 3.75)).unwrap();
        let s: f32 = c.weight.iter().sum();
        assert!((s - 1.0).abs() < 1e-6);
        // Corner 0 is vertex (1, 2, 3).
        assert_eq!(g.vertex[c.slot[0] as usize], (3 * 5 + 2) * 5 + 1);
        assert!((c.weight[7] - 0.25 * 0.5 * 0.75).abs() < 1e-6);
    }

    #[test]
    fn interpolation_reproduces_a_linear_function() {
        let mut g = SparseGrid::new(4, unit(), 0, |_, _, _| true);
        let len = g.record_len();
        for s in 0..g.slots() {
            let (i, j, k) = g.vertex_ijk(g.vertex[s]);
            g.values[s * len] = i as f32 + 2.0 * j as f32 - k as f32;
        }
        let u = Vec3::new(0.3, 3.2, 1.9);
        let mut rec = vec![0.0; len];
        g.interpolate(&g.corners(u).unwrap(), &mut rec);
        assert!((rec[0] - (0.3 + 6.4 - 1.9)).abs() < 1e-5);
    }

    #[test]
    fn empty_cells_and_outside_points_have_no_corners() {
        let g = SparseGrid::new(4, unit(), 1, |i, j, k| i <= 1 && j <= 1 && k <= 1);
        assert!(g.corners(Vec3::splat(0.5)).is_some());
        assert!(g.corners(Vec3::splat(2.5)).is_none());
        assert!(g.corners(Vec3::splat(-0.1)).is_none());
        assert!(g.corners(Vec3::splat(f32::NAN)).is_none());
        // A cell touching a stored vertex is active.
        assert!(g.corners(Vec3::splat(1.5)).is_some());
    }

    /// A cube off the origin, for the inside tests.
    fn skewed_cube() -> Aabb {
        Aabb {
            min: Vec3::new(-1.0, -0.5, 0.25),
            max: Vec3::new(1.0, 1.5, 2.25),
        }
    }

    /// The fast inside test answers as `density(p) >= σ` everywhere,
    /// thresholds that are some point's exact density included.
    #[test]
    fn is_inside_matches_the_density_test() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(15);
        let cube = skewed_cube();
        let keep: Vec<bool> = (0..9 * 9 * 9).map(|_| rng.random::<f32>() < 0.8).collect();
        let mut g = SparseGrid::new(8, cube, 1, |i, j, k| keep[((k * 9 + j) * 9 + i) as usize]);
        for v in g.values.iter_mut() {
            *v = rng.random_range(-3.0..12.0);
        }
        let point = |rng: &mut rand_chacha::ChaCha8Rng| {
            // Some points outside the cube too.
            cube.min + Vec3::new(rng.random(), rng.random(), rng.random()) * 2.2 - 0.1
        };
        let mut sigmas: Vec<f32> = [-6.0f32, -4.9, -2.0, 0.0, 1.5, 5.0, 20.0]
            .iter()
            .map(|&x| activate_density(x + DENSITY_SHIFT).0 * g.density_scale())
            .collect();
        sigmas.extend([0.0, -1.0, f32::MIN_POSITIVE]);
        for _ in 0..20 {
            let d = g.density(point(&mut rng));
            sigmas.extend([d, d.next_up(), d.next_down()]);
        }
        let (mut fast, mut all, mut banded) = (0usize, 0usize, 0usize);
        for &sigma in &sigmas {
            let t = g.inside_threshold(sigma);
            let band = t.lo.is_finite() && t.hi.is_finite();
            banded += usize::from(band);
            for _ in 0..20_000 {
                let p = point(&mut rng);
                assert_eq!(
                    g.is_inside(p, &t),
                    g.density(p) >= sigma,
                    "σ {sigma} at {p}: density {}",
                    g.density(p)
                );
                if let Some(raw) = g.raw_density(p).filter(|_| band) {
                    all += 1;
                    fast += usize::from(raw < t.lo || raw > t.hi);
                }
            }
        }
        // Most thresholds get a band, and it decides nearly every point
        // (else nothing is gained).
        assert!(
            banded * 2 > sigmas.len(),
            "{banded} of {} banded",
            sigmas.len()
        );
        assert!(fast * 10 > all * 9, "{fast} of {all} decided by the band");
    }

    #[test]
    fn the_density_copy_answers_with_the_same_bits() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
        let cube = skewed_cube();
        for degree in 0..3 {
            let keep: Vec<bool> = (0..9 * 9 * 9).map(|_| rng.random::<f32>() < 0.7).collect();
            let mut g = SparseGrid::new(8, cube, degree, |i, j, k| {
                keep[((k * 9 + j) * 9 + i) as usize]
            });
            for v in g.values.iter_mut() {
                *v = rng.random_range(-3.0..12.0);
            }
            let copy = g
                .for_point_queries()
                .expect("a sparse grid offers its copy");
            let t = g.inside_threshold(g.density(cube.min + Vec3::splat(0.9)));
            for _ in 0..20_000 {
                let p = cube.min + Vec3::new(rng.random(), rng.random(), rng.random()) * 2.2 - 0.1;
                assert_eq!(copy.density(p).to_bits(), g.density(p).to_bits(), "{p}");
                assert_eq!(copy.is_inside(p, &t), g.is_inside(p, &t), "{p}");
            }
            let dir = Vec3::new(0.3, -0.8, 0.52).normalize();
            assert_eq!(
                copy.color(cube.min + 1.0, dir),
                g.color(cube.min + 1.0, dir)
            );
            assert_eq!(copy.bounds(), g.bounds());
            assert_eq!(copy.resolution(), g.resolution());
        }
    }

    #[test]
    fn activation_is_smooth_and_matches_its_derivative() {
        for &x in &[-10.0f32, 0.0, 3.9, 4.0, 8.0, 18.0, 30.0] {
            let (y, d) = activate_density(x);
            let h = 1e-2;
            let fd = (activate_density(x + h).0 - activate_density(x - h).0) / (2.0 * h);
            assert!(y >= 0.0 && (d - fd).abs() < 1e-3, "x={x} d={d} fd={fd}");
        }
    }
}
