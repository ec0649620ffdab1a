//! Fitting one curve (size or quality) of one object with
//! Levenberg–Marquardt.
//!
//! - **Bounds by reparameterisation.** LM sees `θ ∈ R⁴` (`R⁵` for the quads
//!   family's size); the model sees `k = e^θ₀ > 0` and `a`, `b`, `m` (and
//!   `c`) each `lo + (hi − lo)·σ(θᵢ)` inside its bounds ([`Bounds`]):
//!   `a ∈ [−g_min/2, 2·g_max]`, `b ∈ [−p_min/2, max(256 − 2·p_max,
//!   2·p_max)]` (so `g + a ≥ g/2 > 0`: no pole over the domain; `p + b`
//!   stays in the fixed-point range), size `m ∈ [0, min S]` (a constant
//!   part no larger than the smallest bake), the per-quad `c ∈ [0, min
//!   S/(g/2)²]` (the per-quad term alone no larger than any bake), quality
//!   `m ∈ [0, 1]` (an SSIM asymptote).
//! - **Starting values.** For `(a, b)` on a small grid of starts, the model
//!   is linear in `(k, m)` (`S = k·X + m`, `Q = m − k·(1/X)`; the quads
//!   family's size in `(k, c, m)`), so these come from linear least
//!   squares, clipped into bounds; LM runs from each start and the lowest
//!   residual wins.
//! - **Residuals.** Quality residuals are absolute SSIM. Size residuals are
//!   *relative* (`(fit − measured)/measured`): sizes span three to four
//!   orders of magnitude over a sweep, absolute residuals would let the
//!   largest bakes decide alone (the constant `m` becomes invisible), and the
//!   planner needs the small and middle configurations right as much as the
//!   big ones. Reported residuals ([`Residuals`]) are absolute either way.

use super::FitError;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{storage::Owned, DMatrix, DVector, Dyn, OMatrix};
use nerflex_core::profiler::{Curve, Family, Params, MAX_P_BASE, MAX_SIZE_C};

/// One measured point: grid, patch, measured value (bytes or SSIM).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Grid g.
    pub g: u32,
    /// Patch p.
    pub p: u32,
    /// Measured value: bytes (size) or SSIM (quality).
    pub y: f64,
}

/// The configuration domain the fitted curve must be valid on (its
/// bounds on `a` and `b` follow from it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Domain {
    /// Smallest g.
    pub g_min: u32,
    /// Largest g.
    pub g_max: u32,
    /// Smallest p.
    pub p_min: u32,
    /// Largest p.
    pub p_max: u32,
}

impl Domain {
    /// The smallest domain holding every point's (g, p); `None` if empty.
    pub fn of_points(points: &[Point]) -> Option<Domain> {
        let first = points.first()?;
        Some(points.iter().fold(
            Domain {
                g_min: first.g,
                g_max: first.g,
                p_min: first.p,
                p_max: first.p,
            },
            |d, q| Domain {
                g_min: d.g_min.min(q.g),
                g_max: d.g_max.max(q.g),
                p_min: d.p_min.min(q.p),
                p_max: d.p_max.max(q.p),
            },
        ))
    }

    /// The smallest domain holding both.
    pub fn union(self, o: Domain) -> Domain {
        Domain {
            g_min: self.g_min.min(o.g_min),
            g_max: self.g_max.max(o.g_max),
            p_min: self.p_min.min(o.p_min),
            p_max: self.p_max.max(o.p_max),
        }
    }
}

/// Bounds of `a`, `b`, `m` and `c` (closed intervals).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Offset added to g.
    pub a: (f64, f64),
    /// Offset added to p.
    pub b: (f64, f64),
    /// Constant term / asymptote.
    pub m: (f64, f64),
    /// Per-quad scale (size of the quads family; `(0, 0)` for quality).
    pub c: (f64, f64),
}

