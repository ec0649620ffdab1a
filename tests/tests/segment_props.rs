//! Property tests of the segmentation's building blocks: crop boxes, the
//! enlargement and the frequency measure on arbitrary inputs.

use nerflex_sim::camera::{Camera, Intrinsics};
use nerflex_sim::capture::image::{GrayImage, RgbaImage};
use nerflex_sim::segment::enlarge::{crop_box, enlarge, EnlargeOptions};
use nerflex_sim::segment::frequency::{detail_frequency, mask_bbox, FrequencyOptions, PixelBox};
use proptest::prelude::*;

fn region() -> impl Strategy<Value = (u32, u32, PixelBox)> {
    (1u32..300, 1u32..300).prop_flat_map(|(w, h)| {
        (0..w, 0..h).prop_flat_map(move |(x0, y0)| {
            (x0 + 1..=w, y0 + 1..=h).prop_map(move |(x1, y1)| (w, h, PixelBox { x0, y0, x1, y1 }))
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn crop_boxes_contain_the_object_stay_inside_and_keep_the_aspect(
        (w, h, bbox) in region(), margin in 0.0f32..0.5,
    ) {
        let full = PixelBox { x0: 0, y0: 0, x1: w, y1: h };
        let c = crop_box(bbox, full, margin);
        prop_assert!(c.x0 <= bbox.x0 && c.y0 <= bbox.y0 && c.x1 >= bbox.x1 && c.y1 >= bbox.y1);
        prop_assert!(c.x1 <= w && c.y1 <= h && c.width() >= 1 && c.height() >= 1);
        // The image's aspect ratio, up to rounding one side to whole pixels
        // (less than a pixel off along one axis), unless the crop reached
        // the image's size. The camera records fx and fy apart, so the
        // geometry stays exact either way.
        let off = (c.width() as i64 * h as i64 - c.height() as i64 * w as i64).abs();
        let at_limit = c.width() == w || c.height() == h;
        prop_assert!(at_limit || off < w.max(h) as i64, "{c:?} in {w}×{h}");
    }

    #[test]
    fn enlarge_and_measure_handle_any_mask_without_panicking(
        w in 1u32..48, h in 1u32..48, seed in any::<u64>(), label in 0u8..4,
    ) {
        // Pseudo-random labels and colours from the seed.
        let mut s = seed | 1;
        let mut next = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
        let raw: Vec<u8> = (0..w * h * 4).map(|_| next() as u8).collect();
        let labels: Vec<u8> = (0..w * h).map(|_| (next() % 4) as u8).collect();
        let image = RgbaImage::from_raw(w, h, raw).unwrap();
        let mask = GrayImage::from_raw(w, h, labels).unwrap();
        let cam = Camera::orbit(10.0, 20.0, 4.0, Default::default(), Intrinsics::from_fov_x(0.7, w, h));
        let present = mask_bbox(&mask, label).is_some();
        let e = enlarge(&image, &mask, label, &cam, &EnlargeOptions::default());
        prop_assert_eq!(e.is_some(), present);
        if let Some(e) = e {
            prop_assert_eq!(e.image.dimensions(), (w, h));
            prop_assert!(e.zoom.0 >= 1.0 && e.zoom.1 >= 1.0);
            prop_assert!(e.camera.intrinsics.fx >= cam.intrinsics.fx * 0.999);
        }
        let opts = FrequencyOptions { min_pixels: 1, ..Default::default() };
        if let Some(f) = detail_frequency(&image, &mask, label, &opts) {
            prop_assert!(f.cycles_per_diameter.is_finite() && f.cycles_per_diameter >= 0.0);
            prop_assert!(f.cycles_per_diameter <= 32.0 + 1e-9, "{f:?}");
        }
    }
}
