//! The bake geometry inside the pipeline (`nerflex run`, `nerflex eval`,
//! `nerflex simulate`): the bake store keys a planes bake exactly as before
//! the geometry was part of a request and a mesh bake apart from it; a plan
//! with one object as mesh realises with a real mesh export, and its run's
//! files feed `nerflex simulate`; the hull baker refuses a mesh by name.
//! Tiny captures (24–48 px) and a few seconds of training.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use nerflex_sim::asset::Asset;
use nerflex_sim::bake::sweep::{Cache, Fnv64, ObjectViews};
use nerflex_sim::bake::trained::TRAINED_BAKER_VERSION;
use nerflex_sim::bake::BakeParams;
use nerflex_sim::baselines::Method;
use nerflex_sim::capture::Capture;
use nerflex_sim::device::Device;
use nerflex_sim::geometry::Geometry;
use nerflex_sim::pipeline::{
    self, BakeRequest, BakeStore, Baker, FieldStore, Geometries, Input, Options, Quiet,
};
use nerflex_sim::procedural::ObjectKind;
use nerflex_sim::simulate::TurntableSpec;

use nerflex_tests::tiny_baker;

fn views_of(dir: &Path, kinds: &[ObjectKind], size: u32, train: usize) -> ObjectViews {
    let cap = nerflex_tests::small_capture(dir, "capture", kinds, 5, (train, 2), size);
    ObjectViews::from_capture(&Capture::load(cap).unwrap(), None).unwrap()
}

/// The trained store's key of a planes bake as `BakeStore::key` formed it
/// before requests carried a geometry (the formula, copied).
fn key_before_geometry(views: &ObjectViews, baker: &Baker, g: u32, p: u32) -> String {
    let Baker::Trained(t) = baker else {
        unreachable!()
    };
    let key = Cache::key(views, &BakeParams::new(g, p), false);
    let mut params = t.bake.clone();
    params.grid = g;
    params.patch = p;
    let mut h = Fnv64::default();
    h.write(key.as_bytes());
    h.write(
        format!(
            "trained v{TRAINED_BAKER_VERSION} field {} {params:?}",
            FieldStore::key(views, &t.train)
        )
        .as_bytes(),
    );
    format!("{}-g{g}-p{p}-t{:016x}", views.name, h.finish())
}

#[test]
fn a_planes_key_is_unchanged_and_a_mesh_key_is_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let views = views_of(dir.path(), &[ObjectKind::Ball], 24, 3);
    let root = dir.path().join("bakes");
    let hull = BakeStore::new(&root);
    let trained = BakeStore::with_baker(&root, tiny_baker());

    // Planes with a fixed lattice: byte for byte the keys (and so the
    // folders) of before; a chosen lattice (the default since session 37)
    // adds to them.
    let Baker::Trained(t0) = tiny_baker() else {
        unreachable!()
    };
    let fixed = Baker::trained_fixed_lattice(t0.train.clone(), t0.bake.clone());
    let fixed_planes =
        BakeStore::with_baker(&root, fixed.clone()).key_of(&views, 16, 5, Geometry::Planes, false);
    assert_eq!(fixed_planes, key_before_geometry(&views, &fixed, 16, 5));
    let planes = trained.key_of(&views, 16, 5, Geometry::Planes, false);
    assert_ne!(planes, fixed_planes);
    assert_eq!(planes, trained.key(&views, 16, 5, false));
    let hull_planes = hull.key_of(&views, 16, 5, Geometry::Planes, false);
    assert_eq!(
        hull_planes,
        Cache::key(&views, &BakeParams::new(16, 5), false)
    );

    // Mesh: its own key, naming the geometry, following (g, p) and LPIPS.
    let mesh = trained.key_of(&views, 16, 5, Geometry::Mesh, false);
    assert!(mesh.starts_with("ball-g16-p5-mesh-t"), "{mesh}");
    let keys = [
        planes.clone(),
        hull_planes,
        mesh.clone(),
        trained.key_of(&views, 16, 7, Geometry::Mesh, false),
        trained.key_of(&views, 16, 5, Geometry::Mesh, true),
        hull.key_of(&views, 16, 5, Geometry::Mesh, false),
    ];
    let distinct: HashSet<&String> = keys.iter().collect();
    assert_eq!(distinct.len(), keys.len(), "{keys:#?}");
    // The mesh's key follows the store's settings (another fine-tune) ...
    let Baker::Trained(t) = tiny_baker() else {
        unreachable!()
    };
    let mut bake = t.bake.clone();
    bake.finetune.epochs = 2.0;
    let other = BakeStore::with_baker(&root, Baker::trained(t.train.clone(), bake.clone()));
    assert_ne!(other.key_of(&views, 16, 5, Geometry::Mesh, false), mesh);
    // ... but not the planes' visibility rounds: the mesh runs its own
    // default (none), as `nerflex bake --surface mesh` does.
    let mut rounds = t.bake.clone();
    rounds.visibility.rounds += 1;
    let rounds = BakeStore::with_baker(&root, Baker::trained(t.train.clone(), rounds));
    assert_ne!(rounds.key(&views, 16, 5, false), planes);
    assert_eq!(rounds.key_of(&views, 16, 5, Geometry::Mesh, false), mesh);
}

