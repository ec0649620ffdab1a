//! What segmentation works on: posed RGBA views with instance masks.
//!
//! These types are deliberately plain (`image` buffers and
//! [`crate::camera::Camera`]) so the core functions do not depend on how a
//! capture was read; [`SegCapture::load`] adapts a capture folder.

use super::frequency::PixelBox;
use crate::camera::Camera;
use crate::capture::{mask_from_alpha, Capture, CaptureError, Frame, SceneInfo};
use image::{GrayImage, RgbaImage};
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
    /// A capture folder could not be read or written.
    #[error(transparent)]
    Capture(#[from] CaptureError),
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
    /// The capture's `scene.json` (object kinds, placement, bounds), if it
    /// had one; the training folders get the entries of their objects.
    pub scene: Option<SceneInfo>,
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
            // The value a group folder's scene.json declares for objects
            // outside it names none of the objects here.
            let others = self.scene.as_ref().and_then(|s| s.other_objects_mask_value);
            let named = f.mask.as_raw().iter().filter(|&&l| Some(l) != others).max();
            if let Some(&l) = named {
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

    /// Reads a capture folder with [`Capture::load`] (NeRF-synthetic layout,
    /// instance masks and `scene.json` when present).
    pub fn load(dir: &Path) -> Result<Self, SegmentError> {
        Self::from_capture(Capture::load(dir)?)
    }

    /// Adapts a loaded capture. Objects are named by its `scene.json`.
    /// Without one: masks with labels up to n > 1 name objects `object1` …
    /// `objectn`; otherwise it is one object named after its folder, whose
    /// mask is `alpha > 0` (a real NeRF-synthetic capture).
    pub fn from_capture(cap: Capture) -> Result<Self, SegmentError> {
        let max_label = cap
            .frames()
            .filter_map(|f| f.mask.as_ref())
            .filter_map(|m| m.as_raw().iter().copied().max())
            .max()
            .unwrap_or(0);
        let objects = match (&cap.scene, max_label) {
            (Some(scene), _) => scene.objects.iter().map(|o| o.name.clone()).collect(),
            // Masks but no scene.json: name the objects by their labels.
            (None, n) if n > 1 => (1..=n).map(|k| format!("object{k}")).collect(),
            (None, _) => vec![cap
                .dir
                .canonicalize()
                .ok()
                .and_then(|p| p.file_name().map(|s| s.to_string_lossy().into_owned()))
                .unwrap_or_else(|| "object".into())],
        };
        let convert = |frames: Vec<Frame>| -> Vec<SegFrame> {
            frames
                .into_iter()
                .map(|f| {
                    let mask = match f.mask {
                        Some(m) => m,
                        None => mask_from_alpha(&f.image),
                    };
                    SegFrame {
                        file_path: f.file_path,
                        image: f.image,
                        mask,
                        camera: f.camera,
                        object_views: Vec::new(),
                    }
                })
                .collect()
        };
        let seg = SegCapture {
            objects,
            camera_angle_x: cap.camera_angle_x,
            source: cap.dir.display().to_string(),
            train: convert(cap.train),
            test: convert(cap.test),
            scene: cap.scene,
        };
        seg.validate()?;
        Ok(seg)
    }
}

/// Reads one image as RGBA8, naming the file on failure.
pub fn read_rgba(path: &Path) -> Result<RgbaImage, SegmentError> {
    crate::validate::regular_file(path).map_err(|source| SegmentError::Io {
        path: path.to_path_buf(),
        source,
    })?;
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
