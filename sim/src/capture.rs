//! Posed captures in the NeRF-synthetic layout: one reader for built-in and
//! real folders, and one writer.
//!
//! A capture folder holds
//! - `transforms_train.json` (required) and `transforms_test.json` (optional:
//!   no file means no held-out views), read by [`crate::camera::Transforms`];
//! - one RGBA PNG per frame at `<file_path>.png` (alpha = coverage);
//! - optionally one **instance mask** per frame at `<file_path>_mask.png`:
//!   8-bit grayscale, 0 = background, k = object index + 1 (so at most 255
//!   objects); either every frame has a mask or none has;
//! - optionally `scene.json` ([`SceneInfo`]): the objects, their placement
//!   and world-space bounds.
//!
//! Real NeRF-synthetic folders have neither masks nor `scene.json`;
//! [`Frame::instance_mask`] then derives a single-object mask from alpha
//! ([`mask_from_alpha`]). Every frame of a capture has the same image size.

/// The image crate of the frame types, re-exported so users name the same version.
pub use image;

use crate::camera::{rows_from_mat4, Camera};
use crate::camera::{CameraError, FrameEntry, Intrinsics, Transforms};
use image::{DynamicImage, GrayImage, ImageFormat, RgbaImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// File name of the training transforms.
pub const TRAIN_TRANSFORMS: &str = "transforms_train.json";
/// File name of the held-out transforms.
pub const TEST_TRANSFORMS: &str = "transforms_test.json";
/// File name of the scene description.
pub const SCENE_FILE: &str = "scene.json";

/// The mask value segmentation writes where an object outside a group's
/// folder covers the view ([`SceneInfo::other_objects_mask_value`]).
pub const OTHER_OBJECTS_MASK_VALUE: u8 = 255;
/// Suffix that turns a frame's `file_path` into its mask's path.
pub const MASK_SUFFIX: &str = "_mask.png";
/// Value of [`SceneInfo::format`] this version writes and reads.
pub const SCENE_FORMAT: &str = "nerflex-scene/1";

/// Errors reading or writing a capture. Each names the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// A transforms file is missing, malformed or has a bad matrix.
    #[error(transparent)]
    Transforms(#[from] CameraError),
    /// The folder is not a capture.
    #[error("{dir}: not a NeRF-synthetic capture folder: {what}")]
    NotACapture {
        /// The folder.
        dir: PathBuf,
        /// What is missing.
        what: String,
    },
    /// A frame named by a transforms file has no image file.
    #[error("{path}: missing frame file (frame {index} of {transforms})")]
    MissingFrame {
        /// The expected image path.
        path: PathBuf,
        /// The transforms file naming it.
        transforms: PathBuf,
        /// The frame's index in that file.
        index: usize,
    },
    /// An image or mask file could not be decoded.
    #[error("{path}: cannot decode image: {source}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
    /// A frame image has no alpha channel.
    #[error("{path}: image has no alpha channel ({color}); capture frames must be RGBA with alpha = coverage")]
    NoAlpha {
        /// The file.
        path: PathBuf,
        /// Its colour type.
        color: String,
    },
    /// Frames differ in size.
    #[error("{path}: image is {width}×{height} but {first} is {first_width}×{first_height}; all frames of a capture must have one size")]
    SizeMismatch {
        /// The odd frame.
        path: PathBuf,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// The first frame.
        first: PathBuf,
        /// The first frame's width.
        first_width: u32,
        /// The first frame's height.
        first_height: u32,
    },
    /// A mask is not 8-bit grayscale.
    #[error("{path}: mask must be an 8-bit grayscale PNG, found {color}")]
    MaskFormat {
        /// The mask file.
        path: PathBuf,
        /// Its colour type.
        color: String,
    },
    /// A mask's size differs from its image's.
    #[error("{path}: mask is {width}×{height} but its image is {image_width}×{image_height}")]
    MaskSizeMismatch {
        /// The mask file.
        path: PathBuf,
        /// Mask width.
        width: u32,
        /// Mask height.
        height: u32,
        /// Image width.
        image_width: u32,
        /// Image height.
        image_height: u32,
    },
    /// Some value is present but unusable (names the file and field).
    #[error("{path}: {what}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
    /// `scene.json` is malformed.
    #[error("{path}: invalid scene JSON: {source}")]
    SceneJson {
        /// The file.
        path: PathBuf,
        /// The cause (serde names line, column and field).
        source: serde_json::Error,
    },
    /// A file could not be read or written.
    #[error("{path}: {action}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The cause.
        source: std::io::Error,
    },
    /// An image could not be encoded.
    #[error("{path}: cannot encode PNG: {source}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
}

