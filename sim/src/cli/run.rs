//! `nerflex run`: the whole NeRFlex pipeline on one capture or built-in
//! scene — segment → profiler sample bakes → fit → plan → bake the chosen
//! configurations → render the held-out views → SSIM/PSNR/LPIPS →
//! simulate on the device — with a progress bar and a short report.

use crate::bake::trained::lattice_choice;
use crate::baselines::{Method, Objective};
use crate::device::Device;
use crate::eval::scale::{Scale, Sizes};
use crate::metrics::Lpips;
use crate::pipeline::{self, Baker, Geometries, Input, Options, Progress};
use crate::procedural::Preset;
use crate::simulate::{self, SimOptions};
use crate::train::trainer::Level;
use anyhow::{bail, Context as _};
use nerflex_core::units::Bytes;
use std::path::{Path, PathBuf};

/// Flags of `nerflex run`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["capture", "preset"])))]
pub struct Args {
    /// Capture folder (NeRF-synthetic layout with instance masks, or one object).
    #[arg(long, value_name = "DIR")]
    pub capture: Option<PathBuf>,
    /// Or a built-in scene: scene1, scene2, scene3, scene4 (generated into OUT/capture).
    #[arg(long, value_name = "NAME")]
    pub preset: Option<Preset>,
    /// Device: a built-in name (iphone13, pixel4) or a device TOML file.
    #[arg(long, value_name = "NAME|FILE")]
    pub device: String,
    /// Configuration selection method.
    #[arg(long, value_enum, default_value_t = Method::Dp)]
    pub method: Method,
    /// Output folder.
    #[arg(long, value_name = "DIR", default_value = "results/run")]
    pub out: PathBuf,
    /// Settings shared with `nerflex eval`.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// Flags shared by `nerflex run` and `nerflex eval`: the built-in captures'
/// size, the simulation's length, the bake store, LPIPS and the progress bar.
/// Sizes left out come from the command's scale (`nerflex run`: the
/// reduced one; `nerflex eval`: `--scale`).
#[derive(Debug, clap::Args)]
pub struct PipelineArgs {
    /// Image side of a generated (built-in) capture, pixels [default: 160;
    /// eval: by --scale].
    #[arg(long)]
    pub size: Option<u32>,
    /// Training views of a generated capture [default: 16; eval: by --scale].
    #[arg(long)]
    pub views: Option<usize>,
    /// Held-out views of a generated capture [default: 10; eval: by --scale].
    #[arg(long)]
    pub test_views: Option<usize>,
    /// Frames of each turntable simulation [default: 2000; eval: by --scale].
    #[arg(long)]
    pub frames: Option<usize>,
    /// Folder of kept bakes, shared between runs [default: OUT/bakes].
    #[arg(long, value_name = "DIR")]
    pub store: Option<PathBuf>,
    /// Baker: `trained` (a radiance field trained per network, kept in
    /// STORE/fields, baked and fine-tuned) or `hull` (visual hull, no
    /// training) [default: trained; hull for `nerflex eval --quick`, whose
    /// 15-minute budget the trained baker does not fit (docs/evaluation.md)].
    #[arg(long, value_parser = parse_baker)]
    pub baker: Option<BakerName>,
    /// The trained baker's training schedule, `RES:STEPS` comma-separated
    /// [default: by the scale; run: 48:300].
    #[arg(long, value_delimiter = ',', value_parser = parse_level, value_name = "RES:STEPS")]
    pub train_levels: Vec<Level>,
    /// Rays per training step [default: by the scale; run: 2048].
    #[arg(long)]
    pub train_batch: Option<u32>,
    /// The trained baker's fine-tune passes over the training pixels
    /// [default: by the scale; run: 3].
    #[arg(long)]
    pub epochs: Option<f32>,
    /// The trained baker's feature lattice, cells per edge, fixed for every
    /// object (0: one cell per two pixels of the object). Default: chosen
    /// per object on training views held back from three bakes at (64, 9),
    /// kept in STORE/lattices (`bake::trained::lattice_choice`).
    #[arg(long, value_name = "CELLS")]
    pub feature_res: Option<u32>,
    /// Grow each dedicated network's crop by this fraction of its object's
    /// larger box side before enlarging [default: 0, the paper's tight
    /// crop]. With 0 no training ray passes just outside the object, so its
    /// field may keep floaters there (docs/evaluation.md, "Session 10").
    #[arg(long, value_name = "FRACTION")]
    pub crop_margin: Option<f32>,
    /// Geometries the profiler samples and the planner chooses from per
    /// object: `planes`, or `both` (planes and mesh; sample bakes of each,
    /// a profile per geometry; needs the trained baker).
    #[arg(long, value_enum, default_value_t = Geometries::Planes)]
    pub geometry: Geometries,
    /// What the selectors maximise: `mean` (the paper's sum of each
    /// network's SSIM on its own views) or `area` (each network weighted by
    /// 1 / zoom², its segmentation's enlargement, so every network counts
    /// per pixel of the original frames; plans still report unweighted
    /// SSIM).
    #[arg(long, value_enum, default_value_t = Objective::Mean)]
    pub objective: Objective,
    /// Leave LPIPS out even when its weights are available.
    #[arg(long)]
    pub no_lpips: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl PipelineArgs {
    /// Checks the flags and turns them into the pipeline's options (the
    /// reduced defaults otherwise), with the bake store under `out` unless
    /// `--store` names one.
    pub fn options(&self, out: &Path) -> anyhow::Result<Options> {
        self.options_at(out, Scale::Reduced)
    }

    /// As [`PipelineArgs::options`], with `scale`'s sizes and training
    /// settings for those not given.
    pub fn options_at(&self, out: &Path, scale: Scale) -> anyhow::Result<Options> {
        let defaults: Sizes = scale.sizes();
        let size = self.size.unwrap_or(defaults.size);
        let views = self.views.unwrap_or(defaults.train_views);
        let test_views = self.test_views.unwrap_or(defaults.test_views);
        let frames = self.frames.unwrap_or(defaults.frames);
        simulate::check_frames(frames).map_err(anyhow::Error::msg)?;
        if !(16..=2048).contains(&size) {
            bail!("--size: must be 16..=2048 pixels, got {size}");
        }
        if views < 2 || test_views == 0 {
            bail!("--views must be at least 2 and --test-views at least 1");
        }
        let mut opts = Options::reduced(self.store.clone().unwrap_or_else(|| out.join("bakes")));
        opts.size = size;
        opts.train_views = views;
        opts.test_views = test_views;
        opts.configs = scale.configs();
        opts.sim = SimOptions {
            frames,
            ..SimOptions::default()
        };
        opts.baker = self.baker_at(scale)?;
        opts.geometries = self.geometry;
        opts.objective = self.objective;
        if self.geometry == Geometries::Both && opts.baker == Baker::Hull {
            bail!(if self.baker == Some(BakerName::Hull) {
                "--geometry both needs the trained baker: --baker hull bakes planes only (leave out --baker hull, or use --geometry planes)"
            } else {
                "--geometry both needs the trained baker: --quick (--scale quick) bakes with the hull, which bakes planes only, unless given --baker trained (add --baker trained, or use --geometry planes)"
            });
        }
        if let Some(m) = self.crop_margin {
            if !(m.is_finite() && (0.0..=1.0).contains(&m)) {
                bail!("--crop-margin: must be a fraction in 0..=1 of the object's box, got {m}");
            }
            opts.crop_margin = m;
        }
        Ok(opts)
    }

    /// The baker the flags choose, with `scale`'s settings where no flag
    /// overrides them.
    fn baker_at(&self, scale: Scale) -> anyhow::Result<Baker> {
        let trained_flags = !self.train_levels.is_empty()
            || self.train_batch.is_some()
            || self.epochs.is_some()
            || self.feature_res.is_some();
        let name = self
            .baker
            .unwrap_or(if trained_flags || scale != Scale::Quick {
                BakerName::Trained
            } else {
                BakerName::Hull
            });
        match name {
            BakerName::Hull if trained_flags => bail!(
                "--train-levels, --train-batch, --epochs and --feature-res are for --baker trained, not --baker hull"
            ),
            BakerName::Hull => Ok(Baker::Hull),
            BakerName::Trained => {
                let mut train = scale.train_settings();
                if !self.train_levels.is_empty() {
                    train.levels = self.train_levels.clone();
                }
                if let Some(b) = self.train_batch {
                    train.batch = b;
                }
                train
                    .validate()
                    .map_err(|e| anyhow::anyhow!("--train-levels/--train-batch: {e}"))?;
                let mut bake = scale.bake_settings();
                if let Some(e) = self.epochs {
                    if !(e.is_finite() && (0.0..=100.0).contains(&e)) {
                        bail!("--epochs: must be a number in 0..=100, got {e}");
                    }
                    bake.finetune.epochs = e;
                }
                Ok(match self.feature_res {
                    Some(cells) => {
                        bake.feature_res = cells;
                        // The settings are checked per bake; this one
                        // before anything trains.
                        let mut at = bake.clone();
                        (at.grid, at.patch) = lattice_choice::SWEEP_CONFIG;
                        at.validate().map_err(anyhow::Error::msg)?;
                        Baker::trained_fixed_lattice(train, bake)
                    }
                    None => Baker::trained(train, bake),
                })
            }
        }
    }

    /// Keeps the default bake store (OUT/bakes, about 1 GB for a built-in
    /// scene) out of git when OUT is inside a checkout (`results/run` by
    /// default): a `.gitignore` of `*` in it. A store named with `--store`
    /// is left alone.
    pub fn ignore_default_store(&self, out: &Path) -> anyhow::Result<()> {
        if self.store.is_none() {
            ignore_in_git(&out.join("bakes"))?;
        }
        Ok(())
    }

    /// The LPIPS network (unless `--no-lpips` or its weights are absent).
    pub fn lpips(&self) -> anyhow::Result<Option<Lpips>> {
        lpips(self.no_lpips)
    }

    /// The progress bar (hidden with `--quiet`).
    pub fn bar(&self) -> Bar {
        Bar::new(self.quiet)
    }
}

/// The baker named by `--baker`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BakerName {
    /// The trained baker.
    Trained,
    /// The visual hull.
    Hull,
}

fn parse_baker(s: &str) -> Result<BakerName, String> {
    match s {
        "trained" => Ok(BakerName::Trained),
        "hull" => Ok(BakerName::Hull),
        _ => Err(format!("`{s}` is not a baker (trained, hull)")),
    }
}

fn parse_level(s: &str) -> Result<Level, String> {
    let (r, i) = s
        .split_once(':')
        .ok_or_else(|| format!("`{s}`: expected RES:STEPS, e.g. 64:300"))?;
    let num = |t: &str, what: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|_| format!("`{t}` is not a {what}"))
    };
    Ok(Level {
        res: num(r, "resolution")?,
        iters: num(i, "step count")?,
    })
}

