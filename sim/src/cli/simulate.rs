//! `nerflex simulate`: load a planned scene's baked assets on a simulated
//! device and turn it on the turntable; print the average FPS (or the load
//! failure), write the per-frame FPS as CSV/JSON and the FPS plot.

use crate::baselines::{self, Budget, Plan};
use crate::device::Device;
use crate::scene_file;
use crate::simulate::assets::AssetScene;
use crate::simulate::{self, SimOptions, Simulation, Turntable, TurntableSpec};
use anyhow::{bail, Context as _};
use nerflex_core::units::Bytes;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Flags of `nerflex simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (JSON, as for `nerflex plan`).
    #[arg(long, value_name = "FILE")]
    pub scene: PathBuf,
    /// A plan (JSON, as `nerflex plan --json` prints it).
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with = "method",
        required_unless_present = "method"
    )]
    pub plan: Option<PathBuf>,
    /// Or: plan the scene now with this method for the device's budget.
    #[arg(long, value_enum)]
    pub method: Option<baselines::Method>,
    /// Device: a built-in name (iphone13, pixel4) or a device TOML file.
    #[arg(long, value_name = "NAME|FILE")]
    pub device: String,
    /// Folder of baked assets, `<object>/g<g>_p<p>/` (`…_mesh/` for an
    /// object planned as a mesh) [default: `assets/` beside the scene file].
    #[arg(long, value_name = "DIR")]
    pub assets: Option<PathBuf>,
    /// Frames to simulate.
    #[arg(long, default_value_t = 2000)]
    pub frames: usize,
    /// Seconds per turntable revolution.
    #[arg(long, default_value_t = 7.5)]
    pub period_s: f64,
    /// Turntable angles whose coverage is measured (interpolated between).
    #[arg(long, default_value_t = TurntableSpec::DEFAULT.angles)]
    pub angles: usize,
    /// Width of the coverage render, pixels (scaled to the viewer's size).
    #[arg(long, default_value_t = TurntableSpec::DEFAULT.coverage_width)]
    pub coverage_px: u32,
    /// Camera elevation above the turntable, degrees.
    #[arg(long, default_value_t = TurntableSpec::DEFAULT.elevation_deg, allow_negative_numbers = true)]
    pub elevation_deg: f32,
    /// Camera distance from the turntable's axis, world units.
    #[arg(long, default_value_t = TurntableSpec::DEFAULT.distance)]
    pub distance: f32,
    /// Write the FPS plot (PNG) here.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Write the per-frame CSV here.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Print the whole simulation (summary and every frame) as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The turntable settings of the flags, checked.
pub fn turntable_spec(
    angles: usize,
    coverage_px: u32,
    elevation_deg: f32,
    distance: f32,
) -> anyhow::Result<TurntableSpec> {
    if angles == 0 {
        bail!("--angles: must be at least 1");
    }
    if !(8..=4096).contains(&coverage_px) {
        bail!("--coverage-px: must be 8..=4096, got {coverage_px}");
    }
    if !(elevation_deg.is_finite() && elevation_deg.abs() < 90.0) {
        bail!("--elevation-deg: must be strictly between -90 and 90, got {elevation_deg}");
    }
    if !(distance.is_finite() && distance > 0.0) {
        bail!("--distance: must be a positive number, got {distance}");
    }
    Ok(TurntableSpec {
        angles,
        coverage_width: coverage_px,
        elevation_deg,
        distance,
        ..TurntableSpec::DEFAULT
    })
}

fn read_plan(path: &Path) -> anyhow::Result<Plan> {
    let text = crate::validate::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let plan: Plan = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not a plan (as `nerflex plan --json` writes)",
            path.display()
        )
    })?;
    if plan.objects.is_empty() {
        bail!("{}: objects: the plan has no objects", path.display());
    }
    Ok(plan)
}

/// One-paragraph summary of a simulation.
pub fn summary(sim: &Simulation, what: &str) -> String {
    let mut s = format!(
        "{what} on {}: data {:.2} MB, GPU-resident {:.2} MB (incl. G-buffer)\n",
        sim.device,
        Bytes(sim.data_bytes).as_mb(),
        Bytes(sim.resident_bytes).as_mb()
    );
    match &sim.load_failure {
        Some(f) => s.push_str(&format!(
            "load FAILED: {f}; FPS 0 over {} frames\n",
            sim.frames.len()
        )),
        None => {
            if sim.over_soft_limit {
                s.push_str("over the soft memory limit: frames slowed by the device's penalty\n");
            }
            s.push_str(&format!(
                "loaded after {}; mean FPS {:.1} over {} frames (after loading {:.1}, lowest {:.1})\n",
                sim.loaded_at_s
                    .map_or("never".to_string(), |t| format!("{t:.2} s")),
                sim.mean_fps,
                sim.frames.len(),
                sim.steady_fps,
                sim.min_fps
            ));
        }
    }
    s
}

/// Runs `nerflex simulate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    simulate::check_frames(args.frames).map_err(anyhow::Error::msg)?;
    let device = Device::lookup(&args.device)?;
    let scene = scene_file::load(&args.scene)?;
    let spec = turntable_spec(
        args.angles,
        args.coverage_px,
        args.elevation_deg,
        args.distance,
    )?;
    if args.frames == 0 {
        bail!("--frames: must be at least 1");
    }
    if !(args.period_s.is_finite() && args.period_s > 0.0) {
        bail!(
            "--period-s: must be a positive number of seconds, got {}",
            args.period_s
        );
    }
    let plan = match (&args.plan, args.method) {
        (Some(p), _) => read_plan(p)?,
        (None, Some(m)) => {
            let mut p = baselines::plan(m, &scene, Budget::new(device.budget()))
                .with_context(|| format!("{m} plan for {}", args.scene.display()))?;
            p.device = Some(device.name.clone());
            p
        }
        (None, None) => bail!("give --plan FILE or --method M"),
    };
    let root = match &args.assets {
        Some(d) => d.clone(),
        None => args
            .scene
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join("assets"),
    };
    let scene_assets = AssetScene::load_plan(&plan, &root)?;
    let items = scene_assets.load_items();
    let tt = Turntable::new(spec, device.viewer(), &scene_assets);
    let sim = simulate::simulate(
        &device,
        &items,
        &tt,
        SimOptions {
            frames: args.frames,
            period_s: args.period_s,
        },
    )?;
    let what = format!("{} plan ({} objects)", plan.method, plan.objects.len());
    if let Some(csv) = &args.csv {
        simulate::write_csv(&sim, csv)?;
    }
    if let Some(png) = &args.plot {
        let chart = simulate::output::fps_chart(
            &format!("{what} on {}", device.name),
            &[(plan.method.name(), &sim)],
        );
        chart
            .save(png)
            .with_context(|| format!("{}: cannot draw the FPS plot", png.display()))?;
    }
    let text = if args.json {
        let mut t = serde_json::to_string(&sim)?;
        t.push('\n');
        t
    } else {
        summary(&sim, &what)
    };
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing to stdout")?;
    Ok(())
}
