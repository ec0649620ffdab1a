//! Greedy baseline in LP order (the classic MCKP heuristic): every object
//! starts at its cheapest configuration; upgrades along each object's upper
//! convex hull of (units, quality) are taken in order of quality gained per
//! unit, highest first, while they fit. An upgrade that does not fit freezes
//! its object (later hull steps build on it); other objects keep upgrading.

use super::problem::{Cand, Problem};
use super::{Method, Plan, PlanError};
use std::cmp::Ordering;

pub(crate) fn plan(problem: &Problem) -> Result<Plan, PlanError> {
    problem.check_cheapest_fits()?;
    let hulls: Vec<Vec<usize>> = problem.objects.iter().map(|o| hull(&o.cands)).collect();
    // Upgrades: (object, step k: hull[k-1] → hull[k], Δunits, Δquality).
    let mut steps: Vec<(usize, usize, u64, u64)> = Vec::new();
    for (i, h) in hulls.iter().enumerate() {
        let cands = &problem.objects[i].cands;
        for k in 1..h.len() {
            let (a, b) = (&cands[h[k - 1]], &cands[h[k]]);
            steps.push((i, k, b.units - a.units, (b.q.raw() - a.q.raw()) as u64));
        }
    }
    // Highest Δq/Δu first (exact cross-multiplication), then smaller Δu,
    // then object and step order.
    steps.sort_by(|x, y| {
        let lhs = x.3 as u128 * y.2 as u128;
        let rhs = y.3 as u128 * x.2 as u128;
        rhs.cmp(&lhs)
            .then(x.2.cmp(&y.2))
            .then(x.0.cmp(&y.0))
            .then(x.1.cmp(&y.1))
    });
    let mut at = vec![0usize; hulls.len()];
    let mut frozen = vec![false; hulls.len()];
    let used: u64 = problem
        .objects
        .iter()
        .zip(&hulls)
        .map(|(o, h)| o.cands[h[0]].units)
        .sum();
    let mut left = problem.budget_units - used; // the cheapest plan fits
    for (i, k, du, _) in steps {
        if frozen[i] || at[i] + 1 != k {
            continue;
        }
        if du <= left {
            left -= du;
            at[i] = k;
        } else {
            frozen[i] = true;
        }
    }
    let choices: Vec<usize> = at.iter().zip(&hulls).map(|(&k, h)| h[k]).collect();
    problem.plan(Method::Greedy, &choices)
}

/// Positions (into `cands`) of the upper convex hull of the Pareto frontier,
/// from the cheapest configuration up; slopes strictly decrease. Never empty.
fn hull(cands: &[Cand]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_by(|&a, &b| {
        let (x, y) = (&cands[a], &cands[b]);
        x.units
            .cmp(&y.units)
            .then(y.q.cmp(&x.q))
            .then(x.size.cmp(&y.size))
            .then(x.index.cmp(&y.index))
    });
    // Pareto frontier: strictly increasing quality.
    let mut front: Vec<usize> = Vec::new();
    for k in order {
        if front.last().is_none_or(|&l| cands[k].q > cands[l].q) {
            front.push(k);
        }
    }
    // Upper hull (monotone chain): drop a middle point on or below the chord.
    let mut h: Vec<usize> = Vec::new();
    for k in front {
        while h.len() >= 2 {
            let (o, a) = (&cands[h[h.len() - 2]], &cands[h[h.len() - 1]]);
            let b = &cands[k];
            // Slope(o→a) <= slope(a→b) means `a` is not a hull vertex.
            let s1 = (a.q.raw() - o.q.raw()) as u128 * (b.units - a.units) as u128;
            let s2 = (b.q.raw() - a.q.raw()) as u128 * (a.units - o.units) as u128;
            if s1.cmp(&s2) != Ordering::Greater {
                h.pop();
            } else {
                break;
            }
        }
        h.push(k);
    }
    h
}
