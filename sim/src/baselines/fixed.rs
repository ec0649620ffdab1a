//! Baselines that do not optimise: Block-NeRF and Single-NeRF.
//!
//! Both always return their plan; `feasible` says whether it fits. Both use
//! planes configurations only (MobileNeRF's default geometry), whatever
//! else the scene offers.
//!
//! **Single-NeRF** is one network for the whole scene at (128, 17). If the
//! scene file has a top-level `"single"` entry (measured configurations of
//! that network), its (128, 17) configuration is used. Otherwise it is
//! derived from the objects' own tables: one 128³ grid spread over n objects
//! gives each about 128³/n voxels, i.e. an effective grid of `128/∛n` per
//! axis, so each object is taken at its largest measured g ≤ 128/∛n (the
//! smallest g if none is that small) with p = 17. The network's size is the
//! sum of those sizes, its SSIM their mean. This is optimistic for
//! Single-NeRF: it assumes the objects fill the scene's bounding box (empty
//! space between them would waste voxels) and ignores the loss from sharing
//! one MLP. The evaluation issue replaces it with measured Single-NeRF bakes.
//! Feasibility of a derived network counts each object's part rounded up
//! to the unit, like every other method; a measured one rounds its total.

use super::problem::{Cand, Problem};
use super::{Method, Plan, PlanError, PlannedObject, DEFAULT_G, DEFAULT_P};
use crate::geometry::Geometry;
use nerflex_core::units::{Bytes, QualityQ, QualitySum};

/// Block-NeRF: every object at (128, 17).
pub(crate) fn block(problem: &Problem) -> Result<Plan, PlanError> {
    let choices = problem
        .objects
        .iter()
        .map(|o| {
            o.cands
                .iter()
                .position(|c| c.g == DEFAULT_G && c.p == DEFAULT_P && c.geometry.is_planes())
                .ok_or_else(|| PlanError::MissingConfig {
                    method: Method::Block,
                    object: o.name().to_string(),
                    g: DEFAULT_G,
                    p: DEFAULT_P,
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    problem.plan(Method::Block, &choices)
}

/// Effective per-object grid of one 128³ network shared by `n` objects.
pub fn effective_grid(n: usize) -> f64 {
    DEFAULT_G as f64 / (n.max(1) as f64).cbrt()
}

/// Single-NeRF: one network for the whole scene at (128, 17).
pub(crate) fn single(problem: &Problem) -> Result<Plan, PlanError> {
    let n = problem.objects.len();
    if let Some(entry) = &problem.scene.single {
        let (index, c) = entry
            .configs
            .iter()
            .enumerate()
            .find(|(_, c)| c.g == DEFAULT_G && c.p == DEFAULT_P && c.geometry.is_planes())
            .ok_or_else(|| PlanError::MissingConfig {
                method: Method::Single,
                object: entry.name.clone(),
                g: DEFAULT_G,
                p: DEFAULT_P,
            })?;
        let q = QualityQ::from_f64(c.quality).map_err(|_| PlanError::BadQuality {
            object: entry.name.clone(),
            g: c.g,
            p: c.p,
            value: c.quality,
        })?;
        let units = c.size.units_ceil(problem.unit).unwrap_or(u64::MAX);
        let total_q = QualitySum(q.raw() as u64 * n as u64);
        return Ok(single_plan(
            problem,
            &entry.name,
            c.size,
            c.quality,
            n as f64 * c.quality,
            total_q,
            units,
            Some(index),
        ));
    }
    // Derived: each object at its largest g <= 128/∛n with p = 17.
    let g_eff = effective_grid(n);
    let mut parts: Vec<Cand> = Vec::with_capacity(n);
    for o in &problem.objects {
        let at_p: Vec<&Cand> = o
            .cands
            .iter()
            .filter(|c| c.p == DEFAULT_P && c.geometry.is_planes())
            .collect();
        let below = at_p
            .iter()
            .filter(|c| c.g as f64 <= g_eff + 1e-9)
            .max_by_key(|c| (c.g, std::cmp::Reverse(c.index)));
        let pick = below
            .or_else(|| at_p.iter().min_by_key(|c| (c.g, c.index)))
            .ok_or_else(|| PlanError::MissingConfig {
                method: Method::Single,
                object: o.name().to_string(),
                g: g_eff.floor() as u32,
                p: DEFAULT_P,
            })?;
        parts.push(**pick);
    }
    let size = parts
        .iter()
        .fold(Bytes::ZERO, |s, c| s.saturating_add(c.size));
    let units = parts.iter().fold(0u64, |s, c| s.saturating_add(c.units));
    let total_q = parts
        .iter()
        .fold(QualitySum::ZERO, |s, c| s.saturating_add(c.q));
    let total_quality: f64 = parts.iter().map(|c| c.quality).sum();
    Ok(single_plan(
        problem,
        "single",
        size,
        total_quality / n as f64,
        total_quality,
        total_q,
        units,
        None,
    ))
}

#[allow(clippy::too_many_arguments)]
fn single_plan(
    problem: &Problem,
    name: &str,
    size: Bytes,
    quality: f64,
    total_quality: f64,
    total_quality_q: QualitySum,
    units: u64,
    config_index: Option<usize>,
) -> Plan {
    Plan {
        method: Method::Single,
        device: None,
        budget_bytes: problem.budget.0,
        feasible: units <= problem.budget_units && size <= problem.budget,
        objects: vec![PlannedObject {
            name: name.to_string(),
            g: DEFAULT_G,
            p: DEFAULT_P,
            size_bytes: size.0,
            quality,
            geometry: Geometry::Planes,
            config_index,
        }],
        total_size_bytes: size.0,
        total_quality,
        total_quality_q,
        total_units: units,
        budget_units: problem.budget_units,
        unit_bytes: problem.unit.0,
    }
}
