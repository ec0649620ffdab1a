//! Full 800×800 frames of the real drums shape at a few turntable angles:
//! one sample per pixel with fixed-point (exact, per pixel), narrow
//! (batched: AVX2 when present) and `f32` shading; the default 2 × 2
//! supersampled render (`supersampled/…`); and the coverage-only pass the
//! device simulator uses. Tiles run in parallel on all cores (rayon); a
//! single-thread pool gives the one-core figure.
//!
//! Needs `../shared/data` (skips otherwise).
//! `cargo bench -p nerflex-hostbench --bench render`

use criterion::{criterion_group, criterion_main, Criterion};
use nerflex_core::raster::glam::Vec3;
use nerflex_sim::asset::Asset;
use nerflex_sim::camera::{Camera, Intrinsics};
use nerflex_sim::render::{
    coverage, narrow_tables, rayon, render, try_render_scene_narrow, RenderOptions,
};
use std::hint::black_box;

const ANGLES: [f32; 3] = [0.0, 30.0, 120.0];

fn camera(angle: f32) -> Camera {
    let k = Intrinsics::from_fov_x(39.6f32.to_radians(), 800, 800);
    Camera::orbit(angle, 30.0, 4.031, Vec3::ZERO, k)
}

fn bench(c: &mut Criterion) {
    let Some(data) = nerflex_sim::data::require_data("render bench") else {
        return;
    };
    let asset = Asset::load(&data.join("mobilenerf/drums")).expect("drums asset");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let narrow = narrow_tables(&[&asset]).expect("narrow tables");
    // One sample per pixel (the figures recorded before supersampling
    // became the default).
    let one_sample = RenderOptions {
        float: false,
        supersample: false,
    };
    let narrow_render = |cam: &Camera| {
        try_render_scene_narrow(&[&asset], cam, &one_sample, &narrow).expect("renders")
    };
    let mut g = c.benchmark_group("render_drums_800");
    g.sample_size(20);
    for angle in ANGLES {
        let cam = camera(angle);
        let (_, s) = render(&asset, &cam, &one_sample);
        println!(
            "angle {angle}°: quads drawn {} of {}, visible {}, pixels shaded {}, fragments {}, discarded {}",
            s.quads_drawn, s.quads_total, s.quads_visible, s.pixels_shaded, s.tiles.fragments, s.tiles.discarded
        );
        g.bench_function(format!("fixed/{angle}"), |b| {
            b.iter(|| black_box(render(&asset, &cam, &one_sample)))
        });
        g.bench_function(format!("supersampled/{angle}"), |b| {
            b.iter(|| black_box(render(&asset, &cam, &RenderOptions::default())))
        });
        g.bench_function(format!("f32/{angle}"), |b| {
            b.iter(|| {
                black_box(render(
                    &asset,
                    &cam,
                    &RenderOptions {
                        float: true,
                        ..one_sample
                    },
                ))
            })
        });
        g.bench_function(format!("fixed_one_core/{angle}"), |b| {
            b.iter(|| one.install(|| black_box(render(&asset, &cam, &one_sample))))
        });
        g.bench_function(format!("narrow_one_core/{angle}"), |b| {
            b.iter(|| one.install(|| black_box(narrow_render(&cam))))
        });
        g.bench_function(format!("narrow/{angle}"), |b| {
            b.iter(|| black_box(narrow_render(&cam)))
        });
        g.bench_function(format!("coverage/{angle}"), |b| {
            b.iter(|| black_box(coverage(&asset, &cam)))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