#[test]
fn the_hull_baker_refuses_a_mesh_request_by_name_and_bakes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let views = views_of(dir.path(), &[ObjectKind::Ball], 24, 3);
    let root = dir.path().join("bakes");
    let hull = BakeStore::new(&root);
    let expected = "cannot bake ball at g=16 p=5 as mesh: the hull baker bakes planes only; a mesh bake needs the trained baker (`--baker trained`)";
    // In a batch, a planes request first: nothing starts.
    let reqs = [
        BakeRequest::planes(&views, 8, 3),
        BakeRequest::new(&views, 16, 5, Geometry::Mesh),
    ];
    let label = |i: usize| format!("bake {i}");
    let e = hull
        .get_or_bake_many(&reqs, None, &Quiet, &label)
        .unwrap_err();
    assert_eq!(format!("{e:#}"), expected);
    // One request alone.
    let e = hull.get_or_bake(&reqs[1], None).unwrap_err();
    assert_eq!(format!("{e:#}"), expected);
    assert!(!root.exists(), "the hull baked something");

    // The trained baker checks a mesh request's settings before training
    // its field: above the mesh's largest grid is an error, not a panic.
    let trained = BakeStore::with_baker(&root, tiny_baker());
    let big = [BakeRequest::new(&views, 600, 5, Geometry::Mesh)];
    let e = trained
        .get_or_bake_many(&big, None, &Quiet, &label)
        .unwrap_err();
    let e = format!("{e:#}");
    assert!(
        e.starts_with("baking ball at g=600 p=5 as mesh: ") && e.contains("above 512"),
        "{e}"
    );
    assert!(!root.exists(), "a field was trained for a bad request");
}

/// The fraction of an asset's quad corners whose position is another
/// corner's too: most on a mesh (neighbouring quads share their corners;
/// 0.83 on the ball below, the rest on the edges of what the views show),
/// none on the planes (each voxel's quads are its own, grown against
/// cracks).
fn shared_corners(a: &Asset) -> f64 {
    let mut count: HashMap<[u32; 3], usize> = HashMap::new();
    for q in a.shapes.iter().flat_map(|s| &s.quads) {
        let n = if q.single_triangle { 3 } else { 4 };
        for c in &q.corners[..n] {
            *count.entry(c.pos.map(f32::to_bits)).or_default() += 1;
        }
    }
    let all: usize = count.values().sum();
    let shared: usize = count.values().filter(|&&n| n > 1).sum();
    shared as f64 / all.max(1) as f64
}

fn tiny_options(store: &Path, baker: Baker) -> Options {
    let mut o = nerflex_tests::tiny_pipeline(store.to_path_buf(), 2);
    o.baker = baker;
    o.train_views = 8;
    nerflex_tests::tiny_simulation(&mut o, 6, 40, 100);
    o
}

/// The two-object capture of the pipeline tests: 8 training and 2
/// held-out views at 48 px.
fn ball_and_box(dir: &Path) -> std::path::PathBuf {
    nerflex_tests::small_capture(
        dir,
        "capture",
        &[ObjectKind::Ball, ObjectKind::Box],
        5,
        (8, 2),
        48,
    )
}