/// Training or held-out split.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Split {
    /// `transforms_train.json`, images under `train/`.
    Train,
    /// `transforms_test.json`, images under `test/`.
    Test,
}

impl Split {
    /// The folder name (`train` / `test`).
    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Test => "test",
        }
    }

    /// The transforms file name of this split.
    pub fn transforms_file(self) -> &'static str {
        match self {
            Split::Train => TRAIN_TRANSFORMS,
            Split::Test => TEST_TRANSFORMS,
        }
    }
}

/// One posed view.
#[derive(Debug, Clone)]
pub struct Frame {
    /// The frame's `file_path` as written in the transforms file (`./train/r_0`).
    pub file_path: String,
    /// The camera, with this frame's intrinsics at the image's size.
    pub camera: Camera,
    /// 8-bit RGBA, straight (not premultiplied) alpha = coverage.
    pub image: RgbaImage,
    /// Instance mask: 0 background, k = object index + 1; `None` for real captures.
    pub mask: Option<GrayImage>,
}

impl Frame {
    /// The instance mask, or for captures without masks the single-object
    /// mask from alpha ([`mask_from_alpha`]).
    pub fn instance_mask(&self) -> Cow<'_, GrayImage> {
        match &self.mask {
            Some(m) => Cow::Borrowed(m),
            None => Cow::Owned(mask_from_alpha(&self.image)),
        }
    }

    /// Binary mask of one object (255 where the instance mask equals
    /// `mask_value`, else 0).
    pub fn object_mask(&self, mask_value: u8) -> GrayImage {
        let m = self.instance_mask();
        GrayImage::from_fn(m.width(), m.height(), |x, y| {
            image::Luma([if m.get_pixel(x, y).0[0] == mask_value {
                255
            } else {
                0
            }])
        })
    }
}

/// The single-object instance mask of an RGBA image: 1 where alpha > 0, else 0.
pub fn mask_from_alpha(image: &RgbaImage) -> GrayImage {
    GrayImage::from_fn(image.width(), image.height(), |x, y| {
        image::Luma([u8::from(image.get_pixel(x, y).0[3] > 0)])
    })
}

/// Where an object sits: `world = translation + scale · Rz(rotation_z_deg) · local`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    /// World position of the object's local origin.
    pub translation: [f64; 3],
    /// Turn about world +z, degrees, counter-clockwise seen from above.
    pub rotation_z_deg: f64,
    /// Uniform scale (world units per local unit).
    pub scale: f64,
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            translation: [0.0; 3],
            rotation_z_deg: 0.0,
            scale: 1.0,
        }
    }
}

