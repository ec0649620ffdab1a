//! `nerflex profile samples|fit|accuracy`: the white-box profiler.
//!
//! - `samples --g-range 16..512 --p-range 3..33 [--step triple|double]`:
//!   the paper's variable step-size sample points and the matching
//!   `nerflex bake --sweep` flags.
//! - `fit --samples FILE.csv [--object NAME]… --out profiles.json`: fits
//!   both models of each object and writes a scene file in profile form
//!   (`nerflex plan --scene profiles.json` reads it).
//! - `combine --planes profiles.json --mesh-profiles mesh/profiles.json
//!   --out scene.json`: one scene whose objects carry both geometries'
//!   profiles (`"profiles": {"planes", "mesh"}`), so the planner chooses
//!   the geometry per object.
//! - `accuracy --samples FILE.csv [--train-on leave-one-out|variable-step]
//!   [--max-size-mb MB] [--max-g G] [--plots DIR]`: prediction errors beside
//!   the paper's (leave-one-out, or trained on the variable-step points
//!   only), optionally summarised over the held-out points in a size or
//!   grid range, and fitted curves over the measured points (PNG).

use crate::fit::{
    self, accuracy, plots, profiles, samples,
    sampling::{self, IntRange, Step},
    FamilyChoice, ObjectFit,
};
use crate::geometry::Geometry;
use crate::scene_file::{self, Scene};
use anyhow::Context;
use nerflex_core::units::BYTES_PER_MB;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Flags of `nerflex profile`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The `nerflex profile` subcommands.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum Command {
    /// Print the variable step-size sample points (g × {min, mid, max p}).
    Samples(SamplesArgs),
    /// Fit size and quality models to a samples CSV; write profiles.
    Fit(FitArgs),
    /// Leave-one-out accuracy of the fitted models; fitted-curve pictures.
    Accuracy(AccuracyArgs),
    /// Join planes and mesh profiles of the same objects into one scene.
    Combine(CombineArgs),
}

/// Flags of `nerflex profile combine`.
#[derive(Debug, Clone, clap::Args)]
pub struct CombineArgs {
    /// Planes profiles: a scene file in profile form (`fit` on a planes sweep).
    #[arg(long, value_name = "FILE.json")]
    pub planes: PathBuf,
    /// Mesh profiles of the same objects: a scene file in profile form
    /// (`fit` on a `nerflex bake --surface mesh` sweep).
    #[arg(long, value_name = "FILE.json")]
    pub mesh_profiles: PathBuf,
    /// Output scene file (objects with `"profiles": {"planes", "mesh"}`).
    #[arg(long, value_name = "FILE.json")]
    pub out: PathBuf,
}

/// Flags of `nerflex profile samples`.
#[derive(Debug, Clone, clap::Args)]
pub struct SamplesArgs {
    /// Grid range LO..HI (inclusive).
    #[arg(long, value_name = "LO..HI", default_value = "16..512")]
    pub g_range: IntRange,
    /// Patch range LO..HI (inclusive).
    #[arg(long, value_name = "LO..HI", default_value = "3..33")]
    pub p_range: IntRange,
    /// Next g after g′: `triple` = g′ + 2·g′ (the paper's "step 2·g′"),
    /// `double` = 2·g′.
    #[arg(long, value_enum, default_value_t = Step::Triple)]
    pub step: Step,
    /// Print CSV (`g,p`) only.
    #[arg(long)]
    pub csv: bool,
}

/// Flags of `nerflex profile fit`.
#[derive(Debug, Clone, clap::Args)]
pub struct FitArgs {
    /// Samples CSV (`object,g,p,size_bytes,gpu_bytes,quads,ssim,psnr,lpips`).
    #[arg(long, value_name = "FILE.csv")]
    pub samples: PathBuf,
    /// Fit only this object (repeatable; default: every object).
    #[arg(long = "object", value_name = "NAME")]
    pub objects: Vec<String>,
    /// Output scene file (profile form).
    #[arg(long, value_name = "FILE.json")]
    pub out: PathBuf,
    /// Model family: `auto` fits the size as `(g+a)³`, `(g+a)²` and the
    /// quads law `(g+a)^1.5·(p+b)² + c·(g+a)²`, the quality as `(g+a)³` and
    /// `(g+a)²`, and keeps the lowest RMSE of each; `classic` is `auto`
    /// without the quads law (the fits before it existed).
    #[arg(long, value_enum, default_value_t = FamilyChoice::Auto)]
    pub family: FamilyChoice,
    /// g values of the written configuration space (default: the sampled ones).
    #[arg(long, value_name = "G,G,…", value_delimiter = ',')]
    pub grid: Vec<u32>,
    /// p values of the written configuration space (default: the sampled ones).
    #[arg(long, value_name = "P,P,…", value_delimiter = ',')]
    pub patch: Vec<u32>,
}

