//! The stages of the NeRFlex pipeline, each a function of the previous
//! stages' results, so `nerflex run` (one method, one device) and
//! `nerflex eval` (every method, both devices, four scenes) share them.
//!
//! 1. [`prepare`]: capture (a built-in preset is generated), detail-based
//!    segmentation, the profiler's sample bakes, curve fitting → a
//!    [`Prepared`] scene with fitted profiles (the planner's input);
//! 2. [`plan_for`]: one method's plan for one device's budget (timed);
//! 3. [`realise`]: the plan's configurations baked (or found in the store),
//!    the held-out views of the whole scene rendered with every object's
//!    asset and measured (SSIM, PSNR, LPIPS) → a [`Realised`] scene;
//! 4. [`simulate_on`]: the realised scene on a device (load, FPS).
//!
//! Single-NeRF and Block-NeRF do not go through the profiler: Single-NeRF is
//! one bake of the whole scene (every object's pixels as one silhouette) at
//! (128, 17), Block-NeRF one bake per object at (128, 17) from the original
//! (not enlarged) views ([`baseline_views`], [`baseline_plan`]).

use super::bakes::{BakeRequest, BakeStore, Baked, Baker};
use super::geometries::{self, Geometries};
use super::views::{score_view, ViewScores};
use crate::bake::sweep::{Fnv64, ObjectViews};
use crate::baselines::{
    self, Budget, Method, Objective, Plan, PlannedObject, DEFAULT_G, DEFAULT_P,
};
use crate::camera::Camera;
use crate::capture::Capture;
use crate::device::Device;
use crate::eval::scale::Configs;
use crate::fit;
use crate::geometry::Geometry;
use crate::metrics::{Lpips, Metrics};
use crate::procedural::{arrange, make_capture, CaptureSpec, Layout, Preset, RenderOptions};
use crate::render::{try_render_scene, RenderOptions as DrawOptions};
use crate::scene_file::Scene;
use crate::segment::{self, EnlargeOptions, SegCapture, SegmentOptions, Segmentation};
use crate::simulate::assets::AssetScene;
use crate::simulate::{self, SimOptions, Simulation, Turntable, TurntableSpec};
use anyhow::{bail, Context as _};
use image::RgbaImage;
use nerflex_core::units::Bytes;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the scene comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Input {
    /// A capture folder (NeRF-synthetic layout; instance masks or alpha).
    Capture(PathBuf),
    /// A built-in scene, generated into `<out>/capture`.
    Preset(Preset),
    /// Single-object captures (e.g. the real lego and chair) resized to
    /// `size × size` and composed side by side by the segmentation module
    /// (a 2-D montage: each object keeps its own cameras, so there is no
    /// whole-scene view to render, and no Single-NeRF).
    Composite {
        /// The captures.
        dirs: Vec<PathBuf>,
        /// Image side after resizing, pixels.
        size: u32,
    },
}

/// Settings of the pipeline (the reduced defaults of `nerflex run` are in
/// [`Options::reduced`]).
#[derive(Clone, Debug)]
pub struct Options {
    /// Image side of a generated capture, pixels.
    pub size: u32,
    /// Training views of a generated capture.
    pub train_views: usize,
    /// Held-out views of a generated capture.
    pub test_views: usize,
    /// The profiler's sample points and the planner's configurations.
    pub configs: Configs,
    /// The turntable.
    pub turntable: TurntableSpec,
    /// Frames and period.
    pub sim: SimOptions,
    /// Folder of kept bakes (and trained fields, in `fields/`).
    pub store: PathBuf,
    /// Where every asset comes from: the trained baker (default; fields
    /// trained per network with the scale's settings) or the visual hull.
    pub baker: Baker,
    /// Write the rendered held-out views here (`None`: not kept).
    pub renders: Option<PathBuf>,
    /// The (g, p) of Single-NeRF and Block-NeRF (the paper: MobileNeRF's
    /// (128, 17)).
    pub baseline: (u32, u32),
    /// For the simulation only: place object k at x = (k − (n−1)/2)·spread
    /// (world units). Objects of a composite of separate captures all sit
    /// at their own origin; spreading them makes a plausible turntable.
    pub spread: Option<f32>,
    /// The segmentation's crop margin: each dedicated network's box grows
    /// by this fraction of its object's larger box side (0: the paper's
    /// tight crop, [`EnlargeOptions::margin`]).
    pub crop_margin: f32,
    /// The geometries the profiler samples and the planner chooses from
    /// (`--geometry`; planes only by default).
    pub geometries: Geometries,
    /// What the selectors maximise (`--objective`; the paper's sum of
    /// per-network SSIM by default).
    pub objective: Objective,
}

impl Options {
    /// The reduced defaults: 160 × 160 captures with 16 training and 4
    /// held-out views (the test suite's budget; `nerflex run` takes 10 from
    /// [`crate::eval::scale::Scale::Reduced`]); sample points g ∈ {16, 32, 64} × p ∈ {3, 10, 17};
    /// planning over g ∈ {16, 24, 32, 48, 64} ×
    /// p ∈ {3, 5, 7, 9, 11, 13, 15, 17} (40 configurations per object).
    pub fn reduced(store: PathBuf) -> Options {
        Options {
            size: 160,
            train_views: 16,
            test_views: 4,
            configs: crate::eval::scale::Scale::Reduced.configs(),
            turntable: TurntableSpec::DEFAULT,
            sim: SimOptions::default(),
            store,
            baker: crate::eval::scale::Scale::Reduced.baker(),
            renders: None,
            baseline: (DEFAULT_G, DEFAULT_P),
            spread: None,
            crop_margin: 0.0,
            geometries: Geometries::Planes,
            objective: Objective::Mean,
        }
    }

