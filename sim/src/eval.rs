//! The NeRFlex paper's evaluation, regenerated from scratch: Scenes 1–4
//! (built-in) × {iPhone 13, Pixel 4} × {Single-NeRF, Block-NeRF, NeRFlex
//! (DP), NeRFlex-Fairness, NeRFlex-SLSQP}: SSIM / PSNR / LPIPS, data size,
//! mean FPS and load failures; Scene 4's per-object quality and size
//! allocation; the overhead breakdown (segmentation, profiler, DP); the FPS
//! curves of Scene 3; and the calibration check of the device model. The
//! same on the real lego + chair capture (composed side by side).
//!
//! - [`calibrate`]: the one throughput factor per device;
//! - [`stats`]: bootstrap intervals, paired differences, rank correlation;
//! - [`compare`]: the intervals and paired differences of a report's rows;
//! - [`detail`]: does the segmentation's measure predict what a dedicated
//!   network gains?
//! - [`verdicts`]: one line per claim of the paper;
//! - [`honesty`]: what this evaluation substitutes for the paper's setup;
//! - [`scale`]: the paper-scale and quick settings;
//! - [`plots`]: the PNG figures;
//! - [`report`]: the Markdown report.
//!
//! Everything measured goes into `eval.json`; the Markdown and the plots
//! are drawn from it.

pub mod calibrate;
pub mod compare;
pub mod detail;
pub mod honesty;
pub mod plots;
pub mod renders;
pub mod report;
pub mod scale;
pub mod stats;
pub mod verdicts;

use crate::baselines::Method;
use crate::device::Device;
use crate::metrics::Lpips;
use crate::pipeline::stages::{is_planner, next_budget, plan_within, planned_bytes, MAX_REPLANS};
use crate::pipeline::views::ViewScores;
use crate::pipeline::{
    method_plan, prepare, realise, simulate_devices, Input, Options, Prepared, Progress, Realised,
    RealisedObject, SceneQuality, Timings,
};
use crate::procedural::Preset;
use crate::simulate::output::write_text;
use crate::simulate::Simulation;
use anyhow::Context as _;
use nerflex_core::units::Bytes;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The methods of the paper's comparison, in the order reported.
pub const METHODS: [Method; 5] = [
    Method::Single,
    Method::Block,
    Method::Dp,
    Method::Fairness,
    Method::Slsqp,
];

/// The paper's figures the device model is calibrated against: NeRFlex (DP)
/// on Scene 3, mean FPS per device.
pub const CALIBRATION_TARGETS: [(&str, f64); 2] = [("iphone13", 35.0), ("pixel4", 25.0)];

/// The paper's overhead breakdown (seconds, twenty training images).
pub const PAPER_OVERHEAD_S: [(&str, f64); 3] =
    [("segmentation", 3.8), ("profiler", 0.277), ("DP", 1.87)];

/// What to evaluate.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// Pipeline settings (sizes, views, sample points, store).
    pub pipeline: Options,
    /// Built-in scenes.
    pub scenes: Vec<Preset>,
    /// Devices.
    pub devices: Vec<Device>,
    /// The real single-object captures to compose (lego, chair), if any.
    pub real: Vec<PathBuf>,
    /// Image side of the composed real capture.
    pub real_size: u32,
    /// The scene whose FPS curves are kept and plotted (the paper: Scene 3).
    pub fps_scene: Preset,
}

/// One (scene, device, method).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// Scene.
    pub scene: String,
    /// Device.
    pub device: String,
    /// Method.
    pub method: Method,
    /// Why there is no plan (e.g. SLSQP found none), if so.
    pub error: Option<String>,
    /// The budget, bytes.
    pub budget_bytes: u64,
    /// Whether the planner's sizes fit the budget.
    pub planned_feasible: bool,
    /// Total size the planner predicted, bytes (for Single/Block: baked).
    pub predicted_bytes: u64,
    /// Total size of the baked files, bytes.
    pub file_bytes: u64,
    /// Seconds the planner took (re-plans included).
    pub plan_s: f64,
    /// Re-plans because the bakes came out over the budget (0 if older).
    #[serde(default)]
    pub replans: u32,
    /// The objects as baked.
    pub objects: Vec<RealisedObject>,
    /// Whole-scene quality on the held-out views.
    pub quality: Option<SceneQuality>,
    /// Why the scene did not load on the device, if so.
    pub load_failure: Option<String>,
    /// Whether the data is over the device's soft limit.
    pub over_soft_limit: bool,
    /// Mean FPS over the frames (0 on a load failure).
    pub mean_fps: f64,
    /// Mean FPS after loading.
    pub steady_fps: f64,
    /// When loading finished, seconds.
    pub loaded_at_s: Option<f64>,
    /// Mean raster time per frame after loading, ms.
    #[serde(default)]
    pub raster_ms: f64,
    /// Mean MLP shading time per frame after loading, ms.
    #[serde(default)]
    pub shade_ms: f64,
    /// Quads of the loaded scene.
    #[serde(default)]
    pub quads: u64,
    /// Every held-out view's scores (whole image and each scene object in
    /// its box): what the intervals and paired differences are over.
    #[serde(default)]
    pub views: Vec<ViewScores>,
}

