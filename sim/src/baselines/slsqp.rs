//! SLSQP baseline: the continuous relaxation in (g, p), solved with the
//! `slsqp` crate and mapped back to configurations.
//!
//! Each object's size and quality become continuous functions of (g, p):
//! its fitted profile when the scene gives one, otherwise bilinear
//! interpolation of its table over the g × p grid (the table must then be
//! a full grid). SLSQP maximises the total quality subject to
//! `Σ S_i(g_i, p_i) ≤ H` within each object's g and p range, starting from
//! the smallest (g, p). The solution is mapped to configurations:
//! 1. each object's nearest configuration in (g, p) (ranges normalised);
//!    if that plan fits, done;
//! 2. otherwise each object's nearest configuration whose size is within
//!    the size the relaxation gave it; if that plan fits, done;
//! 3. otherwise it fails, as the paper's SLSQP baseline can.
//!
//! **Geometry** is discrete, so it is not relaxed: each object is given one
//! of its geometries (planes, mesh), the continuous problem is solved over
//! that geometry's profile (or table) and rounded to that geometry's
//! configurations as above, once per assignment of geometries to objects,
//! and the best feasible plan is kept (higher total quality, then fewer
//! units; ties to the earlier assignment, planes first). A planes-only
//! scene has one assignment, so its plan is as before. Beyond
//! [`MAX_ASSIGNMENTS`] combinations only the uniform assignments are
//! tried (every object planes where it can, and every object mesh where
//! it can). When no assignment gives a feasible plan, the first one's
//! error is returned.

use super::problem::{Cand, Obj, Problem};
use super::{Method, Plan, PlanError};
use crate::geometry::Geometry;
use crate::scene_file::Profile;
use slsqp::{FailStatus, StopTols};

/// Most geometry assignments solved one by one (2^6: six objects with both
/// geometries); more fall back to the uniform assignments.
pub(crate) const MAX_ASSIGNMENTS: usize = 64;

