//! Prediction accuracy of the fitted profiles on measured samples.
//!
//! Two ways to hold configurations out ([`Training`]):
//!
//! - **Leave-one-out** ([`leave_one_out`]): for each object and each of its
//!   samples, both curves are fitted to the object's *other* samples and the
//!   left-out configuration is predicted.
//! - **Training subset** ([`train_subset`]): both curves are fitted once to
//!   the samples at the training (g, p) pairs — e.g. the paper's
//!   variable-step points ([`super::sampling::variable_step_on`]) — and
//!   every other configuration is predicted: how the profiler is meant to be
//!   used, baking a few samples to predict the rest.
//!
//! Fits are bounded over the object's full sampled domain either way (the
//! bounds do not move with what is held out), and predictions come from
//! the fixed-point `nerflex_core::profiler` — the same numbers the planner
//! and the device use. The errors `|predicted − measured|` (SSIM, and size
//! in MB = 10^6 bytes) are summarised as mean ± standard deviation
//! (population sd, numpy's default), beside the NeRFlex paper's figures;
//! [`Accuracy::restricted`] summarises a subset of the held-out points (for
//! example those whose measured size is in the paper's regime) without
//! changing the fits.
//!
//! An SSIM error means little without the curve it sits on: a flat curve
//! is predicted to within its own flatness by any fit. So every error is
//! also given relative to its object's **spread**, the largest minus the
//! smallest measured SSIM over all its samples ([`LooPoint::ssim_error_rel`]).
//!
//! A size error's sign matters too: an under-predicted size is what makes
//! a plan overshoot its budget. So every summary also gives the **worst
//! under-prediction** (the most negative `(predicted − measured)/measured`,
//! [`ErrorSummary::worst_under`]) and how many sizes were under-predicted.

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

/// One held-out configuration and its prediction.
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
    /// Size predicted by a fit that did not see this sample.
    pub size_predicted: Bytes,
    /// Measured SSIM.
    pub ssim_measured: f64,
    /// SSIM predicted by a fit that did not see this sample.
    pub ssim_predicted: f64,
    /// Family chosen for size without this sample.
    pub size_family: Family,
    /// Family chosen for quality without this sample.
    pub quality_family: Family,
    /// The object's SSIM spread: largest minus smallest measured SSIM over
    /// all its samples (held out or not).
    pub ssim_spread: f64,
}

impl LooPoint {
    /// `|predicted − measured|` SSIM.
    pub fn ssim_error(&self) -> f64 {
        (self.ssim_predicted - self.ssim_measured).abs()
    }

    /// `|predicted − measured|` SSIM as a fraction of the object's spread
    /// (`None` for an object whose samples all measured the same).
    pub fn ssim_error_rel(&self) -> Option<f64> {
        (self.ssim_spread > 0.0).then(|| self.ssim_error() / self.ssim_spread)
    }

    /// `|predicted − measured|` size in MB.
    pub fn size_error_mb(&self) -> f64 {
        self.size_predicted.0.abs_diff(self.size_measured.0) as f64 / BYTES_PER_MB as f64
    }

    /// `|predicted − measured| / measured` size (fraction).
    pub fn size_error_rel(&self) -> f64 {
        self.size_error_signed_rel().abs()
    }

    /// `(predicted − measured) / measured` size (fraction; negative: the
    /// size was under-predicted).
    pub fn size_error_signed_rel(&self) -> f64 {
        self.size_error_signed_mb() * BYTES_PER_MB as f64 / (self.size_measured.0.max(1)) as f64
    }

    /// `predicted − measured` size in MB (negative: under-predicted).
    pub fn size_error_signed_mb(&self) -> f64 {
        let (p, m) = (self.size_predicted.0, self.size_measured.0);
        let d = p.abs_diff(m) as f64 / BYTES_PER_MB as f64;
        if p < m {
            -d
        } else {
            d
        }
    }
}

/// The held-out size predicted furthest below its measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct WorstUnder {
    /// Object name.
    pub object: String,
    /// Grid.
    pub g: u32,
    /// Patch.
    pub p: u32,
    /// `(predicted − measured)/measured` (fraction, the smallest of the set).
    pub rel: f64,
    /// `predicted − measured` in MB.
    pub mb: f64,
}