/// A scene's results.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneReport {
    /// Scene name.
    pub scene: String,
    /// Networks of the segmentation and their objects.
    pub networks: Vec<(String, Vec<String>)>,
    /// Stage timings.
    pub timings: Timings,
    /// The profiler's sample bakes (object, g, p, sizes, quality).
    pub samples: Vec<crate::bake::sweep::Sample>,
    /// Every (device, method).
    pub rows: Vec<Row>,
    /// Each scene object: its network, complexity and detail frequencies.
    #[serde(default)]
    pub objects: Vec<detail::ObjectDetail>,
    /// Each network's feature lattice as the trained baker chose it (its
    /// cells and the candidates' held-back scores), so a report says which
    /// lattice every bake used; empty for the hull baker or a fixed
    /// lattice (and in reports written before session 46).
    #[serde(default)]
    pub lattices: Vec<crate::bake::sweep::LatticeChosen>,
}

/// One FPS curve (the paper's FPS figure).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FpsCurve {
    /// Scene.
    pub scene: String,
    /// Device.
    pub device: String,
    /// Method.
    pub method: Method,
    /// Per-frame FPS.
    pub fps: Vec<f64>,
    /// Mean.
    pub mean_fps: f64,
    /// Whether it failed to load.
    pub load_failure: Option<String>,
}

/// Everything the evaluation measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvalReport {
    /// Settings, in words.
    pub settings: Vec<(String, String)>,
    /// The built-in scenes.
    pub scenes: Vec<SceneReport>,
    /// The real lego + chair composite, if evaluated.
    pub real: Option<SceneReport>,
    /// FPS curves of the FPS scene.
    pub fps: Vec<FpsCurve>,
    /// The device model against the paper's FPS figures.
    pub calibration: Vec<calibrate::Calibration>,
    /// Wall-clock seconds of the whole evaluation.
    pub wall_s: f64,
    /// The baker every asset came from ([`crate::pipeline::BakeStore::baker`]).
    #[serde(default = "hull_baker")]
    pub baker: String,
}

/// What reports older than the field were made with.
fn hull_baker() -> String {
    crate::pipeline::bakes::HULL_BAKER.to_string()
}

/// What a scene's evaluation adds to the report besides its rows.
struct Extras<'a> {
    /// Keep the FPS curves and check the calibration (the FPS scene).
    keep_fps: bool,
    fps: &'a mut Vec<FpsCurve>,
    calibration: &'a mut Vec<calibrate::Calibration>,
    /// Keep every realised plan's held-out renders under this folder and
    /// write each device's strip of one view into the second (`None`: no
    /// pictures, e.g. a composite, which has no whole-scene view).
    renders: Option<(PathBuf, &'a Path)>,
}

/// A plan measured once: its configurations, its method, the result and
/// where its held-out renders went.
type Measured = (Vec<(String, u32, u32)>, Method, Realised, Option<PathBuf>);

/// A plan (or why there is none) and the devices it is simulated on.
type DevicePlans<'d> = Vec<(
    Vec<&'d Device>,
    anyhow::Result<(crate::baselines::Plan, f64)>,
)>;

