//! The visual hull as a fast point test.
//!
//! [`Silhouettes::inside`] projects a point into every view: bounding a
//! field's inside test by it at each of the tens of millions of lattice
//! points a bake at g = 256 classifies would cost more than the
//! classification. A coarse grid settles most points at once: a voxel
//! whose footprint (grown by the point test's whole window) is background
//! in some view holds no point of the hull, one whose footprint lies
//! inside the silhouette in every view holds only points of it, and only
//! the voxels between take the per-point test. Verdicts agree with
//! [`Silhouettes::inside`] by construction (tested below).

use glam::Vec3;
use rayon::prelude::*;

use super::{judge_sphere, Silhouettes, Verdict, MAX_GRID};
use crate::bake::Aabb;

/// What a lookup voxel says about its points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cell {
    /// Every point is outside the hull.
    Out,
    /// Every point is inside.
    In,
    /// Points differ: test each in the views of [`Open`] number `n`.
    Test(u32),
}

/// A voxel the footprints leave open: the views that must test its
/// points (`views[start..end]` of the lookup), and how many views have
/// all of it on the silhouette already.
#[derive(Debug, Clone, Copy)]
struct Open {
    start: usize,
    end: usize,
    seen: u32,
}

/// The visual hull of [`Silhouettes`] over a cube as a point test
/// ([`HullLookup::inside`] = [`Silhouettes::inside`]), settled voxel by
/// voxel on a grid where it can be.
pub struct HullLookup<'s> {
    sil: &'s Silhouettes,
    origin: Vec3,
    inv_voxel: f32,
    g: u32,
    cells: Vec<Cell>,
    open: Vec<Open>,
    views: Vec<usize>,
    min_seen: usize,
    /// After [`HullLookup::split_open`]: the eight half-size cells of
    /// each open voxel (indexed as `open`; x fastest, then y, then z).
    halves: Vec<[Cell; 8]>,
}

/// One z-slab of the lookup: its cells (open ones numbered within the
/// slab), open voxels (views numbered within the slab) and views.
type Slab = (Vec<Cell>, Vec<Open>, Vec<usize>);

/// Voxels per edge of a coarse voxel of the first level.
const FANOUT: u32 = 4;

/// What a voxel's parent on the coarse level says.
#[derive(Debug, Clone, Copy)]
enum Parent {
    /// No coarse level: judge in every view.
    All,
    /// Wholly outside.
    Out,
    /// Wholly inside.
    In,
    /// Open, with this many views that have it on the silhouette.
    Open(u32),
}

/// Judges a cell (bounding sphere `centre`, `radius`; footprint grown by
/// `margin` pixels) in the views `candidates`, `seen` views having it on
/// the silhouette already: [`Cell::Out`] when one view shows background
/// there, [`Cell::In`] when every view has it on the silhouette, else
/// [`Cell::Test`] with the views left to the point test appended to
/// `slab` (its opens and views).
fn judge_cell(
    sil: &Silhouettes,
    centre: Vec3,
    radius: f32,
    margin: f32,
    candidates: &[usize],
    mut seen: u32,
    slab: &mut Slab,
) -> Cell {
    let start = slab.2.len();
    for &vi in candidates {
        let (p, t) = (&sil.projs[vi], &sil.tables[vi]);
        match judge_sphere(p, t, centre, radius, margin) {
            Verdict::Background => {
                slab.2.truncate(start);
                return Cell::Out;
            }
            // Wholly in frame on the silhouette: every point's window is too.
            Verdict::Inside => seen += 1,
            Verdict::Object | Verdict::Unseen => slab.2.push(vi),
        }
    }
    if slab.2.len() == start && !sil.is_empty() {
        return Cell::In;
    }
    slab.1.push(Open {
        start,
        end: slab.2.len(),
        seen,
    });
    Cell::Test(slab.1.len() as u32 - 1)
}

