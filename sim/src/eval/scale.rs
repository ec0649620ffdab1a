//! The sizes an evaluation runs at.
//!
//! - [`Scale::Paper`] (the default of `nerflex eval`): 800 × 800 built-in
//!   captures — the NeRF-synthetic resolution the paper's scenes have — with
//!   **50 training and 12 held-out views**. 50 is the floor the issue sets
//!   for training a field: a trained field's cost per iteration does not
//!   depend on the number of views, but rendering the capture, carving and
//!   colouring (the hull baker), loading, and the segmentation's per-view
//!   analysis and enlargement all grow linearly with it, and so does
//!   memory (62 views × 12 view sets of 2.56 MB at 800² ≈ 1.9 GB per
//!   scene). 12 held-out views: the intervals are over views, and a
//!   percentile bootstrap needs about ten to be usable; each held-out view
//!   costs one render + SSIM + LPIPS (≈ 1 s at 800²) per realised plan and
//!   per profiler sample bake, the largest measuring cost of the run.
//! - [`Scale::Quick`]: 128 × 128 with 16 training and 10 held-out views,
//!   1000 turntable frames and the real composite at 128 — the same
//!   pipeline and report (with intervals) in minutes, for checking the
//!   machinery, never for the paper's claims.
//! - [`Scale::Reduced`]: `nerflex run`'s defaults: 160 × 160, 16 training
//!   and 10 held-out views, 200-pixel real composite. The report committed
//!   before the paper-scale run had these sizes with 4 held-out views;
//!   since session 9 the main job bakes trained assets and prints whether
//!   each network's quality range exceeds the scatter of its views
//!   ([`crate::pipeline::range`]), and four views gave intervals too wide
//!   to say (a percentile bootstrap wants about ten).

use crate::bake::trained::TrainedParams;
use crate::pipeline::Baker;
use crate::train::trainer::{Level, TrainSettings};

/// An evaluation's sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Scale {
    /// 800 × 800, 50 training + 12 held-out views.
    Paper,
    /// 128 × 128, 16 + 10 views, 1000 frames.
    Quick,
    /// 160 × 160, 16 + 10 views (`nerflex run`).
    Reduced,
}

/// The numbers of a [`Scale`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sizes {
    /// Built-in capture side, pixels.
    pub size: u32,
    /// Training views.
    pub train_views: usize,
    /// Held-out views.
    pub test_views: usize,
    /// Turntable frames.
    pub frames: usize,
    /// Side of the composed real capture, pixels.
    pub real_size: u32,
}

impl Scale {
    /// Its numbers.
    pub fn sizes(self) -> Sizes {
        match self {
            Scale::Paper => Sizes {
                size: 800,
                train_views: 50,
                test_views: 12,
                frames: 2000,
                real_size: 800,
            },
            Scale::Quick => Sizes {
                size: 128,
                train_views: 16,
                test_views: 10,
                frames: 1000,
                real_size: 128,
            },
            Scale::Reduced => Sizes {
                size: 160,
                train_views: 16,
                test_views: 10,
                frames: 2000,
                real_size: 200,
            },
        }
    }

    /// How the trained baker's fields are trained at this scale
    /// (`docs/evaluation.md`, "Training budgets").
    pub fn train_settings(self) -> TrainSettings {
        // Measured choices and the reasons: docs/evaluation.md, "Training
        // budgets".
        let (levels, batch) = match self {
            // One 128³ level of 800 steps at 8192 rays (session 21): the
            // 400 × 4096 of session 7 held spring's network out at 24.1 dB
            // with haze between its coils, and its bakes fell from g = 32
            // to 64; 4× the rays lifted the fields by 1.4–2.6 dB and,
            // with two fine-tune epochs, the bakes rise with g
            // (docs/evaluation.md, "Session 21").
            Scale::Paper => (
                vec![Level {
                    res: 128,
                    iters: 800,
                }],
                8192,
            ),
            // 16 views of an enlarged network at 128–160 px: one 48³
            // level held out as well as 64³ → 96³ at a third of the time.
            Scale::Quick | Scale::Reduced => (
                vec![Level {
                    res: 48,
                    iters: 300,
                }],
                2048,
            ),
        };
        TrainSettings {
            levels,
            batch,
            // Measured with TV every step; keeps the stores' field keys.
            tv_every: 1,
            ..TrainSettings::default()
        }
    }

    /// How the trained baker bakes a field at this scale (`grid` and
    /// `patch` are set per bake).
    pub fn bake_settings(self) -> TrainedParams {
        let mut p = TrainedParams::new(DEFAULT_GRID, DEFAULT_PATCH);
        p.finetune.epochs = match self {
            // 50 views × 800² pixels: one pass is ≈ 8–10 M pixel steps
            // per network, ≈ 7 s since the fine-tune got faster (≈ 30 s
            // when half a pass was chosen). Half a pass left the texels
            // under-trained, most where g is larger (more texels, fewer
            // pixels each), so bakes fell with g; two passes gain
            // 0.01–0.03 SSIM and rise (docs/evaluation.md, "Session 21").
            Scale::Paper => 2.0,
            Scale::Quick | Scale::Reduced => 3.0,
        };
        p
    }

    /// The trained baker with this scale's settings.
    pub fn baker(self) -> Baker {
        Baker::trained(self.train_settings(), self.bake_settings())
    }

