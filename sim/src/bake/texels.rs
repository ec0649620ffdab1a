//! Per-texel colour from the training views that see the texel.
//!
//! For each quad and each view that faces it, every texel's surface point is
//! projected into the view and kept if it passes a depth test against the
//! view's depth map of the carved quads (rendered here, once per view). The
//! texel colour is the coverage-weighted mean of those views' colours,
//! weighted toward frontal views by cos(θ)^k (θ between the quad's normal
//! and the direction to the camera). Each view is sampled at the level of
//! its image pyramid whose pixels match the texel's footprint, so a coarse
//! patch gets the average colour of the area it covers rather than an
//! aliased point sample. Colours are averaged premultiplied by the object's
//! coverage, so background never bleeds into the object's edge texels.
//!
//! Texels no view sees take the mean of their nearest seen neighbours in
//! the same patch; quads no view sees at all are coloured from the facing
//! views without the depth test.

use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::atlas::{Atlas, AtlasLayout, AtlasPage};
use super::mlp_fit::ColourCode;
use super::quads::Quad;
use super::BakeView;
use image::RgbaImage;

/// Settings of the texel pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexelSettings {
    /// Texels per quad edge (p).
    pub patch: u32,
    /// Voxel edge, world units.
    pub voxel: f32,
    /// Exponent k of the frontal weight cos(θ)^k.
    pub frontal_power: f32,
    /// Views at a grazing angle (|cos θ| below this) do not contribute.
    pub min_cos: f32,
    /// Whether views behind a quad (cos θ < 0) count too (shell quads have
    /// no inside).
    pub two_sided: bool,
    /// Colour each quad from at most this many views, those that see it
    /// best (0: every facing view).
    pub max_views: usize,
}

impl TexelSettings {
    /// Defaults for a patch size and voxel size.
    pub fn new(patch: u32, voxel: f32) -> Self {
        Self {
            patch,
            voxel,
            frontal_power: 1.0,
            min_cos: 0.05,
            two_sided: false,
            max_views: 8,
        }
    }
}

/// Premultiplied-colour image pyramid of one view: level 0 is the image,
/// each next level a 2×2 box average.
struct Pyramid {
    levels: Vec<Level>,
}

struct Level {
    width: u32,
    height: u32,
    /// Premultiplied (r·a, g·a, b·a, a), all in [0, 1].
    px: Vec<[f32; 4]>,
}

impl Level {
    /// Bilinear sample at continuous pixel coordinates (pixel centres at
    /// i + 0.5), clamped to the border.
    #[inline]
    fn bilinear(&self, x: f32, y: f32) -> [f32; 4] {
        let fx = (x - 0.5).clamp(0.0, (self.width - 1) as f32);
        let fy = (y - 0.5).clamp(0.0, (self.height - 1) as f32);
        // fx, fy ≥ 0: truncation is floor, without a libm call.
        let x0 = fx as u32;
        let y0 = fy as u32;
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
        let w = self.width as usize;
        let at = |x: u32, y: u32| self.px[y as usize * w + x as usize];
        let (p00, p10, p01, p11) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        let mut out = [0f32; 4];
        for c in 0..4 {
            let top = p00[c] + ax * (p10[c] - p00[c]);
            let bot = p01[c] + ax * (p11[c] - p01[c]);
            out[c] = top + ay * (bot - top);
        }
        out
    }
}

impl Pyramid {
    fn new(view: &BakeView<'_>) -> Self {
        let (w, h) = view.image.dimensions();
        let mut px = Vec::with_capacity(w as usize * h as usize);
        for y in 0..h {
            for x in 0..w {
                let p = view.image.get_pixel(x, y).0;
                let a = f32::from(view.coverage(x, y)) / 255.0;
                px.push([
                    a * f32::from(p[0]) / 255.0,
                    a * f32::from(p[1]) / 255.0,
                    a * f32::from(p[2]) / 255.0,
                    a,
                ]);
            }
        }
        let mut levels = vec![Level {
            width: w,
            height: h,
            px,
        }];
        while levels.len() < 10 {
            let prev = &levels[levels.len() - 1];
            if prev.width < 2 && prev.height < 2 {
                break;
            }
            let (nw, nh) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
            let mut px = Vec::with_capacity(nw as usize * nh as usize);
            for y in 0..nh {
                for x in 0..nw {
                    let mut s = [0f32; 4];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let sx = (2 * x + dx).min(prev.width - 1);
                        let sy = (2 * y + dy).min(prev.height - 1);
                        let p = prev.px[sy as usize * prev.width as usize + sx as usize];
                        for c in 0..4 {
                            s[c] += 0.25 * p[c];
                        }
                    }
                    px.push(s);
                }
            }
            levels.push(Level {
                width: nw,
                height: nh,
                px,
            });
        }
        Self { levels }
    }
}