#[test]
fn a_plan_with_one_mesh_object_realises_it_as_a_mesh_export() {
    let dir = tempfile::tempdir().unwrap();
    let cap = ball_and_box(dir.path());
    let store = dir.path().join("bakes");
    // The profiler's samples from the hull (fast); the plan's bakes from
    // the trained baker, or the hull to see it refuse.
    let hull = tiny_options(&store, Baker::Hull);
    let trained = tiny_options(&store, tiny_baker());
    let out = dir.path().join("run");
    let input = Input::Capture(cap);
    let prepared = pipeline::prepare(&input, &hull, &out, None, &Quiet).unwrap();
    let device = Device::builtin("pixel4").unwrap();
    let (mut plan, _) = pipeline::plan_for(&prepared, Method::Dp, &device).unwrap();
    // At most two objects (two fields to train); the first as a mesh.
    plan.objects.truncate(2);
    let name = plan.objects[0].name.clone();
    (plan.objects[0].g, plan.objects[0].p) = (16, 4);
    plan.objects[0].geometry = Geometry::Mesh;

    let e = pipeline::realise(&prepared, &plan, &hull, None, &Quiet)
        .err()
        .expect("the hull baked a mesh");
    let e = format!("{e:#}");
    assert!(
        e.starts_with(&format!(
            "cannot bake {name} at g=16 p=4 as mesh: the hull baker"
        )),
        "{e}"
    );

    let realised = pipeline::realise(&prepared, &plan, &trained, None, &Quiet).unwrap();
    let r = &realised.objects[0];
    assert_eq!(
        (r.name.as_str(), r.g, r.p, r.geometry),
        (name.as_str(), 16, 4, Geometry::Mesh)
    );
    for (o, p) in realised.objects.iter().zip(&plan.objects).skip(1) {
        assert_eq!(o.geometry, p.geometry);
        assert_eq!(o.geometry, Geometry::Planes);
    }
    // Its store entry is the mesh's, and the trained baker says so.
    let entry = r.asset.parent().unwrap();
    let entry_name = entry.file_name().unwrap().to_str().unwrap();
    assert!(
        entry_name.starts_with(&format!("{name}-g16-p4-mesh-t")),
        "{entry_name}"
    );
    let details: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(entry.join("bake.json")).unwrap()).unwrap();
    assert_eq!(
        (&details["baker"], &details["geometry"]),
        (&"trained".into(), &"mesh".into())
    );

    // The planes bake of the same network at the same (g, p), from the
    // same store: another entry, another export.
    let views = &prepared
        .networks
        .iter()
        .find(|n| n.name == name)
        .unwrap()
        .views;
    let store_t = trained.bake_store();
    let planes = store_t
        .get_or_bake(&BakeRequest::planes(views, 16, 4), None)
        .unwrap();
    assert_eq!(
        planes.dir.parent().unwrap(),
        store.join(store_t.key(views, 16, 4, false))
    );
    assert_ne!(planes.dir, r.asset);
    let mesh_asset = Asset::load(&r.asset).unwrap();
    let planes_asset = Asset::load(&planes.dir).unwrap();
    let quads = |a: &Asset| a.shapes.iter().map(|s| s.quads.len() as u64).sum::<u64>();
    assert_ne!(quads(&mesh_asset), quads(&planes_asset));
    let (ms, ps) = (shared_corners(&mesh_asset), shared_corners(&planes_asset));
    assert!(
        ms > 0.5 && ps < 0.1,
        "shared corners: mesh {ms:.3}, planes {ps:.3}"
    );
    // Everything the reports and the simulation count is the export's.
    assert_eq!(r.file_bytes, mesh_asset.file_bytes);
    assert_eq!(r.quads, quads(&mesh_asset));

    // The run's files: the report names the geometry, the asset link has
    // the mesh's folder, and `nerflex simulate` loads the plan from them.
    let sim = pipeline::simulate_on(&realised, &device, &trained).unwrap();
    assert_eq!(sim.data_bytes, realised.file_bytes());
    let run = pipeline::RunResult {
        label: prepared.label.clone(),
        device: device.name.clone(),
        plan: plan.clone(),
        plan_s: 0.0,
        replans: 0,
        realised,
        simulation: sim,
        timings: prepared.timings,
        networks: vec![],
        sample_bakes: (0, 0),
        scene_json: prepared.scene_json.clone(),
        baker: trained.baker.name().to_string(),
        objective: trained.objective.name().to_string(),
        times: pipeline::RunTimes::default(),
        ranges: vec![],
        lattices: Vec::new(),
    };
    let text = run.report_text(1.0, false);
    assert!(text.contains("SSIM  geometry"), "{text}");
    assert!(
        text.lines()
            .any(|l| l.trim_start().starts_with(&name) && l.ends_with("  mesh")),
        "{text}"
    );
    run.write(&out).unwrap();
    let link = out.join("assets").join(&name).join("g16_p4_mesh");
    assert_eq!(
        std::fs::canonicalize(&link).unwrap(),
        std::fs::canonicalize(&run.realised.objects[0].asset).unwrap()
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["objects"][0]["geometry"], "mesh");
    assert!(report["objects"][1].get("geometry").is_none());
    let csv = out.join("fps.csv");
    nerflex_sim::cli::simulate::run(nerflex_sim::cli::simulate::Args {
        scene: out.join("scene.json"),
        plan: Some(out.join("plan.json")),
        method: None,
        device: "pixel4".into(),
        assets: None,
        frames: 50,
        period_s: 7.5,
        angles: 4,
        coverage_px: 40,
        elevation_deg: 30.0,
        distance: TurntableSpec::DEFAULT.distance,
        plot: None,
        csv: Some(csv.clone()),
        json: false,
    })
    .unwrap();
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 51);
}