/// One object of a scene, as `scene.json` records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectInfo {
    /// Unique name in the scene (`gear`, `ball-2`).
    pub name: String,
    /// Which procedural object (or another generator's kind name).
    pub kind: String,
    /// Its value in the instance masks (= index in `objects` + 1).
    pub mask_value: u8,
    /// Where it sits in the world.
    pub placement: Placement,
    /// World-space axis-aligned bounds, minimum corner (contains the whole object).
    pub bounds_min: [f64; 3],
    /// World-space axis-aligned bounds, maximum corner.
    pub bounds_max: [f64; 3],
    /// Geometric complexity: quad faces of its occupancy at
    /// [`SceneInfo::complexity_grid`] cells over its own bounds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub complexity_quads: Option<u64>,
    /// Nominal finest texture frequency, cycles per local unit length.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture_frequency: Option<f64>,
    /// Other keys, kept so a rewrite loses nothing.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// `scene.json`: what a multi-object capture contains.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneInfo {
    /// Always [`SCENE_FORMAT`].
    pub format: String,
    /// The objects; object `i` has mask value `i + 1`.
    pub objects: Vec<ObjectInfo>,
    /// How the objects were arranged (`row`, `ring`, `random`, `single`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<String>,
    /// The seed of the layout and cameras.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The preset name, if made from one (`scene4`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Grid cells per axis used for `complexity_quads`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub complexity_grid: Option<u32>,
    /// The mask value (above every object's) that marks pixels where an
    /// object *not listed here* covers the view (usually
    /// [`OTHER_OBJECTS_MASK_VALUE`]): a segmentation group's folder keeps
    /// the rest of the scene out of its images but records where it hid
    /// the group's objects, so the baker treats those pixels as unknown
    /// rather than background (see `docs/segmentation.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub other_objects_mask_value: Option<u8>,
    /// Other keys, kept so a rewrite loses nothing.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl SceneInfo {
    /// A scene description of these objects with no optional fields set.
    pub fn new(objects: Vec<ObjectInfo>) -> Self {
        Self {
            format: SCENE_FORMAT.into(),
            objects,
            layout: None,
            seed: None,
            preset: None,
            complexity_grid: None,
            other_objects_mask_value: None,
            extra: Default::default(),
        }
    }

    /// Whether an instance mask of this scene may hold value `v`: 0
    /// (nothing), an object's value, or the declared
    /// [`SceneInfo::other_objects_mask_value`].
    pub fn mask_value_allowed(&self, v: u8) -> bool {
        usize::from(v) <= self.objects.len() || self.other_objects_mask_value == Some(v)
    }

    /// Reads and validates `scene.json`.
    pub fn read(path: &Path) -> Result<Self, CaptureError> {
        let text = crate::validate::read_to_string(path).map_err(|source| CaptureError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
        let s: SceneInfo =
            serde_json::from_str(&text).map_err(|source| CaptureError::SceneJson {
                path: path.to_path_buf(),
                source,
            })?;
        s.validate().map_err(|what| CaptureError::Invalid {
            path: path.to_path_buf(),
            what,
        })?;
        Ok(s)
    }

    /// Writes `scene.json` atomically (temporary file, then rename).
    pub fn write(&self, path: &Path) -> Result<(), CaptureError> {
        self.validate().map_err(|what| CaptureError::Invalid {
            path: path.to_path_buf(),
            what,
        })?;
        let text =
            serde_json::to_string_pretty(self).map_err(|source| CaptureError::SceneJson {
                path: path.to_path_buf(),
                source,
            })?;
        write_atomic(path, text.as_bytes())
    }

    /// Checks format, names, mask values and bounds; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        if self.format != SCENE_FORMAT {
            return Err(format!(
                "format = {:?}, expected {SCENE_FORMAT:?}",
                self.format
            ));
        }
        if self.objects.is_empty() {
            return Err("objects: empty".into());
        }
        if self.objects.len() > 255 {
            return Err(format!(
                "objects: {} objects, masks hold at most 255",
                self.objects.len()
            ));
        }
        if let Some(v) = self.other_objects_mask_value {
            if usize::from(v) <= self.objects.len() {
                return Err(format!(
                    "other_objects_mask_value = {v} must exceed every object's mask value (1..={})",
                    self.objects.len()
                ));
            }
        }
        let mut names = std::collections::HashSet::new();
        for (i, o) in self.objects.iter().enumerate() {
            if o.name.is_empty() || !names.insert(o.name.as_str()) {
                return Err(format!(
                    "objects[{i}].name {:?} is empty or not unique",
                    o.name
                ));
            }
            if usize::from(o.mask_value) != i + 1 {
                return Err(format!(
                    "objects[{i}] ({}): mask_value = {}, expected {}",
                    o.name,
                    o.mask_value,
                    i + 1
                ));
            }
            let p = &o.placement;
            let finite = p.translation.iter().all(|v| v.is_finite())
                && p.rotation_z_deg.is_finite()
                && p.scale.is_finite()
                && p.scale > 0.0;
            if !finite {
                return Err(format!(
                    "objects[{i}] ({}): placement has a non-finite value or a scale ≤ 0",
                    o.name
                ));
            }
            for a in 0..3 {
                let (lo, hi) = (o.bounds_min[a], o.bounds_max[a]);
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    return Err(format!(
                        "objects[{i}] ({}): bounds_min/bounds_max axis {a} = [{lo}, {hi}] is not an interval",
                        o.name
                    ));
                }
            }
        }
        Ok(())
    }

    /// The object with this name.
    pub fn object(&self, name: &str) -> Option<&ObjectInfo> {
        self.objects.iter().find(|o| o.name == name)
    }
}

/// A capture folder in memory.
#[derive(Debug, Clone)]
pub struct Capture {
    /// The folder it was read from.
    pub dir: PathBuf,
    /// Horizontal field of view of the training transforms, radians.
    pub camera_angle_x: f64,
    /// Training views, in file order.
    pub train: Vec<Frame>,
    /// Held-out views, in file order (empty without `transforms_test.json`).
    pub test: Vec<Frame>,
    /// `scene.json`, if present.
    pub scene: Option<SceneInfo>,
}

