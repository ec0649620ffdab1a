//! What the selectors maximise: the paper's sum of per-network SSIM, or
//! the same with each network weighted by its share of the scene's pixels.
//!
//! The paper scores each network on its own training views. A dedicated
//! network's views are crops enlarged by its segmentation's zoom (×3–6 in
//! our scenes), so one unit of its SSIM covers about `1 / zoom²` of the
//! pixels that a unit of the shared network's SSIM (original frames)
//! covers. Summing them with equal weights lets the selector buy a small
//! SSIM gain on a heavily enlarged crop at the price of a larger loss on
//! the frame (measured in `results/eval/objective-check.md`: the
//! equal-weight sum predicted the scene-SSIM differences between plans
//! with r = +0.04, the `1 / zoom²` weighting with r = +0.95).
//!
//! [`Objective::Area`] plans on that weighted sum. Plans still *report*
//! each object's unweighted predicted SSIM and their sum, so reports and
//! tables read the same under either objective; only the choice differs.
//! Fairness splits the budget before it looks at qualities and picks each
//! object's best within its share, so a positive per-object weight cannot
//! change its plan; Block-NeRF and Single-NeRF do not optimise.

use super::{plan, Budget, Method, Plan, PlanError};
use crate::scene_file::{Profile, Scene};
use nerflex_core::units::{QualityQ, QualitySum};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The selectors' objective.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// The paper's: the sum of each network's predicted SSIM on its own views.
    #[default]
    Mean,
    /// Each network's predicted SSIM weighted by `1 / zoom²`, its
    /// segmentation's mean enlargement (1 for the shared network): the
    /// sum then counts every network per pixel of the original frames.
    Area,
}

impl Objective {
    /// The name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Objective::Mean => "mean",
            Objective::Area => "area",
        }
    }

    /// Each object's weight from its network's mean zoom (`zooms` by scene
    /// object name; a name not listed is a network on original frames,
    /// zoom 1), scaled so the largest weight is 1. All 1 for
    /// [`Objective::Mean`].
    pub fn weights(self, scene: &Scene, zooms: &[(String, f64)]) -> Result<Vec<f64>, String> {
        let raw = scene
            .objects
            .iter()
            .map(|o| match self {
                Objective::Mean => Ok(1.0),
                Objective::Area => {
                    let zoom = zooms
                        .iter()
                        .find(|(n, _)| *n == o.name)
                        .map_or(1.0, |&(_, z)| z);
                    if zoom.is_finite() && zoom > 0.0 {
                        Ok(1.0 / (zoom * zoom))
                    } else {
                        Err(format!(
                            "object `{}`: zoom {zoom} is not a positive number",
                            o.name
                        ))
                    }
                }
            })
            .collect::<Result<Vec<f64>, String>>()?;
        let max = raw.iter().copied().fold(0.0_f64, f64::max);
        Ok(raw
            .into_iter()
            .map(|w| if max > 0.0 { w / max } else { 1.0 })
            .collect())
    }
}

