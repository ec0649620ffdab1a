//! NeRFlex's selector: the exact DP of `nerflex_core::mck`, with tables
//! sized to the problem on the heap.

use super::problem::Problem;
use super::{Method, Plan, PlanError};
use nerflex_core::mck::{self, Config, Item, MckError, TableLens, Tables};

/// Largest tables the host DP allocates.
const MAX_TABLE_BYTES: usize = 1 << 30;

pub(crate) fn plan(problem: &Problem) -> Result<Plan, PlanError> {
    problem.check_cheapest_fits()?;
    let objects: Vec<Vec<Config>> = problem
        .objects
        .iter()
        .map(|o| {
            o.cands
                .iter()
                .map(|c| Config {
                    size: c.size,
                    quality: c.q,
                })
                .collect()
        })
        .collect();
    // The capacity the solver tabulates: min(⌊H/u⌋, Σ largest fitting units).
    let sum_max: u64 = problem
        .objects
        .iter()
        .map(|o| {
            o.cands
                .iter()
                .map(|c| c.units)
                .filter(|&u| u <= problem.budget_units)
                .max()
                .unwrap_or(0)
        })
        .fold(0u64, u64::saturating_add);
    let cap = problem.budget_units.min(sum_max);
    let too_fine = || PlanError::TooManyUnits {
        units: cap,
        unit: problem.unit.0,
    };
    let cells = usize::try_from(cap).map_err(|_| too_fine())?;
    let n = objects.len();
    let width = objects.iter().map(Vec::len).max().unwrap_or(0);
    if mck::memory_bytes(n, width, cells) > MAX_TABLE_BYTES {
        return Err(too_fine());
    }
    let lens = TableLens::new(n, width, cells);
    let mut best = vec![0u64; lens.best];
    let mut choice = vec![0u8; lens.choice];
    let mut items = vec![Item::EMPTY; lens.items];
    let mut picked = vec![0u8; lens.picked];
    let solution = Tables::new(&mut best, &mut choice, &mut items, &mut picked)
        .solve(&objects, problem.budget, problem.unit)
        .map_err(|e| map_error(problem, e))?;
    let choices: Vec<usize> = solution.choices.iter().map(|&c| c as usize).collect();
    let plan = problem.plan(Method::Dp, &choices)?;
    if plan.total_quality_q != solution.total_quality || plan.total_units != solution.total_units {
        return Err(PlanError::Internal(
            "dp: totals disagree with the solver".into(),
        ));
    }
    Ok(plan)
}

fn map_error(problem: &Problem, e: MckError) -> PlanError {
    let name = |i: usize| {
        problem
            .objects
            .get(i)
            .map_or_else(|| format!("#{i}"), |o| o.name().to_string())
    };
    match e {
        MckError::NoConfigs { object } => PlanError::NoConfigs {
            object: name(object),
        },
        MckError::TooManyConfigs {
            object, configs, ..
        } => PlanError::TooManyConfigs {
            object: name(object),
            configs,
        },
        MckError::Infeasible {
            cheapest_total,
            budget,
        } => PlanError::Infeasible {
            cheapest_total,
            budget,
        },
        MckError::UnitTooCoarse {
            cheapest_total,
            cheapest_rounded,
            budget,
            unit,
        } => PlanError::UnitTooCoarse {
            cheapest_total,
            cheapest_rounded,
            budget,
            unit,
        },
        MckError::TooManyUnits { units, .. } => PlanError::TooManyUnits {
            units,
            unit: problem.unit.0,
        },
        MckError::ZeroUnit => PlanError::ZeroUnit,
        MckError::NoObjects => PlanError::EmptyScene,
        other => PlanError::Internal(other.to_string()),
    }
}