impl Bounds {
    /// The bounds used for `curve` over `domain` with measured `points`.
    pub fn new(curve: Curve, domain: Domain, points: &[Point]) -> Bounds {
        let a = (-(domain.g_min as f64) / 2.0, 2.0 * domain.g_max as f64);
        // `b` may grow far beyond `p_max`: on disk the texel atlases are PNG-
        // compressed, so size grows much more slowly than p² and a large `b`
        // (`(p+b)² ≈ b² + 2bp`, nearly affine in p) is how the model says so.
        // The cap keeps `p + b ≤ MAX_P_BASE − p_max` inside the fixed-point
        // range over the domain, and is 2·p_max at the top of that range.
        let p_max = domain.p_max as f64;
        let b = (
            -(domain.p_min as f64) / 2.0,
            (MAX_P_BASE - 2.0 * p_max).max(2.0 * p_max),
        );
        let smallest = |f: fn(&Point) -> f64| points.iter().map(f).fold(f64::INFINITY, f64::min);
        let (m, c) = match curve {
            Curve::Size => (
                (0.0, smallest(|q| q.y).max(0.0)),
                // G ≥ g/2 over the domain (the bound on a), so c·G² ≤ S at
                // every point needs c ≤ S/(g/2)² at every point.
                (
                    0.0,
                    smallest(|q| q.y / (q.g as f64 / 2.0).powi(2)).clamp(0.0, MAX_SIZE_C),
                ),
            ),
            Curve::Quality => ((0.0, 1.0), (0.0, 0.0)),
        };
        Bounds { a, b, m, c }
    }
}

/// How well one fitted curve matches its points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residuals {
    /// Root mean square of `fit − measured` (bytes or SSIM).
    pub rmse: f64,
    /// Largest `|fit − measured|`.
    pub max_abs: f64,
    /// Number of points.
    pub n: usize,
}

/// One fitted curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveFit {
    /// Which model.
    pub curve: Curve,
    /// Fitted parameters (family included).
    pub params: Params,
    /// Residuals of the fitted curve on its points.
    pub residuals: Residuals,
    /// Model function evaluations LM used (all starts).
    pub evaluations: usize,
    /// Parameters that ended at a bound (within 0.1 % of its width):
    /// `a`, `b`, `m`, `c` in that order (`c` only in the quads family).
    pub at_bound: [bool; 4],
}

/// Which family to fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum FamilyChoice {
    /// Fit every family the curve has, keep the lowest RMSE (ties go to the
    /// paper's volume form): volume, surface and quads for the size,
    /// volume and surface for the quality.
    #[default]
    Auto,
    /// Only `G³` (the paper).
    Volume,
    /// Only `G²`.
    Surface,
    /// The size as `k·G^{3/2}·P² + c·G² + m`; the quality as `auto` (the
    /// per-quad term is a size law's).
    Quads,
    /// `auto` without the quads family (volume and surface for both
    /// curves): what `auto` was before the quads family existed.
    Classic,
}

/// The quality model's families (the per-quad term is the size's only),
/// and both curves' before the quads family.
const QUALITY_FAMILIES: [Family; 2] = [Family::Volume, Family::Surface];

impl FamilyChoice {
    /// The families to try for `curve`.
    pub fn families(self, curve: Curve) -> &'static [Family] {
        match (self, curve) {
            (FamilyChoice::Auto, Curve::Size) => &Family::ALL,
            (FamilyChoice::Auto | FamilyChoice::Quads, Curve::Quality) => &QUALITY_FAMILIES,
            (FamilyChoice::Classic, _) => &QUALITY_FAMILIES,
            (FamilyChoice::Volume, _) => &[Family::Volume],
            (FamilyChoice::Surface, _) => &[Family::Surface],
            (FamilyChoice::Quads, Curve::Size) => &[Family::Quads],
        }
    }
}

/// Parameters of `family`'s model of `curve` (5 for the quads family's
/// size: `k, a, b, m, c`; 4 otherwise).
pub fn parameter_count(curve: Curve, family: Family) -> usize {
    if has_c(curve, family) {
        5
    } else {
        4
    }
}

/// Whether the fit has the per-quad term `c`.
fn has_c(curve: Curve, family: Family) -> bool {
    curve == Curve::Size && family == Family::Quads
}

/// The fit of one curve, with the RMSE of every family tried.
#[derive(Clone, Debug, PartialEq)]
pub struct FamilyFit {
    /// The chosen fit (lowest RMSE).
    pub best: CurveFit,
    /// Every family tried with its fit.
    pub tried: Vec<CurveFit>,
}

