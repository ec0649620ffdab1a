//! The optimisation: carve the visual hull, train a coarse grid inside it,
//! refine to finer grids where the coarse one found matter, Adam on random
//! ray batches drawn over all training views, on every core.

use std::time::Instant;

use glam::Vec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::adam::Adam;
use super::grid::{activate_density, SparseGrid};
use super::march::{self, GradBuf, GridRay, MarchBox, MarchParams, RayLoss, Scratch};
use super::pixels::{box_corners, PixelRay, PixelSet};
use super::tv::{self, Neighbours, TvWeights};
use crate::bake::carve::{self, Silhouettes, VoxelTest};
use crate::bake::sweep::ObjectViews;
use crate::bake::Aabb;

/// Raised whenever training changes what it produces for the same
/// [`TrainSettings`] (stores of trained fields key on it). 2: session 4's
/// losses, pruning and TV schedule.
pub const TRAINER_VERSION: u32 = 2;

/// One level of the coarse-to-fine schedule.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Level {
    /// Cells per edge.
    pub res: u32,
    /// Optimisation steps at this level.
    pub iters: u32,
}

/// Training settings (saved with the field).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainSettings {
    /// Coarse to fine; each level's resolution must be above the last.
    pub levels: Vec<Level>,
    /// Rays per step.
    pub batch: u32,
    /// SH degree of the colour (0–2).
    pub sh_degree: u32,
    /// Adam learning rate of the raw density at the start.
    pub lr_density: f32,
    /// Adam learning rate of the SH coefficients at the start.
    pub lr_color: f32,
    /// Factor the learning rates reach at the end of each level
    /// (exponential decay within a level).
    pub lr_final: f32,
    /// Sample spacing, cells of the current level.
    pub step: f32,
    /// A refined level keeps the cells whose coarse opacity per cell
    /// exceeds this (and their neighbours).
    pub keep_opacity: f32,
    /// Rays are drawn as `patch`×`patch` pixel patches (1: independent
    /// pixels).
    pub patch: u32,
    /// Seed of the ray draws.
    pub seed: u64,
    /// Weight of the per-sample colour loss (DVGO's `rgbper`).
    #[serde(default)]
    pub rgbper: f32,
    /// Samples of smaller weight pass no gradient (DVGO's
    /// `fast_color_thres`).
    #[serde(default)]
    pub skip_weight: f32,
    /// Every `prune_every` steps of a level (from the step `prune_every`
    /// on; 0: never), cells whose opacity stays below `prune_opacity` are
    /// skipped from then on ([`SparseGrid::prune_cells`]).
    #[serde(default)]
    pub prune_every: u32,
    /// See `prune_every`.
    #[serde(default)]
    pub prune_opacity: f32,
    /// Total variation of the raw density over lattice edges
    /// (`train::tv`).
    #[serde(default)]
    pub tv_density: f32,
    /// Total variation of the SH coefficients.
    #[serde(default)]
    pub tv_color: f32,
    /// The total variation is applied every `tv_every` steps with its
    /// weights multiplied by `tv_every` (its pass over the touched slots'
    /// neighbours costs as much as Adam's at 256³; DVGO's `tv_every`).
    #[serde(default = "one")]
    pub tv_every: u32,
    /// Weight of the entropy of each ray's final transmittance (DVGO's
    /// `entropy_last`).
    #[serde(default)]
    pub entropy: f32,
    /// Weight of the distortion loss (mip-NeRF 360; `march::RayLoss`).
    /// Left out of the serialised settings while 0, so the field stores'
    /// keys of earlier settings do not move.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub distortion: f32,
    /// The learning rates of every level after the first start at this
    /// fraction of `lr_density` / `lr_color` (1: each level restarts at
    /// full strength). Left out of the serialised settings while 1.
    #[serde(default = "one_f32", skip_serializing_if = "is_one")]
    pub finer_lr: f32,
}

