//! Multi-object captures composed from separate captures, and resized
//! captures.
//!
//! The real NeRF-synthetic captures hold one object each and no instance
//! masks. [`compose_side_by_side`] places frame i of every source side by
//! side on one canvas (source k at x offset k·W), and takes each source's
//! alpha as the instance mask of object k (label k + 1).
//!
//! **Cameras.** The composite is a 2-D montage, not a photograph of one 3-D
//! scene: the sources were shot from different poses. Each object therefore
//! keeps the camera of its own source ([`SegFrame::object_views`]), with the
//! principal point moved right by its offset on the canvas. That camera is
//! exact for every pixel of that object, which is all segmentation needs:
//! frequencies are measured per object, and an enlarged crop of object k
//! gets `cropped` intrinsics of source k's camera — the same crop taken from
//! the source image, and its enlarged view has the source's size (W × H),
//! not the canvas'. The frame-level camera is the first object's.

use super::enlarge::resize_view;
use super::frequency::PixelBox;
use super::input::{ObjectView, SegCapture, SegFrame, SegmentError};
use crate::camera::Camera;
use image::{imageops::FilterType, GrayImage, RgbaImage};
use rayon::prelude::*;
use std::path::Path;

/// Composes single- or multi-object captures side by side (see the module
/// docs). Frame i of the result uses frame i of every source; the frame
/// count is the smallest among the sources. All sources must have one
/// image size. Object names are the sources' object names.
pub fn compose_side_by_side(sources: &[SegCapture]) -> Result<SegCapture, SegmentError> {
    let Some(first) = sources.first() else {
        return Err(SegmentError::Invalid("compose: no source captures".into()));
    };
    let (w, h) = first.image_size();
    for s in sources {
        s.validate()?;
        if s.image_size() != (w, h) {
            return Err(SegmentError::Invalid(format!(
                "compose: {} has {:?} images, {} has {:?}; resize them to one size first (--size)",
                s.source,
                s.image_size(),
                first.source,
                (w, h)
            )));
        }
    }
    let mut objects = Vec::new();
    for s in sources {
        objects.extend(s.objects.iter().cloned());
    }
    let total_objects = objects.len();
    if total_objects > 255 {
        return Err(SegmentError::Invalid(format!(
            "compose: {total_objects} objects; masks hold at most 255"
        )));
    }
    let n = sources.len() as u32;
    let canvas_w = w.checked_mul(n).ok_or_else(|| {
        SegmentError::Invalid("compose: the composed image would be too wide".into())
    })?;
    let compose_split = |pick: fn(&SegCapture) -> &Vec<SegFrame>| -> Vec<SegFrame> {
        let count = sources.iter().map(|s| pick(s).len()).min().unwrap_or(0);
        (0..count)
            .into_par_iter()
            .map(|i| {
                let mut image = RgbaImage::new(canvas_w, h);
                let mut mask = GrayImage::new(canvas_w, h);
                let mut cameras = Vec::with_capacity(total_objects);
                let mut names = Vec::new();
                let mut label_base = 0u8;
                for (k, s) in sources.iter().enumerate() {
                    let f = &pick(s)[i];
                    let ox = k as u32 * w;
                    image::imageops::replace(&mut image, &f.image, ox as i64, 0);
                    for (x, y, p) in f.mask.enumerate_pixels() {
                        if p[0] != 0 {
                            mask.put_pixel(ox + x, y, image::Luma([p[0] + label_base]));
                        }
                    }
                    for o in 0..s.objects.len() {
                        let mut camera: Camera = f.camera_of(o);
                        camera.intrinsics.cx += ox as f32;
                        camera.intrinsics.width = canvas_w;
                        let r = f.region_of(o);
                        cameras.push(ObjectView {
                            camera,
                            region: PixelBox {
                                x0: r.x0 + ox,
                                x1: r.x1 + ox,
                                ..r
                            },
                        });
                    }
                    label_base += s.objects.len() as u8;
                    let stem = f.file_path.rsplit('/').next().unwrap_or(&f.file_path);
                    names.push(format!("{}.{stem}", s.objects.join("-")));
                }
                let dir = pick(first)[i]
                    .file_path
                    .rsplit_once('/')
                    .map_or(".", |(d, _)| d)
                    .to_string();
                SegFrame {
                    file_path: format!("{dir}/{}", names.join("+")),
                    image,
                    mask,
                    camera: cameras[0].camera,
                    object_views: cameras,
                }
            })
            .collect()
    };
    let cap = SegCapture {
        scene: None,
        objects,
        camera_angle_x: first.camera_angle_x,
        train: compose_split(|s| &s.train),
        test: compose_split(|s| &s.test),
        source: format!(
            "composed({})",
            sources
                .iter()
                .map(|s| s.source.as_str())
                .collect::<Vec<_>>()
                .join(" + ")
        ),
    };
    cap.validate()?;
    Ok(cap)
}

