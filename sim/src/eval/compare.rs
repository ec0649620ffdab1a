//! The statistics of an evaluation's rows: each (scene, device, method)'s
//! means with 95 % bootstrap intervals over the held-out views, and paired
//! differences NeRFlex (DP) − each other method over the same views, for
//! the whole image and for each scene object in its box.

use super::stats::{bootstrap_mean, paired_difference, Interval};
use super::{Row, SceneReport};
use crate::baselines::Method;
use crate::pipeline::views::ViewScores;

/// A per-view metric.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metric {
    /// SSIM (higher is better).
    Ssim,
    /// PSNR, dB (higher is better).
    Psnr,
    /// LPIPS (lower is better).
    Lpips,
}

impl Metric {
    /// All three, in report order.
    pub const ALL: [Metric; 3] = [Metric::Ssim, Metric::Psnr, Metric::Lpips];

    /// The column name.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Ssim => "SSIM",
            Metric::Psnr => "PSNR dB",
            Metric::Lpips => "LPIPS",
        }
    }

    /// Decimals to print.
    pub fn digits(self) -> usize {
        match self {
            Metric::Psnr => 2,
            _ => 4,
        }
    }

    /// Whether a larger value is better.
    pub fn higher_is_better(self) -> bool {
        !matches!(self, Metric::Lpips)
    }

    fn of(self, v: &ViewScores) -> Option<f64> {
        match self {
            Metric::Ssim => Some(v.ssim),
            Metric::Psnr => Some(v.psnr),
            Metric::Lpips => v.lpips,
        }
    }
}

/// The key of a view: its source capture (composites) and index.
fn key(v: &ViewScores) -> (Option<&str>, usize) {
    (v.source.as_deref(), v.view)
}

/// A row's per-view values of `metric` (empty when it has none).
pub fn series(row: &Row, metric: Metric) -> Vec<f64> {
    row.views.iter().filter_map(|v| metric.of(v)).collect()
}

/// A row's mean of `metric` with its interval over the views.
pub fn interval(row: &Row, metric: Metric) -> Option<Interval> {
    bootstrap_mean(&series(row, metric))
}

/// Values of both rows over the views they share, in order.
fn pairs(a: &Row, b: &Row, f: impl Fn(&ViewScores) -> Option<f64>) -> (Vec<f64>, Vec<f64>) {
    let (mut xa, mut xb) = (Vec::new(), Vec::new());
    for va in &a.views {
        if let Some(vb) = b.views.iter().find(|vb| key(vb) == key(va)) {
            if let (Some(x), Some(y)) = (f(va), f(vb)) {
                xa.push(x);
                xb.push(y);
            }
        }
    }
    (xa, xb)
}

/// `a − b` of `metric`, paired over the views both rows measured.
pub fn paired(a: &Row, b: &Row, metric: Metric) -> Option<Interval> {
    let (xa, xb) = pairs(a, b, |v| metric.of(v));
    paired_difference(&xa, &xb)
}

/// One scene object's SSIM in its box, per view of a row.
pub fn object_series(row: &Row, object: &str) -> Vec<f64> {
    row.views
        .iter()
        .filter_map(|v| v.objects.iter().find(|o| o.object == object))
        .map(|o| o.ssim)
        .collect()
}

/// One scene object's SSIM in its box: `a − b`, paired over the views
/// where both rows scored it.
pub fn paired_object(a: &Row, b: &Row, object: &str) -> Option<Interval> {
    let get = |v: &ViewScores| {
        v.objects
            .iter()
            .find(|o| o.object == object)
            .map(|o| o.ssim)
    };
    let (xa, xb) = pairs(a, b, get);
    paired_difference(&xa, &xb)
}

/// The row of (device, method) in a scene, if it was measured.
pub fn measured<'a>(s: &'a SceneReport, device: &str, method: Method) -> Option<&'a Row> {
    s.rows
        .iter()
        .find(|r| r.device == device && r.method == method && r.error.is_none())
        .filter(|r| !r.views.is_empty())
}

/// Whether two rows baked exactly the same configurations (their
/// difference is zero by construction, not by measurement).
pub fn same_plan(a: &Row, b: &Row) -> bool {
    a.objects.len() == b.objects.len()
        && a.objects
            .iter()
            .zip(&b.objects)
            .all(|(x, y)| x.name == y.name && x.g == y.g && x.p == y.p && x.asset == y.asset)
}