pub(crate) fn plan(problem: &Problem) -> Result<Plan, PlanError> {
    problem.check_cheapest_fits()?;
    let mut best: Option<Plan> = None;
    let mut first_err: Option<PlanError> = None;
    for assignment in assignments(problem) {
        match solve(problem, &assignment) {
            Ok(p) => {
                let wins = best.as_ref().is_none_or(|b| {
                    (p.total_quality_q, std::cmp::Reverse(p.total_units))
                        > (b.total_quality_q, std::cmp::Reverse(b.total_units))
                });
                if wins {
                    best = Some(p);
                }
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    best.ok_or_else(|| {
        first_err.unwrap_or_else(|| PlanError::Internal("slsqp: no geometry assignment".into()))
    })
}

/// The geometry of each object, per assignment to try (see the module docs).
fn assignments(problem: &Problem) -> Vec<Vec<Geometry>> {
    let per_object: Vec<Vec<Geometry>> = problem
        .objects
        .iter()
        .map(|o| {
            Geometry::ALL
                .into_iter()
                .filter(|&g| o.cands.iter().any(|c| c.geometry == g))
                .collect()
        })
        .collect();
    let combinations = per_object
        .iter()
        .try_fold(1usize, |n, g| n.checked_mul(g.len()))
        .filter(|&n| n <= MAX_ASSIGNMENTS);
    if combinations.is_none() {
        let mut out: Vec<Vec<Geometry>> = Vec::new();
        for want in Geometry::ALL {
            let a: Vec<Geometry> = per_object
                .iter()
                .map(|gs| if gs.contains(&want) { want } else { gs[0] })
                .collect();
            if !out.contains(&a) {
                out.push(a);
            }
        }
        return out;
    }
    // Cartesian product, the first object varying slowest.
    let mut out: Vec<Vec<Geometry>> = vec![Vec::new()];
    for gs in &per_object {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                gs.iter().map(move |&g| {
                    let mut a = prefix.clone();
                    a.push(g);
                    a
                })
            })
            .collect();
    }
    out
}

/// The SLSQP plan with object i restricted to geometry `assignment[i]`.
fn solve(problem: &Problem, assignment: &[Geometry]) -> Result<Plan, PlanError> {
    let models = problem
        .objects
        .iter()
        .zip(assignment)
        .map(|(o, &geometry)| Model::new(o, geometry))
        .collect::<Result<Vec<_>, _>>()?;
    let n = models.len();
    let budget = (problem.budget_units as f64 * problem.unit.0 as f64).max(1.0);
    // Variables: per object (x_g, x_p) in [0, 1], mapped to its g and p range.
    let objective = |x: &[f64], grad: Option<&mut [f64]>, _: &mut ()| -> f64 {
        let mut total = 0.0;
        let mut gbuf = vec![0.0; 2 * n];
        for (i, m) in models.iter().enumerate() {
            let e = m.eval(x[2 * i], x[2 * i + 1]);
            total += e.q;
            gbuf[2 * i] = -e.dq.0 / n as f64;
            gbuf[2 * i + 1] = -e.dq.1 / n as f64;
        }
        if let Some(g) = grad {
            g.copy_from_slice(&gbuf);
        }
        -total / n as f64
    };
    let constraint = |x: &[f64], grad: Option<&mut [f64]>, _: &mut ()| -> f64 {
        let mut total = 0.0;
        let mut gbuf = vec![0.0; 2 * n];
        for (i, m) in models.iter().enumerate() {
            let e = m.eval(x[2 * i], x[2 * i + 1]);
            total += e.s;
            gbuf[2 * i] = e.ds.0 / budget;
            gbuf[2 * i + 1] = e.ds.1 / budget;
        }
        if let Some(g) = grad {
            g.copy_from_slice(&gbuf);
        }
        total / budget - 1.0
    };
    let x0 = vec![0.0; 2 * n];
    let bounds = vec![(0.0, 1.0); 2 * n];
    let tols = StopTols {
        ftol_rel: 1e-10,
        xtol_rel: 1e-9,
        ..StopTols::default()
    };
    // The solver is machine-translated C: contain any panic as a failure.
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        slsqp::minimize(objective, &x0, &bounds, &[constraint], (), 2000, Some(tols))
    }))
    .map_err(|_| PlanError::Slsqp("the solver panicked".into()))?;
    let x = match outcome {
        Ok((_, x, _)) => x,
        // Round-off limited: the iterate is still usable.
        Err((FailStatus::RoundoffLimited, x, _)) => x,
        Err((status, _, _)) => return Err(PlanError::Slsqp(format!("SLSQP failed ({status:?})"))),
    };
    if x.len() != 2 * n || x.iter().any(|v| !v.is_finite()) {
        return Err(PlanError::Slsqp("SLSQP returned a non-finite point".into()));
    }
    let points: Vec<(f64, f64, f64)> = models
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let (xg, xp) = (x[2 * i].clamp(0.0, 1.0), x[2 * i + 1].clamp(0.0, 1.0));
            let (g, p) = m.gp(xg, xp);
            (g, p, m.eval(xg, xp).s)
        })
        .collect();

    // 1. Nearest configurations.
    let rounded: Vec<usize> = problem
        .objects
        .iter()
        .zip(&models)
        .zip(&points)
        .map(|((o, m), &(g, p, _))| {
            nearest(o, m, g, p, f64::INFINITY).ok_or_else(|| {
                PlanError::Internal(format!(
                    "slsqp: object `{}` has no {} configuration",
                    o.name(),
                    m.geometry
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    let plan = problem.plan(Method::Slsqp, &rounded)?;
    if plan.feasible {
        return Ok(plan);
    }
    // 2. Nearest within each object's relaxed size.
    let mut within = Vec::with_capacity(n);
    for ((o, m), &(g, p, s)) in problem.objects.iter().zip(&models).zip(&points) {
        within.push(nearest(o, m, g, p, s).ok_or_else(|| {
            PlanError::Slsqp(format!(
                "object `{}`: no configuration within the {:.2} MB the relaxation gave it",
                o.name(),
                s / 1e6
            ))
        })?);
    }
    let plan = problem.plan(Method::Slsqp, &within)?;
    if plan.feasible {
        return Ok(plan);
    }
    Err(PlanError::Slsqp(format!(
        "the relaxation's solution maps to {:.2} MB, over the budget of {:.2} MB",
        plan.total_size_bytes as f64 / 1e6,
        plan.budget_bytes as f64 / 1e6
    )))
}

/// Position of the configuration of the model's geometry nearest (g, p) in
/// normalised distance among those of at most `max_size` bytes; ties to
/// smaller size, index.
fn nearest(o: &Obj, m: &Model, g: f64, p: f64, max_size: f64) -> Option<usize> {
    let (rg, rp) = m.ranges();
    let key = |c: &Cand| {
        let dg = (c.g as f64 - g) / rg;
        let dp = (c.p as f64 - p) / rp;
        dg * dg + dp * dp
    };
    o.cands
        .iter()
        .enumerate()
        .filter(|(_, c)| c.geometry == m.geometry)
        // Profile sizes were rounded up to whole bytes: compare likewise.
        .filter(|(_, c)| c.size.0 as f64 <= max_size.ceil())
        .min_by(|(_, a), (_, b)| {
            key(a)
                .total_cmp(&key(b))
                .then(a.size.cmp(&b.size))
                .then(a.index.cmp(&b.index))
        })
        .map(|(k, _)| k)
}

/// Size and quality with their gradients in the normalised variables.
struct Eval {
    s: f64,
    q: f64,
    ds: (f64, f64),
    dq: (f64, f64),
}

/// A continuous model of one object in one geometry.
struct Model<'s> {
    geometry: Geometry,
    curves: Curves<'s>,
}

/// Its size and quality as continuous functions of (g, p).
enum Curves<'s> {
    Profile {
        profile: &'s Profile,
        g: (f64, f64),
        p: (f64, f64),
    },
    Grid {
        gs: Vec<f64>,
        ps: Vec<f64>,
        /// `[ig * ps.len() + ip]`.
        size: Vec<f64>,
        quality: Vec<f64>,
    },
}

fn range(values: impl Iterator<Item = u32>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v as f64), hi.max(v as f64))
    })
}

