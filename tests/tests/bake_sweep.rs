//! The sweep: samples CSV round trip and errors, cache reuse, ordering.

use glam::Vec3;
use image::{Rgba, RgbaImage};
use nerflex_sim::bake::sweep::{self, Cache, ObjectViews, Sample, SweepOptions, CSV_HEADER};
use nerflex_sim::bake::BakeParams;
use nerflex_sim::camera::{Camera, Intrinsics};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A capture of a flat-shaded ball (orange) at 64 px from 6 views.
fn ball(name: &str, radius: f32) -> ObjectViews {
    let k = Intrinsics::from_fov_x(0.69, 64, 64);
    let cams: Vec<Camera> = (0..8)
        .map(|i| {
            Camera::orbit(
                45.0 * i as f32,
                if i % 2 == 0 { 30.0 } else { -20.0 },
                3.5,
                Vec3::ZERO,
                k,
            )
        })
        .collect();
    let img = |c: &Camera| {
        RgbaImage::from_fn(64, 64, |x, y| {
            let (o, d) = c.ray(x as f32 + 0.5, y as f32 + 0.5);
            let b = o.dot(d);
            let disc = b * b - (o.length_squared() - radius * radius);
            if disc >= 0.0 {
                Rgba([230, 130, 40, 255])
            } else {
                Rgba([0, 0, 0, 0])
            }
        })
    };
    ObjectViews {
        name: name.into(),
        content_hash: (radius * 1000.0) as u64,
        train: cams[..6].iter().map(|c| (*c, img(c), None)).collect(),
        test: cams[6..].iter().map(|c| (*c, img(c))).collect(),
        test_hidden: Vec::new(),
        search_box: None,
    }
}

#[test]
fn csv_round_trips_and_bad_rows_name_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub/samples.csv");
    let samples = vec![
        Sample {
            object: "lego".into(),
            g: 16,
            p: 5,
            size_bytes: 1234,
            gpu_bytes: 5678,
            quads: 90,
            ssim: 0.75,
            psnr: 17.25,
            lpips: Some(0.25),
        },
        Sample {
            object: "chair".into(),
            g: 32,
            p: 9,
            size_bytes: 1,
            gpu_bytes: 2,
            quads: 3,
            ssim: 0.5,
            psnr: 10.0,
            lpips: None,
        },
    ];
    sweep::write_csv(&path, &samples).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with(CSV_HEADER));
    assert!(
        text.contains("chair,32,9,1,2,3,0.500000,10.0000,\n"),
        "{text}"
    );
    assert_eq!(sweep::read_csv(&path).unwrap(), samples);

    std::fs::write(
        &path,
        format!("{CSV_HEADER}\nlego,16,5,1,2,3,0.5,10,\nlego,x,5,1,2,3,0.5,10,\n"),
    )
    .unwrap();
    let e = format!("{:#}", sweep::read_csv(&path).unwrap_err());
    assert!(e.contains("line 3") && e.contains("bad g"), "{e}");
    std::fs::write(&path, format!("{CSV_HEADER}\nlego,16,5\n")).unwrap();
    let e = format!("{:#}", sweep::read_csv(&path).unwrap_err());
    assert!(e.contains("line 2") && e.contains("3 fields"), "{e}");
    std::fs::write(&path, "object,g\n").unwrap();
    let e = format!("{:#}", sweep::read_csv(&path).unwrap_err());
    assert!(e.contains("line 1") && e.contains("header"), "{e}");
}