impl Default for TrainSettings {
    fn default() -> Self {
        TrainSettings {
            levels: vec![
                Level {
                    res: 128,
                    iters: 1000,
                },
                Level {
                    res: 256,
                    iters: 2000,
                },
                // Session 12: a third level (chair +0.36 dB, +0.0056 SSIM
                // at 384³ against 256³ alone in about the same time).
                // Session 21: 4500 steps there (3000 before), which the
                // march's prefetching fits in 10 minutes: chair reaches
                // 0.965 SSIM (docs/training.md).
                Level {
                    res: 384,
                    iters: 4500,
                },
            ],
            batch: 8192,
            sh_degree: 1,
            lr_density: 0.5,
            lr_color: 0.3,
            lr_final: 0.1,
            step: 0.5,
            keep_opacity: 0.002,
            patch: 1,
            seed: 0,
            rgbper: 0.01,
            entropy: 0.001,
            distortion: 0.0,
            finer_lr: 1.0,
            skip_weight: 1e-4,
            tv_density: 1e-10,
            tv_color: 1e-10,
            prune_every: 100,
            // Session 10: TV every 4th step, and the time it frees spent
            // on more 256³ steps: lego 31.03 dB in 517 s (docs/training.md).
            tv_every: 4,
            prune_opacity: 1e-3,
        }
    }
}

impl TrainSettings {
    /// Checks the settings, naming the bad one.
    pub fn validate(&self) -> Result<(), String> {
        if self.levels.is_empty() {
            return Err("at least one level is needed".into());
        }
        let mut last = 0;
        for l in &self.levels {
            if !(4..=MAX_RES).contains(&l.res) || l.res <= last {
                return Err(format!(
                    "level resolutions must rise and lie in 4..={MAX_RES} (got {})",
                    l.res
                ));
            }
            last = l.res;
        }
        if !(1..=1 << 20).contains(&self.batch) {
            return Err(format!("batch must be in 1..=1048576 (got {})", self.batch));
        }
        if !(1..=64).contains(&self.patch) {
            return Err(format!("patch must be in 1..=64 (got {})", self.patch));
        }
        if self.sh_degree > super::sh::MAX_DEGREE {
            return Err(format!(
                "SH degree must be 0, 1 or 2 (got {})",
                self.sh_degree
            ));
        }
        let positive = [
            ("lr_density", self.lr_density),
            ("lr_color", self.lr_color),
            ("lr_final", self.lr_final),
            ("step", self.step),
            ("finer_lr", self.finer_lr),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be finite and positive (got {v})"));
            }
        }
        for (name, v) in [
            ("rgbper", self.rgbper),
            ("entropy", self.entropy),
            ("distortion", self.distortion),
            ("skip_weight", self.skip_weight),
            ("tv_density", self.tv_density),
            ("tv_color", self.tv_color),
            ("prune_opacity", self.prune_opacity),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be finite and not negative (got {v})"));
            }
        }
        if !(self.keep_opacity.is_finite() && (0.0..1.0).contains(&self.keep_opacity)) {
            return Err(format!(
                "keep_opacity must be in [0, 1) (got {})",
                self.keep_opacity
            ));
        }
        Ok(())
    }
}

fn one() -> u32 {
    1
}

fn is_zero(v: &f32) -> bool {
    *v == 0.0
}

fn one_f32() -> f32 {
    1.0
}

fn is_one(v: &f32) -> bool {
    *v == 1.0
}

/// Largest grid (cells per edge): 512³ cells of index = 0.5 GB.
pub const MAX_RES: u32 = 512;

/// Where the time went and how training went.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct TrainReport {
    /// Carving the hull, seconds.
    pub carve_s: f64,
    /// Each level: (resolution, stored vertices, seconds).
    pub levels: Vec<(u32, usize, f64)>,
    /// Whole training, seconds.
    pub total_s: f64,
    /// (seconds since start, training-batch PSNR in dB), every few steps.
    pub curve: Vec<(f64, f64)>,
    /// Samples shaded in total.
    pub samples: u64,
    /// Seconds in the optimiser's passes over the grid (total variation,
    /// Adam, pruning), all levels; the rest of a level is the ray march.
    #[serde(default)]
    pub optimiser_s: f64,
}

/// Called every few steps with (level, step, steps in level, batch PSNR).
pub type Progress<'a> = dyn Fn(usize, u32, u32, f64) + Sync + 'a;

