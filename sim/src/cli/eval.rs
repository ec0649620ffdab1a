//! `nerflex eval`: the NeRFlex paper's evaluation, regenerated from scratch
//! (`nerflex_sim::eval`), written as `eval.json`, `report.md` and PNG plots.

use crate::cli::run::PipelineArgs;
use crate::device::Device;
use crate::eval::scale::Scale;
use crate::eval::{self, EvalOptions};
use crate::procedural::Preset;
use anyhow::{bail, Context as _};
use std::path::PathBuf;

/// Flags of `nerflex eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (report.md, eval.json, plots; work folders under scenes/).
    #[arg(long, value_name = "DIR", default_value = "results/eval")]
    pub out: PathBuf,
    /// Built-in scenes to evaluate.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "scene1,scene2,scene3,scene4"
    )]
    pub scenes: Vec<Preset>,
    /// Devices (built-in names or TOML files).
    #[arg(long, value_delimiter = ',', default_value = "iphone13,pixel4")]
    pub devices: Vec<String>,
    /// Real single-object captures to compose and evaluate [default: lego
    /// and chair from the shared data folder, when present].
    #[arg(long, value_delimiter = ',', value_name = "DIR,DIR")]
    pub real: Vec<PathBuf>,
    /// Skip the real capture.
    #[arg(long)]
    pub no_real: bool,
    /// Image side of the composed real capture, pixels [default: by --scale].
    #[arg(long)]
    pub real_size: Option<u32>,
    /// Sizes: paper (800 × 800, 50 + 12 views), quick (128 × 128, 16 + 10
    /// views, 1000 frames) or reduced (160 × 160, 16 + 10 views); flags
    /// given explicitly win.
    #[arg(long, value_enum, default_value_t = Scale::Paper)]
    pub scale: Scale,
    /// Same as `--scale quick`: the whole evaluation in minutes, to check
    /// the machinery (never for the paper's claims).
    #[arg(long, conflicts_with = "scale")]
    pub quick: bool,
    /// Redraw report.md and the plots from OUT/eval.json without measuring
    /// anything (after a change to the report; the intervals need an
    /// eval.json with per-view scores).
    #[arg(long)]
    pub redraw: bool,
    /// Settings shared with `nerflex run`.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// Runs `nerflex eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.redraw {
        let path = args.out.join("eval.json");
        let text = std::fs::read_to_string(&path).with_context(|| {
            format!("{}: cannot read (run `nerflex eval` first)", path.display())
        })?;
        let report: eval::EvalReport = serde_json::from_str(&text)
            .with_context(|| format!("{}: not an evaluation report", path.display()))?;
        eval::write_report(&report, &args.out)?;
        println!(
            "redrew {}/report.md and the plots from eval.json",
            args.out.display()
        );
        return Ok(());
    }
    if args.scenes.is_empty() {
        bail!("--scenes: give at least one scene");
    }
    let scale = if args.quick { Scale::Quick } else { args.scale };
    let sizes = scale.sizes();
    let pipeline = args.pipeline.options_at(&args.out, scale)?;
    let real_size = args.real_size.unwrap_or(sizes.real_size);
    if !(16..=2048).contains(&real_size) {
        bail!("--real-size: must be 16..=2048 pixels, got {real_size}");
    }
    let devices = args
        .devices
        .iter()
        .map(|d| Device::lookup(d))
        .collect::<Result<Vec<_>, _>>()?;
    let real = if args.no_real {
        Vec::new()
    } else if !args.real.is_empty() {
        args.real.clone()
    } else {
        match crate::data::shared_data_dir() {
            Some(d) => {
                let v = vec![
                    d.join("nerf_synthetic").join("lego"),
                    d.join("nerf_synthetic").join("chair"),
                ];
                if v.iter().all(|p| p.is_dir()) {
                    v
                } else {
                    Vec::new()
                }
            }
            None => Vec::new(),
        }
    };
    // Check the real captures before the (long) scene work.
    for dir in &real {
        let t = dir.join("transforms_train.json");
        crate::camera::Transforms::read(&t)
            .with_context(|| format!("--real {}: not a capture folder", dir.display()))?;
    }
    let opts = EvalOptions {
        pipeline,
        scenes: args.scenes.clone(),
        devices,
        real,
        real_size,
        fps_scene: Preset::Scene3,
    };
    args.pipeline.ignore_default_store(&args.out)?;
    crate::cli::run::ignore_in_git(&args.out.join("scenes"))?;
    let lpips = args.pipeline.lpips()?;
    let bar = args.pipeline.bar();
    let result = eval::run(&opts, &args.out, lpips.as_ref(), &bar);
    bar.finish();
    let report = result.context("evaluation")?;
    println!(
        "evaluated {} scene(s){} in {:.0} s → {}/report.md, eval.json and plots",
        report.scenes.len(),
        if report.real.is_some() {
            " + the real capture"
        } else {
            ""
        },
        report.wall_s,
        args.out.display()
    );
    for c in &report.calibration {
        println!(
            "{}: {} mean FPS {:.1} (paper {:.1}); factor that would match: {:.4}",
            c.device, c.against, c.fps_with_file, c.target_fps, c.scale
        );
    }
    Ok(())
}
