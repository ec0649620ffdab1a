//! The profiler on the committed bake sweep (`results/bake/samples.csv`:
//! lego, chair and 12 built-in objects × g 16…256 × p 5…17, 280 real
//! bakes): `nerflex profile fit` writes profiles that `nerflex plan`
//! accepts, the plans stay within the device budgets and use the fitted
//! profiles, and the fits predict held-out bakes. Needs no external data.
//!
//! The two committed example scenes are the fits before the quads family
//! existed (`--family classic`: the surface family's size on every object):
//! the README's plans and the firmware's tables are built on them.
//! `--family auto` picks the quads family on every object (checked below).

use nerflex_core::profiler::Family;
use nerflex_core::units::Bytes;
use nerflex_sim::baselines::{plan, Budget, Method};
use nerflex_sim::cli::profile::{fit_report, FitArgs};
use nerflex_sim::device::Device;
use nerflex_sim::fit::{self, accuracy, samples, FamilyChoice};
use nerflex_sim::scene_file;
use std::path::PathBuf;

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path)
}

const OBJECTS: [&str; 5] = ["lego", "chair", "gear", "tree", "vase"];
const GRID: [u32; 9] = [16, 24, 32, 48, 64, 96, 128, 192, 256];
const PATCH: [u32; 7] = [5, 7, 9, 11, 13, 15, 17];

#[test]
fn fitted_real_profiles_plan_within_budget() {
    let csv = repo("results/bake/samples.csv");
    let all = samples::read(&csv).unwrap();
    assert_eq!(all.len(), 280);
    assert_eq!(samples::objects(&all).len(), 14);

    // The command the README names for examples/scenes/real_profiles.json.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("real_profiles.json");
    let text = fit_report(&FitArgs {
        samples: csv.clone(),
        objects: OBJECTS.iter().map(|s| s.to_string()).collect(),
        out: out.clone(),
        family: FamilyChoice::Classic,
        grid: GRID.to_vec(),
        patch: PATCH.to_vec(),
    })
    .unwrap();
    assert!(text.contains("fitted 5 object(s)"), "{text}");

    let scene = scene_file::load(&out).unwrap();
    let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, OBJECTS);
    let only: Vec<String> = OBJECTS.iter().map(|s| s.to_string()).collect();
    let domain = fit::Domain {
        g_min: 16,
        g_max: 256,
        p_min: 5,
        p_max: 17,
    };
    let fits = fit::fit_objects(&all, &only, Some(domain), FamilyChoice::Classic).unwrap();
    let auto = fit::fit_objects(&all, &only, Some(domain), FamilyChoice::Auto).unwrap();
    for ((obj, f), a) in scene.objects.iter().zip(&fits).zip(&auto) {
        assert_eq!(obj.configs.len(), GRID.len() * PATCH.len());
        assert_eq!(f.size.best.params.family, Family::Surface, "{}", obj.name);
        // The quads family (a per-quad term) wins on every real object.
        assert_eq!(a.size.best.params.family, Family::Quads, "{}", obj.name);
        assert!(
            a.size.best.residuals.rmse < f.size.best.residuals.rmse,
            "{}: {:?} vs {:?}",
            obj.name,
            a.size.best.residuals,
            f.size.best.residuals
        );
        let prof = f.profile().unwrap();
        for c in &obj.configs {
            let want = prof.config(c.g, c.p).unwrap();
            assert_eq!(c.size, want.size, "{} ({}, {})", obj.name, c.g, c.p);
            assert_eq!(c.quality, want.quality.to_f64());
        }
    }

    // The committed example scene is what the command writes today.
    assert_same_scene("examples/scenes/real_profiles.json", &out);

    for device in ["iphone13", "pixel4"] {
        let budget_bytes = Device::lookup(device).unwrap().budget();
        let p = plan(Method::Dp, &scene, Budget::new(budget_bytes)).unwrap();
        assert!(p.feasible, "{device}: {p:?}");
        assert!(p.total_size_bytes <= budget_bytes.0, "{device}: {p:?}");
        // Five objects whose largest bakes are 100–300 MB each: the budget
        // binds, and the plan uses most of it.
        assert!(
            p.total_size_bytes as f64 > 0.9 * budget_bytes.0 as f64,
            "{device}: {p:?}"
        );
        assert_eq!(p.objects.len(), OBJECTS.len());
        for (po, obj) in p.objects.iter().zip(&scene.objects) {
            assert_eq!(po.name, obj.name);
            let prof = fits.iter().find(|f| f.name == po.name).unwrap().profile();
            let want = prof.unwrap().config(po.g, po.p).unwrap();
            assert_eq!(Bytes(po.size_bytes), want.size, "{device} {}", po.name);
            assert_eq!(po.quality, want.quality.to_f64(), "{device} {}", po.name);
        }
        let sum: u64 = p.objects.iter().map(|o| o.size_bytes).sum();
        assert_eq!(sum, p.total_size_bytes);
    }
}