/// The hull-restricted starting grid: vertices of carved cells, dilated by
/// one cell so the surface is free to move.
fn initial_grid(views: &ObjectViews, res: u32, sh_degree: u32) -> Result<SparseGrid, String> {
    let bake_views = views.bake_views();
    let sil = Silhouettes::new(&bake_views);
    let search = views.search_box.unwrap_or(carve::NERF_SYNTHETIC_BOX);
    let cube = carve::object_cube(&sil, &search)
        .ok_or("carving left nothing: do the masks and cameras belong together?")?;
    // A little room around the hull's cube: the carve is voxel-accurate.
    let cube = cube.grown(2.0 * (cube.max.x - cube.min.x) / res as f32);
    // The hull is carved at half the resolution (8× fewer voxel tests),
    // which the dilation below more than covers.
    let coarse = (res / 2).max(4);
    let hull = carve::carve(&sil, &cube, coarse, VoxelTest::Footprint);
    if hull.occupied_count() == 0 {
        return Err("carving left no occupied voxel".into());
    }
    let r = coarse as i64;
    let ratio = coarse as f32 / res as f32;
    Ok(SparseGrid::new(res, cube, sh_degree, |i, j, k| {
        // The coarse cells around the vertex, one more on every side.
        let at = |v: u32| (v as f32 * ratio) as i64;
        let (i, j, k) = (at(i), at(j), at(k));
        for ck in (k - 2).max(0)..=(k + 1).min(r - 1) {
            for cj in (j - 2).max(0)..=(j + 1).min(r - 1) {
                for ci in (i - 2).max(0)..=(i + 1).min(r - 1) {
                    if hull.occupied(ci, cj, ck) {
                        return true;
                    }
                }
            }
        }
        false
    }))
}

/// The next level's grid: vertices in cells where the coarse field holds
/// matter (opacity per coarse cell above `keep`, dilated by one coarse
/// cell), values interpolated from the coarse grid.
fn refine(coarse: &SparseGrid, res: u32, keep: f32) -> SparseGrid {
    let len = coarse.record_len();
    let n = coarse.res as usize + 1;
    let tau_cell = coarse.density_scale() * coarse.voxel();
    let alive: Vec<bool> = (0..n * n * n)
        .map(|v| {
            let s = coarse.index[v];
            s != super::grid::EMPTY && {
                let raw = coarse.values[s as usize * len];
                1.0 - (-activate_density(raw).0 * tau_cell).exp() > keep
            }
        })
        .collect();
    let near_alive = |i: i64, j: i64, k: i64| {
        let m = n as i64;
        for dk in -1..=2 {
            for dj in -1..=2 {
                for di in -1..=2 {
                    let (a, b, c) = (i + di, j + dj, k + dk);
                    let inside = a >= 0 && b >= 0 && c >= 0 && a < m && b < m && c < m;
                    if inside && alive[((c * m + b) * m + a) as usize] {
                        return true;
                    }
                }
            }
        }
        false
    };
    let ratio = coarse.res as f32 / res as f32;
    let mut fine = SparseGrid::new(res, coarse.cube, coarse.sh_degree, |i, j, k| {
        let u = Vec3::new(i as f32, j as f32, k as f32) * ratio;
        near_alive(u.x as i64, u.y as i64, u.z as i64)
    });
    let vertex = fine.vertex.clone();
    fine.values
        .par_chunks_mut(len)
        .zip(vertex.par_iter())
        .for_each(|(rec, &v)| {
            let (i, j, k) = {
                let m = res + 1;
                (v % m, (v / m) % m, v / (m * m))
            };
            let u = Vec3::new(i as f32, j as f32, k as f32) * ratio;
            if let Some(c) = coarse.corners_any(u) {
                coarse.interpolate(&c, rec);
            }
        });
    fine
}

