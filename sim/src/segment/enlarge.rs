//! Enlarged training views of one object, and views with objects removed.
//!
//! An object's view is cropped to the bounding box of its mask, widened to
//! the image's aspect ratio (so the object is never stretched and the
//! enlarged camera keeps square pixels up to rounding), and scaled back to
//! the full image size with a Lanczos-3 filter (`image::imageops::resize`) on
//! premultiplied colour. The camera of the enlarged view is the original one
//! with [`Intrinsics::cropped`]: a narrower field of view and a shifted
//! principal point, so every world point projects onto the same content.
//! `image`'s resampler maps output pixel centres `(i + 0.5)·w/out_w` to the
//! crop, which is exactly the affine map `cropped` assumes.

use super::frequency::{mask_bbox, PixelBox};
use crate::camera::{Camera, Intrinsics};
use image::{imageops, imageops::FilterType, GrayImage, Luma, Rgba, Rgba32FImage, RgbaImage};

/// Settings of the enlargement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnlargeOptions {
    /// Resampling filter (Lanczos3 by default; CatmullRom is the bicubic one).
    pub filter: FilterType,
    /// Extra border around the mask's bounding box, as a fraction of the
    /// box's longer side (0 = the mask's outermost pixels are the border, as
    /// in the NeRFlex paper).
    pub margin: f32,
}

impl Default for EnlargeOptions {
    fn default() -> Self {
        Self {
            filter: FilterType::Lanczos3,
            margin: 0.0,
        }
    }
}

/// One enlarged view of one object.
#[derive(Debug, Clone)]
pub struct Enlarged {
    /// Full-size image; alpha is the object's own coverage (other objects
    /// and the background are transparent).
    pub image: RgbaImage,
    /// The object's mask at full size: 1 on the object, 0 elsewhere.
    pub mask: GrayImage,
    /// The camera that sees this image: same pose, cropped intrinsics.
    pub camera: Camera,
    /// The crop in the original image's pixels.
    pub crop: PixelBox,
    /// Scale factors output/crop along x and y (≥ 1).
    pub zoom: (f64, f64),
}

/// The crop box for an object with tight box `bbox` (inside `region`):
/// `bbox` plus `margin`, widened about its centre to the region's aspect
/// ratio, shifted to lie inside the region.
pub fn crop_box(bbox: PixelBox, region: PixelBox, margin: f32) -> PixelBox {
    let (width, height) = (region.width(), region.height());
    let bbox = PixelBox {
        x0: bbox.x0.clamp(region.x0, region.x1) - region.x0,
        y0: bbox.y0.clamp(region.y0, region.y1) - region.y0,
        x1: bbox.x1.clamp(region.x0, region.x1) - region.x0,
        y1: bbox.y1.clamp(region.y0, region.y1) - region.y0,
    };
    let m = (margin.max(0.0) * bbox.width().max(bbox.height()) as f32).round() as u32;
    let (bw, bh) = (
        (bbox.width() + 2 * m).min(width),
        (bbox.height() + 2 * m).min(height),
    );
    // Widen the shorter side so bw / bh = width / height (integers, rounded
    // up so the object always fits).
    let (bw, bh) = if (bw as u64) * (height as u64) < (bh as u64) * (width as u64) {
        let w2 = ((bh as u64 * width as u64).div_ceil(height as u64)) as u32;
        (w2.min(width), bh)
    } else {
        let h2 = ((bw as u64 * height as u64).div_ceil(width as u64)) as u32;
        (bw, h2.min(height))
    };
    let place = |lo: u32, hi: u32, len: u32, limit: u32| -> u32 {
        let centre2 = lo as i64 + hi as i64; // twice the centre
        let start = (centre2 - len as i64).div_euclid(2);
        start.clamp(0, (limit - len) as i64) as u32
    };
    let x0 = region.x0 + place(bbox.x0, bbox.x1, bw, width);
    let y0 = region.y0 + place(bbox.y0, bbox.y1, bh, height);
    PixelBox {
        x0,
        y0,
        x1: x0 + bw,
        y1: y0 + bh,
    }
}

/// The enlarged view of the object labelled `label`, seen through `camera`,
/// at the image's size; `None` when the object is absent from the view.
pub fn enlarge(
    image: &RgbaImage,
    mask: &GrayImage,
    label: u8,
    camera: &Camera,
    opts: &EnlargeOptions,
) -> Option<Enlarged> {
    let region = PixelBox {
        x0: 0,
        y0: 0,
        x1: image.width(),
        y1: image.height(),
    };
    enlarge_within(image, mask, label, camera, region, opts)
}

