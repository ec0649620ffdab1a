//! Geometry from a radiance field: planar quads on the field's surface,
//! and binary texel opacity at p×p per quad.
//!
//! A point is *inside* when the field's opacity over a step of half a field
//! cell reaches `surface_alpha` (default 0.05: a trained field's surface
//! spreads over a few cells, so each half cell is only partly opaque). Voxels of the
//! g³ grid are classified at the 27 points of a half-voxel lattice, as the
//! hull baker does: all inside → full, none → empty, else *shell* (the
//! surface crosses it).
//!
//! [`extract`] puts the quads on the surface (MobileNeRF moves its quads'
//! vertices onto the surface while training; here they are placed there
//! from the start): per shell voxel, the surface seen along an axis from
//! one side is a height field over the voxel's cross-section; each side
//! that sees enough of the surface gets one parallelogram tilted onto the
//! plane fitted to its height field, a texel opaque iff its line along the
//! axis enters the inside within the voxel, or within a quarter voxel
//! beyond its slab (see [`extract_with`]). A ray
//! then stops at a texel on (a plane through) the surface, so a texel
//! shows the same surface point from every view.
//!
//! [`extract_voxel_faces`] is the first geometry: every face of every
//! shell voxel (`bake::quads::shell_quads`), a texel opaque iff its point
//! is inside; the first opaque texel a ray meets is up to a voxel behind
//! the surface (parallax).

use crate::rounding::floor;
use glam::Vec3;
use rayon::prelude::*;

use super::super::carve::{HullLookup, ShellGrid, VoxelClass};
use super::super::quads::{shell_quads, Quad};
use super::super::Aabb;
use crate::train::field::{InsideThreshold, RadianceField};

/// Cells per edge of the coarse pass that finds the object's cube.
pub const COARSE: u32 = 96;

/// The inside test of a field.
#[derive(Clone, Copy)]
pub struct Surface<'a> {
    /// The field.
    pub field: &'a dyn RadianceField,
    /// Density σ (per world unit) at and above which a point is inside.
    pub sigma: f32,
    /// `sigma` prepared for the field's inside test.
    threshold: InsideThreshold,
    /// The visual hull that bounds the inside, if any
    /// ([`Surface::bounded_by`]).
    hull: Option<&'a HullLookup<'a>>,
}

impl<'a> Surface<'a> {
    /// The surface where opacity over half a field cell reaches `alpha`.
    pub fn new(field: &'a dyn RadianceField, alpha: f32) -> Self {
        Self::with_sigma(field, super::threshold::sigma_of_alpha(field, alpha))
    }

    /// The surface where the density reaches `sigma` (per world unit).
    pub fn with_sigma(field: &'a dyn RadianceField, sigma: f32) -> Self {
        Self {
            field,
            sigma,
            threshold: field.inside_threshold(sigma),
            hull: None,
        }
    }

    /// The same surface with only the points of the training views'
    /// visual hull inside. Where the field's density is soft beyond the
    /// photos' contour (a threshold lowered into its falloff), the
    /// inside would otherwise reach past the hull, and the hull carve
    /// would then empty the outermost planes with nothing behind them:
    /// pawn (256, 9) lost 14 % of its held-out interior pixels that way
    /// (docs/baking.md, "Session 35").
    pub fn bounded_by<'b>(self, hull: &'b HullLookup<'b>) -> Surface<'b>
    where
        'a: 'b,
    {
        Surface {
            field: self.field,
            sigma: self.sigma,
            threshold: self.threshold,
            hull: Some(hull),
        }
    }