/// Fits `curve` to `points` over `domain`, trying the families of `choice`.
pub fn fit(
    curve: Curve,
    points: &[Point],
    domain: Domain,
    choice: FamilyChoice,
) -> Result<FamilyFit, FitError> {
    check_points(curve, points, 4)?;
    let mut tried = Vec::new();
    let families = choice.families(curve);
    for &family in families {
        // Under `auto`, a family with more parameters than points is left
        // out rather than fitted exactly; asked for alone, it is an error.
        if families.len() > 1 && points.len() < parameter_count(curve, family) {
            continue;
        }
        tried.push(fit_family(curve, family, points, domain)?);
    }
    let best = *tried
        .iter()
        .min_by(|x, y| x.residuals.rmse.total_cmp(&y.residuals.rmse))
        .ok_or(FitError::NoFamily)?;
    Ok(FamilyFit { best, tried })
}

fn check_points(curve: Curve, points: &[Point], needed: usize) -> Result<(), FitError> {
    let distinct = |f: fn(&Point) -> u32| {
        let mut v: Vec<u32> = points.iter().map(f).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    };
    let (gs, ps) = (distinct(|q| q.g), distinct(|q| q.p));
    if points.len() < needed || gs < 2 || ps < 2 {
        return Err(FitError::TooFewPoints {
            curve,
            needed,
            points: points.len(),
            grids: gs,
            patches: ps,
        });
    }
    if let Some(q) = points.iter().find(|q| !q.y.is_finite()) {
        return Err(FitError::BadValue {
            curve,
            g: q.g,
            p: q.p,
            value: q.y,
        });
    }
    Ok(())
}

/// Fits one family from several starts; the lowest residual wins.
pub fn fit_family(
    curve: Curve,
    family: Family,
    points: &[Point],
    domain: Domain,
) -> Result<CurveFit, FitError> {
    check_points(curve, points, parameter_count(curve, family))?;
    let bounds = Bounds::new(curve, domain, points);
    let weights = weights(curve, points);
    let (g_min, p_min) = (domain.g_min as f64, domain.p_min as f64);
    let a_starts = [0.0, -0.25 * g_min, 0.5 * g_min, 2.0 * g_min];
    let b_starts = [0.0, -0.25 * p_min, 0.5 * p_min, 2.0 * p_min];
    let solver = LevenbergMarquardt::new().with_patience(200);
    let mut best: Option<(f64, Params)> = None;
    let mut evaluations = 0;
    for &a0 in &a_starts {
        for &b0 in &b_starts {
            let (a0, b0) = (clamp_inside(a0, bounds.a), clamp_inside(b0, bounds.b));
            let start = if has_c(curve, family) {
                quads_start(points, &weights, a0, b0, bounds)
            } else {
                linear_start(curve, family, points, a0, b0, bounds)
            };
            let problem = Problem::new(curve, family, points, bounds, &weights, &start);
            let (solved, report) = solver.minimize(problem);
            evaluations += report.number_of_evaluations;
            if report.termination.was_usage_issue() {
                continue;
            }
            let params = solved.params_f64();
            let sse = weighted_sse(curve, &params, points, &weights);
            if sse.is_finite() && best.as_ref().is_none_or(|(b, _)| sse < *b) {
                best = Some((sse, params));
            }
        }
    }
    let (_, params) = best.ok_or(FitError::NoConvergence { curve, family })?;
    let near = |v: f64, (lo, hi): (f64, f64)| {
        let tol = 1e-3 * (hi - lo).abs().max(f64::MIN_POSITIVE);
        (v - lo).abs() <= tol || (hi - v).abs() <= tol
    };
    Ok(CurveFit {
        curve,
        params,
        residuals: residuals(curve, &params, points),
        evaluations,
        at_bound: [
            near(params.a, bounds.a),
            near(params.b, bounds.b),
            near(params.m, bounds.m),
            has_c(curve, family) && near(params.c, bounds.c),
        ],
    })
}

/// The model's value at (g, p) in `f64`.
pub fn predict(curve: Curve, params: &Params, g: u32, p: u32) -> f64 {
    match curve {
        Curve::Size => params.size_f64(g as f64, p as f64),
        Curve::Quality => params.quality_f64(g as f64, p as f64),
    }
}

/// Residual weights: `1/measured` for size (relative residuals), 1 for
/// quality.
fn weights(curve: Curve, points: &[Point]) -> Vec<f64> {
    let mean = points.iter().map(|q| q.y.abs()).sum::<f64>() / points.len().max(1) as f64;
    points
        .iter()
        .map(|q| match curve {
            Curve::Size if q.y > 0.0 => 1.0 / q.y,
            Curve::Size => 1.0 / mean.max(1.0),
            Curve::Quality => 1.0,
        })
        .collect()
}

