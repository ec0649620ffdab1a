//! The NeRFlex paper's variable step-size sample selection.
//!
//! The paper: "for selecting the g values of the sample points, the step
//! size is 2·g′, where g′ represents the value of the previous sample point.
//! For each g value, we select the maximum, minimum, and midpoint values of
//! the patch size range."
//!
//! We read "step size 2·g′" literally: the *step* (the increment) is twice
//! the previous value, so `g_{k+1} = g′ + 2·g′ = 3·g′` ([`Step::Triple`], the
//! default): 16, 48, 144, 432 over 16..512. Reading it as "the next value is
//! 2·g′" gives doubling ([`Step::Double`]): 16, 32, …, 512. Tripling is what
//! the sentence says and what "minimise the number of sampling points" asks
//! for (4 instead of 6 g values here, 12 bakes instead of 18); both need at
//! least the models' 4 parameters per curve (3 g values × 3 p values = 9).
//! The sequence starts at the range's minimum and stops at the last value
//! not above the maximum (the maximum itself is sampled only if the sequence
//! hits it). `p` takes the range's minimum, midpoint (rounded down) and
//! maximum.

use std::fmt;
use std::ops::RangeInclusive;
use std::str::FromStr;

/// How the next `g` follows from the previous one `g′`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Step {
    /// `g′ + 2·g′ = 3·g′` (the paper's "step size 2·g′", read literally).
    #[default]
    Triple,
    /// `2·g′` (the other reading).
    Double,
}

impl Step {
    /// The factor between consecutive `g` values.
    pub fn factor(self) -> u32 {
        match self {
            Step::Triple => 3,
            Step::Double => 2,
        }
    }
}

/// The sample points: every `g` paired with every `p`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SamplePlan {
    /// Grid values, increasing.
    pub grids: Vec<u32>,
    /// Patch values: minimum, midpoint, maximum (fewer if they coincide).
    pub patches: Vec<u32>,
}

impl SamplePlan {
    /// Every (g, p) pair, `g`-major.
    pub fn points(&self) -> Vec<(u32, u32)> {
        self.grids
            .iter()
            .flat_map(|&g| self.patches.iter().map(move |&p| (g, p)))
            .collect()
    }

    /// The baker's sweep flags for these points: `--grid … --patch …`.
    pub fn bake_flags(&self) -> String {
        let list = |v: &[u32]| v.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
        format!(
            "--sweep --grid {} --patch {}",
            list(&self.grids),
            list(&self.patches)
        )
    }
}

/// The variable-step sample points over `g` and `p` ranges (inclusive,
/// positive, non-empty).
pub fn variable_step(
    g: RangeInclusive<u32>,
    p: RangeInclusive<u32>,
    step: Step,
) -> Result<SamplePlan, String> {
    let (g0, g1) = (*g.start(), *g.end());
    let (p0, p1) = (*p.start(), *p.end());
    if g0 == 0 || g0 > g1 {
        return Err(format!(
            "g range {g0}..{g1} must be positive and increasing"
        ));
    }
    if p0 == 0 || p0 > p1 {
        return Err(format!(
            "p range {p0}..{p1} must be positive and increasing"
        ));
    }
    let mut grids = vec![g0];
    let mut cur = g0;
    while let Some(next) = cur.checked_mul(step.factor()).filter(|&n| n <= g1) {
        grids.push(next);
        cur = next;
    }
    let mut patches = vec![p0, p0 + (p1 - p0) / 2, p1];
    patches.dedup();
    Ok(SamplePlan { grids, patches })
}

