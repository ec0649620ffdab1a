//! The trained pipeline inside `nerflex run` / `nerflex eval` (issue 16):
//! the field store trains a field once and then loads it; the bake store's
//! keys keep hull and trained bakes (and different training settings)
//! apart; a whole run on a tiny two-object capture with the trained baker
//! produces assets, a report naming the trained baker and the time split,
//! and a second run trains and bakes nothing.

use std::path::{Path, PathBuf};

use nerflex_sim::bake::sweep::ObjectViews;
use nerflex_sim::baselines::Method;
use nerflex_sim::capture::Capture;
use nerflex_sim::device::Device;
use nerflex_sim::pipeline::{self, BakeStore, Baker, FieldStore, Input, Options, Quiet};
use nerflex_sim::procedural::ObjectKind;

/// A capture of `kinds` at `size` px with `views` + 2 held-out views.
fn capture(dir: &Path, kinds: &[ObjectKind], size: u32, views: usize) -> PathBuf {
    nerflex_tests::small_capture(dir, "capture", kinds, 5, (views, 2), size)
}

use nerflex_tests::{tiny_baker, tiny_training};

#[test]
fn the_field_store_trains_once_then_loads() {
    let dir = tempfile::tempdir().unwrap();
    let cap = Capture::load(capture(dir.path(), &[ObjectKind::Mug], 32, 8)).unwrap();
    let views = ObjectViews::from_capture(&cap, None).unwrap();
    let store = FieldStore::new(dir.path().join("fields"));
    let settings = tiny_training(30);
    assert!(!store.contains(&views, &settings));

    let calls = std::sync::atomic::AtomicUsize::new(0);
    let count = |_: usize, _: u32, _: u32, _: f64| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    };
    let first = store.get_or_train(&views, &settings, &count).unwrap();
    assert!(first.trained_now && first.train_s > 0.0);
    assert!(first.path.is_file() && store.contains(&views, &settings));
    let trained_calls = calls.load(std::sync::atomic::Ordering::Relaxed);
    assert!(trained_calls > 0, "the trainer reported no progress");
    let written = std::fs::metadata(&first.path).unwrap().modified().unwrap();

    // The second request loads the stored file: no training step, the same
    // grid, the file untouched.
    let second = store.get_or_train(&views, &settings, &count).unwrap();
    assert!(!second.trained_now);
    assert_eq!(second.train_s, 0.0);
    assert_eq!(
        calls.load(std::sync::atomic::Ordering::Relaxed),
        trained_calls
    );
    assert_eq!(*second.grid, *first.grid);
    assert_eq!(second.key, first.key);
    assert_eq!(
        std::fs::metadata(&first.path).unwrap().modified().unwrap(),
        written
    );

    // Other settings are another field.
    let other = tiny_training(31);
    assert_ne!(
        FieldStore::key(&views, &other),
        FieldStore::key(&views, &settings)
    );
    assert!(!store.contains(&views, &other));

    // A damaged file is trained again and replaced, not trusted.
    std::fs::write(&first.path, b"not a field").unwrap();
    let third = store.get_or_train(&views, &settings, &count).unwrap();
    assert!(third.trained_now);
    assert!(nerflex_sim::train::io::load(&first.path).is_ok());
}

#[test]
fn hull_and_trained_bakes_never_share_a_key() {
    let dir = tempfile::tempdir().unwrap();
    let cap = Capture::load(capture(dir.path(), &[ObjectKind::Ball], 24, 3)).unwrap();
    let views = ObjectViews::from_capture(&cap, None).unwrap();
    let root = dir.path().join("bakes");
    let hull = BakeStore::new(&root);
    let trained = BakeStore::with_baker(&root, tiny_baker());
    assert_eq!(hull.baker(), "hull");
    assert_eq!(trained.baker(), "trained");
    let (kh, kt) = (
        hull.key(&views, 16, 5, false),
        trained.key(&views, 16, 5, false),
    );
    assert_ne!(kh, kt);
    assert!(kt.starts_with("ball-g16-p5-t"), "{kt}");
    // The trained key follows the field's settings and the bake's.
    let Baker::Trained(t) = tiny_baker() else {
        unreachable!()
    };
    let other_field =
        BakeStore::with_baker(&root, Baker::trained(tiny_training(41), t.bake.clone()));
    let mut bake = t.bake.clone();
    bake.finetune.epochs = 2.0;
    let other_bake = BakeStore::with_baker(&root, Baker::trained(t.train.clone(), bake));
    let keys = [
        kt.clone(),
        other_field.key(&views, 16, 5, false),
        other_bake.key(&views, 16, 5, false),
        trained.key(&views, 16, 7, false),
        trained.key(&views, 16, 5, true),
    ];
    for (i, a) in keys.iter().enumerate() {
        for b in &keys[i + 1..] {
            assert_ne!(a, b);
        }
    }
    // The hull key is the bake sweep's, as before this change.
    assert_eq!(
        kh,
        nerflex_sim::bake::sweep::Cache::key(
            &views,
            &nerflex_sim::bake::BakeParams::new(16, 5),
            false
        )
    );
}

