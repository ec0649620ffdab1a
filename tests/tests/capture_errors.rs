//! Bad captures give clear errors naming the file and the problem, never a
//! panic; the writer loses nothing already written.

use nerflex_sim::camera::{Camera, Intrinsics};
use nerflex_sim::capture::image::{self, DynamicImage, GrayImage, Luma, Rgba, RgbaImage};
use nerflex_sim::capture::{
    write_png, Capture, CaptureError, CaptureWriter, ObjectInfo, Placement, SceneInfo, Split,
};
use nerflex_sim::procedural::Vec3;
use std::path::Path;

fn cam(size: u32, az: f32) -> Camera {
    Camera::orbit(
        az,
        30.0,
        4.03,
        Vec3::ZERO,
        Intrinsics::from_fov_x(0.69, size, size),
    )
}

fn disc(size: u32) -> RgbaImage {
    RgbaImage::from_fn(size, size, |x, y| {
        let (dx, dy) = (x as f32 - size as f32 / 2.0, y as f32 - size as f32 / 2.0);
        if dx * dx + dy * dy < (size as f32 / 3.0).powi(2) {
            Rgba([200, 100, 50, 255])
        } else {
            Rgba([0, 0, 0, 0])
        }
    })
}

fn scene(n: usize) -> SceneInfo {
    SceneInfo::new(
        (0..n)
            .map(|i| ObjectInfo {
                name: format!("o{i}"),
                kind: "ball".into(),
                mask_value: (i + 1) as u8,
                placement: Placement::default(),
                bounds_min: [-1.0; 3],
                bounds_max: [1.0; 3],
                complexity_quads: None,
                texture_frequency: None,
                extra: Default::default(),
            })
            .collect(),
    )
}

/// A valid 2-train, 1-test capture with masks and a one-object scene.
fn valid(dir: &Path) {
    let w = CaptureWriter::create(dir, 0.69).unwrap();
    for (split, i) in [(Split::Train, 0), (Split::Train, 1), (Split::Test, 0)] {
        let img = disc(16);
        let mask = nerflex_sim::capture::mask_from_alpha(&img);
        w.write_frame(
            split,
            i,
            &format!("r_{i}"),
            &cam(16, 40.0 * i as f32),
            &img,
            Some(&mask),
        )
        .unwrap();
    }
    w.finish(Some(&scene(1))).unwrap();
    Capture::load(dir).unwrap();
}

fn load_err(dir: &Path) -> String {
    let e: CaptureError = Capture::load(dir).unwrap_err();
    e.to_string()
}

#[test]
fn missing_frame_file_is_named() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    std::fs::remove_file(d.path().join("train/r_1.png")).unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("r_1.png") && e.contains("missing frame") && e.contains("transforms_train.json"),
        "{e}"
    );
}

#[test]
fn bad_matrix_is_named() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    let p = d.path().join("transforms_train.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["frames"][1]["transform_matrix"][0][0] = serde_json::json!(3.0);
    std::fs::write(&p, v.to_string()).unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("transforms_train.json") && e.contains("frame 1") && e.contains("orthonormal"),
        "{e}"
    );
    std::fs::write(&p, "{\"camera_angle_x\": 0.7, \"frames\": [").unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("transforms_train.json") && e.contains("invalid transforms JSON"),
        "{e}"
    );
}

#[test]
fn image_size_mismatch_is_named() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    write_png(
        &d.path().join("test/r_0.png"),
        &DynamicImage::ImageRgba8(disc(20)),
    )
    .unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("test/r_0_mask.png") && e.contains("mask is 16×16 but its image is 20×20"),
        "{e}"
    );
    write_png(
        &d.path().join("test/r_0_mask.png"),
        &DynamicImage::ImageLuma8(GrayImage::new(20, 20)),
    )
    .unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("test/r_0.png") && e.contains("20×20") && e.contains("16×16"),
        "{e}"
    );
}

#[test]
fn missing_alpha_is_named() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    let rgb = DynamicImage::ImageRgba8(disc(16)).to_rgb8();
    write_png(
        &d.path().join("train/r_0.png"),
        &DynamicImage::ImageRgb8(rgb),
    )
    .unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("train/r_0.png") && e.contains("no alpha channel") && e.contains("Rgb8"),
        "{e}"
    );
}

