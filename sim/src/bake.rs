//! The baker: MobileNeRF-format assets at any grid g and patch p from posed
//! captures, without training.
//!
//! A fast, honest stand-in for MobileNeRF's hours of GPU training that
//! produces the same kind of asset from the same kind of input:
//!
//! 1. [`carve`]: a g×g×g voxel grid over the object's cube is carved with
//!    every training silhouette (visual hull, conservative footprint test);
//! 2. [`quads`]: one axis-aligned quad on every face between an occupied and
//!    an empty cell (MobileNeRF's grid-aligned quads);
//! 3. [`atlas`]: each quad owns a p×p texel cell in RGBA8 pages of at most
//!    4096²;
//! 4. [`texels`]: each texel's colour is the average of the training views
//!    that see its surface point (depth test against a depth map of the
//!    carved quads), weighted toward frontal views;
//! 5. [`mlp_fit`]: an analytic 11→16→16→3 MLP plus a per-channel byte code
//!    such that the renderer's shader turns each texel's features back into
//!    its colour;
//! 6. [`sweep`]: many (g, p) bakes in parallel, measured, cached, as a CSV.
//!
//! Design notes and measured figures: `docs/baking.md`.

pub mod atlas;
pub mod carve;
pub mod compare;
pub mod mlp_fit;
pub mod quads;
pub mod sweep;
pub mod texels;
pub mod trained;

use glam::Vec3;
use image::{GrayImage, RgbaImage};
use std::time::Instant;

use crate::asset::{self, Asset, AssetError, AtlasPair, Mlp, Shape};
use crate::camera::Camera;
use nerflex_core::raster::{Quad as RasterQuad, Vertex};

/// Version of the baking algorithm; part of every sweep cache key, so a
/// change to the baker that changes its output must bump it.
pub const BAKER_VERSION: u32 = 1;

/// Errors of the baker (bad parameters or unusable views).
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A parameter is out of its range.
    #[error("{0}")]
    BadParam(String),
    /// The views cannot be used (none, sizes disagree with the cameras, …).
    #[error("{0}")]
    BadViews(String),
    /// Carving removed every voxel: silhouettes and cameras disagree.
    #[error("carving left no occupied voxel (do the masks and cameras belong together, is the object label right?)")]
    Empty,
}

/// An axis-aligned box in world units (z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Aabb {
    /// The smallest cube with the same centre that contains the box.
    pub fn cube(&self) -> Aabb {
        let c = 0.5 * (self.min + self.max);
        let half = 0.5 * (self.max - self.min).max_element();
        Aabb {
            min: c - Vec3::splat(half),
            max: c + Vec3::splat(half),
        }
    }

    /// The box grown by `margin` on every side.
    pub fn grown(&self, margin: f32) -> Aabb {
        Aabb {
            min: self.min - Vec3::splat(margin),
            max: self.max + Vec3::splat(margin),
        }
    }

    fn is_valid(&self) -> bool {
        self.min.is_finite() && self.max.is_finite() && self.min.cmplt(self.max).all()
    }
}

/// Which pixels of a view belong to the object being baked.
#[derive(Debug, Clone, Copy)]
pub enum Silhouette<'a> {
    /// The image's alpha is the object's coverage (single-object captures
    /// such as the real NeRF-synthetic ones).
    Alpha,
    /// An instance mask: the object owns the pixels whose value equals
    /// `label` (object index + 1); its coverage there is the image alpha.
    Instance {
        /// The instance mask, same size as the image.
        mask: &'a GrayImage,
        /// The object's label in the mask.
        label: u8,
    },
}

/// One posed training view of the object.
#[derive(Debug, Clone, Copy)]
pub struct BakeView<'a> {
    /// The camera (its intrinsics must match the image size).
    pub camera: Camera,
    /// RGBA image, alpha = coverage, straight (not premultiplied) colour.
    pub image: &'a RgbaImage,
    /// Which pixels are the object.
    pub silhouette: Silhouette<'a>,
}

