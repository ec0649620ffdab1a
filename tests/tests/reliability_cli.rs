//! Issue 13 from the outside: each hostile input of the issue gives a clean
//! error (exit 1 or 2, a message naming the file or flag) and leaves every
//! pre-existing output byte-identical.
//!
//! The command lines are parsed by clap exactly as the `nerflex` binary
//! parses them (the same `Args` types) and run in-process, with the binary's
//! exit codes: 2 for a flag clap refuses, 1 for an error of the command.
//! Inputs are tiny (a 6-view 64-px capture, a few-KB asset) so the file
//! runs in seconds.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use clap::Parser as _;
use nerflex_sim::cli;
use nerflex_sim::procedural::{
    arrange, make_capture, CaptureSpec, Layout, ObjectKind, RenderOptions,
};

#[derive(clap::Parser)]
#[command(name = "nerflex")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    Plan(cli::plan::Args),
    Render(cli::render::Args),
    Metrics(cli::metrics::Args),
    Bake(cli::bake::Args),
    Segment(cli::segment::Args),
    Simulate(cli::simulate::Args),
    Run(cli::run::Args),
    Eval(cli::eval::Args),
}

/// Runs `nerflex ARGS…`: (exit code, stderr message).
fn nerflex(args: &[&str]) -> (i32, String) {
    let cli = match Cli::try_parse_from(std::iter::once("nerflex").chain(args.iter().copied())) {
        Ok(c) => c,
        Err(e) => return (e.exit_code(), e.to_string()),
    };
    let r = match cli.command {
        Command::Plan(a) => cli::plan::run(a),
        Command::Render(a) => cli::render::run(a),
        Command::Metrics(a) => cli::metrics::run(a),
        Command::Bake(a) => cli::bake::run(a),
        Command::Segment(a) => cli::segment::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
        Command::Run(a) => cli::run::run(a),
        Command::Eval(a) => cli::eval::run(a),
    };
    match r {
        Ok(()) => (0, String::new()),
        Err(e) => (1, format!("error: {e:#}")),
    }
}

/// Asserts a clean failure whose message contains every `needle`.
#[track_caller]
fn fails(args: &[&str], needles: &[&str]) -> String {
    let (code, msg) = nerflex(args);
    assert!(code == 1 || code == 2, "{args:?}: exit {code}, {msg}");
    for n in needles {
        assert!(msg.contains(n), "{args:?}: message lacks {n:?}: {msg}");
    }
    msg
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file under `dir` (relative path → length and hash of its bytes),
/// and the entries beside it: a failed command must change neither (no
/// stray temporaries).
type Snapshot = (BTreeMap<PathBuf, (usize, u64)>, Vec<String>);

fn snapshot(dir: &Path) -> Snapshot {
    let mut files = BTreeMap::new();
    fn walk(root: &Path, d: &Path, out: &mut BTreeMap<PathBuf, (usize, u64)>) {
        use std::hash::{Hash as _, Hasher as _};
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let bytes = std::fs::read(&p).unwrap();
                let mut h = std::collections::hash_map::DefaultHasher::new();
                bytes.hash(&mut h);
                out.insert(
                    p.strip_prefix(root).unwrap().into(),
                    (bytes.len(), h.finish()),
                );
            }
        }
    }
    if dir.is_dir() {
        walk(dir, dir, &mut files);
    }
    let mut beside: Vec<String> = std::fs::read_dir(dir.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    beside.sort();
    (files, beside)
}

/// A 6-view, 2-test-view, 64-px capture of a pawn and a ball, made once.
fn capture() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = std::env::temp_dir().join(format!("nerflex-rel-{}", std::process::id()));
        let out = root.join("two");
        let spec = CaptureSpec {
            objects: arrange(&[ObjectKind::Pawn, ObjectKind::Ball], Layout::Row, 1, 1.0),
            layout: "row".into(),
            preset: None,
            seed: 1,
            train_views: 6,
            test_views: 2,
            size: 64,
            render: RenderOptions {
                edge_samples: 0,
                texture_samples: 0,
                shadows: false,
                ambient_occlusion: false,
                ..RenderOptions::default()
            },
        };
        make_capture(&spec, &out, &|| {}).unwrap();
        out
    })
}

