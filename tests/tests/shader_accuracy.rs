//! Fixed-point shaders vs the `f64` reference on real MobileNeRF data:
//! every occupied texel of the drums atlas × 64 view directions × every
//! weight set in `mobilenerf/weights/` and `drums/mlp.json`, for the exact
//! shader (`FixedMlp`) and the narrow one (`NarrowMlp`, 16-bit weights and
//! activations, 32-bit accumulators).
//!
//! Pass: the 8-bit RGB is within 1 step of the rounded `f64` result for
//! ≥ 99.9 % of samples and never more than 2 steps away. The error
//! histogram is printed (run with `--nocapture` to see it). The narrow test
//! also checks that the batched paths (portable, AVX2 when the CPU has it)
//! give exactly the per-pixel narrow result on every sample.

use nerflex_core::shader::narrow::batch::{self, BatchInput, LANES};
use nerflex_core::shader::narrow::{check_samples, NarrowMlp, WeightBits, INPUT_PAIRS};
use nerflex_core::shader::{mlp_input_f64, mlp_logits_f64, FixedMlp, MlpWeights, ViewDir};
use nerflex_sim::asset::{mlp_json, png_io};
use std::collections::HashMap;
use std::path::Path;

/// `n` directions spread evenly over the sphere (Fibonacci lattice).
fn sphere_directions(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// A distinct (feat0, feat1) texel pair and how many texels have it.
type Texel = ([u8; 4], [u8; 4], u64);

/// Distinct occupied texels (feat0.R ≠ 0) of a page pair, and their total.
fn occupied_texels(dir: &Path) -> (Vec<Texel>, u64) {
    let f0 = png_io::read_rgba8(&dir.join("shape2.pngfeat0.png")).unwrap();
    let f1 = png_io::read_rgba8(&dir.join("shape2.pngfeat1.png")).unwrap();
    let mut counts: HashMap<([u8; 4], [u8; 4]), u64> = HashMap::new();
    let mut total = 0;
    for (a, b) in f0.pixels().zip(f1.pixels()) {
        if a.0[0] != 0 {
            *counts.entry((a.0, b.0)).or_default() += 1;
            total += 1;
        }
    }
    let mut v: Vec<_> = counts.into_iter().map(|((a, b), n)| (a, b, n)).collect();
    v.sort_unstable();
    (v, total)
}

/// Histogram of max |shader − reference| over RGB, in 8-bit steps (index 3 = "≥ 3").
fn histogram(
    w: &MlpWeights,
    texels: &[Texel],
    dirs: &[[f64; 3]],
    shade: &(dyn Fn([u8; 4], [u8; 4], ViewDir) -> [u8; 3] + Sync),
) -> [u64; 4] {
    let qdirs: Vec<(ViewDir, [f64; 3])> = dirs
        .iter()
        .map(|&d| (ViewDir::from_f64(d).unwrap(), d))
        .collect();
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let chunk = texels.len().div_ceil(threads);
    std::thread::scope(|s| {
        let handles: Vec<_> = texels
            .chunks(chunk.max(1))
            .map(|part| {
                let qdirs = &qdirs;
                s.spawn(move || {
                    let mut h = [0u64; 4];
                    for &(f0, f1, n) in part {
                        for &(q, d) in qdirs {
                            let got = shade(f0, f1, q);
                            // The f64 reference: logits, then σ rounded to 8 bits
                            // (std's exp: faster than no_std libm's, same values
                            // to within an ulp).
                            let want = mlp_logits_f64(w, &mlp_input_f64(f0, f1, d))
                                .map(|z| (255.0 / (1.0 + (-z).exp())).round() as u8);
                            let e = got
                                .iter()
                                .zip(want)
                                .map(|(a, b)| (*a as i32 - b as i32).unsigned_abs())
                                .max()
                                .unwrap_or(0);
                            h[(e as usize).min(3)] += n;
                        }
                    }
                    h
                })
            })
            .collect();
        let mut h = [0u64; 4];
        for t in handles {
            let r = t.join().unwrap();
            for (a, b) in h.iter_mut().zip(r) {
                *a += b;
            }
        }
        h
    })
}

/// The real weight sets, each distinct content once: (name, weights).
fn weight_sets(mn: &Path) -> Vec<(String, MlpWeights)> {
    let mut sets: Vec<(String, Vec<u8>)> = Vec::new();
    for name in ["chair_mlp.json", "drums_mlp.json", "lego_mlp.json"] {
        let p = mn.join("weights").join(name);
        sets.push((format!("weights/{name}"), std::fs::read(&p).unwrap()));
    }
    sets.push((
        "drums/mlp.json".into(),
        std::fs::read(mn.join("drums/mlp.json")).unwrap(),
    ));
    let mut done: Vec<(String, Vec<u8>)> = Vec::new();
    let mut out = Vec::new();
    for (name, bytes) in sets {
        // Identical files give identical results: evaluate each content once.
        if let Some((same, _)) = done.iter().find(|(_, b)| *b == bytes) {
            println!("{name}: byte-identical to {same}, same result");
            continue;
        }
        let (w, _) = mlp_json::parse(std::str::from_utf8(&bytes).unwrap()).unwrap();
        out.push((name.clone(), w));
        done.push((name, bytes));
    }
    out
}

/// Runs `shader(w)` over the drums samples for every weight set and checks
/// the criterion.
fn check_real(
    what: &str,
    shader: impl Fn(&MlpWeights) -> Box<dyn Fn([u8; 4], [u8; 4], ViewDir) -> [u8; 3] + Sync>,
) {
    let Some(data) = nerflex_sim::data::require_data(what) else {
        return;
    };
    let mn = data.join("mobilenerf");
    let (texels, total) = occupied_texels(&mn.join("drums"));
    let dirs = sphere_directions(64);
    println!(
        "{what}: drums shape2 atlas: {total} occupied texels ({} distinct feature pairs), {} directions",
        texels.len(),
        dirs.len()
    );
    println!("| weight set | samples | exact | 1 step | 2 steps | ≥3 steps | within 1 |");
    println!("|---|---|---|---|---|---|---|");
    for (name, w) in weight_sets(&mn) {
        let shade = shader(&w);
        let h = histogram(&w, &texels, &dirs, &*shade);
        let n: u64 = h.iter().sum();
        assert_eq!(n, total * dirs.len() as u64);
        let within1 = (h[0] + h[1]) as f64 / n as f64;
        println!(
            "| {name} | {n} | {} | {} | {} | {} | {:.5} % |",
            h[0],
            h[1],
            h[2],
            h[3],
            100.0 * within1
        );
        assert!(within1 >= 0.999, "{name}: only {within1} within one step");
        assert_eq!(h[3], 0, "{name}: {} samples ≥ 3 steps off", h[3]);
    }
}

#[test]
fn fixed_point_shader_matches_f64_on_real_drums_atlas_and_weights() {
    check_real("shader accuracy on real drums", |w| {
        let m = FixedMlp::from_weights(w).unwrap();
        Box::new(move |f0, f1, d| m.shade(f0, f1, d))
    });
}

#[test]
fn narrow_shader_matches_f64_on_real_drums_atlas_and_weights() {
    check_real("narrow shader accuracy on real drums", |w| {
        let m = NarrowMlp::from_weights(w, WeightBits::Sixteen).unwrap();
        Box::new(move |f0, f1, d| m.shade(f0, f1, d))
    });
}

/// The build-time check picks the narrow shader for every real weight set,
/// and its batched paths equal the per-pixel one on every real sample.
#[test]
fn narrow_check_accepts_real_weights_and_batches_are_bit_identical() {
    let Some(data) = nerflex_sim::data::require_data("narrow batches on real drums") else {
        return;
    };
    let mn = data.join("mobilenerf");
    let (texels, _) = occupied_texels(&mn.join("drums"));
    let dirs: Vec<ViewDir> = sphere_directions(64)
        .into_iter()
        .map(|d| ViewDir::from_f64(d).unwrap())
        .collect();
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    for (name, w) in weight_sets(&mn) {
        let (m, h) = NarrowMlp::choose(&w, || check_samples(2048, 8))
            .unwrap()
            .unwrap_or_else(|| panic!("{name}: the check rejects the narrow shader"));
        println!(
            "{name}: check picks weight_max {} ({:?} on {} samples)",
            m.weight_max,
            h.counts,
            h.total()
        );
        // Every 8th distinct texel pair (90 k) × 64 directions: 5.8 M samples.
        let samples: Vec<_> = texels
            .iter()
            .step_by(8)
            .flat_map(|&(f0, f1, _)| dirs.iter().map(move |&d| (f0, f1, d)))
            .collect();
        let mut checked = 0usize;
        for chunk in samples.chunks(LANES) {
            let mut x: BatchInput = [[0; LANES]; INPUT_PAIRS];
            for (lane, &(f0, f1, d)) in chunk.iter().enumerate() {
                batch::set_lane(&mut x, lane, f0, f1, d);
            }
            let portable = batch::shade_portable(&m, &x);
            #[allow(unsafe_code)]
            // SAFETY: only called when AVX2 was detected.
            let simd = avx2.then(|| unsafe { batch::avx2::shade(&m, &x) });
            for (lane, &(f0, f1, d)) in chunk.iter().enumerate() {
                let want = m.shade(f0, f1, d);
                assert_eq!(portable[lane], want, "{name}: portable batch differs");
                if let Some(s) = simd {
                    assert_eq!(s[lane], want, "{name}: AVX2 batch differs");
                }
                checked += 1;
            }
        }
        println!("{name}: {checked} samples, batches bit-identical (AVX2: {avx2})");
    }
}

/// `render` with the batched narrow shader against the exact shader on the
/// real drums asset: same coverage, colours within the narrow shader's error.
#[test]
fn narrow_batched_render_tracks_the_exact_render() {
    use nerflex_core::raster::glam::Vec3;
    use nerflex_sim::camera::{Camera, Intrinsics};
    use nerflex_sim::render::{narrow_tables, try_render_scene, try_render_scene_narrow};
    let Some(data) = nerflex_sim::data::require_data("narrow render on real drums") else {
        return;
    };
    let asset = nerflex_sim::asset::Asset::load(&data.join("mobilenerf/drums")).unwrap();
    let k = Intrinsics::from_fov_x(39.6f32.to_radians(), 800, 800);
    let cam = Camera::orbit(30.0, 30.0, 4.031, Vec3::ZERO, k);
    // One sample per pixel: the narrow shader has no supersampled path.
    let opts = nerflex_sim::render::RenderOptions {
        supersample: false,
        ..Default::default()
    };
    let narrow = narrow_tables(&[&asset]).unwrap();
    assert!(
        narrow[0].is_some(),
        "the drums weights pass the narrow check"
    );
    let (exact, se) = try_render_scene(&[&asset], &cam, &opts).unwrap();
    let (fast, sn) = try_render_scene_narrow(&[&asset], &cam, &opts, &narrow).unwrap();
    assert_eq!(se.pixels_shaded, sn.pixels_shaded);
    assert!(se.pixels_shaded > 10_000);
    let mut h = [0u64; 4];
    for (a, b) in exact.pixels().zip(fast.pixels()) {
        assert_eq!(a.0[3], b.0[3], "coverage differs");
        if a.0[3] == 0 {
            continue; // background
        }
        let e = (0..3).map(|c| a.0[c].abs_diff(b.0[c])).max().unwrap();
        h[usize::from(e).min(3)] += 1;
    }
    println!("narrow vs exact render, max RGB difference per shaded pixel: {h:?}");
    assert_eq!(h.iter().sum::<u64>(), se.pixels_shaded);
    assert_eq!(h[3], 0);
    assert!((h[0] + h[1]) * 1000 >= 999 * h.iter().sum::<u64>());
}
