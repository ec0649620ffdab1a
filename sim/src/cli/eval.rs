//! `nerflex eval`: the NeRFlex paper's evaluation, regenerated from scratch
//! (`nerflex_sim::eval`), written as `eval.json`, `report.md` and PNG plots.

use crate::cli::run::PipelineArgs;
use crate::device::Device;
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
    /// Image side of the composed real capture, pixels.
    #[arg(long, default_value_t = 200)]
    pub real_size: u32,
    /// Settings shared with `nerflex run`.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// Runs `nerflex eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.scenes.is_empty() {
        bail!("--scenes: give at least one scene");
    }
    let pipeline = args.pipeline.options(&args.out)?;
    if !(16..=2048).contains(&args.real_size) {
        bail!(
            "--real-size: must be 16..=2048 pixels, got {}",
            args.real_size
        );
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
        real_size: args.real_size,
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
