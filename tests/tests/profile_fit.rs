//! Profile fitting on synthetic sweeps with known parameters plus noise:
//! the fit recovers them, picks the right family, the leave-one-out report
//! is sane, and `nerflex profile fit` writes profiles `nerflex plan` reads.

use nerflex_core::profiler::{Curve, Family, Params};
use nerflex_sim::cli::profile::{
    accuracy_report, fit_report, samples_report, AccuracyArgs, FitArgs, SamplesArgs, TrainOn,
};
use nerflex_sim::fit::{
    self, accuracy, curve, samples,
    sampling::{self, Step},
    synthetic::{self, Noise},
    Domain, FamilyChoice,
};
use std::path::Path;

const GRIDS: [u32; 5] = [16, 32, 64, 128, 256];
const PATCHES: [u32; 4] = [5, 9, 13, 17];

/// A baked-object-like size model: surface-like, ~130 MB at (256, 17).
fn size_truth(family: Family) -> Params {
    let (k, c) = match family {
        Family::Surface => (6.0, 0.0),
        Family::Volume => (0.03, 0.0),
        Family::Quads => (40.0, 1500.0),
    };
    Params {
        k,
        a: 2.0,
        b: 1.0,
        c,
        m: 50_000.0,
        family,
    }
}

fn quality_truth(family: Family) -> Params {
    // The quality has no quads family: its truth is the surface one.
    let (k, family) = match family {
        Family::Surface | Family::Quads => (2.0e3, Family::Surface),
        Family::Volume => (6.0e4, Family::Volume),
    };
    Params {
        k,
        a: 4.0,
        b: 0.5,
        c: 0.0,
        m: 0.965,
        family,
    }
}

fn rel(x: f64, y: f64) -> f64 {
    (x - y).abs() / y.abs()
}

#[test]
fn recovers_parameters_without_noise() {
    for family in Family::ALL {
        let s = synthetic::samples(
            "obj",
            &size_truth(family),
            &quality_truth(family),
            &GRIDS,
            &PATCHES,
            Noise::NONE,
            1,
        );
        let refs: Vec<_> = s.iter().collect();
        let f = fit::fit_object("obj", &refs, None, FamilyChoice::Auto).unwrap();
        let (sp, qp) = (f.size.best.params, f.quality.best.params);
        let quality_family = quality_truth(family).family;
        assert_eq!((sp.family, qp.family), (family, quality_family), "{f:#?}");
        // Sizes are rounded to whole bytes: parameters within 1e-3.
        assert!(rel(sp.k, size_truth(family).k) < 1e-3, "{sp:?}");
        assert!(
            sp.c == size_truth(family).c || rel(sp.c, size_truth(family).c) < 1e-3,
            "{sp:?}"
        );
        assert!(
            (sp.a - 2.0).abs() < 1e-2 && (sp.b - 1.0).abs() < 1e-2,
            "{sp:?}"
        );
        assert!(rel(sp.m, 50_000.0) < 1e-2, "{sp:?}");
        assert!(rel(qp.k, quality_truth(family).k) < 1e-3, "{qp:?}");
        assert!(
            (qp.a - 4.0).abs() < 1e-2 && (qp.b - 0.5).abs() < 1e-2,
            "{qp:?}"
        );
        assert!((qp.m - 0.965).abs() < 1e-6, "{qp:?}");
    }
}

#[test]
fn noisy_fit_predicts_held_out_truth() {
    // 2 % size noise, 0.003 SSIM noise: the fitted curves must predict the
    // *noise-free* truth at unseen configurations far better than the noise.
    let family = Family::Surface;
    let (st, qt) = (size_truth(family), quality_truth(family));
    let s = synthetic::samples(
        "obj",
        &st,
        &qt,
        &GRIDS,
        &PATCHES,
        Noise {
            size_rel: 0.02,
            ssim_abs: 0.003,
        },
        7,
    );
    let refs: Vec<_> = s.iter().collect();
    let f = fit::fit_object(
        "obj",
        &refs,
        Some(Domain {
            g_min: 16,
            g_max: 256,
            p_min: 5,
            p_max: 17,
        }),
        FamilyChoice::Auto,
    )
    .unwrap();
    let prof = f.profile().unwrap();
    for (g, p) in [(24, 7), (48, 11), (96, 15), (200, 16)] {
        let c = prof.config(g, p).unwrap();
        let s_true = st.size_f64(g as f64, p as f64);
        let q_true = qt.quality_f64(g as f64, p as f64);
        assert!(
            rel(c.size.0 as f64, s_true) < 0.02,
            "size at ({g}, {p}): {} vs {s_true}",
            c.size.0
        );
        assert!(
            (c.quality.to_f64() - q_true).abs() < 0.004,
            "SSIM at ({g}, {p}): {} vs {q_true}",
            c.quality
        );
    }
    // Residuals reflect the noise level.
    assert!(
        f.quality.best.residuals.rmse < 0.006,
        "{:?}",
        f.quality.best
    );
}

