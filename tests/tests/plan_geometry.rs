//! The bake geometry as a per-object choice of the planner: scenes whose
//! objects have planes and mesh configurations, each method's treatment of
//! them, the plan's output, and `nerflex profile combine`.

use nerflex_core::units::Bytes;
use nerflex_sim::baselines::{plan, Budget, Method, Plan};
use nerflex_sim::cli::profile::{combine_report, CombineArgs};
use nerflex_sim::geometry::Geometry;
use nerflex_sim::scene_file::{self, ConfigEntry, Scene, SceneObject};
use std::path::PathBuf;

/// (g, p, size in bytes, quality, geometry).
type Cfg = (u32, u32, u64, f64, Geometry);

const P: Geometry = Geometry::Planes;
const M: Geometry = Geometry::Mesh;

fn scene(objects: &[(&str, &[Cfg])]) -> Scene {
    Scene {
        objects: objects
            .iter()
            .map(|(name, cfgs)| SceneObject {
                name: name.to_string(),
                configs: cfgs
                    .iter()
                    .map(|&(g, p, s, q, geometry)| ConfigEntry {
                        geometry,
                        ..ConfigEntry::planes(g, p, Bytes(s), q)
                    })
                    .collect(),
                profile: None,
                mesh_profile: None,
            })
            .collect(),
        single: None,
    }
}

fn only(s: &Scene, g: Geometry) -> Scene {
    Scene {
        objects: s
            .objects
            .iter()
            .map(|o| SceneObject {
                configs: o
                    .configs
                    .iter()
                    .filter(|c| c.geometry == g)
                    .copied()
                    .collect(),
                ..o.clone()
            })
            .collect(),
        single: None,
    }
}

fn picks(p: &Plan) -> Vec<(u32, u32, Geometry)> {
    p.objects.iter().map(|o| (o.g, o.p, o.geometry)).collect()
}

/// `a` is better as mesh, `b` as planes: at 40 bytes the best plan mixes.
fn mixed() -> Scene {
    scene(&[
        (
            "a",
            &[
                (1, 1, 10, 0.5, P),
                (2, 1, 30, 0.7, P),
                (1, 1, 10, 0.4, M),
                (2, 1, 20, 0.75, M),
            ],
        ),
        (
            "b",
            &[
                (1, 1, 10, 0.5, P),
                (2, 1, 20, 0.8, P),
                (1, 1, 10, 0.45, M),
                (2, 1, 30, 0.82, M),
            ],
        ),
    ])
}

fn bytes_budget(total: u64) -> Budget {
    Budget::with_unit(Bytes(total), Bytes(1))
}

#[test]
fn union_strictly_beats_either_geometry_alone_within_the_budget() {
    let s = mixed();
    let budget = bytes_budget(40);
    // Planes alone: a (1,1) + b (2,1) = 1.3; mesh alone: a (1,1) + b (2,1) = 1.22.
    let planes = plan(Method::Dp, &only(&s, P), budget).unwrap();
    let mesh = plan(Method::Dp, &only(&s, M), budget).unwrap();
    assert!((planes.total_quality - 1.3).abs() < 1e-9);
    assert!((mesh.total_quality - 1.22).abs() < 1e-9);
    for method in [Method::Dp, Method::Brute, Method::Greedy, Method::Slsqp] {
        let u = plan(method, &s, budget).unwrap();
        assert_eq!(picks(&u), [(2, 1, M), (2, 1, P)], "{method}");
        assert!((u.total_quality - 1.55).abs() < 1e-9, "{method}");
        assert!(u.feasible && u.total_size_bytes <= 40, "{method}");
        assert!(u.total_quality_q > planes.total_quality_q);
        assert!(u.total_quality_q > mesh.total_quality_q);
    }
    // Fairness: 20 bytes each, best of either geometry inside the share.
    let f = plan(Method::Fairness, &s, budget).unwrap();
    assert_eq!(picks(&f), [(2, 1, M), (2, 1, P)]);
    // One byte less and the mix no longer fits: back to planes alone.
    let u = plan(Method::Dp, &s, bytes_budget(39)).unwrap();
    assert!(u.total_size_bytes <= 39);
    assert_eq!(
        u.total_quality_q,
        plan(Method::Dp, &only(&s, P), bytes_budget(39))
            .unwrap()
            .total_quality_q
    );
}

