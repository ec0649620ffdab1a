//! Segmentation on a ray-cast capture of textured spheres whose detail is
//! known (stripe count), with exact 3-D geometry to check the enlarged views.

use nerflex_sim::camera::{Intrinsics, Transforms};
use nerflex_sim::segment::compose::resize_capture;
use nerflex_sim::segment::input::read_rgba;
use nerflex_sim::segment::testscene::{render_view, ring_of_five, sphere_capture};
use nerflex_sim::segment::{
    analyse, segment, Decision, FrequencyOptions, SegmentOptions, Segmentation, SEGMENTATION_FILE,
};

#[test]
fn ranking_follows_the_stripes_and_is_stable_from_800_to_400_pixels() {
    let cap = sphere_capture(&ring_of_five(), 20, 0, 800);
    let small = resize_capture(&cap, 400, 400).unwrap();
    let tiny = resize_capture(&cap, 200, 200).unwrap();
    let opts = FrequencyOptions::default();
    let a800 = analyse(&cap, &opts).unwrap();
    let a400 = analyse(&small, &opts).unwrap();
    let a200 = analyse(&tiny, &opts).unwrap();
    for ((a, b), c) in a800.objects.iter().zip(&a400.objects).zip(&a200.objects) {
        eprintln!(
            "{}: {:.1} (800) {:.1} (400) {:.1} (200) cycles per object diameter",
            a.name, a.max_frequency, b.max_frequency, c.max_frequency
        );
        // Within the band, the value in object units does not depend on size.
        assert!((a.max_frequency / b.max_frequency - 1.0).abs() < 0.05);
    }
    // s24, s12, s06, s03, s01: the sphere with more stripes ranks higher.
    assert_eq!(a800.ranking(), vec![4, 3, 2, 1, 0]);
    assert_eq!(a400.ranking(), a800.ranking());
}

