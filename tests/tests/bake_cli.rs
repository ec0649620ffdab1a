//! `nerflex bake` end to end on a tiny built-in two-object capture (6 views
//! at 96 px, draft quality): one bake with --measure, a sweep with plots,
//! and errors that name the flag or file.

use std::path::{Path, PathBuf};

use nerflex_sim::asset::Asset;
use nerflex_sim::bake::carve::VoxelTest;
use nerflex_sim::bake::{sweep, Geometry};
use nerflex_sim::cli::bake::{run, Args, Reports};
use nerflex_sim::procedural::ObjectKind;

fn capture(dir: &Path) -> PathBuf {
    let kinds = [ObjectKind::Pawn, ObjectKind::Ball];
    nerflex_tests::small_capture(dir, "two", &kinds, 1, (6, 2), 96)
}

fn args(capture: &Path) -> Args {
    Args {
        capture: vec![capture.to_path_buf()],
        object: vec![],
        grid: vec![12],
        patch: vec![5],
        configs: vec![],
        out: None,
        measure: false,
        renders: None,
        renders_size: None,
        sweep: false,
        csv: PathBuf::from("unused.csv"),
        plots: None,
        cache: None,
        no_cache: false,
        jobs: 1,
        max_views: None,
        max_test_views: None,
        frontal_power: 1.0,
        voxel_test: VoxelTest::Centre,
        geometry: Geometry::Shell,
        reports: Box::new(Reports {
            table_configs: vec![(8, 3), (12, 5)],
            ..Reports::default()
        }),
        trained: Default::default(),
        lpips_weights: Some(PathBuf::from("/nonexistent/lpips.safetensors")),
    }
}

#[test]
fn bake_one_object_writes_a_loadable_asset_and_measures_it() {
    let tmp = tempfile::tempdir().unwrap();
    let cap = capture(tmp.path());
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    a.out = Some(tmp.path().join("ball"));
    a.renders = Some(tmp.path().join("renders"));
    a.renders_size = Some(48);
    a.measure = true;
    a.lpips_weights = None; // default location; skipped if absent
    run(a).unwrap();
    let asset = Asset::load(&tmp.path().join("ball")).unwrap();
    assert!(asset.report().quads > 50);
    assert!(tmp.path().join("renders/test_0.png").is_file());
    assert!(tmp.path().join("renders/test_1.png").is_file());
    let truth = image::open(tmp.path().join("renders/truth_1.png")).unwrap();
    assert_eq!((truth.width(), truth.height()), (48, 48));
}

#[test]
fn sweep_writes_csv_and_plots_then_reuses_the_cache() {
    let tmp = tempfile::tempdir().unwrap();
    let cap = capture(tmp.path());
    let mut a = args(&cap);
    a.sweep = true;
    a.object = vec!["pawn".into(), "ball".into()];
    a.grid = vec![];
    a.patch = vec![];
    a.configs = vec![(8, 3), (8, 5), (12, 3), (12, 5)];
    a.csv = tmp.path().join("out/samples.csv");
    a.cache = Some(tmp.path().join("cache"));
    a.plots = Some(tmp.path().join("plots"));
    a.reports.table = Some(tmp.path().join("out/table.md"));
    a.lpips_weights = None;
    run(a).unwrap();
    let table = std::fs::read_to_string(tmp.path().join("out/table.md")).unwrap();
    assert_eq!(table.lines().count(), 2 + 4, "{table}");
    assert!(table.contains("| pawn | 12 | 5 |"), "{table}");
    let rows = sweep::read_csv(&tmp.path().join("out/samples.csv")).unwrap();
    assert_eq!(rows.len(), 8);
    assert_eq!(rows[0].object, "pawn");
    assert!(tmp.path().join("plots/pawn.png").is_file());
    assert!(tmp.path().join("plots/ball.png").is_file());
    let cached = std::fs::read_dir(tmp.path().join("cache")).unwrap().count();
    assert_eq!(cached, 8);
}

#[test]
fn compare_draws_truth_and_each_bake_side_by_side() {
    let tmp = tempfile::tempdir().unwrap();
    let cap = capture(tmp.path());
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    a.grid = vec![];
    a.patch = vec![];
    a.configs = vec![(12, 5), (4, 3)];
    a.reports.compare = Some(tmp.path().join("pics/cmp.png"));
    a.reports.view = 1;
    a.renders_size = Some(48);
    a.lpips_weights = None;
    run(a).unwrap();
    let pic = image::open(tmp.path().join("pics/cmp.png")).unwrap();
    // Three tiles no wider than 48 px each, side by side, with captions.
    assert!(
        pic.width() > 3 * 20 && pic.width() <= 4 * 8 + 3 * 48,
        "{}",
        pic.width()
    );
    assert!(pic.height() > 48 / 2, "{}", pic.height());
    // A view that does not exist.
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    a.configs = vec![(12, 5)];
    a.reports.compare = Some(tmp.path().join("pics/cmp2.png"));
    a.reports.view = 7;
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("--view 7"), "{e}");
}

#[test]
fn errors_name_the_flag_or_file() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nothing-here");
    let mut a = args(&missing);
    a.measure = true;
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("nothing-here"), "{e}");

    let cap = capture(tmp.path());
    // Two objects, none chosen.
    let mut a = args(&cap);
    a.measure = true;
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(
        e.contains("--object") && e.contains("pawn") && e.contains("ball"),
        "{e}"
    );
    // An unknown object.
    let mut a = args(&cap);
    a.measure = true;
    a.object = vec!["teapot".into()];
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("teapot") && e.contains("scene.json"), "{e}");
    // Lists without --sweep.
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    a.grid = vec![8, 16];
    a.measure = true;
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("--sweep"), "{e}");
    // Nothing to do.
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("--out") && e.contains("--measure"), "{e}");
    // A bad grid.
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    a.grid = vec![0];
    a.out = Some(tmp.path().join("x"));
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("--grid 0"), "{e}");
    // LPIPS weights that do not exist.
    let mut a = args(&cap);
    a.object = vec!["ball".into()];
    a.measure = true;
    let e = format!("{:#}", run(a).unwrap_err());
    assert!(e.contains("lpips.safetensors"), "{e}");
}