/// Loads NeRF-synthetic folders, resizes each to `size × size` when given,
/// and composes them side by side.
pub fn compose_dirs(dirs: &[&Path], size: Option<u32>) -> Result<SegCapture, SegmentError> {
    let mut sources = Vec::new();
    for d in dirs {
        let c = SegCapture::load(d)?;
        sources.push(match size {
            Some(s) => resize_capture(&c, s, s)?,
            None => c,
        });
    }
    compose_side_by_side(&sources)
}

/// The same capture at `width × height`: colour resampled premultiplied
/// with Lanczos-3, masks by nearest neighbour, cameras rescaled.
pub fn resize_capture(
    cap: &SegCapture,
    width: u32,
    height: u32,
) -> Result<SegCapture, SegmentError> {
    if width == 0 || height == 0 {
        return Err(SegmentError::Invalid(format!(
            "resize: {width}×{height} is not an image size"
        )));
    }
    // Every resized view (RGBA8 + mask, 5 B per pixel) is kept, plus about
    // 64 B per pixel of resampling and spectrum buffers while one is worked on.
    let frames = (cap.train.len() + cap.test.len()) as u128;
    let pixels = u128::from(width) * u128::from(height);
    crate::validate::memory(
        &format!("--size: {width}×{height} pixels × {frames} views"),
        pixels * (5 * frames + 64),
        "the resized views (5 B per pixel each) and one view's working buffers (64 B per pixel)",
    )
    .map_err(SegmentError::Invalid)?;
    let resize = |frames: &Vec<SegFrame>| -> Vec<SegFrame> {
        frames
            .par_iter()
            .map(|f| {
                let (image, mask) =
                    resize_view(&f.image, &f.mask, width, height, FilterType::Lanczos3);
                let (sx, sy) = (
                    width as f64 / f.image.width() as f64,
                    height as f64 / f.image.height() as f64,
                );
                let rc = |c: &Camera| Camera {
                    intrinsics: c.intrinsics.resized(width, height),
                    c2w: c.c2w,
                };
                let rr = |r: PixelBox| PixelBox {
                    x0: (r.x0 as f64 * sx).round() as u32,
                    y0: (r.y0 as f64 * sy).round() as u32,
                    x1: ((r.x1 as f64 * sx).round() as u32).min(width),
                    y1: ((r.y1 as f64 * sy).round() as u32).min(height),
                };
                SegFrame {
                    file_path: f.file_path.clone(),
                    image,
                    mask,
                    camera: rc(&f.camera),
                    object_views: f
                        .object_views
                        .iter()
                        .map(|v| ObjectView {
                            camera: rc(&v.camera),
                            region: rr(v.region),
                        })
                        .collect(),
                }
            })
            .collect()
    };
    Ok(SegCapture {
        objects: cap.objects.clone(),
        camera_angle_x: cap.camera_angle_x,
        train: resize(&cap.train),
        test: resize(&cap.test),
        source: format!("{} at {width}×{height}", cap.source),
        scene: cap.scene.clone(),
    })
}