/// Camera constants of one view.
#[derive(Clone, Copy)]
struct ViewCam {
    w2c: Mat4,
    position: Vec3,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: u32,
    height: u32,
}

impl ViewCam {
    #[inline]
    fn project(&self, c: Vec3) -> Option<(f32, f32, f32)> {
        let depth = -c.z;
        (depth > 1e-4).then(|| {
            (
                self.cx + self.fx * c.x / depth,
                self.cy - self.fy * c.y / depth,
                depth,
            )
        })
    }
}

/// A view ready for the texel pass: camera, pyramid and depth map.
struct Prepared {
    cam: ViewCam,
    pyramid: Pyramid,
    /// Distance along the view axis of the nearest quad per pixel
    /// (`f32::INFINITY` where no quad covers the pixel centre).
    depth: Vec<f32>,
}

/// All views prepared for the texel pass.
pub struct PreparedViews {
    views: Vec<Prepared>,
}

impl PreparedViews {
    /// Builds every view's pyramid and depth map of `quads` (in parallel);
    /// `occupancy` (p² per quad, see [`super::carve::texel_occupancy`])
    /// makes empty texels transparent in the depth maps.
    pub fn new(views: &[BakeView<'_>], quads: &[Quad], occupancy: &[bool], patch: u32) -> Self {
        let views = views
            .par_iter()
            .map(|v| {
                let k = &v.camera.intrinsics;
                let cam = ViewCam {
                    w2c: v.camera.w2c(),
                    position: v.camera.position(),
                    fx: k.fx,
                    fy: k.fy,
                    cx: k.cx,
                    cy: k.cy,
                    width: k.width,
                    height: k.height,
                };
                Prepared {
                    depth: depth_map(&cam, quads, occupancy, patch),
                    pyramid: Pyramid::new(v),
                    cam,
                }
            })
            .collect();
        Self { views }
    }

    /// Number of views.
    pub fn len(&self) -> usize {
        self.views.len()
    }

    /// Whether there are no views.
    pub fn is_empty(&self) -> bool {
        self.views.is_empty()
    }

    /// The depth map of view `i` (row-major, `INFINITY` = nothing), for
    /// tests and debugging pictures.
    pub fn depth(&self, i: usize) -> Option<(&[f32], u32, u32)> {
        self.views
            .get(i)
            .map(|p| (p.depth.as_slice(), p.cam.width, p.cam.height))
    }
}

/// Z-buffer of the quads seen from `cam` (depth at pixel centres), with
/// empty texels left out.
fn depth_map(cam: &ViewCam, quads: &[Quad], occupancy: &[bool], patch: u32) -> Vec<f32> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let p = patch.max(2) as usize;
    let mut z = vec![f32::INFINITY; w * h];
    for (qi, q) in quads.iter().enumerate() {
        let c = q.corners();
        let mut s = [Vertex::default(); 4];
        let mut ok = true;
        for (i, p) in c.iter().enumerate() {
            match cam.project(cam.w2c.transform_point3(*p)) {
                Some(v) => {
                    s[i] = Vertex {
                        x: v.0,
                        y: v.1,
                        inv_depth: 1.0 / v.2,
                        st: CORNER_ST[i],
                    }
                }
                None => ok = false,
            }
        }
        if !ok {
            continue; // a corner behind the camera: cameras sit outside objects
        }
        let mask = occupancy.get(qi * p * p..(qi + 1) * p * p);
        let mut tri =
            |a: Vertex, b: Vertex, c: Vertex| raster_triangle(&mut z, w, h, [a, b, c], mask, p);
        tri(s[0], s[1], s[3]);
        tri(s[0], s[3], s[2]);
    }
    z
}

/// Quad coordinates (s, t) of the corners in export order.
const CORNER_ST: [[f32; 2]; 4] = [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0], [1.0, 1.0]];

/// A projected corner: pixel position, 1/depth and quad coordinates.
#[derive(Debug, Clone, Copy, Default)]
struct Vertex {
    x: f32,
    y: f32,
    inv_depth: f32,
    st: [f32; 2],
}