/// A copy of the capture in `dir` (to mutate).
fn copy_capture(dir: &Path) -> PathBuf {
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let p = e.unwrap().path();
            let t = to.join(p.file_name().unwrap());
            if p.is_dir() {
                copy(&p, &t);
            } else {
                std::fs::copy(&p, &t).unwrap();
            }
        }
    }
    let to = dir.join("cap");
    copy(capture(), &to);
    to
}

/// Bakes the ball at g=8, p=3 into `out` (succeeds).
fn bake_into(out: &Path) {
    let (code, msg) = nerflex(&[
        "bake",
        "--capture",
        s(capture()),
        "--object",
        "ball",
        "--grid",
        "8",
        "--patch",
        "3",
        "--out",
        s(out),
    ]);
    assert_eq!(code, 0, "{msg}");
}

/// A safetensors file of LPIPS's tensor names and shapes, every value from
/// `value(name)`.
fn lpips_file(path: &Path, value: &dyn Fn(&str) -> f32) {
    let convs = [
        (11, 3, 64),
        (5, 64, 192),
        (3, 192, 384),
        (3, 384, 256),
        (3, 256, 256),
    ];
    let mut tensors: Vec<(String, Vec<usize>)> = Vec::new();
    for (i, &(k, cin, cout)) in convs.iter().enumerate() {
        tensors.push((
            format!("alexnet.conv{i}.kernel_hwio"),
            vec![k, k, cin, cout],
        ));
        tensors.push((format!("alexnet.conv{i}.bias"), vec![cout]));
        tensors.push((format!("lin{i}.kernel"), vec![cout]));
    }
    let mut header = serde_json::Map::new();
    let mut data = Vec::new();
    for (name, shape) in &tensors {
        let n: usize = shape.iter().product();
        let start = data.len();
        for _ in 0..n {
            data.extend_from_slice(&value(name).to_le_bytes());
        }
        header.insert(
            name.clone(),
            serde_json::json!({"dtype": "F32", "shape": shape, "data_offsets": [start, data.len()]}),
        );
    }
    let mut h = serde_json::Value::Object(header).to_string().into_bytes();
    while h.len() % 8 != 0 {
        h.push(b' ');
    }
    let mut bytes = (h.len() as u64).to_le_bytes().to_vec();
    bytes.extend_from_slice(&h);
    bytes.extend_from_slice(&data);
    std::fs::write(path, bytes).unwrap();
}

fn png(path: &Path, w: u32, h: u32) {
    image::RgbaImage::from_pixel(w, h, image::Rgba([200, 100, 50, 255]))
        .save(path)
        .unwrap();
}

#[test]
fn a_failed_measurement_leaves_the_old_asset_byte_identical() {
    let tmp = tempfile::tempdir().unwrap();
    // Alone in its parent: the parent's listing shows stray temporaries.
    let out = tmp.path().join("o/asset");
    bake_into(&out);
    let before = snapshot(&out);
    let bad = tmp.path().join("bad.safetensors");
    std::fs::write(&bad, b"not safetensors").unwrap();
    let base = [
        "bake",
        "--capture",
        s(capture()),
        "--object",
        "ball",
        "--grid",
        "10",
        "--patch",
        "4",
        "--out",
        s(&out),
        "--measure",
    ];
    // Bad LPIPS weights: the measurement fails after the bake.
    let mut a = base.to_vec();
    a.extend(["--lpips-weights", s(&bad)]);
    fails(&a, &["bad.safetensors"]);
    assert_eq!(snapshot(&out), before);
    // No test views to measure on.
    let mut a = base.to_vec();
    a.extend(["--max-test-views", "0", "--lpips-weights", "/nonexistent"]);
    fails(&a, &[]);
    assert_eq!(snapshot(&out), before);
    // --renders names a file.
    let file = tmp.path().join("renders");
    std::fs::write(&file, "mine").unwrap();
    let mut a = base.to_vec();
    a.extend(["--renders", s(&file)]);
    fails(&a, &["renders"]);
    assert_eq!(snapshot(&out), before);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
    // The same bake without the failure replaces the folder whole.
    let mut a = base[..base.len() - 1].to_vec();
    a.push("--max-views");
    a.push("3");
    assert_eq!(nerflex(&a).0, 0);
    assert_ne!(snapshot(&out).0, before.0);
    assert_eq!(snapshot(&out).1, before.1, "no temporaries left beside it");
}