/// Evaluates one prepared scene: every method on every device.
fn evaluate_scene(
    prepared: &Prepared,
    devices: &[Device],
    opts: &Options,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
    extras: Extras<'_>,
) -> anyhow::Result<SceneReport> {
    let Extras {
        keep_fps,
        fps: fps_out,
        calibration: calib_out,
        renders,
    } = extras;
    let mut rows: Vec<Row> = Vec::new();
    // (device, method, render folder of its realised plan) for the strips.
    let mut pictured: Vec<(String, Method, Option<PathBuf>)> = Vec::new();
    // Realised plans already measured, by their configurations (a plan the
    // same on both devices is rendered and measured once).
    let mut measured: Vec<Measured> = Vec::new();
    for &method in &METHODS {
        // Device-independent plans (Single, Block) are simulated on all
        // devices at once; the planner's are per device.
        let per_device: DevicePlans<'_> = match method {
            Method::Single | Method::Block => {
                let Some(first) = devices.first() else {
                    continue;
                };
                vec![(
                    devices.iter().collect(),
                    method_plan(prepared, method, first, opts, lpips, progress),
                )]
            }
            _ => devices
                .iter()
                .map(|d| {
                    (
                        vec![d],
                        method_plan(prepared, method, d, opts, lpips, progress),
                    )
                })
                .collect(),
        };
        for (devs, planned) in per_device {
            let (plan, plan_s) = match planned {
                Ok(p) => p,
                Err(e) => {
                    for d in devs {
                        rows.push(Row {
                            scene: prepared.label.clone(),
                            device: d.name.clone(),
                            method,
                            error: Some(format!("{e:#}")),
                            budget_bytes: d.budget().0,
                            planned_feasible: false,
                            predicted_bytes: 0,
                            file_bytes: 0,
                            plan_s: 0.0,
                            replans: 0,
                            objects: Vec::new(),
                            quality: None,
                            load_failure: None,
                            over_soft_limit: false,
                            mean_fps: 0.0,
                            steady_fps: 0.0,
                            loaded_at_s: None,
                            raster_ms: 0.0,
                            shade_ms: 0.0,
                            quads: 0,
                            views: Vec::new(),
                        });
                    }
                    continue;
                }
            };
            let (mut plan, mut plan_s) = (plan, plan_s);
            let mut replans = 0;
            let idx = loop {
                let key: Vec<(String, u32, u32)> = plan
                    .objects
                    .iter()
                    .map(|o| (o.name.clone(), o.g, o.p))
                    .collect();
                let idx = match measured.iter().position(|(k, m, _, _)| {
                    *k == key && (*m == method || !is_baseline(*m) && !is_baseline(method))
                }) {
                    Some(i) => i,
                    None => {
                        let mut o = opts.clone();
                        o.renders = renders.as_ref().map(|(root, _)| {
                            let names: Vec<&str> = devs.iter().map(|d| d.name.as_str()).collect();
                            renders::plan_dir(root, measured.len(), method, &names)
                        });
                        let r = realise(prepared, &plan, &o, lpips, progress)?;
                        measured.push((key, method, r, o.renders));
                        measured.len() - 1
                    }
                };
                // A planner's plan is per device: if it baked over that
                // device's budget, plan again against less (see next_budget).
                let over = match (devs.as_slice(), measured.get(idx)) {
                    ([d], Some((_, _, r, _))) if is_planner(method) && replans < MAX_REPLANS => {
                        next_budget(
                            d.budget(),
                            planned_bytes(&plan),
                            Bytes(r.file_bytes()),
                            replans,
                        )
                        .map(|b| (*d, b))
                    }
                    _ => None,
                };
                let Some((d, budget)) = over else { break idx };
                let (p, s) = plan_within(prepared, method, d, budget)?;
                plan = p;
                plan_s += s;
                replans += 1;
            };
            let realised = &measured[idx].2;
            for d in &devs {
                pictured.push((d.name.clone(), method, measured[idx].3.clone()));
            }
            let devices_owned: Vec<Device> = devs.iter().map(|d| (*d).clone()).collect();
            progress.stage(
                &format!("simulating {} {method}", prepared.label),
                devices_owned.len() as u64,
            );
            let sims = simulate_devices(realised, &devices_owned, opts)?;
            for (d, sim) in devices_owned.iter().zip(&sims) {
                progress.step(&d.name);
                if keep_fps {
                    fps_out.push(FpsCurve {
                        scene: prepared.label.clone(),
                        device: d.name.clone(),
                        method,
                        fps: sim.frames.iter().map(|f| f.fps).collect(),
                        mean_fps: sim.mean_fps,
                        load_failure: sim.load_failure.as_ref().map(ToString::to_string),
                    });
                    if method == Method::Dp {
                        if let Some((_, target)) =
                            CALIBRATION_TARGETS.iter().find(|(n, _)| *n == d.name)
                        {
                            progress.stage(&format!("calibration check on {}", d.name), 1);
                            calib_out.push(calibrate::calibrate(
                                realised,
                                d,
                                opts.turntable,
                                opts.sim,
                                *target,
                                &format!("{} dp", prepared.label),
                            )?);
                            progress.step("done");
                        }
                    }
                }
                rows.push(row(
                    prepared,
                    d,
                    method,
                    &plan,
                    (plan_s, replans),
                    realised,
                    sim,
                ));
            }
        }
    }
    if let (Some((_, out)), Some(capture)) = (&renders, &prepared.capture) {
        if let Some(truth) = capture.test.get(renders::VIEW) {
            for d in devices {
                let entries: Vec<renders::Entry> = pictured
                    .iter()
                    .filter(|(dev, _, _)| *dev == d.name)
                    .filter_map(|(_, m, dir)| {
                        let row = rows.iter().find(|r| r.device == d.name && r.method == *m)?;
                        Some(renders::Entry {
                            method: *m,
                            dir: dir.clone()?,
                            scores: row.views.iter().find(|v| v.view == renders::VIEW).cloned(),
                            megabytes: row.file_bytes as f64 / 1e6,
                        })
                    })
                    .collect();
                if entries.is_empty() {
                    continue;
                }
                let path = out.join(renders::strip_name(&prepared.label, &d.name));
                // A picture is not a measurement: a failure to draw it is
                // reported, not allowed to end a run of hours.
                if let Err(e) = renders::write_strip(&truth.image, &entries, &path) {
                    eprintln!("warning: {e:#}");
                }
            }
        }
    }
    Ok(SceneReport {
        scene: prepared.label.clone(),
        networks: prepared
            .networks
            .iter()
            .map(|n| (n.name.clone(), n.objects.clone()))
            .collect(),
        timings: prepared.timings,
        samples: prepared.samples.iter().map(|b| b.sample.clone()).collect(),
        rows,
        objects: detail::object_details(&prepared.segmentation),
        // Read from the store, where the sample bakes put them.
        lattices: opts
            .bake_store()
            .stored_lattices(prepared.networks.iter().map(|n| &n.views)),
    })
}

