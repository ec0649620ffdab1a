//! Brute force: every combination of configurations (depth first, skipping
//! branches that can no longer fit). Exact on the rounded problem; meant for
//! small cases and as the tests' reference. Independent of the DP's code.

use super::problem::Problem;
use super::{Method, Plan, PlanError};

/// Most combinations (of configurations that fit on their own) searched:
/// 2^28, enough for the paper's 45^5 ≈ 1.8·10^8.
pub(crate) const DEFAULT_LIMIT: u128 = 1 << 28;

pub(crate) fn plan(problem: &Problem, limit: u128) -> Result<Plan, PlanError> {
    problem.check_cheapest_fits()?;
    let b = problem.budget_units;
    // Per object: (units, quality raw, bytes, candidate position), fitting ones only.
    let lists: Vec<Vec<(u64, u64, u64, usize)>> = problem
        .objects
        .iter()
        .map(|o| {
            o.cands
                .iter()
                .enumerate()
                .filter(|(_, c)| c.units <= b)
                .map(|(k, c)| (c.units, c.q.raw() as u64, c.size.0, k))
                .collect()
        })
        .collect();
    let combinations = lists
        .iter()
        .map(|l| l.len() as u128)
        .fold(1u128, |a, n| a.saturating_mul(n));
    if combinations > limit {
        return Err(PlanError::BruteTooLarge {
            combinations,
            limit,
        });
    }
    // Cheapest units of objects i.. (for pruning).
    let mut rest_min = vec![0u64; lists.len() + 1];
    for i in (0..lists.len()).rev() {
        let m = lists[i].iter().map(|x| x.0).min().unwrap_or(u64::MAX);
        rest_min[i] = rest_min[i + 1].saturating_add(m);
    }
    let mut search = Search {
        lists: &lists,
        rest_min: &rest_min,
        current: vec![0; lists.len()],
        best: None,
    };
    search.go(0, b, 0, 0, 0);
    let best = search
        .best
        .ok_or_else(|| PlanError::Internal("brute: no plan although the cheapest fits".into()))?;
    problem.plan(Method::Brute, &best.3)
}

/// (quality, units, bytes, choices) of the best plan so far.
type Best = (u64, u64, u64, Vec<usize>);

struct Search<'a> {
    lists: &'a [Vec<(u64, u64, u64, usize)>],
    rest_min: &'a [u64],
    current: Vec<usize>,
    best: Option<Best>,
}

impl Search<'_> {
    fn go(&mut self, i: usize, left: u64, q: u64, units: u64, bytes: u64) {
        let Some(list) = self.lists.get(i) else {
            // Higher quality, then fewer units, then fewer bytes; the first
            // found (lexicographically smallest choices) wins remaining ties.
            let better = match &self.best {
                None => true,
                Some((bq, bu, bb, _)) => {
                    (q, std::cmp::Reverse((units, bytes))) > (*bq, std::cmp::Reverse((*bu, *bb)))
                }
            };
            if better {
                self.best = Some((q, units, bytes, self.current.clone()));
            }
            return;
        };
        for &(u, cq, cb, k) in list {
            if u > left || left - u < self.rest_min[i + 1] {
                continue;
            }
            self.current[i] = k;
            self.go(i + 1, left - u, q + cq, units + u, bytes.saturating_add(cb));
        }
    }
}