/// The committed scene `example` has the configurations of the freshly
/// written `fresh` (fits agree to 1 ppm in size, 1e-6 in SSIM).
fn assert_same_scene(example: &str, fresh: &std::path::Path) {
    let e = scene_file::load(&repo(example)).unwrap();
    let f = scene_file::load(fresh).unwrap();
    assert_eq!(e.objects.len(), f.objects.len(), "{example}");
    for (eo, fo) in e.objects.iter().zip(&f.objects) {
        assert_eq!(eo.name, fo.name, "{example}");
        assert_eq!(eo.configs.len(), fo.configs.len(), "{example}");
        for (ce, cf) in eo.configs.iter().zip(&fo.configs) {
            assert_eq!((ce.g, ce.p), (cf.g, cf.p), "{example}");
            assert!(
                ce.size.0.abs_diff(cf.size.0) <= 1 + cf.size.0 / 1_000_000,
                "{example} {} ({}, {}): {:?} vs {:?}",
                eo.name,
                ce.g,
                ce.p,
                ce.size,
                cf.size
            );
            assert!((ce.quality - cf.quality).abs() < 1e-6, "{example}");
        }
    }
}

/// `examples/scenes/five_objects_profile.json` (the planning examples' and
/// the Cortex-M firmware's five profiles) is the real fit of lego, chair,
/// gear, tree and vase on a 9 g × 5 p space (our reading of the paper's
/// "45 configuration pairs"; the paper gives no grid).
#[test]
fn five_objects_profile_example_is_the_real_fit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("five.json");
    fit_report(&FitArgs {
        samples: repo("results/bake/samples.csv"),
        objects: OBJECTS.iter().map(|s| s.to_string()).collect(),
        out: out.clone(),
        family: FamilyChoice::Classic,
        grid: (0..9).map(|i| 32 + 16 * i).collect(),
        patch: vec![5, 9, 13, 17, 21],
    })
    .unwrap();
    assert_same_scene("examples/scenes/five_objects_profile.json", &out);
}

#[test]
fn real_fits_predict_held_out_bakes() {
    let all = samples::read(&repo("results/bake/samples.csv")).unwrap();
    let objects = ["lego".to_string(), "chair".to_string(), "vase".to_string()];

    // Leave-one-out: each bake predicted from the object's 19 others.
    let loo = accuracy::leave_one_out(&all, &objects, FamilyChoice::Auto).unwrap();
    assert_eq!(loo.points.len(), 60);
    assert!(loo.all.ssim.mean < 0.004, "{:?}", loo.all);
    assert!(loo.all.size_rel.mean < 0.08, "{:?}", loo.all);
    // The paper's g³ size form is markedly worse on these bakes.
    let vol = accuracy::leave_one_out(&all, &objects, FamilyChoice::Volume).unwrap();
    assert!(
        vol.all.size_rel.mean > 2.0 * loo.all.size_rel.mean,
        "{:?} vs {:?}",
        vol.all,
        loo.all
    );

    // Trained on the variable-step points only (g {16, 64, 256} × p
    // {5, 9, 17}), the other 11 configurations per object are predicted.
    let vs = accuracy::train_subset(
        &all,
        &objects,
        FamilyChoice::Auto,
        &[16, 64, 256],
        &[5, 9, 17],
    )
    .unwrap();
    assert_eq!(vs.points.len(), 33);
    assert!(vs.objects.iter().all(|o| o.trained_on == 9));
    assert!(vs.all.ssim.mean < 0.004, "{:?}", vs.all);
    assert!(vs.all.size_rel.mean < 0.08, "{:?}", vs.all);
}

/// The trained baker's sweep (`results/bake/trained/samples.csv`, lego and
/// chair): bytes per quad are a constant plus a p² part that shrinks with
/// g, which the surface law cannot follow. Trained on the variable-step
/// points, the quads family predicts the other 22 sizes within 10 % on
/// average and under-predicts none by 15 %, where the surface law does.
/// (Session 18's sweep: 6.6 % against 11.0 %, worst −11 % against −24 %.
/// Session 20's, whose g = 256 bakes keep more quads: 6.8 % against 5.5 %,
/// worst −13.3 % against −17.0 %, so the quads law's lead is now only in
/// the worst case; docs/profiler.md, "Re-measured on session 20's sweep".)
#[test]
fn quads_family_predicts_the_trained_sweep() {
    let all = samples::read(&repo("results/bake/trained/samples.csv")).unwrap();
    let vs =
        |family| accuracy::train_subset(&all, &[], family, &[16, 64, 256], &[5, 9, 17]).unwrap();
    let (auto, surface) = (vs(FamilyChoice::Auto), vs(FamilyChoice::Classic));
    assert!(surface
        .objects
        .iter()
        .all(|o| o.fit.size.best.params.family == Family::Surface));
    assert_eq!(auto.points.len(), 22);
    assert!(auto
        .objects
        .iter()
        .all(|o| o.fit.size.best.params.family == Family::Quads));
    let worst = |a: &accuracy::Accuracy| a.all.worst_under.as_ref().unwrap().rel;
    assert!(auto.all.size_rel.mean < 0.10, "{:?}", auto.all);
    assert!(worst(&auto) > -0.15, "{:?}", auto.all);
    assert!(worst(&surface) < -0.15, "{:?}", surface.all);
    assert!(worst(&auto) > worst(&surface) + 0.02);
}
