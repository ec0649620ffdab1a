//! Built-in captures: cameras on the upper hemisphere, rendered in parallel
//! and written in the NeRF-synthetic layout through [`CaptureWriter`].

use super::layout::{scene_info, PlacedObject, Preset, CAMERA_ANGLE_X, CAMERA_DISTANCE};
use super::render::{RenderOptions, SceneRenderer};
use crate::camera::{Camera, Intrinsics};
use crate::capture::{CaptureError, CaptureWriter, SceneInfo, Split};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Lowest camera elevation, degrees above the xy plane.
pub const MIN_ELEVATION_DEG: f32 = 10.0;
/// Highest camera elevation, degrees.
pub const MAX_ELEVATION_DEG: f32 = 80.0;

/// What to generate.
#[derive(Debug, Clone)]
pub struct CaptureSpec {
    /// The placed objects (mask value = index + 1).
    pub objects: Vec<PlacedObject>,
    /// Layout name recorded in `scene.json`.
    pub layout: String,
    /// The preset, if any.
    pub preset: Option<Preset>,
    /// Seed of the layout and the cameras.
    pub seed: u64,
    /// Training views.
    pub train_views: usize,
    /// Held-out views.
    pub test_views: usize,
    /// Image width and height, pixels (square, like NeRF-synthetic).
    pub size: u32,
    /// Renderer quality.
    pub render: RenderOptions,
}

/// What was generated.
#[derive(Debug, Clone)]
pub struct CaptureReport {
    /// The capture folder.
    pub dir: PathBuf,
    /// Its `scene.json`.
    pub scene: SceneInfo,
    /// Views rendered (train + test).
    pub views: usize,
    /// Wall-clock seconds spent rendering and writing the views.
    pub seconds: f64,
}

/// `count` cameras at NeRF-synthetic distance looking at the origin, spread
/// evenly over the band of the upper hemisphere between
/// [`MIN_ELEVATION_DEG`] and [`MAX_ELEVATION_DEG`]: heights uniform in
/// area, azimuths a golden-angle spiral with a seeded start. Train and test
/// use different starts and half-step offsets, so no test view repeats a
/// training view.
pub fn view_cameras(count: usize, seed: u64, split: Split, size: u32) -> Vec<Camera> {
    let k = Intrinsics::from_fov_x(CAMERA_ANGLE_X as f32, size, size);
    let salt = match split {
        Split::Train => 0x7a11,
        Split::Test => 0x7e57,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ salt);
    let start: f32 = rng.random_range(0.0..360.0);
    let offset = match split {
        Split::Train => 0.5,
        Split::Test => 0.25,
    };
    let (z0, z1) = (
        MIN_ELEVATION_DEG.to_radians().sin(),
        MAX_ELEVATION_DEG.to_radians().sin(),
    );
    let golden = 180.0 * (3.0 - 5f32.sqrt());
    (0..count)
        .map(|i| {
            let u = (i as f32 + offset) / count as f32;
            let el = (z0 + u * (z1 - z0)).asin().to_degrees();
            let az = start + golden * i as f32;
            Camera::orbit(az, el, CAMERA_DISTANCE, Vec3::ZERO, k)
        })
        .collect()
}

/// Renders every view of `spec` in parallel and writes the capture to `out`
/// (PNG frames and masks as they finish, then the transforms and
/// `scene.json`). `on_view` is called once per finished view (from any
/// thread), e.g. to advance a progress bar.
pub fn make_capture(
    spec: &CaptureSpec,
    out: &Path,
    on_view: &(dyn Fn() + Sync),
) -> Result<CaptureReport, CaptureError> {
    let invalid = |what: String| CaptureError::Invalid {
        path: out.to_path_buf(),
        what,
    };
    if spec.objects.is_empty() || spec.objects.len() > 255 {
        return Err(invalid(format!(
            "{} objects; a scene holds 1 to 255",
            spec.objects.len()
        )));
    }
    if spec.train_views == 0 {
        return Err(invalid("no training views requested".into()));
    }
    if !(8..=8192).contains(&spec.size) {
        return Err(invalid(format!(
            "image size {} is outside 8..=8192 pixels",
            spec.size
        )));
    }
    let start = Instant::now();
    let scene = scene_info(&spec.objects, &spec.layout, spec.seed, spec.preset);
    let renderer = SceneRenderer::new(&spec.objects);
    let writer = CaptureWriter::create(out, CAMERA_ANGLE_X)?;
    let mut jobs: Vec<(Split, usize, Camera)> = Vec::new();
    for split in [Split::Train, Split::Test] {
        let n = match split {
            Split::Train => spec.train_views,
            Split::Test => spec.test_views,
        };
        for (i, c) in view_cameras(n, spec.seed, split, spec.size)
            .into_iter()
            .enumerate()
        {
            jobs.push((split, i, c));
        }
    }
    jobs.par_iter().try_for_each(|(split, i, cam)| {
        let view = renderer.render(cam, &spec.render);
        writer.write_frame(
            *split,
            *i,
            &format!("r_{i}"),
            cam,
            &view.image,
            Some(&view.mask),
        )?;
        on_view();
        Ok::<(), CaptureError>(())
    })?;
    let dir = writer.finish(Some(&scene))?;
    Ok(CaptureReport {
        dir,
        scene,
        views: jobs.len(),
        seconds: start.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_sit_on_the_upper_hemisphere_and_look_at_the_origin() {
        let train = view_cameras(20, 1, Split::Train, 100);
        let test = view_cameras(5, 1, Split::Test, 100);
        for c in train.iter().chain(&test) {
            let p = c.position();
            assert!((p.length() - CAMERA_DISTANCE).abs() < 1e-3);
            let el = (p.z / p.length()).asin().to_degrees();
            assert!(
                (MIN_ELEVATION_DEG - 0.01..=MAX_ELEVATION_DEG + 0.01).contains(&el),
                "{el}"
            );
            let (x, y, _) = c.project(Vec3::ZERO).unwrap();
            assert!((x - 50.0).abs() < 1e-3 && (y - 50.0).abs() < 1e-3);
        }
        for a in &test {
            for b in &train {
                assert!((a.position() - b.position()).length() > 0.05);
            }
        }
    }
}