    /// Whether world point `p` is inside: `density(p) ≥ sigma` (and, when
    /// bounded, inside the hull).
    #[inline]
    pub fn inside(&self, p: Vec3) -> bool {
        self.field.is_inside(p, &self.threshold) && self.hull.is_none_or(|h| h.inside(p))
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

impl Geometry {
    /// The world point of texel index `texel` (`quad · p² + y · p + x`)
    /// at patch `p`.
    #[inline]
    pub fn texel_point(&self, p: u32, texel: u32) -> Vec3 {
        let p2 = p * p;
        let t = texel % p2;
        texel_point(&self.quads[(texel / p2) as usize], p, t % p, t / p)
    }
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

/// Settings of the surface quads ([`extract_with`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSettings {
    /// Intervals per voxel edge of the sub-lattice (m, 1…63): each texel line
    /// is sampled at m + 1 depths across its voxel, and the axis choice
    /// and the plane fit use the (m + 1)² lattice lines per axis.
    pub sub: u32,
    /// A (axis, side) gets a quad when its lattice lines with an entry
    /// reach this fraction of the best (axis, side)'s (1: the dominant
    /// one only; small: every side the surface shows).
    pub keep: f32,
    /// Bisection steps refining each lattice line's entry for the plane
    /// fit.
    pub refine: u32,
    /// Each quad's cross-section is grown by this fraction of the voxel
    /// edge on every side beyond its voxel's (overlap against cracks).
    pub grow: f32,
    /// A plane sits where the opacity accumulated inward from its lattice
    /// lines' entries reaches this value, in (0, 1). ½ is a volume
    /// renderer's expected surface; 0.2 scores best on lego and chair
    /// (docs/baking.md, "Session 15"): an underside the field never saw
    /// has a long soft march, and nearer its entry its plane no longer
    /// lands on or above the seen side (lego's pixels that see a plane
    /// from behind halve).
    pub depth: f32,
    /// A texel is opaque when its line enters the surface within its
    /// voxel's slab widened by this fraction of the voxel edge on both
    /// ends, in [0, 1) (0: the slab alone, so each crossing belongs to one
    /// voxel along the axis). Stacked planes of a sloped surface then
    /// overlap at their seam instead of opening a crack that views between
    /// the training views find (lego (128, 17), ¼: +0.14 dB, held-out
    /// holes −39 %; docs/baking.md, "Session 28").
    pub reach: f32,
}

impl Default for SurfaceSettings {
    fn default() -> Self {
        Self {
            sub: 4,
            keep: 0.5,
            refine: 5,
            grow: 0.125,
            depth: 0.2,
            reach: 0.25,
        }
    }
}

/// Quads and texel opacity of the field at (g, p) on the field's surface
/// (default [`SurfaceSettings`]); `None` when no point of the field is
/// inside.
pub fn extract(s: &Surface<'_>, g: u32, p: u32) -> Option<Geometry> {
    extract_with(s, g, p, &SurfaceSettings::default())
}

/// Quads on the faces of the shell voxels, a texel opaque iff its point
/// is inside (the first geometry of this baker, kept for comparison):
/// the first opaque texel a ray meets is up to a voxel behind the surface.
pub fn extract_voxel_faces(s: &Surface<'_>, g: u32, p: u32) -> Option<Geometry> {
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

/// Quads on the field's surface: per shell voxel, the surface seen along
/// each axis from each side (where a line along the axis, coming from
/// that side, first enters the inside within the voxel's slab) is a
/// height field over the voxel's cross-section; the sides whose height
/// field covers enough of it (see [`SurfaceSettings::keep`]) get one
/// planar quad each, tilted to the plane fitted to that height field (a
/// parallelogram over the cross-section), a texel opaque iff its line
/// has such an entry within the slab widened by [`SurfaceSettings::reach`]
/// on both ends. The axis choice and the plane fit read the slab alone:
/// slabs of neighbouring voxels share their end depths, so there each
/// crossing belongs to exactly one voxel along the axis.
pub fn extract_with(s: &Surface<'_>, g: u32, p: u32, set: &SurfaceSettings) -> Option<Geometry> {
    let cube = object_cube(s)?;
    let grid = classify(s, &cube, g);
    let shell: Vec<[u32; 3]> = (0..g)
        .flat_map(|k| (0..g).flat_map(move |j| (0..g).map(move |i| [i, j, k])))
        .filter(|&[i, j, k]| grid.class(i as i64, j as i64, k as i64) == VoxelClass::Shell)
        .collect();
    let per: Vec<Vec<(Quad, Vec<bool>)>> = shell
        .par_iter()
        .map(|&[i, j, k]| voxel_quads(s, grid.corner(i, j, k), grid.voxel, [i, j, k], p, set))
        .collect();
    let mut quads = Vec::new();
    let mut opacity = Vec::new();
    for (q, occ) in per.into_iter().flatten() {
        quads.push(q);
        opacity.extend(occ);
    }
    Some(Geometry {
        cube,
        voxel: grid.voxel,
        shell_voxels: grid.count(VoxelClass::Shell),
        full_voxels: grid.count(VoxelClass::Full),
        quads,
        opacity,
    })
}

/// The first entry into the inside along a line sampled at `n` depths
/// (`inside(t)`, t = 0 at the slab's low end), coming from the high end
/// (`from_high`) or the low end: the pair (outside sample, inside sample)
/// of depth indices, if any.
#[inline]
fn first_entry(
    n: usize,
    from_high: bool,
    inside: impl Fn(usize) -> bool,
) -> Option<(usize, usize)> {
    let mut prev = None;
    for step in 0..n {
        let t = if from_high { n - 1 - step } else { step };
        let now = inside(t);
        if now && prev == Some(false) {
            let out = if from_high { t + 1 } else { t - 1 };
            return Some((out, t));
        }
        prev = Some(now);
    }
    None
}

/// The square face of the voxel at `lo` (edge `h`) on `axis`, side
/// `sign`, grown by `e` on every side: as `quads::face`, (origin offset,
/// u, v) chosen so that u × v = −normal.
fn grown_face(lo: Vec3, h: f32, e: f32, axis: usize, positive: bool, voxel: [u32; 3]) -> Quad {
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let (off, u, v) = match (axis, positive) {
        (0, true) => (x, z, y),
        (0, false) => (Vec3::ZERO, y, z),
        (1, true) => (y, x, z),
        (1, false) => (Vec3::ZERO, z, x),
        (2, true) => (z, y, x),
        _ => (Vec3::ZERO, x, y),
    };
    let mut normal = Vec3::ZERO;
    normal[axis] = if positive { 1.0 } else { -1.0 };
    Quad {
        origin: lo + h * off - e * (u + v),
        u: (h + 2.0 * e) * u,
        v: (h + 2.0 * e) * v,
        normal,
        voxel,
        twist: Vec3::ZERO,
    }
}

/// Least-squares plane d = a + b·x + c·y through `pts` (x, y, d); a
/// constant at their mean when they do not span a plane.
fn fit_plane(pts: &[(f32, f32, f32)]) -> (f32, f32, f32) {
    let n = pts.len() as f64;
    if pts.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    let mean = |f: &dyn Fn(&(f32, f32, f32)) -> f64| pts.iter().map(f).sum::<f64>() / n;
    let (mx, my, md) = (
        mean(&|q| f64::from(q.0)),
        mean(&|q| f64::from(q.1)),
        mean(&|q| f64::from(q.2)),
    );
    let (mut sxx, mut sxy, mut syy, mut sxd, mut syd) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for q in pts {
        let (x, y, d) = (
            f64::from(q.0) - mx,
            f64::from(q.1) - my,
            f64::from(q.2) - md,
        );
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sxd += x * d;
        syd += y * d;
    }
    let det = sxx * syy - sxy * sxy;
    let scale = (sxx + syy).max(1e-30);
    let (b, c) = if det > 1e-6 * scale * scale {
        ((sxd * syy - syd * sxy) / det, (syd * sxx - sxd * sxy) / det)
    } else if sxx > 1e-9 * scale && syy <= 1e-9 * scale {
        (sxd / sxx, 0.0)
    } else if syy > 1e-9 * scale && sxx <= 1e-9 * scale {
        (0.0, syd / syy)
    } else {
        (0.0, 0.0)
    };
    let a = md - b * mx - c * my;
    (a as f32, b as f32, c as f32)
}

/// Largest slope of a fitted plane (a steeper fit is clamped: it would
/// come from a few points of a surface seen at grazing incidence).
const MAX_SLOPE: f32 = 3.0;

/// The point along `dir` from `x` (at most `2·h` on) where the opacity
/// accumulated from `x` reaches `alpha` (in (0, 1)): the optical depth ∫σ
/// reaches −ln(1 − alpha) (steps of `h`/16, linear within the last); `x`
/// itself when it never does.
fn opacity_depth(s: &Surface<'_>, x: Vec3, dir: Vec3, h: f32, alpha: f32) -> Vec3 {
    const STEPS: u32 = 32;
    let ds = h / 16.0;
    let target = -(1.0 - alpha.clamp(1e-6, 1.0 - 1e-6)).ln();
    let mut tau = 0.0f32;
    let mut prev = s.field.density(x);
    for i in 1..=STEPS {
        let y = x + (i as f32 * ds) * dir;
        let now = s.field.density(y);
        let add = 0.5 * (prev + now) * ds;
        if tau + add >= target {
            let f = if add > 0.0 { (target - tau) / add } else { 0.0 };
            return x + ((i as f32 - 1.0 + f) * ds) * dir;
        }
        tau += add;
        prev = now;
    }
    x
}

/// The surface quads of one shell voxel (lower corner `lo`, edge `h`).
pub(super) fn voxel_quads(
    s: &Surface<'_>,
    lo: Vec3,
    h: f32,
    voxel: [u32; 3],
    p: u32,
    set: &SurfaceSettings,
) -> Vec<(Quad, Vec<bool>)> {
    let m = set.sub.clamp(1, 63) as usize;
    let n = m + 1;
    let step = h / m as f32;
    let at = |a: usize, b: usize, c: usize| lo + step * Vec3::new(a as f32, b as f32, c as f32);
    let mut lat = vec![false; n * n * n];
    for c in 0..n {
        for b in 0..n {
            for a in 0..n {
                lat[(c * n + b) * n + a] = s.inside(at(a, b, c));
            }
        }
    }
    // Lattice index of (depth t along `axis`, line coordinates (i1, i2)
    // along the axes after it, cyclically).
    let idx = |axis: usize, t: usize, i1: usize, i2: usize| {
        let mut ijk = [0usize; 3];
        ijk[axis] = t;
        ijk[(axis + 1) % 3] = i1;
        ijk[(axis + 2) % 3] = i2;
        (ijk[2] * n + ijk[1]) * n + ijk[0]
    };
    // Lines with an entry, per (axis, side).
    let mut count = [[0usize; 2]; 3];
    for (axis, cnt) in count.iter_mut().enumerate() {
        for (side, c) in cnt.iter_mut().enumerate() {
            for i2 in 0..n {
                for i1 in 0..n {
                    if first_entry(n, side == 0, |t| lat[idx(axis, t, i1, i2)]).is_some() {
                        *c += 1;
                    }
                }
            }
        }
    }
    let best = count.iter().flatten().copied().max().unwrap_or(0);
    if best == 0 {
        return Vec::new();
    }
    let need = ((set.keep * best as f32).ceil() as usize).max(1);
    let p2 = (p * p) as usize;
    let grow = set.grow.clamp(0.0, 1.0) * h;
    // With a reach, a line is also sampled once beyond each end of the
    // slab, `reach` out.
    let reach = set.reach.clamp(0.0, 0.99) * h;
    let ext = reach > 0.0;
    // The samples beyond the slab's ends on each lattice line, per axis
    // (computed for the axes that get a quad).
    let caps = |axis: usize| -> Vec<[bool; 2]> {
        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
        (0..n * n)
            .map(|l| {
                let mut x = lo;
                x[a1] += step * (l % n) as f32;
                x[a2] += step * (l / n) as f32;
                let mut at_depth = |d: f32| {
                    x[axis] = lo[axis] + d;
                    s.inside(x)
                };
                [at_depth(-reach), at_depth(h + reach)]
            })
            .collect()
    };
    let mut cap: [Vec<[bool; 2]>; 3] = Default::default();
    if ext {
        for (axis, cnt) in count.iter().enumerate() {
            if cnt.iter().any(|&c| c >= need) {
                cap[axis] = caps(axis);
            }
        }
    }
    // Inside pattern of each lattice line along each axis (bit t = depth t).
    let column = |axis: usize, i1: usize, i2: usize| -> u64 {
        (0..n).fold(0u64, |acc, t| {
            acc | (u64::from(lat[idx(axis, t, i1, i2)]) << t)
        })
    };
    let mut out = Vec::new();
    let mut columns = Vec::with_capacity(n * n);
    for (axis, cnt) in count.iter().enumerate() {
        if cnt.iter().all(|&c| c < need) {
            continue;
        }
        // Each lattice line's pattern, once per axis: every texel reads
        // four of them.
        columns.clear();
        columns.extend((0..n * n).map(|l| column(axis, l % n, l / n)));
        let column = |i1: usize, i2: usize| columns[i2 * n + i1];
        for (side, &c) in cnt.iter().enumerate() {
            if c < need {
                continue;
            }
            let positive = side == 0;
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            // Plane fit to the refined entries of the lattice lines.
            let mut pts = Vec::with_capacity(n * n);
            for i2 in 0..n {
                for i1 in 0..n {
                    let Some((to, ti)) = first_entry(n, positive, |t| lat[idx(axis, t, i1, i2)])
                    else {
                        continue;
                    };
                    let mut x_out = at(0, 0, 0);
                    x_out[a1] += step * i1 as f32;
                    x_out[a2] += step * i2 as f32;
                    let mut x_in = x_out;
                    x_out[axis] += step * to as f32;
                    x_in[axis] += step * ti as f32;
                    for _ in 0..set.refine {
                        let mid = 0.5 * (x_out + x_in);
                        if s.inside(mid) {
                            x_in = mid;
                        } else {
                            x_out = mid;
                        }
                    }
                    // From the entry on, inward: where the opacity
                    // accumulated along the line reaches `depth` (a
                    // trained field's surface spreads over a few cells
                    // behind the entry).
                    let x_e = 0.5 * (x_out + x_in);
                    let mut dir = Vec3::ZERO;
                    dir[axis] = if positive { -1.0 } else { 1.0 };
                    let d = opacity_depth(s, x_e, dir, h, set.depth)[axis] - lo[axis];
                    pts.push((step * i1 as f32, step * i2 as f32, d));
                }
            }
            let (pa, pb, pc) = fit_plane(&pts);
            let (pb, pc) = (
                pb.clamp(-MAX_SLOPE, MAX_SLOPE),
                pc.clamp(-MAX_SLOPE, MAX_SLOPE),
            );
            let flat = grown_face(lo, h, grow, axis, positive, voxel);
            // Texel opacity: an entry from this side on the texel's line.
            // Where the four lattice lines around the texel's line agree,
            // the line takes their answer (a feature thinner than the
            // lattice between them is lost); where they differ (the
            // silhouette passes between them) it is sampled at all n
            // depths (and the reach's two), exact to a texel.
            let mut occ = vec![false; p2];
            for (t, o) in occ.iter_mut().enumerate() {
                let x = texel_point(&flat, p, t as u32 % p, t as u32 / p);
                let cell = |c: f32| (floor(c / step).max(0.0) as usize).min(m - 1);
                let (j1, j2) = (cell(x[a1] - lo[a1]), cell(x[a2] - lo[a2]));
                let c0 = column(j1, j2);
                let around = [(1, 0), (0, 1), (1, 1)];
                let same = around
                    .iter()
                    .all(|&(d1, d2)| column(j1 + d1, j2 + d2) == c0);
                let sample = |d: f32| {
                    let mut q = x;
                    q[axis] = lo[axis] + d;
                    s.inside(q)
                };
                let bits = if same {
                    *o = first_entry(n, positive, |d| c0 >> d & 1 == 1).is_some();
                    c0
                } else {
                    // Sampled in the order `first_entry` reads the depths,
                    // stopping at the entry: the samples beyond it would
                    // not change the answer, and `bits` is read again
                    // below only when there is none (then it is whole).
                    let mut bits = 0u64;
                    let mut prev = None;
                    for k in 0..n {
                        let d = if positive { n - 1 - k } else { k };
                        let now = sample(step * d as f32);
                        bits |= u64::from(now) << d;
                        if now && prev == Some(false) {
                            *o = true;
                            break;
                        }
                        prev = Some(now);
                    }
                    bits
                };
                // The reach only adds: a line the slab leaves transparent
                // is looked at again with the two samples beyond its ends
                // (the lattice lines' where the four agree, else its own).
                if !*o && ext {
                    let k = j2 * n + j1;
                    let c = &cap[axis];
                    let agree = around
                        .iter()
                        .all(|&(d1, d2)| c.get(k + d2 * n + d1) == c.get(k));
                    let [below, above] = match (agree, c.get(k)) {
                        (true, Some(&b)) => b,
                        _ => [sample(-reach), sample(h + reach)],
                    };
                    // n + 2 ≤ 65 samples: wider than a u64 at m = 63.
                    let wide =
                        u128::from(below) | u128::from(bits) << 1 | u128::from(above) << (n + 1);
                    *o = first_entry(n + 2, positive, |d| wide >> d & 1 == 1).is_some();
                }
            }
            if !occ.iter().any(|&o| o) {
                continue;
            }
            // Tilt the face onto the plane (depth along `axis` affine in
            // the other two coordinates): still a parallelogram.
            let depth = |q: Vec3| pa + pb * (q[a1] - lo[a1]) + pc * (q[a2] - lo[a2]);
            let mut origin = flat.origin;
            origin[axis] = lo[axis] + depth(flat.origin);
            let tilt = |e: Vec3| {
                let mut e2 = e;
                e2[axis] = pb * e[a1] + pc * e[a2];
                e2
            };
            let (u, v) = (tilt(flat.u), tilt(flat.v));
            let normal = (-u.cross(v)).normalize_or(flat.normal);
            out.push((
                Quad {
                    origin,
                    u,
                    v,
                    normal,
                    voxel,
                    twist: Vec3::ZERO,
                },
                occ,
            ));
        }
    }
    out
}

#[cfg(test)]
impl Geometry {
    /// `quads` with `opacity` in the cube [−1, 1]³, 0.1 voxels (tests).
    pub(crate) fn in_cube(quads: Vec<Quad>, opacity: Vec<bool>) -> Self {
        Geometry {
            cube: super::super::Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            },
            voxel: 0.1,
            shell_voxels: 0,
            full_voxels: 0,
            quads,
            opacity,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::analytic::Sphere;
    use super::*;
    use crate::bake::carve::HullLookup;
    use crate::train::field::RadianceField;

    /// |r − R| of every opaque texel of `g` (patch `p`) about `f`'s centre.
    fn texel_radii(g: &Geometry, f: &Sphere, p: u32) -> Vec<f32> {
        let p2 = (p * p) as usize;
        let mut out = Vec::new();
        for (q, occ) in g.quads.iter().zip(g.opacity.chunks(p2)) {
            for (t, &o) in occ.iter().enumerate() {
                if o {
                    let x = texel_point(q, p, t as u32 % p, t as u32 / p);
                    out.push((x - f.centre).length());
                }
            }
        }
        out
    }

    /// The half-space under the plane z = z0 + slope · x.
    struct Slope {
        z0: f32,
        slope: f32,
    }

    impl RadianceField for Slope {
        fn bounds(&self) -> super::super::super::Aabb {
            super::super::super::Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            }
        }

        fn resolution(&self) -> u32 {
            128
        }

        fn density(&self, p: Vec3) -> f32 {
            if p.z < self.z0 + self.slope * p.x {
                100.0
            } else {
                0.0
            }
        }

        fn color(&self, _: Vec3, _: Vec3) -> Vec3 {
            Vec3::splat(0.5)
        }
    }

    /// A surface leaving a voxel's slab through its top: the lines that
    /// enter it just above the slab are transparent on the voxel's +z
    /// quad, and opaque once the reach takes them in; the quads stay where
    /// they were.
    #[test]
    fn the_reach_takes_in_entries_just_beyond_the_slab() {
        // Voxel [0, 0.1]³; the surface at z = 0.09 + 0.3 x crosses its top
        // at x = 0.033 and is 0.02 (a fifth of a voxel) above it at x = 0.1.
        let f = Slope {
            z0: 0.09,
            slope: 0.3,
        };
        let s = Surface::new(&f, 0.5);
        let p = 9;
        let quads = |reach: f32| {
            let set = SurfaceSettings {
                reach,
                ..SurfaceSettings::default()
            };
            voxel_quads(&s, Vec3::ZERO, 0.1, [0; 3], p, &set)
        };
        let (slab, reached) = (quads(0.0), quads(0.25));
        assert_eq!(slab.len(), reached.len());
        let mut top = None;
        for ((q0, o0), (q1, o1)) in slab.iter().zip(&reached) {
            assert_eq!(q0, q1);
            assert!(
                o0.iter().zip(o1).all(|(&a, &b)| !a || b),
                "the reach only adds"
            );
            if q0.normal.z > 0.9 {
                top = Some((o0, o1));
            }
        }
        let (o0, o1) = top.expect("the voxel's surface faces +z");
        let count = |o: &[bool]| o.iter().filter(|&&t| t).count();
        // Before: the third of the cross-section under the slab's top.
        assert!(
            count(o0) > 0 && count(o0) < o0.len() / 2,
            "{} of {}",
            count(o0),
            o0.len()
        );
        assert_eq!(count(o1), o1.len());
        // A reach short of the surface's rise takes in only part of it.
        let (_, o_short) = quads(0.1)
            .into_iter()
            .find(|(q, _)| q.normal.z > 0.9)
            .expect("a +z quad");
        assert!(count(&o_short) > count(o0) && count(&o_short) < o1.len());
    }

    /// A field whose inside reaches past the photos' contour (a sphere of
    /// 0.7 where the photos show one of 0.5, as a soft surface cut at a
    /// lowered threshold does): bounded by the hull, the planes sit on the
    /// hull instead of on the field's surface.
    #[test]
    fn the_hull_bound_puts_the_planes_on_the_hull() {
        use crate::bake::carve::tests::{silhouettes, sphere_views};
        let f = Sphere::new(Vec3::ZERO, 0.7);
        let sil = silhouettes(&sphere_views(&[]), false).with_radius(1.0);
        let s = Surface::new(&f, 0.5);
        let cube = object_cube(&s).expect("the sphere has an inside");
        let mut lookup = HullLookup::new(&sil, &cube, 16);
        lookup.settle_within(|x| s.inside(x));
        let median = |g: &Geometry| {
            let mut r = texel_radii(g, &f, 5);
            r.sort_by(f32::total_cmp);
            r[r.len() / 2]
        };
        let free = extract(&s, 16, 5).expect("an inside");
        let bounded = extract(&s.bounded_by(&lookup), 16, 5).expect("an inside");
        let (rf, rb) = (median(&free), median(&bounded));
        assert!((rf - 0.7).abs() < 0.03, "{rf}");
        assert!(rb > 0.45 && rb < 0.6, "{rb}");
        // Every opaque texel of the bounded planes lies within a voxel of
        // the hull (the planes are tilted and grown beyond their voxels).
        let voxel = (cube.max - cube.min).max_element() / 16.0;
        let (p, p2) = (5, 25);
        for (q, occ) in bounded.quads.iter().zip(bounded.opacity.chunks(p2)) {
            for (t, _) in occ.iter().enumerate().filter(|(_, &o)| o) {
                let x = texel_point(q, p, t as u32 % p, t as u32 / p);
                assert!(sil.inside(x - voxel * x.normalize_or_zero()), "{x}");
            }
        }
    }

    #[test]
    fn a_sphere_gives_a_closed_shell_whose_texels_follow_it() {
        let f = Sphere::new(Vec3::new(0.1, -0.05, 0.0), 0.6);
        let s = Surface::new(&f, 0.5);
        let g = extract_voxel_faces(&s, 16, 5).expect("a sphere has an inside");
        // The cube hugs the sphere (within a coarse cell or two).
        let edge = (g.cube.max - g.cube.min).max_element();
        assert!(
            edge > 1.2 && edge < 1.2 + 4.0 * 3.0 / COARSE as f32,
            "cube edge {edge}"
        );
        assert!(g.shell_voxels > 0 && g.full_voxels > 0);
        // Every opaque texel is inside, and within a voxel of the surface.
        for r in texel_radii(&g, &f, 5) {
            // The field's surface: half its 0.01 density ramp out.
            assert!(r <= 0.6 + 0.005, "opaque texel outside: r = {r}");
            assert!(
                r >= 0.6 - 2.0 * g.voxel,
                "opaque texel deep inside: r = {r}"
            );
        }
    }

    #[test]
    fn surface_quads_put_every_opaque_texel_on_the_sphere() {
        let f = Sphere::new(Vec3::new(0.1, -0.05, 0.0), 0.6);
        let s = Surface::new(&f, 0.5);
        let (surf, faces) = (
            extract(&s, 16, 5).expect("a sphere has an inside"),
            extract_voxel_faces(&s, 16, 5).expect("a sphere has an inside"),
        );
        let mean_off =
            |rs: &[f32]| rs.iter().map(|r| (r - 0.6).abs()).sum::<f32>() / rs.len() as f32;
        let (rs, rf) = (texel_radii(&surf, &f, 5), texel_radii(&faces, &f, 5));
        // Every opaque texel of the surface quads lies within 0.45 voxel
        // of the sphere (0.24 when written: a plane per voxel, grown by an
        // eighth of a voxel, its corners off a curved surface; 0.40 since
        // the reach lets a texel whose line enters up to a quarter voxel
        // beyond the slab sit on its voxel's plane); the voxel faces' lie
        // up to a voxel deep.
        let worst = rs.iter().map(|r| (r - 0.6).abs()).fold(0.0f32, f32::max);
        assert!(
            worst <= 0.45 * surf.voxel,
            "worst |r − R| {worst}, voxel {}",
            surf.voxel
        );
        let (ms, mf) = (mean_off(&rs), mean_off(&rf));
        // Mean |r − R| 0.0054 vs 0.0375 when written (the sphere's density
        // ramp is 0.01 wide).
        assert!(
            ms * 4.0 < mf,
            "mean |r − R|: surface quads {ms}, voxel faces {mf}"
        );
        // Fewer quads, every one a parallelogram with a unit normal
        // facing out of the sphere (roughly: a voxel the surface crosses
        // along its axis from both sides has a quad for each side).
        assert!(surf.quads.len() < faces.quads.len());
        for q in &surf.quads {
            assert!((q.normal.length() - 1.0).abs() < 1e-4);
            assert!((q.normal + q.u.cross(q.v).normalize()).length() < 1e-4);
            let c = q.point(0.5, 0.5);
            let out = q.normal.dot((c - f.centre).normalize());
            assert!(out > -0.5, "inward quad at {c}: {out}");
        }
    }

    #[test]
    fn the_plane_depth_follows_the_accumulated_opacity() {
        // March inward from just outside the sphere along −x: the point
        // where ∫σ reaches −ln(1 − a) lies inside the density ramp
        // (r ∈ R ± 0.005), give or take one march step (h/16), and moves
        // inward as `a` grows.
        let f = Sphere::new(Vec3::ZERO, 0.6);
        let s = Surface::new(&f, 0.05);
        let x = Vec3::new(0.62, 0.0, 0.0);
        let depths: Vec<f32> = [0.05, 0.2, 0.5, 0.9]
            .iter()
            .map(|&a| opacity_depth(&s, x, -Vec3::X, 0.05, a).x)
            .collect();
        for w in depths.windows(2) {
            assert!(w[1] < w[0], "deeper opacity must sit deeper: {depths:?}");
        }
        for d in &depths {
            assert!(
                (d - 0.6).abs() <= 0.005 + 0.05 / 16.0,
                "outside the ramp: {depths:?}"
            );
        }
        // Never reached within 2h (an empty line): the start point.
        let far = Vec3::new(0.9, 0.0, 0.0);
        assert_eq!(opacity_depth(&s, far, -Vec3::X, 0.05, 0.2), far);
    }

    #[test]
    fn an_empty_field_has_no_geometry() {
        let f = Sphere::new(Vec3::ZERO, 0.0);
        assert!(extract(&Surface::new(&f, 0.5), 8, 3).is_none());
    }
}
