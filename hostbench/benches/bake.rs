//! Benchmarks: the baker on the real lego capture (20 training views at
//! 800×800), at the speed point (g = 128, p = 17) and below, plus
//! the stages a sweep adds (asset conversion with PNG encoding, and the
//! MLP design). Skipped with a message without the shared data.

use criterion::{criterion_group, criterion_main, Criterion};
use nerflex_sim::bake::sweep::ObjectViews;
use nerflex_sim::bake::{self, mlp_fit, BakeParams};
use nerflex_sim::capture::Capture;
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    c.bench_function("bake/mlp_design", |b| b.iter(mlp_fit::design));

    let Some(data) = nerflex_sim::data::require_data("bake benchmark") else {
        return;
    };
    let cap = Capture::load(data.join("nerf_synthetic/lego")).unwrap_or_else(|e| panic!("{e}"));
    let obj = ObjectViews::from_capture(&cap, None).unwrap_or_else(|e| panic!("{e:#}"));
    let views = obj.bake_views();
    assert_eq!(views.len(), 20);

    let mut g = c.benchmark_group("bake_lego_20x800");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(20));
    for (grid, patch) in [(32, 9), (64, 9), (128, 17)] {
        g.bench_function(format!("bake_g{grid}_p{patch}"), |b| {
            b.iter(|| bake::bake(black_box(&views), &BakeParams::new(grid, patch)))
        });
    }
    // What `nerflex bake --out` adds: the Asset and its encoded files.
    let baked = bake::bake(&views, &BakeParams::new(128, 17)).unwrap_or_else(|e| panic!("{e}"));
    g.bench_function("asset_and_file_bytes_g128_p17", |b| {
        b.iter(|| {
            let asset = baked.clone().into_asset().unwrap_or_else(|e| panic!("{e}"));
            bake::file_bytes(&asset)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