fn weighted_sse(curve: Curve, params: &Params, points: &[Point], w: &[f64]) -> f64 {
    points
        .iter()
        .zip(w)
        .map(|(q, w)| ((predict(curve, params, q.g, q.p) - q.y) * w).powi(2))
        .sum()
}

fn sse(curve: Curve, params: &Params, points: &[Point]) -> f64 {
    points
        .iter()
        .map(|q| (predict(curve, params, q.g, q.p) - q.y).powi(2))
        .sum()
}

/// RMSE and largest absolute residual of `params` on `points`.
pub fn residuals(curve: Curve, params: &Params, points: &[Point]) -> Residuals {
    let n = points.len();
    let max_abs = points
        .iter()
        .map(|q| (predict(curve, params, q.g, q.p) - q.y).abs())
        .fold(0.0, f64::max);
    Residuals {
        rmse: (sse(curve, params, points) / n.max(1) as f64).sqrt(),
        max_abs,
        n,
    }
}

/// A point strictly inside `(lo, hi)` (0.1 % of the width from the ends).
fn clamp_inside(v: f64, (lo, hi): (f64, f64)) -> f64 {
    let e = 1e-3 * (hi - lo);
    v.clamp(lo + e, hi - e)
}

/// `(k, m)` by linear least squares for fixed `(a, b)`, clipped into bounds.
fn linear_start(
    curve: Curve,
    family: Family,
    points: &[Point],
    a: f64,
    b: f64,
    bounds: Bounds,
) -> Params {
    let base = Params {
        k: 1.0,
        a,
        b,
        c: 0.0,
        m: 0.0,
        family,
    };
    // Regress y on z: size z = X (y = k·z + m); quality z = 1/X (y = m − k·z).
    let zs: Vec<f64> = points
        .iter()
        .map(|q| {
            let x = base.volume_f64(q.g as f64, q.p as f64);
            match curve {
                Curve::Size => x,
                Curve::Quality => 1.0 / x,
            }
        })
        .collect();
    let n = points.len() as f64;
    let zm = zs.iter().sum::<f64>() / n;
    let ym = points.iter().map(|q| q.y).sum::<f64>() / n;
    let (mut szz, mut szy) = (0.0, 0.0);
    for (z, q) in zs.iter().zip(points) {
        szz += (z - zm) * (z - zm);
        szy += (z - zm) * (q.y - ym);
    }
    let slope = if szz > 0.0 { szy / szz } else { 0.0 };
    let (k, m) = match curve {
        Curve::Size => (slope, ym - slope * zm),
        Curve::Quality => (-slope, ym - slope * zm),
    };
    // A wrong-signed slope (size falling, quality falling with g, p): start
    // from a small positive k that explains a tenth of the spread instead.
    let spread = points
        .iter()
        .map(|q| (q.y - ym).abs())
        .fold(0.0, f64::max)
        .max(1e-12);
    let k = if k > 0.0 && k.is_finite() {
        k
    } else {
        0.1 * spread / zm.abs().max(f64::MIN_POSITIVE)
    };
    Params {
        k,
        m: clamp_inside(m, bounds.m),
        ..base
    }
}

/// The quads family's `(k, c, m)` by weighted (relative) linear least
/// squares for fixed `(a, b)`, clipped into bounds.
fn quads_start(points: &[Point], weights: &[f64], a: f64, b: f64, bounds: Bounds) -> Params {
    let base = Params {
        k: 1.0,
        a,
        b,
        c: 0.0,
        m: 0.0,
        family: Family::Quads,
    };
    let n = points.len();
    let mut lhs = DMatrix::<f64>::zeros(n, 3);
    let mut rhs = DVector::<f64>::zeros(n);
    for (i, (q, w)) in points.iter().zip(weights).enumerate() {
        let (g, p) = (q.g as f64, q.p as f64);
        lhs[(i, 0)] = base.volume_f64(g, p) * w;
        lhs[(i, 1)] = base.quads_f64(g) * w;
        lhs[(i, 2)] = *w;
        rhs[i] = q.y * w;
    }
    let sol = lhs
        .svd(true, true)
        .solve(&rhs, 1e-12)
        .ok()
        .filter(|s| s.iter().all(|v| v.is_finite()));
    let (k, c, m) = sol.map_or((0.0, 0.0, 0.0), |s| (s[0], s[1], s[2]));
    // A wrong-signed k: start from one that explains the mean instead.
    let k = if k > 0.0 {
        k
    } else {
        let (sx, sy) = points.iter().fold((0.0, 0.0), |(sx, sy), q| {
            (sx + base.volume_f64(q.g as f64, q.p as f64), sy + q.y)
        });
        (0.5 * sy / sx.max(f64::MIN_POSITIVE)).max(f64::MIN_POSITIVE)
    };
    Params {
        k,
        c: clamp_inside(c, bounds.c),
        m: clamp_inside(m, bounds.m),
        ..base
    }
}