#[test]
fn the_store_chooses_each_objects_lattice_once_and_bakes_with_it() {
    use nerflex_sim::bake::trained::lattice_choice;
    use nerflex_sim::pipeline::{BakeRequest, TrainedBaker};
    let dir = tempfile::tempdir().unwrap();
    let cap = Capture::load(capture(dir.path(), &[ObjectKind::Ball], 32, 8)).unwrap();
    let views = ObjectViews::from_capture(&cap, None).unwrap();
    let root = dir.path().join("bakes");
    let Baker::Trained(t) = tiny_baker() else {
        unreachable!()
    };
    // The default chooses at the sweep's (64, 9); the test at (16, 3).
    assert_eq!(
        BakeStore::with_baker(&root, tiny_baker()).lattice_choice_at(),
        Some(lattice_choice::SWEEP_CONFIG)
    );
    let chooser = |at| {
        BakeStore::with_baker(
            &root,
            Baker::Trained(Box::new(TrainedBaker {
                choose_lattice_at: Some(at),
                ..(*t).clone()
            })),
        )
    };
    let chosen = chooser((16, 3));
    let fixed = BakeStore::with_baker(
        &root,
        Baker::trained_fixed_lattice(t.train.clone(), t.bake.clone()),
    );
    assert_eq!(fixed.lattice_choice_at(), None);
    assert!(fixed.lattice(&views, &Quiet).unwrap().is_none());
    // A chosen lattice is part of the key; where it is chosen too.
    let keys = [
        chosen.key(&views, 16, 5, false),
        fixed.key(&views, 16, 5, false),
        chooser((16, 5)).key(&views, 16, 5, false),
    ];
    assert_ne!(keys[0], keys[1]);
    assert_ne!(keys[0], keys[2]);

    let lattices = root.join("lattices");
    let count = || std::fs::read_dir(&lattices).map_or(0, |d| d.count());
    assert_eq!(count(), 0);
    let a = chosen
        .get_or_bake(&BakeRequest::planes(&views, 16, 5), None)
        .unwrap();
    assert_eq!(count(), 1, "one choice stored for the object");
    let l = chosen.lattice(&views, &Quiet).unwrap().unwrap();
    assert!(l.reused, "the stored choice is read, not made again");
    assert_eq!(l.object, "ball");
    // The finest candidate within the tie margin of the best held-back
    // SSIM (session 45).
    assert!(l.candidates.len() >= 2, "{:?}", l.candidates);
    let best = l.candidates.iter().map(|c| c.1).fold(f64::MIN, f64::max);
    let within = |c: &&(u32, f64, f64)| c.1 >= best - lattice_choice::TIE_SSIM;
    let finest = l.candidates.iter().filter(within).map(|c| c.0).max();
    assert_eq!(Some(l.cells), finest, "{:?}", l.candidates);
    // The bake used it, and says so.
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(a.dir.parent().unwrap().join("bake.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(json["lattice_res"].as_u64(), Some(u64::from(l.cells)));
    assert_eq!(
        json["lattice_choice"]["cells"].as_u64(),
        Some(u64::from(l.cells))
    );
    // Another (g, p) of the object reuses the choice.
    let b = chosen
        .get_or_bake(&BakeRequest::planes(&views, 32, 3), None)
        .unwrap();
    assert!(!b.cached);
    assert_eq!(count(), 1);
    // A store whose choice predates the tie rule (stored as another
    // candidate): its bakes were made at the stored cells, so the choice
    // read now keys bakes of its own and bakes anew.
    let file = std::fs::read_dir(&lattices)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let text = std::fs::read_to_string(&file).unwrap();
    let mut old: serde_json::Value = serde_json::from_str(&text).unwrap();
    let other = l
        .candidates
        .iter()
        .map(|c| c.0)
        .find(|&k| k != l.cells)
        .unwrap();
    old["cells"] = other.into();
    std::fs::write(&file, old.to_string()).unwrap();
    let redecided = chosen.lattice(&views, &Quiet).unwrap().unwrap();
    assert_eq!(
        (redecided.cells, redecided.stored_cells),
        (l.cells, Some(other))
    );
    assert_ne!(chosen.key(&views, 16, 5, false), keys[0]);
    let c = chosen
        .get_or_bake(&BakeRequest::planes(&views, 16, 5), None)
        .unwrap();
    assert!(!c.cached, "not the entry baked at the stored cells");
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(c.dir.parent().unwrap().join("bake.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(json["lattice_res"].as_u64(), Some(u64::from(l.cells)));
    // A choice stored as the rule reads it keeps the plain key.
    std::fs::write(&file, text).unwrap();
    assert_eq!(chosen.key(&views, 16, 5, false), keys[0]);
    assert!(
        chosen
            .get_or_bake(&BakeRequest::planes(&views, 16, 5), None)
            .unwrap()
            .cached
    );
    // The fixed store bakes at the given resolution and stores no choice.
    let Baker::Trained(mut f) = tiny_baker() else {
        unreachable!()
    };
    f.bake.feature_res = 6;
    let six = BakeStore::with_baker(&root, Baker::trained_fixed_lattice(f.train, f.bake));
    let c = six
        .get_or_bake(&BakeRequest::planes(&views, 16, 5), None)
        .unwrap();
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(c.dir.parent().unwrap().join("bake.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(json["lattice_res"].as_u64(), Some(6));
    assert!(json["lattice_choice"].is_null());
    assert_eq!(count(), 1);

    // Two training views cannot spare one: the default serves, no error.
    let few = Capture::load(capture(&dir.path().join("few"), &[ObjectKind::Ball], 32, 2)).unwrap();
    let few = ObjectViews::from_capture(&few, None).unwrap();
    assert!(chosen.lattice(&few, &Quiet).unwrap().is_none());
}

fn tiny_options(store: &Path) -> Options {
    let mut o = Options::reduced(store.to_path_buf());
    o.baker = tiny_baker();
    o.configs = nerflex_tests::tiny_configs();
    o.baseline = (16, 5);
    nerflex_tests::tiny_simulation(&mut o, 6, 40, 100);
    o
}

#[test]
fn a_trained_run_bakes_from_fields_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let cap = capture(dir.path(), &[ObjectKind::Ball, ObjectKind::Box], 48, 8);
    let store = dir.path().join("bakes");
    let opts = tiny_options(&store);
    let device = Device::builtin("pixel4").unwrap();
    let out = dir.path().join("run");
    let input = Input::Capture(cap);

    let run = pipeline::run_one(&input, &opts, &out, Method::Dp, &device, None, &Quiet).unwrap();
    assert_eq!(run.baker, "trained");
    // One field per profiler network, trained now and kept in the store.
    let networks = run.networks.len();
    assert!(networks >= 1);
    assert_eq!(run.times.fields_trained, networks);
    assert!(run.times.train_s > 0.0);
    let fields: Vec<_> = std::fs::read_dir(store.join("fields"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.path().extension().is_some_and(|x| x == "safetensors"))
        .collect();
    assert_eq!(fields.len(), networks);
    // Every planned object has an asset from the trained baker, baked at
    // its network's chosen lattice.
    for o in &run.realised.objects {
        assert!(o.asset.join("mlp.json").is_file(), "{}", o.asset.display());
        let entry = o.asset.parent().unwrap();
        let details: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(entry.join("bake.json")).unwrap())
                .unwrap();
        assert_eq!(details["baker"], "trained");
        assert!(o.file_bytes > 0);
        let chosen = details["lattice_choice"]["cells"].as_u64();
        assert_eq!(details["lattice_res"].as_u64(), chosen);
        let listed = run.lattices.iter().find(|l| l.object == o.name);
        assert_eq!(listed.map(|l| u64::from(l.cells)), chosen, "{}", o.name);
    }
    let q = run.realised.quality;
    assert!(q.ssim > 0.0 && q.ssim <= 1.0 && q.psnr.is_finite(), "{q:?}");
    let text = run.report_text(1.0, false);
    assert!(text.contains("trained baker"), "{text}");
    assert!(text.contains("time: capture"), "{text}");
    run.write(&out).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["baker"], "trained");
    assert!(json["times"]["train_s"].as_f64().unwrap() > 0.0);
    // Each network's chosen lattice, as its bakes used it.
    let lattices = json["lattices"].as_array().unwrap();
    assert_eq!(lattices.len(), networks);
    for (l, (name, _)) in lattices.iter().zip(&run.networks) {
        assert_eq!(l["object"], name.as_str());
        assert!(l["cells"].as_u64().unwrap() > 0);
    }

    // A re-run finds every field and bake in the store.
    let again = pipeline::run_one(&input, &opts, &out, Method::Dp, &device, None, &Quiet).unwrap();
    assert_eq!(again.sample_bakes.0, 0, "sample bakes redone");
    assert_eq!(again.times.fields_trained, 0);
    assert_eq!(again.times.train_s, 0.0);
    assert_eq!(again.realised.quality, run.realised.quality);

    // The hull baker on the same store bakes anew (its keys differ) and
    // trains nothing.
    let mut hull = opts.clone();
    hull.baker = Baker::Hull;
    let h = pipeline::run_one(&input, &hull, &out, Method::Dp, &device, None, &Quiet).unwrap();
    assert_eq!(h.baker, "hull");
    assert_eq!(h.sample_bakes.1, 0, "a hull run reused trained bakes");
    assert_eq!(h.times.train_s, 0.0);
}

#[test]
fn a_trained_evaluation_names_its_baker_and_what_it_substitutes() {
    use nerflex_sim::eval::{self, EvalOptions};
    use nerflex_sim::procedural::Preset;
    let dir = tempfile::tempdir().unwrap();
    let mut p = tiny_options(&dir.path().join("bakes"));
    p.size = 48;
    p.train_views = 6;
    p.test_views = 3;
    let opts = EvalOptions {
        pipeline: p,
        scenes: vec![Preset::Scene1],
        devices: vec![Device::builtin("pixel4").unwrap()],
        real: vec![],
        real_size: 64,
        fps_scene: Preset::Scene1,
    };
    let out = dir.path().join("eval");
    let report = eval::run(&opts, &out, None, &Quiet).unwrap();
    assert_eq!(report.baker, "trained");
    let baker = report
        .settings
        .iter()
        .find(|(k, _)| k == "baker")
        .map(|(_, v)| v.as_str())
        .unwrap_or("");
    assert!(
        baker.starts_with("trained: fields 16³ × 40 steps → 24³ × 40 steps"),
        "{baker}"
    );
    // Every method's row was measured on trained bakes; the fields of
    // Single-NeRF (1), Block-NeRF (one per object) and the networks are in
    // the store.
    let s = &report.scenes[0];
    assert!(s.rows.iter().any(|r| r.quality.is_some()));
    let fields = std::fs::read_dir(dir.path().join("bakes/fields"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "safetensors"))
        })
        .count();
    assert_eq!(fields, 1 + 5 + s.networks.len(), "{:?}", s.networks);
    // Each network's lattice as chosen, in the report and its Markdown.
    let names: Vec<&str> = s.networks.iter().map(|(n, _)| n.as_str()).collect();
    let chosen: Vec<&str> = s.lattices.iter().map(|l| l.object.as_str()).collect();
    assert_eq!(chosen, names);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for (l, (name, objects)) in s.lattices.iter().zip(&s.networks) {
        assert!(l.candidates.iter().any(|c| c.0 == l.cells), "{l:?}");
        let label = match objects.as_slice() {
            [one] if one == name => name.clone(),
            _ => format!("{name} ({})", objects.join(", ")),
        };
        let named = format!("{label} [lattice {}³]", l.cells);
        assert!(md.contains(&named), "{named} not in the report");
    }
    assert!(md.contains("the trained baker"), "no substitution line");
    assert!(!md.contains("visual-hull bakes (no trained field)"));
}

/// One bake request per (g, p), all on `views`.
fn requests<'a>(views: &'a ObjectViews, configs: &[(u32, u32)]) -> Vec<pipeline::BakeRequest<'a>> {
    configs
        .iter()
        .map(|&(g, p)| pipeline::BakeRequest::planes(views, g, p))
        .collect()
}