#[test]
fn paper_sample_plan_is_enough_to_fit() {
    // The 12 variable-step points over 16..512 × 3..33 determine the models.
    let plan = sampling::variable_step(16..=512, 3..=33, Step::Triple).unwrap();
    let family = Family::Volume;
    let s = synthetic::samples(
        "obj",
        &size_truth(family),
        &quality_truth(family),
        &plan.grids,
        &plan.patches,
        Noise::NONE,
        3,
    );
    assert_eq!(s.len(), 12);
    let refs: Vec<_> = s.iter().collect();
    let f = fit::fit_object("obj", &refs, None, FamilyChoice::Volume).unwrap();
    let prof = f.profile().unwrap();
    for g in [16, 100, 300, 512] {
        for p in [3, 10, 33] {
            let c = prof.config(g, p).unwrap();
            let s_true = size_truth(family).size_f64(g as f64, p as f64);
            assert!(rel(c.size.0 as f64, s_true) < 1e-3, "({g}, {p})");
            let q_true = quality_truth(family)
                .quality_f64(g as f64, p as f64)
                .clamp(0.0, 1.0);
            assert!((c.quality.to_f64() - q_true).abs() < 1e-3, "({g}, {p})");
        }
    }
}

#[test]
fn family_choice_follows_residuals() {
    // Data from the surface family: forcing volume fits worse.
    let family = Family::Surface;
    let s = synthetic::samples(
        "obj",
        &size_truth(family),
        &quality_truth(family),
        &GRIDS,
        &PATCHES,
        Noise::NONE,
        1,
    );
    let pts: Vec<curve::Point> = s
        .iter()
        .map(|x| curve::Point {
            g: x.g,
            p: x.p,
            y: x.size.0 as f64,
        })
        .collect();
    let d = Domain::of_points(&pts).unwrap();
    let auto = curve::fit(Curve::Size, &pts, d, FamilyChoice::Auto).unwrap();
    assert_eq!(auto.tried.len(), 3);
    let vol = curve::fit(Curve::Size, &pts, d, FamilyChoice::Volume).unwrap();
    assert_eq!(vol.tried.len(), 1);
    assert!(vol.best.residuals.rmse > 10.0 * auto.best.residuals.rmse);
    assert_eq!(auto.best.params.family, Family::Surface);
}

fn write_sweep(dir: &Path) -> std::path::PathBuf {
    let mut all = Vec::new();
    for (i, (name, family)) in [
        ("alpha", Family::Surface),
        ("beta", Family::Volume),
        ("gamma, \"q\"", Family::Surface),
    ]
    .into_iter()
    .enumerate()
    {
        all.extend(synthetic::samples(
            name,
            &size_truth(family),
            &quality_truth(family),
            &GRIDS,
            &PATCHES,
            Noise {
                size_rel: 0.01,
                ssim_abs: 0.002,
            },
            i as u64,
        ));
    }
    let path = dir.join("sweep.csv");
    samples::write(&path, &all).unwrap();
    path
}