impl Capture {
    /// Reads a NeRF-synthetic folder (built-in or real): transforms, every
    /// frame's RGBA image, masks when present and `scene.json` when present.
    /// Images are decoded in parallel.
    pub fn load(dir: impl AsRef<Path>) -> Result<Capture, CaptureError> {
        let dir = dir.as_ref().to_path_buf();
        let train_path = dir.join(TRAIN_TRANSFORMS);
        if !dir.is_dir() {
            return Err(CaptureError::NotACapture {
                dir,
                what: "no such folder".into(),
            });
        }
        if !train_path.is_file() {
            return Err(CaptureError::NotACapture {
                dir,
                what: format!("{TRAIN_TRANSFORMS} is missing"),
            });
        }
        let train_t = Transforms::read(&train_path)?;
        let test_path = dir.join(TEST_TRANSFORMS);
        let test_t = if test_path.exists() {
            Some(Transforms::read(&test_path)?)
        } else {
            None
        };
        let scene_path = dir.join(SCENE_FILE);
        let scene = if scene_path.exists() {
            Some(SceneInfo::read(&scene_path)?)
        } else {
            None
        };

        let train = load_frames(&dir, &train_path, &train_t)?;
        let test = match &test_t {
            Some(t) => load_frames(&dir, &test_path, t)?,
            None => Vec::new(),
        };
        let capture = Capture {
            camera_angle_x: train_t.camera_angle_x,
            dir,
            train,
            test,
            scene,
        };
        capture.check_consistency()?;
        Ok(capture)
    }

    /// Image size shared by all frames (width, height), pixels.
    pub fn size(&self) -> (u32, u32) {
        self.train
            .first()
            .map_or((0, 0), |f| (f.image.width(), f.image.height()))
    }

    /// Whether the frames carry instance masks.
    pub fn has_masks(&self) -> bool {
        self.train.first().is_some_and(|f| f.mask.is_some())
    }

    /// Number of objects: from `scene.json`, else 1 (a real single-object capture).
    pub fn object_count(&self) -> usize {
        self.scene.as_ref().map_or(1, |s| s.objects.len())
    }

    /// All frames, training first.
    pub fn frames(&self) -> impl Iterator<Item = &Frame> {
        self.train.iter().chain(self.test.iter())
    }

    /// Frames of one split.
    pub fn split(&self, split: Split) -> &[Frame] {
        match split {
            Split::Train => &self.train,
            Split::Test => &self.test,
        }
    }

    fn frame_path(&self, f: &Frame) -> PathBuf {
        image_path(&self.dir, &f.file_path)
    }

