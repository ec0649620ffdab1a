//! Fitted profiles written as a scene file in profile form, which
//! `nerflex plan --scene` reads (`crate::scene_file`).
//!
//! ```json
//! {"objects": [{
//!   "name": "lego",
//!   "profile": {
//!     "size":    {"k": 60.3, "a": -7.5, "b": 4.4, "m": 0, "g_power": 1.5, "c": 1800},
//!     "quality": {"k": 3.2e6, "a": 32, "b": 4, "m": 0.953, "g_power": 3},
//!     "g": [16, 32, 64, 128, 256], "p": [5, 9, 13, 17]},
//!   "fit": {"samples": 20,
//!     "size":    {"rmse_bytes": 812.5, "max_abs_bytes": 1904.0,
//!                 "rmse_by_family": {"volume": 5120.2, "surface": 900.1, "quads": 812.5}},
//!     "quality": {"rmse_ssim": 0.0021, "max_abs_ssim": 0.0049,
//!                 "rmse_by_family": {"volume": 0.0021, "surface": 0.0030}}}}]}
//! ```
//!
//! `g_power` is 3 (the paper's `(g+a)³`, the default when absent), 2
//! (surface-like growth) or 1.5 (the quads family's texel term, with the
//! per-quad term `c·(g+a)²`; `c` is written only when not 0); `fit` is
//! informative and ignored by the planner.

use super::{FitError, ObjectFit};
use nerflex_core::mck::MAX_CONFIGS;
use nerflex_core::profiler::{ConfigSpace, Params};
use serde_json::{json, Map, Value};

/// The (g, p) values a profile is written for.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Space {
    /// Grid values; empty = each object's sampled g values.
    pub grids: Vec<u32>,
    /// Patch values; empty = each object's sampled p values.
    pub patches: Vec<u32>,
}

fn params_json(p: &Params) -> Value {
    crate::scene_file::params_json(p)
}

fn sorted_distinct(v: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut v: Vec<u32> = v.collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// One object's entry: profile in scene-file form plus fit diagnostics.
/// Checks that the fixed-point profile evaluates on every configuration.
pub fn object_json(
    fit: &ObjectFit,
    sampled: &[(u32, u32)],
    space: &Space,
) -> Result<Value, FitError> {
    let grids = if space.grids.is_empty() {
        sorted_distinct(sampled.iter().map(|s| s.0))
    } else {
        space.grids.clone()
    };
    let patches = if space.patches.is_empty() {
        sorted_distinct(sampled.iter().map(|s| s.1))
    } else {
        space.patches.clone()
    };
    let err = |source| FitError::Profile {
        object: fit.name.clone(),
        source,
    };
    let cs = ConfigSpace::new(&grids, &patches).map_err(err)?;
    let profile = fit.profile()?;
    let mut table = [nerflex_core::mck::Config {
        size: nerflex_core::units::Bytes(0),
        quality: nerflex_core::units::QualityQ::ZERO,
    }; MAX_CONFIGS];
    profile.fill_table(&cs, &mut table).map_err(err)?;
    let by_family = |f: &super::FamilyFit| {
        let mut m = Map::new();
        for t in &f.tried {
            m.insert(t.params.family.name().into(), json!(t.residuals.rmse));
        }
        Value::Object(m)
    };
    let (s, q) = (&fit.size.best, &fit.quality.best);
    Ok(json!({
        "name": fit.name,
        "profile": {
            "size": params_json(&s.params),
            "quality": params_json(&q.params),
            "g": grids,
            "p": patches,
        },
        "fit": {
            "samples": fit.samples,
            "size": {
                "rmse_bytes": s.residuals.rmse,
                "max_abs_bytes": s.residuals.max_abs,
                "rmse_by_family": by_family(&fit.size),
            },
            "quality": {
                "rmse_ssim": q.residuals.rmse,
                "max_abs_ssim": q.residuals.max_abs,
                "rmse_by_family": by_family(&fit.quality),
            },
        },
    }))
}

/// The scene file of all fitted objects.
pub fn scene_json(
    fits: &[ObjectFit],
    sampled: impl Fn(&str) -> Vec<(u32, u32)>,
    space: &Space,
) -> Result<Value, FitError> {
    let objects = fits
        .iter()
        .map(|f| object_json(f, &sampled(&f.name), space))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(json!({ "objects": objects }))
}
