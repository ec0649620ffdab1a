//! Per-view scores of a rendered scene: whole-image SSIM / PSNR / LPIPS of
//! each held-out view, and each scene object's SSIM / PSNR in its own box
//! of that view (the ground truth's instance mask, padded). The evaluation
//! needs the views, not only their mean, for intervals and paired
//! differences; it needs the objects for the per-object analysis (Scene 4's
//! allocation, and whether the segmentation's measure predicts what a
//! dedicated network gains), and every method is cropped to the same boxes.

use crate::capture::Frame;
use crate::metrics::{Lpips, Metrics};
use crate::segment::frequency::mask_bbox;
use anyhow::Context as _;
use image::RgbaImage;
use serde::{Deserialize, Serialize};

/// Objects covering fewer pixels than this in a view (hidden or cut by
/// the frame) get no score in that view.
pub const MIN_OBJECT_PIXELS: u32 = 64;

/// Pixels added around an object's mask box, so SSIM's window sees its
/// silhouette against the background.
pub const BOX_MARGIN_PX: u32 = 4;

/// Smallest side of a box, pixels (SSIM's window is 11).
pub const MIN_BOX_SIDE_PX: u32 = 16;

/// PSNR of identical images counts as this (dB), as in the scene means.
pub const PSNR_CAP_DB: f64 = 100.0;

/// One held-out view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewScores {
    /// Index in the capture's held-out views (for a composite: in the
    /// object's source capture's).
    pub view: usize,
    /// For a composite, the object whose own capture the view comes from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// SSIM of the whole image.
    pub ssim: f64,
    /// PSNR of the whole image, dB (capped at [`PSNR_CAP_DB`]).
    pub psnr: f64,
    /// LPIPS of the whole image, if computed.
    pub lpips: Option<f64>,
    /// Each scene object in its box (objects too small in this view are
    /// left out).
    #[serde(default)]
    pub objects: Vec<ObjectScores>,
}

/// One scene object in one view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectScores {
    /// Scene object name (from `scene.json`).
    pub object: String,
    /// SSIM inside its box.
    pub ssim: f64,
    /// PSNR inside its box, dB (capped).
    pub psnr: f64,
    /// Its mask pixels in the ground truth.
    pub pixels: u32,
}

/// The box of `label` in `mask`, padded by [`BOX_MARGIN_PX`], grown to at
/// least [`MIN_BOX_SIDE_PX`] per side and kept inside the image; `None`
/// when the object covers fewer than [`MIN_OBJECT_PIXELS`].
pub fn object_box(mask: &image::GrayImage, label: u8) -> Option<(u32, u32, u32, u32, u32)> {
    let (b, n) = mask_bbox(mask, label)?;
    if n < MIN_OBJECT_PIXELS {
        return None;
    }
    let (w, h) = mask.dimensions();
    let grow = |lo: u32, hi: u32, size: u32| -> (u32, u32) {
        let mut lo = lo.saturating_sub(BOX_MARGIN_PX);
        let mut hi = (hi + BOX_MARGIN_PX).min(size);
        while hi - lo < MIN_BOX_SIDE_PX.min(size) {
            lo = lo.saturating_sub(1);
            if hi < size {
                hi += 1;
            }
        }
        (lo, hi)
    };
    let (x0, x1) = grow(b.x0, b.x1, w);
    let (y0, y1) = grow(b.y0, b.y1, h);
    Some((x0, y0, x1 - x0, y1 - y0, n))
}