    /// The bake store these options name (`store`, `baker`).
    pub fn bake_store(&self) -> BakeStore {
        BakeStore::with_baker(&self.store, self.baker.clone())
    }
}

/// Something to tell the user as the pipeline goes (a progress bar, or nothing).
pub trait Progress: Sync {
    /// A stage begins; `steps` units of work follow.
    fn stage(&self, name: &str, steps: u64);
    /// One unit of work is done; `what` names it.
    fn step(&self, what: &str);
    /// What is happening within the current unit (e.g. a field training).
    fn note(&self, _what: &str) {}
}

/// No progress output.
pub struct Quiet;

impl Progress for Quiet {
    fn stage(&self, _: &str, _: u64) {}
    fn step(&self, _: &str) {}
}

/// One network of the segmentation: its name and its training/held-out views.
pub struct Network {
    /// Name (the segmentation's folder name; the object name for a dedicated network).
    pub name: String,
    /// The scene objects it represents.
    pub objects: Vec<String>,
    /// Its views.
    pub views: ObjectViews,
}

/// Wall-clock seconds of the stages (the paper's overhead figure measures
/// segmentation, profiler and DP; bakes stand for training, excluded there).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Generating the built-in capture (0 for a given capture).
    pub capture_s: f64,
    /// Detail-based segmentation (analysis, enlargement, writing).
    pub segment_s: f64,
    /// Profiler: choosing sample points and fitting the curves.
    pub profile_s: f64,
    /// Baking and measuring the sample points (training excluded; not in
    /// the paper's figure).
    pub sample_bakes_s: f64,
    /// Training the networks' fields for the sample bakes (0 for the hull
    /// baker or fields in the store; not in the paper's figure).
    #[serde(default)]
    pub train_s: f64,
}

/// The method-independent part: segmented, sampled, fitted.
pub struct Prepared {
    /// A short name for reports (preset name or capture folder name).
    pub label: String,
    /// The original capture (held-out views of the whole scene); `None`
    /// for a composite.
    pub capture: Option<Capture>,
    /// Single-NeRF's views (the whole capture as one object); `None` for a composite.
    pub single_views: Option<ObjectViews>,
    /// Block-NeRF's views: each object from the original (not enlarged) views.
    pub block_views: Vec<ObjectViews>,
    /// The segmentation result.
    pub segmentation: Segmentation,
    /// One entry per network, in segmentation order.
    pub networks: Vec<Network>,
    /// Every planes sample bake.
    pub samples: Vec<Baked>,
    /// Every mesh sample bake (none unless [`Options::geometries`] is
    /// [`Geometries::Both`]).
    pub mesh_samples: Vec<Baked>,
    /// The planner's scene (fitted profiles on the configuration space).
    pub scene: Scene,
    /// The scene as JSON (profile form, as `nerflex plan --scene` reads it).
    pub scene_json: serde_json::Value,
    /// What the selectors maximise, and each scene object's weight in it
    /// (scene order; all 1 for the paper's objective).
    pub objective: (Objective, Vec<f64>),
    /// Timings.
    pub timings: Timings,
}

/// Never delete what we did not create: `out/capture` is regenerated for a
/// built-in scene only if `nerflex run` wrote it (its `nerflex-run.json`
/// stamp); any other folder there is the user's and is refused.
pub fn check_preset_capture(out: &Path) -> anyhow::Result<()> {
    let dir = out.join("capture");
    if std::fs::symlink_metadata(&dir).is_ok() && !dir.join("nerflex-run.json").is_file() {
        bail!(
            "{}: exists and was not written by `nerflex run` (it has no nerflex-run.json), so it is not replaced; \
             move it away, use it with --capture {}, or choose another --out",
            dir.display(),
            dir.display()
        );
    }
    Ok(())
}

/// Loads a capture and names it.
fn input_capture(
    input: &Input,
    opts: &Options,
    out: &Path,
    progress: &dyn Progress,
) -> anyhow::Result<(PathBuf, String, f64)> {
    match input {
        Input::Capture(dir) => {
            let label = dir
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or("capture")
                .to_string();
            Ok((dir.clone(), label, 0.0))
        }
        Input::Preset(p) => {
            let dir = out.join("capture");
            let stamp = dir.join("nerflex-run.json");
            let want = serde_json::json!({
                "preset": p.name(), "size": opts.size,
                "train_views": opts.train_views, "test_views": opts.test_views,
            });
            let have = std::fs::read_to_string(&stamp)
                .ok()
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
            if have.as_ref() == Some(&want) && Capture::load(&dir).is_ok() {
                return Ok((dir, p.name().to_string(), 0.0));
            }
            check_preset_capture(out)?;
            let t0 = Instant::now();
            progress.stage(
                &format!(
                    "rendering {} ({} views)",
                    p.name(),
                    opts.train_views + opts.test_views
                ),
                (opts.train_views + opts.test_views) as u64,
            );
            // Built beside OUT/capture; the old one stays until it is complete.
            let stage = crate::output::StagedDir::new(&dir)?;
            let spec = CaptureSpec {
                objects: arrange(&p.kinds(), Layout::Ring, 0, 1.0),
                layout: Layout::Ring.name().into(),
                preset: Some(*p),
                seed: 0,
                train_views: opts.train_views,
                test_views: opts.test_views,
                size: opts.size,
                render: RenderOptions::default(),
            };
            make_capture(&spec, stage.path(), &|| progress.step("view"))
                .with_context(|| format!("writing {}", dir.display()))?;
            crate::output::write_file(
                &stage.path().join("nerflex-run.json"),
                want.to_string().as_bytes(),
            )?;
            stage.commit(
                &|_| stamp.is_file(),
                "OUT/capture is generated by `nerflex run`; choose another --out",
            )?;
            Ok((dir, p.name().to_string(), t0.elapsed().as_secs_f64()))
        }
        Input::Composite { .. } => bail!("a composite has no capture folder"),
    }
}