#[test]
fn segment_writes_training_sets_that_match_the_geometry() {
    let spheres = ring_of_five();
    let cap = sphere_capture(&spheres, 6, 2, 240);
    let out = tempfile::tempdir().unwrap();
    let analysis = analyse(&cap, &FrequencyOptions::default()).unwrap();
    // α between the 3rd and 4th object: three dedicated, two shared.
    let mut maxima: Vec<f64> = analysis.objects.iter().map(|o| o.max_frequency).collect();
    maxima.sort_by(f64::total_cmp);
    let alpha = 0.5 * (maxima[1] + maxima[2]);
    let opts = SegmentOptions {
        alpha: Some(alpha),
        ..Default::default()
    };
    let seg = segment(&cap, &opts, out.path()).unwrap();
    let read = Segmentation::read(&out.path().join(SEGMENTATION_FILE)).unwrap();
    assert_eq!(read, seg);
    assert_eq!(seg.alpha, alpha);
    assert_eq!(seg.groups.len(), 4);
    let dedicated: Vec<&str> = seg
        .objects
        .iter()
        .filter(|o| o.decision == Decision::Dedicated)
        .map(|o| o.name.as_str())
        .collect();
    assert_eq!(dedicated, vec!["s06", "s12", "s24"]);
    let shared = seg.groups.last().unwrap();
    assert_eq!(shared.decision, Decision::Shared);
    assert_eq!(shared.objects, vec!["s01", "s03"]);
    for o in &seg.objects {
        assert_eq!(o.per_image.len(), 6);
        assert!(o.per_image.iter().any(|r| r.image == o.peak_image));
        assert_eq!(seg.groups[o.group].folder, o.folder);
    }

    // Every dedicated view: alpha only on the object, and a fresh render of
    // that sphere alone through the written camera covers the same pixels
    // and shows the same colours.
    for o in seg
        .objects
        .iter()
        .filter(|o| o.decision == Decision::Dedicated)
    {
        let dir = out.path().join(&o.folder);
        let t = Transforms::read(&dir.join("transforms_train.json")).unwrap();
        assert_eq!(t.frames.len(), seg.groups[o.group].train_frames);
        assert!(seg.groups[o.group].mean_zoom > 1.5);
        let sphere = spheres.iter().find(|s| s.name == o.name).unwrap().clone();
        let label = spheres.iter().position(|s| s.name == o.name).unwrap() as u8 + 1;
        let (mut hidden, mut hidden_marked) = (0u32, 0u32);
        for (i, f) in t.frames.iter().enumerate() {
            assert!(f.fl_x.is_some() && f.cx.is_some());
            let img = read_rgba(&dir.join(format!("{}.png", f.file_path))).unwrap();
            assert_eq!(img.dimensions(), (240, 240));
            let mask = image::open(dir.join(format!("{}_mask.png", f.file_path)))
                .unwrap()
                .to_luma8();
            let cam = t.camera(i, 240, 240).unwrap();
            let base = Intrinsics::from_fov_x(t.camera_angle_x as f32, 240, 240);
            let zoom = f64::from(cam.intrinsics.fx / base.fx);
            let (truth, tmask) = render_view(std::slice::from_ref(&sphere), &cam);
            // Where a nearer sphere hides this one, the mask says "another
            // object" (255), not background; elsewhere it never says so
            // unless another sphere is there or within a pixel or two.
            let (_, all) = render_view(&spheres, &cam);
            for (x, y, m) in mask.enumerate_pixels() {
                let (a, t) = (all.get_pixel(x, y)[0], tmask.get_pixel(x, y)[0]);
                // (Pixels the resampled silhouette still claims, at its
                // edge, are the object's, not hidden.)
                if t == 1 && a != label && a != 0 && m[0] != 1 {
                    hidden += 1;
                    hidden_marked += u32::from(m[0] == 255);
                }
                if m[0] == 255 {
                    // One source pixel (grown by one) is `zoom` pixels here.
                    let r = (3.0 * zoom).ceil() as i64 + 1;
                    let near_other = (-r..=r).any(|dy| {
                        (-r..=r).any(|dx| {
                            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                            (0..240).contains(&nx)
                                && (0..240).contains(&ny)
                                && ![0, label].contains(&all.get_pixel(nx as u32, ny as u32)[0])
                        })
                    });
                    assert!(near_other, "{} {}: 255 at ({x}, {y})", o.name, f.file_path);
                }
            }
            let (mut inter, mut union, mut diff, mut n) = (0u32, 0u32, 0.0f64, 0u32);
            for (x, y, p) in img.enumerate_pixels() {
                let a = p[3] > 0;
                let b = tmask.get_pixel(x, y)[0] == 1;
                inter += u32::from(a && b);
                union += u32::from(a || b);
                if a && b && p[3] == 255 {
                    let q = truth.get_pixel(x, y);
                    diff += (0..3)
                        .map(|c| (p[c] as f64 - q[c] as f64).abs())
                        .sum::<f64>()
                        / 3.0;
                    n += 1;
                }
            }
            let iou = inter as f64 / union as f64;
            eprintln!(
                "{} {}: IoU {iou:.3} diff {:.2}",
                o.name,
                f.file_path,
                diff / n as f64
            );
            // The sphere may be partly hidden by a nearer one in the capture.
            assert!(iou > 0.93, "{} {}: IoU {iou}", o.name, f.file_path);
            let mean_diff = diff / n as f64;
            assert!(
                mean_diff < 6.0,
                "{} {}: mean |Δ| {mean_diff}",
                o.name,
                f.file_path
            );
        }
        eprintln!(
            "{}: {hidden_marked} of {hidden} hidden pixels marked",
            o.name
        );
        assert!(
            hidden_marked as f64 >= 0.98 * hidden as f64,
            "{}: {hidden_marked} of {hidden} hidden pixels marked",
            o.name
        );
    }

    // The shared views are the originals with the dedicated objects removed.
    let dir = out.path().join(&shared.folder);
    let t = Transforms::read(&dir.join("transforms_train.json")).unwrap();
    for f in &t.frames {
        let src = cap
            .train
            .iter()
            .find(|s| s.file_path == f.file_path)
            .unwrap();
        let img = read_rgba(&dir.join(format!("{}.png", f.file_path))).unwrap();
        let mask = image::open(dir.join(format!("{}_mask.png", f.file_path)))
            .unwrap()
            .to_luma8();
        for (x, y, p) in img.enumerate_pixels() {
            let label = src.mask.get_pixel(x, y)[0];
            if label == 1 || label == 2 {
                assert_eq!(p, src.image.get_pixel(x, y));
            } else {
                assert_eq!(p[3], 0);
            }
            // The dedicated spheres' pixels are marked, the background not.
            let m = mask.get_pixel(x, y)[0];
            match label {
                0 => assert_eq!(m, 0),
                1 | 2 => assert_eq!(m, label),
                _ => assert_eq!(m, 255),
            }
        }
    }
    assert!(dir.join("transforms_test.json").is_file());
}

