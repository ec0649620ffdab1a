//! The planning problem every method solves: the scene's configurations with
//! sizes rounded up to the budget unit and qualities in fixed point.

use super::{Budget, Method, Plan, PlanError, PlannedObject};
use crate::geometry::Geometry;
use crate::scene_file::{Scene, SceneObject, MAX_CONFIGS};
use nerflex_core::units::{Bytes, QualityQ, QualitySum};

/// One configuration, ready for planning.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cand {
    /// Index in the scene object's `configs`.
    pub index: usize,
    pub g: u32,
    pub p: u32,
    pub size: Bytes,
    /// `size` in budget units, rounded up.
    pub units: u64,
    pub q: QualityQ,
    /// The scene's SSIM value (for output).
    pub quality: f64,
    pub geometry: Geometry,
}

/// One object, ready for planning.
#[derive(Clone, Debug)]
pub(crate) struct Obj<'s> {
    pub entry: &'s SceneObject,
    /// Never empty.
    pub cands: Vec<Cand>,
    cheapest: Cand,
}

impl Obj<'_> {
    pub fn name(&self) -> &str {
        &self.entry.name
    }

    /// The configuration with fewest units, then best quality, then fewest
    /// bytes, then lowest index.
    pub fn cheapest(&self) -> Cand {
        self.cheapest
    }

    /// Best configuration with at most `units` units (quality, then fewer
    /// units, bytes, index), if any.
    pub fn best_within(&self, units: u64) -> Option<Cand> {
        let mut best: Option<Cand> = None;
        for c in self.cands.iter().filter(|c| c.units <= units) {
            best = match best {
                Some(b) if !better(c, &b) => Some(b),
                _ => Some(*c),
            };
        }
        best
    }
}

/// `a` beats `b`: higher quality, then fewer units, fewer bytes, lower index.
pub(crate) fn better(a: &Cand, b: &Cand) -> bool {
    (a.q, std::cmp::Reverse((a.units, a.size, a.index)))
        > (b.q, std::cmp::Reverse((b.units, b.size, b.index)))
}

/// The quantized problem.
#[derive(Clone, Debug)]
pub(crate) struct Problem<'s> {
    pub scene: &'s Scene,
    pub budget: Bytes,
    pub unit: Bytes,
    /// `⌊budget / unit⌋`.
    pub budget_units: u64,
    pub objects: Vec<Obj<'s>>,
}

impl<'s> Problem<'s> {
    /// Validates the scene (non-empty, qualities in [0, 1], at most 256
    /// configurations per object) and rounds sizes up to the unit.
    pub fn new(scene: &'s Scene, budget: Budget) -> Result<Problem<'s>, PlanError> {
        if budget.unit.0 == 0 {
            return Err(PlanError::ZeroUnit);
        }
        if scene.objects.is_empty() {
            return Err(PlanError::EmptyScene);
        }
        let objects = scene
            .objects
            .iter()
            .map(|o| obj(o, budget.unit))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Problem {
            scene,
            budget: budget.total,
            unit: budget.unit,
            budget_units: budget.total.0 / budget.unit.0,
            objects,
        })
    }

    /// Errors unless the cheapest configuration of every object fits.
    pub fn check_cheapest_fits(&self) -> Result<(), PlanError> {
        let mut bytes: Option<u64> = Some(0);
        let mut units: u64 = 0;
        for o in &self.objects {
            let min_bytes = o.cands.iter().map(|c| c.size.0).min().unwrap_or(0);
            bytes = bytes.and_then(|b| b.checked_add(min_bytes));
            units = units.saturating_add(o.cheapest().units);
        }
        if units <= self.budget_units {
            return Ok(());
        }
        match bytes {
            Some(b) if b <= self.budget.0 => Err(PlanError::UnitTooCoarse {
                cheapest_total: Bytes(b),
                cheapest_rounded: Bytes(units.saturating_mul(self.unit.0)),
                budget: self.budget,
                unit: self.unit,
            }),
            b => Err(PlanError::Infeasible {
                cheapest_total: Bytes(b.unwrap_or(u64::MAX)),
                budget: self.budget,
            }),
        }
    }

    /// The plan that uses `choice[i]` (an index into `objects[i].cands`).
    pub fn plan(&self, method: Method, choice: &[usize]) -> Result<Plan, PlanError> {
        let mut objects = Vec::with_capacity(self.objects.len());
        let mut total_size = Bytes::ZERO;
        let mut total_units: u64 = 0;
        let mut total_q = QualitySum::ZERO;
        let mut total_quality = 0.0;
        if choice.len() != self.objects.len() {
            return Err(PlanError::Internal(format!(
                "{method}: wrong number of choices"
            )));
        }
        for (o, &k) in self.objects.iter().zip(choice) {
            let c = o
                .cands
                .get(k)
                .ok_or_else(|| PlanError::Internal(format!("{method}: choice out of range")))?;
            objects.push(PlannedObject {
                name: o.name().to_string(),
                g: c.g,
                p: c.p,
                size_bytes: c.size.0,
                quality: c.quality,
                geometry: c.geometry,
                config_index: Some(c.index),
            });
            total_size = total_size.saturating_add(c.size);
            total_units = total_units.saturating_add(c.units);
            total_q = total_q.saturating_add(c.q);
            total_quality += c.quality;
        }
        Ok(Plan {
            method,
            device: None,
            budget_bytes: self.budget.0,
            feasible: total_units <= self.budget_units && total_size <= self.budget,
            objects,
            total_size_bytes: total_size.0,
            total_quality,
            total_quality_q: total_q,
            total_units,
            budget_units: self.budget_units,
            unit_bytes: self.unit.0,
        })
    }
}

fn obj(o: &SceneObject, unit: Bytes) -> Result<Obj<'_>, PlanError> {
    if o.configs.is_empty() {
        return Err(PlanError::NoConfigs {
            object: o.name.clone(),
        });
    }
    if o.configs.len() > MAX_CONFIGS {
        return Err(PlanError::TooManyConfigs {
            object: o.name.clone(),
            configs: o.configs.len(),
        });
    }
    let cands = o
        .configs
        .iter()
        .enumerate()
        .map(|(index, c)| {
            let q = QualityQ::from_f64(c.quality).map_err(|_| PlanError::BadQuality {
                object: o.name.clone(),
                g: c.g,
                p: c.p,
                value: c.quality,
            })?;
            Ok(Cand {
                index,
                g: c.g,
                p: c.p,
                size: c.size,
                units: c.size.units_ceil(unit).unwrap_or(u64::MAX),
                q,
                quality: c.quality,
                geometry: c.geometry,
            })
        })
        .collect::<Result<Vec<_>, PlanError>>()?;
    let cheapest = *cands
        .iter()
        .min_by_key(|c| (c.units, std::cmp::Reverse(c.q), c.size, c.index))
        .ok_or_else(|| PlanError::NoConfigs {
            object: o.name.clone(),
        })?;
    Ok(Obj {
        entry: o,
        cands,
        cheapest,
    })
}
