//! MobileNeRF-format baked assets: load, build in code, write.
//!
//! A folder holds `mlp.json` and, for each shape `i` in `0..obj_num`,
//! `shape{i}.obj` + `shape{i}.pngfeat0.png` + `shape{i}.pngfeat1.png`
//! (format: `../shared/data/README.md`). [`Asset::load`] reads the shapes
//! that exist and lists the missing ones ([`Asset::missing_shapes`]);
//! [`Asset::write`] writes exactly that layout, so the baker can build an
//! [`Asset`] in memory and save it.
//!
//! In memory:
//! - positions are in the **z-up world frame** of the NeRF-synthetic cameras
//!   (the OBJ stores `(x, z, −y)`; [`obj`] converts both ways). The real
//!   drums shape spans x ∈ [−1.14, 1.14] in these units, the same units as
//!   the dataset's cameras (about 4 from the origin): no scale is applied
//!   (the official web viewer's 0.1 scale is for three.js only).
//! - texture coordinates are the OBJ's `(u, v)`, `v = 1 − y/height`
//!   (see [`nerflex_core::raster::Vertex`]).
//! - each shape owns one pair of RGBA8 atlas pages.

pub mod mlp_json;
pub mod obj;
pub mod png_io;

use crate::output::{self, OutputError, StagedDir};
/// The `image` crate whose `RgbaImage` holds atlas pages (re-exported so
/// code building an [`Asset`] uses the same version).
pub use image;
use image::RgbaImage;
use nerflex_core::raster::{Atlas, Quad};
use nerflex_core::shader::{FixedMlp, MlpWeights, ShaderError};
use std::path::{Path, PathBuf};

/// Errors reading or writing an asset; each names the file (and line or key).
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// A file could not be read or written.
    // The cause is in the message, not chained (`{:#}` would print it twice).
    #[error("{path}: {cause}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// A malformed OBJ line.
    #[error("{path}:{line}: {msg}")]
    Obj {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        msg: String,
    },
    /// A PNG that cannot be decoded or is not what the format requires.
    #[error("{path}: {msg}")]
    Png {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        msg: String,
    },
    /// Malformed `mlp.json` (syntax, missing key, wrong matrix shape).
    #[error("{path}: {msg}")]
    Json {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the key.
        msg: String,
    },
    /// Weights the fixed-point shader cannot represent.
    #[error("{path}: {cause}")]
    Mlp {
        /// The file.
        path: PathBuf,
        /// The cause, naming the key.
        cause: ShaderError,
    },
    /// Something else is inconsistent (names the file or shape).
    #[error("{0}")]
    Invalid(String),
}

/// The MLP weights together with their fixed-point conversion (always valid).
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    weights: MlpWeights,
    fixed: FixedMlp,
}

impl Mlp {
    /// Checks and converts the weights.
    pub fn new(weights: MlpWeights) -> Result<Self, ShaderError> {
        let fixed = FixedMlp::from_weights(&weights)?;
        Ok(Self { weights, fixed })
    }

    /// The float weights.
    pub fn weights(&self) -> &MlpWeights {
        &self.weights
    }

    /// The fixed-point tables.
    pub fn fixed(&self) -> &FixedMlp {
        &self.fixed
    }
}

/// Two RGBA8 feature pages of the same size (feat0, feat1).
#[derive(Clone, PartialEq)]
pub struct AtlasPair {
    feat0: RgbaImage,
    feat1: RgbaImage,
}

impl std::fmt::Debug for AtlasPair {
    // Sizes only: the pages are megabytes.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.dimensions();
        write!(f, "AtlasPair({w}×{h} RGBA8 ×2)")
    }
}

impl AtlasPair {
    /// Checks that both pages have the same, usable size.
    pub fn new(feat0: RgbaImage, feat1: RgbaImage) -> Result<Self, AssetError> {
        if feat0.dimensions() != feat1.dimensions() {
            return Err(AssetError::Invalid(format!(
                "atlas pages differ in size: feat0 {}×{}, feat1 {}×{}",
                feat0.width(),
                feat0.height(),
                feat1.width(),
                feat1.height()
            )));
        }
        let (w, h) = feat0.dimensions();
        Atlas::new(w, h, feat0.as_raw(), feat1.as_raw())
            .map_err(|e| AssetError::Invalid(format!("atlas page of {w}×{h} texels: {e}")))?;
        Ok(Self { feat0, feat1 })
    }

