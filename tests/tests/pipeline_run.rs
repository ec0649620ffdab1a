//! The whole pipeline on a tiny built-in scene (48 × 48 pixels, 6 + 2
//! views, grids ≤ 24): segmentation → sample bakes → fits → DP and
//! Fairness plans under a budget that binds → bakes → held-out views →
//! simulation; the bake store is reused; `nerflex run`'s outputs feed
//! `nerflex simulate`.

use nerflex_core::units::Bytes;
use nerflex_sim::baselines::Method;
use nerflex_sim::device::Device;
use nerflex_sim::pipeline::{self, Input, Options, Quiet};
use nerflex_sim::procedural::Preset;
use nerflex_sim::simulate::TurntableSpec;
use std::path::Path;

fn tiny(store: &Path) -> Options {
    // The hull baker: these tests check the pipeline's machinery, not training.
    let mut o = nerflex_tests::tiny_pipeline(store.to_path_buf(), 2);
    nerflex_tests::tiny_simulation(&mut o, 8, 48, 300);
    o
}

#[test]
fn tiny_scene_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("bakes");
    let opts = tiny(&store);
    let out = dir.path().join("run");
    let prepared =
        pipeline::prepare(&Input::Preset(Preset::Scene1), &opts, &out, None, &Quiet).unwrap();

    // Every object of the scene is in exactly one network.
    let mut covered: Vec<String> = prepared
        .networks
        .iter()
        .flat_map(|n| n.objects.clone())
        .collect();
    covered.sort();
    let mut objects: Vec<String> = prepared
        .capture
        .as_ref()
        .unwrap()
        .scene
        .as_ref()
        .unwrap()
        .objects
        .iter()
        .map(|o| o.name.clone())
        .collect();
    objects.sort();
    assert_eq!(covered, objects);
    // Sample points: g ∈ {8, 24} × p ∈ {3, 4, 5} per network.
    assert_eq!(prepared.samples.len(), prepared.networks.len() * 6);
    assert!(prepared.samples.iter().all(|b| !b.cached));
    assert_eq!(prepared.scene.objects.len(), prepared.networks.len());
    assert!(prepared.scene.objects.iter().all(|o| o.configs.len() == 12));

    // A budget halfway between the cheapest and the dearest plan binds.
    let (lo, hi): (u64, u64) = prepared.scene.objects.iter().fold((0, 0), |(l, h), o| {
        let s = o.configs.iter().map(|c| c.size.0);
        (l + s.clone().min().unwrap(), h + s.max().unwrap())
    });
    let mut device = Device::builtin("pixel4").unwrap();
    device.budget_mb = Bytes((lo + hi) / 2).as_mb();
    device.hard_limit_mb = Some(device.budget_mb * 2.0);
    device.soft_limit = None;

    let (dp, _) = pipeline::plan_for(&prepared, Method::Dp, &device).unwrap();
    let (fair, _) = pipeline::plan_for(&prepared, Method::Fairness, &device).unwrap();
    assert!(dp.feasible && dp.total_size_bytes <= device.budget().0);
    assert!(dp.total_quality >= fair.total_quality - 1e-9);

    let realised = pipeline::realise(&prepared, &dp, &opts, None, &Quiet).unwrap();
    assert_eq!(realised.objects.len(), dp.objects.len());
    for (r, p) in realised.objects.iter().zip(&dp.objects) {
        assert_eq!((r.name.as_str(), r.g, r.p), (p.name.as_str(), p.g, p.p));
        assert!(r.file_bytes > 0 && r.asset.is_dir());
    }
    let q = realised.quality;
    assert_eq!(q.views, 2);
    assert!(q.ssim > 0.0 && q.ssim <= 1.0, "{q:?}");
    assert!(q.psnr.is_finite());

    let sims = pipeline::simulate_devices(&realised, &[device.clone()], &opts).unwrap();
    let sim = &sims[0];
    assert_eq!(sim.frames.len(), 300);
    assert!(sim.load_failure.is_none());
    assert!(sim.mean_fps > 0.0 && sim.mean_fps.is_finite());
    assert_eq!(sim.data_bytes, realised.file_bytes());
    // The same scene on a device that cannot hold it fails to load.
    let mut small = device.clone();
    small.hard_limit_mb = Some(Bytes(realised.file_bytes() - 1).as_mb());
    let failed = pipeline::simulate_on(&realised, &small, &opts).unwrap();
    assert!(failed.load_failure.is_some() && failed.mean_fps == 0.0);

    // A second run finds every bake in the store.
    let again =
        pipeline::prepare(&Input::Preset(Preset::Scene1), &opts, &out, None, &Quiet).unwrap();
    assert!(again.samples.iter().all(|b| b.cached));
    assert_eq!(
        again.samples.iter().map(|b| &b.sample).collect::<Vec<_>>(),
        prepared
            .samples
            .iter()
            .map(|b| &b.sample)
            .collect::<Vec<_>>()
    );

    // The area objective: the same scene from the store, each network
    // weighted by 1 / zoom² (the shared one by 1), and a DP plan that is
    // at least as good on the weighted sum and reports unweighted SSIM.
    let mut area_opts = opts.clone();
    area_opts.objective = nerflex_sim::baselines::Objective::Area;
    let area = pipeline::prepare(
        &Input::Preset(Preset::Scene1),
        &area_opts,
        &out,
        None,
        &Quiet,
    )
    .unwrap();
    assert_eq!(area.scene, prepared.scene);
    assert_eq!(prepared.objective.1, vec![1.0; prepared.networks.len()]);
    let zoom: Vec<f64> = area
        .segmentation
        .groups
        .iter()
        .map(|g| g.mean_zoom)
        .collect();
    let w = &area.objective.1;
    let max = zoom.iter().map(|z| 1.0 / (z * z)).fold(0.0, f64::max);
    for (wi, z) in w.iter().zip(&zoom) {
        assert!((wi - 1.0 / (z * z) / max).abs() < 1e-12, "{w:?} {zoom:?}");
    }
    assert!(area.segmentation.groups.iter().any(|g| g.mean_zoom > 1.0));
    let (dp_area, _) = pipeline::plan_for(&area, Method::Dp, &device).unwrap();
    assert!(dp_area.feasible && dp_area.total_size_bytes <= device.budget().0);
    let weighted = |p: &nerflex_sim::baselines::Plan| -> f64 {
        p.objects.iter().zip(w).map(|(o, w)| w * o.quality).sum()
    };
    assert!(weighted(&dp_area) >= weighted(&dp) - 1e-6);
    for (o, so) in dp_area.objects.iter().zip(&area.scene.objects) {
        assert_eq!(o.quality, so.configs[o.config_index.unwrap()].quality);
    }

    // `nerflex run`'s files feed `nerflex simulate`.
    let run = pipeline::RunResult {
        label: prepared.label.clone(),
        device: device.name.clone(),
        plan: dp.clone(),
        plan_s: 0.0,
        replans: 0,
        realised,
        simulation: sim.clone(),
        timings: prepared.timings,
        networks: vec![],
        sample_bakes: (0, 0),
        scene_json: prepared.scene_json.clone(),
        baker: opts.baker.name().to_string(),
        objective: opts.objective.name().to_string(),
        times: pipeline::RunTimes::default(),
        ranges: pipeline::range::ranges(&again.samples),
        lattices: Vec::new(),
    };
    // Stored bakes keep each held-out view's scores, so a re-run can
    // still compare its sample bakes with their noise.
    assert!(!run.ranges.is_empty());
    assert!(
        run.ranges.iter().all(|r| r.ssim.is_some()),
        "{:?}",
        run.ranges
    );
    run.write(&out).unwrap();
    let device_file = dir.path().join("dev.toml");
    std::fs::write(&device_file, toml_of(&device)).unwrap();
    let csv = dir.path().join("fps.csv");
    let png = dir.path().join("fps.png");
    nerflex_sim::cli::simulate::run(nerflex_sim::cli::simulate::Args {
        scene: out.join("scene.json"),
        plan: Some(out.join("plan.json")),
        method: None,
        device: device_file.display().to_string(),
        assets: None,
        frames: 300,
        period_s: 7.5,
        angles: 8,
        coverage_px: 48,
        elevation_deg: 30.0,
        distance: TurntableSpec::DEFAULT.distance,
        plot: Some(png.clone()),
        csv: Some(csv.clone()),
        json: false,
    })
    .unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().count(), 301);
    assert!(png.is_file());
}

