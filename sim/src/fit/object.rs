//! Both curves of one object: size from `size_bytes`, quality from `ssim`.

use super::curve::{self, Domain, FamilyChoice, FamilyFit, Point};
use super::samples::{self, Sample};
use super::FitError;
use nerflex_core::profiler::{Curve, Profile};

/// One object's fitted profile.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectFit {
    /// Object name.
    pub name: String,
    /// Size fit (bytes).
    pub size: FamilyFit,
    /// Quality fit (SSIM).
    pub quality: FamilyFit,
    /// Number of samples fitted.
    pub samples: usize,
    /// The domain the fit is bounded for.
    pub domain: Domain,
}

impl ObjectFit {
    /// The fitted models in fixed point, as the planner and the device
    /// evaluate them.
    pub fn profile(&self) -> Result<Profile, FitError> {
        Profile::from_params(&self.size.best.params, &self.quality.best.params).map_err(|source| {
            FitError::Profile {
                object: self.name.clone(),
                source,
            }
        })
    }
}

/// The size and quality points of `samples` (all of one object).
pub fn points(samples: &[&Sample]) -> (Vec<Point>, Vec<Point>) {
    let size = samples
        .iter()
        .map(|s| Point {
            g: s.g,
            p: s.p,
            y: s.size.0 as f64,
        })
        .collect();
    let quality = samples
        .iter()
        .map(|s| Point {
            g: s.g,
            p: s.p,
            y: s.ssim,
        })
        .collect();
    (size, quality)
}

/// Fits both curves of one object to its samples. `domain` (default: the
/// samples' own range) is where the profile must be valid; it is widened to
/// include every sample.
pub fn fit_object(
    name: &str,
    samples: &[&Sample],
    domain: Option<Domain>,
    choice: FamilyChoice,
) -> Result<ObjectFit, FitError> {
    let wrap = |source: FitError| FitError::Object {
        object: name.to_string(),
        source: Box::new(source),
    };
    let (size_pts, quality_pts) = points(samples);
    let own = Domain::of_points(&size_pts).ok_or_else(|| {
        wrap(FitError::TooFewPoints {
            curve: Curve::Size,
            needed: curve::parameter_count(Curve::Size, nerflex_core::profiler::Family::Volume),
            points: 0,
            grids: 0,
            patches: 0,
        })
    })?;
    let domain = domain.map_or(own, |d| d.union(own));
    let size = curve::fit(Curve::Size, &size_pts, domain, choice).map_err(wrap)?;
    let quality = curve::fit(Curve::Quality, &quality_pts, domain, choice).map_err(wrap)?;
    Ok(ObjectFit {
        name: name.to_string(),
        size,
        quality,
        samples: samples.len(),
        domain,
    })
}

/// The samples of object `name`.
pub fn of_object<'s>(samples: &'s [Sample], name: &str) -> Vec<&'s Sample> {
    samples.iter().filter(|s| s.object == name).collect()
}

/// Fits every object of `samples` (or only those named in `only`, in that
/// order) over `domain` (see [`fit_object`]), with fits running in parallel.
pub fn fit_objects(
    samples: &[Sample],
    only: &[String],
    domain: Option<Domain>,
    choice: FamilyChoice,
) -> Result<Vec<ObjectFit>, FitError> {
    use rayon::prelude::*;
    let names = select(samples, only)?;
    names
        .par_iter()
        .map(|name| fit_object(name, &of_object(samples, name), domain, choice))
        .collect()
}

/// The object names to work on: `only` (each checked), or all in order.
pub fn select(samples: &[Sample], only: &[String]) -> Result<Vec<String>, FitError> {
    let known = samples::objects(samples);
    if only.is_empty() {
        return Ok(known.into_iter().map(str::to_string).collect());
    }
    for name in only {
        if !known.contains(&name.as_str()) {
            return Err(FitError::UnknownObject {
                name: name.clone(),
                known: known.join(", "),
            });
        }
    }
    Ok(only.to_vec())
}