fn is_baseline(m: Method) -> bool {
    matches!(m, Method::Single | Method::Block)
}

fn row(
    prepared: &Prepared,
    d: &Device,
    method: Method,
    plan: &crate::baselines::Plan,
    (plan_s, replans): (f64, u32),
    realised: &Realised,
    sim: &Simulation,
) -> Row {
    Row {
        scene: prepared.label.clone(),
        device: d.name.clone(),
        method,
        error: None,
        budget_bytes: d.budget().0,
        planned_feasible: plan.total_size_bytes <= d.budget().0,
        predicted_bytes: plan.total_size_bytes,
        file_bytes: realised.file_bytes(),
        plan_s,
        replans,
        objects: realised.objects.clone(),
        quality: Some(realised.quality),
        load_failure: sim.load_failure.as_ref().map(ToString::to_string),
        over_soft_limit: sim.over_soft_limit,
        mean_fps: sim.mean_fps,
        steady_fps: sim.steady_fps,
        loaded_at_s: sim.loaded_at_s,
        raster_ms: sim.steady_raster_ms,
        shade_ms: sim.steady_shade_ms,
        quads: realised.objects.iter().map(|o| o.quads).sum(),
        views: realised.views.clone(),
    }
}

/// Runs the whole evaluation, writing `eval.json`, `report.md` and the
/// plots into `out` (scene work folders under `out/scenes/`).
pub fn run(
    opts: &EvalOptions,
    out: &Path,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<EvalReport> {
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut fps = Vec::new();
    let mut calibration = Vec::new();
    let mut scenes = Vec::new();
    for &p in &opts.scenes {
        let dir = out.join("scenes").join(p.name());
        let prepared = prepare(&Input::Preset(p), &opts.pipeline, &dir, lpips, progress)
            .with_context(|| format!("preparing {}", p.name()))?;
        scenes.push(evaluate_scene(
            &prepared,
            &opts.devices,
            &opts.pipeline,
            lpips,
            progress,
            Extras {
                keep_fps: p == opts.fps_scene,
                fps: &mut fps,
                calibration: &mut calibration,
                renders: Some((dir.join("renders"), out)),
            },
        )?);
    }
    let real = if opts.real.is_empty() {
        None
    } else {
        let dir = out.join("scenes").join("real");
        let input = Input::Composite {
            dirs: opts.real.clone(),
            size: opts.real_size,
        };
        // A side-by-side montage: every object sits at its own capture's
        // origin; place them 1.5 units apart on the turntable and step the
        // camera back so both stay in view.
        let mut popts = opts.pipeline.clone();
        popts.spread = Some(1.5);
        popts.turntable.distance *= 1.6;
        let prepared = prepare(&input, &popts, &dir, lpips, progress)
            .context("preparing the real composite")?;
        let mut sink_fps = Vec::new();
        let mut sink_cal = Vec::new();
        Some(evaluate_scene(
            &prepared,
            &opts.devices,
            &popts,
            lpips,
            progress,
            Extras {
                keep_fps: false,
                fps: &mut sink_fps,
                calibration: &mut sink_cal,
                renders: None,
            },
        )?)
    };
    let report = EvalReport {
        settings: settings(opts, lpips.is_some()),
        scenes,
        real,
        fps,
        calibration,
        wall_s: t0.elapsed().as_secs_f64(),
        baker: opts.pipeline.baker.name().to_string(),
    };
    write(&report, out)?;
    Ok(report)
}

fn settings(opts: &EvalOptions, lpips: bool) -> Vec<(String, String)> {
    let p = &opts.pipeline;
    let c = &p.configs;
    let list = |v: &[u32]| v.iter().map(u32::to_string).collect::<Vec<_>>().join(", ");
    vec![
        (
            "built-in captures".into(),
            format!(
                "{}×{} pixels, {} training + {} held-out views",
                p.size, p.size, p.train_views, p.test_views
            ),
        ),
        (
            "profiler sample points".into(),
            format!(
                "g from {} to {} (×{} steps) × p ∈ {{{}, middle, {}}}",
                c.sample_grid.0,
                c.sample_grid.1,
                c.sample_step.factor(),
                c.sample_patch.0,
                c.sample_patch.1
            ),
        ),
        (
            "planner's configurations".into(),
            format!(
                "g ∈ {{{}}} × p ∈ {{{}}}",
                list(&c.space_grid),
                list(&c.space_patch)
            ),
        ),
        (
            "turntable".into(),
            format!(
                "{} frames, {} s per revolution, coverage at {} angles, {} px wide",
                p.sim.frames, p.sim.period_s, p.turntable.angles, p.turntable.coverage_width
            ),
        ),
        (
            "real capture".into(),
            if opts.real.is_empty() {
                "not evaluated".into()
            } else {
                format!(
                    "{} resized to {}×{} and composed side by side",
                    opts.real
                        .iter()
                        .map(|d| d.display().to_string())
                        .collect::<Vec<_>>()
                        .join(" + "),
                    opts.real_size,
                    opts.real_size
                )
            },
        ),
        ("baker".into(), baker_words(&p.baker)),
        (
            "segmentation crop".into(),
            if p.crop_margin == 0.0 {
                "the mask's box (margin 0, as the paper)".into()
            } else {
                format!(
                    "the mask's box grown by {} of its larger side",
                    p.crop_margin
                )
            },
        ),
        (
            "selector objective".into(),
            match p.objective {
                crate::baselines::Objective::Mean => {
                    "the sum of each network's predicted SSIM on its own views (the paper's)".into()
                }
                crate::baselines::Objective::Area => {
                    "each network's predicted SSIM weighted by 1 / zoom² (`--objective area`; predicted SSIM reported unweighted)".into()
                }
            },
        ),
        (
            "intervals".into(),
            format!(
                "95 % percentile bootstrap over the held-out views, {} resamples, seed {}",
                stats::RESAMPLES,
                stats::SEED
            ),
        ),
        (
            "LPIPS".into(),
            if lpips {
                "AlexNet v0.1".into()
            } else {
                "skipped (no weights)".into()
            },
        ),
    ]
}

/// The baker and its settings, in words.
fn baker_words(b: &crate::pipeline::Baker) -> String {
    match b {
        crate::pipeline::Baker::Hull => "visual hull (no training)".into(),
        crate::pipeline::Baker::Trained(t) => format!(
            "trained: fields {} at {} rays per step, SH degree {}; bakes fine-tuned {} epoch(s), surface alpha {}",
            t.train
                .levels
                .iter()
                .map(|l| format!("{}³ × {} steps", l.res, l.iters))
                .collect::<Vec<_>>()
                .join(" → "),
            t.train.batch,
            t.train.sh_degree,
            t.bake.finetune.epochs,
            t.bake.surface_alpha
        ),
    }
}

/// Writes `eval.json`, `report.md` and the plots.
pub fn write(report: &EvalReport, out: &Path) -> anyhow::Result<()> {
    write_text(
        &out.join("eval.json"),
        &serde_json::to_string_pretty(report)?,
    )?;
    write_report(report, out)
}

/// Writes `report.md` and the plots only (`nerflex eval --redraw`).
pub fn write_report(report: &EvalReport, out: &Path) -> anyhow::Result<()> {
    let mut pictures = plots::draw(report, out)?;
    pictures.extend(renders::listed(out));
    write_text(&out.join("report.md"), &report::markdown(report, &pictures))?;
    Ok(())
}