/// `--geometry both`: the profiler bakes every sample point as planes (the
/// same store entries as a planes-only run, found there) and as mesh (its
/// own entries), fits both profiles per object, and the planner plans over
/// the union of their configurations.
#[test]
fn geometry_both_profiles_the_mesh_and_plans_over_the_union() {
    let dir = tempfile::tempdir().unwrap();
    let cap = ball_and_box(dir.path());
    let store = dir.path().join("bakes");
    let input = Input::Capture(cap);
    let planes_opts = tiny_options(&store, tiny_baker());
    assert_eq!(planes_opts.geometries, Geometries::Planes);
    let planes =
        pipeline::prepare(&input, &planes_opts, &dir.path().join("a"), None, &Quiet).unwrap();
    assert!(planes.mesh_samples.is_empty());
    assert!(planes
        .scene
        .objects
        .iter()
        .all(|o| o.mesh_profile.is_none()
            && o.configs.iter().all(|c| c.geometry == Geometry::Planes)));

    let mut both_opts = tiny_options(&store, tiny_baker());
    both_opts.geometries = Geometries::Both;
    let both = pipeline::prepare(&input, &both_opts, &dir.path().join("b"), None, &Quiet).unwrap();
    // The planes samples: the planes-only run's entries, from the store.
    let dirs = |v: &[pipeline::Baked]| v.iter().map(|b| b.dir.clone()).collect::<Vec<_>>();
    assert_eq!(dirs(&both.samples), dirs(&planes.samples));
    assert!(both.samples.iter().all(|b| b.cached));
    // The mesh samples: the same points, each a mesh entry of the store.
    let n = both.networks.len();
    assert_eq!(both.mesh_samples.len(), both.samples.len());
    assert_eq!(both.mesh_samples.len() % n, 0);
    let bake_store = both_opts.bake_store();
    for (m, p) in both.mesh_samples.iter().zip(&both.samples) {
        assert_eq!(
            (&m.sample.object, m.sample.g, m.sample.p),
            (&p.sample.object, p.sample.g, p.sample.p)
        );
        assert!(!m.cached);
        let views = &both
            .networks
            .iter()
            .find(|n| n.name == m.sample.object)
            .unwrap()
            .views;
        let key = bake_store.key_of(views, m.sample.g, m.sample.p, Geometry::Mesh, false);
        assert!(key.contains("-mesh-t"), "{key}");
        let entry = m.dir.parent().unwrap();
        assert_eq!(entry, store.join(&key));
        let details: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(entry.join("bake.json")).unwrap())
                .unwrap();
        assert_eq!(details["geometry"], "mesh");
    }
    // Both profiles per object; planes' exactly the planes-only run's.
    assert_eq!(both.scene.objects.len(), planes.scene.objects.len());
    for (o, po) in both.scene.objects.iter().zip(&planes.scene.objects) {
        assert_eq!(o.name, po.name);
        assert_eq!(o.profile, po.profile);
        assert!(o.mesh_profile.is_some(), "{}: no mesh profile", o.name);
        let (pl, me): (Vec<_>, Vec<_>) = o
            .configs
            .iter()
            .partition(|c| c.geometry == Geometry::Planes);
        assert_eq!(pl.into_iter().copied().collect::<Vec<_>>(), po.configs);
        assert_eq!(me.len(), po.configs.len(), "{}", o.name);
    }
    // `scene.json` is the same scene, in the two-profile form, with both fits.
    let o0 = &both.scene_json["objects"][0];
    assert!(o0["profiles"]["mesh"].is_object(), "{o0}");
    assert!(o0["fit"]["mesh"]["samples"].as_u64().unwrap() > 0, "{o0}");
    let reread =
        nerflex_sim::scene_file::parse(&both.scene_json.to_string(), "scene.json").unwrap();
    assert_eq!(reread.objects, both.scene.objects);

    // The plan draws from the union: every choice one of its object's
    // configurations (planes or mesh).
    let device = Device::builtin("pixel4").unwrap();
    let (plan, _) = pipeline::plan_for(&both, Method::Dp, &device).unwrap();
    for o in &plan.objects {
        let so = both
            .scene
            .objects
            .iter()
            .find(|s| s.name == o.name)
            .unwrap();
        assert!(
            so.configs
                .iter()
                .any(|c| (c.g, c.p, c.geometry) == (o.g, o.p, o.geometry)),
            "{}: ({}, {}, {}) not among its configurations",
            o.name,
            o.g,
            o.p,
            o.geometry
        );
    }
    // Mesh only (the planes' configurations removed): the planner's
    // choices are the mesh's, so the union really holds them.
    let mut mesh_only = both.scene.clone();
    for o in &mut mesh_only.objects {
        o.configs.retain(|c| c.geometry == Geometry::Mesh);
    }
    let p = nerflex_sim::baselines::plan(
        Method::Dp,
        &mesh_only,
        nerflex_sim::baselines::Budget::new(device.budget()),
    )
    .unwrap();
    assert!(p.objects.iter().all(|o| o.geometry == Geometry::Mesh));
    // ... and such a plan realises as mesh bakes, as any mesh plan does.
    let realised = pipeline::realise(&both, &p, &both_opts, None, &Quiet).unwrap();
    assert!(realised
        .objects
        .iter()
        .all(|o| o.geometry == Geometry::Mesh && o.asset.to_string_lossy().contains("-mesh-t")));
}