    /// Page 0 (features 0..4).
    pub fn feat0(&self) -> &RgbaImage {
        &self.feat0
    }

    /// Page 1 (features 4..8).
    pub fn feat1(&self) -> &RgbaImage {
        &self.feat1
    }

    /// `(width, height)` in texels.
    pub fn dimensions(&self) -> (u32, u32) {
        self.feat0.dimensions()
    }

    /// The core renderer's view of the pages.
    pub fn atlas(&self) -> Atlas<'_> {
        let (w, h) = self.dimensions();
        // Checked in `new`; the fields cannot change afterwards.
        Atlas::new(w, h, self.feat0.as_raw(), self.feat1.as_raw())
            .expect("AtlasPair invariant: pages were validated in AtlasPair::new")
    }

    /// Decoded (GPU-resident) bytes of both pages.
    pub fn gpu_bytes(&self) -> u64 {
        let (w, h) = self.dimensions();
        2 * 4 * w as u64 * h as u64
    }
}

/// One shape file: its quads and its atlas pages.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    /// `i` of `shape{i}.*`.
    pub index: usize,
    /// Quads (and lone triangles) in file order, world z-up positions.
    pub quads: Vec<Quad>,
    /// Its feature pages.
    pub atlas: AtlasPair,
}

/// A MobileNeRF asset.
#[derive(Debug, Clone, PartialEq)]
pub struct Asset {
    /// The view-dependent MLP (`mlp.json`).
    pub mlp: Mlp,
    /// How many shape files the full export has (`obj_num`).
    pub obj_num: usize,
    /// The shapes present, by increasing index.
    pub shapes: Vec<Shape>,
    /// Bytes of the files it was loaded from (0 when built in memory).
    pub file_bytes: u64,
}

/// Sizes of an asset.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AssetReport {
    /// Shapes present.
    pub shapes: usize,
    /// Shape indices in `0..obj_num` that are absent.
    pub missing_shapes: Vec<usize>,
    /// Full quads (two triangles each).
    pub quads: usize,
    /// Lone triangles (quads whose empty half the export dropped).
    pub lone_triangles: usize,
    /// Triangles: `2·quads + lone_triangles`.
    pub triangles: usize,
    /// Vertices as the OBJ stores them: `4·quads + 3·lone_triangles`.
    pub vertices: usize,
    /// RGBA8 atlas pages (two per shape).
    pub atlas_pages: usize,
    /// Bytes of the files on disk (PNG-compressed); 0 if built in memory.
    pub file_bytes: u64,
    /// Bytes resident on a GPU: every page decoded to RGBA8.
    pub gpu_bytes: u64,
}

impl std::fmt::Display for AssetReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} shape(s), {} quads + {} lone triangles ({} triangles, {} vertices), {} atlas pages, {} file bytes ({:.1} MiB), {} GPU bytes ({:.1} MiB)",
            self.shapes,
            self.quads,
            self.lone_triangles,
            self.triangles,
            self.vertices,
            self.atlas_pages,
            self.file_bytes,
            self.file_bytes as f64 / 1048576.0,
            self.gpu_bytes,
            self.gpu_bytes as f64 / 1048576.0
        )
    }
}

/// File names of shape `i`: OBJ, feat0 PNG, feat1 PNG.
pub fn shape_files(i: usize) -> [String; 3] {
    [
        format!("shape{i}.obj"),
        format!("shape{i}.pngfeat0.png"),
        format!("shape{i}.pngfeat1.png"),
    ]
}

/// Largest `obj_num` accepted (a sanity limit on a malformed file).
pub const MAX_OBJ_NUM: usize = 4096;

fn file_len(path: &Path) -> Result<u64, AssetError> {
    std::fs::metadata(path)
        .map(|m| m.len())
        .map_err(|cause| AssetError::Io {
            path: path.to_path_buf(),
            cause,
        })
}