#[test]
fn block_and_single_stay_planes_at_128_17() {
    // A mesh (128, 17) that is smaller and better must not be used.
    let s = scene(&[
        (
            "a",
            &[
                (128, 17, 100, 0.8, P),
                (128, 17, 50, 0.9, M),
                (64, 17, 40, 0.7, P),
            ],
        ),
        (
            "b",
            &[
                (128, 17, 100, 0.8, P),
                (128, 17, 50, 0.9, M),
                (64, 17, 40, 0.7, P),
            ],
        ),
    ]);
    let b = plan(Method::Block, &s, bytes_budget(1000)).unwrap();
    assert_eq!(picks(&b), [(128, 17, P), (128, 17, P)]);
    assert_eq!(b.total_size_bytes, 200);
    // Derived Single-NeRF: 2 objects, g ≤ 128/∛2 ≈ 101.6 → (64, 17) planes.
    let single = plan(Method::Single, &s, bytes_budget(1000)).unwrap();
    assert_eq!(single.total_size_bytes, 80);
    assert_eq!(single.objects[0].geometry, P);
    // With only a mesh (128, 17), Block-NeRF has no configuration.
    let mesh_only = only(&s, M);
    let e = plan(Method::Block, &mesh_only, bytes_budget(1000)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "block: object `a` has no configuration (g 128, p 17)"
    );
}

#[test]
fn slsqp_solves_each_geometry_assignment_and_tolerates_a_partial_grid() {
    // `a`'s mesh rows are not a full g × p grid: assignments giving `a`
    // mesh fail, the planes ones still plan.
    let s = scene(&[
        (
            "a",
            &[
                (1, 1, 10, 0.5, P),
                (2, 1, 20, 0.7, P),
                (1, 1, 5, 0.6, M),
                (2, 3, 30, 0.9, M),
                (1, 3, 20, 0.5, M),
            ],
        ),
        ("b", &[(1, 1, 10, 0.5, P), (2, 1, 20, 0.8, P)]),
    ]);
    let p = plan(Method::Slsqp, &s, bytes_budget(40)).unwrap();
    assert!(p.feasible);
    assert!(p.objects.iter().all(|o| o.geometry == P), "{:?}", picks(&p));
    // Planes-only scenes: exactly the plan of before (one assignment).
    let planes = only(&mixed(), P);
    let a = plan(Method::Slsqp, &planes, bytes_budget(40)).unwrap();
    assert_eq!(picks(&a).len(), 2);
    assert!(picks(&a).iter().all(|c| c.2 == P));
}

#[test]
fn plan_output_names_each_geometry() {
    let s = mixed();
    let budget = bytes_budget(40);
    let mut p = plan(Method::Dp, &s, budget).unwrap();
    p.device = Some("iphone13".into());
    // The plan's own JSON leaves out planes (older readers, pipeline
    // outputs unchanged) and reads back.
    let v = serde_json::to_value(&p).unwrap();
    assert_eq!(v["objects"][0]["geometry"], "mesh");
    assert!(v["objects"][1].get("geometry").is_none());
    let back: Plan = serde_json::from_value(v).unwrap();
    assert_eq!(back.objects[1].geometry, P);
    assert_eq!(back.objects[0].geometry, M);
    // `nerflex plan --json` names it for every object.
    let j = nerflex_sim::cli::plan::json(&p).unwrap();
    assert_eq!(j["objects"][0]["geometry"], "mesh");
    assert_eq!(j["objects"][1]["geometry"], "planes");
    let t = nerflex_sim::cli::plan::table(&p, budget);
    assert!(t.contains("geometry"), "{t}");
    let rows: Vec<&str> = t
        .lines()
        .filter(|l| l.starts_with("a ") || l.starts_with("b "))
        .collect();
    assert!(
        rows[0].contains(" mesh ") && rows[1].contains(" planes "),
        "{t}"
    );
}

fn trained(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../results/profile/trained")
        .join(rel)
}

