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
pub mod close;
pub mod depth;
pub mod depthcarve;
pub mod export;
pub mod extract;
pub mod featgrid;
pub mod fill;
pub mod finetune;
pub mod gbuffer;
pub mod init;
pub mod lattice_choice;
pub mod net;
pub mod nets;
pub mod novel;
pub mod sampling;
pub mod threshold;
pub mod visibility;

use glam::Vec3;
use std::time::{Duration, Instant};

use super::atlas::AtlasLayout;
use super::{BakeError, BakeParams, BakeStats, BakeView, BakedObject, StageTimes};
use crate::train::field::RadianceField;

pub use finetune::{FinetuneReport, FinetuneSettings};
pub use init::FitSettings;

/// Longest run of neighbouring pixels the fine-tune's order keeps
/// together (`--finetune-run`; a batch is 8192 pixels).
const MAX_FINETUNE_RUN: u32 = 1024;

/// Most rounds of the depth carve (each is a G-buffer pass and a march
/// per training pixel; lego was measured with two).
pub const MAX_DEPTH_CARVE_ROUNDS: u32 = 8;

/// Version of the trained baker: part of sweep cache keys (3: session 16's
/// visibility rounds and their fixed-point judgement; 4: session 18's
/// closing of the planes' texel opacity; 5: session 20's fine-tune through
/// the renderer's supersampling where a voxel spans fewer than 4 pixels,
/// [`sampling`]; 6: session 23's hull carve within a 1-pixel radius of a
/// texel's projection instead of the 3 × 3 pixels around it; 7: session
/// 26's visibility judged in blocks of up to a pixel,
/// [`visibility::auto_block`]; 8: session 27's surface threshold lowered
/// where the photos' object rays miss it, [`threshold`]; 9: session 28's
/// texel opacity reaching a quarter voxel beyond each slab,
/// [`extract::SurfaceSettings::reach`]; 10: session 29's feature learning
/// rate halved to 0.015, [`finetune::FinetuneSettings`]; 11: session 30's
/// two visibility rounds on the planes, the earlier fine-tunes a quarter
/// of the last one's, over 2.5 epochs instead of 3,
/// [`visibility::round_epochs`]; 12: session 35's field inside bounded by
/// the visual hull before extraction, [`TrainedParams::hull_surface`]).
pub const TRAINED_BAKER_VERSION: u32 = 12;

/// The geometry a bake extracts from the field.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum GeometryKind {
    /// Per shell voxel, planar quads tilted onto the surface seen from
    /// each side ([`extract::extract_with`]).
    #[default]
    Planes,
    /// One connected mesh: a vertex per voxel the surface crosses, a quad
    /// around each crossing grid edge ([`nets::extract_nets`]; MobileNeRF's
    /// topology).
    Mesh,
    /// The mesh, and the planes in the voxels a feature thinner than a
    /// voxel crosses without a mesh vertex.
    MeshFilled,
}

/// The geometry `params` ask for on `surface`; `None` when the field has
/// no inside.
pub fn extract_geometry(
    surface: &extract::Surface<'_>,
    params: &TrainedParams,
) -> Option<extract::Geometry> {
    let (g, p) = (params.grid, params.patch);
    match params.geometry {
        GeometryKind::Planes => extract::extract_with(surface, g, p, &params.surface),
        GeometryKind::Mesh => nets::extract_nets(surface, g, p, params.surface.refine, None),
        GeometryKind::MeshFilled => {
            nets::extract_nets(surface, g, p, params.surface.refine, Some(&params.surface))
        }
    }
}

/// The hull lookup that bounds `surface` when `params.hull_surface` asks
/// for it: over the cube of the field's own inside, at g voxels per edge
/// within 32…256, its open voxels settled where the field stays within
/// the hull ([`super::carve::HullLookup::settle_within`]: on lego
/// (128, 17) nine in ten, so the bound costs about 3 s of extraction).
pub fn hull_lookup<'s>(
    surface: &extract::Surface<'_>,
    sil: Option<&'s super::carve::Silhouettes>,
    params: &TrainedParams,
) -> Option<(super::carve::HullLookup<'s>, HullBoundReport)> {
    let sil = sil.filter(|_| params.hull_surface)?;
    let t = Instant::now();
    let cube = extract::object_cube(surface)?;
    let g = params.grid.clamp(32, 256);
    let mut lookup = super::carve::HullLookup::new(sil, &cube, g);
    let (outside, inside, open) = lookup.counts();
    let settled = lookup.settle_within(|x| surface.inside(x));
    // Exact (the halves' verdicts are the point test's); the extraction's
    // inside tests in the voxels left open then project into fewer views.
    lookup.split_open();
    let report = HullBoundReport {
        grid: g,
        outside,
        inside,
        open,
        settled,
        seconds: t.elapsed().as_secs_f64(),
    };
    Some((lookup, report))
}

/// How the visual hull bounded the field's inside ([`hull_lookup`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HullBoundReport {
    /// Voxels per edge of the lookup.
    pub grid: u32,
    /// Lookup voxels wholly outside the hull.
    pub outside: u64,
    /// Lookup voxels wholly inside it.
    pub inside: u64,
    /// Lookup voxels the hull's surface may cross.
    pub open: u64,
    /// Of those, voxels where the field stays within the hull (settled
    /// inside: the field alone decides there).
    pub settled: u64,
    /// Time to build and settle the lookup, seconds.
    pub seconds: f64,
}

/// The planner's choice of geometry as the baker's (the scene file names
/// only the two geometries that have profiles).
impl From<crate::geometry::Geometry> for GeometryKind {
    fn from(g: crate::geometry::Geometry) -> GeometryKind {
        match g {
            crate::geometry::Geometry::Planes => GeometryKind::Planes,
            crate::geometry::Geometry::Mesh => GeometryKind::Mesh,
        }
    }
}

