//! Silhouette voxel carving (the visual hull on a g³ grid).
//!
//! A voxel survives if, in every view that sees it whole, its projected
//! footprint touches the object's silhouette, at least half of the views
//! see it (so the corners of the search box outside most frusta go), and
//! it passes a point test ([`VoxelTest`], by default: its centre projects
//! onto the silhouette in every view at once). The footprint is the square
//! around the projected centre that contains the projection of the voxel's
//! bounding sphere; that test alone is conservative (a voxel only goes when
//! some view shows background all around it) and cheap, so it runs first.
//! Views that see a voxel only partly (footprint crossing the image border)
//! or from inside its sphere say nothing about it.
//!
//! Shape finer than a voxel comes from the texels: [`texel_occupancy`]
//! empties the texels of thin voxels that lie outside the hull.
//!
//! In a multi-object capture, pixels of *other* objects (instance-mask
//! values other than 0 and the object's label) are **unknown**, not
//! background: the object may continue behind them, so they never carve.
//! A point projecting onto them counts as in frame but neither confirms
//! nor refutes matter; a voxel or quad footprint touching them is never
//! judged background. Views without such pixels (every view of a
//! single-object capture) take exactly the code path they took before.

use crate::rounding::{ceil, floor};
use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::quads::Quad;
use super::{Aabb, BakeView};

mod lookup;
pub use lookup::HullLookup;

/// Where objects of the NeRF-synthetic convention live: every object of the
/// dataset fits in [-1.5, 1.5]³ (lego spans about [-0.64, 0.64] ×
/// [-1.15, 0.97] × [-0.35, 1.0]).
pub const NERF_SYNTHETIC_BOX: Aabb = Aabb {
    min: Vec3::splat(-1.5),
    max: Vec3::splat(1.5),
};

/// Grid of the coarse carve that finds the object's cube.
pub const SEARCH_GRID: u32 = 96;

/// Largest grid the baker accepts (512³ voxels = 128 MiB of occupancy).
pub const MAX_GRID: u32 = 512;

/// A binary silhouette per view with a summed-area table, so the number of
/// foreground pixels in any rectangle costs four reads.
pub struct Silhouettes {
    tables: Vec<SummedArea>,
    projs: Vec<Proj>,
    /// Which pixels around a point's projection a view reads
    /// ([`Silhouettes::with_margin`], [`Silhouettes::with_radius`]).
    window: Window,
}

struct SummedArea {
    width: u32,
    height: u32,
    /// (width + 1) × (height + 1) prefix sums of the foreground indicator.
    sums: Vec<u32>,
    /// The foreground indicator itself, row-major.
    fg: Vec<bool>,
    /// Where the view shows another object (unknown, never carves), if it
    /// shows any: its indicator and the prefix sums of "foreground or
    /// unknown" (= not background).
    unknown: Option<Unknown>,
}

struct Unknown {
    /// Another object's pixel, row-major.
    px: Vec<bool>,
    /// (width + 1) × (height + 1) prefix sums of "not background".
    sums: Vec<u32>,
}