/// Rasterizes one triangle into the z-buffer, interpolating 1/depth and
/// (s, t)/depth linearly in screen space (perspective-correct); pixels whose
/// nearest texel is empty in `mask` are skipped.
fn raster_triangle(
    z: &mut [f32],
    w: usize,
    h: usize,
    v: [Vertex; 3],
    mask: Option<&[bool]>,
    p: usize,
) {
    let [a, b, c] = v;
    let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if area.abs() < 1e-12 {
        return;
    }
    let minx = a.x.min(b.x).min(c.x).floor().max(0.0) as usize;
    let miny = a.y.min(b.y).min(c.y).floor().max(0.0) as usize;
    let maxx = (a.x.max(b.x).max(c.x).ceil().max(0.0) as usize).min(w);
    let maxy = (a.y.max(b.y).max(c.y).ceil().max(0.0) as usize).min(h);
    let inv = 1.0 / area;
    let last = (p - 1) as f32;
    for y in miny..maxy {
        let py = y as f32 + 0.5;
        for x in minx..maxx {
            let px = x as f32 + 0.5;
            // Barycentric weights (signed areas), inclusive edges so shared
            // edges leave no cracks in the depth map.
            let wa = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) * inv;
            let wb = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) * inv;
            let wc = 1.0 - wa - wb;
            if wa < -1e-6 || wb < -1e-6 || wc < -1e-6 {
                continue;
            }
            let iz = wa * a.inv_depth + wb * b.inv_depth + wc * c.inv_depth;
            let d = 1.0 / iz;
            let slot = &mut z[y * w + x];
            if d >= *slot {
                continue;
            }
            if let Some(m) = mask {
                let s = (wa * a.st[0] * a.inv_depth
                    + wb * b.st[0] * b.inv_depth
                    + wc * c.st[0] * c.inv_depth)
                    * d;
                let t = (wa * a.st[1] * a.inv_depth
                    + wb * b.st[1] * b.inv_depth
                    + wc * c.st[1] * c.inv_depth)
                    * d;
                let tx = (s * last + 0.5).clamp(0.0, last) as usize;
                let ty = (t * last + 0.5).clamp(0.0, last) as usize;
                if !m.get(ty * p + tx).copied().unwrap_or(true) {
                    continue;
                }
            }
            *slot = d;
        }
    }
}

/// The colours of every quad's patch.
pub struct PatchColours {
    /// Texels per patch edge.
    pub patch: u32,
    /// 8-bit sRGB per texel, p² per quad, quad after quad (empty texels: 0).
    pub rgb: Vec<[u8; 3]>,
    /// Per quad: how many of its occupied texels some view saw.
    pub seen: Vec<u32>,
    /// Per quad: how many (texel, view) pairs contributed colour (depth
    /// test passed, coverage > 0): a texel's colour averages
    /// `view_samples / seen` views on average.
    pub view_samples: Vec<u32>,
}

/// Colours every quad's patch from the views (in parallel over quads).
pub fn colour_quads(
    views: &PreparedViews,
    quads: &[Quad],
    occupancy: &[bool],
    settings: &TexelSettings,
) -> PatchColours {
    let p = settings.patch as usize;
    let mut rgb = vec![[0u8; 3]; quads.len() * p * p];
    let mut seen = vec![0u32; quads.len()];
    let mut view_samples = vec![0u32; quads.len()];
    rgb.par_chunks_mut(p * p)
        .zip(seen.par_iter_mut().zip(view_samples.par_iter_mut()))
        .enumerate()
        .for_each_init(
            || vec![[0f32; 3]; p * p],
            |colours, (qi, (out, (seen, samples)))| {
                let occ = &occupancy[qi * p * p..(qi + 1) * p * p];
                let (n, m) = patch_colours(views, &quads[qi], occ, settings, colours);
                (*seen, *samples) = (n as u32, m as u32);
                for ((o, c), &full) in out.iter_mut().zip(colours.iter()).zip(occ) {
                    *o = if full {
                        c.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
                    } else {
                        [0; 3]
                    };
                }
            },
        );
    PatchColours {
        patch: settings.patch,
        rgb,
        seen,
        view_samples,
    }
}

