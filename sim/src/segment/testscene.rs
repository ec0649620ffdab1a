//! A small ray-cast multi-object capture with known detail: textured
//! spheres whose stripe count sets their detail frequency. Used by the
//! segmentation tests and benchmark, where a ground-truth ranking and exact
//! 3-D geometry are needed. (The project's realistic procedural objects are
//! the `procedural` module's job.)

use super::input::{SegCapture, SegFrame};
use crate::camera::{Camera, Intrinsics};
use crate::capture::{ObjectInfo, Placement, SceneInfo};
use glam::Vec3;
use image::{GrayImage, Luma, Rgba, RgbaImage};
use rayon::prelude::*;

/// One sphere with a sinusoidal checker texture.
#[derive(Debug, Clone, PartialEq)]
pub struct TexturedSphere {
    /// Object name.
    pub name: String,
    /// Centre, world units.
    pub centre: Vec3,
    /// Radius, world units.
    pub radius: f32,
    /// Texture periods around the sphere (longitude) and pole to pole × 2.
    pub stripes: f32,
    /// Base colour, linear-ish RGB in [0, 1].
    pub colour: [f32; 3],
}

/// Five spheres on a ring of radius 1 around the origin, stripes 1, 3, 6,
/// 12 and 24 (names `s01` … `s24`), so their detail ranks in that order.
pub fn ring_of_five() -> Vec<TexturedSphere> {
    let colours = [
        [0.8, 0.3, 0.2],
        [0.2, 0.6, 0.3],
        [0.25, 0.35, 0.8],
        [0.75, 0.65, 0.2],
        [0.6, 0.3, 0.7],
    ];
    [1.0f32, 3.0, 6.0, 12.0, 24.0]
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            let a = i as f32 * std::f32::consts::TAU / 5.0;
            TexturedSphere {
                name: format!("s{:02}", k as u32),
                centre: Vec3::new(a.cos(), a.sin(), 0.0),
                radius: 0.32,
                stripes: k,
                colour: colours[i],
            }
        })
        .collect()
}

/// The cameras of a capture: `views` on an orbit of radius 4 at 30° (train)
/// elevation, NeRF-synthetic field of view (0.6911 rad).
pub fn orbit_cameras(views: usize, elevation_deg: f32, width: u32, height: u32) -> Vec<Camera> {
    let k = Intrinsics::from_fov_x(0.691_111_1, width, height);
    (0..views)
        .map(|i| {
            let az = 360.0 * i as f32 / views.max(1) as f32 + 7.0;
            Camera::orbit(az, elevation_deg, 4.0, Vec3::ZERO, k)
        })
        .collect()
}

/// Renders one view: RGBA (alpha = coverage from 2×2 supersampling) and the
/// instance mask (label = sphere index + 1 of the nearest hit at the pixel
/// centre).
pub fn render_view(spheres: &[TexturedSphere], camera: &Camera) -> (RgbaImage, GrayImage) {
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    let light = Vec3::new(0.4, -0.5, 0.8).normalize();
    let shade = |px: f32, py: f32| -> Option<(usize, [f32; 3])> {
        let (o, d) = camera.ray(px, py);
        let mut best: Option<(f32, usize)> = None;
        for (i, s) in spheres.iter().enumerate() {
            let oc = o - s.centre;
            let b = oc.dot(d);
            let c = oc.length_squared() - s.radius * s.radius;
            let disc = b * b - c;
            if disc < 0.0 {
                continue;
            }
            let t = -b - disc.sqrt();
            if t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i));
            }
        }
        let (t, i) = best?;
        let s = &spheres[i];
        let n = ((o + t * d) - s.centre) / s.radius;
        let lon = n.y.atan2(n.x);
        let lat = n.z.clamp(-1.0, 1.0).acos();
        let tex = 0.5 + 0.5 * (s.stripes * lon).sin() * (s.stripes * lat).sin();
        let lit = 0.35 + 0.65 * n.dot(light).max(0.0);
        let m = (0.35 + 0.65 * tex) * lit;
        Some((i, s.colour.map(|c| c * m)))
    };
    let mut image = RgbaImage::new(w, h);
    let mut mask = GrayImage::new(w, h);
    let rows: Vec<(Vec<Rgba<u8>>, Vec<u8>)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut px = Vec::with_capacity(w as usize);
            let mut ms = Vec::with_capacity(w as usize);
            for x in 0..w {
                let centre = shade(x as f32 + 0.5, y as f32 + 0.5);
                ms.push(centre.map_or(0, |(i, _)| (i + 1) as u8));
                let mut acc = [0.0f32; 4];
                for (sx, sy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    if let Some((_, c)) = shade(x as f32 + sx, y as f32 + sy) {
                        for k in 0..3 {
                            acc[k] += c[k];
                        }
                        acc[3] += 1.0;
                    }
                }
                if acc[3] == 0.0 {
                    px.push(Rgba([0; 4]));
                } else {
                    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                    px.push(Rgba([
                        q(acc[0] / acc[3]),
                        q(acc[1] / acc[3]),
                        q(acc[2] / acc[3]),
                        q(acc[3] / 4.0),
                    ]));
                }
            }
            (px, ms)
        })
        .collect();
    for (y, (px, ms)) in rows.into_iter().enumerate() {
        for (x, (p, m)) in px.into_iter().zip(ms).enumerate() {
            image.put_pixel(x as u32, y as u32, p);
            mask.put_pixel(x as u32, y as u32, Luma([m]));
        }
    }
    (image, mask)
}

/// The `scene.json` entries of the spheres (kind `textured-sphere`, placed
/// at their centres with scale = radius, bounds = the sphere's box).
pub fn scene_info(spheres: &[TexturedSphere]) -> SceneInfo {
    let mut scene = SceneInfo::new(
        spheres
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let c = s.centre.to_array().map(f64::from);
                let r = s.radius as f64;
                ObjectInfo {
                    name: s.name.clone(),
                    kind: "textured-sphere".into(),
                    mask_value: (i + 1) as u8,
                    placement: Placement {
                        translation: c,
                        rotation_z_deg: 0.0,
                        scale: r,
                    },
                    bounds_min: c.map(|v| v - r),
                    bounds_max: c.map(|v| v + r),
                    complexity_quads: None,
                    texture_frequency: None,
                    extra: Default::default(),
                }
            })
            .collect(),
    );
    scene.layout = Some("ring".into());
    scene
}

/// A whole capture of `spheres`: `train` views at 30° and `test` views at
/// 45° elevation, `size × size` pixels.
pub fn sphere_capture(
    spheres: &[TexturedSphere],
    train: usize,
    test: usize,
    size: u32,
) -> SegCapture {
    let make = |split: &str, cams: Vec<Camera>| -> Vec<SegFrame> {
        cams.iter()
            .enumerate()
            .map(|(i, c)| {
                let (image, mask) = render_view(spheres, c);
                SegFrame {
                    file_path: format!("./{split}/r_{i}"),
                    image,
                    mask,
                    camera: *c,
                    object_views: Vec::new(),
                }
            })
            .collect()
    };
    SegCapture {
        objects: spheres.iter().map(|s| s.name.clone()).collect(),
        camera_angle_x: 0.691_111_1,
        train: make("train", orbit_cameras(train, 30.0, size, size)),
        test: make("test", orbit_cameras(test, 45.0, size, size)),
        source: format!("spheres({})", spheres.len()),
        scene: Some(scene_info(spheres)),
    }
}