/// The devices of a scene, in row order.
pub fn devices(s: &SceneReport) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for r in &s.rows {
        if !v.contains(&r.device) {
            v.push(r.device.clone());
        }
    }
    v
}

/// The scene objects scored in a scene's rows, in first-seen order.
pub fn scored_objects(s: &SceneReport) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for o in s
        .rows
        .iter()
        .flat_map(|r| &r.views)
        .flat_map(|vw| &vw.objects)
    {
        if !v.contains(&o.object) {
            v.push(o.object.clone());
        }
    }
    v
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::pipeline::views::ObjectScores;
    use crate::pipeline::RealisedObject;

    /// A row with the given per-view SSIMs (PSNR = 20·SSIM, no LPIPS) and
    /// object `o` at SSIM − 0.1 in every view.
    pub(crate) fn row(device: &str, method: Method, ssim: &[f64]) -> Row {
        Row {
            scene: "s".into(),
            device: device.into(),
            method,
            error: None,
            budget_bytes: 150_000_000,
            planned_feasible: true,
            predicted_bytes: 0,
            file_bytes: 0,
            plan_s: 0.0,
            replans: 0,
            objects: vec![RealisedObject {
                name: "o".into(),
                g: 64,
                p: 9,
                geometry: Default::default(),
                predicted_bytes: 0,
                file_bytes: 1_000_000,
                gpu_bytes: 0,
                quads: 0,
                predicted_ssim: 0.0,
                ssim: 0.0,
                psnr: 0.0,
                lpips: None,
                asset: format!("{method}").into(),
            }],
            quality: None,
            load_failure: None,
            over_soft_limit: false,
            mean_fps: 30.0,
            steady_fps: 30.0,
            loaded_at_s: None,
            raster_ms: 0.0,
            shade_ms: 0.0,
            quads: 0,
            views: ssim
                .iter()
                .enumerate()
                .map(|(i, &s)| ViewScores {
                    view: i,
                    source: None,
                    ssim: s,
                    psnr: 20.0 * s,
                    lpips: None,
                    objects: vec![ObjectScores {
                        object: "o".into(),
                        ssim: s - 0.1,
                        psnr: 0.0,
                        pixels: 100,
                    }],
                })
                .collect(),
        }
    }

    #[test]
    fn paired_differences_follow_the_views() {
        let a = row("d", Method::Dp, &[0.90, 0.80, 0.85, 0.95]);
        let b = row("d", Method::Single, &[0.88, 0.78, 0.83, 0.93]);
        let d = paired(&a, &b, Metric::Ssim).unwrap();
        assert!((d.mean - 0.02).abs() < 1e-9 && d.lo > 0.019, "{d:?}");
        let p = paired(&a, &b, Metric::Psnr).unwrap();
        assert!((p.mean - 0.4).abs() < 1e-9, "{p:?}");
        assert!(paired(&a, &b, Metric::Lpips).is_none());
        let o = paired_object(&a, &b, "o").unwrap();
        assert!((o.mean - 0.02).abs() < 1e-9);
        assert!(paired_object(&a, &b, "missing").is_none());
        // Unpaired, the same scores overlap: the views scatter by 0.15.
        let (ia, ib) = (
            interval(&a, Metric::Ssim).unwrap(),
            interval(&b, Metric::Ssim).unwrap(),
        );
        assert!(ia.lo < ib.hi, "{ia:?} {ib:?}");
        assert_eq!(object_series(&a, "o").len(), 4);
    }

    #[test]
    fn only_shared_views_are_paired() {
        let a = row("d", Method::Dp, &[0.9, 0.8, 0.7]);
        let mut b = row("d", Method::Fairness, &[0.9, 0.8, 0.7]);
        b.views.remove(1);
        let d = paired(&a, &b, Metric::Ssim).unwrap();
        assert_eq!((d.n, d.mean), (2, 0.0));
        assert!(!same_plan(&a, &b));
        let mut c = b.clone();
        c.method = Method::Dp;
        c.objects = a.objects.clone();
        assert!(same_plan(&a, &c));
    }
}
