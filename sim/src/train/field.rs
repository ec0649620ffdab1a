//! What a trained radiance field offers to the rest of the pipeline.
//!
//! Bakers, renderers and measurements read a field only through
//! [`RadianceField`], so they can be tested on analytic fields and run on
//! trained ones alike.

use glam::Vec3;

use crate::bake::Aabb;

/// A radiance field over a world-space box (world units, z up, the
/// capture's frame).
pub trait RadianceField: Send + Sync {
    /// The box the field lives in; outside it the field is empty.
    fn bounds(&self) -> Aabb;

    /// Cells per edge of the grid the field was trained at: a hint for
    /// how finely to sample it (a sample step of about half a cell, i.e.
    /// `0.5 * edge / resolution`, resolves it).
    fn resolution(&self) -> u32;

    /// Volume density σ ≥ 0 at world point `p`, per world unit: a segment of
    /// length `δ` at constant σ has opacity `1 − exp(−σ·δ)`.
    fn density(&self, p: Vec3) -> f32;

    /// What [`RadianceField::is_inside`] needs to answer `density(p) ≥
    /// sigma_min` quickly (worked out once per threshold, not per point).
    fn inside_threshold(&self, sigma_min: f32) -> InsideThreshold {
        InsideThreshold::exact(sigma_min)
    }

    /// Whether `density(p) >= t.sigma` (`t` from
    /// [`RadianceField::inside_threshold`]): the same answer, which a field
    /// may reach without computing the density.
    fn is_inside(&self, p: Vec3, t: &InsideThreshold) -> bool {
        self.density(p) >= t.sigma
    }

    /// Emitted colour (linear in the image's 8-bit values / 255, each in
    /// [0, 1]) at world point `p` seen along the unit direction `dir`
    /// (pointing from the camera towards `p`).
    fn color(&self, p: Vec3, dir: Vec3) -> Vec3;

    /// The same field laid out for many scattered point queries (the
    /// bake's), answering every query with the same bits; `None` when
    /// this one is already as fast. Built once per bake.
    fn for_point_queries(&self) -> Option<Box<dyn RadianceField + '_>> {
        None
    }
}

/// A density threshold prepared by [`RadianceField::inside_threshold`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InsideThreshold {
    /// σ at and above which a point is inside.
    pub sigma: f32,
    /// A band of the field's own pre-activation value (the sparse grid's
    /// interpolated raw density), which σ increases with: below `lo` a
    /// point is outside, above `hi` inside; within the band the density
    /// decides (with `lo = −∞`, `hi = ∞` it always does).
    pub lo: f32,
    /// The band's upper end (see `lo`).
    pub hi: f32,
}

impl InsideThreshold {
    /// A threshold answered by the density alone.
    pub fn exact(sigma: f32) -> Self {
        Self {
            sigma,
            lo: f32::NEG_INFINITY,
            hi: f32::INFINITY,
        }
    }
}
