//! Built-in scenes: procedural objects, their placement, a sphere-traced
//! renderer and a capture generator writing the NeRF-synthetic layout.
//!
//! - [`objects`]: twelve objects ([`ObjectKind`]) from a plain ball to a
//!   Menger sponge, as signed distance functions with procedural textures,
//!   in the NeRF-synthetic unit-cube convention (z up, about [−1, 1]³).
//! - [`complexity`]: geometric complexity = boundary quads of the object's
//!   occupancy at a 64³ grid over its bounds (the NeRFlex paper's measure).
//! - [`layout`]: row / ring / random arrangements scaled to stay in every
//!   camera's view, the paper's four preset scenes, `scene.json`.
//! - [`render`]: RGBA (alpha = coverage) + instance mask from any
//!   [`crate::camera::Camera`].
//! - [`generate`]: hemisphere cameras and parallel capture generation.
//!
//! `docs/scenes.md` describes the objects, the renderer and the formats.

pub mod complexity;
pub mod generate;
pub mod layout;
mod noise;
pub mod objects;
pub mod render;
mod sdf;
mod text;
mod tree;

pub use complexity::{complexity_quads, occupancy, ranked, Occupancy, COMPLEXITY_GRID};
pub use generate::{make_capture, view_cameras, CaptureReport, CaptureSpec};
/// The vector type of placements and bounds.
pub use glam::Vec3;
pub use layout::{
    arrange, scene_info, Layout, PlacedObject, Placement, Preset, CAMERA_ANGLE_X, CAMERA_DISTANCE,
    SCENE_RADIUS,
};
pub use objects::{Aabb, Material, ObjectKind};
pub use render::{RenderOptions, RenderedView, SceneRenderer};

use crate::camera::{Camera, Intrinsics};
use image::{Rgba, RgbaImage};

/// Renders placed objects from one camera (convenience for
/// [`SceneRenderer::new`] + [`SceneRenderer::render`]).
pub fn render_view(
    objects: &[PlacedObject],
    camera: &Camera,
    opts: &RenderOptions,
) -> RenderedView {
    SceneRenderer::new(objects).render(camera, opts)
}

/// A `size`×`size` portrait of one object for the documentation: the object
/// alone at its capture placement, seen from azimuth 30° and elevation 25°
/// at the capture distance, the field of view narrowed so the object fills
/// the frame, composited over white.
pub fn portrait(kind: ObjectKind, size: u32) -> RgbaImage {
    let objs = arrange(&[kind], Layout::Row, 0, 1.0);
    let fov = 2.0 * (1.06 * objs[0].bounding_radius() / CAMERA_DISTANCE).asin();
    let cam = Camera::orbit(
        30.0,
        25.0,
        CAMERA_DISTANCE,
        Vec3::ZERO,
        Intrinsics::from_fov_x(fov, size, size),
    );
    let v = render_view(&objs, &cam, &RenderOptions::default());
    let mut out = RgbaImage::new(size, size);
    for (o, p) in out.pixels_mut().zip(v.image.pixels()) {
        let a = p.0[3] as f32 / 255.0;
        let c = |i: usize| (p.0[i] as f32 * a + 255.0 * (1.0 - a) + 0.5) as u8;
        *o = Rgba([c(0), c(1), c(2), 255]);
    }
    out
}
