//! The feature lattice's resolution chosen per object on training views
//! held back from the bake.
//!
//! The default lattice (one cell per two pixels of the object) suits
//! lego's texture and gear's edges, but over-fits glossy objects: a
//! lattice that fine can paint each training view's highlight into the
//! features it reaches, and ball (64, 9) scores 0.9753 SSIM with the
//! default 215³ cells against 0.9819 with 54³ (docs/baking.md, "Session
//! 34"), while lego loses 0.22 dB at 192³. So the choice is measured, not
//! ruled: every [`HOLD_BACK_EVERY`]-th training view is held back, the
//! object is baked from the others at each candidate resolution (the
//! default and [`FRACTIONS`] of it), each bake is rendered by the phone's
//! shader on the held-back views, and the best mean SSIM wins (the finer
//! lattice within [`TIE_SSIM`] of it): the quantity the profiler models
//! and the selector maximises. (On ball
//! (64, 9) the held-back views' PSNR barely tells the lattices apart,
//! 30.71, 30.69 and 30.47 dB for 215³, 108³ and 54³, while their SSIM,
//! 0.9699, 0.9746 and 0.9776, ranks them as the test views do; session
//! 36.) The test views are never looked at.

use image::GrayImage;

use super::super::sweep::{self, Measured, RenderFn};
use super::super::{BakeView, Silhouette};
use super::{bake, TrainedParams};
use crate::train::field::RadianceField;

/// Every this many training views, one is held back (from the fourth, so
/// that the held-back views spread over the capture's order).
pub const HOLD_BACK_EVERY: usize = 8;

/// The candidate resolutions as fractions of the default one, finest
/// first (near-ties go to the finer, [`TIE_SSIM`]).
pub const FRACTIONS: [f32; 3] = [1.0, 0.5, 0.25];

/// The (g, p) a sweep chooses each object's lattice at: a middle
/// configuration, cheap to bake four times (ball and vase chose there in
/// session 36).
pub const SWEEP_CONFIG: (u32, u32) = (64, 9);

/// The coarsest lattice a candidate may have, cells per edge.
pub const MIN_CELLS: u32 = 8;

/// Held-back SSIM by which a coarser lattice must beat a finer one to be
/// chosen over it. Smaller gaps lie within the bake's seed noise on held
/// out views (0.0007–0.0020), and in both such near-ties measured the
/// finer lattice scored higher on the test views at 19 of 24 (g, p):
/// gear 238³ over 119³ (gap 0.0003) at 15 of 20, +0.0005 on average,
/// lower only at g = 16; spring 129³ over 65³ (gap 0.0016) at 4 of 4
/// (docs/baking.md, "Session 45").
pub const TIE_SSIM: f64 = 0.002;

/// One candidate's bake, measured on the held-back views.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Cells per edge.
    pub cells: u32,
    /// Mean PSNR over the held-back views, dB.
    pub psnr: f64,
    /// Mean SSIM over them.
    pub ssim: f64,
    /// Wall time of its bake and measurement, seconds.
    pub seconds: f64,
}

/// What [`choose`] measured and chose.
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeChoice {
    /// Training views the candidates were baked from.
    pub train_views: usize,
    /// Training views held back to judge them.
    pub held_back: usize,
    /// Every candidate, finest first.
    pub candidates: Vec<Candidate>,
    /// The chosen cells per edge.
    pub chosen: u32,
}

/// The indices of the views held back out of `n`: every
/// [`HOLD_BACK_EVERY`]-th from the fourth, and at least one while two stay
/// to bake from; none with fewer than three views.
pub fn held_back(n: usize) -> Vec<usize> {
    if n < 3 {
        return Vec::new();
    }
    let start = (HOLD_BACK_EVERY / 2).min(n - 1);
    let picked: Vec<usize> = (start..n).step_by(HOLD_BACK_EVERY).collect();
    if picked.is_empty() {
        vec![n - 1]
    } else {
        picked
    }
}

/// The candidate resolutions for a default of `default_cells`: the
/// default, then [`FRACTIONS`] of it that are coarser, distinct and at
/// least [`MIN_CELLS`].
pub fn candidates(default_cells: u32) -> Vec<u32> {
    let mut out = vec![default_cells];
    for f in &FRACTIONS[1..] {
        let c = ((default_cells as f32 * f).round() as u32).max(MIN_CELLS);
        if c < default_cells && !out.contains(&c) {
            out.push(c);
        }
    }
    out
}

/// The lattice to choose from `(cells, held-back SSIM)` candidates: the
/// finest whose SSIM is within [`TIE_SSIM`] of the best (a NaN score never
/// wins). `None` when none has a score.
pub fn pick(candidates: &[(u32, f64)]) -> Option<u32> {
    let best = candidates
        .iter()
        .map(|&(_, s)| s)
        .filter(|s| !s.is_nan())
        .fold(None, |b: Option<f64>, s| Some(b.map_or(s, |b| b.max(s))))?;
    candidates
        .iter()
        .filter(|&&(_, s)| s >= best - TIE_SSIM)
        .max_by_key(|&&(cells, _)| cells)
        .map(|&(cells, _)| cells)
}

