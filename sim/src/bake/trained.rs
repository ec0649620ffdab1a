//! The trained baker: a MobileNeRF export at any (g, p) from a radiance
//! field, fine-tuned through the phone's shader.
//!
//! One interface: a field ([`RadianceField`]) + the capture it was trained
//! on (its training views) + (g, p) in, a [`BakedObject`] out (the same
//! type the visual-hull baker produces, so export, sizes and measurement
//! are shared). Stages, one module each:
//!
//! 1. [`extract`]: in each g³ voxel the field's surface crosses, quads
//!    tilted onto the surface (a plane fitted per axis and side; the voxel
//!    faces remain as `extract_voxel_faces`), binary texel opacity at p×p
//!    per quad where the texel's line meets the surface;
//! 2. [`gbuffer`]: each training view rasterized once by the renderer's
//!    own tile rasterizer into (quad, texel) ids; quads no training pixel
//!    shows are dropped (as MobileNeRF drops invisible quads);
//! 3. [`init`]: texel features from the field's colour, and the MLP fitted
//!    to the field's view-dependent colour;
//! 4. [`finetune`]: Adam on the seen texels' 8 features and the MLP against
//!    the training images, through [`net`]'s differentiable version of the
//!    deferred shading (8-bit features, straight-through);
//! 5. [`export`]: atlas pages in the existing layout; parallel PNG writing.
//!
//! [`analytic`] holds fields with known answers for tests and
//! measurements. Design and figures: `docs/baking.md`, "Baking from a
//! trained field".

pub mod analytic;
pub mod export;
pub mod extract;
pub mod finetune;
pub mod gbuffer;
pub mod init;
pub mod net;

use glam::Vec3;
use std::time::Instant;

use super::atlas::AtlasLayout;
use super::{BakeError, BakeParams, BakeStats, BakeView, BakedObject, StageTimes};
use crate::train::field::RadianceField;
use nerflex_core::shader::MlpWeights;

pub use finetune::{FinetuneReport, FinetuneSettings};
pub use init::FitSettings;

/// Version of the trained baker: part of sweep cache keys.
pub const TRAINED_BAKER_VERSION: u32 = 1;

/// Settings of a bake from a field.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainedParams {
    /// Voxels per edge of the object's cube (g).
    pub grid: u32,
    /// Texels per quad edge (p).
    pub patch: u32,
    /// Opacity over half a field cell at which a point counts as inside.
    pub surface_alpha: f32,
    /// G-buffer pixels the MLP's initial fit samples.
    pub fit_samples: usize,
    /// The MLP's initial fit.
    pub fit: FitSettings,
    /// The fine-tune.
    pub finetune: FinetuneSettings,
}

impl TrainedParams {
    /// Defaults at (g, p).
    pub fn new(grid: u32, patch: u32) -> Self {
        Self {
            grid,
            patch,
            surface_alpha: 0.05,
            fit_samples: 65_536,
            fit: FitSettings::default(),
            finetune: FinetuneSettings::default(),
        }
    }

    fn validate(&self) -> Result<(), BakeError> {
        BakeParams::new(self.grid, self.patch).validate()?;
        if !(self.surface_alpha > 0.0 && self.surface_alpha < 1.0) {
            return Err(BakeError::BadParam(format!(
                "surface alpha {} must be in (0, 1)",
                self.surface_alpha
            )));
        }
        if !(self.finetune.epochs.is_finite() && self.finetune.epochs >= 0.0) {
            return Err(BakeError::BadParam(format!(
                "--epochs {} must be a finite number ≥ 0",
                self.finetune.epochs
            )));
        }
        Ok(())
    }
}

/// Wall time of each stage, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrainedTimes {
    /// Cube, voxel classes, quads, texel opacity.
    pub extract_s: f64,
    /// G-buffers of every training view, quad visibility.
    pub gbuffer_s: f64,
    /// Texel features and the MLP's fit from the field.
    pub init_s: f64,
    /// The fine-tune.
    pub finetune_s: f64,
    /// Atlas pages.
    pub atlas_s: f64,
}

/// Counts of a bake from a field.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrainedStats {
    /// Voxels the surface crosses.
    pub shell_voxels: u64,
    /// Voxels wholly inside.
    pub full_voxels: u64,
    /// Quads with an opaque texel.
    pub extracted_quads: u64,
    /// Of those, quads some training pixel shows (exported).
    pub kept_quads: u64,
    /// Opaque texels of the kept quads.
    pub opaque_texels: u64,
    /// Texels some training pixel shows (fine-tuned).
    pub trained_texels: u64,
    /// Opaque texels no training pixel shows that took the features of
    /// the nearest fine-tuned texel of their quad (the others, on quads
    /// with no fine-tuned texel, keep the field's).
    pub filled_texels: u64,
    /// Training pixels the geometry covers.
    pub train_pixels: u64,
    /// Mean squared error (per channel, [0, 1] units) of the MLP's fit to
    /// the field's colours.
    pub fit_mse: f32,
    /// The fine-tune.
    pub finetune: FinetuneReport,
    /// Stage timings.
    pub times: TrainedTimes,
}