impl BakeView<'_> {
    /// The object's coverage at pixel (x, y) in [0, 255].
    #[inline]
    pub fn coverage(&self, x: u32, y: u32) -> u8 {
        let a = self.image.get_pixel(x, y).0[3];
        match self.silhouette {
            Silhouette::Alpha => a,
            Silhouette::Instance { mask, label } => {
                if mask.get_pixel(x, y).0[0] == label {
                    a
                } else {
                    0
                }
            }
        }
    }
}

/// Bake settings.
#[derive(Debug, Clone, PartialEq)]
pub struct BakeParams {
    /// Voxels per edge of the object's cube (g).
    pub grid: u32,
    /// Texels per edge of a quad's patch (p); the quad's corners sit on the
    /// centres of the patch's corner texels, as in MobileNeRF (p = 17).
    pub patch: u32,
    /// Where to look for the object (world units). `None`: the NeRF-synthetic
    /// extent [-1.5, 1.5]³. The baked cube is the bounding cube of a coarse
    /// carve inside this box, see [`carve::object_cube`].
    pub search_box: Option<Aabb>,
    /// Exponent of the frontal weighting cos(θ)^k of a view's contribution
    /// to a texel (θ between the face normal and the direction to the camera).
    pub frontal_power: f32,
    /// Which voxels survive carving ([`Geometry::Boundary`] only).
    pub voxel_test: carve::VoxelTest,
    /// How quads are placed.
    pub geometry: Geometry,
}

/// How the baker places quads on the grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Geometry {
    /// One quad per face between a carved (occupied) voxel and an empty one;
    /// texels are emptied only where a thin voxel sticks out of the hull.
    Boundary,
    /// Every face of the voxels the hull's surface crosses ("shell" voxels),
    /// with texel alpha = inside the hull, and the layers no training view
    /// sees dropped: shape finer than a voxel comes from the texels, as in
    /// MobileNeRF, so the patch p sharpens silhouettes too.
    #[default]
    Shell,
}

impl BakeParams {
    /// Defaults for a given (g, p).
    pub fn new(grid: u32, patch: u32) -> Self {
        Self {
            grid,
            patch,
            search_box: None,
            frontal_power: 1.0,
            voxel_test: carve::VoxelTest::Centre,
            geometry: Geometry::Shell,
        }
    }

    fn validate(&self) -> Result<(), BakeError> {
        if !(1..=1024).contains(&self.grid) {
            return Err(BakeError::BadParam(format!(
                "--grid {} is outside 1..=1024",
                self.grid
            )));
        }
        if !(2..=atlas::MAX_PAGE_TEXELS).contains(&self.patch) {
            return Err(BakeError::BadParam(format!(
                "--patch {} is outside 2..={}",
                self.patch,
                atlas::MAX_PAGE_TEXELS
            )));
        }
        if !(self.frontal_power.is_finite() && self.frontal_power >= 0.0) {
            return Err(BakeError::BadParam(format!(
                "frontal power {} must be a finite number ≥ 0",
                self.frontal_power
            )));
        }
        if let Some(b) = self.search_box {
            if !b.is_valid() {
                return Err(BakeError::BadParam(format!(
                    "search box {b:?} is empty or not finite"
                )));
            }
        }
        Ok(())
    }
}

/// Wall-clock time of each stage, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Silhouette tables, the object's cube and the voxel grid.
    pub carve_s: f64,
    /// Quads and their texel occupancy.
    pub quads_s: f64,
    /// Image pyramids and depth maps of every view.
    pub views_s: f64,
    /// Texel colours.
    pub colour_s: f64,
    /// Atlas layout and filling.
    pub atlas_s: f64,
}

impl StageTimes {
    /// The sum of the stages.
    pub fn total_s(&self) -> f64 {
        self.carve_s + self.quads_s + self.views_s + self.colour_s + self.atlas_s
    }
}