impl Asset {
    /// Loads an export folder. Shapes `0..obj_num` whose OBJ exists are
    /// loaded (both PNGs must then exist); the others are listed by
    /// [`Asset::missing_shapes`] and a warning naming them goes to stderr.
    /// At least one shape must exist.
    pub fn load(dir: &Path) -> Result<Asset, AssetError> {
        let mlp_path = dir.join("mlp.json");
        let (weights, obj_num) = mlp_json::read(&mlp_path)?;
        let mlp = Mlp::new(weights).map_err(|cause| AssetError::Mlp {
            path: mlp_path.clone(),
            cause,
        })?;
        let mut file_bytes = file_len(&mlp_path)?;
        let present: Vec<usize> = (0..obj_num)
            .filter(|&i| dir.join(&shape_files(i)[0]).is_file())
            .collect();
        if present.is_empty() {
            return Err(AssetError::Invalid(format!(
                "{}: no shape files: none of shape0.obj … shape{}.obj exists (obj_num = {obj_num} in mlp.json)",
                dir.display(),
                obj_num.saturating_sub(1)
            )));
        }
        let mut shapes = Vec::with_capacity(present.len());
        for i in present {
            let [o, p0, p1] = shape_files(i).map(|n| dir.join(n));
            for p in [&p0, &p1] {
                if !p.is_file() {
                    return Err(AssetError::Io {
                        path: p.clone(),
                        cause: std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            format!(
                                "missing: shape {i} has {} but not this atlas page",
                                o.display()
                            ),
                        ),
                    });
                }
            }
            // Decode the two pages and parse the OBJ in parallel.
            let ((f0, f1), quads) = rayon::join(
                || rayon::join(|| png_io::read_rgba8(&p0), || png_io::read_rgba8(&p1)),
                || obj::read(&o),
            );
            let (f0, f1, quads) = (f0?, f1?, quads?);
            if f0.dimensions() != f1.dimensions() {
                return Err(AssetError::Png {
                    path: p1.clone(),
                    msg: format!(
                        "wrong size {}×{}: {} is {}×{}",
                        f1.width(),
                        f1.height(),
                        p0.display(),
                        f0.width(),
                        f0.height()
                    ),
                });
            }
            let atlas = AtlasPair::new(f0, f1).map_err(|e| AssetError::Png {
                path: p0.clone(),
                msg: e.to_string(),
            })?;
            file_bytes += file_len(&o)? + file_len(&p0)? + file_len(&p1)?;
            shapes.push(Shape {
                index: i,
                quads,
                atlas,
            });
        }
        let asset = Asset {
            mlp,
            obj_num,
            shapes,
            file_bytes,
        };
        // An asset that draws nothing would render a blank picture and exit 0.
        for s in asset.shapes.iter().filter(|s| s.quads.is_empty()) {
            eprintln!(
                "warning: {}: no faces: shape {} draws nothing",
                dir.join(&shape_files(s.index)[0]).display(),
                s.index
            );
        }
        if asset.shapes.iter().all(|s| s.quads.is_empty()) {
            return Err(AssetError::Invalid(format!(
                "{}: the asset has no faces (every shape*.obj is empty): nothing to render",
                dir.display()
            )));
        }
        let missing = asset.missing_shapes();
        if !missing.is_empty() {
            eprintln!(
                "warning: {}: shape(s) {missing:?} of obj_num = {obj_num} are missing; loaded the {} present",
                dir.display(),
                asset.shapes.len()
            );
        }
        Ok(asset)
    }

    /// Shape indices in `0..obj_num` that are not present.
    pub fn missing_shapes(&self) -> Vec<usize> {
        (0..self.obj_num)
            .filter(|i| !self.shapes.iter().any(|s| s.index == *i))
            .collect()
    }

    /// Counts and sizes.
    pub fn report(&self) -> AssetReport {
        let quads = self
            .shapes
            .iter()
            .flat_map(|s| &s.quads)
            .filter(|q| !q.single_triangle)
            .count();
        let prims: usize = self.shapes.iter().map(|s| s.quads.len()).sum();
        let lone = prims - quads;
        AssetReport {
            shapes: self.shapes.len(),
            missing_shapes: self.missing_shapes(),
            quads,
            lone_triangles: lone,
            triangles: 2 * quads + lone,
            vertices: 4 * quads + 3 * lone,
            atlas_pages: 2 * self.shapes.len(),
            file_bytes: self.file_bytes,
            gpu_bytes: self.shapes.iter().map(|s| s.atlas.gpu_bytes()).sum(),
        }
    }

    /// Writes the export layout as the folder `dir`, replacing it whole:
    /// built beside it ([`Asset::write_staged`]) and renamed into place
    /// only once complete, so a failure leaves the old folder as it was.
    /// An existing `dir` holding anything but asset files is refused
    /// ([`is_asset_file`]): we never delete what we did not write.
    /// Returns the bytes written.
    pub fn write(&self, dir: &Path) -> Result<u64, AssetError> {
        let (staged, bytes) = self.write_staged(dir)?;
        commit_asset_dir(staged)?;
        Ok(bytes)
    }

    /// Builds the export folder beside `dir` without touching `dir`; the
    /// caller commits it with [`commit_asset_dir`] once everything else
    /// (e.g. a measurement) has succeeded, or drops it to discard it.
    pub fn write_staged(&self, dir: &Path) -> Result<(StagedDir, u64), AssetError> {
        let mut seen = std::collections::BTreeSet::new();
        for s in &self.shapes {
            if s.index >= self.obj_num || !seen.insert(s.index) {
                return Err(AssetError::Invalid(format!(
                    "shape index {} is duplicated or not below obj_num = {}",
                    s.index, self.obj_num
                )));
            }
        }
        if self.obj_num > MAX_OBJ_NUM {
            return Err(AssetError::Invalid(format!(
                "obj_num = {} exceeds {MAX_OBJ_NUM}",
                self.obj_num
            )));
        }
        // Refuse a foreign folder before any work.
        output::check_replaceable(dir, &is_asset_file, ASSET_DIR_HINT)?;
        let staged = StagedDir::new(dir)?;
        let bytes = self.write_into(staged.path())?;
        Ok((staged, bytes))
    }

    /// Writes the files into the existing folder `dir` (no staging).
    fn write_into(&self, dir: &Path) -> Result<u64, AssetError> {
        use rayon::prelude::*;
        let json = mlp_json::to_string(self.mlp.weights(), self.obj_num);
        let mut bytes = write_atomic(&dir.join("mlp.json"), json.as_bytes())?;
        // Every file of every shape is encoded and written as its own task,
        // PNGs first (the longest: each one deflate stream on one core), so
        // both cores stay busy to the end rather than pairing a page's two
        // PNGs and writing each shape's OBJ on one core.
        let tasks: Vec<(&Shape, usize)> = (0..3)
            .rev()
            .flat_map(|k| self.shapes.iter().map(move |s| (s, k)))
            .collect();
        let written: Vec<Result<u64, AssetError>> = tasks
            .par_iter()
            .with_max_len(1)
            .map(|&(s, k)| {
                let path = dir.join(&shape_files(s.index)[k]);
                let data = match k {
                    0 => obj::to_string(&s.quads).into_bytes(),
                    _ => png_io::encode_rgba8(if k == 1 {
                        s.atlas.feat0()
                    } else {
                        s.atlas.feat1()
                    })
                    .map_err(|msg| AssetError::Png {
                        path: path.clone(),
                        msg,
                    })?,
                };
                write_atomic(&path, &data)
            })
            .collect();
        for w in written {
            bytes += w?;
        }
        Ok(bytes)
    }
}