/// A bake from a field: the export-ready object and its counts.
#[derive(Debug, Clone)]
pub struct TrainedBake {
    /// The baked object (quads, atlas, MLP).
    pub baked: BakedObject,
    /// Counts and timings.
    pub stats: TrainedStats,
}

fn asset_error(e: crate::asset::AssetError) -> BakeError {
    BakeError::BadParam(format!("building the export failed: {e}"))
}

/// Bakes the export at (g, p) from `field`, fine-tuned on `views` (the
/// capture the field was trained on).
pub fn bake(
    field: &dyn RadianceField,
    views: &[BakeView<'_>],
    params: &TrainedParams,
) -> Result<TrainedBake, BakeError> {
    params.validate()?;
    super::validate_views(views)?;
    let (g, p) = (params.grid, params.patch);
    let p2 = (p * p) as usize;
    let t0 = Instant::now();
    let surface = extract::Surface::new(field, params.surface_alpha);
    let geo = extract::extract(&surface, g, p).ok_or(BakeError::Empty)?;
    let t1 = Instant::now();

    // G-buffers through an export whose atlas carries only the opacity.
    let layout = AtlasLayout::new(geo.quads.len(), p);
    let mask: Vec<[u8; 8]> = geo
        .opacity
        .iter()
        .map(|&o| [u8::from(o), 0, 0, 0, 0, 0, 0, 0])
        .collect();
    let provisional = BakedObject {
        params: BakeParams::new(g, p),
        cube: geo.cube,
        quads: geo.quads.clone(),
        atlas: export::atlas(&layout, &mask),
        mlp: MlpWeights::ZERO,
        stats: BakeStats::default(),
    }
    .into_asset()
    .map_err(asset_error)?;
    drop(mask);
    let gb = gbuffer::rasterize(&provisional, &layout, views)?;
    drop(provisional);

    // Keep the quads some training pixel shows.
    let nq = geo.quads.len();
    let mut hits = vec![0u32; nq];
    let mut dir_sum = vec![Vec3::ZERO; nq];
    for px in &gb.pixels {
        let q = px.texel as usize / p2;
        hits[q] += 1;
        dir_sum[q] += Vec3::from_array(px.dir);
    }
    let mut new_index = vec![u32::MAX; nq];
    let mut quads = Vec::new();
    let mut opacity = Vec::new();
    let mut dirs = Vec::new();
    for q in 0..nq {
        if hits[q] > 0 {
            new_index[q] = quads.len() as u32;
            quads.push(geo.quads[q]);
            opacity.extend_from_slice(&geo.opacity[q * p2..(q + 1) * p2]);
            dirs.push(dir_sum[q].normalize_or(-geo.quads[q].normal));
        }
    }
    let t2 = Instant::now();

    // One trained slot per texel a pixel shows.
    let mut slot_of = vec![u32::MAX; opacity.len()];
    let mut slot_texel: Vec<u32> = Vec::new();
    let pixels: Vec<finetune::TrainPixel> = gb
        .pixels
        .iter()
        .map(|px| {
            let q = new_index[px.texel as usize / p2] as usize;
            let t = q * p2 + px.texel as usize % p2;
            if slot_of[t] == u32::MAX {
                slot_of[t] = slot_texel.len() as u32;
                slot_texel.push(t as u32);
            }
            finetune::TrainPixel {
                slot: slot_of[t],
                dir: px.dir,
                target: px.target,
            }
        })
        .collect();
    drop(gb);
    drop(slot_of);
    drop(new_index);
    let mut trained = vec![false; opacity.len()];
    for &t in &slot_texel {
        trained[t as usize] = true;
    }
    // Features from the field, for the texels that keep them: the trained
    // ones (their starting point) and those of quads without a trained
    // texel (the others take a trained neighbour's after the fine-tune).
    let need: Vec<bool> = trained
        .chunks(p2)
        .flat_map(|tr| {
            let any = tr.iter().any(|&t| t);
            tr.iter().map(move |&t| t || !any)
        })
        .collect();
    let mut texels = init::texel_bytes(field, &quads, &opacity, &need, p, &dirs);
    drop(need);
    let mut features: Vec<[f32; net::FEATURES]> = slot_texel
        .iter()
        .map(|&t| init::decode_bytes(&texels[t as usize]))
        .collect();
    let stride = (pixels.len() / params.fit_samples.max(1)).max(1);
    let samples: Vec<init::FitSample> = {
        use rayon::prelude::*;
        pixels
            .par_iter()
            .step_by(stride)
            .map(|px| {
                let t = slot_texel[px.slot as usize] as usize;
                let q = &quads[t / p2];
                let x = extract::texel_point(q, p, (t % p2) as u32 % p, (t % p2) as u32 / p);
                let c = field.color(x, Vec3::from_array(px.dir));
                init::FitSample {
                    feat: net::quantise(&features[px.slot as usize]),
                    dir: px.dir,
                    target: c.clamp(Vec3::ZERO, Vec3::ONE).to_array(),
                }
            })
            .collect()
    };
    let (mut mlp, fit_mse) = init::fit_mlp(&samples, &params.fit);
    drop(samples);
    let t3 = Instant::now();

    let report = finetune::finetune(&pixels, &mut features, &mut mlp, &params.finetune);
    let t4 = Instant::now();

    for (f, &t) in features.iter().zip(&slot_texel) {
        let (f0, f1) = net::to_bytes(f, true);
        texels[t as usize] = [f0[0], f0[1], f0[2], f0[3], f1[0], f1[1], f1[2], f1[3]];
    }
    let filled = fill_from_trained(&mut texels, &trained, &opacity, p);
    drop(trained);
    let layout = AtlasLayout::new(quads.len(), p);
    let atlas = export::atlas(&layout, &texels);
    let t5 = Instant::now();

    let opaque = opacity.iter().filter(|&&o| o).count() as u64;
    let times = TrainedTimes {
        extract_s: (t1 - t0).as_secs_f64(),
        gbuffer_s: (t2 - t1).as_secs_f64(),
        init_s: (t3 - t2).as_secs_f64(),
        finetune_s: (t4 - t3).as_secs_f64(),
        atlas_s: (t5 - t4).as_secs_f64(),
    };
    let stats = TrainedStats {
        shell_voxels: geo.shell_voxels,
        full_voxels: geo.full_voxels,
        extracted_quads: nq as u64,
        kept_quads: quads.len() as u64,
        opaque_texels: opaque,
        trained_texels: slot_texel.len() as u64,
        filled_texels: filled,
        train_pixels: pixels.len() as u64,
        fit_mse,
        finetune: report,
        times,
    };
    let baked = BakedObject {
        params: BakeParams::new(g, p),
        cube: geo.cube,
        quads,
        atlas,
        mlp,
        stats: BakeStats {
            occupied_voxels: geo.shell_voxels + geo.full_voxels,
            seen_texels: stats.trained_texels,
            unseen_texels: opaque.saturating_sub(stats.trained_texels),
            empty_texels: opacity.len() as u64 - opaque,
            view_samples: stats.train_pixels,
            times: StageTimes {
                carve_s: times.extract_s,
                quads_s: 0.0,
                views_s: times.gbuffer_s,
                colour_s: times.init_s + times.finetune_s,
                atlas_s: times.atlas_s,
            },
        },
    };
    Ok(TrainedBake { baked, stats })
}

/// Gives each opaque texel no training pixel showed the bytes of the
/// nearest fine-tuned texel of the same quad (breadth-first over the p×p
/// grid, 4-neighbours: nearest in city-block distance): after the
/// fine-tune the MLP reads features as the fine-tune left them, so a
/// neighbour's code is a better guess than the field's initial one
/// (held-out views see such texels at patch edges and grazing angles).
/// Returns how many were filled.
fn fill_from_trained(texels: &mut [[u8; 8]], trained: &[bool], opacity: &[bool], p: u32) -> u64 {
    use rayon::prelude::*;
    let p = p as usize;
    let p2 = p * p;
    texels
        .par_chunks_mut(p2)
        .zip(trained.par_chunks(p2).zip(opacity.par_chunks(p2)))
        .map_init(
            || (Vec::with_capacity(p2), vec![false; p2]),
            |(queue, reached), (tex, (tr, op))| {
                queue.clear();
                for (t, r) in reached.iter_mut().enumerate() {
                    *r = tr[t];
                    if tr[t] {
                        queue.push(t);
                    }
                }
                if queue.is_empty() {
                    return 0;
                }
                let mut n = 0;
                let mut head = 0;
                while head < queue.len() {
                    let t = queue[head];
                    head += 1;
                    let (x, y) = (t % p, t / p);
                    let mut visit = |u: usize| {
                        if !reached[u] {
                            reached[u] = true;
                            // Empty texels pass the code on, then are cleared.
                            tex[u] = tex[t];
                            n += u64::from(op[u]);
                            queue.push(u);
                        }
                    };
                    if x > 0 {
                        visit(t - 1);
                    }
                    if x + 1 < p {
                        visit(t + 1);
                    }
                    if y > 0 {
                        visit(t - p);
                    }
                    if y + 1 < p {
                        visit(t + p);
                    }
                }
                // Empty texels carried codes only to pass them on: clear them.
                for (b, &o) in tex.iter_mut().zip(op.iter()) {
                    if !o {
                        *b = [0; 8];
                    }
                }
                n
            },
        )
        .sum()
}