impl SummedArea {
    fn new(view: &BakeView<'_>) -> Self {
        let (w, h) = view.image.dimensions();
        let stride = w as usize + 1;
        let mut sums = vec![0u32; stride * (h as usize + 1)];
        let mut fg = vec![false; w as usize * h as usize];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                // Coverage ≥ 50 % is the object.
                let f = view.coverage(x, y) >= 128;
                fg[y as usize * w as usize + x as usize] = f;
                row += u32::from(f);
                let i = (y as usize + 1) * stride + x as usize + 1;
                sums[i] = sums[i - stride] + row;
            }
        }
        let unknown = Self::unknown_pixels(view, &fg);
        Self {
            width: w,
            height: h,
            sums,
            fg,
            unknown,
        }
    }

    /// The other objects' pixels of an instance-masked view (`None` when
    /// there are none).
    fn unknown_pixels(view: &BakeView<'_>, fg: &[bool]) -> Option<Unknown> {
        let super::Silhouette::Instance { mask, label } = view.silhouette else {
            return None;
        };
        let px: Vec<bool> = mask
            .as_raw()
            .iter()
            .zip(fg)
            .map(|(&m, &f)| !f && m != 0 && m != label)
            .collect();
        if !px.contains(&true) {
            return None;
        }
        let (w, h) = (mask.width() as usize, mask.height() as usize);
        let stride = w + 1;
        let mut sums = vec![0u32; stride * (h + 1)];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += u32::from(fg[y * w + x] || px[y * w + x]);
                let i = (y + 1) * stride + x + 1;
                sums[i] = sums[i - stride] + row;
            }
        }
        Some(Unknown { px, sums })
    }

    /// Foreground pixels in [x0, x1) × [y0, y1) (already clipped).
    #[inline]
    fn count(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> u32 {
        Self::rect(&self.sums, self.width, x0, y0, x1, y1)
    }

    /// Pixels that are not background (foreground or another object's)
    /// in [x0, x1) × [y0, y1).
    #[inline]
    fn count_not_background(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> u32 {
        match &self.unknown {
            None => self.count(x0, y0, x1, y1),
            Some(u) => Self::rect(&u.sums, self.width, x0, y0, x1, y1),
        }
    }

    /// Whether every pixel of [x0, x1) × [y0, y1) grown by `reach` on
    /// every side (clipped to the image) is background.
    #[inline]
    fn background_around(&self, x0: u32, y0: u32, x1: u32, y1: u32, reach: u32) -> bool {
        let (xa, ya) = (x0.saturating_sub(reach), y0.saturating_sub(reach));
        let xb = x1.saturating_add(reach).min(self.width);
        let yb = y1.saturating_add(reach).min(self.height);
        self.count_not_background(xa, ya, xb, yb) == 0
    }

    #[inline]
    fn rect(sums: &[u32], width: u32, x0: u32, y0: u32, x1: u32, y1: u32) -> u32 {
        let s = width as usize + 1;
        let at = |x: u32, y: u32| sums[y as usize * s + x as usize];
        at(x1, y1) + at(x0, y0) - at(x0, y1) - at(x1, y0)
    }

    /// Whether pixel `i` (row-major) shows another object.
    #[inline]
    fn is_unknown(&self, i: usize) -> bool {
        self.unknown.as_ref().is_some_and(|u| u.px[i])
    }
}

impl Silhouettes {
    /// Builds the tables of every view (in parallel).
    pub fn new(views: &[BakeView<'_>]) -> Self {
        Self {
            tables: views.par_iter().map(SummedArea::new).collect(),
            projs: views
                .iter()
                .map(|v| {
                    let k = &v.camera.intrinsics;
                    Proj {
                        w2c: v.camera.w2c(),
                        fx: k.fx,
                        fy: k.fy,
                        cx: k.cx,
                        cy: k.cy,
                        width: k.width as f32,
                        height: k.height as f32,
                    }
                })
                .collect(),
            window: Window::Margin(0),
        }
    }

    /// The same silhouettes, carving a point only where every pixel within
    /// `margin` pixels of its projection is background: a point on the
    /// surface at the silhouette's edge may project onto a background
    /// pixel by rounding alone, which costs little at 800 px but whole
    /// bars of a lattice at 96 px.
    pub fn with_margin(mut self, margin: u32) -> Self {
        self.window = Window::Margin(margin);
        self
    }

    /// The same silhouettes, carving a point only where every pixel whose
    /// centre lies within `radius` pixels of its projection (in x and in
    /// y) is background. A point on the silhouette's 50 % contour lies
    /// within 0.71 px of a foreground pixel's centre, so a radius of 1
    /// keeps the surface's points whatever their rounding and carves
    /// points more than ½ px outside the contour; the whole-pixel margin
    /// of 1 keeps them up to a pixel out, which shows as a one-pixel rim
    /// around the object in held-out views (lego (128, 17) +0.51 dB,
    /// `docs/baking.md`, "Session 23"). Below ½ a point's own pixel may
    /// fall out of the window, so the radius is at least ½ (and at most
    /// 64; NaN reads as ½).
    pub fn with_radius(mut self, radius: f32) -> Self {
        self.window = Window::Radius(radius.clamp(0.5, 64.0).max(0.5));
        self
    }

    /// How a view's pixels around a projection are read.
    fn window(&self) -> Window {
        self.window
    }

    /// Number of views.
    pub fn len(&self) -> usize {
        self.tables.len()
    }

    /// Whether there are no views.
    pub fn is_empty(&self) -> bool {
        self.tables.is_empty()
    }

    /// Whether a point is inside the visual hull: no view that has it in
    /// frame shows background at its pixel.
    #[inline]
    pub fn inside(&self, x: Vec3) -> bool {
        // Points that fewer than half of the views have in frame are not
        // evidence of matter (as for voxels).
        let min_seen = self.len().div_ceil(2).max(1);
        let mut seen = 0;
        for (p, t) in self.projs.iter().zip(&self.tables) {
            match point_in_view(p, t, x, self.window()) {
                PointInView::Background => return false,
                PointInView::Counts => seen += 1,
                PointInView::Silent => {}
            }
        }
        seen >= min_seen
    }
}

/// What one view says about a point.
enum PointInView {
    /// Behind the camera or out of frame: nothing.
    Silent,
    /// In frame on background: the point is outside the hull.
    Background,
    /// In frame on the silhouette or on another object's pixel (unknown):
    /// the view has the point in frame and does not carve it.
    Counts,
}

/// Which pixels around a projection [`point_in_view`] reads.
#[derive(Debug, Clone, Copy)]
enum Window {
    /// The pixel holding it and `n` more on every side (0: that pixel).
    Margin(u32),
    /// The pixels whose centres lie within this distance (pixels, per
    /// axis; at least ½).
    Radius(f32),
}

impl Window {
    /// Pixels a quad's box grows by so that it holds every window of its
    /// texels' projections.
    fn reach(self) -> u32 {
        match self {
            Window::Margin(n) => n,
            Window::Radius(r) => r.ceil() as u32,
        }
    }

    /// How far from a projection (pixels, per axis) the window's pixels
    /// reach, their edges included.
    fn extent(self) -> f32 {
        match self {
            Window::Margin(n) => n as f32 + 1.0,
            Window::Radius(r) => r + 0.5,
        }
    }
}

/// The one projection-and-lookup of a point in a view, shared by
/// [`Silhouettes::inside`] and `inside_views`.
#[inline]
fn point_in_view(p: &Proj, t: &SummedArea, x: Vec3, window: Window) -> PointInView {
    let c = p.w2c.transform_point3(x);
    let depth = -c.z;
    if depth <= 1e-4 {
        return PointInView::Silent;
    }
    let px = p.cx + p.fx * c.x / depth;
    let py = p.cy - p.fy * c.y / depth;
    if !(px >= 0.0 && py >= 0.0 && px < p.width && py < p.height) {
        return PointInView::Silent;
    }
    let (ix, iy) = (px as u32, py as u32);
    if let Window::Radius(r) = window {
        // Centres c + ½ within r of the projection: c in [x − ½ − r, x − ½ + r].
        let lo = |c: f32| ceil(c - 0.5 - r).max(0.0) as u32;
        let hi = |c: f32, n: u32| (floor(c - 0.5 + r) + 1.0).clamp(0.0, n as f32) as u32;
        let (x0, y0, x1, y1) = (lo(px), lo(py), hi(px, t.width), hi(py, t.height));
        return if x1 <= x0 || y1 <= y0 || t.count_not_background(x0, y0, x1, y1) == 0 {
            PointInView::Background
        } else {
            PointInView::Counts
        };
    }
    let margin = window.reach();
    if margin > 0 {
        let (x0, y0) = (ix.saturating_sub(margin), iy.saturating_sub(margin));
        let (x1, y1) = (
            ix.saturating_add(margin).saturating_add(1).min(t.width),
            iy.saturating_add(margin).saturating_add(1).min(t.height),
        );
        return if t.count_not_background(x0, y0, x1, y1) == 0 {
            PointInView::Background
        } else {
            PointInView::Counts
        };
    }
    let i = iy as usize * t.width as usize + ix as usize;
    // Another object's pixel: in frame, but says nothing.
    if !t.fg[i] && !t.is_unknown(i) {
        PointInView::Background
    } else {
        PointInView::Counts
    }
}

impl Silhouettes {
    /// [`Silhouettes::inside`] for a point already known to be on the
    /// silhouette in `known_seen` views: only the views in `views` are tested.
    #[inline]
    fn inside_views(&self, x: Vec3, views: &[usize], known_seen: usize, min_seen: usize) -> bool {
        let mut seen = known_seen;
        for &vi in views {
            let (p, t) = (&self.projs[vi], &self.tables[vi]);
            match point_in_view(p, t, x, self.window()) {
                PointInView::Background => return false,
                PointInView::Counts => seen += 1,
                PointInView::Silent => {}
            }
        }
        seen >= min_seen
    }
}

/// Where a voxel is relative to the visual hull, judged at 27 points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VoxelClass {
    /// No sample inside.
    Empty,
    /// Some samples inside, some outside: the hull's surface crosses it.
    Shell,
    /// Every sample inside.
    Full,
}

/// A g³ grid classified against the hull (see [`shell`]).
#[derive(Debug, Clone)]
pub struct ShellGrid {
    /// Voxels per edge.
    pub g: u32,
    /// World position of the grid's lower corner.
    pub origin: Vec3,
    /// Edge length of a voxel, world units.
    pub voxel: f32,
    /// Class of each voxel, x fastest, then y, then z.
    class: Vec<VoxelClass>,
}

impl ShellGrid {
    /// A grid from per-voxel classes (x fastest, then y, then z), for
    /// classifiers other than the hull's (e.g. a radiance field's opacity);
    /// `None` if `class` does not hold `g`³ entries.
    pub fn from_classes(g: u32, origin: Vec3, voxel: f32, class: Vec<VoxelClass>) -> Option<Self> {
        let n = (g as usize).checked_pow(3)?;
        (class.len() == n).then_some(Self {
            g,
            origin,
            voxel,
            class,
        })
    }

    /// The class of voxel (i, j, k); outside the grid is empty.
    #[inline]
    pub fn class(&self, i: i64, j: i64, k: i64) -> VoxelClass {
        let g = self.g as i64;
        if i < 0 || j < 0 || k < 0 || i >= g || j >= g || k >= g {
            return VoxelClass::Empty;
        }
        self.class[((k * g + j) * g + i) as usize]
    }

    /// The lower corner of voxel (i, j, k).
    #[inline]
    pub fn corner(&self, i: u32, j: u32, k: u32) -> Vec3 {
        self.origin + self.voxel * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// Number of voxels of a class.
    pub fn count(&self, c: VoxelClass) -> u64 {
        self.class.iter().filter(|&&v| v == c).count() as u64
    }
}

/// Classifies a `g`³ grid spanning `cube` by sampling the hull at 27 points
/// of each voxel (corners, edge midpoints, face centres, centre: a lattice of
/// half-voxel spacing). A voxel is [`VoxelClass::Shell`] when they disagree,
/// so parts down to about half a voxel thick are found. The footprint test
/// decides voxels wholly outside (or inside) the hull first, so only the
/// voxels near the surface are sampled.
pub fn shell(sil: &Silhouettes, cube: &Aabb, g: u32) -> ShellGrid {
    let g = g.clamp(1, MAX_GRID);
    let voxel = (cube.max - cube.min).max_element() / g as f32;
    let origin = cube.min;
    let radius = 0.5 * 3f32.sqrt() * voxel;
    let half = 0.5 * voxel;
    let gu = g as usize;
    let mut class = vec![VoxelClass::Empty; gu * gu * gu];
    class
        .par_chunks_mut(gu * gu)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..gu {
                for i in 0..gu {
                    let lo = origin + voxel * Vec3::new(i as f32, j as f32, k as f32);
                    // The footprint test settles most voxels at once: background
                    // in some view → empty; inside the silhouette in every
                    // view → full. Only the others are sampled point by point.
                    let mut all_inside = true;
                    let mut empty = false;
                    for (p, t) in sil.projs.iter().zip(&sil.tables) {
                        match judge(p, t, lo + Vec3::splat(half), radius) {
                            Verdict::Background => {
                                empty = true;
                                break;
                            }
                            Verdict::Inside => {}
                            Verdict::Object | Verdict::Unseen => all_inside = false,
                        }
                    }
                    slice[j * gu + i] = if empty {
                        VoxelClass::Empty
                    } else if all_inside {
                        VoxelClass::Full
                    } else {
                        let inside = (0..27)
                            .filter(|c| {
                                let o =
                                    Vec3::new((c % 3) as f32, ((c / 3) % 3) as f32, (c / 9) as f32);
                                sil.inside(lo + half * o)
                            })
                            .count();
                        match inside {
                            0 => VoxelClass::Empty,
                            27 => VoxelClass::Full,
                            _ => VoxelClass::Shell,
                        }
                    };
                }
            }
        });
    ShellGrid {
        g,
        origin,
        voxel,
        class,
    }
}