const ASSET_DIR_HINT: &str =
    "an asset folder is replaced whole; move that file away or choose another --out";

/// Moves a folder built by [`Asset::write_staged`] into place.
pub fn commit_asset_dir(staged: StagedDir) -> Result<(), AssetError> {
    Ok(staged.commit(&is_asset_file, ASSET_DIR_HINT)?)
}

/// True for the names an export folder holds: `mlp.json` and
/// `shape{i}.obj` / `shape{i}.pngfeat{0,1}.png`.
pub fn is_asset_file(name: &str) -> bool {
    if name == "mlp.json" {
        return true;
    }
    let Some(rest) = name.strip_prefix("shape") else {
        return false;
    };
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    digits > 0 && matches!(&rest[digits..], ".obj" | ".pngfeat0.png" | ".pngfeat1.png")
}

impl From<OutputError> for AssetError {
    fn from(e: OutputError) -> Self {
        AssetError::Invalid(e.to_string())
    }
}

/// Writes `data` to `path` atomically ([`output::write_file`]: a
/// temporary name unique to this writer, then a rename).
pub fn write_atomic(path: &Path, data: &[u8]) -> Result<u64, AssetError> {
    output::write_file(path, data).map_err(|e| match e {
        OutputError::Io { cause, .. } => AssetError::Io {
            path: path.to_path_buf(),
            cause,
        },
        other => other.into(),
    })
}
