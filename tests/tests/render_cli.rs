//! `nerflex render` end to end on the real drums shape: the fixed-point and
//! `--float` PNGs it writes agree within 45 dB PSNR.

use nerflex_sim::asset::image;
use nerflex_sim::cli::render::{run, Args};
use std::path::PathBuf;

fn args(asset: PathBuf, out: PathBuf, float: bool) -> Args {
    Args {
        asset,
        angle: 30.0,
        elevation: 30.0,
        distance: 4.031,
        fov: 39.6,
        transforms: None,
        frame: None,
        size: "800".into(),
        float,
        narrow: false,
        no_supersample: false,
        out,
    }
}

/// PSNR (dB) over RGB (local helper; the metrics module is separate work).
fn psnr(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    let se: f64 = a
        .pixels()
        .zip(b.pixels())
        .flat_map(|(p, q)| (0..3).map(move |k| (p.0[k] as f64 - q.0[k] as f64).powi(2)))
        .sum();
    let mse = se / (a.width() as f64 * a.height() as f64 * 3.0);
    10.0 * (255.0f64.powi(2) / mse).log10()
}

#[test]
fn render_command_writes_fixed_and_float_pngs_that_agree() {
    let Some(data) = nerflex_sim::data::require_data("nerflex render CLI") else {
        return;
    };
    let asset = data.join("mobilenerf/drums");
    let tmp = tempfile::tempdir().unwrap();
    let (fixed, float, narrow) = (
        tmp.path().join("drums.png"),
        tmp.path().join("drums_float.png"),
        tmp.path().join("drums_narrow.png"),
    );
    // One sample per pixel: the narrow shader has no supersampled path.
    let one = |out: &PathBuf, float: bool| Args {
        no_supersample: true,
        ..args(asset.clone(), out.clone(), float)
    };
    run(one(&fixed, false)).unwrap();
    run(one(&float, true)).unwrap();
    let mut n = args(asset.clone(), narrow.clone(), false);
    n.narrow = true;
    run(n).unwrap();
    // The default 2 × 2 supersampled renders: fixed within one level of
    // float (each object's colour is, and so is their coverage-weighted
    // mean), and the same coverage as one sample per pixel where all four
    // subsamples agree.
    let (ss_fixed, ss_float) = (tmp.path().join("ss.png"), tmp.path().join("ss_float.png"));
    run(args(asset.clone(), ss_fixed.clone(), false)).unwrap();
    run(args(asset.clone(), ss_float.clone(), true)).unwrap();
    let (sa, sb) = (
        image::open(&ss_fixed).unwrap().to_rgba8(),
        image::open(&ss_float).unwrap().to_rgba8(),
    );
    for (p, q) in sa.pixels().zip(sb.pixels()) {
        assert_eq!(p.0[3], q.0[3], "supersampled coverage differs");
        for k in 0..3 {
            let d = (i32::from(p.0[k]) - i32::from(q.0[k])).abs();
            assert!(d <= 1, "supersampled fixed vs float: {d} levels");
        }
    }
    let partial = sa.pixels().filter(|p| p.0[3] > 0 && p.0[3] < 255).count();
    assert!(
        partial > 100,
        "edges are blended: {partial} partly covered pixels"
    );
    // The narrow shader is within one level of the exact one everywhere.
    let c = image::open(&narrow).unwrap().to_rgba8();
    let exact = image::open(&fixed).unwrap().to_rgba8();
    let worst = c
        .pixels()
        .zip(exact.pixels())
        .flat_map(|(p, q)| (0..4).map(move |k| (p.0[k] as i32 - q.0[k] as i32).abs()))
        .max()
        .unwrap();
    assert!(worst <= 1, "narrow vs exact: {worst} levels apart");
    let a = image::open(&fixed).unwrap().to_rgba8();
    let b = image::open(&float).unwrap().to_rgba8();
    assert_eq!(a.dimensions(), (800, 800));
    let p = psnr(&a, &b);
    println!("nerflex render --angle 30 --size 800: fixed vs --float PSNR {p:.1} dB");
    assert!(p >= 45.0, "{p}");
    assert!(a.pixels().filter(|p| p.0[3] == 255).count() > 5_000);
    // A dataset camera works too, and a bad frame index is a clear error.
    let t = data.join("nerf_synthetic/lego/transforms_test.json");
    let mut x = args(asset.clone(), tmp.path().join("t.png"), false);
    (x.transforms, x.frame, x.size) = (Some(t.clone()), Some(2), "200x100".into());
    run(x).unwrap();
    assert_eq!(image::open(tmp.path().join("t.png")).unwrap().width(), 200);
    let mut x = args(asset, tmp.path().join("t2.png"), false);
    (x.transforms, x.frame) = (Some(t), Some(99));
    let e = format!("{:#}", run(x).unwrap_err());
    assert!(e.contains("--frame 99") && e.contains("5 frames"), "{e}");
}