fn sigmoid(t: f64) -> f64 {
    1.0 / (1.0 + (-t).exp())
}

fn logit(v: f64, (lo, hi): (f64, f64)) -> f64 {
    let u = ((v - lo) / (hi - lo)).clamp(1e-9, 1.0 - 1e-9);
    (u / (1.0 - u)).ln()
}

/// The LM problem: θ = (ln k, logit a, logit b, logit m[, logit c]).
struct Problem<'p> {
    curve: Curve,
    family: Family,
    points: &'p [Point],
    bounds: Bounds,
    /// Residual weights, one per point.
    weights: &'p [f64],
    theta: DVector<f64>,
}

impl<'p> Problem<'p> {
    fn new(
        curve: Curve,
        family: Family,
        points: &'p [Point],
        bounds: Bounds,
        weights: &'p [f64],
        start: &Params,
    ) -> Self {
        let mut theta = vec![
            start.k.max(f64::MIN_POSITIVE).ln(),
            logit(start.a, bounds.a),
            logit(start.b, bounds.b),
            logit(start.m, bounds.m),
        ];
        if has_c(curve, family) {
            theta.push(logit(start.c, bounds.c));
        }
        Problem {
            curve,
            family,
            points,
            bounds,
            weights,
            theta: DVector::from_vec(theta),
        }
    }

    fn bounded(t: f64, (lo, hi): (f64, f64)) -> (f64, f64) {
        let s = sigmoid(t);
        (lo + (hi - lo) * s, (hi - lo) * s * (1.0 - s))
    }

    /// `c` and `dc/dθ` (0 without the per-quad term).
    fn c(&self) -> (f64, f64) {
        self.theta
            .get(4)
            .map_or((0.0, 0.0), |&t| Self::bounded(t, self.bounds.c))
    }