/// Errors of one object (or of all).
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorSummary {
    /// SSIM error.
    pub ssim: Stats,
    /// SSIM error as a fraction of the object's SSIM spread.
    pub ssim_rel: Stats,
    /// Size error in MB.
    pub size_mb: Stats,
    /// Size error relative to the measured size.
    pub size_rel: Stats,
    /// The point with the smallest signed relative size error (`None`
    /// without points); its `rel` is positive when nothing was
    /// under-predicted.
    pub worst_under: Option<WorstUnder>,
    /// Held-out sizes predicted below their measurement.
    pub under: usize,
}

impl ErrorSummary {
    /// Summary of `points`.
    pub fn of<'a>(points: impl IntoIterator<Item = &'a LooPoint> + Clone) -> ErrorSummary {
        ErrorSummary {
            ssim: Stats::of(points.clone().into_iter().map(LooPoint::ssim_error)),
            ssim_rel: Stats::of(
                points
                    .clone()
                    .into_iter()
                    .filter_map(LooPoint::ssim_error_rel),
            ),
            size_mb: Stats::of(points.clone().into_iter().map(LooPoint::size_error_mb)),
            size_rel: Stats::of(points.clone().into_iter().map(LooPoint::size_error_rel)),
            worst_under: points
                .clone()
                .into_iter()
                .min_by(|x, y| {
                    x.size_error_signed_rel()
                        .total_cmp(&y.size_error_signed_rel())
                })
                .map(|w| WorstUnder {
                    object: w.object.clone(),
                    g: w.g,
                    p: w.p,
                    rel: w.size_error_signed_rel(),
                    mb: w.size_error_signed_mb(),
                }),
            under: points
                .into_iter()
                .filter(|x| x.size_predicted < x.size_measured)
                .count(),
        }
    }
}

/// One object's accuracy.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectAccuracy {
    /// Leave-one-out: the fit on all of the object's samples; training
    /// subset: the fit on the training samples (the one that predicted).
    pub fit: ObjectFit,
    /// Samples the fit(s) saw: all but one (leave-one-out) or the training
    /// subset.
    pub trained_on: usize,
    /// Errors of its held-out points.
    pub errors: ErrorSummary,
}

/// What the fits are trained on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Training {
    /// Each sample predicted from all of the object's other samples.
    LeaveOneOut,
    /// One fit per object on the samples at these (g, p) pairs (every g
    /// with every p); all other samples are predicted.
    Subset {
        /// Training grid values.
        grids: Vec<u32>,
        /// Training patch values.
        patches: Vec<u32>,
    },
}

impl Training {
    /// One line saying what was trained on and what was predicted.
    pub fn describe(&self) -> String {
        match self {
            Training::LeaveOneOut => {
                "leave-one-out: each configuration predicted from the object's other samples".into()
            }
            Training::Subset { grids, patches } => {
                let list = |v: &[u32]| v.iter().map(u32::to_string).collect::<Vec<_>>().join(", ");
                format!(
                    "trained on g {{{}}} × p {{{}}} only; every other configuration predicted",
                    list(grids),
                    list(patches)
                )
            }
        }
    }
}

/// Accuracy over several objects.
#[derive(Clone, Debug, PartialEq)]
pub struct Accuracy {
    /// How the fits were trained.
    pub training: Training,
    /// Every held-out configuration (after any restriction).
    pub points: Vec<LooPoint>,
    /// Per object, in order.
    pub objects: Vec<ObjectAccuracy>,
    /// Over all points.
    pub all: ErrorSummary,
    /// Held-out points before [`Accuracy::restricted`] (equal to
    /// `points.len()` when unrestricted).
    pub unrestricted: usize,
    /// What [`Accuracy::restricted`] kept, in words (empty: everything).
    pub restriction: String,
}

impl Accuracy {
    fn assemble(
        training: Training,
        per_object: Vec<(ObjectFit, usize, Vec<LooPoint>)>,
    ) -> Accuracy {
        let points: Vec<LooPoint> = per_object
            .iter()
            .flat_map(|(_, _, p)| p.iter().cloned())
            .collect();
        let objects = per_object
            .into_iter()
            .map(|(fit, trained_on, pts)| ObjectAccuracy {
                fit,
                trained_on,
                errors: ErrorSummary::of(&pts),
            })
            .collect();
        Accuracy {
            training,
            all: ErrorSummary::of(&points),
            unrestricted: points.len(),
            points,
            objects,
            restriction: String::new(),
        }
    }

