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
use crate::capture::OTHER_OBJECTS_MASK_VALUE;
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
    /// The object's mask at full size: 1 on the object (coverage ≥ ½),
    /// [`OTHER_OBJECTS_MASK_VALUE`] where another object of the source mask
    /// covers the view instead (nearest neighbour, grown by one source pixel
    /// so the resampled silhouette's edge never leaves a gap), 0 elsewhere.
    /// The other objects are transparent in `image` all the same; the mark
    /// tells the baker that the object may continue behind them.
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
    let (iw, cw) = (image.width() as usize, crop.width() as usize);
    let (raw, mraw) = (image.as_raw(), mask.as_raw());
    let mut buf = vec![0.0f32; 4 * cw * crop.height() as usize];
    for y in 0..crop.height() as usize {
        for x in 0..cw {
            let i = (crop.y0 as usize + y) * iw + crop.x0 as usize + x;
            if mraw[i] != label {
                continue;
            }
            let p = &raw[4 * i..4 * i + 4];
            let a = p[3] as f32 / 255.0;
            let o = 4 * (y * cw + x);
            buf[o] = p[0] as f32 / 255.0 * a;
            buf[o + 1] = p[1] as f32 / 255.0 * a;
            buf[o + 2] = p[2] as f32 / 255.0 * a;
            buf[o + 3] = a;
        }
    }
    let src = Rgba32FImage::from_raw(crop.width(), crop.height(), buf)?;
    let big = imageops::resize(&src, w, h, opts.filter);
    // The filter rings near the silhouette: alpha below RING is cut so no
    // faint halo lies outside it, and the mask is where coverage ≥ ½.
    const RING: f32 = 8.0 / 255.0;
    let mut out = RgbaImage::new(w, h);
    let mut mask_out = GrayImage::new(w, h);
    for ((p, q), m) in big
        .pixels()
        .zip(out.pixels_mut())
        .zip(mask_out.pixels_mut())
    {
        if p[3] >= RING {
            *q = unpremultiply(p);
            m[0] = u8::from(p[3] >= 0.5);
        }
    }
    mark_other_objects(&mut mask_out, mask, label, crop, region);
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

