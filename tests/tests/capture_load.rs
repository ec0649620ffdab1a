//! One loader for built-in and real NeRF-synthetic captures: a small
//! generated scene and the real `lego` / `chair` folders go through the same
//! `Capture::load` and come out with the same structure.

use nerflex_sim::capture::{mask_from_alpha, Capture, Frame};
use nerflex_sim::procedural::{
    arrange, make_capture, CaptureSpec, Layout, Preset, RenderOptions, Vec3,
};

/// Three 64×64 training views and two test views of Scene 4.
fn small_scene4(dir: &std::path::Path) -> Capture {
    let kinds = Preset::Scene4.kinds();
    let spec = CaptureSpec {
        objects: arrange(&kinds, Layout::Ring, 0, 1.0),
        layout: "ring".into(),
        preset: Some(Preset::Scene4),
        seed: 0,
        train_views: 3,
        test_views: 2,
        size: 64,
        render: RenderOptions::default(),
    };
    let report = make_capture(&spec, dir, &|| {}).unwrap();
    assert_eq!(report.views, 5);
    Capture::load(dir).unwrap()
}

/// What every capture must satisfy, built-in or real.
fn check_common(c: &Capture, size: (u32, u32)) {
    assert!(!c.train.is_empty() && !c.test.is_empty());
    assert_eq!(c.size(), size);
    assert!(
        (c.camera_angle_x - 0.6911).abs() < 1e-3,
        "NeRF-synthetic field of view"
    );
    for f in c.frames() {
        assert_eq!(f.image.dimensions(), size);
        let k = f.camera.intrinsics;
        assert_eq!((k.width, k.height), size);
        // Cameras about 4 units out on the upper hemisphere, looking at the object.
        let p = f.camera.position();
        assert!((p.length() - 4.03).abs() < 0.1, "{}", f.file_path);
        assert!(p.z > 0.0, "{}", f.file_path);
        let (x, y, _) = f.camera.project(Vec3::ZERO).unwrap();
        assert!(
            (x - size.0 as f32 / 2.0).abs() < size.0 as f32 * 0.06
                && (y - size.1 as f32 / 2.0).abs() < size.1 as f32 * 0.06
        );
        // A visible object, a transparent background.
        let covered = f.image.pixels().filter(|p| p.0[3] > 0).count();
        let total = (size.0 * size.1) as usize;
        assert!(
            covered > total / 50 && covered < total * 9 / 10,
            "{}: {covered} of {total}",
            f.file_path
        );
        assert_eq!(f.image.get_pixel(0, 0).0[3], 0);
        // The instance mask is nonzero exactly where alpha is.
        let m = f.instance_mask();
        for (px, mv) in f.image.pixels().zip(m.pixels()) {
            assert_eq!(px.0[3] > 0, mv.0[0] > 0, "{}", f.file_path);
        }
    }
}

#[test]
fn built_in_scene_loads_with_masks_and_scene_info() {
    let dir = tempfile::tempdir().unwrap();
    let c = small_scene4(dir.path());
    check_common(&c, (64, 64));
    assert_eq!((c.train.len(), c.test.len()), (3, 2));
    assert!(c.has_masks());
    assert_eq!(c.train[1].file_path, "./train/r_1");
    assert!(dir.path().join("train/r_1_mask.png").is_file());
    let scene = c.scene.as_ref().unwrap();
    assert_eq!(scene.objects.len(), 5);
    assert_eq!(c.object_count(), 5);
    let names: Vec<String> = Preset::Scene4
        .kinds()
        .iter()
        .map(|k| k.name().to_string())
        .collect();
    assert_eq!(
        scene
            .objects
            .iter()
            .map(|o| o.name.clone())
            .collect::<Vec<_>>(),
        names
    );
    // Every object is seen whole in every view: its mask is not empty and
    // never touches the image border, and it lies inside the projection of
    // its world bounds recorded in scene.json.
    for f in c.frames() {
        let m = f.mask.as_ref().unwrap();
        for (i, o) in scene.objects.iter().enumerate() {
            let v = (i + 1) as u8;
            assert_eq!(o.mask_value, v);
            let pixels: Vec<(u32, u32)> = m
                .enumerate_pixels()
                .filter(|p| p.2 .0[0] == v)
                .map(|p| (p.0, p.1))
                .collect();
            assert!(
                !pixels.is_empty(),
                "{} not visible in {}",
                o.name,
                f.file_path
            );
            let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
            for ix in 0..8 {
                let pick = |a: usize| if ix >> a & 1 == 0 { o.bounds_min[a] } else { o.bounds_max[a] } as f32;
                let (x, y, _) = f
                    .camera
                    .project(Vec3::new(pick(0), pick(1), pick(2)))
                    .unwrap();
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            }
            for &(x, y) in &pixels {
                assert!(
                    x > 0 && y > 0 && x < 63 && y < 63,
                    "{} touches the border of {}",
                    o.name,
                    f.file_path
                );
                assert!(
                    x as f32 + 1.0 >= x0
                        && x as f32 <= x1 + 1.0
                        && y as f32 + 1.0 >= y0
                        && y as f32 <= y1 + 1.0,
                    "{} pixel ({x}, {y}) outside its bounds' projection in {}",
                    o.name,
                    f.file_path
                );
            }
            assert_eq!(
                f.object_mask(v).pixels().filter(|p| p.0[0] == 255).count(),
                pixels.len()
            );
        }
    }
}

#[test]
fn generation_is_deterministic() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (ca, cb) = (small_scene4(a.path()), small_scene4(b.path()));
    for (fa, fb) in ca.frames().zip(cb.frames()) {
        assert_eq!(fa.image, fb.image);
        assert_eq!(fa.mask, fb.mask);
        assert_eq!(fa.camera, fb.camera);
    }
    assert_eq!(ca.scene, cb.scene);
}

fn check_real(name: &str, first_train: &str) {
    let Some(data) = nerflex_sim::data::require_data(&format!("nerf_synthetic/{name}")) else {
        return;
    };
    let c = Capture::load(data.join("nerf_synthetic").join(name)).unwrap();
    check_common(&c, (800, 800));
    assert_eq!((c.train.len(), c.test.len()), (20, 5));
    assert_eq!(c.train[0].file_path, first_train);
    assert!(!c.has_masks() && c.scene.is_none());
    assert_eq!(c.object_count(), 1);
    let f: &Frame = &c.train[0];
    assert_eq!(*f.instance_mask(), mask_from_alpha(&f.image));
    assert!(f.instance_mask().pixels().all(|p| p.0[0] <= 1));
}

#[test]
fn real_lego_loads_through_the_same_loader() {
    check_real("lego", "./train/r_0");
}

#[test]
fn real_chair_loads_through_the_same_loader() {
    check_real("chair", "./train/r_0");
}