#[test]
fn hull_bakes_two_at_a_time_are_the_bakes_one_at_a_time_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let cap = Capture::load(capture(dir.path(), &[ObjectKind::Ball], 32, 6)).unwrap();
    let views = ObjectViews::from_capture(&cap, None).unwrap();
    let configs = [(8, 3), (16, 5), (12, 4), (16, 5)];
    let reqs = requests(&views, &configs);
    let label = |i: usize| format!("bake {i}");
    let two = BakeStore::new(dir.path().join("two")).with_jobs(2);
    let one = BakeStore::new(dir.path().join("one")).with_jobs(1);
    assert_eq!((two.jobs(), one.jobs()), (2, 1));
    let a = two.get_or_bake_many(&reqs, None, &Quiet, &label).unwrap();
    let b = one.get_or_bake_many(&reqs, None, &Quiet, &label).unwrap();
    assert_eq!(a.len(), configs.len());
    for ((x, y), &(g, p)) in a.iter().zip(&b).zip(&configs) {
        // Each result answers its own request, and the same bits either way.
        assert_eq!((x.sample.g, x.sample.p), (g, p));
        assert_eq!(x.sample.size_bytes, y.sample.size_bytes);
        assert_eq!(x.sample.ssim.to_bits(), y.sample.ssim.to_bits());
    }
    // The repeated request is one store entry, baked once (two workers
    // baking it at once raced to put the entry in place).
    assert_eq!(a[1].dir, a[3].dir);
    assert!(!a[1].cached && a[3].cached);
    // The trained baker honours the store's jobs too (within a network).
    assert_eq!(
        BakeStore::with_baker(dir.path().join("t"), tiny_baker())
            .with_jobs(4)
            .jobs(),
        4
    );
    // A bad request fails the batch with its own error.
    let mut bad = reqs.clone();
    bad[2].g = 0;
    let err = two
        .get_or_bake_many(&bad, None, &Quiet, &label)
        .unwrap_err();
    assert!(format!("{err:#}").contains("g=0"), "{err:#}");
}