/// Writes both feature atlases: occupied texels get `code`'s features of
/// their colour, empty texels feat0 = 0 (discarded by the shader).
pub fn write_atlas(
    colours: &[[u8; 3]],
    occupancy: &[bool],
    layout: &AtlasLayout,
    code: &ColourCode,
) -> Atlas {
    let p = layout.patch as usize;
    let mut pages = Vec::with_capacity(layout.pages.len());
    for (pi, pl) in layout.pages.iter().enumerate() {
        let (pw, ph) = layout.page_size(pi);
        let mut feat0 = RgbaImage::new(pw, ph);
        let row_bytes = p * pw as usize * 4;
        feat0
            .as_mut()
            .par_chunks_mut(row_bytes)
            .enumerate()
            .for_each(|(row, buf)| {
                for (col, q) in pl.row_quads(row) {
                    let base = q * p * p;
                    for ty in 0..p {
                        for tx in 0..p {
                            let t = base + ty * p + tx;
                            let f0 = if occupancy[t] {
                                code.features(colours[t]).0
                            } else {
                                [0; 4] // feat0.R == 0: empty texel
                            };
                            let o = (ty * pw as usize + col * p + tx) * 4;
                            buf[o..o + 4].copy_from_slice(&f0);
                        }
                    }
                }
            });
        // Spare channels stay 0: the MLP gives them zero weight.
        let feat1 = RgbaImage::new(pw, ph);
        pages.push(AtlasPage { feat0, feat1 });
    }
    Atlas {
        layout: layout.clone(),
        pages,
    }
}

/// Per-view constants of one quad.
struct QuadView<'a> {
    view: &'a Prepared,
    weight: f32,
    origin: Vec3,
    du: Vec3,
    dv: Vec3,
    level: usize,
    tol: f32,
}

/// Fills `out` (p×p, row-major, rgb in [0, 1]) with the quad's texel
/// colours; returns how many texels some view saw and how many (texel,
/// view) pairs gave them colour.
fn patch_colours(
    views: &PreparedViews,
    q: &Quad,
    occ: &[bool],
    s: &TexelSettings,
    out: &mut [[f32; 3]],
) -> (usize, usize) {
    let p = s.patch as usize;
    let step = 1.0 / (p.max(2) - 1) as f32;
    let centre = q.point(0.5, 0.5);
    let texel_world = s.voxel * step;
    let facing: Vec<QuadView<'_>> = views
        .views
        .iter()
        .filter_map(|v| {
            let to_cam = v.cam.position - centre;
            let dist = to_cam.length();
            let mut cos = q.normal.dot(to_cam) / dist;
            if s.two_sided {
                cos = cos.abs();
            }
            if cos < s.min_cos {
                return None;
            }
            let c = v.cam.w2c.transform_point3(centre);
            let depth = (-c.z).max(1e-3);
            let f = v.cam.fx.max(v.cam.fy);
            // Texel footprint in pixels → pyramid level.
            let footprint = f * texel_world / depth;
            let level = if footprint > 1.0 {
                (footprint.log2().round() as usize).min(v.pyramid.levels.len() - 1)
            } else {
                0
            };
            // Depth tolerance: half a voxel plus 1.5 pixels' worth of depth
            // change across the surface at this angle.
            let pixel_world = depth / f;
            let tol = 0.5 * s.voxel + 1.5 * pixel_world / cos.max(0.2);
            Some(QuadView {
                view: v,
                weight: cos.powf(s.frontal_power),
                origin: v.cam.w2c.transform_point3(q.origin),
                du: v.cam.w2c.transform_vector3(q.u * step),
                dv: v.cam.w2c.transform_vector3(q.v * step),
                level,
                tol,
            })
        })
        .collect();
    let facing = best_views(facing, p, occ, s.max_views);
    let mut acc = vec![[0f32; 4]; p * p];
    let samples = accumulate(&facing, p, occ, true, &mut acc);
    let seen = acc.iter().filter(|a| a[3] > 1e-4).count();
    if seen == 0 {
        // No view sees any of this quad: colour it from the facing views
        // regardless of occlusion, rather than leave it blank.
        accumulate(&facing, p, occ, false, &mut acc);
        if acc.iter().all(|a| a[3] <= 1e-4) {
            out.fill([0.5; 3]);
            return (0, 0);
        }
    }
    fill_from_neighbours(&mut acc, occ, p);
    for (o, a) in out.iter_mut().zip(&acc) {
        *o = if a[3] > 1e-4 {
            [a[0] / a[3], a[1] / a[3], a[2] / a[3]]
        } else {
            [0.5; 3]
        };
    }
    (seen, if seen == 0 { 0 } else { samples })
}