    fn params_f64(&self) -> Params {
        Params {
            k: self.theta[0].exp(),
            a: Self::bounded(self.theta[1], self.bounds.a).0,
            b: Self::bounded(self.theta[2], self.bounds.b).0,
            c: self.c().0,
            m: Self::bounded(self.theta[3], self.bounds.m).0,
            family: self.family,
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let params = self.params_f64();
        let r = DVector::from_iterator(
            self.points.len(),
            self.points
                .iter()
                .zip(self.weights)
                .map(|(q, w)| (predict(self.curve, &params, q.g, q.p) - q.y) * w),
        );
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<OMatrix<f64, Dyn, Dyn>> {
        let k = self.theta[0].exp();
        let (a, da) = Self::bounded(self.theta[1], self.bounds.a);
        let (b, db) = Self::bounded(self.theta[2], self.bounds.b);
        let (_, dm) = Self::bounded(self.theta[3], self.bounds.m);
        let (c, dc) = self.c();
        let e = self.family.g_power();
        let mut j = OMatrix::<f64, Dyn, Dyn>::zeros(self.points.len(), self.theta.len());
        for (i, (q, w)) in self.points.iter().zip(self.weights).enumerate() {
            let gg = q.g as f64 + a;
            let pp = q.p as f64 + b;
            let x = self.family.g_pow_f64(gg) * pp * pp;
            // dX/da = e·X/G, dX/db = 2·X/P.
            let (dxa, dxb) = (e * x / gg, 2.0 * x / pp);
            let row = match self.curve {
                // S = k·X + c·G² + m; d(c·G²)/da = 2·c·G.
                Curve::Size => [
                    k * x,
                    (k * dxa + 2.0 * c * gg) * da,
                    k * dxb * db,
                    dm,
                    gg * gg * dc,
                ],
                // Q = m − k/X; d(−k/X)/dX = k/X².
                Curve::Quality => {
                    let w = k / (x * x);
                    [-k / x, w * dxa * da, w * dxb * db, dm, 0.0]
                }
            };
            for (col, v) in row.iter().take(self.theta.len()).enumerate() {
                j[(i, col)] = v * w;
            }
        }
        j.iter().all(|v| v.is_finite()).then_some(j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use levenberg_marquardt::differentiate_numerically;

    fn grid_points(curve: Curve, truth: &Params) -> Vec<Point> {
        let mut out = Vec::new();
        for g in [16, 32, 64, 128, 256] {
            for p in [5, 9, 13, 17] {
                out.push(Point {
                    g,
                    p,
                    y: predict(curve, truth, g, p),
                });
            }
        }
        out
    }

    #[test]
    fn jacobian_matches_numerical_derivative() {
        for curve in [Curve::Size, Curve::Quality] {
            for family in Family::ALL {
                let with_c = has_c(curve, family);
                let truth = Params {
                    k: if curve == Curve::Size { 3.0 } else { 2.0e5 },
                    a: 4.0,
                    b: 1.0,
                    c: if with_c { 40.0 } else { 0.0 },
                    m: if curve == Curve::Size { 5.0e4 } else { 0.95 },
                    family,
                };
                let pts = grid_points(curve, &truth);
                let domain = Domain::of_points(&pts).unwrap();
                let bounds = Bounds::new(curve, domain, &pts);
                let start = Params {
                    k: truth.k * 1.3,
                    a: 2.0,
                    b: 0.5,
                    c: truth.c * 0.5,
                    m: truth.m * 0.5,
                    family,
                };
                let w = weights(curve, &pts);
                let mut problem = Problem::new(curve, family, &pts, bounds, &w, &start);
                let analytic = problem.jacobian().unwrap();
                let numeric = differentiate_numerically(&mut problem).unwrap();
                for (x, y) in analytic.iter().zip(numeric.iter()) {
                    assert!(
                        (x - y).abs() <= 1e-5 * x.abs().max(y.abs()).max(1e-6),
                        "{curve:?} {family:?}: {x} vs {y}"
                    );
                }
            }
        }
    }

    #[test]
    fn recovers_exact_parameters() {
        for family in Family::ALL {
            let size = Params {
                k: 2.5,
                a: 3.0,
                b: 1.0,
                c: if family == Family::Quads { 300.0 } else { 0.0 },
                m: 40_000.0,
                family,
            };
            let pts = grid_points(Curve::Size, &size);
            let d = Domain::of_points(&pts).unwrap();
            let f = fit(Curve::Size, &pts, d, FamilyChoice::Auto).unwrap();
            assert_eq!(f.best.params.family, family);
            let rel = f.best.residuals.rmse / 40_000.0;
            assert!(rel < 1e-6, "{family:?}: {:?}", f.best);
            if family == Family::Quads {
                assert!((f.best.params.c / 300.0 - 1.0).abs() < 1e-4, "{:?}", f.best);
                continue;
            }
            let quality = Params {
                k: 3.0e4,
                a: 2.0,
                b: 0.5,
                c: 0.0,
                m: 0.96,
                family,
            };
            let pts = grid_points(Curve::Quality, &quality);
            let f = fit(Curve::Quality, &pts, d, FamilyChoice::Auto).unwrap();
            assert_eq!(f.best.params.family, family);
            assert!(f.best.residuals.rmse < 1e-6, "{family:?}: {:?}", f.best);
            assert!((f.best.params.m - 0.96).abs() < 1e-4, "{:?}", f.best);
        }
    }

    #[test]
    fn too_few_points_is_an_error() {
        let pts = [
            Point {
                g: 16,
                p: 5,
                y: 1.0,
            },
            Point {
                g: 32,
                p: 5,
                y: 2.0,
            },
            Point {
                g: 64,
                p: 5,
                y: 3.0,
            },
            Point {
                g: 128,
                p: 5,
                y: 4.0,
            },
        ];
        let d = Domain::of_points(&pts).unwrap();
        assert!(matches!(
            fit(Curve::Size, &pts, d, FamilyChoice::Auto),
            Err(FitError::TooFewPoints { patches: 1, .. })
        ));
    }
}
