//! Leave-one-out accuracy of the fitted profiles on measured samples.
//!
//! For each object and each of its samples, both curves are fitted to the
//! object's *other* samples (over the object's full domain, so the bounds do
//! not change) and the left-out configuration is predicted by the
//! fixed-point `nerflex_core::profiler` — the same numbers the planner and
//! the device use. The errors `|predicted − measured|` (SSIM, and size in
//! MB = 10^6 bytes) are summarised as mean ± standard deviation (population
//! sd, numpy's default), beside the NeRFlex paper's figures.

use super::curve::{Domain, FamilyChoice};
use super::object::{self, fit_object, ObjectFit};
use super::samples::Sample;
use super::FitError;
use nerflex_core::profiler::Family;
use nerflex_core::units::{Bytes, BYTES_PER_MB};
use rayon::prelude::*;
use std::fmt::Write as _;

/// Mean and standard deviation of a set of errors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stats {
    /// Mean.
    pub mean: f64,
    /// Population standard deviation.
    pub sd: f64,
    /// Number of values.
    pub n: usize,
}

impl Stats {
    /// Mean and population sd of `values` (zeros when empty).
    pub fn of(values: impl IntoIterator<Item = f64>) -> Stats {
        let v: Vec<f64> = values.into_iter().collect();
        let n = v.len();
        if n == 0 {
            return Stats {
                mean: 0.0,
                sd: 0.0,
                n,
            };
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        Stats {
            mean,
            sd: var.sqrt(),
            n,
        }
    }
}

/// The NeRFlex paper's SSIM prediction error (four objects, 45 configurations).
pub const PAPER_SSIM: Stats = Stats {
    mean: 0.0065,
    sd: 0.0088,
    n: 45,
};

/// The NeRFlex paper's size prediction error in MB.
pub const PAPER_SIZE_MB: Stats = Stats {
    mean: 3.3410,
    sd: 2.7345,
    n: 45,
};

/// One left-out configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct LooPoint {
    /// Object name.
    pub object: String,
    /// Grid.
    pub g: u32,
    /// Patch.
    pub p: u32,
    /// Measured size.
    pub size_measured: Bytes,
    /// Size predicted without this sample.
    pub size_predicted: Bytes,
    /// Measured SSIM.
    pub ssim_measured: f64,
    /// SSIM predicted without this sample.
    pub ssim_predicted: f64,
    /// Family chosen for size without this sample.
    pub size_family: Family,
    /// Family chosen for quality without this sample.
    pub quality_family: Family,
}

impl LooPoint {
    /// `|predicted − measured|` SSIM.
    pub fn ssim_error(&self) -> f64 {
        (self.ssim_predicted - self.ssim_measured).abs()
    }

    /// `|predicted − measured|` size in MB.
    pub fn size_error_mb(&self) -> f64 {
        self.size_predicted.0.abs_diff(self.size_measured.0) as f64 / BYTES_PER_MB as f64
    }

    /// `|predicted − measured| / measured` size (fraction).
    pub fn size_error_rel(&self) -> f64 {
        self.size_predicted.0.abs_diff(self.size_measured.0) as f64
            / (self.size_measured.0.max(1)) as f64
    }
}

/// Errors of one object (or of all).
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorSummary {
    /// SSIM error.
    pub ssim: Stats,
    /// Size error in MB.
    pub size_mb: Stats,
    /// Size error relative to the measured size.
    pub size_rel: Stats,
}

impl ErrorSummary {
    /// Summary of `points`.
    pub fn of<'a>(points: impl IntoIterator<Item = &'a LooPoint> + Clone) -> ErrorSummary {
        ErrorSummary {
            ssim: Stats::of(points.clone().into_iter().map(LooPoint::ssim_error)),
            size_mb: Stats::of(points.clone().into_iter().map(LooPoint::size_error_mb)),
            size_rel: Stats::of(points.into_iter().map(LooPoint::size_error_rel)),
        }
    }
}

/// One object's accuracy.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectAccuracy {
    /// The fit on all of the object's samples.
    pub fit: ObjectFit,
    /// Its leave-one-out errors.
    pub errors: ErrorSummary,
}

/// Leave-one-out accuracy over several objects.
#[derive(Clone, Debug, PartialEq)]
pub struct Accuracy {
    /// Every left-out configuration.
    pub points: Vec<LooPoint>,
    /// Per object, in order.
    pub objects: Vec<ObjectAccuracy>,
    /// Over all points.
    pub all: ErrorSummary,
}

/// Leave-one-out over every object of `samples` (or those in `only`).
pub fn leave_one_out(
    samples: &[Sample],
    only: &[String],
    choice: FamilyChoice,
) -> Result<Accuracy, FitError> {
    let names = object::select(samples, only)?;
    let per_object: Vec<(ObjectFit, Vec<LooPoint>)> = names
        .par_iter()
        .map(|name| object_loo(name, &object::of_object(samples, name), choice))
        .collect::<Result<_, _>>()?;
    let points: Vec<LooPoint> = per_object
        .iter()
        .flat_map(|(_, p)| p.iter().cloned())
        .collect();
    let objects = per_object
        .into_iter()
        .map(|(fit, pts)| ObjectAccuracy {
            fit,
            errors: ErrorSummary::of(&pts),
        })
        .collect();
    Ok(Accuracy {
        all: ErrorSummary::of(&points),
        points,
        objects,
    })
}