#[test]
fn fit_command_writes_profiles_plan_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write_sweep(dir.path());
    let out = dir.path().join("profiles.json");
    let args = FitArgs {
        samples: csv.clone(),
        objects: vec![],
        out: out.clone(),
        family: FamilyChoice::Auto,
        grid: vec![],
        patch: vec![],
    };
    let text = fit_report(&args).unwrap();
    assert!(text.contains("alpha: 20 samples"), "{text}");
    assert!(text.contains("fitted 3 object(s)"), "{text}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let objs = json["objects"].as_array().unwrap();
    assert_eq!(objs.len(), 3);
    assert_eq!(objs[0]["profile"]["g"], serde_json::json!(GRIDS));
    assert_eq!(objs[0]["profile"]["p"], serde_json::json!(PATCHES));
    assert_eq!(objs[0]["profile"]["size"]["g_power"], 2);
    assert_eq!(objs[1]["profile"]["size"]["g_power"], 3);
    assert!(objs[0]["fit"]["quality"]["rmse_ssim"].as_f64().unwrap() < 0.004);

    // The planner's scene loader accepts the file and evaluates every
    // configuration exactly as the fixed-point profiler does.
    let scene = nerflex_sim::scene_file::load(&out).unwrap();
    assert_eq!(scene.objects.len(), 3);
    assert_eq!(scene.objects[2].name, "gamma, \"q\"");
    let fits =
        fit::fit_objects(&samples::read(&csv).unwrap(), &[], None, FamilyChoice::Auto).unwrap();
    for (obj, f) in scene.objects.iter().zip(&fits) {
        assert_eq!(obj.configs.len(), 20);
        let prof = f.profile().unwrap();
        for c in &obj.configs {
            let want = prof.config(c.g, c.p).unwrap();
            assert_eq!(c.size, want.size, "{} ({}, {})", obj.name, c.g, c.p);
            assert_eq!(c.quality, want.quality.to_f64());
        }
    }

    // Only one object, with an explicit configuration space.
    let args = FitArgs {
        objects: vec!["beta".into()],
        grid: vec![16, 24, 32, 48, 64, 96, 128, 192, 256],
        patch: vec![5, 7, 9, 11, 13, 15, 17],
        ..args
    };
    fit_report(&args).unwrap();
    let scene = nerflex_sim::scene_file::load(&out).unwrap();
    assert_eq!(scene.objects.len(), 1);
    assert_eq!(scene.objects[0].configs.len(), 63);

    // Errors: unknown object, bad CSV line.
    let bad = FitArgs {
        objects: vec!["nope".into()],
        ..args.clone()
    };
    let e = format!("{:#}", fit_report(&bad).unwrap_err());
    assert!(e.contains("object \"nope\" is not in the samples"), "{e}");
    let broken = dir.path().join("broken.csv");
    let mut text = std::fs::read_to_string(&csv).unwrap();
    text.push_str("alpha,16,5,12,,,not-a-number,,\n");
    std::fs::write(&broken, text).unwrap();
    let e = format!(
        "{:#}",
        fit_report(&FitArgs {
            samples: broken.clone(),
            ..args
        })
        .unwrap_err()
    );
    assert!(
        e.contains("broken.csv:62: ssim: expected a number, got \"not-a-number\""),
        "{e}"
    );
}

#[test]
fn accuracy_command_prints_table_and_draws() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write_sweep(dir.path());
    let plots = dir.path().join("plots");
    let text = accuracy_report(&AccuracyArgs {
        samples: csv.clone(),
        objects: vec![],
        family: FamilyChoice::Auto,
        train_on: TrainOn::LeaveOneOut,
        step: Step::Triple,
        train_grid: vec![],
        train_patch: vec![],
        max_size_mb: None,
        max_g: None,
        plots: Some(plots.clone()),
        json: Some(dir.path().join("acc.json")),
    })
    .unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("acc.json")).unwrap())
            .unwrap();
    assert_eq!(json["points"].as_array().unwrap().len(), 60);
    assert_eq!(json["paper"]["ssim"]["mean"], 0.0065);
    assert!(text.contains("NeRFlex paper"), "{text}");
    assert!(text.contains("0.0065 ± 0.0088"), "{text}");
    // Errors relative to each curve's spread (a flat curve cannot look accurate).
    assert!(text.contains("SSIM/spread (%)"), "{text}");
    let rel = json["all"]["ssim_rel_spread"]["mean"].as_f64().unwrap();
    assert!(rel > 0.0 && rel.is_finite(), "{rel}");
    for name in ["alpha_ssim.png", "alpha_size.png", "gamma___q__size.png"] {
        let img = nerflex_sim::metrics::read_png(&plots.join(name)).unwrap();
        assert!(img.width() >= 400, "{name}");
    }
    // The leave-one-out errors reflect the noise (0.002 SSIM, 1 % size).
    let acc =
        accuracy::leave_one_out(&samples::read(&csv).unwrap(), &[], FamilyChoice::Auto).unwrap();
    assert_eq!(acc.points.len(), 60);
    assert!(acc.all.ssim.mean < 0.004, "{:?}", acc.all);
    assert!(acc.all.size_rel.mean < 0.03, "{:?}", acc.all);
    assert!(acc.all.ssim.mean > 0.0);
}

