//! Volume-rendering a whole view of a field (held-out measurement,
//! previews): every pixel's ray, in parallel over rows.

use image::{Rgba, RgbaImage};
use rayon::prelude::*;

use super::grid::SparseGrid;
use super::march::{render_ray, GridRay, MarchBox, MarchParams};
use crate::camera::Camera;

/// Renders `camera`'s view over a white background at `step` cells per
/// sample (pixel centres, no jitter). Alpha is 255 (composited).
pub fn render_view(grid: &SparseGrid, camera: &Camera, step: f32) -> RgbaImage {
    let (w, h) = (
        camera.intrinsics.width.max(1),
        camera.intrinsics.height.max(1),
    );
    let bx = MarchBox::of(grid);
    let params = MarchParams {
        step,
        background: glam::Vec3::ONE,
    };
    let mut img = RgbaImage::new(w, h);
    img.par_chunks_mut(4 * w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(4).enumerate() {
                let (o, d) = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                let ray = GridRay::from_world(grid, o, d, 0.5);
                let c = render_ray(grid, &bx, &ray, &params).rgb;
                let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                px.copy_from_slice(&Rgba([q(c.x), q(c.y), q(c.z), 255]).0);
            }
        });
    img
}
