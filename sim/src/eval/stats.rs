//! Statistics of the evaluation: means with 95 % bootstrap intervals over
//! held-out views, paired differences, significance, Spearman's rank
//! correlation with an exact (small n) or seeded Monte-Carlo permutation
//! p-value.
//!
//! Every random draw comes from a ChaCha8 generator with a fixed seed, so a
//! report regenerated from the same `eval.json` prints the same intervals.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The seed of every bootstrap and permutation draw.
pub const SEED: u64 = 16;

/// Bootstrap resamples per interval.
pub const RESAMPLES: usize = 10_000;

/// The interval's coverage.
pub const LEVEL: f64 = 0.95;

/// A mean and its percentile-bootstrap interval over `n` values.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    /// The sample mean.
    pub mean: f64,
    /// Lower end of the 95 % interval.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Values the mean is over.
    pub n: usize,
}

/// What a difference's interval says about zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Significance {
    /// The whole interval lies above zero.
    Positive,
    /// The whole interval lies below zero.
    Negative,
    /// The interval contains zero (or has fewer than two values).
    NotSignificant,
}

impl Interval {
    /// Whether the interval excludes zero, and on which side. One value
    /// gives no interval to speak of: never significant.
    pub fn significance(&self) -> Significance {
        if self.n < 2 {
            Significance::NotSignificant
        } else if self.lo > 0.0 {
            Significance::Positive
        } else if self.hi < 0.0 {
            Significance::Negative
        } else {
            Significance::NotSignificant
        }
    }

    /// `0.8912 [0.8890, 0.8931]` with `digits` decimals.
    pub fn show(&self, digits: usize) -> String {
        format!(
            "{:.d$} [{:.d$}, {:.d$}]",
            self.mean,
            self.lo,
            self.hi,
            d = digits
        )
    }

    /// As [`Interval::show`] with a sign on every number (differences).
    pub fn show_signed(&self, digits: usize) -> String {
        format!(
            "{:+.d$} [{:+.d$}, {:+.d$}]",
            self.mean,
            self.lo,
            self.hi,
            d = digits
        )
    }
}

/// The arithmetic mean (`None` for no values).
pub fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// The `q` quantile (0…1) of sorted values, linear between order
/// statistics (numpy's default).
fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    let n = sorted.len();
    if n == 1 {
        return sorted[0];
    }
    let h = q.clamp(0.0, 1.0) * (n - 1) as f64;
    let i = h.floor() as usize;
    let j = (i + 1).min(n - 1);
    sorted[i] + (h - i as f64) * (sorted[j] - sorted[i])
}

/// The mean of `v` and its 95 % percentile-bootstrap interval
/// ([`RESAMPLES`] resamples with replacement, seed [`SEED`]). `None` for
/// no values; non-finite values are an error of the caller and make the
/// interval non-finite. Views are the unit of resampling, so the interval
/// says how much the mean could move with other held-out views of the
/// same scene, not with other scenes.
pub fn bootstrap_mean(v: &[f64]) -> Option<Interval> {
    bootstrap_mean_with(v, RESAMPLES, SEED)
}

/// [`bootstrap_mean`] with a given number of resamples and seed.
pub fn bootstrap_mean_with(v: &[f64], resamples: usize, seed: u64) -> Option<Interval> {
    let m = mean(v)?;
    let n = v.len();
    // All values equal (or one value): every resample has the same mean,
    // the value itself (a sum would round it).
    if v.iter().all(|x| *x == v[0]) {
        return Some(Interval {
            mean: v[0],
            lo: v[0],
            hi: v[0],
            n,
        });
    }
    if resamples == 0 {
        return Some(Interval {
            mean: m,
            lo: m,
            hi: m,
            n,
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut means: Vec<f64> = (0..resamples)
        .map(|_| (0..n).map(|_| v[rng.random_range(0..n)]).sum::<f64>() / n as f64)
        .collect();
    means.sort_by(f64::total_cmp);
    let tail = (1.0 - LEVEL) / 2.0;
    Some(Interval {
        mean: m,
        lo: quantile_sorted(&means, tail),
        hi: quantile_sorted(&means, 1.0 - tail),
        n,
    })
}

/// The paired difference `a − b` over the same units (views): the mean of
/// `aᵢ − bᵢ` with its bootstrap interval. `None` when the lengths differ
/// or there are no pairs.
pub fn paired_difference(a: &[f64], b: &[f64]) -> Option<Interval> {
    if a.len() != b.len() {
        return None;
    }
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    bootstrap_mean(&d)
}

/// Ranks 1…n with ties given their average rank.
pub fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        // Positions i..=j (0-based) share ranks i+1..=j+1.
        let avg = (i + j) as f64 / 2.0 + 1.0;
        for &k in &idx[i..=j] {
            r[k] = avg;
        }
        i = j + 1;
    }
    r
}

/// Pearson's correlation (`None` when either side is constant or the
/// lengths differ or n < 2).
fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() != y.len() || x.len() < 2 {
        return None;
    }
    let (mx, my) = (mean(x)?, mean(y)?);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

/// Spearman's rank correlation ρ: Pearson's correlation of the average
/// ranks (so ties are handled). `None` when a side is constant.
pub fn spearman(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() != y.len() {
        return None;
    }
    pearson(&ranks(x), &ranks(y))
}

/// Spearman's ρ and its two-sided permutation p-value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RankCorrelation {
    /// ρ.
    pub rho: f64,
    /// Share of permutations of `y` with |ρ| at least this large.
    pub p: f64,
    /// Pairs.
    pub n: usize,
    /// Whether every permutation was counted (n ≤ [`EXACT_MAX_N`]).
    pub exact: bool,
}

