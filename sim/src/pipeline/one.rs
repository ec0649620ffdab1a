//! One method on one device: what `nerflex run` does and reports.

use super::stages::{
    self, baseline_plan, is_planner, next_budget, plan_for, plan_within, planned_bytes, realise,
    simulate_on, Input, Options, Prepared, Progress, Realised, RealisedObject, SceneQuality,
    Timings, MAX_REPLANS,
};
use super::views::ViewScores;
use crate::baselines::{Method, Plan};
use crate::device::Device;
use crate::metrics::Lpips;
use crate::simulate::output::write_text;
use crate::simulate::Simulation;
use nerflex_core::units::Bytes;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// The result of `nerflex run`.
pub struct RunResult {
    /// Scene label.
    pub label: String,
    /// Device name.
    pub device: String,
    /// The plan.
    pub plan: Plan,
    /// Seconds the planner took (all re-plans included).
    pub plan_s: f64,
    /// Re-plans because the baked bytes exceeded the device's budget
    /// (the last plan's `budget_bytes` is then below the device's).
    pub replans: u32,
    /// The realised scene.
    pub realised: Realised,
    /// The simulation.
    pub simulation: Simulation,
    /// Stage timings.
    pub timings: Timings,
    /// Networks of the segmentation and their objects.
    pub networks: Vec<(String, Vec<String>)>,
    /// Sample bakes: (baked now, taken from the store).
    pub sample_bakes: (usize, usize),
    /// The planner's scene (profile form).
    pub scene_json: serde_json::Value,
    /// The baker every asset came from (`hull` or `trained`).
    pub baker: String,
    /// What the selector maximised (`mean`, the paper's, or `area`).
    pub objective: String,
    /// Where the time went.
    pub times: RunTimes,
    /// Each network's quality range against its views' noise.
    pub ranges: Vec<super::range::NetworkRange>,
    /// Each network's feature lattice as the trained baker chose it
    /// (empty for the hull baker or a fixed lattice).
    pub lattices: Vec<crate::bake::sweep::LatticeChosen>,
}

/// Wall-clock seconds of a run's parts (what `nerflex run` prints).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RunTimes {
    /// Generating the built-in capture.
    pub capture_s: f64,
    /// Segmentation.
    pub segment_s: f64,
    /// Training fields (profiler networks and the plan's networks).
    pub train_s: f64,
    /// Fields trained now (profiler networks; Single/Block fields count
    /// in `train_s` only).
    pub fields_trained: usize,
    /// The profiler's sample bakes (training excluded).
    pub sample_bakes_s: f64,
    /// The plan's bakes (training excluded; Single/Block: their bakes).
    pub plan_bakes_s: f64,
    /// Rendering and measuring the held-out views of the whole scene.
    pub measure_s: f64,
    /// The device simulation.
    pub simulate_s: f64,
}

