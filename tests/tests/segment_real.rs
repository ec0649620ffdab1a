//! Segmentation of a two-object capture composed from the real NeRF-synthetic
//! `lego` and `chair` views (side by side, their alphas as instance masks).

use nerflex_sim::camera::Transforms;
use nerflex_sim::data::require_data;
use nerflex_sim::segment::compose::{compose_dirs, resize_capture};
use nerflex_sim::segment::input::read_rgba;
use nerflex_sim::segment::{analyse, segment, Decision, FrequencyOptions, SegmentOptions};

#[test]
fn lego_chair_ranking_is_the_same_at_800_and_400_pixels() {
    let Some(data) = require_data("lego + chair segmentation ranking") else {
        return;
    };
    let ns = data.join("nerf_synthetic");
    let cap = compose_dirs(&[&ns.join("lego"), &ns.join("chair")], None).unwrap();
    assert_eq!(cap.image_size(), (1600, 800));
    assert_eq!(cap.objects, vec!["lego", "chair"]);
    let small = resize_capture(&cap, 800, 400).unwrap();
    let opts = FrequencyOptions::default();
    let a800 = analyse(&cap, &opts).unwrap();
    let a400 = analyse(&small, &opts).unwrap();
    for (a, b) in a800.objects.iter().zip(&a400.objects) {
        eprintln!(
            "{}: max {:.2} at {} (800 px), {:.2} at {} (400 px)",
            a.name, a.max_frequency, a.peak_image, b.max_frequency, b.peak_image
        );
        assert!(a.per_image.iter().all(|(_, d)| d.is_some()));
        assert!((a.max_frequency / b.max_frequency - 1.0).abs() < 0.05);
    }
    assert_eq!(a800.ranking(), a400.ranking());
}

#[test]
fn lego_chair_views_are_consistent_with_the_source_cameras() {
    let Some(data) = require_data("lego + chair segmentation output") else {
        return;
    };
    let ns = data.join("nerf_synthetic");
    // Reduced size keeps the test fast; the geometry is the same at 800.
    let cap = compose_dirs(&[&ns.join("lego"), &ns.join("chair")], Some(200)).unwrap();
    let out = tempfile::tempdir().unwrap();
    let seg = segment(&cap, &SegmentOptions::default(), out.path()).unwrap();
    assert_eq!(seg.groups.len(), 2, "every object gets a network");
    let top = seg
        .objects
        .iter()
        .max_by(|a, b| a.max_frequency.total_cmp(&b.max_frequency))
        .unwrap();
    assert_eq!(top.decision, Decision::Dedicated);
    let object = cap.objects.iter().position(|n| *n == top.name).unwrap();
    let dir = out.path().join(&top.folder);
    for split in ["train", "test"] {
        let t = Transforms::read(&dir.join(format!("transforms_{split}.json"))).unwrap();
        let frames = if split == "train" {
            &cap.train
        } else {
            &cap.test
        };
        assert_eq!(t.frames.len(), frames.len());
        for (i, f) in t.frames.iter().enumerate() {
            let img = read_rgba(&dir.join(format!("{}.png", f.file_path))).unwrap();
            // Each object's views have its source's size, not the canvas'.
            assert_eq!(img.dimensions(), (200, 200));
            let written = t.camera(i, 200, 200).unwrap();
            let src = frames.iter().find(|s| s.file_path == f.file_path).unwrap();
            let src_cam = src.camera_of(object);
            // Colour difference between the written view and the source
            // seen through the cameras, and with the camera 3 pixels off.
            let mismatch = |shift: f32| {
                let (mut diff, mut n) = (0.0f64, 0u32);
                for (x, y, p) in img.enumerate_pixels() {
                    if p[3] < 255 || x % 3 != 0 || y % 3 != 0 {
                        continue;
                    }
                    let (o, d) = written.ray(x as f32 + 0.5 + shift, y as f32 + 0.5);
                    let Some((sx, sy, _)) = src_cam.project(o + d * 4.0) else {
                        continue;
                    };
                    let (ix, iy) = (sx.floor() as i64, sy.floor() as i64);
                    if ix < 0 || iy < 0 || ix >= 400 || iy >= 200 {
                        continue;
                    }
                    let q = src.image.get_pixel(ix as u32, iy as u32);
                    diff += (0..3)
                        .map(|c| (p[c] as f64 - q[c] as f64).abs())
                        .sum::<f64>()
                        / 3.0;
                    n += 1;
                }
                assert!(n > 100, "{}: only {n} pixels compared", f.file_path);
                diff / n as f64
            };
            let right = mismatch(0.0);
            let wrong = mismatch(3.0);
            eprintln!("{}: {right:.2} vs {wrong:.2}", f.file_path);
            assert!(
                right < 0.6 * wrong,
                "{}: |Δ| {right:.2} with the written camera vs {wrong:.2} with a shifted one",
                f.file_path
            );
        }
    }
}

#[test]
fn a_composite_cannot_share_one_network_across_cameras() {
    let Some(data) = require_data("lego + chair shared group") else {
        return;
    };
    let ns = data.join("nerf_synthetic");
    let mut cap = compose_dirs(&[&ns.join("lego"), &ns.join("chair")], Some(64)).unwrap();
    cap.train.truncate(2);
    let out = tempfile::tempdir().unwrap();
    let opts = SegmentOptions {
        alpha: Some(1e9),
        ..Default::default()
    };
    let e = segment(&cap, &opts, out.path()).unwrap_err().to_string();
    assert!(
        e.contains("different cameras") && e.contains("--alpha"),
        "{e}"
    );
    assert_eq!(std::fs::read_dir(out.path()).unwrap().count(), 0);
}
