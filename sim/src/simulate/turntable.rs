//! The turntable: a fixed camera and the scene turning about the world z
//! axis (equivalently, the camera orbiting at a fixed distance and
//! elevation), and the work each angle gives the renderer.
//!
//! Coverage is measured at `angles` evenly spaced angles for every load
//! stage actually reached (stage k: the first k objects are loaded) and
//! linearly interpolated in between. Stages are measured lazily: a scene
//! that loads in a fraction of a revolution only measures the few angles
//! its loading frames visit.

use crate::camera::{Camera, Intrinsics};
use crate::device::{FrameWork, Viewer};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::cell::RefCell;
use std::collections::HashMap;

/// Where the camera sits and what it sees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TurntableSpec {
    /// Distance from the target, world units.
    pub distance: f32,
    /// Elevation above the xy plane, degrees.
    pub elevation_deg: f32,
    /// Horizontal field of view, radians.
    pub fov_x_rad: f32,
    /// The point the camera looks at (the turntable's axis passes through it).
    pub target: [f32; 3],
    /// Angles measured per revolution.
    pub angles: usize,
    /// Width of the coverage render, pixels (its height follows the viewer's aspect).
    pub coverage_width: u32,
}

impl TurntableSpec {
    /// The NeRF-synthetic test orbit: distance 4.031, elevation 30°, field
    /// of view 0.6911 rad, looking at the origin; 48 angles (7.5° apart),
    /// coverage at 160 pixels wide.
    pub const DEFAULT: TurntableSpec = TurntableSpec {
        distance: 4.031_129,
        elevation_deg: 30.0,
        fov_x_rad: 0.691_111_2,
        target: [0.0, 0.0, 0.0],
        angles: 48,
        coverage_width: 160,
    };

    /// The coverage render's size for a viewer: `coverage_width` wide, the
    /// viewer's aspect ratio (at least 1 × 1).
    pub fn coverage_size(&self, viewer: Viewer) -> (u32, u32) {
        let w = self.coverage_width.max(1);
        let h = (f64::from(w) * f64::from(viewer.height_px) / f64::from(viewer.width_px.max(1)))
            .round()
            .max(1.0) as u32;
        (w, h)
    }

    /// The camera at angle index `i` (of `angles`), at the coverage size.
    pub fn camera(&self, i: usize, viewer: Viewer) -> Camera {
        let (w, h) = self.coverage_size(viewer);
        let az = 360.0 * i as f32 / self.angles.max(1) as f32;
        Camera::orbit(
            az,
            self.elevation_deg,
            self.distance,
            Vec3::from(self.target),
            Intrinsics::from_fov_x(self.fov_x_rad, w, h),
        )
    }
}

impl Default for TurntableSpec {
    fn default() -> Self {
        TurntableSpec::DEFAULT
    }
}

/// What one view of the loaded objects costs, at the coverage resolution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ViewCoverage {
    /// Quads with a corner in front of the camera and inside the image: what
    /// the GPU sets up and rasterises (independent of the resolution).
    pub quads_in_view: u64,
    /// Quads whose triangles cover at least one pixel centre at the
    /// coverage resolution (resolution-dependent; reported, not costed).
    pub quads_drawn: u64,
    /// Distinct quads owning at least one final pixel.
    pub quads_visible: u64,
    /// Covered pixels (each shaded once by a deferred renderer).
    pub pixels_covered: u64,
}

/// Something that can rasterize the first `loaded` objects of a scene from a
/// camera and count coverage (the host renderer's coverage pass for baked
/// assets; tests use synthetic sources).
pub trait CoverageSource {
    /// How many objects the scene has (load stages are `0..=objects()`).
    fn objects(&self) -> usize;
    /// Coverage of the first `loaded` objects seen by `camera`.
    fn coverage(&self, loaded: usize, camera: &Camera) -> anyhow::Result<ViewCoverage>;
}

/// The per-angle work of a scene on one device's viewer, measured on demand.
pub struct Turntable<'a> {
    spec: TurntableSpec,
    viewer: Viewer,
    source: &'a dyn CoverageSource,
    measured: RefCell<HashMap<(usize, usize), ViewCoverage>>,
}

impl<'a> Turntable<'a> {
    /// A turntable over `source` for a viewer of the given size.
    pub fn new(spec: TurntableSpec, viewer: Viewer, source: &'a dyn CoverageSource) -> Self {
        Self {
            spec,
            viewer,
            source,
            measured: RefCell::new(HashMap::new()),
        }
    }