/// Counts and timings of one bake.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BakeStats {
    /// Occupied voxels after carving.
    pub occupied_voxels: u64,
    /// Texels that some view saw (depth test passed).
    pub seen_texels: u64,
    /// Occupied texels no view saw; they take the colour of their quad's
    /// seen texels (or, if none, of the facing views without depth test).
    pub unseen_texels: u64,
    /// Empty texels (outside the visual hull), stored as feat0.R = 0.
    pub empty_texels: u64,
    /// (texel, view) pairs that gave the seen texels colour: each seen
    /// texel averages `view_samples / seen_texels` views on average.
    pub view_samples: u64,
    /// Stage timings.
    pub times: StageTimes,
}

/// One baked object, ready to write in the MobileNeRF export layout.
#[derive(Debug, Clone)]
pub struct BakedObject {
    /// The bake settings.
    pub params: BakeParams,
    /// The cube the grid spans (world units).
    pub cube: Aabb,
    /// Quads, in atlas order: quad `i` owns cell `i` of [`Self::atlas`].
    pub quads: Vec<quads::Quad>,
    /// The two feature atlases, page by page.
    pub atlas: atlas::Atlas,
    /// The MLP that decodes the features (`W[in][out]` layout).
    pub mlp: mlp_fit::MlpWeights,
    /// Counts and timings.
    pub stats: BakeStats,
}

impl BakedObject {
    /// GPU-resident bytes: every page of both atlases decoded as RGBA8.
    pub fn gpu_bytes(&self) -> u64 {
        self.atlas.gpu_bytes()
    }

    /// The asset in the MobileNeRF export layout (one shape per atlas page),
    /// ready for [`Asset::write`] and the renderer. Consumes the bake so
    /// the (large) pages move instead of being copied.
    pub fn into_asset(self) -> Result<Asset, AssetError> {
        let layout = &self.atlas.layout;
        let mut shapes = Vec::with_capacity(self.atlas.pages.len());
        for (i, page) in self.atlas.pages.into_iter().enumerate() {
            let quads = page_quads(&self.quads, layout, self.params.patch, i)?;
            shapes.push(Shape {
                index: i,
                quads,
                atlas: AtlasPair::new(page.feat0, page.feat1)?,
            });
        }
        let mlp = Mlp::new(self.mlp).map_err(|cause| AssetError::Mlp {
            path: "mlp.json".into(),
            cause,
        })?;
        Ok(Asset {
            mlp,
            obj_num: shapes.len(),
            shapes,
            file_bytes: 0,
        })
    }
}

/// The renderer's quads of atlas page `page` of `layout` at patch `patch`,
/// `quads` in atlas order: each corner at its cell's corner texel centre.
pub fn page_quads(
    quads: &[quads::Quad],
    layout: &atlas::AtlasLayout,
    patch: u32,
    page: usize,
) -> Result<Vec<RasterQuad>, AssetError> {
    let last = (patch - 1) as f32;
    // Corner texel offsets in export order (see `quads::Quad`).
    let tex = [(0.0, 0.0), (0.0, last), (last, 0.0), (last, last)];
    let pl = layout.pages[page];
    let (w, h) = layout.page_size(page);
    (pl.first_quad..pl.first_quad + pl.quads)
        .map(|qi| {
            let cell = layout
                .cell(qi)
                .ok_or_else(|| AssetError::Invalid(format!("quad {qi} has no atlas cell")))?;
            let corners = quads
                .get(qi)
                .ok_or_else(|| AssetError::Invalid(format!("quad {qi} is missing")))?
                .corners();
            let v = |k: usize| {
                let (tx, ty) = tex[k];
                Vertex::at_texel(
                    corners[k].to_array(),
                    cell.x as f32 + tx + 0.5,
                    cell.y as f32 + ty + 0.5,
                    w,
                    h,
                )
            };
            Ok(RasterQuad::new([v(0), v(1), v(2), v(3)]))
        })
        .collect()
}