#[test]
fn accuracy_on_variable_step_points_and_restricted() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write_sweep(dir.path());
    let base = AccuracyArgs {
        samples: csv.clone(),
        objects: vec!["alpha".into()],
        family: FamilyChoice::Auto,
        train_on: TrainOn::VariableStep,
        step: Step::Triple,
        train_grid: vec![],
        train_patch: vec![],
        max_size_mb: None,
        max_g: None,
        plots: None,
        json: None,
    };
    // On g {16,…,256} × p {5,9,13,17} the rule takes g {16, 64, 256}
    // (each next one the first ≥ 3·g′) × p {5, 9, 17}: 9 of 20 samples.
    let text = accuracy_report(&base).unwrap();
    assert!(
        text.contains("trained on g {16, 64, 256} × p {5, 9, 17} only"),
        "{text}"
    );
    let all = samples::read(&csv).unwrap();
    let acc = accuracy::train_subset(
        &all,
        &["alpha".into()],
        FamilyChoice::Auto,
        &[16, 64, 256],
        &[5, 9, 17],
    )
    .unwrap();
    assert_eq!(acc.objects[0].trained_on, 9);
    assert_eq!(acc.points.len(), 11);
    assert!(acc
        .points
        .iter()
        .all(|p| !([16, 64, 256].contains(&p.g) && [5, 9, 17].contains(&p.p))));
    // Nine noisy points still predict the rest within the noise's scale.
    assert!(acc.all.ssim.mean < 0.006, "{:?}", acc.all);
    assert!(acc.all.size_rel.mean < 0.05, "{:?}", acc.all);

    // Restricting the summary keeps the fits and drops points.
    let small = acc.restricted("g ≤ 64", |p| p.g <= 64);
    assert_eq!(
        small.points.len(),
        acc.points.iter().filter(|p| p.g <= 64).count()
    );
    assert_eq!(small.unrestricted, 11);
    assert_eq!(small.objects[0].fit, acc.objects[0].fit);
    let text = accuracy_report(&AccuracyArgs {
        train_on: TrainOn::LeaveOneOut,
        max_size_mb: Some(10.0),
        ..base.clone()
    })
    .unwrap();
    let kept = all
        .iter()
        .filter(|s| s.object == "alpha" && s.size.0 <= 10_000_000)
        .count();
    assert!(
        text.contains(&format!("measured size ≤ 10 MB: {kept} of 20")),
        "{text}"
    );

    // Explicit training lists; conflicting or bad flags are clear errors.
    let text = accuracy_report(&AccuracyArgs {
        train_on: TrainOn::LeaveOneOut,
        train_patch: vec![5, 17],
        ..base.clone()
    })
    .unwrap();
    assert!(
        text.contains("trained on g {16, 32, 64, 128, 256} × p {5, 17}"),
        "{text}"
    );
    let e = accuracy_report(&AccuracyArgs {
        train_grid: vec![16],
        ..base.clone()
    })
    .unwrap_err();
    assert!(format!("{e:#}").contains("give one or the other"), "{e:#}");
    let e = accuracy_report(&AccuracyArgs {
        train_on: TrainOn::LeaveOneOut,
        train_grid: vec![16, 32],
        train_patch: vec![5],
        ..base.clone()
    })
    .unwrap_err();
    assert!(
        format!("{e:#}").contains("need at least 4 samples"),
        "{e:#}"
    );
    let e = accuracy_report(&AccuracyArgs {
        max_size_mb: Some(-1.0),
        ..base
    })
    .unwrap_err();
    assert!(format!("{e:#}").contains("--max-size-mb"), "{e:#}");
}

#[test]
fn samples_command_prints_the_plan() {
    let text = samples_report(&SamplesArgs {
        g_range: "16..512".parse().unwrap(),
        p_range: "3..33".parse().unwrap(),
        step: Step::Triple,
        csv: false,
    })
    .unwrap();
    assert!(text.contains("12 sample points"), "{text}");
    assert!(
        text.contains("--sweep --grid 16,48,144,432 --patch 3,18,33"),
        "{text}"
    );
    let csv = samples_report(&SamplesArgs {
        g_range: "16..512".parse().unwrap(),
        p_range: "3..33".parse().unwrap(),
        step: Step::Double,
        csv: true,
    })
    .unwrap();
    assert_eq!(csv.lines().count(), 1 + 6 * 3);
    assert!(csv.starts_with("g,p\n16,3\n16,18\n16,33\n32,3\n"), "{csv}");
}