/// Pixels of a held-back view that another object owns: scored as
/// perfect, as the held-out measure does ([`sweep::hide_unknown`]).
fn others(v: &BakeView<'_>) -> Option<GrayImage> {
    match v.silhouette {
        Silhouette::Alpha => None,
        Silhouette::Instance { mask, label } => Some(sweep::map_mask(mask, |m| {
            if m != 0 && m != label {
                255
            } else {
                0
            }
        })),
    }
}

/// Bakes `field` from all but the held-back training `views` at each
/// candidate lattice resolution (`params` otherwise as given; its
/// `feature_res`, if not 0, is the default the fractions apply to) and
/// returns the one whose bake `render`s the held-back views best (mean
/// SSIM; the finer within [`TIE_SSIM`] of it). Errors when there are too few views to
/// hold one back, or a bake fails.
pub fn choose(
    field: &dyn RadianceField,
    views: &[BakeView<'_>],
    params: &TrainedParams,
    render: &RenderFn<'_>,
) -> anyhow::Result<LatticeChoice> {
    let back = held_back(views.len());
    if back.is_empty() {
        anyhow::bail!(
            "--choose-feature-res: choosing the feature lattice needs at least 3 training views (one held back, two to bake from), got {}",
            views.len()
        );
    }
    let (mut train, mut judge) = (Vec::new(), Vec::new());
    for (i, v) in views.iter().enumerate() {
        if back.contains(&i) {
            judge.push(v);
        } else {
            train.push(*v);
        }
    }
    let test: Vec<_> = judge.iter().map(|v| (v.camera, v.image.clone())).collect();
    let hidden: Vec<Option<GrayImage>> = judge.iter().map(|v| others(v)).collect();
    let measure = |cells: u32| -> anyhow::Result<(Candidate, u32)> {
        let t = std::time::Instant::now();
        let mut p = params.clone();
        p.feature_res = cells;
        let tb = bake(field, &train, &p)?;
        let res = tb.stats.lattice_res;
        let asset = tb.baked.into_asset()?;
        let m: Measured = sweep::measure_views_hiding(&asset, &test, &hidden, render, None, false)?;
        let c = Candidate {
            cells: res,
            psnr: m.mean.psnr,
            ssim: m.mean.ssim,
            seconds: t.elapsed().as_secs_f64(),
        };
        Ok((c, res))
    };
    // The default first: its resolution is what the fractions apply to.
    let (first, default_cells) = measure(params.feature_res)?;
    let mut all = vec![first];
    for cells in candidates(default_cells).into_iter().skip(1) {
        all.push(measure(cells)?.0);
    }
    let scored: Vec<(u32, f64)> = all.iter().map(|c| (c.cells, c.ssim)).collect();
    let best = pick(&scored).unwrap_or(default_cells);
    Ok(LatticeChoice {
        train_views: train.len(),
        held_back: judge.len(),
        candidates: all,
        chosen: best,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_are_held_back_spread_and_never_all() {
        assert!(held_back(2).is_empty());
        assert_eq!(held_back(3), vec![2]);
        assert_eq!(held_back(5), vec![4]);
        assert_eq!(held_back(20), vec![4, 12]);
        let b = held_back(90);
        assert_eq!(b.len(), 11);
        assert!(b.iter().all(|&i| i < 90));
        for n in 3..200 {
            let b = held_back(n);
            assert!(!b.is_empty() && b.len() + 2 <= n, "n = {n}");
        }
    }

    #[test]
    fn a_coarser_lattice_must_win_by_more_than_the_tie() {
        // Gear and spring (session 45): near-ties go to the finer.
        assert_eq!(
            pick(&[(238, 0.9487), (119, 0.9490), (60, 0.9432)]),
            Some(238)
        );
        assert_eq!(
            pick(&[(258, 0.9370), (129, 0.9477), (65, 0.9493)]),
            Some(129)
        );
        // Clear wins keep the coarser (ball, box).
        assert_eq!(
            pick(&[(215, 0.9699), (108, 0.9746), (54, 0.9776)]),
            Some(54)
        );
        assert_eq!(pick(&[(195, 0.9795), (98, 0.9818), (49, 0.9804)]), Some(98));
        // The order given does not matter, exact ties go to the finer, and
        // unscored candidates never win.
        assert_eq!(pick(&[(54, 0.97), (215, 0.97)]), Some(215));
        assert_eq!(pick(&[(54, 0.9), (215, f64::NAN)]), Some(54));
        assert_eq!(pick(&[(54, f64::NAN)]), None);
        assert_eq!(pick(&[]), None);
    }

    #[test]
    fn candidates_are_distinct_finest_first_and_bounded() {
        assert_eq!(candidates(329), vec![329, 165, 82]);
        assert_eq!(candidates(215), vec![215, 108, 54]);
        assert_eq!(candidates(20), vec![20, 10, 8]);
        assert_eq!(candidates(9), vec![9, 8]);
        assert_eq!(candidates(4), vec![4]);
    }
}