/// Texel occupancy of shell quads: a texel holds matter iff its point is
/// inside the visual hull. Each quad is first judged whole in every view
/// from the bounding box of its projection: a view showing only background
/// there empties the quad, views showing only silhouette there need no
/// per-texel test, so texels are tested only against the views where the
/// quad straddles the silhouette's edge.
pub fn texel_occupancy_hull(sil: &Silhouettes, quads: &[Quad], p: u32) -> Vec<bool> {
    let p = p.max(2);
    let mut occ = vec![true; quads.len() * (p * p) as usize];
    carve_texels(sil, quads, p, &mut occ);
    occ
}

/// Empties the texels of `opacity` (p² per quad, p ≥ 2, row-major) that
/// [`texel_occupancy_hull`] puts outside the hull: `opacity` AND it, with
/// only the opaque texels tested.
pub fn carve_texels(sil: &Silhouettes, quads: &[Quad], p: u32, opacity: &mut [bool]) {
    carve_texels_counted(sil, quads, p, opacity);
}

/// [`carve_texels`], returning how many (block, view) pairs its blocks
/// settled and how many they left to the texels' own tests.
fn carve_texels_counted(
    sil: &Silhouettes,
    quads: &[Quad],
    p: u32,
    opacity: &mut [bool],
) -> (u64, u64) {
    let p = p.max(2) as usize;
    let step = 1.0 / (p - 1) as f32;
    let min_seen = sil.len().div_ceil(2).max(1);
    let cuts = block_cuts(p);
    let carve_one = |sc: &mut CarveScratch, group: &[Verdict], cell: &mut [bool], q: &Quad| {
        let mut blocks = (0u64, 0u64);
        if !cell.contains(&true) {
            return blocks;
        }
        sc.edge_views.clear();
        let mut seen = 0;
        for (vi, (pr, t)) in sil.projs.iter().zip(&sil.tables).enumerate() {
            let verdict = match group.get(vi) {
                Some(Verdict::Inside) => QuadVerdict::Inside,
                Some(Verdict::Background) => QuadVerdict::Background,
                _ => judge_quad(pr, t, q, sil.window()),
            };
            match verdict {
                QuadVerdict::Background => {
                    cell.fill(false); // all texels empty
                    return blocks;
                }
                QuadVerdict::Inside => seen += 1,
                QuadVerdict::Edge => sc.edge_views.push(vi),
            }
        }
        let point = |tx: usize, ty: usize| q.point(tx as f32 * step, ty as f32 * step);
        if q.twist != Vec3::ZERO {
            // Not a parallelogram: no block holds its texels' points
            // within its corners' hull. Texel by texel.
            for ty in 0..p {
                for tx in 0..p {
                    let o = &mut cell[ty * p + tx];
                    if *o {
                        *o = sil.inside_views(point(tx, ty), &sc.edge_views, seen, min_seen);
                    }
                }
            }
            return blocks;
        }
        // In each straddling view, blocks of texels first (their points
        // lie within the hull of the block's corner texels' projections):
        // a block wholly on the silhouette or the background there
        // settles its texels in that view; the others test texel by
        // texel. Per texel the same verdicts as testing it in every
        // straddling view (`Silhouettes::inside_views`): any background
        // empties it, else it needs `min_seen` views.
        let nc = cuts.len();
        sc.seen.clear();
        sc.seen.resize(p * p, seen as u32);
        sc.corner.resize(nc * nc, None);
        for &vi in &sc.edge_views {
            let (pr, t) = (&sil.projs[vi], &sil.tables[vi]);
            for (cb, &cy) in cuts.iter().enumerate() {
                for (ca, &cx) in cuts.iter().enumerate() {
                    sc.corner[cb * nc + ca] = project(pr, point(cx, cy));
                }
            }
            for b in 0..nc - 1 {
                let ys = cuts[b]..if b + 2 == nc { p } else { cuts[b + 1] };
                for a in 0..nc - 1 {
                    let xs = cuts[a]..if a + 2 == nc { p } else { cuts[a + 1] };
                    let alive = ys
                        .clone()
                        .any(|ty| cell[ty * p + xs.start..ty * p + xs.end].contains(&true));
                    if !alive {
                        continue;
                    }
                    let c = [
                        sc.corner[b * nc + a],
                        sc.corner[b * nc + a + 1],
                        sc.corner[(b + 1) * nc + a],
                        sc.corner[(b + 1) * nc + a + 1],
                    ];
                    let verdict = judge_block(pr, t, c, sil.window());
                    match verdict {
                        QuadVerdict::Edge => blocks.1 += 1,
                        _ => blocks.0 += 1,
                    }
                    for ty in ys.clone() {
                        for tx in xs.clone() {
                            let i = ty * p + tx;
                            if !cell[i] {
                                continue;
                            }
                            let v = match verdict {
                                QuadVerdict::Background => PointInView::Background,
                                QuadVerdict::Inside => PointInView::Counts,
                                QuadVerdict::Edge => {
                                    point_in_view(pr, t, point(tx, ty), sil.window())
                                }
                            };
                            match v {
                                PointInView::Background => cell[i] = false,
                                PointInView::Counts => sc.seen[i] += 1,
                                PointInView::Silent => {}
                            }
                        }
                    }
                }
            }
        }
        for (o, &n) in cell.iter_mut().zip(&sc.seen) {
            *o = *o && n as usize >= min_seen;
        }
        blocks
    };
    // Consecutive quads (neighbours in the extraction's scan order) are
    // judged together first, in each view, by their bounding sphere: a
    // footprint wholly on the silhouette, or wholly background, in frame,
    // is each quad's verdict there too (most quads lie inside most views'
    // silhouettes), so only the other views judge quad by quad.
    opacity
        .par_chunks_mut(p * p * QUAD_GROUP)
        .zip(quads.par_chunks(QUAD_GROUP))
        .map_init(
            || (CarveScratch::default(), Vec::new()),
            |(sc, group), (cells, qs)| {
                group.clear();
                if let Some(corners) = bounding_box(qs) {
                    let reach = sil.window().reach();
                    group.extend(
                        sil.projs
                            .iter()
                            .zip(&sil.tables)
                            .map(|(pr, t)| judge_box(pr, t, &corners, reach)),
                    );
                }
                cells
                    .chunks_mut(p * p)
                    .zip(qs)
                    .map(|(cell, q)| carve_one(sc, group, cell, q))
                    .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
            },
        )
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Quads [`carve_texels`] judges together first.
const QUAD_GROUP: usize = 8;

/// The eight corners of the box around every corner of `quads` (`None`
/// if a corner is not finite).
fn bounding_box(quads: &[Quad]) -> Option<[Vec3; 8]> {
    let (lo, hi) = quads
        .iter()
        .flat_map(|q| q.corners())
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), c| {
            (lo.min(c), hi.max(c))
        });
    (lo.is_finite() && hi.is_finite()).then(|| {
        std::array::from_fn(|k| {
            Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        })
    })
}

