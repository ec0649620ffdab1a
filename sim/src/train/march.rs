//! Differentiable volume rendering of one ray through the sparse grid:
//! the trainer's hot loop.
//!
//! Samples sit every `step` cells along the ray inside the grid's box;
//! cells that store nothing are skipped before any gather. The forward
//! pass keeps what the backward pass needs (corners, opacity terms,
//! colours) in a per-worker scratch that is reused, so the loop does not
//! allocate. The backward pass scatters record gradients into a
//! per-worker [`GradBuf`]; the optimiser merges the workers' buffers.
//!
//! With `τᵢ = σᵢ·δ`, `aᵢ = 1 − e^{−τᵢ}`, `Tᵢ = Π_{j<i} e^{−τⱼ}`, `wᵢ = Tᵢ·aᵢ`
//! and `C = Σ wᵢ cᵢ + T_end·bg`:
//! `∂C/∂cᵢ = wᵢ` and `∂C/∂τᵢ = T_{i+1}·cᵢ − Rᵢ` with `Rᵢ = Σ_{j>i} wⱼ cⱼ + T_end·bg`.

use glam::Vec3;

use super::adam::prefetch;
use super::grid::{activate_density, sigmoid, Corners, SparseGrid};
use super::sh;

/// Transmittance below which a ray stops (what is behind is invisible).
pub const T_STOP: f32 = 1e-4;

/// One ray in grid coordinates.
#[derive(Debug, Clone, Copy)]
pub struct GridRay {
    /// Origin, grid units.
    pub origin: Vec3,
    /// Unit direction (the same in world and grid units: the scale is
    /// uniform).
    pub dir: Vec3,
    /// Offset of the first sample, as a fraction of a step in [0, 1).
    pub jitter: f32,
}

impl GridRay {
    /// The ray of a world-space origin and unit direction.
    pub fn from_world(grid: &SparseGrid, origin: Vec3, dir: Vec3, jitter: f32) -> Self {
        GridRay {
            origin: grid.to_grid(origin),
            dir,
            jitter,
        }
    }

    /// A Z-order key of where the ray crosses the box (the middle of
    /// its clipped segment, quantised to 4 cells): rays sorted by it visit
    /// the same cells one after another, which keeps the grid's cache lines
    /// warm. Rays missing the box sort last.
    pub fn locality_key(&self, bx: &MarchBox) -> u64 {
        let Some((t0, t1)) = self.clip(bx.lo, bx.hi) else {
            return u64::MAX;
        };
        let m = (self.origin + 0.5 * (t0 + t1) * self.dir - bx.lo) * 0.25;
        let q = |v: f32| (v.max(0.0) as u64).min(0x1f_ffff);
        morton3(q(m.x), q(m.y), q(m.z))
    }

    /// Where the ray is inside [lo, hi]³ (grid units): (t_near, t_far).
    #[inline]
    fn clip(&self, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
        let inv = self.dir.recip();
        let a = (lo - self.origin) * inv;
        let b = (hi - self.origin) * inv;
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element();
        (t0 < t1 && t0.is_finite() && t1.is_finite()).then_some((t0, t1))
    }
}

