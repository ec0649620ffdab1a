//! `nerflex segment`: flags, bad input and the printed table.

use nerflex_sim::cli::segment::{run, table, Args, Filter};
use nerflex_sim::segment::testscene::{ring_of_five, sphere_capture};
use nerflex_sim::segment::{segment, SegmentOptions};
use std::path::{Path, PathBuf};

fn args(capture: Option<&Path>, out: &Path) -> Args {
    Args {
        capture: capture.map(Path::to_path_buf),
        compose: Vec::new(),
        size: None,
        alpha: None,
        energy_share: 0.75,
        band: 32.0,
        min_pixels: 64,
        margin: 0.0,
        filter: Filter::Lanczos3,
        out: out.to_path_buf(),
    }
}

fn error_of(a: Args) -> String {
    format!("{:#}", run(a).unwrap_err())
}

#[test]
fn bad_flags_and_inputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let missing = dir.path().join("no-such-capture");
    let e = error_of(args(Some(&missing), &out));
    assert!(
        e.contains("--capture") && e.contains("no-such-capture"),
        "{e}"
    );

    let mut a = args(Some(&missing), &out);
    a.energy_share = 1.5;
    assert!(error_of(a).contains("--energy-share"));
    let mut a = args(Some(&missing), &out);
    a.band = 0.0;
    assert!(error_of(a).contains("--band"));
    let mut a = args(Some(&missing), &out);
    a.margin = -0.1;
    assert!(error_of(a).contains("--margin"));
    let mut a = args(Some(&missing), &out);
    a.size = Some(0);
    assert!(error_of(a).contains("--size"));

    // A malformed transforms file names the file.
    let cap = dir.path().join("cap");
    std::fs::create_dir_all(&cap).unwrap();
    std::fs::write(cap.join("transforms_train.json"), "{ not json").unwrap();
    let e = error_of(args(Some(&cap), &out));
    assert!(e.contains("transforms_train.json"), "{e}");

    // A frame whose image is missing names the image.
    std::fs::write(
        cap.join("transforms_train.json"),
        r#"{"camera_angle_x": 0.69, "frames": [{"file_path": "./train/r_0",
            "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]}"#,
    )
    .unwrap();
    let e = error_of(args(Some(&cap), &out));
    assert!(e.contains("r_0.png"), "{e}");

    // A compose source that does not exist is named.
    let mut a = args(None, &out);
    a.compose = vec![missing.clone(), PathBuf::from("also-missing")];
    let e = error_of(a);
    assert!(
        e.contains("--compose") && e.contains("no-such-capture"),
        "{e}"
    );
}

#[test]
fn a_negative_alpha_is_refused_before_anything_is_written() {
    let cap = sphere_capture(&ring_of_five(), 2, 0, 96);
    let dir = tempfile::tempdir().unwrap();
    let opts = SegmentOptions {
        alpha: Some(-1.0),
        ..Default::default()
    };
    let e = segment(&cap, &opts, dir.path()).unwrap_err().to_string();
    assert!(e.contains("--alpha"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn the_table_lists_objects_by_decreasing_frequency_with_decisions() {
    let cap = sphere_capture(&ring_of_five(), 3, 0, 160);
    let dir = tempfile::tempdir().unwrap();
    let seg = segment(&cap, &SegmentOptions::default(), dir.path()).unwrap();
    let t = table(&seg);
    eprintln!("{t}");
    let lines: Vec<&str> = t.lines().collect();
    assert!(lines[0].contains("max freq") && lines[0].contains("decision"));
    let order: Vec<&str> = lines[1..6]
        .iter()
        .map(|l| l.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(order, vec!["s24", "s12", "s06", "s03", "s01"]);
    assert!(lines[5].contains("shared") && lines[1].contains("dedicated"));
    assert!(t.contains("lowest maximum"));
}

#[test]
fn a_colour_mask_or_a_label_without_an_object_is_refused_naming_the_file() {
    use nerflex_sim::capture::SceneInfo;
    use nerflex_sim::segment::SegCapture;
    let cap = sphere_capture(&ring_of_five(), 2, 0, 96);
    let dir = tempfile::tempdir().unwrap();
    let seg = segment(
        &cap,
        &SegmentOptions {
            alpha: Some(1e9),
            ..Default::default()
        },
        dir.path(),
    )
    .unwrap();
    let shared = dir.path().join(&seg.groups[0].folder);
    let names = ["s01", "s03", "s06", "s12", "s24"];
    assert_eq!(SegCapture::load(&shared).unwrap().objects, names);
    // scene.json naming fewer objects than the masks use.
    let scene_path = shared.join("scene.json");
    let mut scene = SceneInfo::read(&scene_path).unwrap();
    scene.objects.truncate(1);
    scene.write(&scene_path).unwrap();
    let e = SegCapture::load(&shared).unwrap_err().to_string();
    assert!(e.contains("mask value") && e.contains("scene.json"), "{e}");
    std::fs::write(&scene_path, r#"{"objects": [{"nom": "a"}]}"#).unwrap();
    let e = SegCapture::load(&shared).unwrap_err().to_string();
    assert!(e.contains("scene.json"), "{e}");
    // Without scene.json the objects are named by their mask labels.
    std::fs::remove_file(&scene_path).unwrap();
    let unnamed = SegCapture::load(&shared).unwrap().objects;
    assert_eq!(
        unnamed,
        ["object1", "object2", "object3", "object4", "object5"]
    );
    // An RGBA file where a grayscale mask belongs.
    std::fs::copy(
        shared.join("train/r_0.png"),
        shared.join("train/r_0_mask.png"),
    )
    .unwrap();
    let e = SegCapture::load(&shared).unwrap_err().to_string();
    assert!(e.contains("r_0_mask.png") && e.contains("grayscale"), "{e}");
}