/// What one view says of every quad within a box (its eight `corners`;
/// the quads' points project into the hull of the corners' projections):
/// [`Verdict::Inside`] when it is each such quad's [`judge_quad`] verdict
/// [`QuadVerdict::Inside`] (the pixels under the box all foreground, in
/// frame), [`Verdict::Background`] when it is each one's
/// [`QuadVerdict::Background`] (every pixel within `reach` of them
/// background, in frame), else [`Verdict::Object`] (judge quad by quad);
/// see [`judge_projected`].
fn judge_box(p: &Proj, t: &SummedArea, corners: &[Vec3; 8], reach: u32) -> Verdict {
    // `judge_quad`'s Inside needs foreground, not another object's pixels.
    match judge_projected(p, t, corners.iter().map(|&c| project(p, c)), reach, false) {
        Footprint::Inside => Verdict::Inside,
        Footprint::Background => Verdict::Background,
        Footprint::Mixed => Verdict::Object,
    }
}

/// What every point projecting into the hull of `points` (pixels; `None`:
/// too near the camera) shows in a view: [`Footprint::Inside`] when every
/// point is in frame and its pixel on the silhouette (foreground, or with
/// `others` another object's pixel too), [`Footprint::Background`] when
/// every point is in frame and every pixel within `reach` of it is
/// background. The box is grown by a pixel beyond what exact arithmetic
/// needs, so a point's own rounding cannot carry it out.
fn judge_projected(
    p: &Proj,
    t: &SummedArea,
    points: impl IntoIterator<Item = Option<(f32, f32)>>,
    reach: u32,
    others: bool,
) -> Footprint {
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for c in points {
        let Some((px, py)) = c else {
            return Footprint::Mixed;
        };
        x0 = x0.min(px);
        x1 = x1.max(px);
        y0 = y0.min(py);
        y1 = y1.max(py);
    }
    // Every point in frame, a pixel to spare.
    if !(x0 >= 1.0 && y0 >= 1.0 && x1 + 1.0 < p.width && y1 + 1.0 < p.height) {
        return Footprint::Mixed;
    }
    // The pixels holding the points: [xa, xb) × [ya, yb).
    let (xa, ya) = (floor(x0) as u32 - 1, floor(y0) as u32 - 1);
    let (xb, yb) = (
        (floor(x1) as u32 + 2).min(t.width),
        (floor(y1) as u32 + 2).min(t.height),
    );
    let on = match others {
        true => t.count_not_background(xa, ya, xb, yb),
        false => t.count(xa, ya, xb, yb),
    };
    if on == (xb - xa) * (yb - ya) {
        return Footprint::Inside;
    }
    if t.background_around(xa, ya, xb, yb, reach) {
        Footprint::Background
    } else {
        Footprint::Mixed
    }
}

/// [`judge_projected`]'s answer.
enum Footprint {
    Inside,
    Background,
    Mixed,
}

/// Working memory of [`carve_texels`], one per rayon job.
#[derive(Default)]
struct CarveScratch {
    /// The views a quad straddles the silhouette's edge in.
    edge_views: Vec<usize>,
    /// Per texel, the views it is on the silhouette in.
    seen: Vec<u32>,
    /// The block corners' projections in the current view.
    corner: Vec<Option<(f32, f32)>>,
}

/// Texels per block edge of [`carve_texels`]' blocks (about).
const BLOCK_TEXELS: usize = 4;

/// The texel indices (along one side of a p-texel patch, p ≥ 2) where
/// [`carve_texels`]' blocks have their corners: 0 first, p − 1 last.
/// Block `a` holds the texels from cut `a` up to cut `a + 1`, the last
/// one's included for the last block.
fn block_cuts(p: usize) -> Vec<usize> {
    let n = (p - 1).div_ceil(BLOCK_TEXELS).max(1);
    (0..=n).map(|k| k * (p - 1) / n).collect()
}

/// Where `x` projects in a view (pixels), if at least 10⁻³ in front of
/// the camera and finite: the same operations as [`point_in_view`]'s.
/// (A NaN corner must not drop out of a box's `min`/`max`.)
#[inline]
fn project(p: &Proj, x: Vec3) -> Option<(f32, f32)> {
    let c = p.w2c.transform_point3(x);
    let depth = -c.z;
    if depth.is_nan() || depth <= 1e-3 {
        return None;
    }
    let (px, py) = (p.cx + p.fx * c.x / depth, p.cy - p.fy * c.y / depth);
    (px.is_finite() && py.is_finite()).then_some((px, py))
}

/// What one view says about every point of a block of texels, from its
/// four corner points' projections (the block a parallelogram, so its
/// points project into their hull): [`QuadVerdict::Inside`] when every
/// point's pixel is in frame and not background, so each point's window
/// counts; [`QuadVerdict::Background`] when every point is in frame and
/// its whole window background: [`point_in_view`]'s verdicts (see
/// [`judge_projected`]).
fn judge_block(
    p: &Proj,
    t: &SummedArea,
    corners: [Option<(f32, f32)>; 4],
    window: Window,
) -> QuadVerdict {
    // A point on another object's pixel counts too (`point_in_view`).
    match judge_projected(p, t, corners, window.reach(), true) {
        Footprint::Inside => QuadVerdict::Inside,
        Footprint::Background => QuadVerdict::Background,
        Footprint::Mixed => QuadVerdict::Edge,
    }
}

/// What one view says about a whole quad.
enum QuadVerdict {
    /// Only background around the quad's projection.
    Background,
    /// Only silhouette around it.
    Inside,
    /// Both, or the quad is not wholly in frame: test texel by texel.
    Edge,
}

