//! Issue 16: the evaluation's statistics and honest report, end to end on
//! one tiny built-in scene (48 × 48 pixels, 6 + 3 views): every measured
//! row keeps each held-out view's scores (whole image and each object in
//! its box) and their mean is the row's quality; the report prints
//! intervals, paired differences, one verdict per paper claim, the
//! segmentation-measure table and the substitutions; the example scene
//! files with invented numbers say so in their names and first lines.

use nerflex_sim::baselines::Method;
use nerflex_sim::device::Device;
use nerflex_sim::eval::{self, compare, detail, verdicts, EvalOptions, EvalReport};
use nerflex_sim::pipeline::Quiet;
use nerflex_sim::procedural::Preset;
use nerflex_sim::simulate::{SimOptions, TurntableSpec};
use std::path::{Path, PathBuf};

fn tiny(dir: &Path) -> (EvalReport, PathBuf) {
    let mut p = nerflex_tests::tiny_pipeline(dir.join("bakes"), 3);
    p.turntable = TurntableSpec {
        angles: 6,
        coverage_width: 40,
        ..TurntableSpec::DEFAULT
    };
    p.sim = SimOptions {
        frames: 100,
        period_s: 7.5,
    };
    p.baseline = (32, 5);
    let opts = EvalOptions {
        pipeline: p,
        scenes: vec![Preset::Scene4],
        devices: vec![
            Device::builtin("iphone13").unwrap(),
            Device::builtin("pixel4").unwrap(),
        ],
        real: vec![],
        real_size: 64,
        fps_scene: Preset::Scene4,
    };
    let out = dir.join("eval");
    (eval::run(&opts, &out, None, &Quiet).unwrap(), out)
}

#[test]
fn per_view_scores_intervals_and_verdicts() {
    let dir = tempfile::tempdir().unwrap();
    let (report, out) = tiny(dir.path());
    let s = &report.scenes[0];
    assert_eq!(report.baker, "hull");
    // Per-view scores: 3 views per measured row, means equal the row's.
    for row in s.rows.iter().filter(|r| r.error.is_none()) {
        assert_eq!(row.views.len(), 3, "{} {}", row.device, row.method);
        let q = row.quality.unwrap();
        let mean = row.views.iter().map(|v| v.ssim).sum::<f64>() / 3.0;
        assert!((mean - q.ssim).abs() < 1e-12, "{mean} vs {}", q.ssim);
        let i = compare::interval(row, compare::Metric::Ssim).unwrap();
        assert!(i.lo <= q.ssim && q.ssim <= i.hi && i.n == 3);
        // Every scene object visible in a view is scored in its box.
        assert!(row.views.iter().all(|v| !v.objects.is_empty()));
    }
    // Single- and Block-NeRF are the same bakes on both devices: the same
    // per-view scores.
    let find = |d: &str, m: Method| compare::measured(s, d, m).unwrap();
    assert_eq!(
        find("iphone13", Method::Block).views,
        find("pixel4", Method::Block).views
    );
    // The segmentation's per-object readings reached the report.
    assert_eq!(s.objects.len(), 5);
    for o in &s.objects {
        assert!(o.max_cycles_per_diameter > 0.0);
        assert!(o.max_cycles_per_pixel.is_some_and(|c| c > 0.0 && c < 0.5));
        assert!(o.complexity_quads.is_some_and(|q| q > 0));
    }
    let a = detail::analyse(&report);
    assert!(!a.gains.is_empty());
    assert!(a.gains.iter().all(|g| g.gain.n >= 1));
    // One verdict per claim, each with its numbers.
    let v = verdicts::verdicts(&report);
    assert_eq!(v.len(), 6);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for x in &v {
        assert!(md.contains(&x.line()), "{}", x.line());
    }
    for needle in [
        "95 % bootstrap interval",
        "NeRFlex (DP) − each other method",
        "## The paper's claims",
        "## Does the segmentation's measure predict",
        "## What this evaluation substitutes",
        "built-in procedural objects",
        "no real-world table",
        "instance masks rendered with the capture",
        "0.1 MB budget unit",
        "9 g × 5 p",
        "circular",
        "> **Scope.**",
        "mean FPS (predicted)",
    ] {
        assert!(md.contains(needle), "report lacks {needle:?}");
    }
    // The JSON keeps the views (the report can be redrawn from it alone).
    let back: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(out.join("eval.json")).unwrap()).unwrap();
    assert_eq!(back.scenes[0].rows[0].views, s.rows[0].views);
    assert_eq!(
        eval::report::markdown(&back, &[]),
        eval::report::markdown(&report, &[])
    );
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn example_scenes_with_invented_numbers_say_so() {
    let dir = repo().join("examples/scenes");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let text = std::fs::read_to_string(&path).unwrap();
        let first = text.lines().next().unwrap_or("");
        if name.contains("illustrative") {
            assert!(
                first.contains("illustrative") && first.contains("not measured"),
                "{name}: first line {first:?}"
            );
        } else {
            // Every other example is a fit of the measured bake sweep, as
            // `nerflex profile fit` writes it (its "fit" records).
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            let objects = v["objects"].as_array().unwrap();
            assert!(
                objects.iter().all(|o| o.get("fit").is_some()),
                "{name}: neither labelled illustrative nor a measured fit"
            );
        }
    }
}

/// `--crop-margin` reaches the segmentation: each dedicated network's
/// crop grows, so its views are enlarged less (a smaller mean zoom), and
/// its views differ, so the store keeps them apart from the tight crop's.
#[test]
fn a_crop_margin_widens_every_dedicated_networks_crop() {
    use nerflex_sim::pipeline::{prepare, Input};
    let dir = tempfile::tempdir().unwrap();
    let run = |margin: f32| {
        let mut p = nerflex_tests::tiny_pipeline(dir.path().join("bakes"), 3);
        p.crop_margin = margin;
        let out = dir.path().join(format!("m{margin}"));
        prepare(&Input::Preset(Preset::Scene4), &p, &out, None, &Quiet).unwrap()
    };
    let (tight, wide) = (run(0.0), run(0.25));
    let mut dedicated = 0;
    for (t, w) in tight
        .segmentation
        .groups
        .iter()
        .zip(&wide.segmentation.groups)
    {
        assert_eq!(t.folder, w.folder);
        if t.objects.len() == 1 && t.folder != "shared" {
            dedicated += 1;
            assert!(
                w.mean_zoom < t.mean_zoom,
                "{}: zoom {} with the margin, {} without",
                t.folder,
                w.mean_zoom,
                t.mean_zoom
            );
        }
    }
    assert!(dedicated > 0, "scene 4 has no dedicated network at 48 px");
    for (t, w) in tight.networks.iter().zip(&wide.networks) {
        if t.name != "shared" {
            assert_ne!(t.views.content_hash, w.views.content_hash, "{}", t.name);
        }
    }
}