#[test]
fn sweep_reuses_unchanged_results_and_rebakes_changed_ones() {
    let dir = tempfile::tempdir().unwrap();
    let objects = vec![ball("small", 0.5), ball("large", 0.7)];
    let renders = AtomicUsize::new(0);
    // A stand-in renderer (the measurement path is tested elsewhere): grey.
    let render = |_: &nerflex_sim::asset::Asset, c: &Camera| {
        renders.fetch_add(1, Ordering::Relaxed);
        Ok(RgbaImage::from_pixel(
            c.intrinsics.width,
            c.intrinsics.height,
            Rgba([128, 128, 128, 255]),
        ))
    };
    let opts = SweepOptions {
        configs: sweep::product(&[8, 12], &[3, 5]),
        base: BakeParams::new(0, 0),
        jobs: 2,
        cache: Some(Cache::new(dir.path().join("cache"))),
        lpips: None,
        progress: false,
        trained: None,
    };
    let first = sweep::run(&objects, &opts, &render).unwrap();
    assert_eq!((first.baked, first.reused, first.samples.len()), (8, 0, 8));
    assert_eq!(renders.load(Ordering::Relaxed), 8 * 2);
    // Ordered by object as given, then g, then p.
    let order: Vec<(String, u32, u32)> = first
        .samples
        .iter()
        .map(|s| (s.object.clone(), s.g, s.p))
        .collect();
    assert_eq!(order[0], ("small".into(), 8, 3));
    assert_eq!(order[3], ("small".into(), 12, 5));
    assert_eq!(order[4], ("large".into(), 8, 3));
    for s in &first.samples {
        assert!(s.quads > 0 && s.size_bytes > 0 && s.gpu_bytes > 0 && s.lpips.is_none());
    }
    // Everything cached: nothing baked, same numbers.
    let again = sweep::run(&objects, &opts, &render).unwrap();
    assert_eq!((again.baked, again.reused), (0, 8));
    assert_eq!(again.samples, first.samples);
    assert_eq!(renders.load(Ordering::Relaxed), 8 * 2);
    // A changed capture (content hash) is baked again; the other is reused.
    let mut changed = vec![ball("small", 0.5), ball("large", 0.7)];
    changed[1].content_hash ^= 1;
    let third = sweep::run(&changed, &opts, &render).unwrap();
    assert_eq!((third.baked, third.reused), (4, 4));
    // So is a changed bake setting.
    let mut opts2 = SweepOptions {
        base: BakeParams::new(0, 0),
        ..opts
    };
    opts2.base.frontal_power = 2.0;
    let fourth = sweep::run(&objects, &opts2, &render).unwrap();
    assert_eq!((fourth.baked, fourth.reused), (8, 0));
    // Size grows with g and with p.
    let get = |g, p| {
        first
            .samples
            .iter()
            .find(|s| s.object == "large" && s.g == g && s.p == p)
            .unwrap()
            .clone()
    };
    assert!(get(12, 3).quads > get(8, 3).quads);
    assert!(get(8, 5).gpu_bytes > get(8, 3).gpu_bytes);
}

#[test]
fn sweep_rejects_duplicate_and_unwritable_names() {
    let opts = SweepOptions {
        configs: vec![(8, 3)],
        base: BakeParams::new(0, 0),
        jobs: 1,
        cache: None,
        lpips: None,
        progress: false,
        trained: None,
    };
    let render = |_: &nerflex_sim::asset::Asset, _: &Camera| Ok(RgbaImage::new(64, 64));
    let e = sweep::run(&[ball("a", 0.5), ball("a", 0.6)], &opts, &render)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`a` is given twice"), "{e}");
    let e = sweep::run(&[ball("a,b", 0.5)], &opts, &render)
        .unwrap_err()
        .to_string();
    assert!(e.contains("CSV"), "{e}");
}

/// A sample of object "x" whose file and GPU bytes are both `bytes`.
fn sample(g: u32, p: u32, bytes: u64, ssim: f64) -> Sample {
    Sample {
        object: "x".into(),
        g,
        p,
        size_bytes: bytes,
        gpu_bytes: bytes,
        quads: 1,
        ssim,
        psnr: 0.0,
        lpips: None,
    }
}

#[test]
fn monotonicity_report_names_the_breaks() {
    let s = sample;
    let samples = vec![
        s(16, 5, 100, 0.70),
        s(16, 9, 200, 0.72),
        s(32, 5, 300, 0.69),
        s(32, 9, 250, 0.75),
    ];
    let r = sweep::monotonicity_report(&samples, 0.005);
    assert_eq!(r.len(), 2, "{r:?}");
    assert!(
        r[0].contains("x (16, 5) → (32, 5): SSIM falls with g"),
        "{r:?}"
    );
    assert!(
        r[1].contains("x (32, 5) → (32, 9): size does not grow with p"),
        "{r:?}"
    );
    assert!(sweep::monotonicity_report(&samples[..2], 0.0).is_empty());
}

#[test]
fn monotonicity_summary_counts_pairs_and_the_largest_drop() {
    let s = sample;
    let samples = vec![
        s(16, 5, 100, 0.70),
        s(16, 9, 200, 0.72),
        s(32, 5, 300, 0.69),
        s(32, 9, 250, 0.7195),
    ];
    let m = sweep::monotonicity_summary(&samples);
    // Along g: (16,5)→(32,5) falls by 0.01, (16,9)→(32,9) falls by 0.0005.
    assert_eq!((m.g.pairs, m.g.size_grows), (2, 2));
    assert_eq!((m.g.ssim_falls, m.g.ssim_falls_over_1e3), (2, 1));
    assert!((m.g.max_ssim_drop - 0.01).abs() < 1e-12, "{m:?}");
    assert_eq!(m.g.max_drop_at.as_deref(), Some("x (16, 5) → (32, 5)"));
    // Along p: (16,5)→(16,9) rises; (32,5)→(32,9) rises but shrinks.
    assert_eq!((m.p.pairs, m.p.size_grows, m.p.ssim_falls), (2, 1, 0));
    assert_eq!(m.p.max_drop_at, None);
}

