//! Benchmarks: SSIM, PSNR and LPIPS on real 800×800 NeRF-synthetic images
//! (lego test views r_2 and r_22). Skipped with a message without the data.

use criterion::{criterion_group, criterion_main, Criterion};
use nerflex_sim::metrics::{self, Lpips, Metrics, WhiteComposite};
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let Some(data) = nerflex_sim::data::require_data("metrics benchmark") else {
        return;
    };
    let lego = data.join("nerf_synthetic/lego/test");
    let load = |name: &str| metrics::read_png(&lego.join(name)).unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = (load("r_2.png"), load("r_22.png"));
    let lpips = Lpips::load(data.join("lpips").join(metrics::LPIPS_WEIGHTS_FILE))
        .unwrap_or_else(|e| panic!("{e}"));
    let (ca, cb) = (WhiteComposite::new(&a), WhiteComposite::new(&b));

    let mut g = c.benchmark_group("metrics_800x800");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(8));
    g.bench_function("composite_over_white", |bench| {
        bench.iter(|| WhiteComposite::new(black_box(&a)))
    });
    g.bench_function("ssim", |bench| {
        bench.iter(|| metrics::ssim_composited(black_box(&ca), black_box(&cb)))
    });
    g.bench_function("psnr", |bench| {
        bench.iter(|| metrics::psnr_composited(black_box(&ca), black_box(&cb)))
    });
    g.bench_function("lpips_features_one_image", |bench| {
        bench.iter(|| lpips.features_composited(black_box(&ca)))
    });
    g.bench_function("lpips_pair", |bench| {
        bench.iter(|| lpips.distance_composited(black_box(&ca), black_box(&cb)))
    });
    g.bench_function("compare_all_three", |bench| {
        bench.iter(|| Metrics::compare(black_box(&a), black_box(&b), Some(&lpips)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