/// Up to this many pairs the p-value counts every permutation (8! = 40 320).
pub const EXACT_MAX_N: usize = 8;

/// Spearman's ρ of `x` and `y` with a two-sided permutation p-value: exact
/// for n ≤ [`EXACT_MAX_N`], else from [`RESAMPLES`] seeded shuffles (the
/// observed order counted as one of them). `None` when ρ is undefined.
pub fn spearman_test(x: &[f64], y: &[f64]) -> Option<RankCorrelation> {
    let rho = spearman(x, y)?;
    let (rx, ry) = (ranks(x), ranks(y));
    let n = x.len();
    // A permutation is "as extreme" if |ρ| ≥ |ρ_obs| up to rounding.
    let extreme = |perm: &[f64]| pearson(&rx, perm).is_some_and(|r| r.abs() >= rho.abs() - 1e-12);
    let (hits, total, exact) = if n <= EXACT_MAX_N {
        let mut perm = ry.clone();
        let (mut hits, mut total) = (0u64, 0u64);
        heap_permutations(&mut perm, &mut |p| {
            total += 1;
            if extreme(p) {
                hits += 1;
            }
        });
        (hits, total, true)
    } else {
        let mut rng = ChaCha8Rng::seed_from_u64(SEED);
        let mut perm = ry.clone();
        let mut hits = 1u64; // the observed order
        for _ in 0..RESAMPLES {
            for i in (1..n).rev() {
                let j = rng.random_range(0..=i);
                perm.swap(i, j);
            }
            if extreme(&perm) {
                hits += 1;
            }
        }
        (hits, RESAMPLES as u64 + 1, false)
    };
    Some(RankCorrelation {
        rho,
        p: hits as f64 / total as f64,
        n,
        exact,
    })
}