#[test]
fn markdown_table_lists_the_chosen_configurations() {
    let s = |o: &str, g, p, ssim| Sample {
        object: o.into(),
        g,
        p,
        size_bytes: 2_500_000,
        gpu_bytes: 1_000_000,
        quads: 42,
        ssim,
        psnr: 20.0,
        lpips: Some(0.25),
    };
    let samples = vec![
        s("a", 16, 5, 0.7),
        s("a", 128, 17, 0.8),
        s("b", 16, 5, 0.6),
        s("a", 32, 5, 0.75),
    ];
    let t = sweep::markdown_table(&samples, &[(16, 5), (128, 17)]);
    let lines: Vec<&str> = t.lines().collect();
    assert_eq!(lines.len(), 2 + 3, "{t}");
    assert!(lines[0].starts_with("| object | g | p | quads"), "{t}");
    assert_eq!(
        lines[3],
        "| a | 128 | 17 | 42 | 2.50 | 1.00 | 0.8000 | 20.00 | 0.2500 |"
    );
    assert!(lines[4].starts_with("| b | 16 | 5 |"), "{t}");
}

/// What another object hides in a held-out view is not scored: a wrong
/// render there costs nothing once the pixels are marked, and the mark
/// changes nothing where the render is right.
#[test]
fn hidden_pixels_of_a_held_out_view_are_not_scored() {
    use nerflex_sim::bake::bake;
    let mut obj = ball("ball", 0.8);
    let asset = bake(&obj.bake_views(), &BakeParams::new(12, 3))
        .unwrap()
        .into_asset()
        .unwrap();
    let plain = obj
        .measure(&asset, &sweep::fixed_point_render, None, false)
        .unwrap();
    // An "occluder" over the left third of the first held-out view: the
    // ground truth there is blank, as a segmentation's folder writes it.
    let (w, h) = obj.test[0].1.dimensions();
    let hidden = image::GrayImage::from_fn(w, h, |x, _| image::Luma([u8::from(x < w / 3)]));
    for (x, _, p) in obj.test[0].1.enumerate_pixels_mut() {
        if x < w / 3 {
            *p = Rgba([0, 0, 0, 0]);
        }
    }
    let unmarked = obj
        .measure(&asset, &sweep::fixed_point_render, None, false)
        .unwrap();
    obj.test_hidden = vec![Some(hidden), None];
    let marked = obj
        .measure(&asset, &sweep::fixed_point_render, None, false)
        .unwrap();
    assert!(unmarked.views[0].psnr < plain.views[0].psnr - 1.0);
    assert!(marked.views[0].psnr > unmarked.views[0].psnr + 1.0);
    // The second view is untouched either way.
    assert_eq!(
        marked.views[1].ssim.to_bits(),
        plain.views[1].ssim.to_bits()
    );
    // hide_unknown copies the truth exactly where marked, nowhere else.
    let mut r = image::RgbaImage::from_pixel(4, 1, Rgba([9, 9, 9, 255]));
    let t = image::RgbaImage::from_pixel(4, 1, Rgba([1, 2, 3, 4]));
    let m = image::GrayImage::from_raw(4, 1, vec![0, 1, 0, 7]).unwrap();
    sweep::hide_unknown(&mut r, &t, Some(&m));
    let px: Vec<[u8; 4]> = r.pixels().map(|p| p.0).collect();
    assert_eq!(
        px,
        vec![[9, 9, 9, 255], [1, 2, 3, 4], [9, 9, 9, 255], [1, 2, 3, 4]]
    );
}

/// A stored lattice choice is decided again from its stored scores when
/// read: one stored before the tie rule (the coarser by 0.0003, gear's
/// case) comes back as the finer; a clear win (ball's) stays.
#[test]
fn stored_lattice_choices_follow_the_tie_rule() {
    use nerflex_sim::bake::sweep::LatticeChosen;
    let dir = tempfile::tempdir().unwrap();
    let cache = Cache::new(dir.path());
    let cases = [
        (
            "gear",
            119,
            [(238, 0.9487), (119, 0.9490), (60, 0.9432)],
            238,
        ),
        ("ball", 54, [(215, 0.9699), (108, 0.9746), (54, 0.9776)], 54),
    ];
    for (object, stored, scores, read) in cases {
        let chosen = LatticeChosen {
            object: object.into(),
            cells: stored,
            candidates: scores.iter().map(|&(k, s)| (k, s, 30.0)).collect(),
            reused: false,
            stored_cells: None,
        };
        cache.put_lattice(object, &chosen).unwrap();
        let got = cache.get_lattice(object).unwrap();
        assert_eq!(got.cells, read, "{object}");
        // What bakes made under the stored choice used, when it differs.
        assert_eq!(
            got.stored_cells,
            (read != stored).then_some(stored),
            "{object}"
        );
    }
    assert!(cache.get_lattice("absent").is_none());
}