/// The `k` views that see most of the quad, frontal first: each facing
/// view is scored by its weight times the share of up to 9 of the quad's
/// occupied texels (spread over the patch) that pass its depth test. Views
/// that see none of the samples go last. `k == 0` keeps every view.
fn best_views<'a>(
    mut facing: Vec<QuadView<'a>>,
    p: usize,
    occ: &[bool],
    k: usize,
) -> Vec<QuadView<'a>> {
    if k == 0 || facing.len() <= k {
        return facing;
    }
    let occupied: Vec<usize> = (0..p * p).filter(|&i| occ[i]).collect();
    if occupied.is_empty() {
        return facing;
    }
    let stride = occupied.len().div_ceil(9);
    let samples: Vec<usize> = occupied.iter().copied().step_by(stride).collect();
    let mut scored: Vec<(f32, QuadView<'a>)> = facing
        .drain(..)
        .map(|qv| {
            let cam = &qv.view.cam;
            let visible = samples
                .iter()
                .filter(|&&i| {
                    let c = qv.origin + (i % p) as f32 * qv.du + (i / p) as f32 * qv.dv;
                    let Some((px, py, depth)) = cam.project(c) else {
                        return false;
                    };
                    if !(px >= 0.0 && py >= 0.0 && px < cam.width as f32 && py < cam.height as f32)
                    {
                        return false;
                    }
                    depth <= qv.view.depth[py as usize * cam.width as usize + px as usize] + qv.tol
                })
                .count();
            (qv.weight * visible as f32 / samples.len() as f32, qv)
        })
        .collect();
    // A view that sees no sample may still see some texel: keep the order
    // of weight among those, after the seeing views.
    scored.sort_by(|a, b| b.0.total_cmp(&a.0).then(b.1.weight.total_cmp(&a.1.weight)));
    // If no view sees a sample, keep them all for the full test.
    if scored.iter().any(|(sc, _)| *sc > 0.0) {
        scored.truncate(k);
    }
    scored.into_iter().map(|(_, qv)| qv).collect()
}

/// Adds every facing view's weighted premultiplied colour to each texel;
/// returns how many (texel, view) samples had coverage.
fn accumulate(
    facing: &[QuadView<'_>],
    p: usize,
    occ: &[bool],
    depth_test: bool,
    acc: &mut [[f32; 4]],
) -> usize {
    let mut samples = 0;
    acc.fill([0.0; 4]);
    for qv in facing {
        let cam = &qv.view.cam;
        let level = &qv.view.pyramid.levels[qv.level];
        let scale = 1.0 / (1u32 << qv.level) as f32;
        for ty in 0..p {
            let row = qv.origin + ty as f32 * qv.dv;
            for tx in 0..p {
                if !occ[ty * p + tx] {
                    continue;
                }
                let c = row + tx as f32 * qv.du;
                let Some((px, py, depth)) = cam.project(c) else {
                    continue;
                };
                if !(px >= 0.0 && py >= 0.0 && px < cam.width as f32 && py < cam.height as f32) {
                    continue;
                }
                if depth_test {
                    let zi = py as usize * cam.width as usize + px as usize;
                    if depth > qv.view.depth[zi] + qv.tol {
                        continue;
                    }
                }
                let v = level.bilinear(px * scale, py * scale);
                samples += usize::from(v[3] > 0.0);
                let a = &mut acc[ty * p + tx];
                for ch in 0..4 {
                    a[ch] += qv.weight * v[ch];
                }
            }
        }
    }
    samples
}

/// Gives occupied texels without colour weight the mean of their coloured
/// 4-neighbours, growing until every texel reachable from a coloured one
/// has a colour.
fn fill_from_neighbours(acc: &mut [[f32; 4]], occ: &[bool], p: usize) {
    let filled = |a: &[f32; 4]| a[3] > 1e-4;
    loop {
        let mut next = acc.to_vec();
        let mut changed = false;
        let mut missing = false;
        for y in 0..p {
            for x in 0..p {
                if filled(&acc[y * p + x]) || !occ[y * p + x] {
                    continue;
                }
                missing = true;
                let mut sum = [0f32; 4];
                let mut n = 0;
                let nb = [
                    (x.wrapping_sub(1), y),
                    (x + 1, y),
                    (x, y.wrapping_sub(1)),
                    (x, y + 1),
                ];
                for (nx, ny) in nb {
                    if nx < p && ny < p && filled(&acc[ny * p + nx]) {
                        let a = acc[ny * p + nx];
                        // Normalise so each neighbour counts once.
                        for c in 0..4 {
                            sum[c] += a[c] / a[3];
                        }
                        n += 1;
                    }
                }
                if n > 0 {
                    next[y * p + x] = sum.map(|v| v / n as f32);
                    changed = true;
                }
            }
        }
        acc.copy_from_slice(&next);
        if !missing || !changed {
            break;
        }
    }
}