/// `--geometry both` with the hull baker: refused before anything is
/// written, by `nerflex run` (naming both flags) and by the pipeline.
#[test]
fn geometry_both_with_the_hull_is_refused_and_writes_nothing() {
    use clap::Parser as _;
    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        run: nerflex_sim::cli::run::Args,
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let store = dir.path().join("store");
    let cli = Cli::try_parse_from([
        "x",
        "--preset",
        "scene4",
        "--device",
        "pixel4",
        "--baker",
        "hull",
        "--geometry",
        "both",
        "--quiet",
        "--no-lpips",
        "--out",
        out.to_str().unwrap(),
        "--store",
        store.to_str().unwrap(),
    ])
    .unwrap();
    let e = nerflex_sim::cli::run::run(cli.run).unwrap_err();
    let e = format!("{e:#}");
    assert!(
        e.contains("--geometry both") && e.contains("--baker hull"),
        "{e}"
    );
    assert!(!out.exists() && !store.exists(), "something was written");

    // The pipeline itself refuses before the capture or segmentation.
    let cap =
        nerflex_tests::small_capture(dir.path(), "capture", &[ObjectKind::Ball], 5, (3, 1), 24);
    let mut opts = tiny_options(&store, Baker::Hull);
    opts.geometries = Geometries::Both;
    let e = pipeline::prepare(&Input::Capture(cap), &opts, &out, None, &Quiet)
        .err()
        .expect("the hull profiled a mesh");
    assert!(format!("{e:#}").contains("--geometry both"), "{e:#}");
    assert!(!out.exists() && !store.exists(), "something was written");
}