    /// The same fits, summarised over the held-out points `keep` accepts
    /// (`what` says which, for the printout).
    pub fn restricted(&self, what: &str, keep: impl Fn(&LooPoint) -> bool) -> Accuracy {
        let points: Vec<LooPoint> = self.points.iter().filter(|p| keep(p)).cloned().collect();
        let objects = self
            .objects
            .iter()
            .map(|o| ObjectAccuracy {
                errors: ErrorSummary::of(points.iter().filter(|p| p.object == o.fit.name)),
                ..o.clone()
            })
            .collect();
        let restriction = match (self.restriction.is_empty(), what.is_empty()) {
            (true, _) => what.to_string(),
            (false, true) => self.restriction.clone(),
            (false, false) => format!("{}, {what}", self.restriction),
        };
        Accuracy {
            training: self.training.clone(),
            all: ErrorSummary::of(&points),
            points,
            objects,
            unrestricted: self.unrestricted,
            restriction,
        }
    }
}

/// Leave-one-out over every object of `samples` (or those in `only`).
pub fn leave_one_out(
    samples: &[Sample],
    only: &[String],
    choice: FamilyChoice,
) -> Result<Accuracy, FitError> {
    let names = object::select(samples, only)?;
    let per_object = names
        .par_iter()
        .map(|name| object_loo(name, &object::of_object(samples, name), choice))
        .collect::<Result<_, _>>()?;
    Ok(Accuracy::assemble(Training::LeaveOneOut, per_object))
}

/// Fits each object (of `samples`, or those in `only`) once on its samples
/// at `grids` × `patches` and predicts all its other samples.
pub fn train_subset(
    samples: &[Sample],
    only: &[String],
    choice: FamilyChoice,
    grids: &[u32],
    patches: &[u32],
) -> Result<Accuracy, FitError> {
    let names = object::select(samples, only)?;
    let per_object = names
        .par_iter()
        .map(|name| {
            let all = object::of_object(samples, name);
            let (train, test): (Vec<&Sample>, Vec<&Sample>) = all
                .iter()
                .partition(|s| grids.contains(&s.g) && patches.contains(&s.p));
            let (size_pts, _) = object::points(&all);
            let fit = fit_object(name, &train, Domain::of_points(&size_pts), choice)?;
            let spread = ssim_spread(&all);
            let points = test
                .iter()
                .map(|s| predict(name, &fit, s, spread))
                .collect::<Result<Vec<_>, _>>()?;
            Ok((fit, train.len(), points))
        })
        .collect::<Result<_, FitError>>()?;
    Ok(Accuracy::assemble(
        Training::Subset {
            grids: grids.to_vec(),
            patches: patches.to_vec(),
        },
        per_object,
    ))
}

/// Largest minus smallest measured SSIM of `samples` (0 for none).
fn ssim_spread(samples: &[&Sample]) -> f64 {
    let (lo, hi) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.ssim), hi.max(s.ssim))
        });
    if hi >= lo {
        hi - lo
    } else {
        0.0
    }
}

/// The fixed-point prediction of `fit` at `left`'s configuration.
fn predict(
    name: &str,
    fit: &ObjectFit,
    left: &Sample,
    ssim_spread: f64,
) -> Result<LooPoint, FitError> {
    let config = fit
        .profile()?
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
        ssim_spread,
    })
}

fn object_loo(
    name: &str,
    samples: &[&Sample],
    choice: FamilyChoice,
) -> Result<(ObjectFit, usize, Vec<LooPoint>), FitError> {
    let (size_pts, _) = object::points(samples);
    let domain = Domain::of_points(&size_pts);
    let full = fit_object(name, samples, domain, choice)?;
    let spread = ssim_spread(samples);
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
            predict(name, &fit, left, spread)
        })
        .collect::<Result<Vec<_>, FitError>>()?;
    Ok((full, samples.len().saturating_sub(1), points))
}