#[test]
fn combine_joins_the_committed_profiles_and_the_union_plans_within_budget() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let text = combine_report(&CombineArgs {
        planes: trained("profiles.json"),
        mesh_profiles: trained("mesh/profiles.json"),
        out: out.clone(),
    })
    .unwrap();
    assert!(
        text.contains("lego: 40 configurations (20 planes, 20 mesh)"),
        "{text}"
    );
    let s = scene_file::load(&out).unwrap();
    let planes = scene_file::load(&trained("profiles.json")).unwrap();
    let mesh = scene_file::load(&trained("mesh/profiles.json")).unwrap();
    for ((o, po), mo) in s.objects.iter().zip(&planes.objects).zip(&mesh.objects) {
        assert_eq!(o.profile, po.profile);
        assert_eq!(o.mesh_profile, mo.profile);
        // The union: the planes configurations as before, then the mesh ones.
        assert_eq!(&o.configs[..20], &po.configs[..]);
        assert!(o.configs[20..]
            .iter()
            .zip(&mo.configs)
            .all(|(c, m)| c.geometry == M
                && (c.g, c.p, c.size, c.quality) == (m.g, m.p, m.size, m.quality)));
    }
    // The union never plans worse than the planes alone, and stays inside
    // the budget. Since session 18's closed texel opacity the planes' own
    // bakes are better per byte at every budget (the mesh sweep is session
    // 15's), so both objects stay planes; before, lego went mesh from
    // 150–200 MB.
    for mb in [100, 150, 200, 300, 400, 600, 800] {
        let budget = Budget::new(Bytes::from_mb_u64(mb));
        let u = plan(Method::Dp, &s, budget).unwrap();
        let p = plan(Method::Dp, &planes, budget).unwrap();
        assert!(u.total_quality_q >= p.total_quality_q, "{mb} MB");
        assert!(u.total_size_bytes <= budget.total.0, "{mb} MB");
        assert_eq!(u.objects[0].name, "lego");
        assert!(u.objects.iter().all(|o| o.geometry == P), "{mb} MB");
    }
    // Offered only the mesh's configurations for lego, the union plans it
    // as a mesh: the join keeps both geometries' configurations usable.
    let mut mesh_lego = s.clone();
    mesh_lego.objects[0].configs.retain(|c| c.geometry == M);
    let budget = Budget::new(Bytes::from_mb_u64(200));
    let m = plan(Method::Dp, &mesh_lego, budget).unwrap();
    assert_eq!(m.objects[0].geometry, M);
    assert_eq!(m.objects[1].geometry, P);
    assert!(m.total_size_bytes <= budget.total.0);
}

#[test]
fn combine_errors_name_the_flag_and_file_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let args = |planes: PathBuf, mesh: PathBuf| CombineArgs {
        planes,
        mesh_profiles: mesh,
        out: out.clone(),
    };
    let missing = dir.path().join("nope.json");
    let e = combine_report(&args(trained("profiles.json"), missing.clone())).unwrap_err();
    let msg = format!("{e:#}");
    assert!(
        msg.starts_with("--mesh-profiles: ") && msg.contains("nope.json: cannot read"),
        "{msg}"
    );
    let e = combine_report(&args(missing, trained("mesh/profiles.json"))).unwrap_err();
    assert!(format!("{e:#}").starts_with("--planes: "), "{e:#}");
    // An object the other file lacks.
    let lego_only = dir.path().join("lego.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(trained("mesh/profiles.json")).unwrap())
            .unwrap();
    v["objects"].as_array_mut().unwrap().truncate(1);
    std::fs::write(&lego_only, v.to_string()).unwrap();
    let e = combine_report(&args(trained("profiles.json"), lego_only.clone())).unwrap_err();
    assert!(
        format!("{e:#}").contains("--mesh-profiles has no object `chair` (it has: lego)"),
        "{e:#}"
    );
    let e = combine_report(&args(lego_only, trained("mesh/profiles.json"))).unwrap_err();
    assert!(
        format!("{e:#}").contains("--planes has no object `chair` (it has: lego)"),
        "{e:#}"
    );
    // A table is not a profile.
    let table = dir.path().join("table.json");
    std::fs::write(&table, r#"{"objects": [{"name": "lego", "configs": [{"g": 1, "p": 1, "size_bytes": 1, "quality": 0.5}]}]}"#).unwrap();
    let e = combine_report(&args(trained("profiles.json"), table)).unwrap_err();
    assert!(
        format!("{e:#}").contains("--mesh-profiles: object `lego` is not in single-profile form"),
        "{e:#}"
    );
    assert!(!out.exists(), "a failed combine wrote {}", out.display());
}
