//! Property tests of the configuration selector and its baselines on random
//! scenes: 1–12 objects, 1–60 configurations each, sizes from 1 byte to
//! 10 GB, budgets from 0 to u64::MAX.

use nerflex_core::units::{Bytes, QualityQ};
use nerflex_sim::baselines::{plan, plan_weighted, Budget, Method, Plan, PlanError};
use nerflex_sim::geometry::Geometry;
use nerflex_sim::scene_file::{ConfigEntry, Scene, SceneObject};
use proptest::prelude::*;

const G_POOL: [u32; 12] = [16, 32, 48, 64, 80, 96, 112, 128, 144, 160, 192, 256];
const P_POOL: [u32; 11] = [3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 25];
const TEN_GB: u64 = 10_000_000_000;

/// A quality that converts to fixed point exactly (raw / 2^31).
fn quality() -> impl Strategy<Value = f64> {
    (0u32..=(1 << 31)).prop_map(|raw| QualityQ::from_raw(raw).map_or(0.0, QualityQ::to_f64))
}

/// Sizes spread over 1 byte … `max` (log-uniform-ish: random digit count).
fn size(max: u64) -> impl Strategy<Value = u64> {
    (0u32..=max.ilog10()).prop_flat_map(move |digits| {
        let hi = 10u64.saturating_pow(digits + 1).min(max);
        let lo = 10u64.pow(digits).min(hi);
        lo..=hi
    })
}

/// One object: a g × p grid, ≤ `max_cfgs` configurations. A tenth of the
/// objects have holes in their grid (SLSQP then needs a profile and fails).
/// `standard`: the grid includes g = 128 and p = 17 (Block-/Single-NeRF's).
/// A third of the objects also have mesh configurations on the same grid
/// (other sizes and qualities, while they stay within `max_cfgs`), so the
/// selector chooses over the union of two geometries.
fn object(
    max_size: u64,
    max_cfgs: usize,
    standard: bool,
) -> impl Strategy<Value = Vec<ConfigEntry>> {
    (1usize..=6.min(max_cfgs))
        .prop_flat_map(move |ng| (Just(ng), 1usize..=10.min(max_cfgs / ng)))
        .prop_flat_map(move |(ng, np)| {
            (
                prop::sample::subsequence(G_POOL.to_vec(), ng),
                prop::sample::subsequence(P_POOL.to_vec(), np),
                prop::collection::vec(
                    (size(max_size), quality(), prop::bool::weighted(0.8)),
                    ng * np,
                ),
                prop::bool::weighted(0.1),
                prop::collection::vec(
                    (size(max_size), quality(), prop::bool::weighted(0.7)),
                    ng * np,
                ),
                prop::bool::weighted(0.33),
            )
        })
        .prop_map(move |(mut gs, mut ps, cells, holes, mesh_cells, mesh)| {
            if standard && !gs.contains(&128) {
                gs[0] = 128;
            }
            if standard && !ps.contains(&17) {
                ps[0] = 17;
            }
            let mut out = Vec::new();
            for (k, (s, q, keep)) in cells.into_iter().enumerate() {
                let (g, p) = (gs[k / ps.len()], ps[k % ps.len()]);
                // Keep (128, 17) in standard grids; at least one config.
                let needed = standard && g == 128 && p == 17
                    || out.is_empty() && k + 1 == gs.len() * ps.len();
                if !holes || keep || needed {
                    out.push(ConfigEntry::planes(g, p, Bytes(s), q));
                }
            }
            if mesh {
                for (k, (s, q, keep)) in mesh_cells.into_iter().enumerate() {
                    if keep && out.len() < max_cfgs {
                        out.push(ConfigEntry {
                            geometry: Geometry::Mesh,
                            ..ConfigEntry::planes(gs[k / ps.len()], ps[k % ps.len()], Bytes(s), q)
                        });
                    }
                }
            }
            out
        })
}

fn scene(max_objects: usize, max_size: u64, max_cfgs: usize) -> impl Strategy<Value = Scene> {
    prop::bool::ANY
        .prop_flat_map(move |standard| {
            prop::collection::vec(object(max_size, max_cfgs, standard), 1..=max_objects)
        })
        .prop_map(|objs| Scene {
            objects: objs
                .into_iter()
                .enumerate()
                .map(|(i, configs)| SceneObject {
                    name: format!("o{i}"),
                    configs,
                    profile: None,
                    mesh_profile: None,
                })
                .collect(),
            single: None,
        })
}

/// Budgets: 0, u64::MAX, anything, or near the scene's interesting range.
fn budget_for(scene: &Scene) -> impl Strategy<Value = u64> {
    let cheapest: u64 = scene
        .objects
        .iter()
        .map(|o| o.configs.iter().map(|c| c.size.0).min().unwrap_or(0))
        .sum();
    let dearest: u64 = scene
        .objects
        .iter()
        .map(|o| o.configs.iter().map(|c| c.size.0).max().unwrap_or(0))
        .sum();
    prop_oneof![
        1 => Just(0u64),
        1 => Just(u64::MAX),
        1 => any::<u64>(),
        2 => cheapest.saturating_sub(cheapest / 10)..=cheapest.saturating_add(cheapest / 10).max(1),
        4 => cheapest..=dearest.max(cheapest),
    ]
}