/// Runs the whole pipeline for one method on one device.
#[allow(clippy::too_many_arguments)]
pub fn run_one(
    input: &Input,
    opts: &Options,
    out: &Path,
    method: Method,
    device: &Device,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<RunResult> {
    let prepared = stages::prepare(input, opts, out, lpips, progress)?;
    let t_plan = Instant::now();
    let (mut plan, mut plan_s) = method_plan(&prepared, method, device, opts, lpips, progress)?;
    // Single/Block bake (and train) inside method_plan.
    let baseline_s = t_plan.elapsed().as_secs_f64() - plan_s;
    let mut times = RunTimes {
        capture_s: prepared.timings.capture_s,
        segment_s: prepared.timings.segment_s,
        train_s: prepared.timings.train_s,
        fields_trained: prepared
            .samples
            .iter()
            .chain(&prepared.mesh_samples)
            .filter(|b| b.field_trained)
            .count(),
        sample_bakes_s: prepared.timings.sample_bakes_s,
        ..RunTimes::default()
    };
    let realise_timed = |plan: &Plan, times: &mut RunTimes| {
        let t0 = Instant::now();
        let r = realise(&prepared, plan, opts, lpips, progress)?;
        times.train_s += r.train_s;
        times.plan_bakes_s += r.bake_s;
        times.measure_s += t0.elapsed().as_secs_f64() - r.bake_s - r.train_s;
        anyhow::Ok(r)
    };
    let mut realised = realise_timed(&plan, &mut times)?;
    let mut replans = 0;
    while is_planner(method) && replans < MAX_REPLANS {
        let Some(next) = next_budget(
            device.budget(),
            planned_bytes(&plan),
            Bytes(realised.file_bytes()),
            replans,
        ) else {
            break;
        };
        let (p, s) = plan_within(&prepared, method, device, next)?;
        plan = p;
        plan_s += s;
        realised = realise_timed(&plan, &mut times)?;
        replans += 1;
    }
    // Baseline bakes were done by method_plan; realise found them stored.
    times.plan_bakes_s += baseline_s.max(0.0);
    progress.stage(&format!("simulating on {}", device.name), 1);
    let t_sim = Instant::now();
    let simulation = simulate_on(&realised, device, opts)?;
    times.simulate_s = t_sim.elapsed().as_secs_f64();
    progress.step("simulated");
    let all_samples = prepared.samples.len() + prepared.mesh_samples.len();
    let baked = prepared
        .samples
        .iter()
        .chain(&prepared.mesh_samples)
        .filter(|b| !b.cached)
        .count();
    Ok(RunResult {
        label: prepared.label.clone(),
        device: device.name.clone(),
        plan,
        plan_s,
        replans,
        realised,
        simulation,
        timings: prepared.timings,
        networks: prepared
            .networks
            .iter()
            .map(|n| (n.name.clone(), n.objects.clone()))
            .collect(),
        sample_bakes: (baked, all_samples - baked),
        scene_json: prepared.scene_json.clone(),
        baker: opts.baker.name().to_string(),
        objective: opts.objective.name().to_string(),
        times,
        ranges: super::range::ranges(&prepared.samples),
        lattices: opts
            .bake_store()
            .stored_lattices(prepared.networks.iter().map(|n| &n.views)),
    })
}

/// The plan of any method: the planner's for the NeRFlex selectors, real
/// bakes at `opts.baseline` ((128, 17)) for Single- and Block-NeRF.
pub fn method_plan(
    prepared: &Prepared,
    method: Method,
    device: &Device,
    opts: &Options,
    lpips: Option<&Lpips>,
    progress: &dyn Progress,
) -> anyhow::Result<(Plan, f64)> {
    match method {
        Method::Single | Method::Block => {
            let views: Vec<&crate::bake::sweep::ObjectViews> = if method == Method::Single {
                vec![prepared.single_views.as_ref().ok_or_else(|| {
                    anyhow::anyhow!(
                        "single: {} is a composite of separate captures; there is no whole scene to bake as one",
                        prepared.label
                    )
                })?]
            } else {
                prepared.block_views.iter().collect()
            };
            let (g, p) = opts.baseline;
            progress.stage(&format!("{method} bakes at ({g}, {p})"), views.len() as u64);
            let store = opts.bake_store();
            let (plan, _) = baseline_plan(
                method,
                &views,
                opts.baseline,
                device,
                &store,
                lpips,
                progress,
            )?;
            Ok((plan, 0.0))
        }
        _ => plan_for(prepared, method, device),
    }
}

#[derive(Serialize)]
struct ReportJson<'a> {
    scene: &'a str,
    device: &'a str,
    method: String,
    baker: &'a str,
    objective: &'a str,
    networks: Vec<NetworkJson<'a>>,
    timings: Timings,
    times: RunTimes,
    plan_s: f64,
    replans: u32,
    sample_bakes_new: usize,
    sample_bakes_reused: usize,
    budget_bytes: u64,
    predicted_bytes: u64,
    file_bytes: u64,
    objects: &'a [RealisedObject],
    quality: SceneQuality,
    views: &'a [ViewScores],
    load_failure: Option<String>,
    mean_fps: f64,
    steady_fps: f64,
    loaded_at_s: Option<f64>,
    profiler_ranges: &'a [super::range::NetworkRange],
    lattices: &'a [crate::bake::sweep::LatticeChosen],
}

#[derive(Serialize)]
struct NetworkJson<'a> {
    name: &'a str,
    objects: &'a [String],
}