/// The accuracy table (text), ours beside the paper's.
pub fn table(acc: &Accuracy) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Prediction error |predicted − measured|, mean ± sd (population)"
    );
    let _ = writeln!(out, "# {}", acc.training.describe());
    if !acc.restriction.is_empty() {
        let _ = writeln!(
            out,
            "# held-out points with {}: {} of {}",
            acc.restriction,
            acc.points.len(),
            acc.unrestricted
        );
    }
    let _ = writeln!(
        out,
        "{:<16} {:>5} {:>4}  {:>19}  {:>15}  {:>19}  {:>15}  {:>11}  {:<16}",
        "object",
        "train",
        "n",
        "SSIM",
        "SSIM/spread (%)",
        "size (MB)",
        "size (%)",
        "worst (%)",
        "family size/SSIM"
    );
    let row = |out: &mut String, name: &str, train: &str, e: &ErrorSummary, fam: &str| {
        if e.ssim.n == 0 {
            let _ = writeln!(out, "{name:<16} {train:>5} {:>4}  (no held-out points)", 0);
            return;
        }
        let _ = writeln!(
            out,
            "{:<16} {:>5} {:>4}  {:>8.4} ± {:<8.4}  {:>6.1} ± {:<6.1}  {:>8.3} ± {:<8.3}  {:>6.2} ± {:<6.2}  {:>11}  {:<16}",
            name,
            train,
            e.ssim.n,
            e.ssim.mean,
            e.ssim.sd,
            100.0 * e.ssim_rel.mean,
            100.0 * e.ssim_rel.sd,
            e.size_mb.mean,
            e.size_mb.sd,
            100.0 * e.size_rel.mean,
            100.0 * e.size_rel.sd,
            e.worst_under
                .as_ref()
                .map_or("-".into(), |w| format!("{:+.1}", 100.0 * w.rel)),
            fam
        );
    };
    for o in &acc.objects {
        let fam = format!(
            "{}/{}",
            o.fit.size.best.params.family, o.fit.quality.best.params.family
        );
        row(
            &mut out,
            &o.fit.name,
            &o.trained_on.to_string(),
            &o.errors,
            &fam,
        );
    }
    row(&mut out, "all", "", &acc.all, "");
    if let Some(w) = &acc.all.worst_under {
        let _ = writeln!(
            out,
            "worst (%) = smallest (predicted − measured)/measured size: all {:+.1} % ({:+.3} MB) at {} (g {}, p {}); {} of {} sizes under-predicted",
            100.0 * w.rel,
            w.mb,
            w.object,
            w.g,
            w.p,
            acc.all.under,
            acc.all.size_rel.n
        );
    }
    let _ = writeln!(
        out,
        "{:<16} {:>5} {:>4}  {:>8.4} ± {:<8.4}  {:>15}  {:>8.3} ± {:<8.3}  {:>15}  {:>11}  (4 objects, MobileNeRF)",
        "NeRFlex paper",
        "",
        PAPER_SSIM.n,
        PAPER_SSIM.mean,
        PAPER_SSIM.sd,
        "-",
        PAPER_SIZE_MB.mean,
        PAPER_SIZE_MB.sd,
        "-",
        "-"
    );
    out
}

/// The accuracy as JSON: summaries (ours and the paper's) and every
/// left-out point.
pub fn to_json(acc: &Accuracy) -> serde_json::Value {
    use serde_json::json;
    let stats = |s: &Stats| json!({"mean": s.mean, "sd": s.sd, "n": s.n});
    let summary = |e: &ErrorSummary| {
        json!({"ssim": stats(&e.ssim), "ssim_rel_spread": stats(&e.ssim_rel),
               "size_mb": stats(&e.size_mb), "size_rel": stats(&e.size_rel),
               "size_under_predicted": e.under,
               "size_worst_under": e.worst_under.as_ref().map(|w| json!({
                   "object": w.object, "g": w.g, "p": w.p, "rel": w.rel, "mb": w.mb}))})
    };
    let training = match &acc.training {
        Training::LeaveOneOut => json!("leave-one-out"),
        Training::Subset { grids, patches } => json!({"grids": grids, "patches": patches}),
    };
    json!({
        "training": training,
        "restriction": acc.restriction,
        "held_out": acc.points.len(),
        "held_out_unrestricted": acc.unrestricted,
        "all": summary(&acc.all),
        "paper": {"ssim": stats(&PAPER_SSIM), "size_mb": stats(&PAPER_SIZE_MB)},
        "objects": acc.objects.iter().map(|o| json!({
            "name": o.fit.name,
            "trained_on": o.trained_on,
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
            "ssim_spread": p.ssim_spread,
        })).collect::<Vec<_>>(),
    })
}