#[test]
fn bake_never_replaces_a_folder_it_did_not_write() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("mine");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("thesis.tex"), "years of work").unwrap();
    let before = snapshot(&out);
    let a = small_bake(capture(), None, &out);
    fails(&strs(&a), &["thesis.tex", "--out"]);
    assert_eq!(snapshot(&out), before);
}

/// `nerflex bake` of the built-in ball at (8, 3) into `out`, from `field`
/// if given (the argument list the bake tests share).
fn small_bake(capture: &Path, field: Option<&Path>, out: &Path) -> Vec<String> {
    let mut a: Vec<String> = ["bake", "--capture", s(capture), "--object", "ball"]
        .map(str::to_string)
        .to_vec();
    if let Some(f) = field {
        a.extend(["--field".to_string(), s(f).to_string()]);
    }
    a.extend(["--grid", "8", "--patch", "3", "--out", s(out)].map(str::to_string));
    a
}

fn strs(a: &[String]) -> Vec<&str> {
    a.iter().map(String::as_str).collect()
}

/// The field loads beside the capture (on its own thread): a bad capture
/// is still reported before a bad field, a bad field names `--field` and
/// its file, and a good pair bakes and measures.
#[test]
fn bake_from_a_field_loads_it_beside_the_capture() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("a");
    let nofield = tmp.path().join("nofield.safetensors");
    let junk = tmp.path().join("junk.safetensors");
    std::fs::write(&junk, b"not safetensors").unwrap();
    let nocapture = tmp.path().join("nocapture");
    let args = |capture: &Path, field: &Path| small_bake(capture, Some(field), &out);
    let run = |a: Vec<String>, needles: &[&str]| fails(&strs(&a), needles);
    let msg = run(args(&nocapture, &nofield), &["nocapture"]);
    assert!(!msg.contains("nofield"), "{msg}");
    run(
        args(capture(), &nofield),
        &["--field", "nofield.safetensors"],
    );
    run(args(capture(), &junk), &["--field", "junk.safetensors"]);
    assert!(!out.exists());
    // The analytic field of the built-in capture: a whole trained bake.
    let mut a = args(capture(), Path::new("builtin"));
    a.extend(["--epochs", "0.2", "--measure"].map(str::to_string));
    let (code, msg) = nerflex(&strs(&a));
    assert_eq!(code, 0, "{msg}");
    assert!(out.join("mlp.json").is_file());
}

#[test]
fn bake_refuses_zero_views_and_an_impossible_patch() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("a");
    let base = [
        "bake",
        "--capture",
        s(capture()),
        "--object",
        "ball",
        "--out",
        s(&out),
    ];
    let mut a = base.to_vec();
    a.extend(["--grid", "8", "--patch", "3", "--max-views", "0"]);
    fails(&a, &["--max-views"]);
    // 4096² texels per quad: refused against memory, not aborted.
    let mut a = base.to_vec();
    a.extend(["--grid", "8", "--patch", "4096"]);
    fails(&a, &["--patch 4096", "limit"]);
    assert!(!out.exists());
}

#[test]
fn cameras_that_overflow_f32_are_refused_by_bake_and_render() {
    let tmp = tempfile::tempdir().unwrap();
    let cap = copy_capture(tmp.path());
    let t = cap.join("transforms_train.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&t).unwrap()).unwrap();
    v["frames"][0]["transform_matrix"][0][3] = serde_json::json!(1e39);
    std::fs::write(&t, v.to_string()).unwrap();
    let out = tmp.path().join("a");
    fails(
        &[
            "bake",
            "--capture",
            s(&cap),
            "--object",
            "ball",
            "--grid",
            "8",
            "--patch",
            "3",
            "--out",
            s(&out),
        ],
        &["transforms_train.json", "transform_matrix[0][3]"],
    );
    assert!(!out.exists());
    // A focal length finite in f64 but not in f32.
    let mut v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(capture().join("transforms_train.json")).unwrap(),
    )
    .unwrap();
    v["fl_x"] = serde_json::json!(1e39);
    std::fs::write(&t, v.to_string()).unwrap();
    fails(
        &[
            "bake",
            "--capture",
            s(&cap),
            "--object",
            "ball",
            "--grid",
            "8",
            "--patch",
            "3",
            "--out",
            s(&out),
        ],
        &["transforms_train.json", "fl_x"],
    );
    let asset = tmp.path().join("asset");
    bake_into(&asset);
    fails(
        &[
            "render",
            "--asset",
            s(&asset),
            "--transforms",
            s(&t),
            "--frame",
            "0",
            "--size",
            "32",
            "--out",
            s(&tmp.path().join("r.png")),
        ],
        &["transforms_train.json", "fl_x"],
    );
    assert!(!tmp.path().join("r.png").exists());
}