/// Bytes the files of `asset` take in the export layout: exactly what
/// [`Asset::write`] writes (same encoders), computed in memory so a sweep
/// need not touch the disk.
pub fn file_bytes(asset: &Asset) -> Result<u64, AssetError> {
    use rayon::prelude::*;
    let json = asset::mlp_json::to_string(asset.mlp.weights(), asset.obj_num).len() as u64;
    let shapes: Result<Vec<u64>, AssetError> = asset
        .shapes
        .par_iter()
        .map(|s| {
            let obj = asset::obj::to_string(&s.quads).len() as u64;
            let png = |img: &image::RgbaImage| {
                asset::png_io::encode_rgba8(img)
                    .map(|b| b.len() as u64)
                    .map_err(|msg| AssetError::Png {
                        path: format!("shape{}", s.index).into(),
                        msg,
                    })
            };
            let (a, b) = rayon::join(|| png(s.atlas.feat0()), || png(s.atlas.feat1()));
            Ok(obj + a? + b?)
        })
        .collect();
    Ok(json + shapes?.iter().sum::<u64>())
}

/// Bytes the texel stages hold per texel: occupancy before and after the
/// quad filter (1 + 1), colour (3), the two RGBA atlas pages (8), rounded up.
const BYTES_PER_TEXEL: u128 = 16;

/// Refuses a bake whose texel buffers (quads × p² texels) would not fit in
/// memory, before allocating them (an allocation failure aborts).
fn texel_memory(quads: usize, patch: u32) -> Result<(), BakeError> {
    let texels = quads as u128 * u128::from(patch) * u128::from(patch);
    crate::validate::memory(
        &format!("--patch {patch} with {quads} quads"),
        texels * BYTES_PER_TEXEL,
        &format!("{texels} texels at {BYTES_PER_TEXEL} B each (lower --patch or --grid)"),
    )
    .map_err(BakeError::BadParam)
}