impl GeometryKind {
    /// The visibility rounds a bake of this geometry runs unless told
    /// otherwise (`nerflex bake` without `--visibility-rounds`, and the
    /// pipeline's bake store): one on the planes, none on the mesh (with or
    /// without planes), whose quads hide little (lego (256, 5): a round
    /// lost 0.16 dB; docs/baking.md, "Session 16").
    pub fn default_visibility_rounds(self) -> u32 {
        match self {
            GeometryKind::Planes => visibility::VisibilitySettings::default().rounds,
            GeometryKind::Mesh | GeometryKind::MeshFilled => 0,
        }
    }

    /// The closing of texel opacity a bake of this geometry takes unless
    /// told otherwise ([`TrainedParams::close`]): 3 on the planes (lego
    /// (128, 17) +0.27 dB, chair +0.11 dB; docs/baking.md, "Session 18"),
    /// none on the mesh (on lego (256, 5) K = 3 closes no texel).
    pub fn default_close(self) -> u32 {
        match self {
            GeometryKind::Planes => 3,
            GeometryKind::Mesh | GeometryKind::MeshFilled => 0,
        }
    }

    /// The hull carve's radius, pixels ([`TrainedParams::hull_radius`]),
    /// unless told otherwise: 1 on the planes (lego (128, 17) +0.51 dB over
    /// the 3 × 3 window; docs/baking.md, "Session 23"), 2 on the mesh. The
    /// mesh's vertices are means of crossings of the field's soft surface
    /// and stray from the photos' contour by more than the planes' texels
    /// do: at a radius of 1 the carve emptied texels across lego's front
    /// surfaces, so training pixels saw the mesh from behind six times as
    /// often (lego (256, 5): 26.21 dB against 29.02 at 2; docs/baking.md,
    /// "Session 25").
    pub fn default_hull_radius(self) -> f32 {
        match self {
            GeometryKind::Planes => 1.0,
            GeometryKind::Mesh | GeometryKind::MeshFilled => 2.0,
        }
    }
}

/// Settings of a bake from a field.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainedParams {
    /// Voxels per edge of the object's cube (g).
    pub grid: u32,
    /// Texels per quad edge (p).
    pub patch: u32,
    /// Opacity over half a field cell at which a point counts as inside.
    pub surface_alpha: f32,
    /// The share of the photos' object rays allowed to miss the inside:
    /// where more of them peak below `surface_alpha`'s density, the
    /// threshold comes down ([`threshold`]; 0: never).
    pub surface_miss: f32,
    /// Rounds of dropping the quads the training views show mostly
    /// against the background (each one more G-buffer pass; 0: none).
    pub carve_rounds: u32,
    /// Which geometry the quads form.
    pub geometry: GeometryKind,
    /// Where the quads go in each shell voxel (planes).
    pub surface: extract::SurfaceSettings,
    /// Before the hull carve, a transparent texel with at least this many
    /// opaque neighbours (of 8) in its patch becomes opaque
    /// ([`close::close`]; 0: off).
    pub close: u32,
    /// Empty the texels outside the training views' visual hull.
    pub hull_carve: bool,
    /// Bound the field's inside by the training views' visual hull before
    /// the quads are extracted ([`extract::Surface::bounded_by`]), so the
    /// planes sit on the hull where the field's surface reaches past it
    /// (baker version 12; without it, pawn (256, 9) lost 14 % of its
    /// held-out interior pixels to the hull carve).
    pub hull_surface: bool,
    /// A texel is outside only where a view shows background on every
    /// pixel whose centre lies within this many pixels of its projection
    /// (`carve::Silhouettes::with_radius`; baker version 6: 1.0, before
    /// it a whole pixel on every side of the projection's own; per
    /// geometry by default, [`GeometryKind::default_hull_radius`]).
    pub hull_radius: f32,
    /// Move the quads onto the field's half-transmittance depth
    /// ([`depth::correct`]; one more G-buffer pass).
    pub depth_correct: bool,
    /// Rounds of the depth carve ([`depthcarve::carve`]: texels training
    /// rays reach in front of the field's median depth go; each round one
    /// more G-buffer pass; 0: none).
    pub depth_carve_rounds: u32,
    /// The depth carve's slack, voxels.
    pub depth_carve_margin: f32,
    /// Whether to train through the renderer's 2 × 2 supersampling
    /// (`render::RenderOptions::supersample`, the default render): each
    /// training pixel shows up to four texels whose mean features the MLP
    /// reads, and partly covered pixels blend with white. By default only
    /// where a voxel spans fewer than [`sampling::SUPERSAMPLE_BELOW_PX`]
    /// pixels (where one sample per pixel loses most); above, it gains
    /// about 0.25 dB for 1.5–2× the bake time, which the 60 s bake at
    /// g = 128 cannot pay (`docs/baking.md`, "Session 20").
    pub sampling: sampling::FinetuneSampling,
    /// Cells per edge of the feature lattice over the object's cube
    /// (independent of g and p: the continuous appearance the texels
    /// sample); 0: [`auto_feature_res`].
    pub feature_res: u32,
    /// G-buffer pixels the MLP's initial fit samples.
    pub fit_samples: usize,
    /// The MLP's initial fit.
    pub fit: FitSettings,
    /// The fine-tune (its epochs split evenly over the visibility
    /// rounds' fine-tunes).
    pub finetune: FinetuneSettings,
    /// Texel opacity judged against the photos ([`visibility`]).
    pub visibility: visibility::VisibilitySettings,
    /// After the last fine-tune, every this many training views (from the
    /// first) are rasterized at the renderer's subsamples, and the nearest
    /// transparent texel of each subsample the photo calls object that
    /// meets nothing opaque becomes opaque ([`fill`]; 0: off).
    pub fill_holes: u32,
}