impl fmt::Display for Objective {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `scene` with each object's qualities (its configurations and its
/// profiles' quality curves) multiplied by its weight.
fn weighted(scene: &Scene, weights: &[f64]) -> Scene {
    let scale = |p: &Profile, w: f64| {
        let mut p = p.clone();
        // Q = m − k / V is linear in (m, k).
        p.quality.m *= w;
        p.quality.k *= w;
        p
    };
    let mut out = scene.clone();
    for (o, &w) in out.objects.iter_mut().zip(weights) {
        for c in &mut o.configs {
            c.quality *= w;
        }
        o.profile = o.profile.as_ref().map(|p| scale(p, w));
        o.mesh_profile = o.mesh_profile.as_ref().map(|p| scale(p, w));
    }
    out
}

/// Plans `scene` with `method` maximising the sum of `weights[i]` × object
/// i's quality (`weights` in scene object order, each in `(0, 1]`; all 1 is
/// [`plan`] exactly). The plan reports the scene's unweighted qualities.
pub fn plan_weighted(
    method: Method,
    scene: &Scene,
    budget: Budget,
    weights: &[f64],
) -> Result<Plan, PlanError> {
    if weights.len() != scene.objects.len() {
        return Err(PlanError::Internal(format!(
            "{} weights for {} objects",
            weights.len(),
            scene.objects.len()
        )));
    }
    if let Some(w) = weights
        .iter()
        .find(|w| !(w.is_finite() && **w > 0.0 && **w <= 1.0))
    {
        return Err(PlanError::Internal(format!(
            "objective weight {w} is not in (0, 1]"
        )));
    }
    let fixed = matches!(method, Method::Block | Method::Single);
    if fixed || weights.iter().all(|&w| w == 1.0) {
        return plan(method, scene, budget);
    }
    let mut p = plan(method, &weighted(scene, weights), budget)?;
    // Report what the profiles predict, not the weighted values.
    let mut total = 0.0;
    let mut total_q = QualitySum::ZERO;
    for po in &mut p.objects {
        let c = scene
            .objects
            .iter()
            .find(|o| o.name == po.name)
            .zip(po.config_index)
            .and_then(|(o, i)| o.configs.get(i))
            .ok_or_else(|| {
                PlanError::Internal(format!("object `{}` lost its configuration", po.name))
            })?;
        po.quality = c.quality;
        total += c.quality;
        total_q = total_q.saturating_add(QualityQ::saturating_from_f64(c.quality));
    }
    p.total_quality = total;
    p.total_quality_q = total_q;
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::{ConfigEntry, SceneObject};
    use nerflex_core::units::Bytes;

    fn object(name: &str, configs: &[(u32, u64, f64)]) -> SceneObject {
        SceneObject {
            name: name.into(),
            configs: configs
                .iter()
                .map(|&(g, mb, q)| ConfigEntry::planes(g, 5, Bytes(mb * 1_000_000), q))
                .collect(),
            profile: None,
            mesh_profile: None,
        }
    }

    /// A shared network on full frames and a dedicated one on crops
    /// enlarged ×4: the equal-weight sum buys the crop's +0.03 for
    /// 20 MB; weighted by 1/16 that is worth less than the frame's +0.01.
    fn scene() -> Scene {
        Scene {
            objects: vec![
                object("shared", &[(32, 10, 0.95), (64, 30, 0.96)]),
                object("crop", &[(32, 10, 0.80), (64, 30, 0.83)]),
            ],
            single: None,
        }
    }

    fn zooms() -> Vec<(String, f64)> {
        vec![("crop".into(), 4.0)]
    }

    #[test]
    fn weights_are_inverse_squared_zoom_scaled_to_one() {
        let s = scene();
        assert_eq!(Objective::Mean.weights(&s, &zooms()).unwrap(), [1.0, 1.0]);
        assert_eq!(
            Objective::Area.weights(&s, &zooms()).unwrap(),
            [1.0, 1.0 / 16.0]
        );
        let err = Objective::Area
            .weights(&s, &[("crop".into(), 0.0)])
            .unwrap_err();
        assert!(err.contains("crop"), "{err}");
    }

    #[test]
    fn area_weighting_moves_the_budget_to_the_frame_and_reports_unweighted_ssim() {
        let s = scene();
        let budget = Budget::new(Bytes(40_000_000));
        let mean = plan(Method::Dp, &s, budget).unwrap();
        let w = Objective::Area.weights(&s, &zooms()).unwrap();
        let area = plan_weighted(Method::Dp, &s, budget, &w).unwrap();
        let gs = |p: &Plan| p.objects.iter().map(|o| o.g).collect::<Vec<_>>();
        assert_eq!(gs(&mean), [32, 64]);
        assert_eq!(gs(&area), [64, 32]);
        assert_eq!(area.objects[0].quality, 0.96);
        assert_eq!(area.objects[1].quality, 0.80);
        assert!((area.total_quality - 1.76).abs() < 1e-12);
        // The brute force agrees under the same weights.
        let brute = plan_weighted(Method::Brute, &s, budget, &w).unwrap();
        assert_eq!(gs(&brute), gs(&area));
        // Equal weights are the paper's plan, bit for bit.
        let same = plan_weighted(Method::Dp, &s, budget, &[1.0, 1.0]).unwrap();
        assert_eq!(same, mean);
    }

    #[test]
    fn fairness_does_not_depend_on_the_weights() {
        let s = scene();
        let budget = Budget::new(Bytes(80_000_000));
        assert_eq!(
            plan_weighted(Method::Fairness, &s, budget, &[1.0, 0.01]).unwrap(),
            plan(Method::Fairness, &s, budget).unwrap()
        );
    }

    #[test]
    fn weighting_scales_the_profiles_quality_curve_too() {
        // SLSQP relaxes over the profile, not the configurations.
        let params = |k: f64, m: f64| crate::scene_file::ModelParams {
            k,
            a: 1.0,
            b: 0.5,
            c: 0.0,
            m,
            family: nerflex_core::profiler::Family::Volume,
        };
        let mut s = scene();
        s.objects[1].profile = Some(Profile {
            size: params(2.0, 1e6),
            quality: params(3.0e4, 0.9),
            g: vec![32, 64],
            p: vec![5],
        });
        let w = weighted(&s, &[1.0, 0.25]);
        let (a, b) = (
            s.objects[1].profile.as_ref().unwrap(),
            w.objects[1].profile.as_ref().unwrap(),
        );
        for (g, p) in [(32.0, 5.0), (50.0, 9.0)] {
            assert!((b.quality_at(g, p) - 0.25 * a.quality_at(g, p)).abs() < 1e-12);
            assert_eq!(b.size_at(g, p), a.size_at(g, p));
        }
        assert_eq!(w.objects[0], s.objects[0]);
    }

    #[test]
    fn bad_weights_are_errors_not_plans() {
        let s = scene();
        let budget = Budget::new(Bytes(80_000_000));
        for w in [
            vec![1.0],
            vec![1.0, 0.0],
            vec![1.0, f64::NAN],
            vec![2.0, 1.0],
        ] {
            assert!(plan_weighted(Method::Dp, &s, budget, &w).is_err(), "{w:?}");
        }
    }
}