fn judge_quad(p: &Proj, t: &SummedArea, q: &Quad, window: Window) -> QuadVerdict {
    let margin = window.reach();
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for c in q.corners() {
        let v = p.w2c.transform_point3(c);
        let depth = -v.z;
        if depth <= 1e-4 {
            return QuadVerdict::Edge;
        }
        let px = p.cx + p.fx * v.x / depth;
        let py = p.cy - p.fy * v.y / depth;
        x0 = x0.min(px);
        x1 = x1.max(px);
        y0 = y0.min(py);
        y1 = y1.max(py);
    }
    // Pixels whose centre-lookup a texel point may hit: floor of the box.
    if x0 < 0.0 || y0 < 0.0 || x1 >= p.width || y1 >= p.height {
        return QuadVerdict::Edge;
    }
    let (xa, ya) = (floor(x0) as u32, floor(y0) as u32);
    let (xb, yb) = (
        (floor(x1) as u32 + 1).min(t.width),
        (floor(y1) as u32 + 1).min(t.height),
    );
    let count = t.count(xa, ya, xb, yb);
    if t.background_around(xa, ya, xb, yb, margin) {
        QuadVerdict::Background
    } else if count == (xb - xa) * (yb - ya) {
        QuadVerdict::Inside
    } else {
        QuadVerdict::Edge
    }
}

/// The carved occupancy of a g³ grid over a cube.
#[derive(Debug, Clone)]
pub struct Grid {
    /// Voxels per edge.
    pub g: u32,
    /// World position of the grid's lower corner.
    pub origin: Vec3,
    /// Edge length of a voxel, world units.
    pub voxel: f32,
    /// Occupancy, x fastest, then y, then z.
    occ: Vec<bool>,
}

impl Grid {
    /// Whether voxel (i, j, k) is occupied; outside the grid is empty.
    #[inline]
    pub fn occupied(&self, i: i64, j: i64, k: i64) -> bool {
        let g = self.g as i64;
        if i < 0 || j < 0 || k < 0 || i >= g || j >= g || k >= g {
            return false;
        }
        self.occ[((k * g + j) * g + i) as usize]
    }

    /// Number of occupied voxels.
    pub fn occupied_count(&self) -> u64 {
        self.occ.iter().filter(|&&o| o).count() as u64
    }

    /// The lower corner of voxel (i, j, k).
    #[inline]
    pub fn corner(&self, i: u32, j: u32, k: u32) -> Vec3 {
        self.origin + self.voxel * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// The box of the occupied voxels, if any.
    pub fn occupied_bounds(&self) -> Option<Aabb> {
        let g = self.g as usize;
        let mut lo = [usize::MAX; 3];
        let mut hi = [0usize; 3];
        for (n, _) in self.occ.iter().enumerate().filter(|(_, &o)| o) {
            let c = [n % g, (n / g) % g, n / (g * g)];
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a] + 1);
            }
        }
        (lo[0] != usize::MAX).then(|| Aabb {
            min: self.origin + self.voxel * Vec3::new(lo[0] as f32, lo[1] as f32, lo[2] as f32),
            max: self.origin + self.voxel * Vec3::new(hi[0] as f32, hi[1] as f32, hi[2] as f32),
        })
    }
}

/// Per-view projection constants for the carving loop.
struct Proj {
    w2c: Mat4,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: f32,
    height: f32,
}

/// Carves a `g`³ grid spanning `cube` with every view's silhouette,
/// keeping the voxels that pass `test`.
pub fn carve(sil: &Silhouettes, cube: &Aabb, g: u32, test: VoxelTest) -> Grid {
    let g = g.clamp(1, MAX_GRID);
    let voxel = (cube.max - cube.min).max_element() / g as f32;
    let origin = cube.min;
    let projs = &sil.projs;
    // Radius of the voxel's bounding sphere.
    let radius = 0.5 * 3f32.sqrt() * voxel;
    // A voxel must be seen by at least half of the views: space outside
    // most frusta (the corners of the search box) is not evidence of matter.
    let min_seen = sil.len().div_ceil(2).max(1);
    let gu = g as usize;
    let mut occ = vec![false; gu * gu * gu];
    occ.par_chunks_mut(gu * gu)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..gu {
                for i in 0..gu {
                    let centre =
                        origin + voxel * Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5);
                    let mut seen = 0usize;
                    let mut keep = true;
                    for (p, t) in projs.iter().zip(&sil.tables) {
                        match judge(p, t, centre, radius) {
                            Verdict::Background => {
                                keep = false;
                                break;
                            }
                            Verdict::Object | Verdict::Inside => seen += 1,
                            Verdict::Unseen => {}
                        }
                    }
                    slice[j * gu + i] = keep
                        && seen >= min_seen
                        && point_test(
                            sil,
                            origin + voxel * Vec3::new(i as f32, j as f32, k as f32),
                            voxel,
                            test,
                        );
                }
            }
        });
    Grid {
        g,
        origin,
        voxel,
        occ,
    }
}

/// Sub-samples per voxel edge of [`VoxelTest::AnyPoint`].
pub const SUBSAMPLES: u32 = 4;

/// Which voxels survive carving (all three first pass the conservative
/// footprint test, which is cheap and rejects most empty space).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VoxelTest {
    /// The voxel's centre projects onto the silhouette in every view: the
    /// surface is off by at most half a voxel either way (the default; it
    /// measured best on lego and chair at g = 16 and 128, see
    /// `docs/baking.md`).
    #[default]
    Centre,
    /// Some point of a 4×4×4 lattice in the voxel does: parts down to a
    /// quarter voxel survive, but the hull grows by up to a voxel.
    AnyPoint,
    /// Only the footprint test: the voxel's projected bounding square
    /// touches the silhouette in every view (most conservative, fattest).
    Footprint,
}

/// The exact part of the voxel test that follows the footprint test.
fn point_test(sil: &Silhouettes, lo: Vec3, voxel: f32, test: VoxelTest) -> bool {
    match test {
        VoxelTest::Footprint => true,
        VoxelTest::Centre => sil.inside(lo + Vec3::splat(0.5 * voxel)),
        VoxelTest::AnyPoint => {
            if sil.inside(lo + Vec3::splat(0.5 * voxel)) {
                return true;
            }
            let n = SUBSAMPLES;
            let step = voxel / n as f32;
            (0..n * n * n).any(|m| {
                let (a, b, c) = (m % n, (m / n) % n, m / (n * n));
                sil.inside(lo + step * Vec3::new(a as f32 + 0.5, b as f32 + 0.5, c as f32 + 0.5))
            })
        }
    }
}

/// What one view says about a voxel.
enum Verdict {
    /// Its footprint shows only background: carve it.
    Background,
    /// Its footprint touches the silhouette.
    Object,
    /// Its footprint lies wholly inside the silhouette.
    Inside,
    /// The view does not see it whole (outside or across the image border,
    /// or the camera inside its bounding sphere).
    Unseen,
}

/// One view's verdict on a voxel (centre, bounding-sphere radius): its
/// footprint a square of half-size f·r/(d − r) grown by a pixel. Off the
/// optical axis that square falls a little short of the sphere's
/// projection (about 3 % of its size at 0.25 rad, well inside the pixel
/// it is grown by), so it is kept for the carves whose output it
/// defines; [`judge_sphere`] is the exact one.
#[inline]
fn judge(p: &Proj, table: &SummedArea, centre: Vec3, radius: f32) -> Verdict {
    let c = p.w2c.transform_point3(centre);
    let depth = -c.z;
    if depth - radius <= 1e-4 {
        return Verdict::Unseen;
    }
    let px = p.cx + p.fx * c.x / depth;
    let py = p.cy - p.fy * c.y / depth;
    let rx = p.fx * radius / (depth - radius) + 1.0;
    let ry = p.fy * radius / (depth - radius) + 1.0;
    judge_rect(p, table, (px - rx, px + rx, py - ry, py + ry))
}