impl TrainedParams {
    /// Defaults at (g, p).
    pub fn new(grid: u32, patch: u32) -> Self {
        Self {
            grid,
            patch,
            surface_alpha: 0.05,
            surface_miss: 0.02,
            feature_res: 0,
            carve_rounds: 0,
            depth_correct: false,
            depth_carve_rounds: 0,
            depth_carve_margin: 1.0,
            sampling: sampling::FinetuneSampling::Auto,
            close: GeometryKind::Planes.default_close(),
            hull_carve: true,
            hull_surface: true,
            hull_radius: GeometryKind::Planes.default_hull_radius(),
            geometry: GeometryKind::Planes,
            surface: extract::SurfaceSettings::default(),
            fit_samples: 65_536,
            fit: FitSettings::default(),
            finetune: FinetuneSettings::default(),
            visibility: visibility::VisibilitySettings::default(),
            fill_holes: 0,
        }
    }

    /// Checks every setting, naming the flag of a bad one.
    pub fn validate(&self) -> Result<(), BakeError> {
        BakeParams::new(self.grid, self.patch).validate()?;
        if !(self.surface_alpha > 0.0 && self.surface_alpha < 1.0) {
            return Err(BakeError::BadParam(format!(
                "surface alpha {} must be in (0, 1)",
                self.surface_alpha
            )));
        }
        if !(0.0..0.5).contains(&self.surface_miss) {
            return Err(BakeError::BadParam(format!(
                "--surface-miss {} must be in [0, 0.5)",
                self.surface_miss
            )));
        }
        let sf = &self.surface;
        if !(sf.keep > 0.0 && sf.keep <= 1.0) {
            return Err(BakeError::BadParam(format!(
                "--surface-keep {} must be in (0, 1]",
                sf.keep
            )));
        }
        if !(0.0..=0.5).contains(&sf.grow) {
            return Err(BakeError::BadParam(format!(
                "--surface-grow {} must be in [0, 0.5]",
                sf.grow
            )));
        }
        if !(0.0..1.0).contains(&sf.reach) {
            return Err(BakeError::BadParam(format!(
                "--surface-reach {} must be in [0, 1)",
                sf.reach
            )));
        }
        if !(sf.depth > 0.0 && sf.depth < 1.0) {
            return Err(BakeError::BadParam(format!(
                "--surface-depth {} must be in (0, 1)",
                sf.depth
            )));
        }
        if !(1..=63).contains(&sf.sub) || sf.refine > 30 {
            return Err(BakeError::BadParam(format!(
                "surface sub-lattice {} must be in 1..=63 and refine {} at most 30",
                sf.sub, sf.refine
            )));
        }
        if self.geometry != GeometryKind::Planes && self.grid > nets::MAX_MESH_GRID {
            return Err(BakeError::BadParam(format!(
                "--grid {} is above {} for --surface mesh",
                self.grid,
                nets::MAX_MESH_GRID
            )));
        }
        if self.carve_rounds > 16 {
            return Err(BakeError::BadParam(format!(
                "--carve-rounds {} must be at most 16 (each is a G-buffer pass)",
                self.carve_rounds
            )));
        }
        if self.close > close::NEIGHBOURS {
            return Err(BakeError::BadParam(format!(
                "--surface-close {} must be at most {} (a texel's patch neighbours; 0: off)",
                self.close,
                close::NEIGHBOURS
            )));
        }
        if !(0.5..=16.0).contains(&self.hull_radius) {
            return Err(BakeError::BadParam(format!(
                "--hull-radius {} px must lie in [0.5, 16] (below ½ a texel's own pixel may fall outside the window)",
                self.hull_radius
            )));
        }
        if self.feature_res != 0 && !(4..=2048).contains(&self.feature_res) {
            return Err(BakeError::BadParam(format!(
                "--feature-res {} must be 0 (automatic) or in 4..=2048",
                self.feature_res
            )));
        }
        if !(self.finetune.epochs.is_finite() && self.finetune.epochs >= 0.0) {
            return Err(BakeError::BadParam(format!(
                "--epochs {} must be a finite number ≥ 0",
                self.finetune.epochs
            )));
        }
        if self.depth_carve_rounds > MAX_DEPTH_CARVE_ROUNDS {
            return Err(BakeError::BadParam(format!(
                "--depth-carve {} must be at most {MAX_DEPTH_CARVE_ROUNDS} (each round rasterizes every training view again)",
                self.depth_carve_rounds
            )));
        }
        if !(self.depth_carve_margin.is_finite() && self.depth_carve_margin >= 0.0) {
            return Err(BakeError::BadParam(format!(
                "--depth-carve-margin {} must be a finite number ≥ 0",
                self.depth_carve_margin
            )));
        }
        let v = &self.visibility;
        if v.rounds > visibility::MAX_ROUNDS {
            return Err(BakeError::BadParam(format!(
                "--visibility-rounds {} must be at most {} (each rasterizes every training view twice more)",
                v.rounds,
                visibility::MAX_ROUNDS
            )));
        }
        if !(v.margin.is_finite() && v.margin >= 0.0) {
            return Err(BakeError::BadParam(format!(
                "--visibility-margin {} must be a finite number ≥ 0",
                v.margin
            )));
        }
        if let Some(m) = v.grow {
            if !(m.is_finite() && m >= 0.0) {
                return Err(BakeError::BadParam(format!(
                    "--visibility-grow {m} must be a finite number ≥ 0"
                )));
            }
            // Growing happens in the rounds: without one it would do nothing.
            if v.rounds == 0 {
                return Err(BakeError::BadParam(
                    "--visibility-grow needs at least one visibility round (--visibility-rounds ≥ 1; the mesh has none by default)".into(),
                ));
            }
        }
        if v.block > visibility::MAX_BLOCK {
            return Err(BakeError::BadParam(format!(
                "--visibility-block {} must lie in [0, {}] (texels per block side; 0: automatic)",
                v.block,
                visibility::MAX_BLOCK
            )));
        }
        if v.block > 1 && v.rounds == 0 {
            return Err(BakeError::BadParam(
                "--visibility-block needs at least one visibility round (--visibility-rounds ≥ 1; the mesh has none by default)".into(),
            ));
        }
        let run = self.finetune.run;
        if !(1..=MAX_FINETUNE_RUN).contains(&run) {
            return Err(BakeError::BadParam(format!(
                "--finetune-run {run} must lie in [1, {MAX_FINETUNE_RUN}] (training pixels per run)"
            )));
        }
        let lr = self.finetune.lr_features;
        if !(lr.is_finite() && lr > 0.0 && lr <= 1.0) {
            return Err(BakeError::BadParam(format!(
                "--feature-lr {lr} must be in (0, 1]"
            )));
        }
        let share = v.tune_share;
        if !(share.is_finite() && share > 0.0 && share <= 1.0) {
            return Err(BakeError::BadParam(format!(
                "--visibility-tune-share {share} must be in (0, 1]"
            )));
        }
        let lr = self.finetune.lr_mlp;
        if !(lr.is_finite() && lr > 0.0 && lr <= 1.0) {
            return Err(BakeError::BadParam(format!(
                "--mlp-lr {lr} must be in (0, 1]"
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
    /// The feature lattice, its initial values and the MLP's fit.
    pub init_s: f64,
    /// The fine-tune (all rounds).
    pub finetune_s: f64,
    /// The visibility rounds' peels, judgements and G-buffers
    /// ([`visibility`]).
    pub visibility_s: f64,
    /// Atlas pages.
    pub atlas_s: f64,
}

/// Counts of a bake from a field.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrainedStats {
    /// The surface's density threshold and its check against the photos.
    pub threshold: threshold::ThresholdReport,
    /// The visual hull's bound on the field's inside, when set
    /// ([`TrainedParams::hull_surface`]).
    pub hull_bound: Option<HullBoundReport>,
    /// Voxels the surface crosses.
    pub shell_voxels: u64,
    /// Voxels wholly inside.
    pub full_voxels: u64,
    /// Quads with an opaque texel.
    pub extracted_quads: u64,
    /// Texels the closing made opaque ([`TrainedParams::close`]).
    pub closed_texels: u64,
    /// The move onto the field's visible depth.
    pub depth: depth::DepthReport,
    /// Quads dropped because the training views show them mostly against
    /// the background.
    pub carved_quads: u64,
    /// The depth carve, summed over its rounds.
    pub depth_carve: depthcarve::DepthCarveReport,
    /// Of the others, quads some training pixel shows (exported).
    pub kept_quads: u64,
    /// Opaque texels of the kept quads.
    pub opaque_texels: u64,
    /// Texels some training pixel shows.
    pub trained_texels: u64,
    /// Cells per edge of the feature lattice.
    pub lattice_res: u32,
    /// Vertices of the feature lattice.
    pub lattice_vertices: u64,
    /// Of those, vertices some training pixel's texel reads.
    pub reached_vertices: u64,
    /// Training pixels the geometry covers.
    pub train_pixels: u64,
    /// The voxel's edge in pixels as the training views see it (median;
    /// 0 when no view sees the cube).
    pub voxel_px: f32,
    /// Whether the fine-tune trained through the 2 × 2 supersampling.
    pub supersampled: bool,
    /// Covered training pixels that show a quad from behind (a geometry
    /// measure: 1–2 % on lego's mesh, 17–20 % on its planes;
    /// `docs/baking.md`, "Session 14").
    pub backface_pixels: u64,
    /// Mean squared error (per channel, [0, 1] units) of the MLP's initial
    /// fit to the training pixels.
    pub fit_mse: f32,
    /// The fine-tune.
    pub finetune: FinetuneReport,
    /// The visibility rounds (texels removed summed over rounds; the
    /// pixels and texels judged are the last round's).
    pub visibility: visibility::VisibilityReport,
    /// The hole fill ([`TrainedParams::fill_holes`]).
    pub fill: fill::FillReport,
    /// The virtual cameras' pass (`keep_novel`; its time is part of the
    /// G-buffers').
    pub novel: novel::NovelReport,
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

/// The feature lattice's default resolution: one cell per two pixels of
/// the object's cube as the training views see it (the median over views
/// of its edge in pixels at its centre's depth), in 4..=512. On lego at
/// 800 px that is 329 cells (session 29's bakes; 256-odd in session 5);
/// 1024 cells scored 0.3 dB lower, 256 and 512 within 0.1 dB
/// (docs/baking.md, "Session 5"), and a 96 px capture gets a lattice its
/// pixels can train. Coarser costs chair: 230 cells for its 287 lost
/// 0.31 dB (session 29).
pub fn auto_feature_res(cube: &super::Aabb, views: &[BakeView<'_>]) -> u32 {
    match sampling::cube_px(cube, views) {
        Some(px) => ((px / 2.0).round() as u32).clamp(4, 512),
        None => 256,
    }
}

/// The quads of `geo` some pixel of `gb` shows or `extra` flags (by
/// quad; shorter: the rest unflagged), their opacity, and each quad's new
/// index (`u32::MAX`: dropped).
fn keep_shown(
    geo: &extract::Geometry,
    gb: &gbuffer::GBuffers,
    p2: usize,
    extra: &[bool],
) -> (Vec<super::quads::Quad>, Vec<bool>, Vec<u32>) {
    use rayon::prelude::*;
    let nq = geo.quads.len();
    // Which quads some pixel shows: one flag array per rayon job, or-ed.
    let shown = (0..gb.pixels.len())
        .into_par_iter()
        .fold(
            || vec![false; nq],
            |mut hit, i| {
                for &t in gb.shown(i) {
                    hit[t as usize / p2] = true;
                }
                hit
            },
        )
        .reduce_with(|mut a, b| {
            a.iter_mut().zip(b).for_each(|(x, y)| *x |= y);
            a
        })
        .unwrap_or_else(|| vec![false; nq]);
    let mut new_index = vec![u32::MAX; nq];
    let mut quads = Vec::new();
    let mut opacity = Vec::new();
    for q in 0..nq {
        if shown[q] || extra.get(q) == Some(&true) {
            new_index[q] = quads.len() as u32;
            quads.push(geo.quads[q]);
            opacity.extend_from_slice(&geo.opacity[q * p2..(q + 1) * p2]);
        }
    }
    (quads, opacity, new_index)
}

/// Per-quad `flags` carried to the quads' new numbers ([`keep_shown`]'s
/// `new_index`; `u32::MAX` for a quad dropped), `n` quads in all.
fn renumbered(flags: &[bool], new_index: &[u32], n: usize) -> Vec<bool> {
    let mut out = vec![false; n];
    for (&f, &i) in flags.iter().zip(new_index) {
        if let Some(o) = out.get_mut(i as usize) {
            *o |= f;
        }
    }
    out
}

/// The training pixels of `gb` once the quads are renumbered by
/// `new_index` ([`keep_shown`]), each naming its texel's slot. Slots are
/// numbered in texel order, one per texel some pixel or subsample shows
/// (a relabelling only: the fine-tune reads a slot's taps, never its
/// number). Returns the pixels, each slot's texel (on `quads`) and how many
/// pixels see their quad from behind. In parallel: on lego at 800 px this
/// was a serial loop over 17.5 M pixels, most of the 2 s of main-thread
/// samples a profile put in [`bake`] itself (docs/baking.md, "Session 29").
/// The G-buffers are consumed: their vectors become the training pixels'
/// in place (0.5 GB of fresh pages a round on lego (128, 17), and fresh
/// pages are the dear part of memory on a VM: docs/baking.md, "Session 53").
fn train_pixels(
    mut gb: gbuffer::GBuffers,
    quads: &[super::quads::Quad],
    new_index: &[u32],
    p2: usize,
) -> (finetune::TrainPixels, Vec<u32>, u64) {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    let texel = |t: u32| new_index[t as usize / p2] as usize * p2 + t as usize % p2;
    let unused = u32::MAX;
    let mut slot_of: Vec<AtomicU32> = (0..quads.len() * p2)
        .into_par_iter()
        .map(|_| AtomicU32::new(unused))
        .collect();
    gb.pixels
        .par_iter()
        .for_each(|px| slot_of[texel(px.texel)].store(0, Relaxed));
    gb.subsamples.par_iter().for_each(|s| {
        for &t in s.iter().filter(|&&t| t != gbuffer::NO_TEXEL) {
            slot_of[texel(t)].store(0, Relaxed);
        }
    });
    let mut slot_texel = Vec::new();
    for (t, s) in slot_of.iter_mut().enumerate() {
        if *s.get_mut() != unused {
            *s.get_mut() = slot_texel.len() as u32;
            slot_texel.push(t as u32);
        }
    }
    let backface = gb
        .pixels
        .par_iter()
        .filter(|px| from_behind(&quads[new_index[px.texel as usize / p2] as usize], px.dir))
        .count() as u64;
    // Texels become slots in place (in parallel); then each `GPixel`
    // becomes a `TrainPixel` of the same size in the same allocation
    // (std collects a mapped `vec::IntoIter` in place: a streaming pass).
    let slot = |t: u32| slot_of[texel(t)].load(Relaxed);
    gb.pixels
        .par_iter_mut()
        .for_each(|px| px.texel = slot(px.texel));
    gb.subsamples.par_iter_mut().for_each(|s| {
        for t in s.iter_mut().filter(|t| **t != gbuffer::NO_TEXEL) {
            *t = slot(*t);
        }
    });
    let pixels = finetune::TrainPixels {
        pixels: gb
            .pixels
            .into_iter()
            .map(|px| finetune::TrainPixel {
                slot: px.texel,
                dir: px.dir,
                target: px.target,
            })
            .collect(),
        subsamples: gb.subsamples,
    };
    (pixels, slot_texel, backface)
}

/// Whether a pixel looking along `dir` sees quad `q` from behind (its
/// outward normal is `v × u`).
#[inline]
fn from_behind(q: &super::quads::Quad, dir: [f32; 3]) -> bool {
    Vec3::from_array(dir).dot(q.v.cross(q.u)) > 0.0
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
    // The field's copy for point queries (lego: a 228 MB lattice) serves
    // the geometry's steps and goes before the fine-tune's peak.
    let copy = field.for_point_queries();
    let points = copy.as_deref().unwrap_or(field);
    let threshold =
        threshold::surface_sigma(points, views, params.surface_alpha, params.surface_miss);
    let surface = extract::Surface::with_sigma(points, threshold.sigma);
    let sil = (params.hull_carve || params.hull_surface)
        .then(|| super::carve::Silhouettes::new(views).with_radius(params.hull_radius));
    let lookup = hull_lookup(&surface, sil.as_ref(), params);
    let hull_bound = lookup.as_ref().map(|l| l.1);
    let surface = match &lookup {
        Some(l) => surface.bounded_by(&l.0),
        None => surface,
    };
    let geo = extract_geometry(&surface, params).ok_or(BakeError::Empty)?;
    drop(lookup);
    let mut geo = geo;
    let voxel_px = sampling::voxel_px(&geo.cube, views, g);
    let supersample = params.sampling.supersampled(voxel_px);
    let visibility_settings = params.visibility.resolved(voxel_px, p);
    // Pinholes and slivers in the planes' texel opacity close first; the
    // hull carve then empties what that put outside a silhouette.
    let closed_texels = close::close(&mut geo.opacity, p, params.close);
    // A point on an opaque object projects onto its silhouette in every
    // view: texels that some training view shows as background go.
    if let (true, Some(sil)) = (params.hull_carve, &sil) {
        super::carve::carve_texels(sil, &geo.quads, p, &mut geo.opacity);
    }
    // 3 MB a view at 800 px: not kept through the G-buffers' peak.
    drop(sil);
    let t1 = Instant::now();

    // G-buffers through an export whose atlas carries only the opacity;
    // quads the training views show mostly against the background are
    // haze the field drew in the background's colour: drop them and look
    // again (what they hid may be more of it).
    let mut dropped_quads = 0u64;
    let mut round = 0;
    // With visibility rounds and no pass after this one, the first round's
    // two layers are rasterized here and give its G-buffers: one pass less.
    let peel_first = params.visibility.rounds > 0
        && params.carve_rounds == 0
        && params.depth_carve_rounds == 0
        && !params.depth_correct;
    let mut layers: Option<visibility::Peel> = None;
    let gb = loop {
        let gb = if peel_first {
            let peeled = visibility::peel(
                &geo,
                p,
                views,
                supersample,
                params.visibility.grow.is_some(),
            )?;
            let (gb, _) = peeled.gbuffers(&geo.opacity, supersample);
            layers = Some(peeled);
            gb
        } else {
            gbuffer::of_geometry(&geo, p, views, supersample)?
        };
        round += 1;
        if round > params.carve_rounds {
            break gb;
        }
        let nq = geo.quads.len();
        let mut votes = vec![0i32; nq];
        for i in 0..gb.pixels.len() {
            for &t in gb.shown(i) {
                votes[t as usize / p2] += 1;
            }
        }
        for &t in &gb.background {
            votes[t as usize / p2] -= 1;
        }
        let mut dropped = 0u64;
        for (q, &v) in votes.iter().enumerate() {
            if v < 0 {
                geo.opacity[q * p2..(q + 1) * p2].fill(false);
                dropped += 1;
            }
        }
        dropped_quads += dropped;
        if dropped == 0 {
            break gb;
        }
    };
    // Texels the training rays reach in front of the field's surface.
    let mut gb = gb;
    let mut depth_carve = depthcarve::DepthCarveReport::default();
    for _ in 0..params.depth_carve_rounds {
        let r = depthcarve::carve(points, &mut geo, p, &gb, views, params.depth_carve_margin);
        depth_carve.pixels_against += r.pixels_against;
        depth_carve.texels_carved += r.texels_carved;
        if r.texels_carved == 0 {
            break;
        }
        drop(gb);
        gb = gbuffer::of_geometry(&geo, p, views, supersample)?;
    }
    // Onto the depth the field's renders show, then look once more.
    let (gb, depth_report) = if params.depth_correct {
        let r = depth::correct(points, &mut geo.quads, p, geo.voxel, &gb, views);
        drop(gb);
        (gbuffer::of_geometry(&geo, p, views, supersample)?, r)
    } else {
        (gb, depth::DepthReport::default())
    };
    drop(copy);

    // Rounds of: keep the shown quads, build the training pixels, fit and
    // fine-tune; then (but the last) judge each shown texel against what
    // lies behind it and rasterize again ([`visibility`]).
    let rounds = params.visibility.rounds;
    let mut gb = gb;
    let mut grid: Option<featgrid::FeatureGrid> = None;
    let mut mlp = nerflex_core::shader::MlpWeights::ZERO;
    let mut fit_mse = 0.0;
    let mut reached = 0;
    let mut report = finetune::FinetuneReport::default();
    let mut visibility = visibility::VisibilityReport::default();
    let nq = geo.quads.len();
    let (mut t2, mut t3) = (t1, t1);
    let mut tune = Duration::ZERO;
    let mut train_pixel_count;
    let mut backface_pixels;
    let mut trained_texels;
    let mut round = 0;
    // With `keep_behind`, the quads of the last two-layer pass's layer
    // behind are kept as well (none before the first pass).
    let behind_of = |pe: &visibility::Peel, nq: usize| match params.visibility.keep_behind {
        true => pe.behind_quads(nq, p2),
        false => Vec::new(),
    };
    let mut also_keep: Vec<bool> = layers
        .as_ref()
        .map(|pe| behind_of(pe, geo.quads.len()))
        .unwrap_or_default();
    // The quads the virtual cameras show, in the current numbering.
    let mut novel_kept: Vec<bool> = Vec::new();
    let mut novel_report = novel::NovelReport::default();
    loop {
        // Keep the quads some training pixel shows; with `keep_behind`
        // also those behind them, and with `keep_novel` those a camera
        // between the training views shows first ([`novel`]): looked for
        // once, before the first round, and kept through the rounds (on
        // lego (128, 17) looking again before each round changed its
        // figures by 0.01 dB and cost two more passes of 3–4 s).
        if params.visibility.keep_novel && round == 0 {
            let t = Instant::now();
            let centre = 0.5 * (geo.cube.min + geo.cube.max);
            let cams = novel::virtual_cameras(views, centre);
            novel_kept = novel::shown_from(&geo, p, &cams, supersample)?;
            novel_report = novel::NovelReport {
                cameras: cams.len() as u32,
                quads: novel_kept.iter().filter(|&&k| k).count() as u64,
                seconds: t.elapsed().as_secs_f64(),
            };
        }
        also_keep.resize(also_keep.len().max(novel_kept.len()), false);
        for (k, s) in also_keep.iter_mut().zip(&novel_kept) {
            *k |= s;
        }
        let (quads, opacity, new_index) = keep_shown(&geo, &gb, p2, &also_keep);
        if !novel_kept.is_empty() {
            novel_kept = renumbered(&novel_kept, &new_index, quads.len());
        }
        if round == 0 {
            t2 = Instant::now();
        }
        geo.quads = quads;
        geo.opacity = opacity;
        let texel_point = |t: usize| geo.texel_point(p, t as u32);
        // The feature lattice around every opaque texel's point, built once:
        // later rounds make texels transparent, or (growing) opaque only
        // where the lattice reaches.
        let grid = grid.get_or_insert_with(|| {
            use rayon::prelude::*;
            let points: Vec<Vec3> = geo
                .opacity
                .par_iter()
                .enumerate()
                .filter(|(_, &o)| o)
                .map(|(t, _)| texel_point(t))
                .collect();
            let res = match params.feature_res {
                0 => auto_feature_res(&geo.cube, views),
                r => r,
            };
            featgrid::FeatureGrid::new(&geo.cube, res, &points)
        });

        // One entry per texel a pixel shows: how it reads the lattice.
        let slot_texel;
        let pixels;
        (pixels, slot_texel, backface_pixels) = train_pixels(gb, &geo.quads, &new_index, p2);
        train_pixel_count = pixels.len();
        trained_texels = slot_texel.len() as u64;
        let taps: Vec<featgrid::Taps> = {
            use rayon::prelude::*;
            slot_texel
                .par_iter()
                .map(|&t| grid.taps(texel_point(t as usize)))
                .collect::<Option<_>>()
                .ok_or_else(|| {
                    BakeError::BadParam("a shown texel lies outside the feature lattice".into())
                })?
        };
        if round == 0 {
            let (values, r) = init::splat(grid, &pixels, &taps, field);
            reached = r;
            grid.values = values;
            let stride = (pixels.len() / params.fit_samples.max(1)).max(1);
            let samples: Vec<init::FitSample> = {
                use rayon::prelude::*;
                (0..pixels.len())
                    .into_par_iter()
                    .step_by(stride)
                    .map(|i| pixels.get(i))
                    .filter(|px| px.full())
                    .map(|px| init::FitSample {
                        feat: px.features(&taps, &grid.values),
                        dir: px.dir,
                        target: px.target,
                    })
                    .collect()
            };
            (mlp, fit_mse) = init::fit_mlp(&samples, &params.fit);
            drop(samples);
            t3 = Instant::now();
        }

        // The fine-tune's epochs split over the rounds.
        let mut settings = params.finetune;
        settings.epochs = visibility::round_epochs(
            params.finetune.epochs,
            rounds,
            params.visibility.tune_share,
            round,
        );
        let ft0 = Instant::now();
        let psnr = finetune::PsnrAt {
            before: round == 0,
            after: round == rounds,
        };
        let r = finetune::finetune(&pixels, &taps, &mut grid.values, &mut mlp, &settings, psnr);
        tune += ft0.elapsed();
        report = if round == 0 {
            r
        } else {
            finetune::FinetuneReport {
                steps: report.steps + r.steps,
                pixel_steps: report.pixel_steps + r.pixel_steps,
                psnr_after: r.psnr_after,
                seconds: report.seconds + r.seconds,
                ..report
            }
        };
        // Gone before the next round's peel and G-buffers take their place.
        drop((taps, pixels));
        if round == rounds {
            break;
        }
        round += 1;
        let v0 = Instant::now();
        let mut unkept = 0;
        let peeled = match layers.take() {
            Some(mut pe) => {
                unkept = pe.renumber(&new_index, p2);
                pe
            }
            None => visibility::peel(
                &geo,
                p,
                views,
                supersample,
                params.visibility.grow.is_some(),
            )?,
        };
        drop(new_index);
        let v1 = Instant::now();
        let r = visibility::prune(
            &mut geo,
            p,
            &peeled.views,
            grid,
            &mlp,
            supersample,
            &visibility_settings,
        );
        // The next G-buffers from the two layers: no third pass. Under
        // supersampling the views are rasterized anew instead: there a
        // subsample whose two layers both went is common where p is small
        // (lego (256, 5): 3.9 % of them), and the fine-tune on layers
        // that read it as uncovered lost 1.3 dB (docs/baking.md, "Session
        // 20"); at one sample per pixel a new pass changes nothing. (The
        // layers' buffers are still built there for their lost count, the
        // report's measure of it: one linear pass, small beside a new
        // rasterization.)
        also_keep = behind_of(&peeled, geo.quads.len());
        let (next, lost) = peeled.gbuffers(&geo.opacity, supersample);
        let tiles = peeled.tiles;
        drop(peeled);
        gb = if supersample {
            drop(next);
            gbuffer::of_geometry(&geo, p, views, supersample)?
        } else {
            next
        };
        visibility = visibility::VisibilityReport {
            pixels: r.pixels,
            shown_texels: r.shown_texels,
            removed_texels: visibility.removed_texels + r.removed_texels,
            nearer_texels: r.nearer_texels,
            added_texels: visibility.added_texels + r.added_texels,
            error_before: r.error_before,
            error_change: visibility.error_change + r.error_change,
            lost_subsamples: visibility.lost_subsamples + lost,
            block: visibility_settings.block,
            unkept_behind: visibility.unkept_behind + unkept,
            peel_tiles: (
                visibility.peel_tiles.0 + tiles.0,
                visibility.peel_tiles.1 + tiles.1,
            ),
            peel_s: visibility.peel_s + (v1 - v0).as_secs_f64(),
            judge_s: visibility.judge_s + v1.elapsed().as_secs_f64(),
        };
    }
    let grid = grid.ok_or(BakeError::Empty)?;
    // Holes the renderer's subsamples find where the photos show the
    // object, on texels the lattice reaches ([`fill`]).
    let mut fill_report = fill::FillReport::default();
    if params.fill_holes > 0 {
        let (texels, mut r) = fill::find(&geo, p, views, params.fill_holes as usize)?;
        for t in texels {
            let (q, i) = (t as usize / p2, t % p2 as u32);
            let reached = geo
                .quads
                .get(q)
                .and_then(|quad| grid.taps(extract::texel_point(quad, p, i % p, i / p)))
                .is_some();
            if let (true, Some(o)) = (reached, geo.opacity.get_mut(t as usize)) {
                r.filled_texels += u64::from(!*o);
                *o = true;
            }
        }
        fill_report = r;
    }
    let t4 = Instant::now();
    let (quads, opacity) = (geo.quads, geo.opacity);
    let texel_point = |t: usize| {
        let (q, i) = (t / p2, (t % p2) as u32);
        extract::texel_point(&quads[q], p, i % p, i / p)
    };

    // Every opaque texel reads the lattice at its point.
    let texels: Vec<[u8; 8]> = {
        use rayon::prelude::*;
        opacity
            .par_iter()
            .enumerate()
            .map(|(t, &o)| {
                let Some(tp) = o.then(|| grid.taps(texel_point(t))).flatten() else {
                    return [0; 8];
                };
                let (f0, f1) = net::to_bytes(&tp.gather(&grid.values), true);
                [f0[0], f0[1], f0[2], f0[3], f1[0], f1[1], f1[2], f1[3]]
            })
            .collect()
    };
    let layout = AtlasLayout::new(quads.len(), p);
    let atlas = export::atlas(&layout, &texels);
    let t5 = Instant::now();

    let opaque = opacity.iter().filter(|&&o| o).count() as u64;
    let times = TrainedTimes {
        extract_s: (t1 - t0).as_secs_f64(),
        gbuffer_s: (t2 - t1).as_secs_f64(),
        init_s: (t3 - t2).as_secs_f64(),
        finetune_s: tune.as_secs_f64(),
        visibility_s: ((t4 - t3).saturating_sub(tune).as_secs_f64() - fill_report.seconds).max(0.0),
        atlas_s: (t5 - t4).as_secs_f64(),
    };
    let stats = TrainedStats {
        threshold,
        hull_bound,
        shell_voxels: geo.shell_voxels,
        full_voxels: geo.full_voxels,
        extracted_quads: nq as u64,
        carved_quads: dropped_quads,
        closed_texels,
        depth_carve,
        depth: depth_report,
        kept_quads: quads.len() as u64,
        opaque_texels: opaque,
        trained_texels,
        lattice_res: grid.res(),
        lattice_vertices: grid.len() as u64,
        reached_vertices: reached as u64,
        train_pixels: train_pixel_count as u64,
        voxel_px: voxel_px.unwrap_or(0.0),
        supersampled: supersample,
        backface_pixels,
        fit_mse,
        finetune: report,
        visibility,
        fill: fill_report,
        novel: novel_report,
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A flag and a way to spoil its setting.
    type Spoil = (&'static str, fn(&mut TrainedParams));

    #[test]
    fn renumbered_flags_follow_their_quads_and_drop_with_them() {
        // Quads 0 and 2 dropped; 1 → 0, 3 → 1; flags on 1 and 2.
        let new_index = [u32::MAX, 0, u32::MAX, 1];
        let flags = [false, true, true, false];
        assert_eq!(renumbered(&flags, &new_index, 2), [true, false]);
        // Fewer flags than quads (none set past the end) is no error.
        assert_eq!(renumbered(&[false, false], &new_index, 2), [false, false]);
    }

    /// The outward normal is `v × u` (`quads::Quad`'s convention): a pixel
    /// on that side looks at the front, one on the other side at the back.
    #[test]
    fn from_behind_follows_the_quads_outward_normal() {
        let q = super::super::quads::Quad {
            origin: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::Z,
            normal: Vec3::Z.cross(Vec3::X),
            voxel: [0; 3],
            twist: Vec3::ZERO,
        };
        assert_eq!(q.normal, Vec3::Y);
        // A camera on +y looks along −y at the front.
        assert!(!from_behind(&q, [0.0, -1.0, 0.0]));
        assert!(!from_behind(&q, [0.6, -0.8, 0.0]));
        // A camera on −y sees the back.
        assert!(from_behind(&q, [0.0, 1.0, 0.0]));
        assert!(from_behind(&q, [0.0, 0.6, -0.8]));
    }

    #[test]
    fn bad_settings_name_their_flag() {
        assert!(TrainedParams::new(32, 5).validate().is_ok());
        let bad: [Spoil; 36] = [
            ("--surface-miss", |p| p.surface_miss = 0.5),
            ("--surface-miss", |p| p.surface_miss = -0.01),
            ("--surface-miss", |p| p.surface_miss = f32::NAN),
            ("--surface-keep", |p| p.surface.keep = f32::NAN),
            ("--surface-close", |p| p.close = 9),
            ("--surface-grow", |p| p.surface.grow = 2.0),
            ("--surface-reach", |p| p.surface.reach = 1.0),
            ("--surface-reach", |p| p.surface.reach = -0.1),
            ("--surface-reach", |p| p.surface.reach = f32::NAN),
            ("--surface-depth", |p| p.surface.depth = 1.0),
            ("--surface-depth", |p| p.surface.depth = f32::NAN),
            ("--carve-rounds", |p| p.carve_rounds = 1000),
            ("--feature-res", |p| p.feature_res = 1),
            ("--epochs", |p| p.finetune.epochs = f32::INFINITY),
            ("--depth-carve", |p| p.depth_carve_rounds = 1000),
            ("--depth-carve-margin", |p| p.depth_carve_margin = -1.0),
            ("--depth-carve-margin", |p| p.depth_carve_margin = f32::NAN),
            ("--finetune-run", |p| p.finetune.run = 0),
            ("--finetune-run", |p| p.finetune.run = 100_000),
            ("--feature-lr", |p| p.finetune.lr_features = 0.0),
            ("--hull-radius", |p| p.hull_radius = 0.25),
            ("--hull-radius", |p| p.hull_radius = f32::NAN),
            ("--feature-lr", |p| p.finetune.lr_features = f32::NAN),
            ("--mlp-lr", |p| p.finetune.lr_mlp = 0.0),
            ("--mlp-lr", |p| p.finetune.lr_mlp = f32::INFINITY),
            ("--visibility-tune-share", |p| p.visibility.tune_share = 0.0),
            ("--visibility-tune-share", |p| {
                p.visibility.tune_share = f32::NAN
            }),
            ("--visibility-rounds", |p| p.visibility.rounds = 100),
            ("--visibility-margin", |p| p.visibility.margin = -0.5),
            ("--visibility-margin", |p| p.visibility.margin = f32::NAN),
            ("--visibility-block", |p| p.visibility.block = 65),
            ("--visibility-block", |p| {
                p.visibility.block = 2;
                p.visibility.rounds = 0;
            }),
            ("--visibility-grow", |p| p.visibility.grow = Some(-1.0)),
            ("--visibility-grow", |p| {
                p.visibility.grow = Some(f32::INFINITY)
            }),
            ("--visibility-grow", |p| {
                p.visibility.grow = Some(0.4);
                p.visibility.rounds = 0;
            }),
            ("--surface mesh", |p| {
                p.geometry = GeometryKind::Mesh;
                p.grid = 1024;
            }),
        ];
        for (flag, spoil) in bad {
            let mut p = TrainedParams::new(32, 5);
            spoil(&mut p);
            let e = p.validate().expect_err(flag).to_string();
            assert!(e.contains(flag), "{flag}: {e}");
        }
    }
}