/// Every view of a capture as one object (alpha = silhouette of all its
/// objects): a shared network, or Single-NeRF's whole scene.
pub fn whole_capture_views(cap: &Capture, name: &str) -> ObjectViews {
    use crate::capture::OTHER_OBJECTS_MASK_VALUE as OTHER;
    // A segmentation group folder of several objects marks the pixels of
    // objects outside the group: there the group's look is unknown (it may
    // be behind), not background. Such views get a two-value instance mask
    // (group = 1, outside = OTHER), which the carver, the trainer and the
    // measure already read as "unknown". A capture without the marker (a
    // whole scene: Single-NeRF) keeps its alpha and its key.
    let marked = |m: &image::GrayImage| m.pixels().any(|v| v.0[0] == OTHER);
    let label_is_other = cap
        .scene
        .as_ref()
        .is_some_and(|s| s.objects.iter().any(|o| o.mask_value == OTHER));
    let group = !label_is_other
        && cap
            .train
            .iter()
            .chain(&cap.test)
            .any(|f| f.mask.as_ref().is_some_and(marked));
    let group_mask = |m: &image::GrayImage| {
        crate::bake::sweep::map_mask(m, |v| match v {
            0 => 0,
            OTHER => OTHER,
            _ => 1,
        })
    };
    let mut h = Fnv64::default();
    h.write(name.as_bytes());
    h.write(b"whole-capture");
    for f in cap.train.iter().chain(&cap.test) {
        h.write(format!("{:?}", f.camera).as_bytes());
        h.write(f.image.as_raw());
        if let (true, Some(m)) = (group, &f.mask) {
            h.write(m.as_raw());
        }
    }
    let test_hidden = if group {
        cap.test
            .iter()
            .map(|f| {
                f.mask
                    .as_ref()
                    .filter(|m| marked(m))
                    .map(|m| crate::bake::sweep::map_mask(m, |v| u8::from(v == OTHER)))
            })
            .collect()
    } else {
        Vec::new()
    };
    ObjectViews {
        name: name.to_string(),
        content_hash: h.finish(),
        train: cap
            .train
            .iter()
            .map(|f| {
                let mask = f
                    .mask
                    .as_ref()
                    .filter(|_| group)
                    .map(|m| (group_mask(m), 1));
                (f.camera, f.image.clone(), mask)
            })
            .collect(),
        test: cap
            .test
            .iter()
            .map(|f| (f.camera, f.image.clone()))
            .collect(),
        test_hidden,
        search_box: None,
    }
}

/// The views of one segmentation group folder, named `name`.
fn network_views(dir: &Path, name: &str) -> anyhow::Result<ObjectViews> {
    let cap = Capture::load(dir).with_context(|| format!("loading {}", dir.display()))?;
    if cap.test.is_empty() {
        bail!("{}: no held-out views to measure against", dir.display());
    }
    let mut views = match &cap.scene {
        Some(s) if s.objects.len() == 1 => ObjectViews::from_capture(&cap, None)?,
        Some(_) => whole_capture_views(&cap, name),
        None => ObjectViews::from_capture(&cap, None)?,
    };
    views.name = name.to_string();
    Ok(views)
}