/// In-sample residuals of the full fits (RMSE), one line per object.
pub fn fit_table(acc: &Accuracy) -> String {
    let mut out = String::new();
    let what = match acc.training {
        Training::LeaveOneOut => "all samples",
        Training::Subset { .. } => "the training samples",
    };
    let _ = writeln!(out, "Fit on {what}: RMSE per family (chosen = lowest)");
    let _ = writeln!(
        out,
        "{:<16} {:>4}  {:>14} {:>14} {:>15}  {:>10} {:>10}",
        "object",
        "n",
        "size vol (MB)",
        "size surf (MB)",
        "size quads (MB)",
        "SSIM vol",
        "SSIM surf"
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
            "{:<16} {:>4}  {:>14} {:>14} {:>15}  {:>10} {:>10}",
            o.fit.name,
            o.fit.samples,
            cell(rmse(&o.fit.size, Family::Volume), 1e6, 4),
            cell(rmse(&o.fit.size, Family::Surface), 1e6, 4),
            cell(rmse(&o.fit.size, Family::Quads), 1e6, 4),
            cell(rmse(&o.fit.quality, Family::Volume), 1.0, 5),
            cell(rmse(&o.fit.quality, Family::Surface), 1.0, 5),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(measured: f64, predicted: f64, spread: f64) -> LooPoint {
        LooPoint {
            object: "o".into(),
            g: 16,
            p: 3,
            size_measured: Bytes(1),
            size_predicted: Bytes(1),
            ssim_measured: measured,
            ssim_predicted: predicted,
            size_family: Family::Surface,
            quality_family: Family::Surface,
            ssim_spread: spread,
        }
    }

    #[test]
    fn a_flat_curve_cannot_look_accurate() {
        // The same absolute error on a flat and on a steep curve.
        let flat = point(0.90, 0.902, 0.004);
        let steep = point(0.90, 0.902, 0.100);
        assert!((flat.ssim_error_rel().unwrap() - 0.5).abs() < 1e-9);
        assert!((steep.ssim_error_rel().unwrap() - 0.02).abs() < 1e-9);
        assert_eq!(point(0.9, 0.9, 0.0).ssim_error_rel(), None);
        let e = ErrorSummary::of(&[flat, steep]);
        assert!((e.ssim_rel.mean - 0.26).abs() < 1e-9);
        assert_eq!(e.ssim_rel.n, 2);
    }

    #[test]
    fn the_worst_under_prediction_is_signed() {
        let sized = |g: u32, measured: u64, predicted: u64| LooPoint {
            g,
            size_measured: Bytes(measured),
            size_predicted: Bytes(predicted),
            ..point(0.9, 0.9, 0.1)
        };
        // +20 %, −10 %, −25 % (the worst), exact.
        let pts = [
            sized(16, 1_000_000, 1_200_000),
            sized(32, 2_000_000, 1_800_000),
            sized(64, 4_000_000, 3_000_000),
            sized(128, 8_000_000, 8_000_000),
        ];
        let e = ErrorSummary::of(&pts);
        let w = e.worst_under.unwrap();
        assert_eq!(w.g, 64);
        assert!(
            (w.rel + 0.25).abs() < 1e-12 && (w.mb + 1.0).abs() < 1e-12,
            "{w:?}"
        );
        assert_eq!(e.under, 2);
        assert!((pts[0].size_error_signed_rel() - 0.2).abs() < 1e-12);
        assert!((pts[1].size_error_rel() - 0.1).abs() < 1e-12);
        // Nothing under-predicted: the smallest error is positive.
        let over = ErrorSummary::of(&pts[..1]);
        assert!(over.worst_under.unwrap().rel > 0.0);
        assert_eq!(over.under, 0);
        assert_eq!(ErrorSummary::of(&[]).worst_under, None);
    }

    #[test]
    fn the_spread_is_over_every_sample() {
        let s = |ssim: f64| Sample {
            object: "o".into(),
            g: 16,
            p: 3,
            size: Bytes(1),
            gpu: None,
            quads: None,
            ssim,
            psnr: None,
            lpips: None,
            line: 0,
        };
        let v = [s(0.7), s(0.95), s(0.8)];
        let r: Vec<&Sample> = v.iter().collect();
        assert!((ssim_spread(&r) - 0.25).abs() < 1e-12);
        assert_eq!(ssim_spread(&[]), 0.0);
    }
}