impl RunResult {
    /// The short final report.
    pub fn report_text(&self, wall_s: f64, with_lpips: bool) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "nerflex run: {} on {} with {}, {} baker ({:.0} s)",
            self.label, self.device, self.plan.method, self.baker, wall_s
        );
        if self.objective != "mean" {
            let _ = writeln!(
                s,
                "objective: {} (each network's SSIM weighted by 1 / zoom²; SSIM below unweighted)",
                self.objective
            );
        }
        let names: Vec<&str> = self.networks.iter().map(|(n, _)| n.as_str()).collect();
        let _ = writeln!(
            s,
            "segmentation: {} networks ({}) in {:.2} s",
            names.len(),
            names.join(", "),
            self.timings.segment_s
        );
        let _ = writeln!(
            s,
            "profiler: {} sample bakes ({} new, {} from the store, {:.0} s), points + fit {:.3} s",
            self.sample_bakes.0 + self.sample_bakes.1,
            self.sample_bakes.0,
            self.sample_bakes.1,
            self.timings.sample_bakes_s,
            self.timings.profile_s
        );
        s.push_str(&super::range::lines(&self.ranges));
        let predicted: u64 = self
            .realised
            .objects
            .iter()
            .map(|o| o.predicted_bytes)
            .sum();
        let _ = writeln!(
            s,
            "plan ({}): {:.2} MB predicted, {:.2} MB baked, budget {:.2} MB; planned in {:.2} ms",
            self.plan.method,
            Bytes(predicted).as_mb(),
            Bytes(self.realised.file_bytes()).as_mb(),
            Bytes(self.plan.budget_bytes).as_mb(),
            self.plan_s * 1e3
        );
        if self.replans > 0 {
            let _ = writeln!(
                s,
                "  (re-planned {}× against a smaller budget: the first plan baked over the device's budget)",
                self.replans
            );
        }
        let _ = write!(
            s,
            "  {:<12} {:>4} {:>3} {:>9} {:>9} {:>9} {:>9}",
            "object", "g", "p", "pred MB", "baked MB", "pred SSIM", "SSIM"
        );
        if self
            .realised
            .objects
            .iter()
            .any(|o| !o.geometry.is_planes())
        {
            s.push_str("  geometry");
        }
        s.push('\n');
        // The geometry column only when the plan bakes something other
        // than planes (planes-only reports read as before).
        let geometry = self
            .realised
            .objects
            .iter()
            .any(|o| !o.geometry.is_planes());
        for o in &self.realised.objects {
            let _ = write!(
                s,
                "  {:<12} {:>4} {:>3} {:>9.2} {:>9.2} {:>9.4} {:>9.4}",
                o.name,
                o.g,
                o.p,
                Bytes(o.predicted_bytes).as_mb(),
                Bytes(o.file_bytes).as_mb(),
                o.predicted_ssim,
                o.ssim
            );
            if geometry {
                let _ = write!(s, "  {}", o.geometry);
            }
            s.push('\n');
        }
        let q = &self.realised.quality;
        let _ = writeln!(
            s,
            "held-out views of the whole scene ({}): SSIM {:.4}  PSNR {:.2} dB  LPIPS {}",
            q.views,
            q.ssim,
            q.psnr,
            match q.lpips {
                Some(l) => format!("{l:.4}"),
                None if with_lpips => "n/a".into(),
                None => "skipped (no weights)".into(),
            }
        );
        interval_lines(&self.realised.views, &mut s);
        let sim = &self.simulation;
        match &sim.load_failure {
            Some(f) => {
                let _ = writeln!(s, "{}: load FAILED ({f}); FPS 0", self.device);
            }
            None => {
                let _ = writeln!(
                    s,
                    "{}: loaded in {}, mean FPS {:.1} over {} frames (after loading {:.1}){}",
                    self.device,
                    sim.loaded_at_s.map_or("—".into(), |t| format!("{t:.2} s")),
                    sim.mean_fps,
                    sim.frames.len(),
                    sim.steady_fps,
                    if sim.over_soft_limit {
                        ", over the soft memory limit"
                    } else {
                        ""
                    }
                );
            }
        }
        let t = &self.times;
        let _ = writeln!(
            s,
            "time: capture {:.0} s, segmentation {:.1} s, training {:.0} s ({} profiler field(s) trained now), \
             sample bakes {:.0} s, plan bakes {:.0} s, held-out views {:.0} s, simulation {:.1} s",
            t.capture_s,
            t.segment_s,
            t.train_s,
            t.fields_trained,
            t.sample_bakes_s,
            t.plan_bakes_s,
            t.measure_s,
            t.simulate_s
        );
        s
    }

    /// Writes `report.json`, `plan.json`, `scene.json` and the asset links
    /// (`assets/<object>/g<g>_p<p>`, `_mesh` appended for a mesh bake, →
    /// the store) into `out`, so
    /// `nerflex simulate --scene OUT/scene.json --plan OUT/plan.json` works.
    pub fn write(&self, out: &Path) -> anyhow::Result<()> {
        let predicted = self
            .realised
            .objects
            .iter()
            .map(|o| o.predicted_bytes)
            .sum();
        let report = ReportJson {
            scene: &self.label,
            device: &self.device,
            method: self.plan.method.to_string(),
            baker: &self.baker,
            objective: &self.objective,
            networks: self
                .networks
                .iter()
                .map(|(n, o)| NetworkJson {
                    name: n,
                    objects: o,
                })
                .collect(),
            timings: self.timings,
            times: self.times,
            plan_s: self.plan_s,
            replans: self.replans,
            sample_bakes_new: self.sample_bakes.0,
            sample_bakes_reused: self.sample_bakes.1,
            budget_bytes: self.plan.budget_bytes,
            predicted_bytes: predicted,
            file_bytes: self.realised.file_bytes(),
            objects: &self.realised.objects,
            quality: self.realised.quality,
            views: &self.realised.views,
            load_failure: self.simulation.load_failure.as_ref().map(|f| f.to_string()),
            mean_fps: self.simulation.mean_fps,
            steady_fps: self.simulation.steady_fps,
            loaded_at_s: self.simulation.loaded_at_s,
            profiler_ranges: &self.ranges,
            lattices: &self.lattices,
        };
        write_text(
            &out.join("report.json"),
            &serde_json::to_string_pretty(&report)?,
        )?;
        write_text(
            &out.join("plan.json"),
            &serde_json::to_string_pretty(&self.plan)?,
        )?;
        write_text(
            &out.join("scene.json"),
            &serde_json::to_string_pretty(&self.scene_json)?,
        )?;
        for o in &self.realised.objects {
            link_asset(&out.join("assets"), o)?;
        }
        Ok(())
    }
}