#[test]
fn default_alpha_gives_every_object_a_network_and_reruns_replace_outputs() {
    let cap = sphere_capture(&ring_of_five(), 4, 0, 160);
    let out = tempfile::tempdir().unwrap();
    let seg = segment(&cap, &SegmentOptions::default(), out.path()).unwrap();
    assert_eq!(seg.groups.len(), 5, "{:#?}", seg.groups);
    let lowest = seg
        .objects
        .iter()
        .min_by(|a, b| a.max_frequency.total_cmp(&b.max_frequency))
        .unwrap();
    assert_eq!(lowest.decision, Decision::Shared);
    assert_eq!(seg.alpha, lowest.max_frequency);
    assert_eq!(seg.groups[lowest.group].objects, vec![lowest.name.clone()]);
    // A second run with every object shared replaces the folders cleanly.
    let all_shared = SegmentOptions {
        alpha: Some(1e9),
        ..Default::default()
    };
    let seg2 = segment(&cap, &all_shared, out.path()).unwrap();
    assert_eq!(seg2.groups.len(), 1);
    assert_eq!(seg2.groups[0].objects.len(), 5);
    let names: Vec<String> = std::fs::read_dir(out.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(names.is_empty(), "leftover temporary files: {names:?}");
}

#[test]
fn written_folders_load_back_as_captures_with_their_masks() {
    use nerflex_sim::segment::SegCapture;
    let cap = sphere_capture(&ring_of_five(), 3, 1, 128);
    let out = tempfile::tempdir().unwrap();
    let all_shared = SegmentOptions {
        alpha: Some(1e9),
        ..Default::default()
    };
    let seg = segment(&cap, &all_shared, out.path()).unwrap();
    let back = SegCapture::load(&out.path().join(&seg.groups[0].folder)).unwrap();
    assert_eq!(back.objects.len(), 5);
    assert_eq!((back.train.len(), back.test.len()), (3, 1));
    for (a, b) in cap.train.iter().zip(&back.train) {
        assert_eq!(a.mask, b.mask);
        assert_eq!(a.camera.c2w, b.camera.c2w);
    }
    let opts = FrequencyOptions::default();
    let (a, b) = (
        analyse(&cap, &opts).unwrap(),
        analyse(&back, &opts).unwrap(),
    );
    for (x, y) in a.objects.iter().zip(&b.objects) {
        assert!((x.max_frequency - y.max_frequency).abs() < 1e-9);
    }
    // A dedicated folder is a one-object capture with its own mask.
    let seg = segment(&cap, &SegmentOptions::default(), out.path()).unwrap();
    let top = seg.groups.first().unwrap();
    let one = SegCapture::load(&out.path().join(&top.folder)).unwrap();
    assert_eq!(one.objects, top.objects);
    // Its scene.json carries the object's entry, renumbered to mask value 1.
    let info = one.scene.as_ref().unwrap();
    let src = cap.scene.as_ref().unwrap().object(&top.objects[0]).unwrap();
    assert_eq!(info.objects.len(), 1);
    assert_eq!(info.objects[0].mask_value, 1);
    assert_eq!(info.objects[0].bounds_min, src.bounds_min);
    // Its masks hold 1 (the object), 0 and the declared value 255 (where
    // the other spheres hid it).
    assert_eq!(info.other_objects_mask_value, Some(255));
    assert!(one
        .train
        .iter()
        .all(|f| f.mask.as_raw().iter().all(|&v| v <= 1 || v == 255)));
    assert!(one.train.iter().any(|f| f.mask.as_raw().contains(&255)));
    // Segmenting that folder again keeps the marks (the other objects are
    // still outside it).
    let again = tempfile::tempdir().unwrap();
    let seg2 = segment(&one, &SegmentOptions::default(), again.path()).unwrap();
    let back2 = SegCapture::load(&again.path().join(&seg2.groups[0].folder)).unwrap();
    assert_eq!(
        back2.scene.as_ref().unwrap().other_objects_mask_value,
        Some(255)
    );
    assert!(back2.train.iter().any(|f| f.mask.as_raw().contains(&255)));
}