/// Marks [`OTHER_OBJECTS_MASK_VALUE`] on the pixels of `out` (the enlarged
/// view of `crop`) that are not the object and whose source pixel, or one of
/// its 8 neighbours inside `region`, shows another object (a nonzero label
/// other than `label`). The source pixel of output pixel i is the one under
/// its centre, crop.x0 + ⌊(i + ½)·crop_w / out_w⌋ (the resampler's map).
fn mark_other_objects(
    out: &mut GrayImage,
    src: &GrayImage,
    label: u8,
    crop: PixelBox,
    region: PixelBox,
) {
    let (w, h) = out.dimensions();
    let (cw, ch) = (u64::from(crop.width()), u64::from(crop.height()));
    let other = |x: u32, y: u32| {
        let v = src.get_pixel(x, y)[0];
        v != 0 && v != label
    };
    // Source rows/columns hit by the output's, and whether a 3×3
    // neighbourhood there shows another object (computed once per source
    // pixel of the crop).
    let sx: Vec<u32> = (0..u64::from(w))
        .map(|i| crop.x0 + ((2 * i + 1) * cw / (2 * u64::from(w))) as u32)
        .collect();
    let sy: Vec<u32> = (0..u64::from(h))
        .map(|j| crop.y0 + ((2 * j + 1) * ch / (2 * u64::from(h))) as u32)
        .collect();
    let near = GrayImage::from_fn(crop.width(), crop.height(), |x, y| {
        let (x, y) = (crop.x0 + x, crop.y0 + y);
        let xs = x.saturating_sub(1).max(region.x0)..=(x + 1).min(region.x1 - 1);
        let found = xs.clone().any(|nx| {
            (y.saturating_sub(1).max(region.y0)..=(y + 1).min(region.y1 - 1))
                .any(|ny| other(nx, ny))
        });
        image::Luma([u8::from(found)])
    });
    for (x, y, m) in out.enumerate_pixels_mut() {
        if m[0] == 0 && near.get_pixel(sx[x as usize] - crop.x0, sy[y as usize] - crop.y0)[0] == 1 {
            m[0] = OTHER_OBJECTS_MASK_VALUE;
        }
    }
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
/// and its mask relabelled through `relabel` (0 = drop): a dropped object's
/// pixels get [`OTHER_OBJECTS_MASK_VALUE`] (so the baker knows something
/// hid the kept objects there), background stays 0. Used for the shared
/// group: the original view with the dedicated objects removed.
pub fn isolate(
    image: &RgbaImage,
    mask: &GrayImage,
    relabel: impl Fn(u8) -> u8,
) -> (RgbaImage, GrayImage) {
    let new_mask = GrayImage::from_fn(mask.width(), mask.height(), |x, y| {
        let l = mask.get_pixel(x, y)[0];
        Luma([match relabel(l) {
            0 if l != 0 => OTHER_OBJECTS_MASK_VALUE,
            v => v,
        }])
    });
    let out = RgbaImage::from_fn(image.width(), image.height(), |x, y| {
        match new_mask.get_pixel(x, y)[0] {
            0 | OTHER_OBJECTS_MASK_VALUE => Rgba([0; 4]),
            _ => *image.get_pixel(x, y),
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn full(w: u32, h: u32) -> PixelBox {
        PixelBox {
            x0: 0,
            y0: 0,
            x1: w,
            y1: h,
        }
    }

    #[test]
    fn crop_box_keeps_the_aspect_contains_the_object_and_stays_inside() {
        let cases = [
            (
                PixelBox {
                    x0: 10,
                    y0: 20,
                    x1: 30,
                    y1: 100,
                },
                800,
                800,
            ),
            (
                PixelBox {
                    x0: 0,
                    y0: 0,
                    x1: 800,
                    y1: 5,
                },
                800,
                800,
            ),
            (
                PixelBox {
                    x0: 790,
                    y0: 700,
                    x1: 800,
                    y1: 800,
                },
                800,
                800,
            ),
            (
                PixelBox {
                    x0: 100,
                    y0: 100,
                    x1: 200,
                    y1: 150,
                },
                1600,
                800,
            ),
            (
                PixelBox {
                    x0: 3,
                    y0: 3,
                    x1: 4,
                    y1: 4,
                },
                640,
                480,
            ),
        ];
        for (b, w, h) in cases {
            let c = crop_box(b, full(w, h), 0.0);
            assert!(
                c.x0 <= b.x0 && c.y0 <= b.y0 && c.x1 >= b.x1 && c.y1 >= b.y1,
                "{b:?} {c:?}"
            );
            assert!(c.x1 <= w && c.y1 <= h);
            let aspect = (c.width() as f64 / c.height() as f64) / (w as f64 / h as f64);
            assert!(
                (aspect - 1.0).abs() < 2.0 / c.height().min(c.width()) as f64 + 1e-9,
                "{c:?}"
            );
        }
        // A margin grows the box; a region confines it.
        let b = PixelBox {
            x0: 300,
            y0: 300,
            x1: 400,
            y1: 400,
        };
        let c = crop_box(b, full(800, 800), 0.1);
        assert_eq!((c.width(), c.height()), (120, 120));
        let r = PixelBox {
            x0: 800,
            y0: 0,
            x1: 1600,
            y1: 800,
        };
        let b = PixelBox {
            x0: 810,
            y0: 10,
            x1: 900,
            y1: 30,
        };
        let c = crop_box(b, r, 0.0);
        assert!(c.x0 >= 800 && c.x1 <= 1600 && c.width() == c.height() && c.width() == 90);
    }

    #[test]
    fn enlarged_dots_land_where_the_adjusted_camera_projects_them() {
        // Bright 3x3 dots at the projections of a few world points; after
        // enlargement the dot centroids must sit at the adjusted camera's
        // projections (to a fraction of a source pixel).
        let k = Intrinsics::from_fov_x(0.69, 320, 240);
        let cam = Camera::orbit(25.0, 30.0, 4.0, Vec3::ZERO, k);
        let points = [
            Vec3::new(0.2, 0.1, 0.0),
            Vec3::new(-0.25, 0.2, 0.1),
            Vec3::new(0.1, -0.3, -0.2),
        ];
        let mut img = RgbaImage::new(320, 240);
        let mut mask = GrayImage::new(320, 240);
        let mut centres = Vec::new();
        for p in points {
            let (x, y, _) = cam.project(p).unwrap();
            let (ix, iy) = (x.floor() as u32, y.floor() as u32);
            centres.push((ix as f32 + 0.5, iy as f32 + 0.5));
            for dy in 0..3 {
                for dx in 0..3 {
                    img.put_pixel(ix + dx - 1, iy + dy - 1, Rgba([255, 255, 255, 255]));
                }
            }
        }
        // The object's mask: a box around all dots (dots on a dark object).
        for (x, y, p) in img.enumerate_pixels_mut() {
            let inside = centres
                .iter()
                .any(|c| (x as f32 - c.0).abs() < 40.0 && (y as f32 - c.1).abs() < 40.0);
            if inside {
                mask.put_pixel(x, y, Luma([1]));
                if p[3] == 0 {
                    *p = Rgba([0, 0, 0, 255]);
                }
            }
        }
        let e = enlarge(&img, &mask, 1, &cam, &EnlargeOptions::default()).unwrap();
        assert!(
            e.zoom.0 > 1.5 && (e.zoom.0 - e.zoom.1).abs() < 0.02,
            "{:?}",
            e.zoom
        );
        for (c, p) in centres.iter().zip(points) {
            // Where the dot centre (pixel centre, not the exact projection)
            // lands: back-project it onto the point's depth, reproject.
            let (_, _, depth) = cam.project(p).unwrap();
            let (o, d) = cam.ray(c.0, c.1);
            let fwd = -cam.c2w.z_axis.truncate();
            let q = o + d * (depth / d.dot(fwd));
            let (ex, ey, _) = e.camera.project(q).unwrap();
            // Brightness-weighted centroid in a window around the prediction.
            let (mut sw, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
            let r = (3.0 * e.zoom.0) as i64 + 3;
            for y in (ey as i64 - r)..=(ey as i64 + r) {
                for x in (ex as i64 - r)..=(ex as i64 + r) {
                    if x < 0 || y < 0 || x >= 320 || y >= 240 {
                        continue;
                    }
                    let v = e.image.get_pixel(x as u32, y as u32)[0] as f64;
                    sw += v;
                    sx += v * (x as f64 + 0.5);
                    sy += v * (y as f64 + 0.5);
                }
            }
            assert!(sw > 0.0);
            let (cx, cy) = (sx / sw, sy / sw);
            let tol = 0.35 * e.zoom.0;
            assert!(
                (cx - ex as f64).abs() < tol && (cy - ey as f64).abs() < tol,
                "centroid ({cx:.2}, {cy:.2}) vs projection ({ex:.2}, {ey:.2})"
            );
        }
        // The mask is where the enlarged coverage is at least one half.
        assert!(e
            .image
            .enumerate_pixels()
            .all(|(x, y, p)| (p[3] >= 128) == (e.mask.get_pixel(x, y)[0] == 1)));
    }

    #[test]
    fn isolate_removes_objects_and_relabels() {
        let img = RgbaImage::from_pixel(4, 1, Rgba([9, 9, 9, 255]));
        let mask = GrayImage::from_raw(4, 1, vec![0, 1, 2, 3]).unwrap();
        let (out, m) = isolate(&img, &mask, |l| if l == 3 { 1 } else { 0 });
        assert_eq!(m.as_raw(), &vec![0, 255, 255, 1]);
        assert_eq!(out.get_pixel(2, 0)[3], 0);
        assert_eq!(out.get_pixel(3, 0)[3], 255);
    }
}