/// Stage 1: capture, segmentation, profiler sample bakes, fit.
pub fn prepare(
    input: &Input,
    opts: &Options,
    out: &Path,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<Prepared> {
    // Before anything is written.
    opts.geometries.check(&opts.baker)?;
    let mut timings = Timings::default();
    let (seg_cap, capture, label) = match input {
        Input::Composite { dirs, size } => {
            let refs: Vec<&Path> = dirs.iter().map(PathBuf::as_path).collect();
            let seg_cap = segment::compose::compose_dirs(&refs, Some(*size))
                .context("composing the captures")?;
            let label = dirs
                .iter()
                .map(|d| {
                    d.file_name()
                        .and_then(|n| n.to_str())
                        .unwrap_or("capture")
                        .to_string()
                })
                .collect::<Vec<_>>()
                .join("+");
            (seg_cap, None, label)
        }
        _ => {
            let (dir, label, capture_s) = input_capture(input, opts, out, progress)?;
            timings.capture_s = capture_s;
            let capture =
                Capture::load(&dir).with_context(|| format!("loading {}", dir.display()))?;
            if capture.test.is_empty() {
                bail!(
                    "{}: the capture has no held-out views (transforms_test.json) to measure quality on",
                    dir.display()
                );
            }
            let seg_cap = SegCapture::load(&dir)
                .with_context(|| format!("segmentation input {}", dir.display()))?;
            (seg_cap, Some(capture), label)
        }
    };

    progress.stage("segmenting", 1);
    let t0 = Instant::now();
    let seg_dir = out.join("segment");
    let seg_opts = SegmentOptions {
        enlarge: EnlargeOptions {
            margin: opts.crop_margin,
            ..EnlargeOptions::default()
        },
        ..SegmentOptions::default()
    };
    let segmentation = segment::segment(&seg_cap, &seg_opts, &seg_dir)
        .with_context(|| format!("segmenting {}", seg_cap.source))?;
    timings.segment_s = t0.elapsed().as_secs_f64();
    progress.step("segmented");
    let networks = segmentation
        .groups
        .iter()
        .map(|g| {
            Ok(Network {
                name: g.folder.clone(),
                objects: g.objects.clone(),
                views: network_views(&seg_dir.join(&g.folder), &g.folder)?,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let (single_views, block_views) = match (&capture, input) {
        (Some(cap), _) => baseline_views(cap)?,
        (None, Input::Composite { dirs, size }) => (None, composite_block_views(dirs, *size)?),
        (None, _) => (None, Vec::new()),
    };

    // The profiler's sample points (timed with the fit below).
    let t_points = Instant::now();
    let plan = fit::sampling::variable_step(
        opts.configs.sample_grid.0..=opts.configs.sample_grid.1,
        opts.configs.sample_patch.0..=opts.configs.sample_patch.1,
        opts.configs.sample_step,
    )
    .map_err(|e| anyhow::anyhow!("profiler sample points: {e}"))?;
    let points = plan.points();
    let points_s = t_points.elapsed().as_secs_f64();

    let store = opts.bake_store();
    progress.stage(
        "profiler sample bakes",
        (networks.len() * points.len()) as u64,
    );
    let t1 = Instant::now();
    let reqs = geometries::sample_requests(&networks, &points, opts.geometries)?;
    let mut samples = store.get_or_bake_many(&reqs, lpips, progress, &|i| {
        let r = &reqs[i];
        let what = format!("{} g={} p={}", r.views.name, r.g, r.p);
        if r.geometry.is_planes() {
            what
        } else {
            format!("{what} mesh")
        }
    })?;
    // Planes first (the requests' order): the rest are the mesh's.
    let mesh_samples = samples.split_off(reqs.iter().filter(|r| r.geometry.is_planes()).count());
    timings.train_s = samples.iter().chain(&mesh_samples).map(|b| b.train_s).sum();
    timings.sample_bakes_s = t1.elapsed().as_secs_f64() - timings.train_s;

    progress.stage("fitting profiles", 1);
    let t2 = Instant::now();
    let space = fit::profiles::Space {
        grids: opts.configs.space_grid.clone(),
        patches: opts.configs.space_patch.clone(),
    };
    let (scene, scene_json) = geometries::fit_scene(&samples, &mesh_samples, &points, &space)?;
    let zooms: Vec<(String, f64)> = segmentation
        .groups
        .iter()
        .map(|g| (g.folder.clone(), g.mean_zoom))
        .collect();
    let weights = opts
        .objective
        .weights(&scene, &zooms)
        .map_err(|e| anyhow::anyhow!("--objective {}: {e}", opts.objective))?;
    timings.profile_s = points_s + t2.elapsed().as_secs_f64();
    progress.step("fitted");
    Ok(Prepared {
        label,
        capture,
        single_views,
        block_views,
        segmentation,
        networks,
        samples,
        mesh_samples,
        scene,
        scene_json,
        objective: (opts.objective, weights),
        timings,
    })
}

/// Stage 2: the plan of `method` for `device`'s budget, and the seconds it took.
pub fn plan_for(
    prepared: &Prepared,
    method: Method,
    device: &Device,
) -> anyhow::Result<(Plan, f64)> {
    plan_within(prepared, method, device, device.budget())
}

/// [`plan_for`] against `budget` instead of the device's own (a re-plan
/// after a bake came out larger than predicted: [`next_budget`]).
pub fn plan_within(
    prepared: &Prepared,
    method: Method,
    device: &Device,
    budget: Bytes,
) -> anyhow::Result<(Plan, f64)> {
    let t0 = Instant::now();
    let mut plan = baselines::plan_weighted(
        method,
        &prepared.scene,
        Budget::new(budget),
        &prepared.objective.1,
    )
    .with_context(|| format!("{method} plan for {} on {}", prepared.label, device.name))?;
    let secs = t0.elapsed().as_secs_f64();
    plan.device = Some(device.name.clone());
    Ok((plan, secs))
}

/// Re-plans at most this often when a plan bakes larger than the budget.
/// Each further try cuts twice as much ([`next_budget`]); three were not
/// always enough (session 21: Scene 2's Pixel 4 plan ended 0.4 MB over
/// 150 MB after three tries).
pub const MAX_REPLANS: u32 = 6;

/// What [`next_budget`] takes the overshoot off: the plan's predicted
/// size, or the budget it was planned against if that is smaller. From
/// the planning budget alone a small cut can leave the same plan
/// optimal (session 22: Scene 4's Pixel 4 plan, predicted 146.5 MB
/// against a 149.x MB planning budget, baked 150.014 MB and came back
/// unchanged six times).
pub fn planned_bytes(plan: &Plan) -> Bytes {
    Bytes(plan.budget_bytes.min(plan.total_size_bytes))
}

/// The planning budget for another try when a plan predicted at `planned`
/// bytes ([`planned_bytes`]) baked to `baked` bytes but the device allows only `budget`, after
/// `tries` re-plans already; `None` when it fits. The selector is exact
/// for the profiles' sizes, but those are predictions (about ±5 %), so a
/// plan that fills the budget can come out over it; the overshoot comes
/// off the planning budget and the selector runs again, never past the
/// budget in baked bytes once it returns `None`. Each further try takes
/// twice as much off (the overshoot × 2^`tries`): a re-plan picks other
/// configurations, whose sizes miss by their own errors, and session 21's
/// Scene 2 on the Pixel 4 was still 0.4 MB over after three tries of the
/// bare overshoot.
pub fn next_budget(budget: Bytes, planned: Bytes, baked: Bytes, tries: u32) -> Option<Bytes> {
    (baked.0 > budget.0).then(|| {
        let cut = (baked.0 - budget.0).saturating_mul(1u64 << tries.min(32));
        Bytes(planned.0.saturating_sub(cut))
    })
}

/// Whether `method` plans from the profiles (and so can re-plan).
pub fn is_planner(method: Method) -> bool {
    !matches!(method, Method::Single | Method::Block)
}

/// Scene-level image quality over the held-out views (means).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneQuality {
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean PSNR, dB (identical images count as 100 dB).
    pub psnr: f64,
    /// Mean LPIPS, if the weights were available.
    pub lpips: Option<f64>,
    /// Views measured: the capture's held-out views, or for a composite
    /// (no whole-scene view) every object's source held-out views.
    pub views: usize,
}

/// One object of a realised scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RealisedObject {
    /// Network name.
    pub name: String,
    /// g.
    pub g: u32,
    /// p.
    pub p: u32,
    /// The geometry it was baked as (left out of JSON for planes, so
    /// planes-only reports read as before).
    #[serde(default, skip_serializing_if = "Geometry::is_planes")]
    pub geometry: Geometry,
    /// Size the planner predicted, bytes.
    pub predicted_bytes: u64,
    /// Size of the baked files, bytes.
    pub file_bytes: u64,
    /// GPU bytes of its atlas pages.
    pub gpu_bytes: u64,
    /// Quads.
    pub quads: u64,
    /// SSIM the planner predicted.
    pub predicted_ssim: f64,
    /// SSIM measured on the network's own held-out views.
    pub ssim: f64,
    /// PSNR on the same views, dB.
    pub psnr: f64,
    /// LPIPS on the same views.
    pub lpips: Option<f64>,
    /// Asset folder.
    pub asset: PathBuf,
}

/// A plan made real: baked, measured.
pub struct Realised {
    /// The objects, in load order.
    pub objects: Vec<RealisedObject>,
    /// The whole scene's quality on the capture's held-out views.
    pub quality: SceneQuality,
    /// The same per held-out view, with each scene object in its box
    /// ([`super::views`]).
    pub views: Vec<ViewScores>,
    /// Wall seconds spent baking now, training aside (a few milliseconds
    /// when everything was in the store).
    pub bake_s: f64,
    /// Seconds spent training fields for those bakes now.
    pub train_s: f64,
}

impl Realised {
    /// Total file bytes.
    pub fn file_bytes(&self) -> u64 {
        self.objects.iter().map(|o| o.file_bytes).sum()
    }
}

/// The views a planned object is baked from.
fn views_of<'a>(
    prepared: &'a Prepared,
    method: Method,
    o: &PlannedObject,
) -> anyhow::Result<&'a ObjectViews> {
    match method {
        Method::Single => prepared
            .single_views
            .as_ref()
            .context("single: a composite of separate captures has no whole-scene views"),
        Method::Block => prepared
            .block_views
            .iter()
            .find(|v| v.name == o.name)
            .with_context(|| format!("block: no views for `{}`", o.name)),
        _ => prepared
            .networks
            .iter()
            .find(|n| n.name == o.name)
            .map(|n| &n.views)
            .with_context(|| format!("no network `{}` in the segmentation", o.name)),
    }
}

/// Single-NeRF's and Block-NeRF's views of a capture: the whole capture,
/// and each scene object from the original views with its instance mask.
pub fn baseline_views(cap: &Capture) -> anyhow::Result<(Option<ObjectViews>, Vec<ObjectViews>)> {
    let single = whole_capture_views(cap, "single");
    let block = match &cap.scene {
        Some(s) if s.objects.len() > 1 => s
            .objects
            .iter()
            .map(|o| ObjectViews::from_capture(cap, Some(&o.name)).map(drop_absent_views))
            .collect::<anyhow::Result<Vec<_>>>()?,
        _ => vec![whole_capture_views(cap, "block")],
    };
    Ok((Some(single), block))
}

/// Leaves out the training views in which the object has no pixel (hidden
/// behind others or out of frame), as the segmentation does for its sets:
/// a silhouette carver would read such a view as "the object is absent" and
/// empty the whole grid (scene2's gear is hidden in one of 16 views). The
/// content hash changes only when a view is dropped, so stored bakes of
/// unaffected objects stay valid.
fn drop_absent_views(mut v: ObjectViews) -> ObjectViews {
    let before = v.train.len();
    let mut kept = Vec::new();
    v.train = std::mem::take(&mut v.train)
        .into_iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let present = match &t.2 {
                Some((mask, label)) => mask.pixels().any(|m| m.0[0] == *label),
                None => true,
            };
            present.then(|| {
                kept.push(i);
                t
            })
        })
        .collect();
    if v.train.len() != before {
        let mut h = Fnv64::default();
        h.write(&v.content_hash.to_le_bytes());
        h.write(format!("views kept {kept:?}").as_bytes());
        v.content_hash = h.finish();
    }
    v
}