/// Calls `f` on every permutation of `v` (Heap's algorithm, iterative).
fn heap_permutations(v: &mut [f64], f: &mut dyn FnMut(&[f64])) {
    let n = v.len();
    let mut c = vec![0usize; n];
    f(v);
    let mut i = 0;
    while i < n {
        if c[i] < i {
            if i % 2 == 0 {
                v.swap(0, i);
            } else {
                v.swap(c[i], i);
            }
            f(v);
            c[i] += 1;
            i = 0;
        } else {
            c[i] = 0;
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_quantiles_by_hand() {
        assert_eq!(mean(&[]), None);
        assert_eq!(mean(&[1.0, 2.0, 6.0]), Some(3.0));
        let s = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile_sorted(&s, 0.0), 1.0);
        assert_eq!(quantile_sorted(&s, 0.5), 3.0);
        assert_eq!(quantile_sorted(&s, 0.125), 1.5);
        assert_eq!(quantile_sorted(&s, 1.0), 5.0);
    }

    #[test]
    fn constant_values_give_a_point_interval() {
        let i = bootstrap_mean(&[0.9; 7]).unwrap();
        assert_eq!((i.mean, i.lo, i.hi, i.n), (0.9, 0.9, 0.9, 7));
        assert_eq!(i.significance(), Significance::Positive);
        let one = bootstrap_mean(&[0.3]).unwrap();
        assert_eq!((one.lo, one.hi), (0.3, 0.3));
        // One value is never significant, whatever its sign.
        assert_eq!(one.significance(), Significance::NotSignificant);
        assert!(bootstrap_mean(&[]).is_none());
    }

    #[test]
    fn two_values_bootstrap_by_hand() {
        // Resampling {0, 1} twice gives means 0, ½, ½, 1 with probabilities
        // ¼, ½, ¼: the 2.5 % and 97.5 % quantiles of many draws are 0 and 1.
        let i = bootstrap_mean(&[0.0, 1.0]).unwrap();
        assert_eq!(i.mean, 0.5);
        assert_eq!((i.lo, i.hi), (0.0, 1.0));
        assert_eq!(i.significance(), Significance::NotSignificant);
    }

    #[test]
    fn interval_brackets_the_mean_and_narrows_with_n() {
        let few: Vec<f64> = (0..5).map(|k| f64::from(k % 3)).collect();
        let many: Vec<f64> = (0..200).map(|k| f64::from(k % 3)).collect();
        let a = bootstrap_mean(&few).unwrap();
        let b = bootstrap_mean(&many).unwrap();
        for i in [a, b] {
            assert!(i.lo <= i.mean && i.mean <= i.hi, "{i:?}");
            assert!(i.lo >= 0.0 && i.hi <= 2.0, "{i:?}");
        }
        assert!(b.hi - b.lo < (a.hi - a.lo) / 3.0, "{a:?} {b:?}");
        // Same input, same seed: the same interval.
        assert_eq!(bootstrap_mean(&few), Some(a));
        // Another seed moves the ends a little, not the mean.
        let c = bootstrap_mean_with(&many, RESAMPLES, SEED + 1).unwrap();
        assert_eq!(c.mean, b.mean);
        assert!((c.lo - b.lo).abs() < 0.05 && (c.hi - b.hi).abs() < 0.05);
    }

    #[test]
    fn paired_differences_and_their_sign() {
        // b is a shifted by exactly 0.01 in every view: the difference is a
        // point interval at +0.01, significant although the views scatter
        // far more than 0.01.
        let a = [0.80, 0.95, 0.70, 0.88, 0.91];
        let b: Vec<f64> = a.iter().map(|x| x - 0.01).collect();
        let d = paired_difference(&a, &b).unwrap();
        assert!((d.mean - 0.01).abs() < 1e-12 && (d.lo - 0.01).abs() < 1e-12);
        assert_eq!(d.significance(), Significance::Positive);
        let r = paired_difference(&b, &a).unwrap();
        assert_eq!(r.significance(), Significance::Negative);
        // Identical: zero, not significant.
        let z = paired_difference(&a, &a).unwrap();
        assert_eq!((z.mean, z.lo, z.hi), (0.0, 0.0, 0.0));
        assert_eq!(z.significance(), Significance::NotSignificant);
        // Differences of both signs: the interval straddles zero.
        let m = paired_difference(&[1.0, 0.0, 1.0, 0.0], &[0.0, 1.0, 0.0, 1.0]).unwrap();
        assert_eq!(m.significance(), Significance::NotSignificant);
        assert!(paired_difference(&[1.0], &[1.0, 2.0]).is_none());
    }

    #[test]
    fn ranks_average_ties() {
        assert_eq!(ranks(&[10.0, 30.0, 20.0]), vec![1.0, 3.0, 2.0]);
        assert_eq!(ranks(&[5.0, 1.0, 5.0, 2.0]), vec![3.5, 1.0, 3.5, 2.0]);
    }

    #[test]
    fn spearman_by_hand() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(spearman(&x, &[2.0, 4.0, 8.0, 16.0, 32.0]), Some(1.0));
        assert_eq!(spearman(&x, &[5.0, 4.0, 3.0, 2.0, 1.0]), Some(-1.0));
        // d = (0, 0, -1, 1, 0): ρ = 1 − 6·2 / (5·24) = 0.9.
        let r = spearman(&x, &[1.0, 2.0, 4.0, 3.0, 5.0]).unwrap();
        assert!((r - 0.9).abs() < 1e-12, "{r}");
        assert_eq!(spearman(&x, &[1.0; 5]), None);
        assert_eq!(spearman(&x, &[1.0, 2.0]), None);
    }

    #[test]
    fn exact_permutation_p_values_by_hand() {
        // n = 5: of the 120 orders, only the identity and its reverse reach
        // |ρ| = 1, so p = 2/120.
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        let t = spearman_test(&x, &x).unwrap();
        assert!(t.exact);
        assert!((t.p - 2.0 / 120.0).abs() < 1e-12, "{t:?}");
        // |ρ| ≥ 0.9 for n = 5: ρ = ±1 (2 orders) and ±0.9 (4 each side: one
        // adjacent swap of the 4 possible) → 10/120.
        let t = spearman_test(&x, &[1.0, 2.0, 4.0, 3.0, 5.0]).unwrap();
        assert!((t.p - 10.0 / 120.0).abs() < 1e-12, "{t:?}");
        // n = 3: every ρ is ±1 or ±0.5, so |ρ| ≥ 0.5 always: p = 1.
        let t = spearman_test(&[1.0, 2.0, 3.0], &[2.0, 1.0, 3.0]).unwrap();
        assert!((t.rho - 0.5).abs() < 1e-12 && (t.p - 1.0).abs() < 1e-12);
    }

    #[test]
    fn monte_carlo_p_value_for_large_n() {
        let x: Vec<f64> = (0..30).map(f64::from).collect();
        let t = spearman_test(&x, &x).unwrap();
        assert!(!t.exact);
        // Only the observed order (and practically no shuffle) is as extreme.
        assert!(t.p <= 2.0 / (RESAMPLES as f64 + 1.0), "{t:?}");
        // Unrelated values: a large p.
        let y: Vec<f64> = (0..30).map(|k| f64::from((k * 17) % 30)).collect();
        let u = spearman_test(&x, &y).unwrap();
        assert!(u.rho.abs() < 0.3 && u.p > 0.1, "{u:?}");
    }
}