/// The variable-step rule applied to an existing sweep: which of the
/// available `grids` and `patches` (any order, duplicates allowed) the
/// strategy would have baked.
///
/// `g` starts at the smallest available value; each next one is the
/// smallest available value at least `factor·g′` (the rule's next value,
/// rounded *up* to the sweep's grid). `p` takes the smallest, the largest,
/// and the available value nearest the range's midpoint (ties go to the
/// smaller, as the midpoint is rounded down). On the bake sweep's
/// g ∈ {16, 32, 64, 128, 256}, p ∈ {5, 9, 13, 17}: `triple` gives
/// g {16, 64, 256} × p {5, 9, 17}; `double` gives every g × p {5, 9, 17}.
pub fn variable_step_on(grids: &[u32], patches: &[u32], step: Step) -> SamplePlan {
    let mut gs: Vec<u32> = grids.to_vec();
    gs.sort_unstable();
    gs.dedup();
    let mut ps: Vec<u32> = patches.to_vec();
    ps.sort_unstable();
    ps.dedup();
    let mut chosen = Vec::new();
    if let Some(&first) = gs.first() {
        chosen.push(first);
        let mut cur = first;
        while let Some(&next) = gs
            .iter()
            .find(|&&g| g > cur && u64::from(g) >= u64::from(cur) * u64::from(step.factor()))
        {
            chosen.push(next);
            cur = next;
        }
    }
    let mut pick = Vec::new();
    if let (Some(&lo), Some(&hi)) = (ps.first(), ps.last()) {
        // Twice the midpoint, to stay in integers.
        let mid2 = u64::from(lo) + u64::from(hi);
        let nearest = ps
            .iter()
            .copied()
            .min_by_key(|&p| (u64::from(p) * 2).abs_diff(mid2))
            .unwrap_or(lo);
        pick = vec![lo, nearest, hi];
        pick.sort_unstable();
        pick.dedup();
    }
    SamplePlan {
        grids: chosen,
        patches: pick,
    }
}

/// An inclusive range of positive integers parsed from `LO..HI` or
/// `LO..=HI` (both ends included either way).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IntRange(pub RangeInclusive<u32>);

impl FromStr for IntRange {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("expected LO..HI with positive integers (e.g. 16..512), got {s:?}");
        let (lo, hi) = s.split_once("..").ok_or_else(bad)?;
        let hi = hi.strip_prefix('=').unwrap_or(hi);
        let lo: u32 = lo.trim().parse().map_err(|_| bad())?;
        let hi: u32 = hi.trim().parse().map_err(|_| bad())?;
        if lo == 0 || lo > hi {
            return Err(bad());
        }
        Ok(IntRange(lo..=hi))
    }
}

impl fmt::Display for IntRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..{}", self.0.start(), self.0.end())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_ranges() {
        let plan = variable_step(16..=512, 3..=33, Step::Triple).unwrap();
        assert_eq!(plan.grids, vec![16, 48, 144, 432]);
        assert_eq!(plan.patches, vec![3, 18, 33]);
        assert_eq!(plan.points().len(), 12);
        assert_eq!(plan.points()[4], (48, 18));
        assert_eq!(
            plan.bake_flags(),
            "--sweep --grid 16,48,144,432 --patch 3,18,33"
        );
        let plan = variable_step(16..=512, 3..=33, Step::Double).unwrap();
        assert_eq!(plan.grids, vec![16, 32, 64, 128, 256, 512]);
    }

    #[test]
    fn on_an_existing_sweep() {
        let (g, p) = ([256, 16, 32, 64, 128], [5, 9, 13, 17, 9]);
        let plan = variable_step_on(&g, &p, Step::Triple);
        assert_eq!(
            (plan.grids, plan.patches),
            (vec![16, 64, 256], vec![5, 9, 17])
        );
        let plan = variable_step_on(&g, &p, Step::Double);
        assert_eq!(plan.grids, vec![16, 32, 64, 128, 256]);
        // Exact multiples are taken; gaps round up; the midpoint is exact.
        let plan = variable_step_on(&[4, 12, 30, 36, 200], &[3, 18, 33], Step::Triple);
        assert_eq!(
            (plan.grids, plan.patches),
            (vec![4, 12, 36, 200], vec![3, 18, 33])
        );
        let plan = variable_step_on(&[], &[7], Step::Triple);
        assert_eq!((plan.grids, plan.patches), (vec![], vec![7]));
    }

    #[test]
    fn edges() {
        let plan = variable_step(5..=5, 4..=5, Step::Triple).unwrap();
        assert_eq!((plan.grids, plan.patches), (vec![5], vec![4, 5]));
        let plan = variable_step(1..=u32::MAX, 7..=7, Step::Triple).unwrap();
        assert_eq!(plan.grids.len(), 21); // 3^20 < 2^32 < 3^21
        assert_eq!(plan.patches, vec![7]);
        assert!(variable_step(0..=4, 1..=2, Step::Double).is_err());
        assert!("16..512".parse::<IntRange>().unwrap().0 == (16..=512));
        assert!("16..=512".parse::<IntRange>().unwrap().0 == (16..=512));
        assert!("512..16".parse::<IntRange>().is_err());
        assert!("x..16".parse::<IntRange>().is_err());
        assert!("16".parse::<IntRange>().is_err());
    }
}