/// Scores `rendered` against the held-out frame `truth`: the whole image,
/// and each of `objects` (name, mask label) in its box.
pub fn score_view(
    view: usize,
    rendered: &RgbaImage,
    truth: &Frame,
    objects: &[(String, u8)],
    lpips: Option<&Lpips>,
) -> anyhow::Result<ViewScores> {
    let s = Metrics::compare(rendered, &truth.image, lpips)
        .with_context(|| format!("measuring held-out view {view}"))?;
    let mut out = ViewScores {
        view,
        source: None,
        ssim: s.ssim,
        psnr: s.psnr.min(PSNR_CAP_DB),
        lpips: s.lpips,
        objects: Vec::new(),
    };
    let Some(mask) = &truth.mask else {
        return Ok(out);
    };
    for (name, label) in objects {
        let Some((x, y, w, h, pixels)) = object_box(mask, *label) else {
            continue;
        };
        let a = image::imageops::crop_imm(rendered, x, y, w, h).to_image();
        let b = image::imageops::crop_imm(&truth.image, x, y, w, h).to_image();
        let o = Metrics::compare(&a, &b, None)
            .with_context(|| format!("measuring {name} in held-out view {view}"))?;
        out.objects.push(ObjectScores {
            object: name.clone(),
            ssim: o.ssim,
            psnr: o.psnr.min(PSNR_CAP_DB),
            pixels,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Intrinsics};
    use image::{GrayImage, Luma, Rgba};

    fn frame(w: u32, h: u32) -> Frame {
        let mut mask = GrayImage::new(w, h);
        let mut image = RgbaImage::from_pixel(w, h, Rgba([0, 0, 0, 0]));
        // Object 1: a 20×10 block at (10, 20); object 2: 3 pixels only.
        for y in 20..30 {
            for x in 10..30 {
                mask.put_pixel(x, y, Luma([1]));
                image.put_pixel(x, y, Rgba([200, 40, 40, 255]));
            }
        }
        for x in 50..53 {
            mask.put_pixel(x, 5, Luma([2]));
        }
        Frame {
            file_path: "./test/r_0".into(),
            camera: Camera {
                intrinsics: Intrinsics::from_fov_x(0.7, w, h),
                c2w: glam::Mat4::IDENTITY,
            },
            image,
            mask: Some(mask),
        }
    }

    #[test]
    fn boxes_are_padded_clamped_and_skip_small_objects() {
        let f = frame(64, 48);
        let m = f.mask.as_ref().unwrap();
        // [10, 30) × [20, 30) padded by 4: [6, 34) × [16, 34).
        assert_eq!(object_box(m, 1), Some((6, 16, 28, 18, 200)));
        assert_eq!(object_box(m, 2), None);
        assert_eq!(object_box(m, 3), None);
        // Near the border a box stays inside and keeps the minimum side.
        let mut edge = GrayImage::new(20, 20);
        for y in 0..8 {
            for x in 0..8 {
                edge.put_pixel(x, y, Luma([1]));
            }
        }
        let (x, y, w, h, n) = object_box(&edge, 1).unwrap();
        assert_eq!((x, y, n), (0, 0, 64));
        assert!(w >= MIN_BOX_SIDE_PX && h >= MIN_BOX_SIDE_PX && w <= 20 && h <= 20);
    }

    #[test]
    fn a_perfect_render_scores_one_and_a_wrong_object_scores_lower() {
        let f = frame(64, 48);
        let objects = [("a".to_string(), 1u8), ("b".to_string(), 2u8)];
        let s = score_view(0, &f.image, &f, &objects, None).unwrap();
        assert!((s.ssim - 1.0).abs() < 1e-12 && s.psnr == PSNR_CAP_DB);
        assert_eq!(s.objects.len(), 1, "object b is too small to score");
        assert!((s.objects[0].ssim - 1.0).abs() < 1e-12);
        let mut wrong = f.image.clone();
        for y in 22..28 {
            for x in 12..28 {
                wrong.put_pixel(x, y, Rgba([20, 200, 20, 255]));
            }
        }
        let w = score_view(0, &wrong, &f, &objects, None).unwrap();
        assert!(w.objects[0].ssim < 0.9, "{w:?}");
        // The object's box is a fraction of the image, so its score drops
        // further than the whole image's.
        assert!(w.objects[0].ssim < w.ssim, "{w:?}");
    }
}