/// Interleaves the low 21 bits of three coordinates (Z-order).
fn morton3(x: u64, y: u64, z: u64) -> u64 {
    fn spread(mut v: u64) -> u64 {
        v &= 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        v = (v | v << 2) & 0x1249_2492_4924_9249;
        v
    }
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// What the forward pass remembers of one sample.
#[derive(Debug, Clone, Copy, Default)]
struct Sample {
    corners: Corners,
    /// ∂τ/∂raw density.
    dtau_draw: f32,
    /// Colour after the sigmoid.
    rgb: [f32; 3],
    /// Weight wᵢ = Tᵢ·aᵢ.
    w: f32,
    /// Transmittance after the sample, T_{i+1}.
    t_after: f32,
    /// Distance of the sample along the ray, cells.
    t: f32,
}

/// Per-worker scratch of the ray loop.
#[derive(Debug, Default)]
pub struct Scratch {
    samples: Vec<Sample>,
    /// ∂(distortion)/∂wᵢ per sample.
    dist_dw: Vec<f32>,
}

/// Settings of the march.
#[derive(Debug, Clone, Copy)]
pub struct MarchParams {
    /// Distance between samples, cells.
    pub step: f32,
    /// Background colour (white for NeRF-synthetic).
    pub background: Vec3,
}

/// The result of one ray: its colour (background included) and how many
/// samples it shaded.
#[derive(Debug, Clone, Copy)]
pub struct RayOut {
    /// Composited colour.
    pub rgb: Vec3,
    /// Remaining transmittance (1 − opacity).
    pub transmittance: f32,
    /// Samples that were shaded.
    pub samples: u32,
}

/// The box of grid coordinates worth marching through.
#[derive(Debug, Clone, Copy)]
pub struct MarchBox {
    /// Lower corner, grid units.
    pub lo: Vec3,
    /// Upper corner, grid units.
    pub hi: Vec3,
}

impl MarchBox {
    /// The box of the grid's stored vertices.
    pub fn of(grid: &SparseGrid) -> Self {
        let mut lo = Vec3::splat(f32::MAX);
        let mut hi = Vec3::splat(f32::MIN);
        for &v in &grid.vertex {
            let (i, j, k) = grid.vertex_ijk(v);
            let p = Vec3::new(i as f32, j as f32, k as f32);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if grid.vertex.is_empty() {
            lo = Vec3::ZERO;
            hi = Vec3::ZERO;
        }
        MarchBox { lo, hi }
    }
}

/// Shades one sample from its interpolated record: (τ, ∂τ/∂raw, rgb).
#[inline(always)]
fn shade<const S: usize, const K: usize>(
    rec: &[f32; S],
    basis: &[f32; K],
    tau_scale: f32,
) -> (f32, f32, [f32; 3]) {
    let (sigma, dsigma) = activate_density(rec[0]);
    let mut rgb = [0.0f32; 3];
    for (ch, out) in rgb.iter_mut().enumerate() {
        let mut s = 0.0;
        for k in 0..K {
            s += rec[1 + ch * K + k] * basis[k];
        }
        *out = sigmoid(s);
    }
    (sigma * tau_scale, dsigma * tau_scale, rgb)
}

/// The basis of a ray's direction, `K` values.
#[inline(always)]
fn basis_of<const K: usize>(degree: u32, dir: Vec3) -> [f32; K] {
    let mut all = [0.0; sh::MAX_COUNT];
    sh::eval(degree, dir, &mut all);
    std::array::from_fn(|k| all[k])
}

/// Runs `$body` with `S` (record length) and `K` (SH count) as constants
/// for the grid's degree.
macro_rules! with_layout {
    ($grid:expr, $f:ident ( $($arg:expr),* )) => {
        match $grid.sh_degree {
            0 => $f::<4, 1>($($arg),*),
            1 => $f::<16, 4>($($arg),*),
            _ => $f::<32, 9>($($arg),*),
        }
    };
}

/// Renders one ray (no gradients): evaluation and previews.
pub fn render_ray(grid: &SparseGrid, bx: &MarchBox, ray: &GridRay, p: &MarchParams) -> RayOut {
    with_layout!(grid, render_ray_k(grid, bx, ray, p))
}

fn render_ray_k<const S: usize, const K: usize>(
    grid: &SparseGrid,
    bx: &MarchBox,
    ray: &GridRay,
    p: &MarchParams,
) -> RayOut {
    forward::<S, K>(grid, bx, ray, p, |_| {})
}

/// Samples ahead of the current one whose cell (occupancy word and
/// lattice-index rows) the forward march prefetches.
const CELL_AHEAD: u32 = 4;
/// Samples ahead whose corner records it prefetches.
const RECORD_AHEAD: u32 = 2;
/// Samples ahead whose gradient records the backward pass prefetches.
const GRAD_AHEAD: usize = 2;

/// The forward march shared by rendering and training: composites the
/// ray and hands every shaded sample to `keep` (a no-op when rendering).
#[inline(always)]
fn forward<const S: usize, const K: usize>(
    grid: &SparseGrid,
    bx: &MarchBox,
    ray: &GridRay,
    p: &MarchParams,
    mut keep: impl FnMut(Sample),
) -> RayOut {
    let mut out = RayOut {
        rgb: p.background,
        transmittance: 1.0,
        samples: 0,
    };
    let Some((t0, t1)) = ray.clip(bx.lo, bx.hi) else {
        return out;
    };
    let basis = basis_of::<K>(grid.sh_degree, ray.dir);
    let tau_scale = grid.density_scale() * grid.voxel() * p.step;
    // Memory, not arithmetic, bounds the march on a large grid, so the
    // samples' corners are looked up `RECORD_AHEAD` samples before they
    // are shaded (their records prefetched then, their index rows
    // `CELL_AHEAD` samples ahead) and kept in a ring until their turn.
    // `lead` steps exactly as a plain `t += step` loop would, so every
    // sample sits where it did without the ring.
    const N: usize = RECORD_AHEAD as usize + 1;
    let mut ring = [(0.0f32, None::<Corners>); N];
    let (mut head, mut len) = (0usize, 0usize);
    let mut lead = t0 + ray.jitter * p.step;
    let cell_lead = (CELL_AHEAD - RECORD_AHEAD) as f32 * p.step;
    let mut trans = 1.0f32;
    let mut acc = Vec3::ZERO;
    loop {
        while len < N && lead < t1 {
            let u = ray.origin + lead * ray.dir;
            grid.prefetch_cell(u + cell_lead * ray.dir);
            let corners = grid.corners(u);
            if let Some(c) = &corners {
                grid.prefetch_records::<S>(c);
            }
            if let Some(slot) = ring.get_mut((head + len) % N) {
                *slot = (lead, corners);
            }
            lead += p.step;
            len += 1;
        }
        let Some(&(at, corners)) = ring.get(head).filter(|_| len > 0) else {
            break;
        };
        head = (head + 1) % N;
        len -= 1;
        let Some(corners) = corners else {
            continue;
        };
        let rec = grid.gather::<S>(&corners);
        let (tau, dtau_draw, rgb) = shade::<S, K>(&rec, &basis, tau_scale);
        let decay = (-tau).exp();
        let w = trans * (1.0 - decay);
        acc += w * Vec3::from_array(rgb);
        trans *= decay;
        out.samples += 1;
        keep(Sample {
            corners,
            dtau_draw,
            rgb,
            w,
            t_after: trans,
            t: at,
        });
        if trans < T_STOP {
            break;
        }
    }
    out.rgb = acc + trans * p.background;
    out.transmittance = trans;
    out
}

/// A worker's gradient accumulator: dense over slots, with a touched
/// flag per slot. A slot's gradient is only meaningful while its flag is
/// set: the first touch after the optimiser cleared the flag overwrites
/// the stale record instead of adding to it, so the optimiser reads each
/// touched record and never writes it back (zeroing it cost two dirty
/// 64-byte lines per touched slot and step).
#[derive(Debug, Default)]
pub struct GradBuf {
    /// Gradients, `slots × record_len` floats; stale where `mark` is false.
    pub grad: Vec<f32>,
    /// Whether a slot was touched since the optimiser last read it.
    pub mark: Vec<bool>,
}

impl GradBuf {
    /// A zeroed buffer for `slots` records of `len` floats.
    pub fn new(slots: usize, len: usize) -> Self {
        GradBuf {
            grad: vec![0.0; slots * len],
            mark: vec![false; slots],
        }
    }

    /// The record of `slot` (`len` floats) to add to: zeroed first if the
    /// slot was not touched since the optimiser last read it. `None` for a
    /// slot outside the buffer.
    pub fn record_mut(&mut self, slot: usize, len: usize) -> Option<&mut [f32]> {
        let m = self.mark.get_mut(slot)?;
        let g = self.grad.get_mut(slot * len..(slot + 1) * len)?;
        if !*m {
            *m = true;
            g.fill(0.0);
        }
        Some(g)
    }

    /// Asks for the gradient records and touched flags of `corners`.
    #[inline(always)]
    fn prefetch<const S: usize>(&self, corners: &Corners) {
        for &s in &corners.slot {
            let s = s as usize;
            prefetch(self.grad.get(s * S..s * S + S));
            prefetch(self.mark.get(s..s + 1));
        }
    }

    #[inline(always)]
    fn scatter<const S: usize>(&mut self, corners: &Corners, gv: &[f32; S]) {
        for c in 0..8 {
            let s = corners.slot[c] as usize;
            let at = s * S;
            let (Some(m), Some(g)) = (
                self.mark.get_mut(s),
                self.grad
                    .get_mut(at..at + S)
                    .and_then(|r| <&mut [f32; S]>::try_from(r).ok()),
            ) else {
                continue;
            };
            let w = corners.weight[c];
            if *m {
                for i in 0..S {
                    g[i] += w * gv[i];
                }
            } else {
                // First touch: overwrite what the last step left.
                *m = true;
                for i in 0..S {
                    g[i] = w * gv[i];
                }
            }
        }
    }
}

/// What a training ray adds beyond its colour loss: the weights of the
/// per-ray regularisers (DVGO's), each relative to the colour loss of one
/// ray, and which samples pass gradients at all.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RayLoss {
    /// Samples whose weight wᵢ is below this pass no gradient (DVGO's
    /// `fast_color_thres`): most samples of a ray lie in near-empty space
    /// or behind the surface, and their scatter is most of the cost.
    pub skip_weight: f32,
    /// Per-sample colour loss `Σᵢ wᵢ‖cᵢ − target‖²` with the weights held
    /// fixed: every sample that shows must have the pixel's colour, which
    /// keeps colour from being spread over a thick shell.
    pub rgbper: f32,
    /// Binary entropy of the ray's final transmittance: a ray ends either
    /// on the object or in the background, never in haze.
    pub entropy: f32,
    /// Distortion loss (mip-NeRF 360, DVGO v2):
    /// `Σᵢ Σⱼ wᵢwⱼ|sᵢ − sⱼ| + ⅓ Σᵢ wᵢ²δ`, distances `s` in units of the
    /// grid's edge: pulls each ray's weight into one thin interval, so the
    /// surface a baker extracts is where the colour is.
    pub distortion: f32,
}

/// Renders one ray, compares it with `target` and adds the gradient of
/// `loss_scale · (‖C − target‖² + 3·reg)` to `grads`, where `reg` is the
/// weighted regularisers. Returns the ray's colour.
#[allow(clippy::too_many_arguments)]
pub fn train_ray(
    grid: &SparseGrid,
    bx: &MarchBox,
    ray: &GridRay,
    p: &MarchParams,
    target: Vec3,
    loss_scale: f32,
    reg: &RayLoss,
    scratch: &mut Scratch,
    grads: &mut GradBuf,
) -> RayOut {
    with_layout!(
        grid,
        train_ray_k(grid, bx, ray, p, target, loss_scale, reg, scratch, grads)
    )
}

/// Clamp of the transmittance inside the entropy's logarithms.
const ENTROPY_EPS: f32 = 1e-6;

/// Binary entropy of the transmittance `t` (natural log), clamped.
pub fn entropy(t: f32) -> f32 {
    let t = t.clamp(ENTROPY_EPS, 1.0 - ENTROPY_EPS);
    -(t * t.ln() + (1.0 - t) * (1.0 - t).ln())
}

#[allow(clippy::too_many_arguments)]
fn train_ray_k<const S: usize, const K: usize>(
    grid: &SparseGrid,
    bx: &MarchBox,
    ray: &GridRay,
    p: &MarchParams,
    target: Vec3,
    loss_scale: f32,
    reg: &RayLoss,
    scratch: &mut Scratch,
    grads: &mut GradBuf,
) -> RayOut {
    scratch.samples.clear();
    let out = forward::<S, K>(grid, bx, ray, p, |s| scratch.samples.push(s));
    let total = out.rgb;
    let basis = basis_of::<K>(grid.sh_degree, ray.dir);

    // Backward.
    let g_c = 2.0 * loss_scale * (total - target);
    // The regularisers are per ray; the colour loss is per channel.
    let reg_scale = 3.0 * loss_scale;
    // ∂H(T_end)/∂τᵢ = H'(T_end)·(−T_end) for every sample i.
    let t_end = out.transmittance;
    let d_tau_entropy = if reg.entropy > 0.0 && (ENTROPY_EPS..1.0 - ENTROPY_EPS).contains(&t_end) {
        -reg.entropy * reg_scale * ((1.0 - t_end) / t_end).ln() * t_end
    } else {
        0.0
    };
    let g_per = 2.0 * reg.rgbper * reg_scale;
    // Distortion: gᵢ = ∂L/∂wᵢ = 2·Σⱼ wⱼ|sᵢ − sⱼ| + ⅔·wᵢδ (prefix sums over
    // the sorted samples), then ∂L/∂τₖ = gₖ·T_{k+1} − Σ_{i>k} gᵢwᵢ
    // (∂wᵢ/∂τₖ = −wᵢ for k < i, T_{k+1} for k = i).
    let dist_on = reg.distortion > 0.0 && scratch.samples.len() > 1;
    let mut g_w_total = 0.0f32;
    let dist_scale = reg.distortion * reg_scale;
    if dist_on {
        let inv_res = 1.0 / grid.res as f32;
        let delta = p.step * inv_res;
        let (w_all, ws_all) = scratch.samples.iter().fold((0.0f32, 0.0f32), |(a, b), s| {
            (a + s.w, b + s.w * s.t * inv_res)
        });
        let (mut w_lo, mut ws_lo) = (0.0f32, 0.0f32);
        scratch.dist_dw.clear();
        for s in &scratch.samples {
            let si = s.t * inv_res;
            let (w_hi, ws_hi) = (w_all - w_lo - s.w, ws_all - ws_lo - s.w * si);
            let g = 2.0 * (si * w_lo - ws_lo + ws_hi - si * w_hi) + 2.0 / 3.0 * s.w * delta;
            scratch.dist_dw.push(g);
            g_w_total += g * s.w;
            w_lo += s.w;
            ws_lo += s.w * si;
        }
    }
    let mut g_w_upto = 0.0f32; // Σ_{i≤k} gᵢwᵢ
    let mut before = Vec3::ZERO; // Σ_{j≤i} wⱼ cⱼ
    for (k, s) in scratch.samples.iter().enumerate() {
        if let Some(ahead) = scratch.samples.get(k + GRAD_AHEAD) {
            grads.prefetch::<S>(&ahead.corners);
        }
        let rgb = Vec3::from_array(s.rgb);
        before += s.w * rgb;
        let d_tau_dist = if dist_on {
            let g = scratch.dist_dw[k];
            g_w_upto += g * s.w;
            dist_scale * (g * s.t_after - (g_w_total - g_w_upto))
        } else {
            0.0
        };
        if s.w < reg.skip_weight {
            continue;
        }
        let rest = total - before;
        let d_tau = g_c.dot(s.t_after * rgb - rest) + d_tau_entropy + d_tau_dist;
        let mut gv = [0.0f32; S];
        gv[0] = d_tau * s.dtau_draw;
        for ch in 0..3 {
            let c = s.rgb[ch];
            let d_c = s.w * (g_c[ch] + g_per * (c - target[ch]));
            let d_pre = d_c * c * (1.0 - c);
            for k in 0..K {
                gv[1 + ch * K + k] = d_pre * basis[k];
            }
        }
        grads.scatter::<S>(&s.corners, &gv);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::Aabb;

    /// A small random grid whose every vertex is stored.
    fn random_grid(degree: u32, seed: u64) -> SparseGrid {
        let cube = Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        let mut g = SparseGrid::new(3, cube, degree, |_, _, _| true);
        let mut x = seed;
        for v in g.values.iter_mut() {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            *v = ((x >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
        }
        let len = g.record_len();
        for s in 0..g.slots() {
            g.values[s * len] *= 2.0; // opacities from ~0.07 to ~1 per sample
        }
        g
    }

    /// The distortion loss straight from its definition (O(n²)): the
    /// reference the backward pass's prefix sums are checked against.
    fn distortion(samples: &[(f32, f32)], delta: f32) -> f32 {
        let mut l = 0.0;
        for &(wi, si) in samples {
            for &(wj, sj) in samples {
                l += wi * wj * (si - sj).abs();
            }
            l += wi * wi * delta / 3.0;
        }
        l
    }

    fn loss(grid: &SparseGrid, ray: &GridRay, p: &MarchParams, target: Vec3) -> f64 {
        let c = render_ray(grid, &MarchBox::of(grid), ray, p).rgb;
        f64::from((c - target).length_squared())
    }

    /// Checks `analytic` (one gradient per stored value) against central
    /// differences of `loss_of` over every value of `grid`; at least 20
    /// must be non-trivial.
    fn check_against_fd(
        grid: &SparseGrid,
        analytic: &[f32],
        what: &str,
        loss_of: impl Fn(&SparseGrid) -> f64,
    ) {
        assert_eq!(analytic.len(), grid.values.len());
        let mut checked = 0;
        for (i, &an) in analytic.iter().enumerate() {
            let h = 1e-2;
            let mut a = grid.clone();
            a.values[i] += h;
            let mut b = grid.clone();
            b.values[i] -= h;
            let fd = (loss_of(&a) - loss_of(&b)) / (2.0 * f64::from(h));
            let an = f64::from(an);
            assert!(
                (fd - an).abs() <= 2e-3 + 2e-2 * fd.abs().max(an.abs()),
                "{what}, value {i}: analytic {an}, finite difference {fd}"
            );
            if an.abs() > 1e-4 {
                checked += 1;
            }
        }
        assert!(checked > 20, "{what}: only {checked} non-trivial gradients");
    }

    /// The samples' (weight, colour) of a ray.
    fn samples_of(
        grid: &SparseGrid,
        ray: &GridRay,
        p: &MarchParams,
    ) -> (Vec<(f32, Vec3, f32)>, f32) {
        let mut v = Vec::new();
        let out = with_layout!(grid, forward_collect(grid, ray, p, &mut v));
        (v, out.transmittance)
    }

    fn forward_collect<const S: usize, const K: usize>(
        grid: &SparseGrid,
        ray: &GridRay,
        p: &MarchParams,
        v: &mut Vec<(f32, Vec3, f32)>,
    ) -> RayOut {
        forward::<S, K>(grid, &MarchBox::of(grid), ray, p, |s| {
            v.push((s.w, Vec3::from_array(s.rgb), s.t))
        })
    }

    /// The regularised loss with the per-sample weights of `fixed_w`
    /// held (the gradient treats them as constants).
    fn reg_loss(
        grid: &SparseGrid,
        ray: &GridRay,
        p: &MarchParams,
        target: Vec3,
        reg: &RayLoss,
        fixed_w: &[f32],
    ) -> f64 {
        let (samples, t_end) = samples_of(grid, ray, p);
        assert_eq!(samples.len(), fixed_w.len());
        let per: f32 = samples
            .iter()
            .zip(fixed_w)
            .map(|((_, c, _), w)| w * (*c - target).length_squared())
            .sum();
        let res = grid.res as f32;
        let ws: Vec<(f32, f32)> = samples.iter().map(|(w, _, t)| (*w, t / res)).collect();
        let dist = distortion(&ws, p.step / res);
        loss(grid, ray, p, target)
            + 3.0
                * f64::from(reg.rgbper * per + reg.entropy * entropy(t_end) + reg.distortion * dist)
    }

    /// The distortion loss alone against finite differences (its weights
    /// are not held: the whole chain through τ is checked).
    #[test]
    fn distortion_matches_finite_differences() {
        regularised_check(&RayLoss {
            distortion: 2.0,
            ..RayLoss::default()
        });
    }

    /// Finite differences of the regularised loss (weights of the
    /// per-sample term held, as the backward pass holds them).
    #[test]
    fn regularisers_match_finite_differences() {
        regularised_check(&RayLoss {
            rgbper: 0.7,
            entropy: 0.4,
            distortion: 1.3,
            skip_weight: 0.0,
        });
    }

    fn regularised_check(reg: &RayLoss) {
        let grid = random_grid(1, 11);
        let bx = MarchBox::of(&grid);
        let p = MarchParams {
            step: 0.41,
            background: Vec3::ONE,
        };
        let ray = GridRay {
            origin: Vec3::new(-0.5, 0.25, 0.3),
            dir: Vec3::new(1.0, 0.5, 0.35).normalize(),
            jitter: 0.6,
        };
        // Lower densities: the ray must end partly transparent for the
        // entropy to have a gradient.
        let mut grid = grid;
        let len = grid.record_len();
        for s in 0..grid.slots() {
            grid.values[s * len] -= 3.0;
        }
        let target = Vec3::new(0.3, 0.5, 0.9);
        let (base, t_end) = samples_of(&grid, &ray, &p);
        assert!((0.05..0.95).contains(&t_end), "T_end {t_end}");
        let fixed_w: Vec<f32> = base.iter().map(|s| s.0).collect();
        let mut scratch = Scratch::default();
        let mut grads = GradBuf::new(grid.slots(), len);
        train_ray(
            &grid,
            &bx,
            &ray,
            &p,
            target,
            1.0,
            reg,
            &mut scratch,
            &mut grads,
        );
        // The held weights: perturbing a density keeps the unperturbed
        // weights in the per-sample term, as the backward pass holds them.
        check_against_fd(&grid, &grads.grad, "regularised", |g| {
            reg_loss(g, &ray, &p, target, reg, &fixed_w)
        });
    }

    /// Finite differences of the loss against every stored value.
    #[test]
    fn backward_matches_finite_differences() {
        for degree in 0..=2 {
            let grid = random_grid(degree, 7 + u64::from(degree));
            let bx = MarchBox::of(&grid);
            let p = MarchParams {
                step: 0.37,
                background: Vec3::new(1.0, 0.9, 0.8),
            };
            let ray = GridRay {
                origin: Vec3::new(-0.5, 0.3, 0.2),
                dir: Vec3::new(1.0, 0.55, 0.4).normalize(),
                jitter: 0.3,
            };
            let target = Vec3::new(0.2, 0.6, 0.4);
            let mut scratch = Scratch::default();
            let mut grads = GradBuf::new(grid.slots(), grid.record_len());
            let out = train_ray(
                &grid,
                &bx,
                &ray,
                &p,
                target,
                1.0,
                &RayLoss::default(),
                &mut scratch,
                &mut grads,
            );
            assert!(out.samples > 5);
            check_against_fd(&grid, &grads.grad, &format!("degree {degree}"), |g| {
                loss(g, &ray, &p, target)
            });
        }
    }

    #[test]
    fn empty_grid_shows_the_background() {
        let cube = Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        let g = SparseGrid::new(4, cube, 1, |_, _, _| false);
        let p = MarchParams {
            step: 0.5,
            background: Vec3::ONE,
        };
        let ray = GridRay {
            origin: Vec3::new(-1.0, 2.0, 2.0),
            dir: Vec3::X,
            jitter: 0.5,
        };
        let out = render_ray(&g, &MarchBox::of(&g), &ray, &p);
        assert_eq!(out.rgb, Vec3::ONE);
        assert_eq!(out.samples, 0);
    }
}