    /// The spec.
    pub fn spec(&self) -> &TurntableSpec {
        &self.spec
    }

    /// Objects in the scene.
    pub fn objects(&self) -> usize {
        self.source.objects()
    }

    /// Coverage of load stage `loaded` at angle index `i` (measured once).
    pub fn coverage_at(&self, loaded: usize, i: usize) -> anyhow::Result<ViewCoverage> {
        let n = self.spec.angles.max(1);
        let key = (loaded.min(self.objects()), i % n);
        if let Some(c) = self.measured.borrow().get(&key) {
            return Ok(*c);
        }
        let c = if key.0 == 0 {
            ViewCoverage::default()
        } else {
            self.source
                .coverage(key.0, &self.spec.camera(key.1, self.viewer))?
        };
        self.measured.borrow_mut().insert(key, c);
        Ok(c)
    }

    /// Measures every angle of load stage `loaded` at once (in parallel when
    /// the source is; here sequentially) — used for the fully loaded scene.
    pub fn measure_stage(&self, loaded: usize) -> anyhow::Result<Vec<ViewCoverage>> {
        (0..self.spec.angles.max(1))
            .map(|i| self.coverage_at(loaded, i))
            .collect()
    }

    /// How many coverage passes have been run.
    pub fn passes(&self) -> usize {
        self.measured.borrow().len()
    }

    /// The work of a frame at turntable angle `angle_rev` (in revolutions;
    /// any real number) with `loaded` objects, at the viewer's resolution:
    /// coverage interpolated linearly between the two nearest measured
    /// angles, pixels scaled by the ratio of viewer to coverage pixels.
    pub fn work(&self, loaded: usize, angle_rev: f64) -> anyhow::Result<(FrameWork, f64)> {
        let n = self.spec.angles.max(1);
        let pos = angle_rev.rem_euclid(1.0) * n as f64;
        let pos = if pos.is_finite() { pos } else { 0.0 };
        let i0 = (pos.floor() as usize) % n;
        let i1 = (i0 + 1) % n;
        let f = pos - pos.floor();
        let a = self.coverage_at(loaded, i0)?;
        let b = self.coverage_at(loaded, i1)?;
        let lerp = |x: u64, y: u64| x as f64 * (1.0 - f) + y as f64 * f;
        let (w, h) = self.spec.coverage_size(self.viewer);
        let scale = self.viewer.pixels() as f64 / (f64::from(w) * f64::from(h));
        Ok((
            FrameWork {
                quads: lerp(a.quads_in_view, b.quads_in_view),
                pixels_shaded: lerp(a.pixels_covered, b.pixels_covered) * scale,
            },
            lerp(a.quads_visible, b.quads_visible),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Coverage grows with the angle index so interpolation is visible.
    struct Ramp;
    impl CoverageSource for Ramp {
        fn objects(&self) -> usize {
            2
        }
        fn coverage(&self, loaded: usize, camera: &Camera) -> anyhow::Result<ViewCoverage> {
            let p = camera.position();
            // Encode the azimuth in the pixel count: 0° → 0, 90° → 100, …
            let az = p.x.atan2(-p.y).to_degrees().rem_euclid(360.0);
            Ok(ViewCoverage {
                quads_in_view: 10 * loaded as u64,
                quads_drawn: 8 * loaded as u64,
                quads_visible: 5 * loaded as u64,
                pixels_covered: (az / 90.0 * 100.0).round() as u64,
            })
        }
    }

    #[test]
    fn interpolates_between_angles_and_scales_pixels() {
        let spec = TurntableSpec {
            angles: 4,
            coverage_width: 100,
            ..TurntableSpec::DEFAULT
        };
        let viewer = Viewer {
            width_px: 200,
            height_px: 200,
        };
        let t = Turntable::new(spec, viewer, &Ramp);
        let (w, _) = t.work(2, 0.125).unwrap();
        // Halfway between 0° (0 px) and 90° (100 px), × 4 for the viewer.
        assert!((w.pixels_shaded - 200.0).abs() < 1e-9, "{w:?}");
        assert_eq!(w.quads, 20.0);
        let (w0, _) = t.work(0, 0.3).unwrap();
        assert_eq!(w0, FrameWork::default());
        // Angles wrap: 1.125 revolutions is 0.125.
        assert_eq!(t.work(2, 1.125).unwrap(), t.work(2, 0.125).unwrap());
        assert_eq!(t.work(2, -0.875).unwrap(), t.work(2, 0.125).unwrap());
    }
}