fn toml_of(d: &Device) -> String {
    format!(
        "name = \"{}\"\nbudget_mb = {}\nhard_limit_mb = {}\n[throughput]\nmac_per_s = {}\nquads_per_s = {}\nframe_overhead_ms = {}\nload_mb_per_s = {}\n[display]\nrefresh_hz = {}\nwidth_px = {}\nheight_px = {}\n",
        d.name,
        d.budget_mb,
        d.hard_limit_mb.unwrap(),
        d.throughput.mac_per_s,
        d.throughput.quads_per_s,
        d.throughput.frame_overhead_ms,
        d.throughput.load_mb_per_s,
        d.display.refresh_hz,
        d.display.width_px,
        d.display.height_px
    )
}

#[test]
fn bad_inputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let opts = tiny(&dir.path().join("bakes"));
    let e = pipeline::prepare(
        &Input::Capture(dir.path().join("nope")),
        &opts,
        &dir.path().join("out"),
        None,
        &Quiet,
    )
    .err()
    .unwrap();
    assert!(format!("{e:#}").contains("nope"), "{e:#}");
}

/// The real lego + chair, composed side by side at 48 × 48 pixels: both
/// NeRFlex's networks and Block-NeRF's bakes are measured on the same
/// source held-out views; there is no Single-NeRF.
#[test]
fn real_composite_tiny() {
    let Some(data) = nerflex_sim::data::require_data("real composite pipeline") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut opts = tiny(&dir.path().join("bakes"));
    opts.baseline = (24, 5);
    let input = Input::Composite {
        dirs: vec![
            data.join("nerf_synthetic/lego"),
            data.join("nerf_synthetic/chair"),
        ],
        size: 48,
    };
    let prepared = pipeline::prepare(&input, &opts, &dir.path().join("out"), None, &Quiet).unwrap();
    assert!(prepared.capture.is_none() && prepared.single_views.is_none());
    assert_eq!(prepared.block_views.len(), 2);
    let device = Device::builtin("iphone13").unwrap();
    let (dp, _) = pipeline::plan_for(&prepared, Method::Dp, &device).unwrap();
    let r = pipeline::realise(&prepared, &dp, &opts, None, &Quiet).unwrap();
    // Five held-out views per source capture, whichever network holds it.
    assert_eq!(r.quality.views, 10);
    assert!(r.quality.ssim > 0.0 && r.quality.ssim <= 1.0);
    let (block, _) =
        pipeline::method_plan(&prepared, Method::Block, &device, &opts, None, &Quiet).unwrap();
    let mut names: Vec<&str> = block.objects.iter().map(|o| o.name.as_str()).collect();
    names.sort();
    assert_eq!(names, ["chair", "lego"]);
    let rb = pipeline::realise(&prepared, &block, &opts, None, &Quiet).unwrap();
    assert_eq!(rb.quality.views, 10);
    let e = pipeline::method_plan(&prepared, Method::Single, &device, &opts, None, &Quiet)
        .err()
        .unwrap();
    assert!(e.to_string().contains("composite"), "{e}");
}