fn object_loo(
    name: &str,
    samples: &[&Sample],
    choice: FamilyChoice,
) -> Result<(ObjectFit, Vec<LooPoint>), FitError> {
    let (size_pts, _) = object::points(samples);
    let domain = Domain::of_points(&size_pts);
    let full = fit_object(name, samples, domain, choice)?;
    let points = (0..samples.len())
        .into_par_iter()
        .map(|i| {
            let left = samples[i];
            let rest: Vec<&Sample> = samples
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, s)| *s)
                .collect();
            let fit = fit_object(name, &rest, domain, choice)?;
            let config =
                fit.profile()?
                    .config(left.g, left.p)
                    .map_err(|source| FitError::Profile {
                        object: name.to_string(),
                        source,
                    })?;
            Ok(LooPoint {
                object: name.to_string(),
                g: left.g,
                p: left.p,
                size_measured: left.size,
                size_predicted: config.size,
                ssim_measured: left.ssim,
                ssim_predicted: config.quality.to_f64(),
                size_family: fit.size.best.params.family,
                quality_family: fit.quality.best.params.family,
            })
        })
        .collect::<Result<Vec<_>, FitError>>()?;
    Ok((full, points))
}

/// The accuracy table (text), ours beside the paper's.
pub fn table(acc: &Accuracy) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Leave-one-out prediction error |predicted − measured|, mean ± sd (population)"
    );
    let _ = writeln!(
        out,
        "{:<16} {:>4}  {:>19}  {:>19}  {:>15}  {:<16}",
        "object", "n", "SSIM", "size (MB)", "size (%)", "family size/SSIM"
    );
    let row = |out: &mut String, name: &str, n: usize, e: &ErrorSummary, fam: &str| {
        let _ = writeln!(
            out,
            "{:<16} {:>4}  {:>8.4} ± {:<8.4}  {:>8.3} ± {:<8.3}  {:>6.2} ± {:<6.2}  {:<16}",
            name,
            n,
            e.ssim.mean,
            e.ssim.sd,
            e.size_mb.mean,
            e.size_mb.sd,
            100.0 * e.size_rel.mean,
            100.0 * e.size_rel.sd,
            fam
        );
    };
    for o in &acc.objects {
        let fam = format!(
            "{}/{}",
            o.fit.size.best.params.family, o.fit.quality.best.params.family
        );
        row(&mut out, &o.fit.name, o.errors.ssim.n, &o.errors, &fam);
    }
    row(&mut out, "all", acc.all.ssim.n, &acc.all, "");
    let _ = writeln!(
        out,
        "{:<16} {:>4}  {:>8.4} ± {:<8.4}  {:>8.3} ± {:<8.3}  {:>15}  (4 objects, MobileNeRF)",
        "NeRFlex paper",
        PAPER_SSIM.n,
        PAPER_SSIM.mean,
        PAPER_SSIM.sd,
        PAPER_SIZE_MB.mean,
        PAPER_SIZE_MB.sd,
        "-"
    );
    out
}

/// The accuracy as JSON: summaries (ours and the paper's) and every
/// left-out point.
pub fn to_json(acc: &Accuracy) -> serde_json::Value {
    use serde_json::json;
    let stats = |s: &Stats| json!({"mean": s.mean, "sd": s.sd, "n": s.n});
    let summary = |e: &ErrorSummary| json!({"ssim": stats(&e.ssim), "size_mb": stats(&e.size_mb), "size_rel": stats(&e.size_rel)});
    json!({
        "all": summary(&acc.all),
        "paper": {"ssim": stats(&PAPER_SSIM), "size_mb": stats(&PAPER_SIZE_MB)},
        "objects": acc.objects.iter().map(|o| json!({
            "name": o.fit.name,
            "errors": summary(&o.errors),
            "size_family": o.fit.size.best.params.family.name(),
            "quality_family": o.fit.quality.best.params.family.name(),
        })).collect::<Vec<_>>(),
        "points": acc.points.iter().map(|p| json!({
            "object": p.object, "g": p.g, "p": p.p,
            "size_measured_bytes": p.size_measured.0,
            "size_predicted_bytes": p.size_predicted.0,
            "ssim_measured": p.ssim_measured,
            "ssim_predicted": p.ssim_predicted,
        })).collect::<Vec<_>>(),
    })
}

/// In-sample residuals of the full fits (RMSE), one line per object.
pub fn fit_table(acc: &Accuracy) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "Fit on all samples: RMSE per family (chosen = lower)");
    let _ = writeln!(
        out,
        "{:<16} {:>4}  {:>14} {:>14}  {:>10} {:>10}",
        "object", "n", "size vol (MB)", "size surf (MB)", "SSIM vol", "SSIM surf"
    );
    for o in &acc.objects {
        let rmse = |f: &super::FamilyFit, fam: Family| {
            f.tried
                .iter()
                .find(|t| t.params.family == fam)
                .map(|t| t.residuals.rmse)
        };
        let cell = |v: Option<f64>, scale: f64, prec: usize| {
            v.map_or("-".to_string(), |v| format!("{:.*}", prec, v / scale))
        };
        let _ = writeln!(
            out,
            "{:<16} {:>4}  {:>14} {:>14}  {:>10} {:>10}",
            o.fit.name,
            o.fit.samples,
            cell(rmse(&o.fit.size, Family::Volume), 1e6, 4),
            cell(rmse(&o.fit.size, Family::Surface), 1e6, 4),
            cell(rmse(&o.fit.quality, Family::Volume), 1.0, 5),
            cell(rmse(&o.fit.quality, Family::Surface), 1.0, 5),
        );
    }
    out
}