impl<'s> Model<'s> {
    fn new(o: &Obj<'s>, geometry: Geometry) -> Result<Model<'s>, PlanError> {
        Ok(Model {
            geometry,
            curves: Curves::new(o, geometry)?,
        })
    }

    fn ranges(&self) -> (f64, f64) {
        self.curves.ranges()
    }

    fn gp(&self, xg: f64, xp: f64) -> (f64, f64) {
        self.curves.gp(xg, xp)
    }

    fn eval(&self, xg: f64, xp: f64) -> Eval {
        self.curves.eval(xg, xp)
    }
}

impl<'s> Curves<'s> {
    fn new(o: &Obj<'s>, geometry: Geometry) -> Result<Curves<'s>, PlanError> {
        if let Some(profile) = o.entry.profile_of(geometry) {
            return Ok(Curves::Profile {
                profile,
                g: range(profile.g.iter().copied()),
                p: range(profile.p.iter().copied()),
            });
        }
        let cands: Vec<&Cand> = o.cands.iter().filter(|c| c.geometry == geometry).collect();
        let mut gs: Vec<u32> = cands.iter().map(|c| c.g).collect();
        let mut ps: Vec<u32> = cands.iter().map(|c| c.p).collect();
        gs.sort_unstable();
        gs.dedup();
        ps.sort_unstable();
        ps.dedup();
        let mut size = vec![f64::NAN; gs.len() * ps.len()];
        let mut quality = vec![f64::NAN; gs.len() * ps.len()];
        for c in &cands {
            let ig = gs.binary_search(&c.g).unwrap_or(0);
            let ip = ps.binary_search(&c.p).unwrap_or(0);
            size[ig * ps.len() + ip] = c.size.0 as f64;
            quality[ig * ps.len() + ip] = c.quality;
        }
        if size.iter().any(|v| v.is_nan()) {
            return Err(PlanError::Slsqp(format!(
                "object `{}`: the continuous relaxation needs a profile or a full g × p grid of configurations{}; it has {} of {} × {}",
                o.name(),
                if geometry.is_planes() { String::new() } else { format!(" ({geometry})") },
                cands.len(),
                gs.len(),
                ps.len()
            )));
        }
        Ok(Curves::Grid {
            gs: gs.into_iter().map(f64::from).collect(),
            ps: ps.into_iter().map(f64::from).collect(),
            size,
            quality,
        })
    }

    fn bounds(&self) -> ((f64, f64), (f64, f64)) {
        match self {
            Curves::Profile { g, p, .. } => (*g, *p),
            Curves::Grid { gs, ps, .. } => ((gs[0], gs[gs.len() - 1]), (ps[0], ps[ps.len() - 1])),
        }
    }

    /// Width of the g and p ranges (1 when a range is a single value).
    fn ranges(&self) -> (f64, f64) {
        let ((g0, g1), (p0, p1)) = self.bounds();
        let w = |lo: f64, hi: f64| if hi > lo { hi - lo } else { 1.0 };
        (w(g0, g1), w(p0, p1))
    }

    fn gp(&self, xg: f64, xp: f64) -> (f64, f64) {
        let ((g0, g1), (p0, p1)) = self.bounds();
        (g0 + xg * (g1 - g0), p0 + xp * (p1 - p0))
    }

    fn eval(&self, xg: f64, xp: f64) -> Eval {
        let ((g0, g1), (p0, p1)) = self.bounds();
        let (sg, sp) = (g1 - g0, p1 - p0);
        let (g, p) = self.gp(xg.clamp(0.0, 1.0), xp.clamp(0.0, 1.0));
        match self {
            Curves::Profile { profile, .. } => {
                let (dsg, dsp) = profile.size_gradient(g, p);
                let (dqg, dqp) = profile.quality_gradient(g, p);
                Eval {
                    s: profile.size_at(g, p),
                    q: profile.quality_at(g, p),
                    ds: (dsg * sg, dsp * sp),
                    dq: (dqg * sg, dqp * sp),
                }
            }
            Curves::Grid {
                gs,
                ps,
                size,
                quality,
            } => {
                let (ig, tg, wg) = cell(gs, g);
                let (ip, tp, wp) = cell(ps, p);
                let np = ps.len();
                let at = |v: &[f64], a: usize, b: usize| v[a * np + b];
                let (ig1, ip1) = ((ig + 1).min(gs.len() - 1), (ip + 1).min(np - 1));
                let bil = |v: &[f64]| {
                    let (f00, f10, f01, f11) = (
                        at(v, ig, ip),
                        at(v, ig1, ip),
                        at(v, ig, ip1),
                        at(v, ig1, ip1),
                    );
                    let f = (1.0 - tg) * (1.0 - tp) * f00
                        + tg * (1.0 - tp) * f10
                        + (1.0 - tg) * tp * f01
                        + tg * tp * f11;
                    let dg = if wg > 0.0 {
                        ((1.0 - tp) * (f10 - f00) + tp * (f11 - f01)) / wg
                    } else {
                        0.0
                    };
                    let dp = if wp > 0.0 {
                        ((1.0 - tg) * (f01 - f00) + tg * (f11 - f10)) / wp
                    } else {
                        0.0
                    };
                    (f, dg * sg, dp * sp)
                };
                let (s, dsg, dsp) = bil(size);
                let (q, dqg, dqp) = bil(quality);
                Eval {
                    s,
                    q,
                    ds: (dsg, dsp),
                    dq: (dqg, dqp),
                }
            }
        }
    }
}

/// The grid cell holding `v`: (lower index, fraction in the cell, cell width).
fn cell(axis: &[f64], v: f64) -> (usize, f64, f64) {
    if axis.len() < 2 {
        return (0, 0.0, 0.0);
    }
    let i = axis
        .partition_point(|&a| a <= v)
        .saturating_sub(1)
        .min(axis.len() - 2);
    let w = axis[i + 1] - axis[i];
    (i, ((v - axis[i]) / w).clamp(0.0, 1.0), w)
}
