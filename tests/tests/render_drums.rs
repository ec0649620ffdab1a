//! The renderer on the real drums shape: fixed vs float, host vs the
//! core's tile-by-tile `DrawTarget` path, coverage pass, dataset cameras.

use nerflex_core::raster::{glam, render_frame, TileRenderer};
use nerflex_sim::asset::image::RgbaImage;
use nerflex_sim::asset::Asset;
use nerflex_sim::camera::{Camera, Intrinsics, Transforms};
use nerflex_sim::render::{coverage, render, view_of, RenderOptions};
use nerflex_tests::Fb;
use std::sync::OnceLock;

/// PSNR (dB) of the RGB channels of two equal-size images (local helper:
/// the metrics module is separate work).
fn psnr(a: &RgbaImage, b: &RgbaImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut se = 0f64;
    for (p, q) in a.pixels().zip(b.pixels()) {
        for k in 0..3 {
            let d = p.0[k] as f64 - q.0[k] as f64;
            se += d * d;
        }
    }
    let mse = se / (a.width() as f64 * a.height() as f64 * 3.0);
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

fn drums() -> Option<&'static Asset> {
    static A: OnceLock<Option<Asset>> = OnceLock::new();
    A.get_or_init(|| {
        let data = nerflex_sim::data::require_data("drums render")?;
        Some(Asset::load(&data.join("mobilenerf/drums")).unwrap())
    })
    .as_ref()
}

/// The `nerflex render` default orbit camera (fov 39.6°, distance 4.031).
/// One sample per pixel: what the microcontroller's tile path renders, and
/// where coverage is binary.
const ONE_SAMPLE: RenderOptions = RenderOptions {
    float: false,
    supersample: false,
};

fn orbit(angle: f32, elevation: f32, size: u32) -> Camera {
    let k = Intrinsics::from_fov_x(39.6f32.to_radians(), size, size);
    Camera::orbit(angle, elevation, 4.031, glam::Vec3::ZERO, k)
}

#[test]
fn drums_at_30_degrees_fixed_and_float_agree_above_45_db() {
    let Some(a) = drums() else { return };
    let cam = orbit(30.0, 30.0, 800);
    let (fixed, s) = render(a, &cam, &ONE_SAMPLE);
    let (float, sf) = render(
        a,
        &cam,
        &RenderOptions {
            float: true,
            ..ONE_SAMPLE
        },
    );
    let p = psnr(&fixed, &float);
    let differing = fixed
        .pixels()
        .zip(float.pixels())
        .filter(|(x, y)| x != y)
        .count();
    println!(
        "drums 800×800 at 30°: quads drawn {} of {} ({} visible), pixels shaded {}, fixed {:?} / f32 {:?}; \
         PSNR fixed vs f32 {p:.1} dB ({differing} pixels differ)",
        s.quads_drawn, s.quads_total, s.quads_visible, s.pixels_shaded, s.time, sf.time
    );
    assert!(p >= 45.0, "PSNR {p}");
    assert_eq!(
        (s.quads_drawn, s.pixels_shaded),
        (sf.quads_drawn, sf.pixels_shaded)
    );
    // Coverage is alpha; uncovered pixels are white.
    let covered = fixed.pixels().filter(|p| p.0[3] == 255).count() as u64;
    assert_eq!(covered, s.pixels_shaded);
    assert!(fixed
        .pixels()
        .filter(|p| p.0[3] == 0)
        .all(|p| p.0 == [255, 255, 255, 0]));
    assert!(s.pixels_shaded > 5_000, "{s:?}");
    assert!(
        s.quads_visible > 1_000
            && s.quads_visible <= s.quads_drawn
            && s.quads_drawn <= s.quads_total
    );
    assert_eq!(s.quads_total, 6_278);
    // The part is not a white or black blob: its colours vary.
    let lum: Vec<f64> = fixed
        .pixels()
        .filter(|p| p.0[3] == 255)
        .map(|p| (p.0[0] as f64 + p.0[1] as f64 + p.0[2] as f64) / 3.0)
        .collect();
    let mean = lum.iter().sum::<f64>() / lum.len() as f64;
    let sd = (lum.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / lum.len() as f64).sqrt();
    assert!(
        sd > 20.0 && mean > 30.0 && mean < 225.0,
        "mean {mean} sd {sd}"
    );
    // A close-up (≈ 6× more pixels shaded): still ≥ 45 dB.
    let k = Intrinsics::from_fov_x(39.6f32.to_radians(), 800, 800);
    let close = Camera::orbit(90.0, 45.0, 1.8, glam::Vec3::new(0.0, 0.0, -0.5), k);
    let (fixed, s) = render(a, &close, &RenderOptions::default());
    let (float, _) = render(
        a,
        &close,
        &RenderOptions {
            float: true,
            ..Default::default()
        },
    );
    let p = psnr(&fixed, &float);
    let differing = fixed
        .pixels()
        .zip(float.pixels())
        .filter(|(x, y)| x != y)
        .count();
    println!(
        "close-up 800×800: pixels shaded {}, PSNR fixed vs f32 {p:.1} dB ({differing} pixels differ)",
        s.pixels_shaded
    );
    assert!(p >= 45.0, "PSNR {p}");
}

