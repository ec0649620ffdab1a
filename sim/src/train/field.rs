//! What a trained radiance field offers to the rest of the pipeline.
//!
//! Bakers, renderers and measurements read a field only through
//! [`RadianceField`], so they can be tested on analytic fields and run on
//! trained ones alike.

use glam::Vec3;

use crate::bake::Aabb;

/// A radiance field over a world-space box (world units, z up, the
/// capture's frame).
pub trait RadianceField: Sync {
    /// The box the field lives in; outside it the field is empty.
    fn bounds(&self) -> Aabb;

    /// Cells per edge of the grid the field was trained at: a hint for
    /// how finely to sample it (a sample step of about half a cell, i.e.
    /// `0.5 * edge / resolution`, resolves it).
    fn resolution(&self) -> u32;

    /// Volume density σ ≥ 0 at world point `p`, per world unit: a segment of
    /// length `δ` at constant σ has opacity `1 − exp(−σ·δ)`.
    fn density(&self, p: Vec3) -> f32;

    /// Emitted colour (linear in the image's 8-bit values / 255, each in
    /// [0, 1]) at world point `p` seen along the unit direction `dir`
    /// (pointing from the camera towards `p`).
    fn color(&self, p: Vec3, dir: Vec3) -> Vec3;
}