/// Trains a field of one object from its training views.
pub fn train(
    views: &ObjectViews,
    settings: &TrainSettings,
    progress: &Progress<'_>,
) -> Result<(SparseGrid, TrainReport), String> {
    settings.validate()?;
    if views.train.is_empty() {
        return Err("no training views".into());
    }
    let start = Instant::now();
    let mut report = TrainReport::default();
    let first = settings.levels[0];
    let mut grid = initial_grid(views, first.res, settings.sh_degree)?;
    report.carve_s = start.elapsed().as_secs_f64();
    let pixels = PixelSet::new(&views.train, &box_corners(grid.cube.min, grid.cube.max));
    if pixels.area() == 0 {
        return Err("the object's box projects into no training view".into());
    }
    let workers_n = rayon::current_num_threads().max(1);
    let background = Vec3::ONE;

    for (li, level) in settings.levels.iter().enumerate() {
        let t_level = Instant::now();
        if li > 0 {
            grid = refine(&grid, level.res, settings.keep_opacity);
        }
        let len = grid.record_len();
        let mut adam = Adam::new(grid.values.len());
        let mut workers: Vec<(Scratch, ChaCha8Rng, Vec<PixelRay>)> = (0..workers_n)
            .map(|w| {
                (
                    Scratch::default(),
                    ChaCha8Rng::seed_from_u64(settings.seed ^ ((li as u64) << 32) ^ w as u64),
                    Vec::new(),
                )
            })
            .collect();
        let mut grads: Vec<GradBuf> = (0..workers_n)
            .map(|_| GradBuf::new(grid.slots(), len))
            .collect();
        let params = MarchParams {
            step: settings.step,
            background,
        };
        let bx = MarchBox::of(&grid);
        let per_worker = (settings.batch as usize).div_ceil(workers_n);
        let loss_scale = 1.0 / (3.0 * (per_worker * workers_n) as f32);
        let reg = RayLoss {
            rgbper: settings.rgbper,
            entropy: settings.entropy,
            distortion: settings.distortion,
            skip_weight: settings.skip_weight,
        };
        let tv_w = TvWeights {
            density: settings.tv_density,
            color: settings.tv_color,
        };
        let neighbours = if tv_w.is_off() {
            Neighbours::default()
        } else {
            Neighbours::of(&grid)
        };
        let (mut sse_acc, mut n_acc) = (0.0f64, 0u64);
        for it in 0..level.iters {
            let frac = it as f32 / level.iters.max(1) as f32;
            let decay = settings.lr_final.powf(frac) * if li > 0 { settings.finer_lr } else { 1.0 };
            let g = &grid;
            let (sse, samples, rays): (f64, u64, u64) = workers
                .par_iter_mut()
                .zip(grads.par_iter_mut())
                .map(|((scratch, rng, batch), grads)| {
                    let mut sse = 0.0f64;
                    let mut samples = 0u64;
                    batch.clear();
                    while batch.len() < per_worker {
                        pixels.draw_patch(rng, settings.patch, batch);
                    }
                    // Independent pixels, processed in an order that
                    // keeps neighbouring cells together (same gradient,
                    // several times the throughput of a random order).
                    let mut rays: Vec<(u64, GridRay, Vec3)> = batch
                        .iter()
                        .map(|px| {
                            let jitter = rand::Rng::random::<f32>(rng);
                            let ray = GridRay::from_world(g, px.origin, px.dir, jitter);
                            (ray.locality_key(&bx), ray, px.target)
                        })
                        .collect();
                    rays.sort_unstable_by_key(|r| r.0);
                    for (_, ray, target) in &rays {
                        let (ray, px_target) = (*ray, *target);
                        let out = march::train_ray(
                            g, &bx, &ray, &params, px_target, loss_scale, &reg, scratch, grads,
                        );
                        sse += f64::from((out.rgb - px_target).length_squared());
                        samples += u64::from(out.samples);
                    }
                    (sse, samples, batch.len() as u64)
                })
                .reduce(|| (0.0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
            report.samples += samples;
            let t_opt = Instant::now();
            let every = settings.tv_every.max(1);
            if (it + 1) % every == 0 {
                let w = TvWeights {
                    density: tv_w.density * every as f32,
                    color: tv_w.color * every as f32,
                };
                tv::add_grad(&grid.values, len, &neighbours, w, &mut grads);
            }
            adam.step(
                &mut grid.values,
                len,
                &mut grads,
                settings.lr_density * decay,
                settings.lr_color * decay,
            );
            sse_acc += sse;
            n_acc += rays * 3;
            if settings.prune_every > 0 && (it + 1) % settings.prune_every == 0 {
                grid.prune_cells(settings.prune_opacity);
            }
            report.optimiser_s += t_opt.elapsed().as_secs_f64();
            if (it + 1) % 25 == 0 || it + 1 == level.iters {
                let mse = sse_acc / n_acc.max(1) as f64;
                let psnr = -10.0 * mse.max(1e-12).log10();
                report.curve.push((start.elapsed().as_secs_f64(), psnr));
                progress(li, it + 1, level.iters, psnr);
                sse_acc = 0.0;
                n_acc = 0;
            }
        }
        report
            .levels
            .push((level.res, grid.slots(), t_level.elapsed().as_secs_f64()));
    }
    // The pruned cells stay pruned: the field was trained with them
    // skipped, and their thin haze, summed along a ray, costs 0.4 dB held
    // out on lego when they are marched again. The file keeps the bits.
    report.total_s = start.elapsed().as_secs_f64();
    Ok((grid, report))
}

/// World corners of a box (for callers that hold an [`Aabb`]).
pub fn aabb_corners(b: &Aabb) -> [Vec3; 8] {
    box_corners(b.min, b.max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Intrinsics};
    use crate::train::view::render_view;

    /// A distortion weight of 0 is not serialised (the field stores' keys
    /// of settings from before it existed stay), any other is, and both
    /// read back.
    #[test]
    fn a_zero_distortion_leaves_the_serialised_settings_as_they_were() {
        let off = TrainSettings::default();
        let json = serde_json::to_string(&off).unwrap();
        assert!(!json.contains("distortion"), "{json}");
        assert!(!json.contains("finer_lr"), "{json}");
        let back: TrainSettings = serde_json::from_str(&json).unwrap();
        assert_eq!(back.distortion, 0.0);
        assert_eq!(back.finer_lr, 1.0);
        let on = TrainSettings {
            distortion: 0.25,
            ..TrainSettings::default()
        };
        let json = serde_json::to_string(&on).unwrap();
        assert!(json.contains("\"distortion\":0.25"), "{json}");
        let back: TrainSettings = serde_json::from_str(&json).unwrap();
        assert_eq!(back.distortion, 0.25);
    }

    /// Views of a known field (a coloured ball) and the field itself.
    pub(crate) fn ball_views(n: usize, size: u32) -> (SparseGrid, ObjectViews) {
        let cube = Aabb {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        };
        let mut gt = SparseGrid::new(16, cube, 1, |_, _, _| true);
        let len = gt.record_len();
        for s in 0..gt.slots() {
            let (i, j, k) = gt.vertex_ijk(gt.vertex[s]);
            let p = Vec3::new(i as f32, j as f32, k as f32) / 8.0 - Vec3::ONE;
            let rec = &mut gt.values[s * len..(s + 1) * len];
            rec[0] = if p.length() < 0.6 { 10.0 } else { -6.0 };
            rec[1] = 4.0 * p.x; // red varies along x
            rec[5] = 4.0 * p.y; // green along y
            rec[9] = -3.0 * p.z; // blue along z
            rec[2] = 1.0; // some view dependence
        }
        let intr = Intrinsics::from_fov_x(0.8, size, size);
        let views: Vec<_> = (0..n)
            .map(|v| {
                let az = v as f32 * 360.0 / n as f32;
                let el = if v % 2 == 0 { 20.0 } else { -15.0 };
                let cam = Camera::orbit(az, el, 3.5, Vec3::ZERO, intr);
                let img = render_view(&gt, &cam, 0.5);
                (cam, img, None)
            })
            .collect();
        let test = views
            .iter()
            .take(2)
            .map(|(c, i, _): &crate::bake::sweep::TrainView| (*c, i.clone()))
            .collect();
        let ov = ObjectViews {
            name: "ball".into(),
            content_hash: 0,
            train: views,
            test,
            test_hidden: Vec::new(),
            search_box: Some(cube),
        };
        (gt, ov)
    }

    /// Training recovers a known field's views (the optimiser and the
    /// gradients together work).
    #[test]
    fn fits_the_views_of_a_known_field() {
        let (_gt, views) = ball_views(16, 48);
        let settings = TrainSettings {
            levels: vec![Level {
                res: 16,
                iters: 400,
            }],
            batch: 1024,
            patch: 1,
            ..TrainSettings::default()
        };
        let (_grid, report) = train(&views, &settings, &|_, _, _, _| {}).unwrap();
        let last = report.curve.last().unwrap().1;
        let first = report.curve.first().unwrap().1;
        eprintln!("{:?}", report.curve);
        assert!(last > 30.0, "train PSNR {first:.2} → {last:.2} dB");
    }
}