#[test]
fn host_renderer_equals_the_microcontroller_tile_path_and_coverage_pass() {
    let Some(a) = drums() else { return };
    let cam = orbit(200.0, 15.0, 320);
    let (host, s) = render(a, &cam, &ONE_SAMPLE);
    let view = view_of(&cam).unwrap();
    let parts = nerflex_tests::core_parts(a);
    let mut fb = Fb(RgbaImage::new(320, 320));
    // A 16 × 8 tile: 2 KiB of G-buffer, microcontroller-sized.
    let mut tile = Box::new(TileRenderer::<16, 8>::new());
    let fs = render_frame(&mut tile, &view, &parts, &mut fb).unwrap();
    for (h, d) in host.pixels().zip(fb.0.pixels()) {
        assert_eq!(h.0[..3], d.0[..3]);
    }
    assert_eq!(u64::from(fs.pixels_shaded), s.pixels_shaded);
    assert_eq!(fs.quads_drawn, s.quads_drawn);
    let c = coverage(a, &cam).unwrap();
    assert_eq!(
        (c.pixels_covered, c.quads_drawn, c.quads_visible),
        (s.pixels_shaded, s.quads_drawn, s.quads_visible)
    );
    let mut bits = vec![0u32; (c.quads_total as usize).div_ceil(32)];
    let cc = nerflex_core::raster::coverage(&mut tile, &view, &parts, &mut bits).unwrap();
    assert_eq!(
        (u64::from(cc.pixels_covered), cc.quads_visible),
        (c.pixels_covered, c.quads_visible)
    );
}

#[test]
fn dataset_camera_sees_the_part_below_the_centre_of_the_frame() {
    let Some(a) = drums() else { return };
    let data = nerflex_sim::data::shared_data_dir().unwrap();
    let t = Transforms::read(&data.join("nerf_synthetic/lego/transforms_train.json")).unwrap();
    for frame in [0, 5, 10] {
        let cam = t.camera(frame, 400, 400).unwrap();
        assert!(
            cam.position().z > 0.0,
            "NeRF-synthetic cameras look from above"
        );
        let (img, s) = render(a, &cam, &RenderOptions::default());
        let (mut x0, mut x1, mut y0, mut y1) = (u32::MAX, 0, u32::MAX, 0);
        for (x, y, p) in img.enumerate_pixels() {
            if p.0[3] == 255 {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        println!(
            "frame {frame}: {} pixels, box x {x0}..{x1} y {y0}..{y1}",
            s.pixels_shaded
        );
        // The floor-level part (world z ≈ −0.5) of an object centred at the
        // origin: centred left-right, in the lower half, inside the frame.
        assert!(s.pixels_shaded > 500);
        assert!(x0 < 170 && x1 > 230, "spans the centre column");
        assert!(y0 > 150 && y1 < 400, "below the centre");
    }
}

#[test]
fn close_or_broken_cameras_do_not_panic() {
    let Some(a) = drums() else { return };
    // Inside the object: triangles behind the camera plane are skipped.
    let k = Intrinsics::from_fov_x(1.2, 96, 64);
    let cam = Camera::look_at(
        glam::Vec3::new(0.0, 0.0, -0.48),
        glam::Vec3::new(1.0, 0.2, -0.5),
        glam::Vec3::Z,
        k,
    );
    let (img, s) = render(a, &cam, &RenderOptions::default());
    assert_eq!(img.dimensions(), (96, 64));
    assert!(s.camera_error.is_none());
    assert!(s.tiles.triangles_clipped > 0 || s.quads_drawn < s.quads_total);
    // A zero-sized image is rejected, not a panic.
    let mut bad = orbit(0.0, 30.0, 64);
    bad.intrinsics.width = 0;
    let (_, s) = render(a, &bad, &RenderOptions::default());
    assert!(s.camera_error.is_some());
}
