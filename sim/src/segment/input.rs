//! What segmentation works on: posed RGBA views with instance masks.
//!
//! These types are deliberately plain (`image` buffers and
//! [`crate::camera::Camera`]) so the core functions do not depend on how a
//! capture was read; [`SegCapture::load`] adapts a capture folder.

use super::frequency::PixelBox;
use crate::camera::{Camera, Transforms};
use image::{GrayImage, Luma, RgbaImage};
use std::path::{Path, PathBuf};

/// Errors of the segmentation stage; each names the file, flag or object.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// An image could not be decoded or encoded.
    #[error("{path}: {source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
    /// A transforms file is malformed.
    #[error(transparent)]
    Camera(#[from] crate::camera::CameraError),
    /// The capture is unusable (sizes differ, no frames, an object never
    /// visible, …); the text says what and where.
    #[error("{0}")]
    Invalid(String),
}

/// One posed view.
#[derive(Debug, Clone)]
pub struct SegFrame {
    /// Image path as in the transforms file, without extension (`./train/r_0`).
    pub file_path: String,
    /// 8-bit RGBA, alpha = coverage.
    pub image: RgbaImage,
    /// Instance mask, same size: 0 background, k = object index + 1.
    pub mask: GrayImage,
    /// The frame's camera.
    pub camera: Camera,
    /// Per-object cameras and regions (index = object index), or empty when
    /// every object is seen through [`SegFrame::camera`] over the whole
    /// image. Only 2-D composites of separate captures ([`super::compose`])
    /// need them: each object keeps the camera of the capture it came from.
    pub object_views: Vec<ObjectView>,
}

/// How one object of a composite is seen: its own camera (intrinsics for
/// the whole composite image) and the part of the image it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectView {
    /// The object's camera.
    pub camera: Camera,
    /// The sub-rectangle of the image its source occupies.
    pub region: PixelBox,
}

impl SegFrame {
    /// The camera through which object `object` (0-based) is seen.
    pub fn camera_of(&self, object: usize) -> Camera {
        self.object_views
            .get(object)
            .map_or(self.camera, |v| v.camera)
    }

    /// The part of the image object `object` lives in (the whole image
    /// unless the frame is a composite).
    pub fn region_of(&self, object: usize) -> PixelBox {
        self.object_views.get(object).map_or(
            PixelBox {
                x0: 0,
                y0: 0,
                x1: self.image.width(),
                y1: self.image.height(),
            },
            |v| v.region,
        )
    }
}

/// A multi-object capture: named objects (mask label = index + 1) and the
/// training and held-out views.
#[derive(Debug, Clone)]
pub struct SegCapture {
    /// Object names; object `i` has mask label `i + 1`.
    pub objects: Vec<String>,
    /// Horizontal field of view of the source transforms file, radians (kept
    /// so written transforms files stay valid NeRF-synthetic files).
    pub camera_angle_x: f64,
    /// Training views.
    pub train: Vec<SegFrame>,
    /// Held-out views (may be empty).
    pub test: Vec<SegFrame>,
    /// Where it was read from, for reports.
    pub source: String,
}

impl SegCapture {
    /// Checks what the later steps rely on: at least one object (at most
    /// 255), at least one training frame, every image the size of its mask
    /// and all images of one size, per-object cameras complete.
    pub fn validate(&self) -> Result<(), SegmentError> {
        let bad = |what: String| Err(SegmentError::Invalid(format!("{}: {what}", self.source)));
        if self.objects.is_empty() {
            return bad("no objects".into());
        }
        if self.objects.len() > 255 {
            return bad(format!(
                "{} objects; instance masks hold at most 255",
                self.objects.len()
            ));
        }
        for (i, name) in self.objects.iter().enumerate() {
            if self.objects[..i].contains(name) {
                return bad(format!("object name {name:?} appears twice"));
            }
        }
        let Some(first) = self.train.first() else {
            return bad("no training frames".into());
        };
        let size = first.image.dimensions();
        for f in self.train.iter().chain(&self.test) {
            if f.image.dimensions() != size {
                return bad(format!(
                    "{}: image is {:?}, the first training image is {size:?}",
                    f.file_path,
                    f.image.dimensions()
                ));
            }
            if f.mask.dimensions() != size {
                return bad(format!(
                    "{}: mask is {:?}, image is {size:?}",
                    f.file_path,
                    f.mask.dimensions()
                ));
            }
            if !f.object_views.is_empty() && f.object_views.len() != self.objects.len() {
                return bad(format!(
                    "{}: {} object views for {} objects",
                    f.file_path,
                    f.object_views.len(),
                    self.objects.len()
                ));
            }
            if let Some(&l) = f.mask.as_raw().iter().max() {
                if l as usize > self.objects.len() {
                    return bad(format!(
                        "{}: mask label {l} but only {} object(s) are named",
                        f.file_path,
                        self.objects.len()
                    ));
                }
            }
            for (o, v) in f.object_views.iter().enumerate() {
                let r = v.region;
                if r.x0 >= r.x1 || r.y0 >= r.y1 || r.x1 > size.0 || r.y1 > size.1 {
                    return bad(format!(
                        "{}: object {o}: region {r:?} is empty or outside the image",
                        f.file_path
                    ));
                }
            }
        }
        Ok(())
    }