impl<'s> HullLookup<'s> {
    /// The lookup over `cube` at `g`³ voxels (clamped to 1…[`MAX_GRID`]);
    /// points outside the cube take the per-point test.
    pub fn new(sil: &'s Silhouettes, cube: &Aabb, g: u32) -> Self {
        let g = g.clamp(1, MAX_GRID);
        let voxel = (cube.max - cube.min).max_element() / g as f32;
        let origin = cube.min;
        // A footprint grown by the point test's window holds every window
        // of the voxel's points (and a little more, against rounding).
        let margin = Self::margin(sil);
        let all: Vec<usize> = (0..sil.len()).collect();
        // Two levels: a voxel lies within its parent's bounding sphere, so
        // its footprint lies within the parent's, and only the views that
        // leave the parent open need judging it (lego at g = 128: judging
        // every voxel in all 100 views took most of the build).
        let coarse: Option<(usize, Slab)> = (g >= 2 * FANOUT).then(|| {
            let gp = g.div_ceil(FANOUT);
            let pv = voxel * FANOUT as f32;
            let level = Self::level(sil, origin, pv, gp, margin, |_| (Parent::All, &all[..]));
            (gp as usize, level)
        });
        let parent = |[i, j, k]: [usize; 3]| -> (Parent, &[usize]) {
            let Some((gp, (cells, open, views))) = &coarse else {
                return (Parent::All, &all[..]);
            };
            let f = FANOUT as usize;
            match cells[((k / f) * gp + j / f) * gp + i / f] {
                Cell::Out => (Parent::Out, &[]),
                Cell::In => (Parent::In, &[]),
                Cell::Test(n) => {
                    let o = open[n as usize];
                    let v = &views[o.start..o.end];
                    (Parent::Open(o.seen), v)
                }
            }
        };
        let gu = g as usize;
        let (cells, open, views) = Self::level(sil, origin, voxel, g, margin, parent);
        debug_assert_eq!(cells.len(), gu * gu * gu);
        Self {
            sil,
            origin,
            inv_voxel: 1.0 / voxel,
            g,
            cells,
            open,
            views,
            min_seen: sil.len().div_ceil(2).max(1),
            halves: Vec::new(),
        }
    }

    /// The footprint margin (pixels) of [`HullLookup::new`]: a footprint
    /// grown by the point test's window holds every window of the
    /// voxel's points (and a little more, against rounding).
    fn margin(sil: &Silhouettes) -> f32 {
        sil.window().extent() + 0.05
    }

    /// The `g`³ voxels' cells, each judged in the views its parent leaves
    /// open (`parent`: its verdict and those views), numbered in z-slabs.
    fn level<'v>(
        sil: &Silhouettes,
        origin: Vec3,
        voxel: f32,
        g: u32,
        margin: f32,
        parent: impl Fn([usize; 3]) -> (Parent, &'v [usize]) + Sync,
    ) -> Slab {
        let radius = 0.5 * 3f32.sqrt() * voxel;
        let gu = g as usize;
        let slabs: Vec<Slab> = (0..gu)
            .into_par_iter()
            .map(|k| {
                let mut slab: Slab = (Vec::with_capacity(gu * gu), Vec::new(), Vec::new());
                for ij in 0..gu * gu {
                    let (i, j) = (ij % gu, ij / gu);
                    let (verdict, candidates) = parent([i, j, k]);
                    let seen = match verdict {
                        Parent::Out => {
                            slab.0.push(Cell::Out);
                            continue;
                        }
                        Parent::In => {
                            slab.0.push(Cell::In);
                            continue;
                        }
                        Parent::Open(seen) => seen,
                        Parent::All => 0,
                    };
                    let centre = origin + voxel * (Vec3::new(i as f32, j as f32, k as f32) + 0.5);
                    let cell = judge_cell(sil, centre, radius, margin, candidates, seen, &mut slab);
                    slab.0.push(cell);
                }
                slab
            })
            .collect();
        let mut level: Slab = (Vec::with_capacity(gu * gu * gu), Vec::new(), Vec::new());
        for (cells, open, views) in slabs {
            let (o, v) = (level.1.len() as u32, level.2.len());
            level.0.extend(cells.into_iter().map(|c| match c {
                Cell::Test(n) => Cell::Test(n + o),
                c => c,
            }));
            level.1.extend(open.into_iter().map(|op| Open {
                start: op.start + v,
                end: op.end + v,
                seen: op.seen,
            }));
            level.2.extend(views);
        }
        level
    }