fn scene_and_budget(
    max_objects: usize,
    max_size: u64,
    max_cfgs: usize,
) -> impl Strategy<Value = (Scene, u64)> {
    scene(max_objects, max_size, max_cfgs).prop_flat_map(|s| {
        let b = budget_for(&s);
        (Just(s), b)
    })
}

/// Units the cheapest plan needs (each object's smallest size rounded up).
fn cheapest_units(scene: &Scene, unit: Bytes) -> u64 {
    scene
        .objects
        .iter()
        .map(|o| {
            o.configs
                .iter()
                .map(|c| c.size.0.div_ceil(unit.0))
                .min()
                .unwrap_or(0)
        })
        .sum()
}

/// Checks a plan's internal consistency against the scene.
fn check_consistent(scene: &Scene, p: &Plan) -> Result<(), TestCaseError> {
    if p.method == Method::Single {
        prop_assert_eq!(p.objects.len(), 1);
        return Ok(());
    }
    prop_assert_eq!(p.objects.len(), scene.objects.len());
    let mut size = 0u64;
    for (o, so) in p.objects.iter().zip(&scene.objects) {
        prop_assert_eq!(&o.name, &so.name);
        let c = &so.configs[o.config_index.expect("index")];
        prop_assert_eq!(
            (c.g, c.p, c.size.0, c.quality, c.geometry),
            (o.g, o.p, o.size_bytes, o.quality, o.geometry)
        );
        size += o.size_bytes;
    }
    prop_assert_eq!(size, p.total_size_bytes);
    prop_assert_eq!(p.feasible, p.total_units <= p.budget_units);
    if p.feasible {
        prop_assert!(p.total_size_bytes <= p.budget_bytes);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Large random scenes: the DP stays within budget, never panics, fails
    /// exactly when the cheapest plan does not fit, and no baseline's
    /// feasible plan beats it.
    #[test]
    fn dp_is_within_budget_and_beats_every_feasible_baseline(
        (scene, budget) in scene_and_budget(12, TEN_GB, 60),
    ) {
        let budget = Budget::new(Bytes(budget));
        let dp = plan(Method::Dp, &scene, budget);
        let fits = cheapest_units(&scene, budget.unit) <= budget.units();
        match &dp {
            Ok(p) => {
                prop_assert!(fits);
                prop_assert!(p.feasible);
                prop_assert!(p.total_size_bytes <= budget.total.0);
                prop_assert!(p.total_units <= budget.units());
                check_consistent(&scene, p)?;
            }
            Err(PlanError::Infeasible { cheapest_total, budget: b }) => {
                prop_assert!(!fits);
                prop_assert!(cheapest_total > b);
            }
            Err(PlanError::UnitTooCoarse { .. }) => prop_assert!(!fits),
            Err(e) => prop_assert!(false, "unexpected DP error: {e}"),
        }
        for method in [Method::Fairness, Method::Slsqp, Method::Greedy, Method::Block, Method::Single] {
            match plan(method, &scene, budget) {
                Ok(p) => {
                    check_consistent(&scene, &p)?;
                    if p.feasible {
                        let dp = dp.as_ref().map_err(|e| TestCaseError::fail(format!("{method} feasible but DP failed: {e}")))?;
                        prop_assert!(
                            dp.total_quality_q >= p.total_quality_q,
                            "{} beat the DP: {} > {}", method, p.total_quality, dp.total_quality
                        );
                    }
                }
                Err(e) => {
                    // Optimising baselines may fail; the error must say why.
                    prop_assert!(!e.to_string().is_empty());
                }
            }
        }
    }

    /// Small scenes: the DP's quality and total units equal brute force's.
    #[test]
    fn dp_equals_brute_force_on_small_cases(
        (scene, budget) in scene_and_budget(4, 5_000, 8),
    ) {
        let budget = Budget::new(Bytes(budget));
        let dp = plan(Method::Dp, &scene, budget);
        let brute = plan(Method::Brute, &scene, budget);
        match (&dp, &brute) {
            (Ok(d), Ok(b)) => {
                prop_assert_eq!(d.total_quality_q, b.total_quality_q);
                prop_assert_eq!(d.total_units, b.total_units);
                check_consistent(&scene, d)?;
                check_consistent(&scene, b)?;
            }
            (Err(d), Err(b)) => prop_assert_eq!(d, b),
            _ => prop_assert!(false, "dp {:?} vs brute {:?}", dp, brute),
        }
    }

    /// Small scenes in a unit of 1 byte: the rounded problem is the exact
    /// one, so the DP is the true optimum in bytes.
    #[test]
    fn dp_is_exact_in_bytes_with_a_one_byte_unit(
        (scene, budget) in scene_and_budget(3, 300, 6),
    ) {
        let budget = Budget::with_unit(Bytes(budget.min(3_000)), Bytes(1));
        let dp = plan(Method::Dp, &scene, budget);
        // Exhaustive in bytes, independent of the crate.
        let mut best: Option<u64> = None;
        let counts: Vec<usize> = scene.objects.iter().map(|o| o.configs.len()).collect();
        let mut idx = vec![0usize; counts.len()];
        'all: loop {
            let size: u64 = idx.iter().zip(&scene.objects).map(|(&j, o)| o.configs[j].size.0).sum();
            let q: u64 = idx.iter().zip(&scene.objects)
                .map(|(&j, o)| QualityQ::from_f64(o.configs[j].quality).map_or(0, |q| q.raw() as u64)).sum();
            if size <= budget.total.0 {
                best = Some(best.map_or(q, |b| b.max(q)));
            }
            for k in 0..idx.len() {
                idx[k] += 1;
                if idx[k] < counts[k] { continue 'all; }
                idx[k] = 0;
            }
            break;
        }
        match (dp, best) {
            (Ok(p), Some(q)) => prop_assert_eq!(p.total_quality_q.0, q),
            (Err(_), None) => {}
            (dp, best) => prop_assert!(false, "dp {:?} vs exhaustive {:?}", dp, best),
        }
    }

    /// Scenes with both geometries: the DP over the union never plans
    /// worse than over either geometry alone (each a sub-problem of the
    /// union), and never exceeds the budget.
    #[test]
    fn union_of_geometries_is_never_worse_than_either_alone(
        (scene, budget) in scene_and_budget(6, TEN_GB, 40),
    ) {
        let budget = Budget::new(Bytes(budget));
        let only = |g: Geometry| -> Option<Scene> {
            let objects: Vec<SceneObject> = scene.objects.iter().map(|o| SceneObject {
                configs: o.configs.iter().filter(|c| c.geometry == g).copied().collect(),
                ..o.clone()
            }).collect();
            // A geometry alone is a problem only if every object has it.
            objects.iter().all(|o| !o.configs.is_empty()).then_some(Scene { objects, single: None })
        };
        let union = plan(Method::Dp, &scene, budget);
        if let Ok(u) = &union {
            prop_assert!(u.feasible && u.total_size_bytes <= budget.total.0);
            check_consistent(&scene, u)?;
        }
        for g in Geometry::ALL {
            let Some(alone) = only(g) else { continue };
            if let Ok(a) = plan(Method::Dp, &alone, budget) {
                let u = union.as_ref().map_err(|e| TestCaseError::fail(format!("{g} alone plans but the union fails: {e}")))?;
                prop_assert!(u.total_quality_q >= a.total_quality_q, "{} alone {} beat the union {}", g, a.total_quality, u.total_quality);
            }
        }
    }

    /// Weighted objectives (`--objective area`): the DP stays within the
    /// budget, reports the scene's unweighted qualities, and its weighted
    /// sum is the exhaustive optimum of the weighted problem (in budget
    /// units, to the fixed point's rounding of each weighted quality).
    #[test]
    fn weighted_dp_is_the_weighted_optimum_and_reports_unweighted_quality(
        ((scene, budget), weights) in scene_and_budget(4, 5_000, 8).prop_flat_map(|(s, b)| {
            let n = s.objects.len();
            (Just((s, b)), prop::collection::vec(1u32..=1_000, n))
        }),
    ) {
        let max = *weights.iter().max().unwrap_or(&1) as f64;
        let w: Vec<f64> = weights.iter().map(|&x| x as f64 / max).collect();
        let budget = Budget::new(Bytes(budget));
        let dp = plan_weighted(Method::Dp, &scene, budget, &w);
        let value = |idx: &[usize]| -> f64 {
            idx.iter().zip(&scene.objects).zip(&w).map(|((&j, o), w)| w * o.configs[j].quality).sum()
        };
        let counts: Vec<usize> = scene.objects.iter().map(|o| o.configs.len()).collect();
        let mut idx = vec![0usize; counts.len()];
        let mut best: Option<f64> = None;
        'all: loop {
            let units: u64 = idx.iter().zip(&scene.objects)
                .map(|(&j, o)| o.configs[j].size.0.div_ceil(budget.unit.0)).sum();
            if units <= budget.units() {
                best = Some(best.map_or(value(&idx), |b| b.max(value(&idx))));
            }
            for k in 0..idx.len() {
                idx[k] += 1;
                if idx[k] < counts[k] { continue 'all; }
                idx[k] = 0;
            }
            break;
        }
        match (&dp, best) {
            (Ok(p), Some(b)) => {
                prop_assert!(p.feasible && p.total_size_bytes <= budget.total.0);
                check_consistent(&scene, p)?;
                let chosen: Vec<usize> = p.objects.iter().map(|o| o.config_index.unwrap_or(0)).collect();
                let tol = 1e-8 * scene.objects.len() as f64;
                prop_assert!(value(&chosen) >= b - tol, "weighted {} < optimum {}", value(&chosen), b);
                let sum: f64 = p.objects.iter().map(|o| o.quality).sum();
                prop_assert!((p.total_quality - sum).abs() < 1e-9);
            }
            (Err(_), None) => {}
            _ => prop_assert!(false, "dp {:?} vs exhaustive {:?}", dp, best),
        }
    }
}
