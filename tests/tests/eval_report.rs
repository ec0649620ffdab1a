//! `nerflex eval` on one tiny built-in scene (48 × 48 pixels, 6 + 2 views):
//! every method on both built-in devices, the report's numbers consistent
//! with each other, the Markdown and the plots written, the JSON readable.

use nerflex_sim::baselines::Method;
use nerflex_sim::device::Device;
use nerflex_sim::eval::{self, EvalOptions, EvalReport, METHODS};
use nerflex_sim::pipeline::Quiet;
use nerflex_sim::procedural::Preset;
use nerflex_sim::simulate::{SimOptions, TurntableSpec};

#[test]
fn tiny_evaluation() {
    let dir = tempfile::tempdir().unwrap();
    let mut p = nerflex_tests::tiny_pipeline(dir.path().join("bakes"), 2);
    p.turntable = TurntableSpec {
        angles: 6,
        coverage_width: 40,
        ..TurntableSpec::DEFAULT
    };
    p.sim = SimOptions {
        frames: 200,
        period_s: 7.5,
    };
    // Smaller than the paper's (128, 17) to keep the test short.
    p.baseline = (32, 5);
    let devices = vec![
        Device::builtin("iphone13").unwrap(),
        Device::builtin("pixel4").unwrap(),
    ];
    let opts = EvalOptions {
        pipeline: p,
        scenes: vec![Preset::Scene3],
        devices,
        real: vec![],
        real_size: 64,
        fps_scene: Preset::Scene3,
    };
    let out = dir.path().join("eval");
    let report = eval::run(&opts, &out, None, &Quiet).unwrap();

    assert_eq!(report.scenes.len(), 1);
    let s = &report.scenes[0];
    // One row per device and method.
    assert_eq!(s.rows.len(), 2 * METHODS.len());
    for row in &s.rows {
        if let Some(e) = &row.error {
            // Only the optimisers may find no plan.
            assert!(
                matches!(row.method, Method::Slsqp | Method::Fairness),
                "{e}"
            );
            continue;
        }
        let q = row.quality.unwrap();
        assert!(q.ssim > 0.0 && q.ssim <= 1.0);
        assert_eq!(
            row.file_bytes,
            row.objects.iter().map(|o| o.file_bytes).sum::<u64>()
        );
        // A load failure is exactly data over the device's hard limit.
        let d = Device::builtin(&row.device).unwrap();
        let over = d.hard_limit().is_some_and(|h| row.file_bytes > h.0);
        assert_eq!(row.load_failure.is_some(), over, "{row:?}");
        assert!(row.mean_fps.is_finite() && row.mean_fps >= 0.0);
        match row.method {
            // Real bakes: one for the whole scene, one per object.
            Method::Single => {
                assert_eq!(row.objects.len(), 1);
                assert_eq!(row.objects[0].name, "single");
                assert_eq!((row.objects[0].g, row.objects[0].p), (32, 5));
            }
            Method::Block => {
                assert_eq!(row.objects.len(), 5);
                assert!(row.objects.iter().all(|o| (o.g, o.p) == (32, 5)));
            }
            _ => assert!(row.predicted_bytes <= row.budget_bytes),
        }
    }
    // Single- and Block-NeRF are the same bakes on both devices.
    let find = |d: &str, m: Method| {
        s.rows
            .iter()
            .find(|r| r.device == d && r.method == m)
            .unwrap()
    };
    for m in [Method::Single, Method::Block] {
        assert_eq!(find("iphone13", m).file_bytes, find("pixel4", m).file_bytes);
    }
    // The FPS scene keeps its curves; the calibration check ran per device.
    assert_eq!(
        report.fps.len(),
        2 * METHODS.len() - s.rows.iter().filter(|r| r.error.is_some()).count()
    );
    assert!(report.fps.iter().all(|c| c.fps.len() == 200));
    assert_eq!(report.calibration.len(), 2);
    for c in &report.calibration {
        assert!(c.scale > 0.0 && c.scale.is_finite());
        assert!((c.fps_at_scale - c.target_fps).abs() < 0.05 || c.scale <= 1e-4 || c.scale >= 1e4);
    }
    // Files: the JSON reads back, the report names every figure it drew.
    let back: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(out.join("eval.json")).unwrap()).unwrap();
    assert_eq!(back.scenes[0].rows.len(), s.rows.len());
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for f in [
        "quality_iphone13.png",
        "size_pixel4.png",
        "selectors_pixel4.png",
        "fps_iphone13.png",
        "overhead.png",
        // One held-out view: the truth beside every method's render.
        "renders_scene3_iphone13.png",
        "renders_scene3_pixel4.png",
    ] {
        assert!(out.join(f).is_file(), "{f}");
        assert!(md.contains(f), "{f}");
    }
    assert!(md.contains("| scene3 |") || md.contains("### scene3"));
    // Every realised plan's held-out renders are kept in the work folder.
    let kept = std::fs::read_dir(out.join("scenes/scene3/renders"))
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.path().join("test_1.png").is_file())
        .count();
    assert!(kept >= 3, "{kept} render folders");
}
