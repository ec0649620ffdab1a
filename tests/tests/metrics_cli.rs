//! `nerflex metrics`: output formats, LPIPS weights lookup, errors naming files.

use nerflex_sim::cli::metrics::{report, Args};
use nerflex_sim::metrics::{Rgba, RgbaImage};
use std::path::{Path, PathBuf};

fn args(a: &Path, b: &Path) -> Args {
    Args {
        a: a.to_owned(),
        b: b.to_owned(),
        lpips_weights: None,
        json: false,
    }
}

/// Writes a `w`×`h` gradient PNG (with `shade` mixed in) to `dir/name`.
fn png(dir: &Path, name: &str, w: u32, h: u32, shade: u8) -> PathBuf {
    let img = RgbaImage::from_fn(w, h, |x, y| {
        Rgba([(x * 7) as u8 ^ shade, (y * 5) as u8, shade, 255])
    });
    let path = dir.join(name);
    img.save(&path).unwrap();
    path
}

#[test]
fn text_and_json_reports() {
    let dir = tempfile::tempdir().unwrap();
    let a = png(dir.path(), "a.png", 40, 36, 0);
    let b = png(dir.path(), "b.png", 40, 36, 30);
    let lpips_weights =
        nerflex_tests::shared_data_dir().map(|d| d.join("lpips/alexnet_lpips_v0.1.safetensors"));

    let mut same = args(&a, &a);
    same.lpips_weights = lpips_weights.clone();
    let text = report(&same).unwrap();
    assert!(text.contains("SSIM   1.000000"), "{text}");
    assert!(text.contains("PSNR   inf dB"), "{text}");
    if lpips_weights.is_some() {
        assert!(text.contains("LPIPS  0.000000"), "{text}");
    }

    let mut diff = args(&a, &b);
    diff.json = true;
    diff.lpips_weights = lpips_weights.clone();
    let v: serde_json::Value = serde_json::from_str(&report(&diff).unwrap()).unwrap();
    let ssim = v["ssim"].as_f64().unwrap();
    assert!(ssim < 1.0 && ssim > -1.0, "{v}");
    assert!(v["psnr"].as_f64().unwrap().is_finite(), "{v}");
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(40), Some(36))
    );
    if lpips_weights.is_some() {
        assert!(v["lpips"].as_f64().unwrap() > 0.0, "{v}");
        assert!(v["lpips_skipped"].is_null());
    }

    same.json = true;
    let v: serde_json::Value = serde_json::from_str(&report(&same).unwrap()).unwrap();
    assert!(v["psnr"].is_null(), "identical → PSNR null in JSON: {v}");
}

#[test]
fn errors_name_the_files() {
    let dir = tempfile::tempdir().unwrap();
    let a = png(dir.path(), "first.png", 40, 36, 0);
    let small = png(dir.path(), "small.png", 20, 36, 0);
    let err = report(&args(&a, &small)).unwrap_err().to_string();
    assert!(
        err.contains("first.png") && err.contains("small.png") && err.contains("same size"),
        "{err}"
    );

    let err = report(&args(&a, &dir.path().join("missing.png")))
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.png"), "{err}");

    let text = dir.path().join("notes.png");
    std::fs::write(&text, "not an image").unwrap();
    let err = report(&args(&text, &a)).unwrap_err().to_string();
    assert!(
        err.contains("notes.png") && err.contains("not a PNG"),
        "{err}"
    );

    let mut bad_weights = args(&a, &a);
    bad_weights.lpips_weights = Some(dir.path().join("weights.safetensors"));
    let err = report(&bad_weights).unwrap_err().to_string();
    assert!(err.contains("weights.safetensors"), "{err}");
}
