//! `nerflex plan` end to end: flags, table and JSON output, exit codes.

use std::path::PathBuf;
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn nerflex(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nerflex"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("run nerflex")
}

/// `nerflex plan --scene SCENE --device iphone13`, which must fail: its
/// standard error.
fn plan_error(scene: &str) -> String {
    let out = nerflex(&["plan", "--scene", scene, "--device", "iphone13"]);
    assert!(!out.status.success(), "planning {scene} succeeded");
    text(&out.stderr)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

const SCENE: &str = "examples/scenes/illustrative_five_objects.json";

#[test]
fn json_for_every_method() {
    for method in [
        "dp", "fairness", "slsqp", "greedy", "block", "single", "brute",
    ] {
        let out = nerflex(&[
            "plan", "--scene", SCENE, "--device", "iphone13", "--method", method, "--json",
        ]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|e| panic!("{method}: {e}: {}", text(&out.stdout)));
        assert_eq!(v["method"], method);
        assert_eq!(v["device"], "iphone13");
        assert_eq!(v["budget_bytes"], 240_000_000u64);
        let feasible = v["feasible"].as_bool().unwrap();
        let total: u64 = v["objects"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| o["size_bytes"].as_u64().unwrap())
            .sum();
        assert_eq!(v["total_size_bytes"].as_u64(), Some(total));
        // Infeasible plans (Block-NeRF here) exit non-zero with the reason.
        assert_eq!(
            out.status.success(),
            feasible,
            "{method}: {}",
            text(&out.stderr)
        );
        if feasible {
            assert!(total <= 240_000_000);
        } else {
            assert_eq!(method, "block");
            assert!(
                text(&out.stderr).contains("block plan is infeasible: it needs 337.86 MB"),
                "{}",
                text(&out.stderr)
            );
        }
    }
}

#[test]
fn table_output() {
    let out = nerflex(&["plan", "--scene", SCENE, "--device", "pixel4"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let t = text(&out.stdout);
    assert!(t.starts_with("dp plan on pixel4: budget 150.00 MB"), "{t}");
    assert!(t.contains("object"), "{t}");
    assert!(t.contains("size MB") && t.contains("SSIM"), "{t}");
    for name in ["lego", "chair", "drums", "ficus", "hotdog", "total"] {
        assert!(
            t.lines().any(|l| l.starts_with(name)),
            "{name} missing: {t}"
        );
    }
    assert!(
        t.lines().last().unwrap().starts_with("budget used: "),
        "{t}"
    );
}

#[test]
fn budget_override_and_infeasible_budget() {
    let out = nerflex(&[
        "plan",
        "--scene",
        SCENE,
        "--device",
        "iphone13",
        "--budget-mb",
        "100",
        "--json",
    ]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["budget_bytes"], 100_000_000u64);
    assert!(v["total_size_bytes"].as_u64().unwrap() <= 100_000_000);

    let out = nerflex(&[
        "plan",
        "--scene",
        SCENE,
        "--device",
        "iphone13",
        "--budget-mb",
        "5",
    ]);
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    let e = text(&out.stderr);
    assert!(e.contains("infeasible: the cheapest plan needs 7.95 MB (7946528 bytes), over the budget of 5.00 MB"), "{e}");
}

#[test]
fn bad_input_is_a_clear_error() {
    let cases: &[(&[&str], &str)] = &[
        (
            &["--budget-mb", "-3"],
            "--budget-mb: must be a non-negative number of MB: negative value -3",
        ),
        (&["--budget-mb", "nan"], "--budget-mb"),
        (&["--unit-bytes", "0"], "--unit-bytes: must be at least 1"),
    ];
    for (extra, expect) in cases {
        let mut args = vec!["plan", "--scene", SCENE, "--device", "iphone13"];
        args.extend_from_slice(extra);
        let out = nerflex(&args);
        assert!(!out.status.success(), "{extra:?}");
        assert!(
            text(&out.stderr).contains(expect),
            "{extra:?}: {}",
            text(&out.stderr)
        );
    }
    {
        let args = ["plan", "--scene", SCENE, "--device", "nokia3310"];
        let expect = "nokia3310: not a built-in device (iphone13, pixel4) and no such file";
        let out = nerflex(&args);
        assert!(!out.status.success(), "{args:?}");
        assert!(
            text(&out.stderr).contains(expect),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }

    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("scene.json");
    std::fs::write(&bad, r#"{"objects": [{"name": "a", "configs": [{"g": 1, "p": 1, "size_bytes": -3, "quality": 0.5}]}]}"#).unwrap();
    let e = plan_error(bad.to_str().unwrap());
    assert!(
        e.contains("scene.json: objects[0].configs[0].size_bytes: negative value -3"),
        "{e}"
    );

    let e = plan_error("does/not/exist.json");
    assert!(e.contains("does/not/exist.json: cannot read"), "{e}");

    let out = nerflex(&[
        "plan", "--scene", SCENE, "--device", "iphone13", "--method", "magic",
    ]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("invalid value 'magic'"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn device_from_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiny.toml");
    let pixel = std::fs::read_to_string(root().join("sim/devices/pixel4.toml")).unwrap();
    std::fs::write(
        &path,
        pixel
            .replace("name = \"pixel4\"", "name = \"tiny\"")
            .replace("budget_mb = 150.0", "budget_mb = 60.0"),
    )
    .unwrap();
    let out = nerflex(&[
        "plan",
        "--scene",
        SCENE,
        "--device",
        path.to_str().unwrap(),
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["device"], "tiny");
    assert_eq!(v["budget_bytes"], 60_000_000u64);

    std::fs::write(
        &path,
        pixel.replace("refresh_hz = 90.0", "refresh_hz = 90.0\nbrightness = 3"),
    )
    .unwrap();
    let out = nerflex(&["plan", "--scene", SCENE, "--device", path.to_str().unwrap()]);
    assert!(!out.status.success());
    let e = text(&out.stderr);
    assert!(
        e.contains("tiny.toml: display.brightness: unknown field `brightness`"),
        "{e}"
    );
}

#[test]
fn two_geometry_scene_plans_name_each_geometry() {
    // A table scene where lego is worth more as a mesh and chair as planes
    // (the committed lego + chair profiles choose planes for both since
    // session 24, docs/profiler.md).
    let dir = tempfile::tempdir().unwrap();
    let scene_file = dir.path().join("scene.json");
    std::fs::write(
        &scene_file,
        r#"{"objects": [
            {"name": "lego", "configs": [
                {"g": 128, "p": 17, "size_bytes": 100000000, "quality": 0.93, "geometry": "planes"},
                {"g": 256, "p": 5, "size_bytes": 60000000, "quality": 0.94, "geometry": "mesh"}]},
            {"name": "chair", "configs": [
                {"g": 128, "p": 9, "size_bytes": 50000000, "quality": 0.95, "geometry": "planes"},
                {"g": 128, "p": 5, "size_bytes": 40000000, "quality": 0.90, "geometry": "mesh"}]}]}"#,
    )
    .unwrap();
    let scene = scene_file.to_str().unwrap();
    let args = [
        "plan",
        "--scene",
        scene,
        "--device",
        "iphone13",
        "--budget-mb",
        "150",
    ];
    let out = nerflex(&[&args[..], &["--json"]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let objects = v["objects"].as_array().unwrap();
    assert_eq!(objects[0]["name"], "lego");
    assert_eq!(objects[0]["geometry"], "mesh");
    assert_eq!(objects[1]["geometry"], "planes");
    assert!(v["total_size_bytes"].as_u64().unwrap() <= 150_000_000);
    let out = nerflex(&args);
    let t = text(&out.stdout);
    assert!(t.contains("geometry"), "{t}");
    assert!(
        t.lines()
            .any(|l| l.starts_with("lego") && l.contains(" mesh ")),
        "{t}"
    );
}

#[test]
fn bad_geometry_and_combine_paths_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"objects": [{"name": "lego", "configs": [
            {"g": 1, "p": 1, "size_bytes": 1, "quality": 0.5, "geometry": "voxels"}]}]}"#,
    )
    .unwrap();
    let e = plan_error(bad.to_str().unwrap());
    assert!(
        e.contains("objects[0].configs[0].geometry: object \"lego\": unknown geometry \"voxels\""),
        "{e}"
    );
    let out_file = dir.path().join("scene.json");
    let out = nerflex(&[
        "profile",
        "combine",
        "--planes",
        "results/profile/trained/profiles.json",
        "--mesh-profiles",
        "no/such/mesh.json",
        "--out",
        out_file.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = text(&out.stderr);
    assert!(
        e.contains("--mesh-profiles") && e.contains("no/such/mesh.json"),
        "{e}"
    );
    assert!(!out_file.exists());
}

/// `--objective area` reads each network's zoom from a segmentation file:
/// a ×4 crop's +0.03 SSIM is then worth less than the frame's +0.01, so
/// the budget goes to the shared network; missing or stray flags and an
/// object the segmentation lacks are errors naming the flag or file.
#[test]
fn area_objective_weighs_by_the_segmentations_zoom() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    let cfg = |g: u32, mb: u64, q: f64| serde_json::json!({"g": g, "p": 5, "size_bytes": mb * 1_000_000, "quality": q});
    std::fs::write(
        &scene,
        serde_json::json!({"objects": [
            {"name": "shared", "configs": [cfg(32, 10, 0.95), cfg(64, 30, 0.96)]},
            {"name": "crop", "configs": [cfg(32, 10, 0.80), cfg(64, 30, 0.83)]},
        ]})
        .to_string(),
    )
    .unwrap();
    let seg = dir.path().join("segmentation.json");
    std::fs::write(
        &seg,
        r#"{"groups": [{"folder": "crop", "mean_zoom": 4.0}, {"folder": "shared", "mean_zoom": 1.0}]}"#,
    )
    .unwrap();
    let (scene, seg) = (scene.to_str().unwrap(), seg.to_str().unwrap());
    let plan = |extra: &[&str]| -> Output {
        let mut a = vec![
            "plan",
            "--scene",
            scene,
            "--device",
            "iphone13",
            "--budget-mb",
            "40",
            "--json",
        ];
        a.extend_from_slice(extra);
        nerflex(&a)
    };
    let grids = |out: &Output| -> Vec<u64> {
        assert!(out.status.success(), "{}", text(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["objects"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| o["g"].as_u64().unwrap())
            .collect()
    };
    assert_eq!(grids(&plan(&[])), [32, 64]);
    let area = plan(&["--objective", "area", "--segmentation", seg]);
    assert_eq!(grids(&area), [64, 32]);
    let v: serde_json::Value = serde_json::from_slice(&area.stdout).unwrap();
    assert_eq!(v["objective"], "area");
    assert_eq!(v["objects"][0]["quality"], 0.96);
    assert!((v["total_quality"].as_f64().unwrap() - 1.76).abs() < 1e-12);

    let err = |out: Output| {
        assert!(!out.status.success());
        text(&out.stderr)
    };
    assert!(err(plan(&["--objective", "area"])).contains("--segmentation"));
    assert!(err(plan(&["--segmentation", seg])).contains("--objective area"));
    let other = dir.path().join("other.json");
    std::fs::write(
        &other,
        r#"{"groups": [{"folder": "crop", "mean_zoom": 4.0}]}"#,
    )
    .unwrap();
    let e = err(plan(&[
        "--objective",
        "area",
        "--segmentation",
        other.to_str().unwrap(),
    ]));
    assert!(e.contains("other.json") && e.contains("shared"), "{e}");
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{").unwrap();
    assert!(err(plan(&[
        "--objective",
        "area",
        "--segmentation",
        bad.to_str().unwrap()
    ]))
    .contains("bad.json"));
}