#[test]
fn mask_problems_are_named() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    let mp = d.path().join("train/r_1_mask.png");
    write_png(&mp, &DynamicImage::ImageLuma8(GrayImage::new(8, 8))).unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("r_1_mask.png") && e.contains("8×8") && e.contains("16×16"),
        "{e}"
    );

    write_png(&mp, &DynamicImage::ImageRgba8(disc(16))).unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("r_1_mask.png") && e.contains("8-bit grayscale"),
        "{e}"
    );

    write_png(
        &mp,
        &DynamicImage::ImageLuma8(GrayImage::from_pixel(16, 16, Luma([3]))),
    )
    .unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("r_1_mask.png") && e.contains("mask value 3") && e.contains("has 1"),
        "{e}"
    );

    std::fs::remove_file(&mp).unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("r_1_mask.png") && e.contains("every frame has a mask or none"),
        "{e}"
    );
}

#[test]
fn scene_json_problems_are_named() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    let p = d.path().join("scene.json");
    std::fs::write(&p, "{\"format\": \"nerflex-scene/1\", \"objects\": 3}").unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("scene.json") && e.contains("invalid scene JSON"),
        "{e}"
    );
    let mut s = scene(1);
    s.objects[0].mask_value = 4;
    std::fs::write(&p, serde_json::to_string(&s).unwrap()).unwrap();
    let e = load_err(d.path());
    assert!(
        e.contains("scene.json") && e.contains("mask_value = 4"),
        "{e}"
    );
}

#[test]
fn not_a_capture_is_named() {
    let d = tempfile::tempdir().unwrap();
    let e = load_err(d.path());
    assert!(e.contains("transforms_train.json is missing"), "{e}");
    let e = load_err(&d.path().join("nope"));
    assert!(e.contains("no such folder"), "{e}");
}

#[test]
fn real_capture_without_test_split_still_loads() {
    let d = tempfile::tempdir().unwrap();
    valid(d.path());
    std::fs::remove_file(d.path().join("transforms_test.json")).unwrap();
    let c = Capture::load(d.path()).unwrap();
    assert!(c.test.is_empty() && c.train.len() == 2);
}

#[test]
fn writer_keeps_what_it_wrote_when_a_later_frame_fails() {
    let d = tempfile::tempdir().unwrap();
    let w = CaptureWriter::create(d.path(), 0.69).unwrap();
    w.write_frame(Split::Train, 0, "r_0", &cam(16, 0.0), &disc(16), None)
        .unwrap();
    // A frame of another size is refused before anything is written.
    let e = w
        .write_frame(Split::Train, 1, "r_1", &cam(20, 10.0), &disc(20), None)
        .unwrap_err();
    assert!(e.to_string().contains("all frames"), "{e}");
    assert!(!d.path().join("train/r_1.png").exists());
    // The first frame is complete on disk, and no temporary files remain.
    let img = image::open(d.path().join("train/r_0.png"))
        .unwrap()
        .into_rgba8();
    assert_eq!(img, disc(16));
    let stray: Vec<_> = std::fs::read_dir(d.path().join("train"))
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(stray.is_empty());
    // Masks beyond the scene's objects are refused at finish.
    let w = CaptureWriter::create(d.path(), 0.69).unwrap();
    w.write_frame(
        Split::Train,
        0,
        "r_0",
        &cam(16, 0.0),
        &disc(16),
        Some(&GrayImage::from_pixel(16, 16, Luma([2]))),
    )
    .unwrap();
    let e = w.finish(Some(&scene(1))).unwrap_err().to_string();
    assert!(e.contains("value 2") && e.contains("1 objects"), "{e}");
}

#[test]
fn writer_reports_an_unwritable_folder() {
    let d = tempfile::tempdir().unwrap();
    let file = d.path().join("plain-file");
    std::fs::write(&file, b"x").unwrap();
    let e = CaptureWriter::create(&file, 0.69).unwrap_err().to_string();
    assert!(
        e.contains("plain-file") && e.contains("cannot create folder"),
        "{e}"
    );
}