    /// One size for all frames; masks on all frames or none; mask values
    /// name objects of `scene.json`.
    fn check_consistency(&self) -> Result<(), CaptureError> {
        let Some(first) = self.train.first() else {
            return Err(CaptureError::NotACapture {
                dir: self.dir.clone(),
                what: format!("{TRAIN_TRANSFORMS} has no frames"),
            });
        };
        let (w, h) = (first.image.width(), first.image.height());
        let has_mask = first.mask.is_some();
        for f in self.frames() {
            if (f.image.width(), f.image.height()) != (w, h) {
                return Err(CaptureError::SizeMismatch {
                    path: self.frame_path(f),
                    width: f.image.width(),
                    height: f.image.height(),
                    first: self.frame_path(first),
                    first_width: w,
                    first_height: h,
                });
            }
            if f.mask.is_some() != has_mask {
                let (with, without) = if has_mask { (first, f) } else { (f, first) };
                return Err(CaptureError::Invalid {
                    path: mask_path(&self.dir, &without.file_path),
                    what: format!(
                        "mask file missing while {} has one; either every frame has a mask or none",
                        mask_path(&self.dir, &with.file_path).display()
                    ),
                });
            }
            if let (Some(m), Some(scene)) = (&f.mask, &self.scene) {
                let n = scene.objects.len();
                if let Some((x, y, v)) = m
                    .enumerate_pixels()
                    .find(|(_, _, p)| !scene.mask_value_allowed(p.0[0]))
                    .map(|(x, y, p)| (x, y, p.0[0]))
                {
                    return Err(CaptureError::Invalid {
                        path: mask_path(&self.dir, &f.file_path),
                        what: format!(
                            "mask value {v} at ({x}, {y}) names no object: {SCENE_FILE} has {n}"
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

/// The image file of a frame: `<dir>/<file_path>.png` (or `file_path` itself
/// when it already ends in `.png`).
pub fn image_path(dir: &Path, file_path: &str) -> PathBuf {
    let file_path = file_path.strip_prefix("./").unwrap_or(file_path);
    if file_path.to_ascii_lowercase().ends_with(".png") {
        dir.join(file_path)
    } else {
        dir.join(format!("{file_path}.png"))
    }
}

/// The mask file of a frame: `<dir>/<file_path>_mask.png`.
pub fn mask_path(dir: &Path, file_path: &str) -> PathBuf {
    let file_path = file_path.strip_prefix("./").unwrap_or(file_path);
    let stem = file_path
        .strip_suffix(".png")
        .or_else(|| file_path.strip_suffix(".PNG"))
        .unwrap_or(file_path);
    dir.join(format!("{stem}{MASK_SUFFIX}"))
}

fn load_frames(dir: &Path, tpath: &Path, t: &Transforms) -> Result<Vec<Frame>, CaptureError> {
    t.frames
        .par_iter()
        .enumerate()
        .map(|(index, entry)| load_frame(dir, tpath, t, index, entry))
        .collect()
}

fn load_frame(
    dir: &Path,
    tpath: &Path,
    t: &Transforms,
    index: usize,
    entry: &FrameEntry,
) -> Result<Frame, CaptureError> {
    let path = image_path(dir, &entry.file_path);
    if !path.is_file() {
        return Err(CaptureError::MissingFrame {
            path,
            transforms: tpath.to_path_buf(),
            index,
        });
    }
    let img = decode(&path)?;
    if !img.color().has_alpha() {
        return Err(CaptureError::NoAlpha {
            path,
            color: format!("{:?}", img.color()),
        });
    }
    let image = img.into_rgba8();
    let (w, h) = image.dimensions();
    let camera = t.camera(index, w, h).ok_or_else(|| CaptureError::Invalid {
        path: tpath.to_path_buf(),
        what: format!("frame {index} has no camera"),
    })?;
    let mpath = mask_path(dir, &entry.file_path);
    let mask = if mpath.is_file() {
        let m = match decode(&mpath)? {
            DynamicImage::ImageLuma8(m) => m,
            other => {
                return Err(CaptureError::MaskFormat {
                    path: mpath,
                    color: format!("{:?}", other.color()),
                })
            }
        };
        if m.dimensions() != (w, h) {
            return Err(CaptureError::MaskSizeMismatch {
                path: mpath,
                width: m.width(),
                height: m.height(),
                image_width: w,
                image_height: h,
            });
        }
        Some(m)
    } else {
        None
    };
    Ok(Frame {
        file_path: entry.file_path.clone(),
        camera,
        image,
        mask,
    })
}

fn decode(path: &Path) -> Result<DynamicImage, CaptureError> {
    let reader = crate::validate::regular_file(path)
        .and_then(|()| image::ImageReader::open(path))
        .and_then(|r| r.with_guessed_format())
        .map_err(|source| CaptureError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
    reader.decode().map_err(|source| CaptureError::Decode {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a
/// rename, so a reader never sees a half-written file and a failure leaves
/// the previous file intact.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CaptureError> {
    crate::output::write_file(path, bytes)
        .map(|_| ())
        .map_err(|e| CaptureError::Io {
            path: path.to_path_buf(),
            action: "cannot write",
            source: e.into_io(),
        })
}

/// Encodes an image as PNG and writes it atomically.
pub fn write_png(path: &Path, image: &DynamicImage) -> Result<(), CaptureError> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, ImageFormat::Png)
        .map_err(|source| CaptureError::Encode {
            path: path.to_path_buf(),
            source,
        })?;
    write_atomic(path, bytes.get_ref())
}

/// Writes a capture folder frame by frame.
///
/// Frames may be written from many threads ([`CaptureWriter::write_frame`]
/// takes `&self`); each PNG is written atomically as soon as it is ready, so
/// an error later loses nothing already written. The transforms files and
/// `scene.json` are written last by [`CaptureWriter::finish`], which makes the
/// folder a readable capture.
#[derive(Debug)]
pub struct CaptureWriter {
    dir: PathBuf,
    camera_angle_x: f64,
    state: Mutex<WriterState>,
}

#[derive(Debug, Default)]
struct WriterState {
    /// First frame's size and path.
    size: Option<(u32, u32, String)>,
    /// Whether frames carry masks (set by the first frame).
    masks: Option<bool>,
    /// Which mask values were written (bit v of word v / 64).
    mask_values: [u64; 4],
    train: BTreeMap<usize, FrameEntry>,
    test: BTreeMap<usize, FrameEntry>,
}

impl CaptureWriter {
    /// Creates `dir`, `dir/train` and `dir/test`. `camera_angle_x` (radians)
    /// is written to the transforms files; frames whose intrinsics differ from
    /// it get per-frame `fl_x`, `fl_y`, `cx`, `cy`.
    pub fn create(dir: &Path, camera_angle_x: f64) -> Result<Self, CaptureError> {
        if !(camera_angle_x.is_finite()
            && camera_angle_x > 0.0
            && camera_angle_x < std::f64::consts::PI)
        {
            return Err(CaptureError::Invalid {
                path: dir.to_path_buf(),
                what: format!("camera_angle_x = {camera_angle_x} is not an angle in (0, π)"),
            });
        }
        for sub in [Split::Train, Split::Test] {
            let p = dir.join(sub.as_str());
            std::fs::create_dir_all(&p).map_err(|source| CaptureError::Io {
                path: p,
                action: "cannot create folder",
                source,
            })?;
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            camera_angle_x,
            state: Mutex::new(WriterState::default()),
        })
    }

    /// The output folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes frame `index` of `split` as `<split>/<name>.png` (and
    /// `<split>/<name>_mask.png`) and records its camera. `name` is a plain
    /// file stem such as `r_0`. Returns the frame's `file_path`.
    pub fn write_frame(
        &self,
        split: Split,
        index: usize,
        name: &str,
        camera: &Camera,
        image: &RgbaImage,
        mask: Option<&GrayImage>,
    ) -> Result<String, CaptureError> {
        let file_path = format!("./{}/{name}", split.as_str());
        let ipath = image_path(&self.dir, &file_path);
        let invalid = |what: String| CaptureError::Invalid {
            path: ipath.clone(),
            what,
        };
        if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
            return Err(invalid(format!(
                "frame name {name:?} must be a plain file stem"
            )));
        }
        let (w, h) = image.dimensions();
        if w == 0 || h == 0 {
            return Err(invalid("image is empty".into()));
        }
        if camera.intrinsics.width != w || camera.intrinsics.height != h {
            return Err(invalid(format!(
                "camera is for {}×{} but the image is {w}×{h}",
                camera.intrinsics.width, camera.intrinsics.height
            )));
        }
        if let Some(m) = mask {
            if m.dimensions() != (w, h) {
                return Err(CaptureError::MaskSizeMismatch {
                    path: mask_path(&self.dir, &file_path),
                    width: m.width(),
                    height: m.height(),
                    image_width: w,
                    image_height: h,
                });
            }
        }
        {
            let mut st = self.lock();
            match &st.size {
                Some((fw, fh, first)) if (*fw, *fh) != (w, h) => {
                    return Err(CaptureError::SizeMismatch {
                        path: ipath,
                        width: w,
                        height: h,
                        first: image_path(&self.dir, first),
                        first_width: *fw,
                        first_height: *fh,
                    });
                }
                Some(_) => {}
                None => st.size = Some((w, h, file_path.clone())),
            }
            match st.masks {
                Some(m) if m != mask.is_some() => {
                    return Err(invalid("either every frame has a mask or none has".into()));
                }
                Some(_) => {}
                None => st.masks = Some(mask.is_some()),
            }
            let map = match split {
                Split::Train => &st.train,
                Split::Test => &st.test,
            };
            if map.contains_key(&index) {
                return Err(invalid(format!(
                    "frame index {index} of {} written twice",
                    split.as_str()
                )));
            }
        }
        write_png(&ipath, &DynamicImage::ImageRgba8(image.clone()))?;
        let mut mask_values = [0u64; 4];
        for &v in mask.map_or(&[][..], |m| m.as_raw().as_slice()) {
            mask_values[usize::from(v / 64)] |= 1 << (v % 64);
        }
        if let Some(m) = mask {
            write_png(
                &mask_path(&self.dir, &file_path),
                &DynamicImage::ImageLuma8(m.clone()),
            )?;
        }
        let entry = self.entry(&file_path, camera);
        let mut st = self.lock();
        for (a, b) in st.mask_values.iter_mut().zip(mask_values) {
            *a |= b;
        }
        match split {
            Split::Train => st.train.insert(index, entry),
            Split::Test => st.test.insert(index, entry),
        };
        Ok(file_path)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, WriterState> {
        // A panic in another writer thread cannot leave the maps half-updated
        // (each update is one insert), so a poisoned lock is still usable.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn entry(&self, file_path: &str, camera: &Camera) -> FrameEntry {
        let k = camera.intrinsics;
        let base = Intrinsics::from_fov_x(self.camera_angle_x as f32, k.width, k.height);
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-3 * (1.0 + b.abs());
        let standard = close(k.fx, base.fx)
            && close(k.fy, base.fy)
            && close(k.cx, base.cx)
            && close(k.cy, base.cy);
        let own = |v: f32| (!standard).then_some(v as f64);
        FrameEntry {
            file_path: file_path.to_string(),
            transform_matrix: rows_from_mat4(&camera.c2w),
            fl_x: own(k.fx),
            fl_y: own(k.fy),
            cx: own(k.cx),
            cy: own(k.cy),
            extra: Default::default(),
        }
    }

    /// Writes `transforms_train.json`, `transforms_test.json` (when test
    /// frames were written) and `scene.json` (when given), each atomically.
    /// Frame order is by index. Fails if no training frame was written or if
    /// a mask value names no object of the scene (and is not its declared
    /// [`SceneInfo::other_objects_mask_value`]).
    pub fn finish(self, scene: Option<&SceneInfo>) -> Result<PathBuf, CaptureError> {
        let st = self.state.into_inner().unwrap_or_else(|e| e.into_inner());
        let Some((w, h, _)) = st.size else {
            return Err(CaptureError::NotACapture {
                dir: self.dir,
                what: "no frame was written".into(),
            });
        };
        if st.train.is_empty() {
            return Err(CaptureError::NotACapture {
                dir: self.dir,
                what: "no training frame was written".into(),
            });
        }
        if let Some(scene) = scene {
            let p = self.dir.join(SCENE_FILE);
            let written = |v: u8| st.mask_values[usize::from(v / 64)] & (1 << (v % 64)) != 0;
            if let Some(v) = (0..=u8::MAX).find(|&v| written(v) && !scene.mask_value_allowed(v)) {
                return Err(CaptureError::Invalid {
                    path: p,
                    what: format!(
                        "masks use value {v} but the scene has {} objects{}",
                        scene.objects.len(),
                        scene
                            .other_objects_mask_value
                            .map_or_else(String::new, |o| format!(
                                " (and other objects' value {o})"
                            ))
                    ),
                });
            }
            scene.write(&p)?;
        }
        for (split, frames) in [(Split::Train, &st.train), (Split::Test, &st.test)] {
            if frames.is_empty() {
                continue;
            }
            let per_frame = frames.values().any(|f| f.fl_x.is_some());
            let t = Transforms {
                camera_angle_x: self.camera_angle_x,
                fl_x: None,
                fl_y: None,
                cx: None,
                cy: None,
                // Pixel intrinsics refer to this size; readers rescale them
                // for a resized image.
                w: per_frame.then_some(w),
                h: per_frame.then_some(h),
                frames: frames.values().cloned().collect(),
            };
            let path = self.dir.join(split.transforms_file());
            let text =
                serde_json::to_string_pretty(&t).map_err(|source| CaptureError::SceneJson {
                    path: path.clone(),
                    source,
                })?;
            write_atomic(&path, text.as_bytes())?;
        }
        Ok(self.dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn cam(w: u32, h: u32) -> Camera {
        Camera::orbit(
            20.0,
            30.0,
            4.0,
            Vec3::ZERO,
            Intrinsics::from_fov_x(0.69, w, h),
        )
    }

    #[test]
    fn mask_paths_follow_the_frame() {
        let d = Path::new("/x");
        assert_eq!(
            mask_path(d, "./train/r_0"),
            Path::new("/x/train/r_0_mask.png")
        );
        assert_eq!(
            mask_path(d, "train/r_0.png"),
            Path::new("/x/train/r_0_mask.png")
        );
        assert_eq!(image_path(d, "./test/r_2"), Path::new("/x/test/r_2.png"));
    }

    #[test]
    fn writer_round_trips_cameras_and_per_frame_intrinsics() {
        let dir = tempfile::tempdir().unwrap();
        let w = CaptureWriter::create(dir.path(), 0.69).unwrap();
        let img = RgbaImage::from_pixel(8, 6, image::Rgba([10, 20, 30, 255]));
        let mask = GrayImage::from_pixel(8, 6, image::Luma([1]));
        let c0 = cam(8, 6);
        let mut c1 = cam(8, 6);
        c1.intrinsics = c1.intrinsics.cropped(1.0, 1.0, 4.0, 3.0, 8, 6);
        w.write_frame(Split::Train, 1, "r_1", &c1, &img, Some(&mask))
            .unwrap();
        w.write_frame(Split::Train, 0, "r_0", &c0, &img, Some(&mask))
            .unwrap();
        let mut scene = SceneInfo::new(vec![ObjectInfo {
            name: "a".into(),
            kind: "ball".into(),
            mask_value: 1,
            placement: Placement::default(),
            bounds_min: [-1.0; 3],
            bounds_max: [1.0; 3],
            complexity_quads: Some(3),
            texture_frequency: None,
            extra: Default::default(),
        }]);
        scene.layout = Some("single".into());
        w.finish(Some(&scene)).unwrap();
        let c = Capture::load(dir.path()).unwrap();
        assert_eq!(c.train.len(), 2);
        assert!(c.test.is_empty());
        assert_eq!(c.train[0].file_path, "./train/r_0");
        assert_eq!(c.scene.as_ref(), Some(&scene));
        let k = c.train[1].camera.intrinsics;
        assert!((k.fx - c1.intrinsics.fx).abs() < 1e-3 && (k.cx - c1.intrinsics.cx).abs() < 1e-3);
        assert!((c.train[0].camera.intrinsics.fx - c0.intrinsics.fx).abs() < 1e-3);
        assert!(c.has_masks());
    }

    #[test]
    fn the_other_objects_mask_value_is_accepted_only_when_declared() {
        let one = || {
            SceneInfo::new(vec![ObjectInfo {
                name: "a".into(),
                kind: "ball".into(),
                mask_value: 1,
                placement: Placement::default(),
                bounds_min: [-1.0; 3],
                bounds_max: [1.0; 3],
                complexity_quads: None,
                texture_frequency: None,
                extra: Default::default(),
            }])
        };
        let mut bad = one();
        bad.other_objects_mask_value = Some(1);
        assert!(bad
            .validate()
            .unwrap_err()
            .contains("other_objects_mask_value"));
        // A mask with 0, the object (1) and another object (255).
        let img = RgbaImage::new(4, 1);
        let mask = GrayImage::from_raw(4, 1, vec![0, 1, 255, 1]).unwrap();
        let write = |scene: &SceneInfo| {
            let dir = tempfile::tempdir().unwrap();
            let w = CaptureWriter::create(dir.path(), 0.69).unwrap();
            w.write_frame(Split::Train, 0, "r_0", &cam(4, 1), &img, Some(&mask))
                .unwrap();
            w.finish(Some(scene)).map(|_| dir)
        };
        let e = write(&one()).unwrap_err().to_string();
        assert!(e.contains("value 255") && e.contains("1 objects"), "{e}");
        let mut declared = one();
        declared.other_objects_mask_value = Some(OTHER_OBJECTS_MASK_VALUE);
        let dir = write(&declared).unwrap();
        let c = Capture::load(dir.path()).unwrap();
        assert_eq!(c.train[0].mask.as_ref(), Some(&mask));
        // The same folder without the declaration is refused on load.
        one().write(&dir.path().join(SCENE_FILE)).unwrap();
        let e = Capture::load(dir.path()).unwrap_err().to_string();
        assert!(e.contains("mask value 255"), "{e}");
    }

    #[test]
    fn writer_rejects_inconsistent_frames() {
        let dir = tempfile::tempdir().unwrap();
        let w = CaptureWriter::create(dir.path(), 0.69).unwrap();
        let img = RgbaImage::new(8, 8);
        w.write_frame(Split::Train, 0, "r_0", &cam(8, 8), &img, None)
            .unwrap();
        let e = w
            .write_frame(
                Split::Train,
                1,
                "r_1",
                &cam(4, 4),
                &RgbaImage::new(4, 4),
                None,
            )
            .unwrap_err();
        assert!(e.to_string().contains("all frames"), "{e}");
        let e = w
            .write_frame(
                Split::Train,
                1,
                "r_1",
                &cam(8, 8),
                &img,
                Some(&GrayImage::new(8, 8)),
            )
            .unwrap_err();
        assert!(e.to_string().contains("mask"), "{e}");
        let e = w
            .write_frame(Split::Train, 1, "../r", &cam(8, 8), &img, None)
            .unwrap_err();
        assert!(e.to_string().contains("file stem"), "{e}");
    }
}