/// As [`enlarge`], for an object that lives in the sub-rectangle `region`
/// of the image (a source's place in a composite): the crop stays inside
/// `region` and the output has the region's size. `camera` is the object's
/// camera for the whole image.
pub fn enlarge_within(
    image: &RgbaImage,
    mask: &GrayImage,
    label: u8,
    camera: &Camera,
    region: PixelBox,
    opts: &EnlargeOptions,
) -> Option<Enlarged> {
    if mask.dimensions() != image.dimensions()
        || region.x1 > image.width()
        || region.y1 > image.height()
        || region.x0 >= region.x1
        || region.y0 >= region.y1
    {
        return None;
    }
    let (w, h) = (region.width(), region.height());
    let (bbox, _) = mask_bbox(mask, label)?;
    let crop = crop_box(bbox, region, opts.margin);
    // Premultiplied crop with everything but the object made transparent.
    let src = Rgba32FImage::from_fn(crop.width(), crop.height(), |x, y| {
        let (sx, sy) = (crop.x0 + x, crop.y0 + y);
        if mask.get_pixel(sx, sy)[0] != label {
            return Rgba([0.0; 4]);
        }
        let p = image.get_pixel(sx, sy);
        let a = p[3] as f32 / 255.0;
        Rgba([
            p[0] as f32 / 255.0 * a,
            p[1] as f32 / 255.0 * a,
            p[2] as f32 / 255.0 * a,
            a,
        ])
    });
    let binary = GrayImage::from_fn(crop.width(), crop.height(), |x, y| {
        Luma([if mask.get_pixel(crop.x0 + x, crop.y0 + y)[0] == label {
            255
        } else {
            0
        }])
    });
    let big = imageops::resize(&src, w, h, opts.filter);
    // The mask is resampled the same way and cut at one half, so the
    // filter's ringing cannot leave faint alpha outside the silhouette.
    let big_mask = imageops::resize(&binary, w, h, FilterType::Triangle);
    let mask_out = GrayImage::from_fn(w, h, |x, y| Luma([u8::from(big_mask.get_pixel(x, y)[0] >= 128)]));
    let out = RgbaImage::from_fn(w, h, |x, y| {
        if mask_out.get_pixel(x, y)[0] == 0 {
            return Rgba([0; 4]);
        }
        unpremultiply(big.get_pixel(x, y))
    });
    let k = camera.intrinsics;
    let intrinsics: Intrinsics = k.cropped(
        crop.x0 as f32,
        crop.y0 as f32,
        crop.width() as f32,
        crop.height() as f32,
        w,
        h,
    );
    Some(Enlarged {
        image: out,
        mask: mask_out,
        camera: Camera {
            intrinsics,
            c2w: camera.c2w,
        },
        crop,
        zoom: (
            w as f64 / crop.width() as f64,
            h as f64 / crop.height() as f64,
        ),
    })
}

fn unpremultiply(p: &Rgba<f32>) -> Rgba<u8> {
    let a = p[3].clamp(0.0, 1.0);
    if a < 0.5 / 255.0 {
        return Rgba([0; 4]);
    }
    let c = |v: f32| ((v / a).clamp(0.0, 1.0) * 255.0).round() as u8;
    Rgba([c(p[0]), c(p[1]), c(p[2]), (a * 255.0).round() as u8])
}

/// `image` with every pixel whose mask label is not kept made transparent,
/// and its mask relabelled through `relabel` (0 = drop). Used for the shared
/// group: the original view with the dedicated objects removed.
pub fn isolate(
    image: &RgbaImage,
    mask: &GrayImage,
    relabel: impl Fn(u8) -> u8,
) -> (RgbaImage, GrayImage) {
    let new_mask = GrayImage::from_fn(mask.width(), mask.height(), |x, y| {
        Luma([relabel(mask.get_pixel(x, y)[0])])
    });
    let out = RgbaImage::from_fn(image.width(), image.height(), |x, y| {
        if new_mask.get_pixel(x, y)[0] == 0 {
            Rgba([0; 4])
        } else {
            *image.get_pixel(x, y)
        }
    });
    (out, new_mask)
}

/// Resizes a whole view: colour premultiplied with `filter`, the instance
/// mask by nearest neighbour, the cameras with [`Intrinsics::resized`].
pub fn resize_view(
    image: &RgbaImage,
    mask: &GrayImage,
    width: u32,
    height: u32,
    filter: FilterType,
) -> (RgbaImage, GrayImage) {
    let src = Rgba32FImage::from_fn(image.width(), image.height(), |x, y| {
        let p = image.get_pixel(x, y);
        let a = p[3] as f32 / 255.0;
        Rgba([
            p[0] as f32 / 255.0 * a,
            p[1] as f32 / 255.0 * a,
            p[2] as f32 / 255.0 * a,
            a,
        ])
    });
    let big = imageops::resize(&src, width, height, filter);
    let out = RgbaImage::from_fn(width, height, |x, y| unpremultiply(big.get_pixel(x, y)));
    let m = imageops::resize(mask, width, height, FilterType::Nearest);
    (out, m)
}