/// Flags of `nerflex profile accuracy`.
#[derive(Debug, Clone, clap::Args)]
pub struct AccuracyArgs {
    /// Samples CSV.
    #[arg(long, value_name = "FILE.csv")]
    pub samples: PathBuf,
    /// Only this object (repeatable; default: every object).
    #[arg(long = "object", value_name = "NAME")]
    pub objects: Vec<String>,
    /// Model family (see `fit`).
    #[arg(long, value_enum, default_value_t = FamilyChoice::Auto)]
    pub family: FamilyChoice,
    /// What the fits see: every sample but the predicted one
    /// (`leave-one-out`), or only the sweep's variable-step points
    /// (`variable-step`, see `--step`; all other samples are predicted).
    #[arg(long, value_enum, default_value_t = TrainOn::LeaveOneOut)]
    pub train_on: TrainOn,
    /// With `--train-on variable-step`: the next g after g′ is the sweep's
    /// first g ≥ 3·g′ (`triple`, the paper's "step 2·g′") or ≥ 2·g′ (`double`).
    #[arg(long, value_enum, default_value_t = Step::Triple)]
    pub step: Step,
    /// Train only on samples with these g (and `--train-patch` p) values;
    /// every other sample is predicted. Default with `--train-patch` alone:
    /// every g.
    #[arg(long, value_name = "G,G,…", value_delimiter = ',')]
    pub train_grid: Vec<u32>,
    /// Train only on samples with these p values (see `--train-grid`).
    #[arg(long, value_name = "P,P,…", value_delimiter = ',')]
    pub train_patch: Vec<u32>,
    /// Summarise only held-out points whose measured size is at most this
    /// many MB (10^6 bytes); the fits still use every training sample.
    #[arg(long, value_name = "MB")]
    pub max_size_mb: Option<f64>,
    /// Summarise only held-out points with g at most this (fits unchanged).
    #[arg(long, value_name = "G")]
    pub max_g: Option<u32>,
    /// Write `<object>_ssim.png` and `<object>_size.png` here (the curves of
    /// the full fit, or of the training fit with a training subset).
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Also write the summaries and every left-out point as JSON here.
    #[arg(long, value_name = "FILE.json")]
    pub json: Option<PathBuf>,
}

/// What `nerflex profile accuracy` trains its fits on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum TrainOn {
    /// Each sample predicted from all the object's other samples.
    #[default]
    LeaveOneOut,
    /// Only the variable-step points of the sweep's g and p values.
    VariableStep,
}

/// Runs `nerflex profile`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let text = match &args.command {
        Command::Samples(a) => samples_report(a)?,
        Command::Fit(a) => fit_report(a)?,
        Command::Accuracy(a) => accuracy_report(a)?,
        Command::Combine(a) => combine_report(a)?,
    };
    print!("{text}");
    Ok(())
}

/// What `nerflex profile samples` prints.
pub fn samples_report(args: &SamplesArgs) -> anyhow::Result<String> {
    let plan = sampling::variable_step(args.g_range.0.clone(), args.p_range.0.clone(), args.step)
        .map_err(anyhow::Error::msg)?;
    let mut out = String::new();
    if args.csv {
        out.push_str("g,p\n");
        for (g, p) in plan.points() {
            let _ = writeln!(out, "{g},{p}");
        }
        return Ok(out);
    }
    let rule = match args.step {
        Step::Triple => "g_{k+1} = g_k + 2·g_k = 3·g_k",
        Step::Double => "g_{k+1} = 2·g_k",
    };
    let _ = writeln!(
        out,
        "# variable step over g {} and p {}: {rule}; p = min, mid, max",
        args.g_range, args.p_range
    );
    let _ = writeln!(out, "# {} sample points", plan.points().len());
    let _ = writeln!(out, "{:>6} {:>4}", "g", "p");
    for (g, p) in plan.points() {
        let _ = writeln!(out, "{g:>6} {p:>4}");
    }
    let _ = writeln!(out, "# nerflex bake flags: {}", plan.bake_flags());
    Ok(out)
}

fn load_samples(path: &std::path::Path) -> anyhow::Result<Vec<samples::Sample>> {
    Ok(samples::read(path)?)
}