/// One view's verdict on every point within a sphere and within `margin`
/// pixels of its projection: the exact bounding rectangle of the
/// sphere's projection ([`sphere_rect`]) grown by `margin` on every side.
#[inline]
fn judge_sphere(p: &Proj, table: &SummedArea, centre: Vec3, radius: f32, margin: f32) -> Verdict {
    match sphere_rect(p, centre, radius) {
        Some((x0, x1, y0, y1)) => judge_rect(
            p,
            table,
            (x0 - margin, x1 + margin, y0 - margin, y1 + margin),
        ),
        None => Verdict::Unseen,
    }
}

/// The bounding rectangle `(x0, x1, y0, y1)` (pixels) of a sphere's
/// projection, `None` unless the sphere lies more than 10⁻⁴ in front of
/// the camera. Exact off the optical axis too: the extreme slopes x/d of
/// its points are those of the two planes through the camera's y axis
/// tangent to it, t = (x·d ± r·√(x² + d² − r²)) / (d² − r²) for a centre
/// at (x, d), and likewise in y.
#[inline]
fn sphere_rect(p: &Proj, centre: Vec3, radius: f32) -> Option<(f32, f32, f32, f32)> {
    let c = p.w2c.transform_point3(centre);
    let depth = -c.z;
    if depth.is_nan() || depth - radius <= 1e-4 {
        return None;
    }
    let den = (depth - radius) * (depth + radius);
    let slopes = |x: f32| {
        let mid = x * depth;
        let half = radius * (den + x * x).sqrt();
        ((mid - half) / den, (mid + half) / den)
    };
    let (tx0, tx1) = slopes(c.x);
    let (ty0, ty1) = slopes(c.y);
    let rect = (
        p.cx + p.fx * tx0,
        p.cx + p.fx * tx1,
        p.cy - p.fy * ty1,
        p.cy - p.fy * ty0,
    );
    [rect.0, rect.1, rect.2, rect.3]
        .iter()
        .all(|v| v.is_finite())
        .then_some(rect)
}

/// One view's verdict on a footprint rectangle `(x0, x1, y0, y1)`
/// (pixels).
#[inline]
fn judge_rect(p: &Proj, table: &SummedArea, (x0, x1, y0, y1): (f32, f32, f32, f32)) -> Verdict {
    if x1 <= 0.0 || y1 <= 0.0 || x0 >= p.width || y0 >= p.height {
        return Verdict::Unseen;
    }
    let clipped = x0 < 0.0 || y0 < 0.0 || x1 > p.width || y1 > p.height;
    let xa = floor(x0.max(0.0)) as u32;
    let ya = floor(y0.max(0.0)) as u32;
    let xb = (ceil(x1.min(p.width)) as u32).min(table.width);
    let yb = (ceil(y1.min(p.height)) as u32).min(table.height);
    if xa >= xb || ya >= yb {
        return Verdict::Unseen;
    }
    let count = table.count(xa, ya, xb, yb);
    if count == (xb - xa) * (yb - ya) && !clipped {
        Verdict::Inside
    } else if count > 0 {
        Verdict::Object
    } else if clipped || table.count_not_background(xa, ya, xb, yb) > 0 {
        // Partly out of frame, or hidden behind another object: unknown.
        Verdict::Unseen
    } else {
        Verdict::Background
    }
}

/// The object's cube: the bounding cube of a coarse ([`SEARCH_GRID`]³)
/// conservative carve of `search`, so the g voxels of the bake span the
/// object rather than the whole search box. `None` if nothing survives.
pub fn object_cube(sil: &Silhouettes, search: &Aabb) -> Option<Aabb> {
    let coarse = carve(sil, &search.cube(), SEARCH_GRID, VoxelTest::Footprint);
    let b = coarse.occupied_bounds()?;
    // A little margin keeps surface voxels off the grid border.
    Some(b.cube().grown(0.5 * coarse.voxel))
}

