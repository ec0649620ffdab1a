//! `nerflex train`: learn one object's radiance field from its posed
//! training views; optionally measure it on the held-out views.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context as _};

use crate::bake::sweep::ObjectViews;
use crate::capture::Capture;
use crate::metrics::{Lpips, Metrics};
use crate::train::io;
use crate::train::trainer::{self, Level, TrainSettings};
use crate::train::view::render_view;

/// Flags of `nerflex train`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Capture folder in the NeRF-synthetic layout.
    #[arg(long)]
    pub capture: PathBuf,
    /// Object of a multi-object capture (a `scene.json` name).
    #[arg(long)]
    pub object: Option<String>,
    /// Where to write the field (safetensors).
    #[arg(long, required_unless_present = "field")]
    pub out: Option<PathBuf>,
    /// Measure this saved field instead of training one.
    #[arg(long, conflicts_with = "out")]
    pub field: Option<PathBuf>,
    /// Render the held-out views and report PSNR, SSIM, LPIPS.
    #[arg(long)]
    pub measure: bool,
    /// With `--measure`: write each held-out render (`test_{i}.png`) here.
    #[arg(long)]
    pub renders: Option<PathBuf>,
    /// Coarse-to-fine schedule, `RES:STEPS` comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_level, default_value = "128:1000,256:2000,384:4500")]
    pub levels: Vec<Level>,
    /// Rays per optimisation step.
    #[arg(long, default_value_t = 8192)]
    pub batch: u32,
    /// SH degree of the colour (0, 1 or 2).
    #[arg(long, default_value_t = 1)]
    pub sh_degree: u32,
    /// Adam learning rate of the density.
    #[arg(long, default_value_t = 0.5)]
    pub lr_density: f32,
    /// Adam learning rate of the SH colour.
    #[arg(long, default_value_t = 0.3)]
    pub lr_color: f32,
    /// Seed of the ray draws.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Rays are drawn in PATCH×PATCH pixel patches (1: independent pixels).
    #[arg(long, default_value_t = 1)]
    pub patch: u32,
    /// Factor the learning rates decay to by the end of each level.
    #[arg(long, default_value_t = 0.1)]
    pub lr_final: f32,
    /// Weight of the per-sample colour loss (DVGO's `rgbper`; 0: off).
    #[arg(long, default_value_t = 0.01)]
    pub rgbper: f32,
    /// Weight of the entropy of each ray's final transmittance (DVGO's
    /// `entropy_last`; 0: off).
    #[arg(long, default_value_t = 0.001)]
    pub entropy: f32,
    /// Weight of the distortion loss (mip-NeRF 360's; 0: off): each ray's
    /// weight gathers into one thin interval, a sharper surface to bake.
    #[arg(long, default_value_t = 0.0)]
    pub distortion: f32,
    /// Learning rates of the levels after the first start at this
    /// fraction (1: every level restarts at full strength).
    #[arg(long, default_value_t = 1.0)]
    pub finer_lr: f32,
    /// Samples of smaller weight pass no gradient (0: all do).
    #[arg(long, default_value_t = 1e-4)]
    pub skip_weight: f32,
    /// Total variation weight on the raw density (0: off).
    #[arg(long, default_value_t = 1e-10)]
    pub tv_density: f32,
    /// Total variation weight on the SH colour (0: off).
    #[arg(long, default_value_t = 1e-10)]
    pub tv_color: f32,
    /// Apply the total variation every N steps (weights × N). Every 4th
    /// step frees time for more steps at 256³ (docs/training.md).
    #[arg(long, default_value_t = 4)]
    pub tv_every: u32,
    /// Every N steps, skip cells whose opacity stays below
    /// `--prune-opacity` (0: never).
    #[arg(long, default_value_t = 100)]
    pub prune_every: u32,
    /// See `--prune-every`.
    #[arg(long, default_value_t = 1e-3)]
    pub prune_opacity: f32,
    /// Use only the first N training views.
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Measure only the first N held-out views.
    #[arg(long)]
    pub max_test_views: Option<usize>,
    /// Draw the training PSNR against time into this PNG.
    #[arg(long)]
    pub curve: Option<PathBuf>,
    /// LPIPS weights (default: the shared data's AlexNet weights).
    #[arg(long)]
    pub lpips_weights: Option<PathBuf>,
}

fn parse_level(s: &str) -> Result<Level, String> {
    let (r, i) = s
        .split_once(':')
        .ok_or_else(|| format!("`{s}`: expected RES:STEPS, e.g. 128:1500"))?;
    Ok(Level {
        res: r
            .trim()
            .parse()
            .map_err(|_| format!("`{r}` is not a resolution"))?,
        iters: i
            .trim()
            .parse()
            .map_err(|_| format!("`{i}` is not a step count"))?,
    })
}