    /// Image size (width, height) of the capture.
    pub fn image_size(&self) -> (u32, u32) {
        self.train.first().map_or((0, 0), |f| f.image.dimensions())
    }

    /// Reads a capture folder in the NeRF-synthetic layout:
    /// `transforms_{train,test}.json`, `<file_path>.png` per frame, and when
    /// present the instance masks `<file_path>_mask.png` and `scene.json`
    /// (object names). Without masks the capture is one object named after
    /// the folder whose mask is `alpha > 0`.
    pub fn load(dir: &Path) -> Result<Self, SegmentError> {
        let folder_name = dir
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|s| s.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "object".into());
        let train_t = Transforms::read(&dir.join("transforms_train.json"))?;
        let test_path = dir.join("transforms_test.json");
        let test_t = if test_path.is_file() {
            Some(Transforms::read(&test_path)?)
        } else {
            None
        };
        let train = read_frames(dir, &train_t)?;
        let test = match &test_t {
            Some(t) => read_frames(dir, t)?,
            None => Vec::new(),
        };
        let objects = match scene_object_names(dir)? {
            Some(names) => names,
            None => {
                // No scene.json: as many objects as the largest mask label.
                let max = train
                    .iter()
                    .chain(&test)
                    .flat_map(|f| f.mask.as_raw().iter().copied().max())
                    .max()
                    .unwrap_or(0);
                match max {
                    0 | 1 => vec![folder_name],
                    n => (1..=n).map(|k| format!("object{k}")).collect(),
                }
            }
        };
        let cap = SegCapture {
            objects,
            camera_angle_x: train_t.camera_angle_x,
            train,
            test,
            source: dir.display().to_string(),
        };
        cap.validate()?;
        Ok(cap)
    }
}

/// Object names from `scene.json` (`objects[i].name`), if the file exists.
fn scene_object_names(dir: &Path) -> Result<Option<Vec<String>>, SegmentError> {
    let path = dir.join("scene.json");
    if !path.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|source| SegmentError::Io {
        path: path.clone(),
        source,
    })?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| SegmentError::Invalid(format!("{}: invalid JSON: {e}", path.display())))?;
    let objects = v
        .get("objects")
        .and_then(|o| o.as_array())
        .ok_or_else(|| SegmentError::Invalid(format!("{}: no `objects` array", path.display())))?;
    objects
        .iter()
        .enumerate()
        .map(|(i, o)| {
            o.get("name")
                .and_then(|n| n.as_str())
                .map(str::to_string)
                .ok_or_else(|| {
                    SegmentError::Invalid(format!(
                        "{}: objects[{i}] has no string `name`",
                        path.display()
                    ))
                })
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// The instance mask of a single-object image: label 1 where alpha > 0.
pub fn mask_from_alpha(image: &RgbaImage) -> GrayImage {
    GrayImage::from_fn(image.width(), image.height(), |x, y| {
        Luma([u8::from(image.get_pixel(x, y)[3] > 0)])
    })
}

/// Reads one image as RGBA8, naming the file on failure.
pub fn read_rgba(path: &Path) -> Result<RgbaImage, SegmentError> {
    let img = image::open(path).map_err(|source| SegmentError::Image {
        path: path.to_path_buf(),
        source,
    })?;
    if !img.color().has_alpha() {
        return Err(SegmentError::Invalid(format!(
            "{}: image has no alpha channel (alpha is the object's coverage)",
            path.display()
        )));
    }
    Ok(img.to_rgba8())
}

fn read_frames(dir: &Path, t: &Transforms) -> Result<Vec<SegFrame>, SegmentError> {
    use rayon::prelude::*;
    (0..t.frames.len())
        .into_par_iter()
        .map(|i| {
            let entry = &t.frames[i];
            let path = dir.join(format!("{}.png", entry.file_path));
            let image = read_rgba(&path)?;
            let camera = t.camera(i, image.width(), image.height()).ok_or_else(|| {
                SegmentError::Invalid(format!("{}: frame {i} has no camera", path.display()))
            })?;
            let mask_path = dir.join(format!("{}{}", entry.file_path, super::output::MASK_SUFFIX));
            let mask = if mask_path.is_file() {
                let m = image::open(&mask_path).map_err(|source| SegmentError::Image {
                    path: mask_path.clone(),
                    source,
                })?;
                if m.color() != image::ColorType::L8 {
                    return Err(SegmentError::Invalid(format!(
                        "{}: an instance mask must be 8-bit grayscale, found {:?}",
                        mask_path.display(),
                        m.color()
                    )));
                }
                m.into_luma8()
            } else {
                mask_from_alpha(&image)
            };
            Ok(SegFrame {
                file_path: entry.file_path.clone(),
                mask,
                image,
                camera,
                object_views: Vec::new(),
            })
        })
        .collect()
}
