//! Fairness baseline: the budget split equally; each object takes its best
//! configuration inside its share.

use super::problem::Problem;
use super::{Method, Plan, PlanError};
use nerflex_core::units::Bytes;

pub(crate) fn plan(problem: &Problem) -> Result<Plan, PlanError> {
    problem.check_cheapest_fits()?;
    // Shares in whole units, so their sum never exceeds ⌊H/u⌋.
    let share = problem.budget_units / problem.objects.len() as u64;
    let choices = problem
        .objects
        .iter()
        .map(|o| {
            let best = o
                .best_within(share)
                .ok_or_else(|| PlanError::ShareTooSmall {
                    object: o.name().to_string(),
                    share: Bytes(share.saturating_mul(problem.unit.0)),
                })?;
            o.cands
                .iter()
                .position(|c| c.index == best.index)
                .ok_or_else(|| PlanError::Internal("fairness: lost a candidate".into()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    problem.plan(Method::Fairness, &choices)
}