/// Bakes one object from its training views.
pub fn bake(views: &[BakeView<'_>], params: &BakeParams) -> Result<BakedObject, BakeError> {
    params.validate()?;
    validate_views(views)?;
    let t0 = Instant::now();
    let search = params.search_box.unwrap_or(carve::NERF_SYNTHETIC_BOX);
    let silhouettes = carve::Silhouettes::new(views);
    let cube = carve::object_cube(&silhouettes, &search).ok_or(BakeError::Empty)?;
    let p2 = (params.patch * params.patch) as usize;
    let t1;
    let (boundary, all_occ, voxel, occupied) = match params.geometry {
        Geometry::Boundary => {
            let grid = carve::carve(&silhouettes, &cube, params.grid, params.voxel_test);
            t1 = Instant::now();
            let quads = quads::boundary_quads(&grid);
            texel_memory(quads.len(), params.patch)?;
            let occ = carve::texel_occupancy(&silhouettes, &grid, &quads, params.patch);
            (quads, occ, grid.voxel, grid.occupied_count())
        }
        Geometry::Shell => {
            let grid = carve::shell(&silhouettes, &cube, params.grid);
            t1 = Instant::now();
            let quads = quads::shell_quads(&grid);
            texel_memory(quads.len(), params.patch)?;
            let occ = carve::texel_occupancy_hull(&silhouettes, &quads, params.patch);
            let n = grid.count(carve::VoxelClass::Shell) + grid.count(carve::VoxelClass::Full);
            (quads, occ, grid.voxel, n)
        }
    };
    drop(silhouettes);
    if occupied == 0 {
        return Err(BakeError::Empty);
    }
    // Quads whose every texel is empty are dropped (nothing to draw).
    let (quads, occupancy) = keep_quads(&boundary, &all_occ, p2, |_, occ| occ.iter().any(|&o| o));
    drop(all_occ);
    let t2 = Instant::now();
    let prepared = texels::PreparedViews::new(views, &quads, &occupancy, params.patch);
    let t3 = Instant::now();
    let mut settings = texels::TexelSettings::new(params.patch, voxel);
    settings.frontal_power = params.frontal_power;
    settings.two_sided = params.geometry == Geometry::Shell;
    let colours = texels::colour_quads(&prepared, &quads, &occupancy, &settings);
    drop(prepared);
    let t4 = Instant::now();
    // Shell layers no training view sees are hidden behind others: drop
    // them. (Boundary quads are the only surface there is: they keep a
    // colour from the facing views.)
    let keep: Vec<bool> = match params.geometry {
        Geometry::Shell => colours.seen.iter().map(|&n| n > 0).collect(),
        Geometry::Boundary => vec![true; quads.len()],
    };
    let (quads, occupancy) = keep_quads(&quads, &occupancy, p2, |i, _| keep[i]);
    let rgb: Vec<[u8; 3]> = colours
        .rgb
        .chunks(p2)
        .zip(&keep)
        .filter(|(_, &k)| k)
        .flat_map(|(c, _)| c.iter().copied())
        .collect();
    let seen: u64 = colours.seen.iter().map(|&n| u64::from(n)).sum();
    let view_samples: u64 = colours
        .view_samples
        .iter()
        .zip(&keep)
        .filter(|(_, &k)| k)
        .map(|(&n, _)| u64::from(n))
        .sum();
    let occupied_texels = occupancy.iter().filter(|&&o| o).count() as u64;
    let layout = atlas::AtlasLayout::new(quads.len(), params.patch);
    let (mlp, code) = mlp_fit::design();
    let atlas = texels::write_atlas(&rgb, &occupancy, &layout, &code);
    let t5 = Instant::now();
    let counts = (
        seen,
        occupied_texels.saturating_sub(seen),
        occupancy.len() as u64 - occupied_texels,
    );
    Ok(BakedObject {
        params: params.clone(),
        cube,
        quads,
        atlas,
        mlp,
        stats: BakeStats {
            occupied_voxels: occupied,
            seen_texels: counts.0,
            unseen_texels: counts.1,
            empty_texels: counts.2,
            view_samples,
            times: StageTimes {
                carve_s: (t1 - t0).as_secs_f64(),
                quads_s: (t2 - t1).as_secs_f64(),
                views_s: (t3 - t2).as_secs_f64(),
                colour_s: (t4 - t3).as_secs_f64(),
                atlas_s: (t5 - t4).as_secs_f64(),
            },
        },
    })
}

/// The quads for which `keep(index, occupancy)` holds, with their
/// occupancy.
fn keep_quads(
    quads: &[quads::Quad],
    occupancy: &[bool],
    p2: usize,
    keep: impl Fn(usize, &[bool]) -> bool,
) -> (Vec<quads::Quad>, Vec<bool>) {
    let mut q_out = Vec::with_capacity(quads.len());
    let mut o_out = Vec::with_capacity(occupancy.len());
    for (i, (q, occ)) in quads.iter().zip(occupancy.chunks(p2)).enumerate() {
        if keep(i, occ) {
            q_out.push(*q);
            o_out.extend_from_slice(occ);
        }
    }
    (q_out, o_out)
}

fn validate_views(views: &[BakeView<'_>]) -> Result<(), BakeError> {
    if views.is_empty() {
        return Err(BakeError::BadViews("no training views".into()));
    }
    for (i, v) in views.iter().enumerate() {
        let k = &v.camera.intrinsics;
        // Cameras built in code are checked as the files' are (finite and
        // bounded in f32): a huge value would carve garbage or panic.
        let c2w = v.camera.c2w.to_cols_array();
        for (what, x) in [("fx", k.fx), ("fy", k.fy), ("cx", k.cx), ("cy", k.cy)]
            .into_iter()
            .chain(c2w.iter().map(|&x| ("c2w", x)))
        {
            crate::validate::f32_finite(what, x)
                .map_err(|e| BakeError::BadViews(format!("view {i}: camera {e}")))?;
        }
        if (k.width, k.height) != v.image.dimensions() {
            return Err(BakeError::BadViews(format!(
                "view {i}: image is {}×{} but its camera is {}×{}",
                v.image.width(),
                v.image.height(),
                k.width,
                k.height
            )));
        }
        if let Silhouette::Instance { mask, .. } = v.silhouette {
            if mask.dimensions() != v.image.dimensions() {
                return Err(BakeError::BadViews(format!(
                    "view {i}: mask is {}×{} but the image is {}×{}",
                    mask.width(),
                    mask.height(),
                    v.image.width(),
                    v.image.height()
                )));
            }
        }
    }
    Ok(())
}