/// Runs `nerflex train`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.max_views == Some(0) {
        bail!("--max-views 0: training needs at least one view");
    }
    let t_load = Instant::now();
    let mut cap = Capture::load(&args.capture)?;
    if let Some(n) = args.max_views {
        cap.train.truncate(n);
    }
    if let Some(n) = args.max_test_views {
        cap.test.truncate(n);
    }
    let views = ObjectViews::from_capture(&cap, args.object.as_deref())?;
    drop(cap);
    println!(
        "{}: {} training views, {} held-out, loaded in {:.1} s",
        views.name,
        views.train.len(),
        views.test.len(),
        t_load.elapsed().as_secs_f64()
    );
    // Check the measurement's inputs before spending minutes on training.
    let lpips = if args.measure {
        if views.test.is_empty() {
            bail!(
                "--measure: {} has no held-out views (transforms_test.json)",
                args.capture.display()
            );
        }
        match args.lpips_weights.clone().or_else(Lpips::default_path) {
            Some(p) => Some(Lpips::load(&p)?),
            None => {
                eprintln!("LPIPS weights not found: LPIPS is left out (pass --lpips-weights FILE)");
                None
            }
        }
    } else {
        None
    };

    let (grid, step) = if let Some(field) = &args.field {
        let saved = io::load(field)?;
        let step = saved.settings.as_ref().map_or(0.5, |s| s.step);
        (saved.grid, step)
    } else {
        let out = args.out.as_ref().context("--out FILE is needed to train")?;
        let settings = TrainSettings {
            levels: args.levels.clone(),
            batch: args.batch,
            sh_degree: args.sh_degree,
            lr_density: args.lr_density,
            lr_color: args.lr_color,
            seed: args.seed,
            patch: args.patch,
            lr_final: args.lr_final,
            rgbper: args.rgbper,
            entropy: args.entropy,
            distortion: args.distortion,
            finer_lr: args.finer_lr,
            skip_weight: args.skip_weight,
            tv_density: args.tv_density,
            tv_color: args.tv_color,
            prune_every: args.prune_every,
            tv_every: args.tv_every,
            prune_opacity: args.prune_opacity,
            ..TrainSettings::default()
        };
        settings
            .validate()
            .map_err(|e| anyhow::anyhow!("training settings: {e}"))?;
        let total: u64 = settings.levels.iter().map(|l| u64::from(l.iters)).sum();
        let bar = indicatif::ProgressBar::new(total);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} steps  {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        let done_before: Vec<u64> = settings
            .levels
            .iter()
            .scan(0u64, |acc, l| {
                let before = *acc;
                *acc += u64::from(l.iters);
                Some(before)
            })
            .collect();
        let levels = settings.levels.clone();
        let progress = |li: usize, it: u32, _n: u32, psnr: f64| {
            bar.set_position(done_before[li] + u64::from(it));
            bar.set_message(format!("{}³  train PSNR {psnr:.2} dB", levels[li].res));
        };
        let (grid, report) = trainer::train(&views, &settings, &progress)
            .map_err(|e| anyhow::anyhow!("{}: {e}", args.capture.display()))?;
        bar.finish_and_clear();
        println!("carve {:.1} s", report.carve_s);
        for (res, slots, s) in &report.levels {
            println!("level {res}³: {slots} stored vertices, {s:.1} s");
        }
        println!(
            "total {:.1} s ({:.1} s in the optimiser's grid passes), {:.2} M samples ({:.2} M samples/s)",
            report.total_s,
            report.optimiser_s,
            report.samples as f64 / 1e6,
            report.samples as f64 / 1e6 / report.total_s.max(1e-9)
        );
        let every = report.curve.len().div_ceil(12).max(1);
        let points: Vec<String> = report
            .curve
            .iter()
            .enumerate()
            .filter(|(i, _)| (i + 1) % every == 0 || i + 1 == report.curve.len())
            .map(|(_, (t, p))| format!("{t:.0}s {p:.2}"))
            .collect();
        println!("training-batch PSNR (dB) by time: {}", points.join(", "));
        io::save(out, &grid, &settings, &report)?;
        println!("field -> {}", out.display());
        if let Some(png) = &args.curve {
            draw_curve(png, &views.name, &report.curve)?;
            println!("curve -> {}", png.display());
        }
        (grid, settings.step)
    };

    if args.measure {
        if let Some(dir) = &args.renders {
            std::fs::create_dir_all(dir).with_context(|| format!("--renders {}", dir.display()))?;
        }
        let t = Instant::now();
        let mut sums = (0.0, 0.0, 0.0, 0usize);
        println!("view   PSNR dB   SSIM     LPIPS");
        for (i, (camera, truth)) in views.test.iter().enumerate() {
            let mut img = render_view(&grid, camera, step);
            let hidden = views.test_hidden.get(i).and_then(Option::as_ref);
            crate::bake::sweep::hide_unknown(&mut img, truth, hidden);
            let s = Metrics::compare(&img, truth, lpips.as_ref())?;
            println!(
                "{i:>4}   {:7.3}   {:.4}   {}",
                s.psnr,
                s.ssim,
                s.lpips.map_or("-".into(), |l| format!("{l:.4}"))
            );
            sums.0 += s.psnr;
            sums.1 += s.ssim;
            sums.2 += s.lpips.unwrap_or(0.0);
            sums.3 += 1;
            if let Some(dir) = &args.renders {
                let p = dir.join(format!("test_{i}.png"));
                img.save(&p)
                    .with_context(|| format!("writing {}", p.display()))?;
            }
        }
        let n = sums.3.max(1) as f64;
        println!(
            "mean   {:7.3}   {:.4}   {}   ({} held-out views, {:.1} s)",
            sums.0 / n,
            sums.1 / n,
            if lpips.is_some() {
                format!("{:.4}", sums.2 / n)
            } else {
                "-".into()
            },
            sums.3,
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

fn draw_curve(path: &std::path::Path, name: &str, curve: &[(f64, f64)]) -> anyhow::Result<()> {
    use crate::plot::{Chart, Series};
    Chart::new(format!("{name}: PSNR of the training batches"))
        .x_label("time (s)")
        .y_label("PSNR (dB)")
        .series(Series::line("train PSNR", curve.iter().copied()))
        .save(path)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