#[test]
fn segment_replaces_its_folder_whole_and_refuses_foreign_files() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("seg");
    let seg = |alpha: &str| {
        nerflex(&[
            "segment",
            "--capture",
            s(capture()),
            "--alpha",
            alpha,
            "--out",
            s(&out),
        ])
    };
    // All dedicated, then all shared: no stale group folder survives.
    assert_eq!(seg("0").0, 0);
    assert_eq!(seg("1e9").0, 0);
    let text = std::fs::read_to_string(out.join("segmentation.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut want: Vec<String> = v["groups"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| g["folder"].as_str().unwrap().to_string())
        .collect();
    want.push("segmentation.json".into());
    want.sort();
    let mut have: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    have.sort();
    assert_eq!(have, want);
    // A failure (an impossible size) leaves it as it was.
    let before = snapshot(&out);
    fails(
        &[
            "segment",
            "--capture",
            s(capture()),
            "--size",
            "100000",
            "--out",
            s(&out),
        ],
        &["--size", "limit"],
    );
    assert_eq!(snapshot(&out), before);
    // Something we did not write is never removed.
    std::fs::write(out.join("notes.md"), "mine").unwrap();
    let before = snapshot(&out);
    fails(
        &[
            "segment",
            "--capture",
            s(capture()),
            "--alpha",
            "0",
            "--out",
            s(&out),
        ],
        &["notes.md"],
    );
    assert_eq!(snapshot(&out), before);
}

#[test]
fn run_refuses_a_capture_folder_it_did_not_write() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    std::fs::create_dir_all(out.join("capture")).unwrap();
    std::fs::write(out.join("capture/photo.jpg"), "mine").unwrap();
    let before = snapshot(&out.join("capture"));
    fails(
        &[
            "run",
            "--preset",
            "scene1",
            "--device",
            "pixel4",
            "--out",
            s(&out),
            "--no-lpips",
            "--quiet",
            "--size",
            "16",
            "--views",
            "2",
            "--test-views",
            "1",
        ],
        &["capture", "nerflex-run.json", "--capture", "--out"],
    );
    assert_eq!(snapshot(&out.join("capture")), before);
}

#[test]
fn sizes_beyond_memory_are_refused_before_allocating() {
    let tmp = tempfile::tempdir().unwrap();
    // --frames 2³²: refused before the scene or the assets are read.
    fails(
        &[
            "simulate",
            "--scene",
            "/nonexistent.json",
            "--device",
            "pixel4",
            "--method",
            "dp",
            "--frames",
            "4294967296",
        ],
        &["--frames 4294967296", "limit"],
    );
    fails(
        &[
            "run",
            "--preset",
            "scene1",
            "--device",
            "pixel4",
            "--out",
            s(&tmp.path().join("r")),
            "--frames",
            "4294967296",
            "--no-lpips",
        ],
        &["--frames", "limit"],
    );
    // Two 8192² PNGs with LPIPS: refused, not aborted.
    let (a, b) = (tmp.path().join("a.png"), tmp.path().join("b.png"));
    png(&a, 8192, 8192);
    std::fs::copy(&a, &b).unwrap();
    let w = tmp.path().join("w.safetensors");
    lpips_file(&w, &|_| 0.01);
    fails(
        &["metrics", s(&a), s(&b), "--lpips-weights", s(&w)],
        &["8192×8192", "limit"],
    );
}

#[test]
fn a_two_million_entry_scene_list_is_refused_quickly() {
    let tmp = tempfile::tempdir().unwrap();
    let g: Vec<u32> = (1..=2_000_000).collect();
    let scene = serde_json::json!({"objects": [{"name": "x", "profile": {
        "g": g, "p": [1],
        "size": {"k": 1.0, "a": 1.0, "b": 1.0, "m": 0.0},
        "quality": {"k": 0.5, "a": 0.0, "b": 0.0, "m": 0.0}
    }}]});
    let path = tmp.path().join("scene.json");
    std::fs::write(&path, scene.to_string()).unwrap();
    let t0 = Instant::now();
    fails(
        &["plan", "--scene", s(&path), "--device", "pixel4"],
        &["scene.json", "profile.g"],
    );
    assert!(t0.elapsed() < Duration::from_secs(20), "{:?}", t0.elapsed());
}