/// The 95 % bootstrap intervals of the whole scene's and each object's
/// scores over the held-out views (`eval::stats`): how far the means could
/// move with other views, so a difference smaller than that is noise.
fn interval_lines(views: &[ViewScores], s: &mut String) {
    use crate::eval::stats::bootstrap_mean;
    let col = |f: &dyn Fn(&ViewScores) -> Option<f64>| -> Vec<f64> {
        views.iter().filter_map(f).collect()
    };
    let (Some(ssim), Some(psnr)) = (
        bootstrap_mean(&col(&|v| Some(v.ssim))),
        bootstrap_mean(&col(&|v| Some(v.psnr))),
    ) else {
        return;
    };
    let lpips = bootstrap_mean(&col(&|v| v.lpips));
    let _ = writeln!(
        s,
        "  95 % intervals over the {} views: SSIM {}  PSNR {} dB{}",
        ssim.n,
        ssim.show(4),
        psnr.show(2),
        lpips.map_or(String::new(), |l| format!("  LPIPS {}", l.show(4)))
    );
    let mut names: Vec<&str> = Vec::new();
    for o in views.iter().flat_map(|v| &v.objects) {
        if !names.contains(&o.object.as_str()) {
            names.push(&o.object);
        }
    }
    if names.is_empty() {
        return;
    }
    let _ = writeln!(s, "  each object's SSIM in its box, mean [95 % interval]:");
    for n in names {
        let v: Vec<f64> = views
            .iter()
            .flat_map(|v| &v.objects)
            .filter(|o| o.object == n)
            .map(|o| o.ssim)
            .collect();
        if let Some(i) = bootstrap_mean(&v) {
            let _ = writeln!(s, "    {n:<12} {} over {} views", i.show(4), i.n);
        }
    }
}

/// `root/<object>/g<g>_p<p>` (or `…_mesh`,
/// [`crate::simulate::assets::asset_dir`]) → the asset in the store (a
/// symbolic link on Unix, a copy elsewhere).
fn link_asset(root: &Path, o: &RealisedObject) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let link = crate::simulate::assets::asset_dir(root, &o.name, o.g, o.p, o.geometry);
    if let Some(parent) = link.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    if link.symlink_metadata().is_ok() {
        if link.is_dir() && !link.is_symlink() {
            std::fs::remove_dir_all(&link)
        } else {
            std::fs::remove_file(&link)
        }
        .with_context(|| format!("{}: cannot replace", link.display()))?;
    }
    let target = std::fs::canonicalize(&o.asset)
        .with_context(|| format!("{}: missing", o.asset.display()))?;
    #[cfg(unix)]
    std::os::unix::fs::symlink(&target, &link)
        .with_context(|| format!("{}: cannot link", link.display()))?;
    #[cfg(not(unix))]
    {
        std::fs::create_dir_all(&link)?;
        for e in std::fs::read_dir(&target)? {
            let e = e?;
            std::fs::copy(e.path(), link.join(e.file_name()))?;
        }
    }
    Ok(())
}