    /// The name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Scale::Paper => "paper",
            Scale::Quick => "quick",
            Scale::Reduced => "reduced",
        }
    }
}

/// The profiler's sample points and the planner's configurations of a
/// [`Scale`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Configs {
    /// Sample points: g range (variable step from the low end, by
    /// `sample_step`).
    pub sample_grid: (u32, u32),
    /// Sample points: p range (low, middle, high).
    pub sample_patch: (u32, u32),
    /// How g steps from one sample point to the next.
    pub sample_step: crate::fit::sampling::Step,
    /// The planner's g values.
    pub space_grid: Vec<u32>,
    /// The planner's p values.
    pub space_patch: Vec<u32>,
}

impl Scale {
    /// The configurations profiled and planned over at this scale.
    ///
    /// Reduced (`nerflex run`): samples g ∈ {16, 32, 64} (the step read as
    /// ×2) × p ∈ {3, 10, 17}, planning over g ∈ {16, 24, 32, 48, 64} ×
    /// p ∈ {3, 5, …, 17}. Until session 9 it sampled g ∈ {16, 48, 144} and
    /// planned up to 144; on trained assets at 160 px every network's SSIM
    /// peaked at g = 16–48 and fell at 144 by 0.015–0.08 (about 1.1 pixels
    /// per voxel: most quads seen by few training pixels), its fits
    /// interpolated over the fall, and the DP spent 104 of its 135 MB on
    /// g = 144 bakes that measured below the g = 48 ones (docs/evaluation.md,
    /// "Session 9").
    ///
    /// Paper: samples g ∈ {16, 32, 64} (the step read as ×2) × p ∈ {3,
    /// 10, 17}, planning over g ∈ {16, 24, 32, 48, 64, 96}. Measured on
    /// Scene 4 at 800 px on trained assets (`results/eval-paper-scene4/`):
    /// the networks' SSIM rose by 0.06–0.13 from (16, 3) to (48, 17) and
    /// was flat or fell (−0.001 to −0.008) from g = 48 to 144, whose
    /// sample bakes were half of a 55-minute scene. Points at 16, 32, 64
    /// sample the rise the fits need instead of the plateau.
    ///
    /// Quick stops at
    /// g = 96 (samples g ∈ {8, 24, 72}): its 128-pixel views hold less than
    /// one pixel per voxel beyond that, so larger grids add bytes and bake
    /// time (a g = 144, p = 17 hull bake of a 128-pixel network: 9.6 s,
    /// against 2.9 s at g = 72) but no detail the held-out views can show.
    /// Single- and Block-NeRF keep the paper's (128, 17) at every scale.
    pub fn configs(self) -> Configs {
        let patches = vec![3, 5, 7, 9, 11, 13, 15, 17];
        use crate::fit::sampling::Step;
        match self {
            Scale::Reduced => Configs {
                sample_grid: (16, 64),
                sample_patch: (3, 17),
                sample_step: Step::Double,
                space_grid: vec![16, 24, 32, 48, 64],
                space_patch: patches,
            },
            Scale::Paper => Configs {
                sample_grid: (16, 64),
                sample_patch: (3, 17),
                sample_step: Step::Double,
                space_grid: vec![16, 24, 32, 48, 64, 96],
                space_patch: patches,
            },
            Scale::Quick => Configs {
                sample_grid: (8, 72),
                sample_patch: (3, 17),
                sample_step: Step::Triple,
                space_grid: vec![8, 12, 16, 24, 32, 48, 64, 72, 96],
                space_patch: patches,
            },
        }
    }
}

/// Placeholders of [`Scale::bake_settings`] (replaced per bake).
const DEFAULT_GRID: u32 = 128;
const DEFAULT_PATCH: u32 = 17;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_scale_meets_the_issue_floors() {
        let p = Scale::Paper.sizes();
        assert_eq!(p.size, 800);
        assert!(p.train_views >= 50 && p.test_views >= 10);
        // Quick keeps enough held-out views for an interval.
        assert!(Scale::Quick.sizes().test_views >= 10);
        assert_eq!(Scale::Reduced.sizes().size, 160);
    }

    #[test]
    fn every_scale_plans_over_its_sample_points() {
        for s in [Scale::Paper, Scale::Quick, Scale::Reduced] {
            let c = s.configs();
            let plan = crate::fit::sampling::variable_step(
                c.sample_grid.0..=c.sample_grid.1,
                c.sample_patch.0..=c.sample_patch.1,
                c.sample_step,
            )
            .unwrap();
            // Three g values for the fits, each one the planner can choose,
            // and a space that does not reach far past the samples.
            assert_eq!(plan.grids.len(), 3, "{s:?}");
            assert!(plan.grids.iter().all(|g| c.space_grid.contains(g)), "{s:?}");
            let top = *plan.grids.last().unwrap();
            assert!(c.space_grid.iter().all(|&g| g <= top * 3 / 2), "{s:?}");
        }
        assert!(Scale::Quick.configs().space_grid.iter().all(|&g| g <= 96));
    }

    #[test]
    fn every_scale_trains_with_valid_settings() {
        for s in [Scale::Paper, Scale::Quick, Scale::Reduced] {
            s.train_settings().validate().unwrap();
            assert_eq!(s.baker().name(), crate::pipeline::bakes::TRAINED_BAKER);
        }
    }
}