#[test]
fn trained_bakes_of_one_network_run_together_after_one_training() {
    let dir = tempfile::tempdir().unwrap();
    let cap = Capture::load(capture(dir.path(), &[ObjectKind::Mug], 32, 8)).unwrap();
    let views = ObjectViews::from_capture(&cap, None).unwrap();
    let configs = [(8, 3), (12, 5), (16, 5)];
    let reqs = requests(&views, &configs);
    let label = |i: usize| format!("bake {i}");
    let two = BakeStore::with_baker(dir.path().join("two"), tiny_baker()).with_jobs(2);
    let one = BakeStore::with_baker(dir.path().join("one"), tiny_baker()).with_jobs(1);
    let a = two.get_or_bake_many(&reqs, None, &Quiet, &label).unwrap();
    let b = one.get_or_bake_many(&reqs, None, &Quiet, &label).unwrap();
    for ((x, y), &(g, p)) in a.iter().zip(&b).zip(&configs) {
        assert_eq!((x.sample.g, x.sample.p), (g, p));
        assert!(!x.cached);
        // Same geometry; the fine-tune's parallel sums may round apart.
        assert_eq!(x.sample.quads, y.sample.quads);
        let (sa, sb) = (x.sample.ssim, y.sample.ssim);
        assert!((sa - sb).abs() < 0.01, "g={g} p={p}: {sa} vs {sb}");
    }
    // The field was trained once, and its time is counted once, on the
    // group's first bake, as one at a time counts it.
    let trained: Vec<bool> = a.iter().map(|b| b.field_trained).collect();
    assert_eq!(trained, [true, false, false]);
    assert_eq!(a.iter().filter(|b| b.train_s > 0.0).count(), 1);
    assert_eq!(b.iter().filter(|b| b.train_s > 0.0).count(), 1);
    let fields = std::fs::read_dir(two.fields().root())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "safetensors"))
        })
        .count();
    assert_eq!(fields, 1);
    // A second batch finds everything stored and trains nothing.
    let c = two.get_or_bake_many(&reqs, None, &Quiet, &label).unwrap();
    assert!(c
        .iter()
        .all(|b| b.cached && !b.field_trained && b.train_s == 0.0));

    // Two networks in one batch (as Block-NeRF's and the plans' bakes
    // are): both fields trained first, each counted on its network's first
    // missing bake, and every result answers its own request.
    let ball_dir = dir.path().join("ball");
    std::fs::create_dir_all(&ball_dir).unwrap();
    let ball = Capture::load(capture(&ball_dir, &[ObjectKind::Ball], 32, 8)).unwrap();
    let ball = ObjectViews::from_capture(&ball, None).unwrap();
    let mixed = [
        pipeline::BakeRequest::planes(&views, 12, 3),
        pipeline::BakeRequest::planes(&ball, 8, 3),
        pipeline::BakeRequest::planes(&ball, 12, 5),
    ];
    let d = two.get_or_bake_many(&mixed, None, &Quiet, &label).unwrap();
    let got: Vec<(&str, u32, u32)> = d
        .iter()
        .map(|b| (b.sample.object.as_str(), b.sample.g, b.sample.p))
        .collect();
    assert_eq!(got, [("mug", 12, 3), ("ball", 8, 3), ("ball", 12, 5)]);
    // The mug's field was already stored; the ball's was trained now.
    let trained: Vec<bool> = d.iter().map(|b| b.field_trained).collect();
    assert_eq!(trained, [false, true, false]);
}
