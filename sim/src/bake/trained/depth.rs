//! Moving each quad onto the depth the field's renders show.
//!
//! The extraction places quads on an isosurface of the field's density,
//! but what a volume render shows sits where the ray's transmittance
//! falls to one half; on a trained field's soft surface the two differ by
//! a field cell or more (~3 px on lego at 800 px), and a texel that far
//! off the visible surface shows different surface points from different
//! views (parallax): the fine-tune cannot fit them all (lego's training
//! pixels stayed at 24 dB whatever the feature lattice's resolution).
//!
//! So, for every training pixel a quad shows, the field is marched along
//! the pixel's ray over a window of ± [`WINDOW`] voxels around the texel
//! point the pixel shows (transmittance restarted at the window's start),
//! and the depth where it reaches one half is compared with the texel's
//! along the quad's axis. Each quad moves along its axis by the median of
//! those differences (at most [`MAX_SHIFT`] voxels).

use glam::Vec3;
use rayon::prelude::*;

use super::super::quads::Quad;
use super::super::BakeView;
use super::extract::texel_point;
use super::gbuffer::GBuffers;
use crate::train::field::RadianceField;

/// Half-width of the searched window along a ray, voxels.
pub const WINDOW: f32 = 2.0;
/// Largest move of a quad, voxels.
pub const MAX_SHIFT: f32 = 1.0;
/// Fewest pixels with a crossing a quad needs to move.
pub const MIN_PIXELS: usize = 3;

/// Along the ray `o + t·d`, the `t` in `[t0, t1]` where the transmittance
/// from `t0` falls to one half (sampled every `step`, linear between
/// samples), if it does.
fn half_depth(
    field: &dyn RadianceField,
    o: Vec3,
    d: Vec3,
    t0: f32,
    t1: f32,
    step: f32,
) -> Option<f32> {
    // Optical depth of one half: −ln 0.5.
    const HALF: f32 = std::f32::consts::LN_2;
    let mut tau = 0.0f32;
    let mut t = t0;
    while t < t1 {
        let dt = field.density(o + (t + 0.5 * step) * d) * step;
        if tau + dt >= HALF {
            return Some(t + step * (HALF - tau) / dt.max(f32::MIN_POSITIVE));
        }
        tau += dt;
        t += step;
    }
    None
}

/// What the correction did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DepthReport {
    /// Quads moved.
    pub moved: u64,
    /// Mean |move| of the moved quads, voxels.
    pub mean_shift: f32,
    /// Pixels whose window held a half-opacity depth.
    pub crossings: u64,
}

/// Moves `quads` (p×p texels each, `voxel` world units) onto the field's
/// half-transmittance depth seen by the training pixels of `gb` (the
/// G-buffers of `views` with these quads).
pub fn correct(
    field: &dyn RadianceField,
    quads: &mut [Quad],
    p: u32,
    voxel: f32,
    gb: &GBuffers,
    views: &[BakeView<'_>],
) -> DepthReport {
    let p2 = p * p;
    let b = field.bounds();
    let step = 0.25 * (b.max - b.min).max_element() / field.resolution().max(1) as f32;
    let origins = gb.origins(views);
    // (quad, the move along its outward normal that puts this pixel's hit
    // on the half-transmittance depth).
    let mut diffs: Vec<(u32, f32)> = gb
        .pixels
        .par_iter()
        .zip(origins.par_iter())
        .filter_map(|(px, &o)| {
            let q = &quads[(px.texel / p2) as usize];
            let t = px.texel % p2;
            let x = texel_point(q, p, t % p, t / p);
            let d = Vec3::from_array(px.dir);
            let tx = (x - o).dot(d);
            let h = half_depth(field, o, d, tx - WINDOW * voxel, tx + WINDOW * voxel, step)?;
            // Moving the quad by a·n moves the hit along the ray by
            // a / (d·n) (d·n < 0: the ray looks at the quad's front).
            let dn = d.dot(q.normal);
            if dn > -0.2 {
                return None;
            }
            Some((px.texel / p2, (h - tx) * dn))
        })
        .collect();
    let crossings = diffs.len() as u64;
    diffs.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut moved = 0u64;
    let mut total = 0.0f32;
    let mut i = 0;
    while i < diffs.len() {
        let q = diffs[i].0;
        let mut j = i;
        while j < diffs.len() && diffs[j].0 == q {
            j += 1;
        }
        if j - i >= MIN_PIXELS {
            let a = diffs[(i + j) / 2]
                .1
                .clamp(-MAX_SHIFT * voxel, MAX_SHIFT * voxel);
            let quad = &mut quads[q as usize];
            // The normal is an axis: the move keeps the quad over its
            // cross-section (and so its texels' opacity pattern).
            quad.origin += a * quad.normal;
            moved += 1;
            total += a.abs() / voxel;
        }
        i = j;
    }
    DepthReport {
        moved,
        mean_shift: if moved > 0 { total / moved as f32 } else { 0.0 },
        crossings,
    }
}