#[test]
fn eval_checks_its_real_captures_first() {
    let tmp = tempfile::tempdir().unwrap();
    let t0 = Instant::now();
    fails(
        &[
            "eval",
            "--scenes",
            "scene1",
            "--real",
            "/nonexistent/lego",
            "--out",
            s(&tmp.path().join("e")),
            "--no-lpips",
            "--quiet",
        ],
        &["--real", "/nonexistent/lego"],
    );
    assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
}

#[test]
fn lpips_weights_are_checked_on_load() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a.png"), tmp.path().join("b.png"));
    png(&a, 64, 64);
    png(&b, 64, 64);
    let nan = tmp.path().join("nan.safetensors");
    lpips_file(&nan, &|n| {
        if n.starts_with("alexnet.conv2") {
            f32::NAN
        } else {
            0.01
        }
    });
    fails(
        &["metrics", s(&a), s(&b), "--lpips-weights", s(&nan)],
        &["nan.safetensors", "alexnet.conv2", "not finite"],
    );
    let neg = tmp.path().join("neg.safetensors");
    lpips_file(&neg, &|n| if n.starts_with("lin") { -1.0 } else { 0.01 });
    fails(
        &["metrics", s(&a), s(&b), "--lpips-weights", s(&neg)],
        &["neg.safetensors", "lin0.kernel", "negative"],
    );
    let ok = tmp.path().join("ok.safetensors");
    lpips_file(&ok, &|_| 0.01);
    assert_eq!(
        nerflex(&["metrics", s(&a), s(&b), "--lpips-weights", s(&ok)]).0,
        0
    );
}

#[test]
fn an_asset_without_faces_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let asset = tmp.path().join("asset");
    bake_into(&asset);
    std::fs::write(asset.join("shape0.obj"), "").unwrap();
    let png = tmp.path().join("r.png");
    fails(
        &[
            "render",
            "--asset",
            s(&asset),
            "--size",
            "32",
            "--out",
            s(&png),
        ],
        &["no faces"],
    );
    assert!(!png.exists());
}

#[cfg(unix)]
#[test]
fn a_fifo_is_refused_instead_of_blocking() {
    let tmp = tempfile::tempdir().unwrap();
    let asset = tmp.path().join("asset");
    bake_into(&asset);
    std::fs::remove_file(asset.join("mlp.json")).unwrap();
    let made = std::process::Command::new("mkfifo")
        .arg(asset.join("mlp.json"))
        .status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("SKIPPED a_fifo_is_refused_instead_of_blocking: mkfifo unavailable");
        return;
    }
    let out = tmp.path().join("r.png");
    let (tx, rx) = std::sync::mpsc::channel();
    let args: [String; 7] = [
        "render".to_string(),
        "--asset".into(),
        s(&asset).into(),
        "--size".into(),
        "32".into(),
        "--out".into(),
        s(&out).into(),
    ];
    std::thread::spawn(move || {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let _ = tx.send(nerflex(&a));
    });
    let (code, msg) = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("render blocked on a FIFO mlp.json");
    assert_eq!(code, 1, "{msg}");
    assert!(
        msg.contains("mlp.json") && msg.contains("not a regular file"),
        "{msg}"
    );
}

#[test]
fn concurrent_sweeps_storing_one_key_do_not_collide() {
    use nerflex_sim::bake::sweep::{Cache, Sample};
    let tmp = tempfile::tempdir().unwrap();
    let sample = Sample {
        object: "ball".into(),
        g: 8,
        p: 3,
        size_bytes: 1,
        gpu_bytes: 2,
        quads: 3,
        ssim: 0.9,
        psnr: 30.0,
        lpips: None,
    };
    std::thread::scope(|sc| {
        for _ in 0..4 {
            sc.spawn(|| {
                let c = Cache::new(tmp.path());
                for _ in 0..200 {
                    c.put("k", &sample).unwrap();
                }
            });
        }
    });
    assert_eq!(Cache::new(tmp.path()).get("k"), Some(sample));
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1);
}
