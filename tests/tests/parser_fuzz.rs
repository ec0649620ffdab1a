//! Error, never panic: every parser of a user file (OBJ, mlp.json,
//! transforms, scene JSON, device TOML, samples CSV, safetensors) on
//! arbitrary bytes and on valid files with random byte edits.
//!
//! proptest fails a case that panics; each case only asserts that the
//! parser returns (Ok or Err). Case counts keep the file to a few seconds.

use std::path::Path;

use nerflex_sim::asset::{mlp_json, obj};
use nerflex_sim::bake::sweep::{self, CSV_HEADER};
use nerflex_sim::camera::Transforms;
use nerflex_sim::device::Device;
use nerflex_sim::fit::samples;
use nerflex_sim::metrics::Lpips;
use nerflex_sim::scene_file;
use proptest::prelude::*;

const OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n\
                   f 1/1 2/2 4/4\nf 1/1 4/4 3/3\n";
const TRANSFORMS: &str = r#"{"camera_angle_x": 0.69, "fl_x": 100.0, "w": 64, "h": 64, "frames": [
  {"file_path": "./train/r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]},
  {"file_path": "./train/r_1", "fl_x": 90, "transform_matrix": [[0,-1,0,1],[1,0,0,0],[0,0,1,4],[0,0,0,1]]}]}"#;
const SCENE: &str = include_str!("../../examples/scenes/illustrative_two_objects_single.json");
const PROFILE_SCENE: &str = r#"{"objects": [{"name": "x", "profile": {"g": [8, 16], "p": [3, 5],
  "size": {"k": 1.0, "a": 1.0, "b": 1.0, "m": 0.0, "g_power": 2},
  "quality": {"k": 0.5, "a": 0.1, "b": 0.0, "m": 0.0}}}]}"#;
const DEVICE: &str = include_str!("../../sim/devices/pixel4.toml");

fn csv() -> String {
    format!(
        "{CSV_HEADER}\nlego,16,5,1000,2000,30,0.9,28.5,0.1\nlego,32,5,4000,8000,90,0.95,30.1,\n"
    )
}

fn mlp() -> String {
    let (weights, _) = nerflex_sim::bake::mlp_fit::design();
    mlp_json::to_string(&weights, 1)
}

/// A safetensors file of one F32 tensor `t` of shape [2, 2].
fn safetensors() -> Vec<u8> {
    let header = br#"{"t":{"dtype":"F32","shape":[2,2],"data_offsets":[0,16]}}"#;
    let mut b = (header.len() as u64).to_le_bytes().to_vec();
    b.extend_from_slice(header);
    for v in [1.0f32, -2.0, 0.5, 3.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

/// Random bytes, or `seed` with a few random byte edits (overwrite,
/// insert, delete, truncate): the second reaches far deeper into a parser.
fn mutated(seed: Vec<u8>) -> impl Strategy<Value = Vec<u8>> {
    let edits = prop::collection::vec((0usize..4, any::<prop::sample::Index>(), any::<u8>()), 1..8);
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..512),
        edits.prop_map(move |edits| {
            let mut b = seed.clone();
            for (kind, at, byte) in edits {
                let i = if b.is_empty() { 0 } else { at.index(b.len()) };
                match kind {
                    0 if !b.is_empty() => b[i] = byte,
                    1 => b.insert(i, byte),
                    2 if !b.is_empty() => {
                        b.remove(i);
                    }
                    _ => b.truncate(i),
                }
            }
            b
        }),
    ]
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn with_file<T>(bytes: &[u8], name: &str, f: impl FnOnce(&Path) -> T) -> T {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    f(&p)
}

#[test]
fn the_seeds_parse() {
    assert!(obj::parse(OBJ).is_ok());
    assert!(mlp_json::parse(&mlp()).is_ok());
    assert!(with_file(TRANSFORMS.as_bytes(), "t.json", Transforms::read).is_ok());
    assert!(scene_file::parse(SCENE, "s.json").is_ok());
    assert!(scene_file::parse(PROFILE_SCENE, "s.json").is_ok());
    assert!(Device::from_toml_str(DEVICE, "d.toml").is_ok());
    assert!(samples::parse(&csv(), "s.csv").is_ok());
    assert!(with_file(csv().as_bytes(), "s.csv", sweep::read_csv).is_ok());
    // A valid safetensors file without LPIPS's tensors: a named error.
    let e = with_file(&safetensors(), "w.safetensors", |p| Lpips::load(p)).unwrap_err();
    assert!(e.to_string().contains("alexnet.conv0"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn obj_errs_never_panics(b in mutated(OBJ.into())) {
        let _ = obj::parse(&text(&b));
    }

    #[test]
    fn mlp_json_errs_never_panics(b in mutated(mlp().into_bytes())) {
        let _ = mlp_json::parse(&text(&b));
    }

    #[test]
    fn scene_json_errs_never_panics(b in mutated(SCENE.into()), p in mutated(PROFILE_SCENE.into())) {
        let _ = scene_file::parse(&text(&b), "s.json");
        let _ = scene_file::parse(&text(&p), "s.json");
    }

    #[test]
    fn device_toml_errs_never_panics(b in mutated(DEVICE.into())) {
        let _ = Device::from_toml_str(&text(&b), "d.toml");
    }

    #[test]
    fn samples_csv_errs_never_panics(b in mutated(csv().into_bytes())) {
        let _ = samples::parse(&text(&b), "s.csv");
    }
}

proptest! {
    // These read real files (a temporary folder per case).
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn transforms_errs_never_panics(b in mutated(TRANSFORMS.into())) {
        let _ = with_file(&b, "transforms_train.json", Transforms::read);
    }

    #[test]
    fn sweep_csv_errs_never_panics(b in mutated(csv().into_bytes())) {
        let _ = with_file(&b, "samples.csv", sweep::read_csv);
    }

    #[test]
    fn safetensors_errs_never_panics(b in mutated(safetensors())) {
        prop_assert!(with_file(&b, "w.safetensors", |p| Lpips::load(p)).is_err());
    }

    #[test]
    fn mlp_json_files_err_never_panic(b in mutated(mlp().into_bytes())) {
        let _ = with_file(&b, "mlp.json", mlp_json::read);
    }
}