    /// Whether `x` is inside the visual hull ([`Silhouettes::inside`]).
    #[inline]
    pub fn inside(&self, x: Vec3) -> bool {
        let f = (x - self.origin) * self.inv_voxel;
        let g = self.g as f32;
        if !(f.min_element() >= 0.0 && f.max_element() < g) {
            return self.sil.inside(x);
        }
        let gu = self.g as usize;
        let (i, j, k) = (f.x as usize, f.y as usize, f.z as usize);
        match self.cells[(k * gu + j) * gu + i] {
            Cell::Out => false,
            Cell::In => true,
            Cell::Test(n) => {
                let n = match self.halves.get(n as usize) {
                    Some(half) => {
                        let b = |v: f32, i: usize| usize::from(v - i as f32 >= 0.5);
                        match half[b(f.x, i) | b(f.y, j) << 1 | b(f.z, k) << 2] {
                            Cell::Out => return false,
                            Cell::In => return true,
                            Cell::Test(m) => m,
                        }
                    }
                    None => n,
                };
                let o = self.open[n as usize];
                let views = &self.views[o.start..o.end];
                self.sil
                    .inside_views(x, views, o.seen as usize, self.min_seen)
            }
        }
    }

    /// Splits every open voxel into eight half-size cells, each judged in
    /// the views that leave its voxel open (as [`HullLookup::new`] judges
    /// voxels, so verdicts still agree with [`Silhouettes::inside`]): a
    /// point of an open voxel then takes the per-point test in its half's
    /// views only, and not at all where its half is settled. Best after
    /// [`HullLookup::settle_within`], which leaves few voxels open (lego
    /// at g = 128: a tenth); once only. Returns the halves left open.
    pub fn split_open(&mut self) -> u64 {
        if !self.halves.is_empty() || self.open.is_empty() || self.sil.is_empty() {
            return 0;
        }
        let sil = self.sil;
        let voxel = 1.0 / self.inv_voxel;
        let (origin, gu) = (self.origin, self.g as usize);
        let radius = 0.25 * 3f32.sqrt() * voxel;
        let margin = Self::margin(sil);
        let mut voxel_of = vec![usize::MAX; self.open.len()];
        for (c, cell) in self.cells.iter().enumerate() {
            if let Cell::Test(n) = *cell {
                voxel_of[n as usize] = c;
            }
        }
        let this = &*self;
        // Per open voxel: its halves (open ones numbered from 0) and their
        // opens and views, numbered from 0; renumbered when appended.
        let split: Vec<Slab> = voxel_of
            .par_iter()
            .enumerate()
            .map(|(n, &c)| {
                let mut out: Slab = (Vec::with_capacity(8), Vec::new(), Vec::new());
                if c == usize::MAX {
                    // Settled since (`settle_within`): never read.
                    out.0.resize(8, Cell::In);
                    return out;
                }
                let o = this.open[n];
                let ijk = Vec3::new(
                    (c % gu) as f32,
                    ((c / gu) % gu) as f32,
                    (c / (gu * gu)) as f32,
                );
                for h in 0..8 {
                    let off = Vec3::new((h & 1) as f32, ((h >> 1) & 1) as f32, (h >> 2) as f32);
                    let centre = origin + voxel * (ijk + 0.25 + 0.5 * off);
                    let views = &this.views[o.start..o.end];
                    let cell = judge_cell(sil, centre, radius, margin, views, o.seen, &mut out);
                    out.0.push(cell);
                }
                out
            })
            .collect();
        let mut halves = Vec::with_capacity(split.len());
        let mut left = 0;
        for (cells, open, views) in split {
            let (o, v) = (self.open.len() as u32, self.views.len());
            left += open.len() as u64;
            let mut half = [Cell::In; 8];
            for (h, c) in half.iter_mut().zip(cells) {
                *h = match c {
                    Cell::Test(m) => Cell::Test(m + o),
                    c => c,
                };
            }
            halves.push(half);
            self.open.extend(open.into_iter().map(|op| Open {
                start: op.start + v,
                end: op.end + v,
                seen: op.seen,
            }));
            self.views.extend(views);
        }
        self.halves = halves;
        left
    }

    /// Settles each open voxel where `matter` (e.g. a field's inside)
    /// stays within the hull at all 27 points of its half-voxel lattice:
    /// its points count as inside from then on. The lookup then bounds
    /// `matter` only where `matter` reaches past the hull by about half a
    /// voxel or more; finer excursions are left to a finer test (the
    /// texel carve). Returns how many voxels it settled.
    pub fn settle_within(&mut self, matter: impl Fn(Vec3) -> bool + Sync) -> u64 {
        let gu = self.g as usize;
        let half = 0.5 / self.inv_voxel;
        let origin = self.origin;
        let this = &*self;
        let settled: Vec<usize> = (0..this.cells.len())
            .into_par_iter()
            .filter(|&c| {
                if !matches!(this.cells[c], Cell::Test(_)) {
                    return false;
                }
                let (i, j, k) = (c % gu, (c / gu) % gu, c / (gu * gu));
                let lo = origin + 2.0 * half * Vec3::new(i as f32, j as f32, k as f32);
                (0..27).all(|n| {
                    let o = Vec3::new((n % 3) as f32, ((n / 3) % 3) as f32, (n / 9) as f32);
                    let x = lo + half * o;
                    !matter(x) || this.inside(x)
                })
            })
            .collect();
        for &c in &settled {
            self.cells[c] = Cell::In;
        }
        settled.len() as u64
    }