/// Creates `dir` with a `.gitignore` of `*` in it (work files that must not
/// be committed by accident), unless it already has one.
pub fn ignore_in_git(dir: &Path) -> anyhow::Result<()> {
    let f = dir.join(".gitignore");
    if f.exists() {
        return Ok(());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    std::fs::write(
        &f,
        "# work files of nerflex (bakes, captures): not for git\n*\n",
    )
    .with_context(|| format!("{}: cannot write", f.display()))
}

/// A progress bar over the stages.
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    /// A bar drawn on stderr (hidden when `quiet`).
    pub fn new(quiet: bool) -> Bar {
        let b = if quiet {
            indicatif::ProgressBar::hidden()
        } else {
            indicatif::ProgressBar::new(0)
        };
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} {prefix:.bold} [{bar:28}] {pos}/{len} {wide_msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        Bar(b)
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl Progress for Bar {
    fn stage(&self, name: &str, steps: u64) {
        self.0.set_prefix(name.to_string());
        self.0.set_length(steps);
        self.0.set_position(0);
        self.0.set_message("");
    }
    fn step(&self, what: &str) {
        self.0.set_message(what.to_string());
        self.0.inc(1);
    }
    fn note(&self, what: &str) {
        self.0.set_message(what.to_string());
    }
}

/// The LPIPS network if its weights are found (and wanted).
pub fn lpips(no_lpips: bool) -> anyhow::Result<Option<Lpips>> {
    if no_lpips {
        return Ok(None);
    }
    match Lpips::default_path() {
        Some(p) => {
            Ok(Some(Lpips::load(&p).with_context(|| {
                format!("loading LPIPS weights {}", p.display())
            })?))
        }
        None => Ok(None),
    }
}

/// Runs `nerflex run`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let device = Device::lookup(&args.device)?;
    let mut opts = args.pipeline.options(&args.out)?;
    let input = match (&args.capture, args.preset) {
        (Some(c), _) => Input::Capture(c.clone()),
        (None, Some(p)) => Input::Preset(p),
        (None, None) => bail!("give --capture DIR or --preset NAME"),
    };
    if matches!(input, Input::Preset(_)) {
        // Before anything is written into OUT.
        crate::pipeline::stages::check_preset_capture(&args.out)?;
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    args.pipeline.ignore_default_store(&args.out)?;
    opts.renders = Some(args.out.join("renders"));
    let lpips = args.pipeline.lpips()?;
    let bar = args.pipeline.bar();
    let t0 = std::time::Instant::now();
    let result = pipeline::run_one(
        &input,
        &opts,
        &args.out,
        args.method,
        &device,
        lpips.as_ref(),
        &bar,
    );
    bar.finish();
    let run = result?;
    let report = run.report_text(t0.elapsed().as_secs_f64(), lpips.is_some());
    simulate::write_plot(
        &run.simulation,
        &format!("{} {} on {}", run.label, args.method, device.name),
        &args.out.join("fps.png"),
    )?;
    simulate::write_csv(&run.simulation, &args.out.join("fps.csv"))?;
    run.write(&args.out)?;
    print!("{report}");
    println!(
        "wrote {}/{{report.json, plan.json, scene.json, fps.png, fps.csv, renders/}}",
        args.out.display()
    );
    if let Some(f) = &run.simulation.load_failure {
        eprintln!(
            "note: the plan's {:.2} MB did not load on {}: {f}",
            Bytes(run.simulation.data_bytes).as_mb(),
            device.name
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser as _;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        pipeline: PipelineArgs,
    }

    fn options(flags: &[&str]) -> anyhow::Result<Options> {
        let cli = Cli::try_parse_from(std::iter::once("x").chain(flags.iter().copied()))?;
        cli.pipeline.options(Path::new("OUT"))
    }

    #[test]
    fn shared_flags_reach_the_options() {
        let o = options(&["--size", "64", "--views", "5", "--frames", "10"]).unwrap();
        assert_eq!((o.size, o.train_views, o.test_views), (64, 5, 10));
        assert_eq!(o.sim.frames, 10);
        assert_eq!(o.store, Path::new("OUT").join("bakes"));
        let o = options(&["--store", "S"]).unwrap();
        assert_eq!(o.store, Path::new("S"));
        // The paper's tight crop unless a margin is asked for.
        assert_eq!(o.crop_margin, 0.0);
        let o = options(&["--crop-margin", "0.1"]).unwrap();
        assert_eq!(o.crop_margin, 0.1);
        // The paper's objective unless the area weighting is asked for.
        assert_eq!(o.objective, Objective::Mean);
        let o = options(&["--objective", "area"]).unwrap();
        assert_eq!(o.objective, Objective::Area);
        assert!(options(&["--objective", "pixels"]).is_err());
    }

    #[test]
    fn the_baker_flags_choose_the_baker() {
        // `run` bakes trained assets unless told otherwise.
        let o = options(&[]).unwrap();
        assert_eq!(o.baker, Scale::Reduced.baker());
        let o = options(&["--baker", "trained"]).unwrap();
        assert_eq!(o.baker, Scale::Reduced.baker());
        assert_eq!(o.baker.name(), "trained");
        let o = options(&["--baker", "hull"]).unwrap();
        assert_eq!(o.baker, Baker::Hull);
        let at = |scale: Scale, flags: &[&str]| {
            let cli =
                Cli::try_parse_from(std::iter::once("x").chain(flags.iter().copied())).unwrap();
            cli.pipeline
                .options_at(Path::new("OUT"), scale)
                .unwrap()
                .baker
        };
        // The paper scale bakes trained assets unless told otherwise.
        assert_eq!(at(Scale::Paper, &[]), Scale::Paper.baker());
        assert_eq!(at(Scale::Paper, &["--baker", "hull"]), Baker::Hull);
        // --quick keeps the hull: the trained baker does not fit its budget.
        assert_eq!(at(Scale::Quick, &[]), Baker::Hull);
        assert_eq!(
            at(Scale::Quick, &["--baker", "trained"]),
            Scale::Quick.baker()
        );
        let o = options(&["--train-levels", "32:10,48:20", "--epochs", "0.5"]).unwrap();
        let Baker::Trained(t) = &o.baker else {
            panic!("not trained: {:?}", o.baker)
        };
        assert_eq!(
            t.train.levels,
            vec![Level { res: 32, iters: 10 }, Level { res: 48, iters: 20 }]
        );
        assert_eq!(t.bake.finetune.epochs, 0.5);
        // Each object's lattice chosen unless --feature-res fixes it.
        assert_eq!(t.choose_lattice_at, Some(lattice_choice::SWEEP_CONFIG));
        let o = options(&["--feature-res", "40"]).unwrap();
        let Baker::Trained(t) = &o.baker else {
            panic!("not trained: {:?}", o.baker)
        };
        assert_eq!((t.choose_lattice_at, t.bake.feature_res), (None, 40));
        for (flags, name) in [
            (&["--feature-res", "2"][..], "--feature-res"),
            (
                &["--baker", "hull", "--feature-res", "40"][..],
                "--feature-res",
            ),
            (&["--baker", "fancy"][..], "fancy"),
            (&["--baker", "hull", "--epochs", "1"][..], "--baker hull"),
            (&["--train-levels", "64"][..], "RES:STEPS"),
            (&["--train-levels", "64:10,32:10"][..], "--train-levels"),
            (&["--epochs=-1"][..], "--epochs"),
            (&["--epochs", "inf"][..], "--epochs"),
        ] {
            let e = options(flags).err().unwrap();
            assert!(format!("{e:#}").contains(name), "{flags:?}: {e:#}");
        }
    }

    #[test]
    fn the_geometry_flag_reaches_the_options_and_needs_the_trained_baker() {
        assert_eq!(options(&[]).unwrap().geometries, Geometries::Planes);
        assert_eq!(
            options(&["--geometry", "planes"]).unwrap().geometries,
            Geometries::Planes
        );
        let o = options(&["--geometry", "both"]).unwrap();
        assert_eq!(o.geometries, Geometries::Both);
        assert_eq!(o.baker.name(), "trained");
        let e = options(&["--geometry", "both", "--baker", "hull"]).unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains("--geometry both") && e.contains("--baker hull"),
            "{e}"
        );
        // --quick's hull, not asked for by name: the error says where it came from.
        let cli = Cli::try_parse_from(["x", "--geometry", "both"]).unwrap();
        let e = cli
            .pipeline
            .options_at(Path::new("OUT"), Scale::Quick)
            .unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains("--geometry both") && e.contains("--quick") && e.contains("--baker trained"),
            "{e}"
        );
        let cli = Cli::try_parse_from(["x", "--geometry", "both", "--baker", "trained"]).unwrap();
        let o = cli
            .pipeline
            .options_at(Path::new("OUT"), Scale::Quick)
            .unwrap();
        assert_eq!(o.geometries, Geometries::Both);
        let e = options(&["--geometry", "mesh"]).err().unwrap();
        assert!(format!("{e:#}").contains("--geometry"), "{e:#}");
    }

    #[test]
    fn work_folders_are_kept_out_of_git() {
        let dir = tempfile::tempdir().unwrap();
        let cli = Cli::try_parse_from(["x"]).unwrap();
        cli.pipeline.ignore_default_store(dir.path()).unwrap();
        let text = std::fs::read_to_string(dir.path().join("bakes/.gitignore")).unwrap();
        assert!(text.lines().any(|l| l == "*"), "{text}");
        let cli = Cli::try_parse_from(["x", "--store", "elsewhere"]).unwrap();
        let other = dir.path().join("other");
        cli.pipeline.ignore_default_store(&other).unwrap();
        assert!(!other.exists());
    }

    #[test]
    fn bad_shared_flags_name_the_flag() {
        for (flags, name) in [
            (&["--frames", "0"][..], "--frames"),
            (&["--size", "8"][..], "--size"),
            (&["--views", "1"][..], "--views"),
            (&["--test-views", "0"][..], "--test-views"),
            (&["--crop-margin=-0.1"][..], "--crop-margin"),
            (&["--crop-margin", "NaN"][..], "--crop-margin"),
            (&["--crop-margin", "2"][..], "--crop-margin"),
        ] {
            let e = options(flags).err().unwrap();
            assert!(format!("{e:#}").contains(name), "{flags:?}: {e:#}");
        }
    }
}
