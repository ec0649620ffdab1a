//! Benchmarks of the profiler (the NeRFlex paper: 0.277 s for sample
//! generation and curve fitting).
//!
//! - `profiler/fit_object/*`: fitting both curves of one object (size and
//!   SSIM, every family tried, all LM starts) to a synthetic sweep of known
//!   parameters plus noise — the 20-point sweep grid (5 g × 4 p) and the
//!   paper's 12 variable-step points (16..512 × 3..33).
//! - `profiler/fit_real/*`: the same on real bakes from the committed sweep
//!   (`results/bake/samples.csv`): lego's 20 samples, its 9 variable-step
//!   samples (g {16, 64, 256} × p {5, 9, 17}), and all 14 objects (280
//!   samples, what `nerflex profile fit` does on the sweep; rayon over 2
//!   cores).
//! - `profiler/table/*`: fixed-point evaluation of a full configuration
//!   table (`nerflex_core::profiler::Profile::fill_table`), 45 configurations
//!   (our 9 g × 5 p grid; the paper gives none) and 256 (the solver's maximum), beside the `f64`
//!   reference.
//!
//! Run: `cargo bench -p nerflex-hostbench --bench profiler`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nerflex_core::mck::Config;
use nerflex_core::profiler::{ConfigSpace, Family, Params, Profile};
use nerflex_core::units::{Bytes, QualityQ};
use nerflex_sim::fit::{
    self,
    sampling::{self, Step},
    synthetic::{self, Noise},
    FamilyChoice,
};
use std::hint::black_box;

fn truth() -> (Params, Params) {
    (
        Params {
            k: 6.0,
            a: 2.0,
            b: 1.0,
            c: 0.0,
            m: 5.0e4,
            family: Family::Surface,
        },
        Params {
            k: 2.0e3,
            a: 4.0,
            b: 0.5,
            c: 0.0,
            m: 0.965,
            family: Family::Surface,
        },
    )
}

fn bench_fit(c: &mut Criterion) {
    let (s, q) = truth();
    let noise = Noise {
        size_rel: 0.02,
        ssim_abs: 0.003,
    };
    let plan = sampling::variable_step(16..=512, 3..=33, Step::Triple).unwrap();
    let cases = [
        (
            "sweep_5x4",
            synthetic::samples(
                "o",
                &s,
                &q,
                &[16, 32, 64, 128, 256],
                &[5, 9, 13, 17],
                noise,
                1,
            ),
        ),
        (
            "paper_plan_4x3",
            synthetic::samples("o", &s, &q, &plan.grids, &plan.patches, noise, 1),
        ),
    ];
    let mut group = c.benchmark_group("profiler/fit_object");
    for (name, samples) in &cases {
        let refs: Vec<_> = samples.iter().collect();
        for choice in [FamilyChoice::Auto, FamilyChoice::Volume] {
            let id = BenchmarkId::new(*name, format!("{choice:?}").to_lowercase());
            group.bench_function(id, |b| {
                b.iter(|| fit::fit_object("o", black_box(&refs), None, choice).unwrap())
            });
        }
    }
    group.finish();
}

fn bench_fit_real(c: &mut Criterion) {
    let csv = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../results/bake/samples.csv");
    let all = fit::samples::read(&csv).unwrap();
    let lego = fit::object::of_object(&all, "lego");
    let plan = sampling::variable_step_on(&[16, 32, 64, 128, 256], &[5, 9, 13, 17], Step::Triple);
    let lego_vs: Vec<_> = lego
        .iter()
        .copied()
        .filter(|s| plan.grids.contains(&s.g) && plan.patches.contains(&s.p))
        .collect();
    assert_eq!(lego_vs.len(), 9);
    let mut group = c.benchmark_group("profiler/fit_real");
    group.bench_function("lego_20", |b| {
        b.iter(|| fit::fit_object("lego", black_box(&lego), None, FamilyChoice::Auto).unwrap())
    });
    group.bench_function("lego_variable_step_9", |b| {
        b.iter(|| fit::fit_object("lego", black_box(&lego_vs), None, FamilyChoice::Auto).unwrap())
    });
    group.sample_size(20);
    group.bench_function("all_14_objects_280", |b| {
        b.iter(|| fit::fit_objects(black_box(&all), &[], None, FamilyChoice::Auto).unwrap())
    });
    group.finish();
}

fn bench_table(c: &mut Criterion) {
    let (s, q) = truth();
    let profile = Profile::from_params(&s, &q).unwrap();
    let paper_g: Vec<u32> = vec![16, 32, 48, 64, 96, 128, 192, 256, 384];
    let paper_p: Vec<u32> = vec![5, 9, 13, 17, 21];
    let max_g: Vec<u32> = (1..=16).map(|i| 32 * i).collect();
    let max_p: Vec<u32> = (1..=16).map(|i| 2 * i + 1).collect();
    let mut group = c.benchmark_group("profiler/table");
    for (name, gs, ps) in [("45", &paper_g, &paper_p), ("256", &max_g, &max_p)] {
        let space = ConfigSpace::new(gs, ps).unwrap();
        let mut out = [Config {
            size: Bytes(0),
            quality: QualityQ::ZERO,
        }; 256];
        group.bench_function(BenchmarkId::new("fixed", name), |b| {
            b.iter(|| {
                profile
                    .fill_table(black_box(&space), &mut out)
                    .map(|t| t.len())
                    .unwrap()
            })
        });
        group.bench_function(BenchmarkId::new("f64_reference", name), |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for (g, p) in black_box(&space).iter() {
                    acc += s.size_f64(g as f64, p as f64) + q.quality_f64(g as f64, p as f64);
                }
                acc
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_fit, bench_fit_real, bench_table);
criterion_main!(benches);