/// Block-NeRF's views of a composite: each source capture, resized like the
/// composite, as one object named after its folder.
fn composite_block_views(dirs: &[PathBuf], size: u32) -> anyhow::Result<Vec<ObjectViews>> {
    dirs.iter()
        .map(|d| {
            let c = SegCapture::load(d).with_context(|| format!("loading {}", d.display()))?;
            let c = segment::compose::resize_capture(&c, size, size)?;
            let name = d
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or("object")
                .to_string();
            let mut h = Fnv64::default();
            h.write(name.as_bytes());
            h.write(format!("block-composite {size}").as_bytes());
            for f in c.train.iter().chain(&c.test) {
                h.write(format!("{:?}", f.camera).as_bytes());
                h.write(f.image.as_raw());
            }
            Ok(ObjectViews {
                name,
                content_hash: h.finish(),
                train: c
                    .train
                    .iter()
                    .map(|f| (f.camera, f.image.clone(), None))
                    .collect(),
                test: c.test.iter().map(|f| (f.camera, f.image.clone())).collect(),
                test_hidden: Vec::new(),
                search_box: None,
            })
        })
        .collect()
}

/// The plans of Single-NeRF and Block-NeRF: real bakes at `(g, p)` (the
/// paper: (128, 17)), not the planner's derived tables. Their sizes are the
/// baked file bytes; `feasible` compares them with the device's budget.
pub fn baseline_plan(
    method: Method,
    views: &[&ObjectViews],
    (g, p): (u32, u32),
    device: &Device,
    store: &BakeStore,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<(Plan, Vec<Baked>)> {
    let mut objects = Vec::new();
    let reqs: Vec<BakeRequest<'_>> = views
        .iter()
        .map(|&v| BakeRequest::planes(v, g, p))
        .collect();
    let bakes = store.get_or_bake_many(&reqs, lpips, progress, &|i| {
        format!("{} {} g={g} p={p}", method, reqs[i].views.name)
    })?;
    for (v, b) in views.iter().zip(&bakes) {
        objects.push(PlannedObject {
            name: v.name.clone(),
            g,
            p,
            size_bytes: b.sample.size_bytes,
            quality: b.sample.ssim,
            geometry: Geometry::Planes,
            config_index: None,
        });
    }
    let total: u64 = objects.iter().map(|o| o.size_bytes).sum();
    let total_quality: f64 = objects.iter().map(|o| o.quality).sum();
    let budget = device.budget();
    Ok((
        Plan {
            method,
            device: Some(device.name.clone()),
            budget_bytes: budget.0,
            feasible: total <= budget.0,
            objects,
            total_size_bytes: total,
            total_quality,
            total_quality_q: Default::default(),
            total_units: 0,
            budget_units: 0,
            unit_bytes: 0,
        },
        bakes,
    ))
}

/// Stage 3: bakes the plan's configurations (or finds them in the store),
/// renders the capture's held-out views with all of them and measures.
///
/// Each object is baked as its planned geometry: a mesh choice is a mesh
/// bake of the trained baker ([`BakeStore`], "Geometry"; the hull baker
/// refuses it with an error naming the object, before any bake starts),
/// and every size, count and score of the [`RealisedObject`] is the baked
/// export's.
pub fn realise(
    prepared: &Prepared,
    plan: &Plan,
    opts: &Options,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<Realised> {
    let store = opts.bake_store();
    progress.stage(
        &format!("baking the {} plan", plan.method),
        plan.objects.len() as u64,
    );
    let mut objects = Vec::new();
    let mut train_s = 0.0;
    // Wall time: the store may run two bakes at once.
    let t_bakes = Instant::now();
    let reqs = plan
        .objects
        .iter()
        .map(|o| {
            Ok(BakeRequest::new(
                views_of(prepared, plan.method, o)?,
                o.g,
                o.p,
                o.geometry,
            ))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let bakes = store.get_or_bake_many(&reqs, lpips, progress, &|i| {
        let o = &plan.objects[i];
        if o.geometry.is_planes() {
            format!("{} g={} p={}", o.name, o.g, o.p)
        } else {
            format!("{} g={} p={} {}", o.name, o.g, o.p, o.geometry)
        }
    })?;
    let bakes_wall_s = t_bakes.elapsed().as_secs_f64();
    for (o, b) in plan.objects.iter().zip(bakes) {
        train_s += b.train_s;
        objects.push(RealisedObject {
            name: o.name.clone(),
            g: o.g,
            p: o.p,
            geometry: o.geometry,
            predicted_bytes: o.size_bytes,
            file_bytes: b.sample.size_bytes,
            gpu_bytes: b.sample.gpu_bytes,
            quads: b.sample.quads,
            predicted_ssim: o.quality,
            ssim: b.sample.ssim,
            psnr: b.sample.psnr,
            lpips: b.sample.lpips,
            asset: b.dir.clone(),
        });
    }
    let (quality, views) = scene_quality(prepared, &objects, opts, lpips, progress)?;
    Ok(Realised {
        objects,
        quality,
        views,
        bake_s: (bakes_wall_s - train_s).max(0.0),
        train_s,
    })
}

/// Renders the capture's held-out views with every object and compares
/// them with the ground truth: the means and every view's scores.
fn scene_quality(
    prepared: &Prepared,
    objects: &[RealisedObject],
    opts: &Options,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<(SceneQuality, Vec<ViewScores>)> {
    let Some(capture) = &prepared.capture else {
        return composite_quality(prepared, objects, lpips, progress);
    };
    let assets = objects
        .iter()
        .map(|o| {
            crate::asset::Asset::load(&o.asset)
                .with_context(|| format!("loading {}", o.asset.display()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let refs: Vec<&crate::asset::Asset> = assets.iter().collect();
    let scene_objects: Vec<(String, u8)> = capture
        .scene
        .iter()
        .flat_map(|s| s.objects.iter().map(|o| (o.name.clone(), o.mask_value)))
        .collect();
    let test = &capture.test;
    progress.stage("rendering the held-out views", test.len() as u64);
    let mut views = Vec::with_capacity(test.len());
    for (i, f) in test.iter().enumerate() {
        let img = render(&refs, &f.camera)?;
        views.push(score_view(i, &img, f, &scene_objects, lpips)?);
        if let Some(dir) = &opts.renders {
            let path = dir.join(format!("test_{i}.png"));
            let png = crate::asset::png_io::encode_rgba8(&img)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            crate::output::create_parent(&path)?;
            crate::output::write_file(&path, &png)?;
        }
        progress.step(&format!("view {i}"));
    }
    Ok((mean_quality(&views, lpips.is_some()), views))
}

/// The means of per-view scores.
fn mean_quality(views: &[ViewScores], lpips: bool) -> SceneQuality {
    let n = views.len().max(1) as f64;
    SceneQuality {
        ssim: views.iter().map(|v| v.ssim).sum::<f64>() / n,
        psnr: views.iter().map(|v| v.psnr).sum::<f64>() / n,
        lpips: lpips.then(|| views.iter().filter_map(|v| v.lpips).sum::<f64>() / n),
        views: views.len(),
    }
}

/// A composite has no whole-scene view: each object's asset is rendered from
/// its own source capture's held-out cameras (the same views for every
/// method, enlarged or not) and compared with those images; the means are
/// over every (object, view).
fn composite_quality(
    prepared: &Prepared,
    objects: &[RealisedObject],
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<(SceneQuality, Vec<ViewScores>)> {
    let source_of = |name: &str| -> Option<&ObjectViews> {
        let object = prepared
            .networks
            .iter()
            .find(|n| n.name == name)
            .and_then(|n| n.objects.first().map(String::as_str))
            .unwrap_or(name);
        prepared.block_views.iter().find(|v| v.name == object)
    };
    let count: usize = objects
        .iter()
        .filter_map(|o| source_of(&o.name))
        .map(|v| v.test.len())
        .sum();
    progress.stage("rendering the held-out views", count as u64);
    let mut views = Vec::with_capacity(count);
    for o in objects {
        let src =
            source_of(&o.name).with_context(|| format!("no source capture for `{}`", o.name))?;
        let asset = crate::asset::Asset::load(&o.asset)
            .with_context(|| format!("loading {}", o.asset.display()))?;
        for (i, (cam, gt)) in src.test.iter().enumerate() {
            let img = render(&[&asset], cam)?;
            let s = Metrics::compare(&img, gt, lpips)
                .with_context(|| format!("measuring {} held-out view {i}", o.name))?;
            views.push(ViewScores {
                view: i,
                source: Some(src.name.clone()),
                ssim: s.ssim,
                psnr: s.psnr.min(super::views::PSNR_CAP_DB),
                lpips: s.lpips,
                objects: Vec::new(),
            });
            progress.step(&format!("{} view {i}", o.name));
        }
    }
    Ok((mean_quality(&views, lpips.is_some()), views))
}

fn render(assets: &[&crate::asset::Asset], camera: &Camera) -> anyhow::Result<RgbaImage> {
    try_render_scene(assets, camera, &DrawOptions::default())
        .map(|(img, _)| img)
        .map_err(|e| anyhow::anyhow!("the renderer rejected a held-out camera: {e}"))
}

/// Stage 4: the realised scene on a device's turntable.
pub fn simulate_on(
    realised: &Realised,
    device: &Device,
    opts: &Options,
) -> anyhow::Result<Simulation> {
    let mut v = simulate_devices(realised, std::slice::from_ref(device), opts)?;
    v.pop().context("no simulation")
}

/// Loads a realised scene's assets once (unless no device can load it) and
/// simulates it on every device; devices with the same viewer size share
/// the measured coverage. `turntable` overrides `opts.turntable`.
pub fn simulate_devices(
    realised: &Realised,
    devices: &[Device],
    opts: &Options,
) -> anyhow::Result<Vec<Simulation>> {
    let names: Vec<String> = realised.objects.iter().map(|o| o.name.clone()).collect();
    let bytes: Vec<u64> = realised.objects.iter().map(|o| o.file_bytes).collect();
    let data = nerflex_core::units::Bytes(bytes.iter().sum());
    let any_loads = devices.iter().any(|d| d.load_check(data).is_ok());
    // A scene no device can load is never drawn: its assets stay on disk.
    let mut assets = if any_loads {
        realised
            .objects
            .iter()
            .map(|o| {
                crate::asset::Asset::load(&o.asset)
                    .with_context(|| format!("loading {}", o.asset.display()))
            })
            .collect::<anyhow::Result<Vec<_>>>()?
    } else {
        Vec::new()
    };
    if let Some(spread) = opts.spread {
        let n = assets.len() as f32;
        for (k, a) in assets.iter_mut().enumerate() {
            let dx = (k as f32 - (n - 1.0) / 2.0) * spread;
            for q in a.shapes.iter_mut().flat_map(|s| s.quads.iter_mut()) {
                for c in &mut q.corners {
                    c.pos[0] += dx;
                }
            }
        }
    }
    let scene = AssetScene::new(names.clone(), assets, bytes.clone());
    let items = if any_loads {
        scene.load_items()
    } else {
        names
            .iter()
            .zip(&bytes)
            .map(|(n, &b)| simulate::LoadItem {
                name: n.clone(),
                file_bytes: b,
                resident_bytes: 0,
            })
            .collect()
    };
    let empty = NoCoverage(names.len());
    let source: &dyn simulate::CoverageSource = if any_loads { &scene } else { &empty };
    let mut turntables: Vec<(crate::device::Viewer, Turntable<'_>)> = Vec::new();
    let mut out = Vec::new();
    for d in devices {
        let viewer = d.viewer();
        let k = match turntables.iter().position(|(v, _)| *v == viewer) {
            Some(k) => k,
            None => {
                turntables.push((viewer, Turntable::new(opts.turntable, viewer, source)));
                turntables.len() - 1
            }
        };
        out.push(simulate::simulate(d, &items, &turntables[k].1, opts.sim)?);
    }
    Ok(out)
}

/// The coverage of a scene that never loads (never asked for).
struct NoCoverage(usize);

impl simulate::CoverageSource for NoCoverage {
    fn objects(&self) -> usize {
        self.0
    }
    fn coverage(&self, _: usize, _: &Camera) -> anyhow::Result<simulate::ViewCoverage> {
        bail!("coverage of a scene that failed to load")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Intrinsics};
    use image::{GrayImage, Luma, RgbaImage};

    #[test]
    fn next_budget_takes_the_overshoot_off_the_planning_budget() {
        let mb = |v: u64| Bytes(v * 1_000_000);
        // Fits: no re-plan, also exactly at the budget.
        assert_eq!(next_budget(mb(150), mb(150), mb(143), 0), None);
        assert_eq!(next_budget(mb(150), mb(150), mb(150), 0), None);
        // 151.2 MB baked from a 150 MB plan: plan again against 148.8 MB.
        assert_eq!(
            next_budget(mb(150), mb(150), Bytes(151_200_000), 0),
            Some(Bytes(148_800_000))
        );
        // A second overshoot shrinks the already smaller budget further,
        // by twice the overshoot, a third by four times.
        assert_eq!(next_budget(mb(150), mb(148), mb(151), 1), Some(mb(146)));
        assert_eq!(next_budget(mb(150), mb(146), mb(151), 2), Some(mb(142)));
        // Tries beyond any sensible count saturate instead of overflowing.
        assert_eq!(next_budget(mb(150), mb(146), mb(151), 99), Some(Bytes(0)));
        // Never below zero.
        assert_eq!(next_budget(mb(1), mb(1), mb(500), 0), Some(Bytes(0)));
        assert!(is_planner(Method::Dp) && is_planner(Method::Slsqp));
        assert!(!is_planner(Method::Single) && !is_planner(Method::Block));
    }

    #[test]
    fn a_replan_cuts_below_the_plans_predicted_size() {
        // Session 22's Scene 4 on the Pixel 4: predicted 146.5 MB against a
        // 149.9 MB planning budget, baked 150.014 MB. Cut from the planning
        // budget the next budget (149.886 MB) still admits the same plan;
        // cut from the predicted size it does not.
        let plan: Plan = serde_json::from_str(
            r#"{"method": "dp", "device": "pixel4", "budget_bytes": 149900000,
                "feasible": true, "objects": [], "total_size_bytes": 146500000,
                "total_quality": 4.0}"#,
        )
        .unwrap();
        assert_eq!(planned_bytes(&plan), Bytes(146_500_000));
        let next = next_budget(
            Bytes(150_000_000),
            planned_bytes(&plan),
            Bytes(150_014_000),
            0,
        );
        assert_eq!(next, Some(Bytes(146_486_000)));
        // A plan predicted over its planning budget (it cannot be, but the
        // sizes are the caller's) is cut from the budget.
        let over = Plan {
            total_size_bytes: 151_000_000,
            ..plan
        };
        assert_eq!(planned_bytes(&over), Bytes(149_900_000));
    }

    fn views(labels_present: &[bool]) -> ObjectViews {
        let cam = Camera {
            intrinsics: Intrinsics::from_fov_x(0.8, 4, 4),
            c2w: glam::Mat4::IDENTITY,
        };
        ObjectViews {
            name: "o".into(),
            content_hash: 7,
            train: labels_present
                .iter()
                .map(|&present| {
                    let mut m = GrayImage::new(4, 4);
                    // Another object (label 2) is always in view.
                    m.put_pixel(0, 0, Luma([2]));
                    if present {
                        m.put_pixel(1, 1, Luma([3]));
                    }
                    (cam, RgbaImage::new(4, 4), Some((m, 3)))
                })
                .collect(),
            test: Vec::new(),
            test_hidden: Vec::new(),
            search_box: None,
        }
    }

    #[test]
    fn views_without_the_object_are_left_out_and_rekeyed() {
        let all = drop_absent_views(views(&[true, true, true]));
        assert_eq!((all.train.len(), all.content_hash), (3, 7));
        let some = drop_absent_views(views(&[true, false, true]));
        assert_eq!(some.train.len(), 2);
        assert_ne!(some.content_hash, 7);
        let other = drop_absent_views(views(&[false, true, true]));
        assert_ne!(other.content_hash, some.content_hash);
    }

    /// A capture of 4×4 frames whose masks are `masks` (train then test).
    fn capture_of(train: &[GrayImage], test: &[GrayImage]) -> Capture {
        let cam = Camera {
            intrinsics: Intrinsics::from_fov_x(0.8, 4, 4),
            c2w: glam::Mat4::IDENTITY,
        };
        let frame = |m: &GrayImage| crate::capture::Frame {
            file_path: "./train/r_0".into(),
            camera: cam,
            image: RgbaImage::new(4, 4),
            mask: Some(m.clone()),
        };
        Capture {
            dir: PathBuf::from("cap"),
            camera_angle_x: 0.8,
            train: train.iter().map(frame).collect(),
            test: test.iter().map(frame).collect(),
            scene: None,
        }
    }

    #[test]
    fn a_group_folder_marks_outside_objects_unknown_and_a_whole_scene_keeps_alpha() {
        use crate::capture::OTHER_OBJECTS_MASK_VALUE as OTHER;
        let mut a = GrayImage::new(4, 4);
        a.put_pixel(0, 0, Luma([1]));
        a.put_pixel(1, 0, Luma([2]));
        let mut b = a.clone();
        b.put_pixel(3, 3, Luma([OTHER]));
        // A whole scene (labels only): alpha silhouettes, nothing hidden.
        let whole = whole_capture_views(&capture_of(&[a.clone()], &[a.clone()]), "single");
        assert!(whole.train[0].2.is_none() && whole.test_hidden.is_empty());
        // A group folder (some 255): group = 1, outside = 255, hidden marked.
        let group = whole_capture_views(&capture_of(&[b.clone()], &[a.clone(), b.clone()]), "g");
        let (m, label) = group.train[0].2.as_ref().expect("a group mask");
        assert_eq!(*label, 1);
        assert_eq!(
            (
                m.get_pixel(0, 0).0[0],
                m.get_pixel(1, 0).0[0],
                m.get_pixel(3, 3).0[0],
                m.get_pixel(2, 2).0[0]
            ),
            (1, 1, OTHER, 0)
        );
        assert_eq!(group.test_hidden.len(), 2);
        assert!(group.test_hidden[0].is_none());
        let h = group.test_hidden[1]
            .as_ref()
            .expect("the second test view hides a pixel");
        assert_eq!(h.pixels().filter(|v| v.0[0] != 0).count(), 1);
        assert_eq!(h.get_pixel(3, 3).0[0], 1);
        // The masks are part of a group's key.
        let other = whole_capture_views(&capture_of(&[b.clone()], &[b.clone(), b.clone()]), "g");
        assert_ne!(other.content_hash, group.content_hash);
    }
}