fn describe(f: &ObjectFit) -> String {
    let s = &f.size.best;
    let q = &f.quality.best;
    let others = |ff: &fit::FamilyFit, scale: f64, unit: &str| {
        ff.tried
            .iter()
            .map(|t| format!("{} {:.4}{unit}", t.params.family, t.residuals.rmse / scale))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let bound = |c: &fit::CurveFit| {
        let names = ["a", "b", "m", "c"];
        let hit: Vec<&str> = names
            .iter()
            .zip(c.at_bound)
            .filter(|(_, h)| *h)
            .map(|(n, _)| *n)
            .collect();
        if hit.is_empty() {
            String::new()
        } else {
            format!("  [at bound: {}]", hit.join(", "))
        }
    };
    format!(
        "{name}: {n} samples\n  size    S = {k:.6e}·(g{a:+.3})^{e}·(p{b:+.3})²{c} + {m:.0} B   RMSE {rmse:.4} MB, max {max:.4} MB ({fam}; RMSE {tried}){sb}\n  quality Q = {qm:.5} − {qk:.6e}/((g{qa:+.3})^{qe}·(p{qb:+.3})²)   RMSE {qr:.5}, max {qx:.5} ({qfam}; RMSE {qtried}){qbd}\n",
        name = f.name,
        n = f.samples,
        k = s.params.k,
        a = s.params.a,
        e = s.params.family.g_power(),
        b = s.params.b,
        c = if s.params.c != 0.0 {
            format!(" + {:.3}·(g{:+.3})²", s.params.c, s.params.a)
        } else {
            String::new()
        },
        m = s.params.m,
        rmse = s.residuals.rmse / 1e6,
        max = s.residuals.max_abs / 1e6,
        fam = s.params.family,
        tried = others(&f.size, 1e6, " MB"),
        sb = bound(s),
        qm = q.params.m,
        qk = q.params.k,
        qa = q.params.a,
        qe = q.params.family.g_power(),
        qb = q.params.b,
        qr = q.residuals.rmse,
        qx = q.residuals.max_abs,
        qfam = q.params.family,
        qtried = others(&f.quality, 1.0, ""),
        qbd = bound(q),
    )
}

/// Fits, writes `--out`, and returns what `nerflex profile fit` prints.
pub fn fit_report(args: &FitArgs) -> anyhow::Result<String> {
    let all = load_samples(&args.samples)?;
    let space = profiles::Space {
        grids: args.grid.clone(),
        patches: args.patch.clone(),
    };
    let domain = match (
        args.grid.iter().min(),
        args.grid.iter().max(),
        args.patch.iter().min(),
        args.patch.iter().max(),
    ) {
        (Some(&g_min), Some(&g_max), Some(&p_min), Some(&p_max)) => Some(fit::Domain {
            g_min,
            g_max,
            p_min,
            p_max,
        }),
        _ => None,
    };
    if args.grid.contains(&0) || args.patch.contains(&0) {
        anyhow::bail!("--grid and --patch values must be positive");
    }
    let start = Instant::now();
    let fits = fit::fit_objects(&all, &args.objects, domain, args.family)
        .with_context(|| format!("fitting {}", args.samples.display()))?;
    let elapsed = start.elapsed();
    let sampled = |name: &str| -> Vec<(u32, u32)> {
        all.iter()
            .filter(|s| s.object == name)
            .map(|s| (s.g, s.p))
            .collect()
    };
    let json = profiles::scene_json(&fits, sampled, &space)?;
    let text = serde_json::to_string_pretty(&json)? + "\n";
    fit::write_atomic(&args.out, text.as_bytes())
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    let mut out = String::new();
    for f in &fits {
        out.push_str(&describe(f));
    }
    let _ = writeln!(
        out,
        "fitted {} object(s) in {:.3} s; wrote {}",
        fits.len(),
        elapsed.as_secs_f64(),
        args.out.display()
    );
    Ok(out)
}

/// Runs the leave-one-out evaluation, draws plots, returns the printout.
pub fn accuracy_report(args: &AccuracyArgs) -> anyhow::Result<String> {
    let all = load_samples(&args.samples)?;
    let names = fit::object::select(&all, &args.objects)?;
    let selected: Vec<&samples::Sample> =
        all.iter().filter(|s| names.contains(&s.object)).collect();
    let distinct = |f: fn(&samples::Sample) -> u32| {
        let mut v: Vec<u32> = selected.iter().map(|s| f(s)).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let lists_given = !args.train_grid.is_empty() || !args.train_patch.is_empty();
    let subset = match (args.train_on, lists_given) {
        (TrainOn::VariableStep, true) => anyhow::bail!(
            "--train-grid/--train-patch and --train-on variable-step both choose the \
             training samples; give one or the other"
        ),
        (TrainOn::VariableStep, false) => {
            let plan =
                sampling::variable_step_on(&distinct(|s| s.g), &distinct(|s| s.p), args.step);
            Some((plan.grids, plan.patches))
        }
        (TrainOn::LeaveOneOut, true) => {
            let or_all = |v: &Vec<u32>, f| if v.is_empty() { distinct(f) } else { v.clone() };
            Some((
                or_all(&args.train_grid, |s| s.g),
                or_all(&args.train_patch, |s| s.p),
            ))
        }
        (TrainOn::LeaveOneOut, false) => None,
    };
    if let Some(mb) = args.max_size_mb {
        if !(mb.is_finite() && mb > 0.0) {
            anyhow::bail!("--max-size-mb must be a positive number of MB, got {mb}");
        }
    }
    let start = Instant::now();
    let mut acc = match &subset {
        None => accuracy::leave_one_out(&all, &args.objects, args.family)
            .with_context(|| format!("leave-one-out on {}", args.samples.display()))?,
        Some((grids, patches)) => {
            accuracy::train_subset(&all, &args.objects, args.family, grids, patches)
                .with_context(|| format!("training subset of {}", args.samples.display()))?
        }
    };
    let elapsed = start.elapsed();
    if let Some(mb) = args.max_size_mb {
        let limit = mb * BYTES_PER_MB as f64;
        acc = acc.restricted(&format!("measured size ≤ {mb} MB"), |p| {
            p.size_measured.0 as f64 <= limit
        });
    }
    if let Some(g) = args.max_g {
        acc = acc.restricted(&format!("g ≤ {g}"), |p| p.g <= g);
    }
    let mut out = accuracy::table(&acc);
    out.push('\n');
    out.push_str(&accuracy::fit_table(&acc));
    let fits: usize = match subset {
        None => acc.objects.iter().map(|o| o.fit.samples + 1).sum(),
        Some(_) => acc.objects.len(),
    };
    let _ = writeln!(
        out,
        "\n{fits} object fits in {:.3} s",
        elapsed.as_secs_f64()
    );
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&accuracy::to_json(&acc))? + "\n";
        fit::write_atomic(path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        let _ = writeln!(out, "wrote {}", path.display());
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for o in &acc.objects {
            let samples = fit::object::of_object(&all, &o.fit.name);
            for path in plots::draw(&o.fit, &samples, dir)? {
                let _ = writeln!(out, "wrote {}", path.display());
            }
        }
    }
    Ok(out)
}

/// Joins the two files' profiles, writes `--out` (only when every check
/// passed), and returns what `nerflex profile combine` prints.
pub fn combine_report(args: &CombineArgs) -> anyhow::Result<String> {
    let planes = scene_file::load(&args.planes).context("--planes")?;
    let mesh = scene_file::load(&args.mesh_profiles).context("--mesh-profiles")?;
    let scene = combine(&planes, &mesh).map_err(|e| {
        anyhow::anyhow!(
            "--planes {} / --mesh-profiles {}: {e}",
            args.planes.display(),
            args.mesh_profiles.display()
        )
    })?;
    let text = serde_json::to_string_pretty(&scene.to_json())? + "\n";
    // Read back what is written, so a file this writes always plans.
    scene_file::parse(&text, &args.out.display().to_string())?;
    fit::write_atomic(&args.out, text.as_bytes())
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    let mut out = String::new();
    for o in &scene.objects {
        let _ = writeln!(
            out,
            "{}: {} configurations ({} planes, {} mesh)",
            o.name,
            o.configs.len(),
            o.configs
                .iter()
                .filter(|c| c.geometry == Geometry::Planes)
                .count(),
            o.configs
                .iter()
                .filter(|c| c.geometry == Geometry::Mesh)
                .count()
        );
    }
    let _ = writeln!(out, "wrote {}", args.out.display());
    Ok(out)
}

/// `planes`' objects with `mesh`'s profile of the same name added as their
/// mesh profile ([`scene_file::union`], errors naming the two flags).
pub fn combine(planes: &Scene, mesh: &Scene) -> Result<Scene, String> {
    scene_file::union((planes, "--planes"), (mesh, "--mesh-profiles"))
}
