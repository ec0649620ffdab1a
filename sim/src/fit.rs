//! The profiler's host side: sample selection, curve fitting, profiles for
//! the planner, and the measured accuracy of the fitted models.
//!
//! - [`sampling`]: the NeRFlex paper's variable step-size sample points.
//! - [`samples`]: the bake sweep's samples CSV (read, validate, write).
//! - [`curve`]: Levenberg–Marquardt fit of one curve (size or quality) of
//!   one family (`G³` or `G²`), bounded by reparameterisation.
//! - [`object`]: both curves of one object, the family picked by residual.
//! - [`profiles`]: the fitted profiles as a scene file (`nerflex plan`).
//! - [`accuracy`]: leave-one-out prediction errors, beside the paper's.
//! - [`plots`]: fitted curves over the measured points (PNG).
//! - [`synthetic`]: samples from known parameters plus noise (tests, benches).
//!
//! The fitted parameters are evaluated by `nerflex_core::profiler` in fixed
//! point, exactly as on the device; `f64` is only used to fit.

pub mod accuracy;
pub mod curve;
pub mod object;
pub mod plots;
pub mod profiles;
pub mod samples;
pub mod sampling;
pub mod synthetic;

pub use curve::{CurveFit, Domain, FamilyChoice, FamilyFit, Point, Residuals};
pub use object::{fit_object, fit_objects, ObjectFit};
pub use samples::Sample;

use nerflex_core::profiler::{Curve, Family, ProfileError};
use std::path::Path;

/// Why a fit could not be made.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// Not enough distinct points to determine the parameters.
    #[error(
        "{curve}: {points} samples over {grids} g and {patches} p values; \
         need at least {needed} samples with at least 2 distinct g and 2 distinct p"
    )]
    TooFewPoints {
        /// Which curve.
        curve: Curve,
        /// Samples the family needs (its parameter count).
        needed: usize,
        /// Samples given.
        points: usize,
        /// Distinct g values.
        grids: usize,
        /// Distinct p values.
        patches: usize,
    },
    /// A measured value is not finite.
    #[error("{curve}: the value at (g {g}, p {p}) is not finite ({value})")]
    BadValue {
        /// Which curve.
        curve: Curve,
        /// Grid.
        g: u32,
        /// Patch.
        p: u32,
        /// The value.
        value: f64,
    },
    /// Every start failed.
    #[error("{curve}: the {family} fit did not converge from any start")]
    NoConvergence {
        /// Which curve.
        curve: Curve,
        /// Which family.
        family: Family,
    },
    /// No family was tried.
    #[error("no model family to fit")]
    NoFamily,
    /// An object asked for is not in the samples.
    #[error("object {name:?} is not in the samples (objects: {known})")]
    UnknownObject {
        /// The name asked for.
        name: String,
        /// The names present, comma-separated.
        known: String,
    },
    /// The fitted model cannot be evaluated in fixed point.
    #[error("object {object:?}: {source}")]
    Profile {
        /// Object name.
        object: String,
        /// Why.
        source: ProfileError,
    },
    /// A fit for one object failed.
    #[error("object {object:?}: {source}")]
    Object {
        /// Object name.
        object: String,
        /// Why.
        source: Box<FitError>,
    },
}

/// Writes `bytes` to `path` through a temporary file beside it and a
/// rename, so an existing file is never left half-written.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    crate::output::write_file(path, bytes)
        .map(|_| ())
        .map_err(crate::output::OutputError::into_io)
}