/// Which texels of each quad's p×p patch hold matter (row-major per quad,
/// quad after quad).
///
/// Quads lie on voxel faces, so part of a boundary voxel's face may be
/// outside the visual hull; MobileNeRF shows such sub-voxel shape with
/// empty (discarded) texels. A texel is empty when its point and every
/// point behind it through its own voxel (along the inward normal, one
/// sample per texel spacing) are outside the hull, and the voxel behind
/// is empty — so looking through an empty texel shows what is behind the
/// voxel, never the inside of a solid region (which has no quads).
pub fn texel_occupancy(sil: &Silhouettes, grid: &Grid, quads: &[Quad], p: u32) -> Vec<bool> {
    let p = p.max(2) as usize;
    let mut occ = vec![true; quads.len() * p * p];
    let step = 1.0 / (p - 1) as f32;
    occ.par_chunks_mut(p * p)
        .zip(quads.par_iter())
        .for_each(|(cell, q)| {
            let v = q.voxel.map(i64::from);
            let behind = [
                v[0] - q.normal.x as i64,
                v[1] - q.normal.y as i64,
                v[2] - q.normal.z as i64,
            ];
            if grid.occupied(behind[0], behind[1], behind[2]) {
                return; // a solid region: keep every texel
            }
            let inward = -q.normal * grid.voxel;
            for ty in 0..p {
                for tx in 0..p {
                    let x = q.point(tx as f32 * step, ty as f32 * step);
                    // Samples at depth 0, 1/(p−1), …, 1 of the voxel.
                    let matter = (0..p).any(|d| sil.inside(x + (d as f32 * step) * inward));
                    cell[ty * p + tx] = matter;
                }
            }
        });
    occ
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::bake::{BakeView, Silhouette};
    use crate::camera::{Camera, Intrinsics};
    use image::{GrayImage, Luma, Rgba, RgbaImage};

    const R: f32 = 0.5;

    /// Views of a sphere of radius `R` at the origin: image (alpha =
    /// sphere), instance mask (1 = sphere). In the views listed in
    /// `hidden`, another object (label 2) covers the sphere's pixels whose
    /// surface point is below z = −0.15, as an object in front would.
    pub(crate) fn sphere_views(hidden: &[usize]) -> Vec<(Camera, RgbaImage, GrayImage)> {
        let k = Intrinsics::from_fov_x(40f32.to_radians(), 64, 64);
        (0..12)
            .map(|i| {
                let el = [-30.0, 0.0, 30.0][i % 3];
                let cam = Camera::orbit(i as f32 * 30.0, el, 3.0, Vec3::ZERO, k);
                let mut img = RgbaImage::new(64, 64);
                let mut mask = GrayImage::new(64, 64);
                for (x, y, px) in img.enumerate_pixels_mut() {
                    let (o, d) = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                    let b = o.dot(d);
                    let disc = b * b - (o.length_squared() - R * R);
                    if disc < 0.0 {
                        continue;
                    }
                    let hit = o + (-b - disc.sqrt()) * d;
                    *px = Rgba([200, 100, 50, 255]);
                    let label = if hidden.contains(&i) && hit.z < -0.15 {
                        2
                    } else {
                        1
                    };
                    mask.put_pixel(x, y, Luma([label]));
                }
                (cam, img, mask)
            })
            .collect()
    }

    pub(crate) fn silhouettes(
        views: &[(Camera, RgbaImage, GrayImage)],
        instance: bool,
    ) -> Silhouettes {
        let bv: Vec<BakeView<'_>> = views
            .iter()
            .map(|(camera, image, mask)| BakeView {
                camera: *camera,
                image,
                silhouette: if instance {
                    Silhouette::Instance { mask, label: 1 }
                } else {
                    Silhouette::Alpha
                },
            })
            .collect();
        Silhouettes::new(&bv)
    }

    /// The footprint the hull lookup judges by holds every point of its
    /// sphere, off the optical axis too, and no more than it must.
    #[test]
    fn sphere_rect_is_the_exact_bounds_of_the_projection() {
        let p = Proj {
            w2c: Mat4::IDENTITY,
            fx: 400.0,
            fy: 380.0,
            cx: 400.0,
            cy: 410.0,
            width: 800.0,
            height: 800.0,
        };
        let n = 4000;
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let mut worst_short = 0f32;
        for (ax, ay, d, r) in [
            (0.0, 0.0, 3.0, 0.05),
            (0.25, 0.0, 3.0, 0.02),
            (0.6, -0.4, 2.0, 0.3),
            (-0.7, 0.7, 1.0, 0.3),
            (0.9, 0.1, 4.0, 1.2),
        ] {
            let centre = Vec3::new(ax * d, ay * d, -d);
            let (x0, x1, y0, y1) = sphere_rect(&p, centre, r).expect("in front");
            let mut seen = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
            for k in 0..n {
                let z = 1.0 - 2.0 * (k as f32 + 0.5) / n as f32;
                let (s, a) = ((1.0 - z * z).sqrt(), golden * k as f32);
                let q = centre + r * Vec3::new(s * a.cos(), s * a.sin(), z);
                let (px, py) = project(&p, q).expect("in front");
                let tol = 1e-3 * (1.0 + px.abs().max(py.abs()));
                assert!(
                    px >= x0 - tol && px <= x1 + tol,
                    "x {px} outside [{x0}, {x1}]"
                );
                assert!(
                    py >= y0 - tol && py <= y1 + tol,
                    "y {py} outside [{y0}, {y1}]"
                );
                seen = (
                    seen.0.min(px),
                    seen.1.max(px),
                    seen.2.min(py),
                    seen.3.max(py),
                );
            }
            // Tight: the samples reach each edge to within their spacing.
            let size = (x1 - x0).max(y1 - y0);
            for gap in [seen.0 - x0, x1 - seen.1, seen.2 - y0, y1 - seen.3] {
                assert!(gap < 0.02 * size, "gap {gap} of {size}");
            }
            // The old square f·r/(d − r) about the centre's projection.
            let half = p.fx * r / (d - r);
            let px = p.cx + p.fx * centre.x / d;
            worst_short = worst_short.max((x1 - (px + half)).max((px - half) - x0));
        }
        // Off axis the square falls short of the exact bounds (why the
        // lookup does not use it).
        assert!(worst_short > 0.0);
        // Behind or around the camera: no rectangle.
        assert!(sphere_rect(&p, Vec3::new(0.0, 0.0, -0.5), 0.5).is_none());
        assert!(sphere_rect(&p, Vec3::new(f32::NAN, 0.0, -3.0), 0.1).is_none());
    }

    #[test]
    fn a_part_hidden_behind_another_object_survives_carving() {
        let views = sphere_views(&[0, 1, 2, 3]);
        let sil = silhouettes(&views, true);
        assert!(sil.tables[0].unknown.is_some());
        assert!(sil.tables[5].unknown.is_none());
        // The sphere's lower part, hidden in views 0–3, is still inside…
        let low = Vec3::new(0.0, 0.0, -0.4);
        assert!(sil.inside(low));
        // …and space outside the sphere is still carved by the other views.
        assert!(!sil.inside(Vec3::new(0.0, 0.0, -0.7)));
        assert!(!sil.inside(Vec3::new(0.45, 0.45, -0.4)));
        // Were other objects' pixels background, the lower part would go.
        let views_as_bg: Vec<_> = views
            .iter()
            .map(|(c, img, m)| {
                let mut img = img.clone();
                for (p, l) in img.pixels_mut().zip(m.pixels()) {
                    if l.0[0] == 2 {
                        p.0 = [0; 4];
                    }
                }
                (*c, img, m.clone())
            })
            .collect();
        assert!(!silhouettes(&views_as_bg, false).inside(low));

        // The voxel grid keeps it too: a voxel at the bottom of the sphere.
        let cube = Aabb {
            min: Vec3::splat(-0.6),
            max: Vec3::splat(0.6),
        };
        let grid = shell(&sil, &cube, 12);
        let (i, k) = (6, 1); // x, y ≈ 0, z ≈ −0.45
        assert_ne!(grid.class(i, i, k), VoxelClass::Empty);
        let bottom_kept = |g: &ShellGrid| (0..3).any(|k| g.class(6, 6, k) != VoxelClass::Empty);
        assert!(bottom_kept(&grid));
        let as_bg = shell(&silhouettes(&views_as_bg, false), &cube, 12);
        assert!(
            !bottom_kept(&as_bg),
            "the occluded bottom was expected to go"
        );
        // And every voxel outside the sphere's bounding box is carved.
        assert_eq!(grid.class(0, 0, 0), VoxelClass::Empty);
    }

    #[test]
    fn the_radius_window_keeps_the_contour_and_carves_half_a_pixel_out() {
        // One view whose left half (x < 32) is the object.
        let k = Intrinsics::from_fov_x(40f32.to_radians(), 64, 64);
        let cam = Camera::orbit(0.0, 0.0, 3.0, Vec3::ZERO, k);
        let mut img = RgbaImage::new(64, 64);
        for (x, _, px) in img.enumerate_pixels_mut() {
            if x < 32 {
                *px = Rgba([200, 100, 50, 255]);
            }
        }
        let view = BakeView {
            camera: cam,
            image: &img,
            silhouette: Silhouette::Alpha,
        };
        let sil = Silhouettes::new(std::slice::from_ref(&view));
        let (pr, t) = (&sil.projs[0], &sil.tables[0]);
        // The point whose projection is (px, 20.5).
        let at = |px: f32| {
            let (o, d) = cam.ray(px, 20.5);
            o + 3.0 * d
        };
        let kept =
            |px: f32, w: Window| matches!(point_in_view(pr, t, at(px), w), PointInView::Counts);
        // The contour is x = 32; the last object pixel's centre is 31.5.
        for w in [Window::Radius(1.0), Window::Margin(1)] {
            assert!(kept(31.9, w), "{w:?}: inside the contour");
            assert!(kept(32.3, w), "{w:?}: 0.3 px out, by rounding");
        }
        // The radius keeps up to ½ px out (1 from the centre), the 3 × 3
        // pixels up to a whole pixel out.
        assert!(kept(32.45, Window::Radius(1.0)));
        assert!(!kept(32.55, Window::Radius(1.0)));
        assert!(!kept(32.7, Window::Radius(1.0)));
        assert!(kept(32.7, Window::Margin(1)));
        assert!(kept(32.95, Window::Margin(1)));
        assert!(!kept(33.05, Window::Margin(1)));
        // The builder clamps the radius to [½, 64] (NaN: ½), so a point's
        // own pixel stays in and no window overflows.
        let s = Silhouettes::new(std::slice::from_ref(&view)).with_radius(0.0);
        assert!(matches!(s.window(), Window::Radius(r) if r == 0.5));
        assert!(s.inside(at(31.99)));
        let nan = Silhouettes::new(std::slice::from_ref(&view)).with_radius(f32::NAN);
        assert!(matches!(nan.window(), Window::Radius(r) if r == 0.5));
        let huge = Silhouettes::new(std::slice::from_ref(&view)).with_radius(1e30);
        assert!(huge.inside(at(60.0)), "64 px reaches the object");
        let q = crate::bake::quads::Quad::facing_minus_y(at(40.0), 0.01);
        let _ = texel_occupancy_hull(&huge, &[q], 3);
        let wide = Silhouettes::new(std::slice::from_ref(&view)).with_margin(u32::MAX);
        assert!(wide.inside(at(60.0)));
        let _ = texel_occupancy_hull(&wide, &[q], 3);
        // Near the image's edges the window clips without panicking.
        for px in [0.01, 63.99] {
            let _ = kept(px, Window::Radius(16.0));
        }
    }

    #[test]
    fn carving_opaque_texels_is_and_with_the_hull_occupancy() {
        let views = sphere_views(&[]);
        let sil = silhouettes(&views, false);
        let cube = Aabb {
            min: Vec3::splat(-0.6),
            max: Vec3::splat(0.6),
        };
        let quads = crate::bake::quads::shell_quads(&shell(&sil, &cube, 12));
        let p = 5;
        let hull = texel_occupancy_hull(&sil, &quads, p);
        assert!(hull.contains(&true) && hull.contains(&false));
        // Some texels already transparent, in a pattern unrelated to the hull.
        let before: Vec<bool> = (0..hull.len()).map(|i| (i * 7919) % 5 != 0).collect();
        let mut carved = before.clone();
        carve_texels(&sil, &quads, p, &mut carved);
        let expect: Vec<bool> = before.iter().zip(&hull).map(|(a, b)| a & b).collect();
        assert_eq!(carved, expect);
    }

    /// The block-level carve gives every texel the point test's verdict:
    /// axis-aligned shell quads and tilted parallelograms across the
    /// sphere's silhouette, several patch sizes and windows, with and
    /// without another object's pixels in some views.
    #[test]
    fn carved_texels_are_the_point_tests_verdicts() {
        let cube = Aabb {
            min: Vec3::splat(-0.6),
            max: Vec3::splat(0.6),
        };
        for hidden in [&[][..], &[0, 1, 2, 3]] {
            let views = sphere_views(hidden);
            let instance = !hidden.is_empty();
            let base = silhouettes(&views, instance);
            let mut quads = crate::bake::quads::shell_quads(&shell(&base, &cube, 10));
            // Tilted parallelograms of several sizes around the radius.
            for k in 0..60 {
                let a = k as f32 * 0.61;
                let dir =
                    Vec3::new(a.cos() * (0.3 * a).sin(), a.sin(), (0.3 * a).cos()).normalize();
                let centre = (0.4 + 0.004 * (k % 9) as f32) * dir;
                let u = dir.any_orthonormal_vector() * (0.02 + 0.01 * (k % 5) as f32);
                let v = dir.cross(u) * (1.0 + 0.3 * (k % 3) as f32) + 0.2 * u;
                quads.push(crate::bake::quads::Quad {
                    origin: centre - 0.5 * (u + v),
                    u,
                    v,
                    normal: dir,
                    voxel: [0; 3],
                    twist: Vec3::ZERO,
                });
            }
            for sil in [
                base,
                silhouettes(&views, instance).with_radius(0.5),
                silhouettes(&views, instance).with_radius(2.5),
                silhouettes(&views, instance).with_margin(0),
                silhouettes(&views, instance).with_margin(2),
            ] {
                for p in [2u32, 5, 17, 25] {
                    let mut carved = vec![true; quads.len() * (p * p) as usize];
                    let (settled, tested) = carve_texels_counted(&sil, &quads, p, &mut carved);
                    // Both paths taken where blocks are smaller than the
                    // quads (at p = 2 the one block is the quad, which
                    // straddles by definition).
                    assert!(
                        tested > 0 && (p < 17 || settled > 0),
                        "{settled} {tested} at p = {p}"
                    );
                    let step = 1.0 / (p - 1) as f32;
                    let mut mixed = 0;
                    for (q, cell) in quads.iter().zip(carved.chunks(p as usize * p as usize)) {
                        for (i, &c) in cell.iter().enumerate() {
                            let (tx, ty) = (i as u32 % p, i as u32 / p);
                            let x = q.point(tx as f32 * step, ty as f32 * step);
                            assert_eq!(c, sil.inside(x), "texel ({tx}, {ty}) at p = {p}: {x}");
                        }
                        mixed += usize::from(cell.contains(&true) && cell.contains(&false));
                    }
                    assert!(mixed > 5, "{mixed} quads cross the silhouette at p = {p}");
                }
            }
        }
    }

    /// A small box at the sphere's centre is inside every view's
    /// silhouette, one off to the side in the image's corner region is
    /// background, one across the contour or behind the camera is
    /// neither.
    #[test]
    fn a_box_is_judged_by_its_corners_projections() {
        let views = sphere_views(&[]);
        let sil = silhouettes(&views, false);
        let cube = |c: Vec3, h: f32| -> [Vec3; 8] {
            std::array::from_fn(|k| {
                c + h * Vec3::new(
                    if k & 1 == 0 { -1.0 } else { 1.0 },
                    if k & 2 == 0 { -1.0 } else { 1.0 },
                    if k & 4 == 0 { -1.0 } else { 1.0 },
                )
            })
        };
        let (pr, t) = (&sil.projs[1], &sil.tables[1]);
        let cam = &views[1].0;
        let centre = cube(Vec3::ZERO, 0.05);
        assert!(matches!(judge_box(pr, t, &centre, 1), Verdict::Inside));
        // Beside the sphere, in frame: a point a little off its contour.
        let (o, d) = cam.ray(6.0, 6.0);
        let side = cube(o + 3.0 * d, 0.02);
        assert!(matches!(judge_box(pr, t, &side, 1), Verdict::Background));
        // A reach wide enough to touch the sphere: no longer background.
        assert!(matches!(judge_box(pr, t, &side, 30), Verdict::Object));
        // Across the contour: the sphere's radius, sideways to the view.
        let perp = o.normalize().any_orthonormal_vector();
        let across = cube(0.5 * perp, 0.05);
        assert!(matches!(judge_box(pr, t, &across, 1), Verdict::Object));
        let behind = cube(o - d, 0.1);
        assert!(matches!(judge_box(pr, t, &behind, 1), Verdict::Object));
        // A NaN corner does not drop out of the box: no verdict.
        let mut broken = centre;
        broken[7] = Vec3::NAN;
        assert!(matches!(judge_box(pr, t, &broken, 1), Verdict::Object));
    }

    #[test]
    fn block_cuts_span_the_patch() {
        for p in 2..40 {
            let c = block_cuts(p);
            assert_eq!((c[0], *c.last().unwrap()), (0, p - 1), "p = {p}");
            assert!(c
                .windows(2)
                .all(|w| w[0] < w[1] && w[1] - w[0] <= BLOCK_TEXELS));
        }
    }

    #[test]
    fn instance_masks_without_other_objects_carve_exactly_as_alpha() {
        let views = sphere_views(&[]);
        let (a, b) = (silhouettes(&views, false), silhouettes(&views, true));
        assert!(b.tables.iter().all(|t| t.unknown.is_none()));
        let cube = Aabb {
            min: Vec3::splat(-0.6),
            max: Vec3::splat(0.6),
        };
        assert_eq!(shell(&a, &cube, 16).class, shell(&b, &cube, 16).class);
        let (ga, gb) = (
            carve(&a, &cube, 16, VoxelTest::Centre),
            carve(&b, &cube, 16, VoxelTest::Centre),
        );
        assert_eq!(ga.occ, gb.occ);
    }
}