    /// Voxels settled outside, settled inside, and left to the point test.
    pub fn counts(&self) -> (u64, u64, u64) {
        let n = |f: fn(&Cell) -> bool| self.cells.iter().filter(|c| f(c)).count() as u64;
        (
            n(|c| *c == Cell::Out),
            n(|c| *c == Cell::In),
            n(|c| matches!(c, Cell::Test(_))),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::carve::tests::{silhouettes, sphere_views};

    /// Every verdict of the lookup is the point test's, at points spread
    /// over the cube and beyond it, for windows of several sizes, with and
    /// without another object's pixels in some views.
    #[test]
    fn lookup_agrees_with_the_point_test() {
        let cube = Aabb {
            min: Vec3::splat(-0.8),
            max: Vec3::splat(0.8),
        };
        for hidden in [&[][..], &[0, 1, 2, 3]] {
            let views = sphere_views(hidden);
            for (radius, g) in [(0.5, 7), (1.0, 12), (2.0, 7)] {
                let sil = silhouettes(&views, true).with_radius(radius);
                let mut lookup = HullLookup::new(&sil, &cube, g);
                let (out, inn, test) = lookup.counts();
                // At 64 px only coarse voxels lie wholly inside, and with
                // another object over the sphere none does.
                assert!(out > 0 && test > 0, "{out} {inn} {test}");
                assert_eq!(inn > 0, hidden.is_empty(), "{out} {inn} {test}");
                for split in [false, true] {
                    if split {
                        // Some halves settle (fewer than 8 per open voxel
                        // stay open), and the verdicts stay the same.
                        let left = lookup.split_open();
                        assert!(left > 0 && left < 8 * test, "{left} of {}", 8 * test);
                        assert_eq!(lookup.split_open(), 0, "once only");
                    }
                    let n = 49;
                    let mut inside = 0;
                    for k in 0..n {
                        for j in 0..n {
                            for i in 0..n {
                                let x = Vec3::new(i as f32, j as f32, k as f32) / (n - 1) as f32
                                    * 2.0
                                    - Vec3::splat(1.0);
                                assert_eq!(
                                    lookup.inside(x),
                                    sil.inside(x),
                                    "{x} at radius {radius}, split {split}"
                                );
                                inside += usize::from(sil.inside(x));
                            }
                        }
                    }
                    assert!(inside > 1000, "{inside}");
                }
            }
        }
    }

    /// Matter within the hull settles every open voxel; matter reaching
    /// past it keeps the voxels it leaves the hull in open, and the
    /// lookup still bounds it there.
    #[test]
    fn settling_keeps_the_bound_where_matter_leaves_the_hull() {
        let cube = Aabb {
            min: Vec3::splat(-0.8),
            max: Vec3::splat(0.8),
        };
        let views = sphere_views(&[]);
        let sil = silhouettes(&views, false).with_radius(1.0);
        // Matter a little inside the sphere: every open voxel settles.
        let mut within = HullLookup::new(&sil, &cube, 16);
        let open = within.counts().2;
        assert_eq!(within.settle_within(|x| x.length() < 0.45), open);
        assert_eq!(within.counts().2, 0);
        // Matter out to 0.7: the voxels across the sphere's surface stay
        // open, and the bounded matter ends at the hull.
        let mut past = HullLookup::new(&sil, &cube, 16);
        let matter = |x: Vec3| x.length() < 0.7;
        past.settle_within(matter);
        assert!(past.counts().2 > 0);
        // The halves of the voxels left open bound it the same way.
        assert!(past.split_open() > 0);
        for r in [0.3, 0.4, 0.55, 0.6, 0.65] {
            for d in [
                Vec3::X,
                Vec3::Y,
                Vec3::Z,
                Vec3::new(1.0, 1.0, 0.3).normalize(),
            ] {
                let x = r * d;
                assert_eq!(matter(x) && past.inside(x), sil.inside(x), "{x}");
            }
        }
    }
}
