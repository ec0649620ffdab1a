//! Solve time of the exact MCK configuration selector: a paper-sized problem
//! (5 objects × 45 configurations, H = 240 MB in 0.1 MB units — the unit and
//! the 9 × 5 grid are our choices, not the paper's; the paper reports 1.87 s
//! for its DP) and its growth with objects, configurations
//! and budget resolution.
//!
//! `cargo bench -p nerflex-hostbench --bench mck`, then
//! `cargo run -p nerflex-hostbench --bin summary`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nerflex_core::mck::{Config, Item, Solver, TableLens, Tables};
use nerflex_core::units::Bytes;
use nerflex_hostbench::{
    synthetic_objects, PAPER_BUDGET, PAPER_CONFIGS, PAPER_OBJECTS, PAPER_UNIT,
};
use std::hint::black_box;

/// Heap tables sized for a problem (the growth series goes beyond what a
/// stack-allocated `Solver` should hold).
struct Heap {
    best: Vec<u64>,
    choice: Vec<u8>,
    items: Vec<Item>,
    picked: Vec<u8>,
}

impl Heap {
    fn new(objects: usize, configs: usize, units: usize) -> Heap {
        let l = TableLens::new(objects, configs, units);
        Heap {
            best: vec![0; l.best],
            choice: vec![0; l.choice],
            items: vec![Item::EMPTY; l.items],
            picked: vec![0; l.picked],
        }
    }

    fn solve(&mut self, objects: &[Vec<Config>], budget: Bytes, unit: Bytes) -> u64 {
        let s = Tables::new(
            &mut self.best,
            &mut self.choice,
            &mut self.items,
            &mut self.picked,
        )
        .solve(objects, budget, unit)
        .expect("the benchmark instances are feasible");
        s.total_quality.0
    }
}

fn paper(c: &mut Criterion) {
    let objects = synthetic_objects(PAPER_OBJECTS, PAPER_CONFIGS);
    // The firmware's configuration: tables inline, sized by const generics.
    let mut solver = Box::new(Solver::<PAPER_OBJECTS, PAPER_CONFIGS, 2400>::new());
    let mut g = c.benchmark_group("mck");
    g.bench_function("paper", |b| {
        b.iter(|| {
            let s = solver
                .solve(black_box(&objects), black_box(PAPER_BUDGET), PAPER_UNIT)
                .expect("feasible");
            s.total_quality.0
        })
    });
    g.finish();
}

fn growth(c: &mut Criterion) {
    let mut g = c.benchmark_group("mck_objects");
    for n in [5usize, 10, 20, 50, 100] {
        let objects = synthetic_objects(n, PAPER_CONFIGS);
        let mut heap = Heap::new(n, PAPER_CONFIGS, 2400);
        g.bench_with_input(BenchmarkId::from_parameter(n), &objects, |b, o| {
            b.iter(|| heap.solve(black_box(o), PAPER_BUDGET, PAPER_UNIT))
        });
    }
    g.finish();

    let mut g = c.benchmark_group("mck_configs");
    for k in [9usize, 25, 45, 70, 100] {
        let objects = synthetic_objects(PAPER_OBJECTS, k);
        let mut heap = Heap::new(PAPER_OBJECTS, k, 2400);
        g.bench_with_input(BenchmarkId::from_parameter(k), &objects, |b, o| {
            b.iter(|| heap.solve(black_box(o), PAPER_BUDGET, PAPER_UNIT))
        });
    }
    g.finish();

    // Budget resolution: unit in bytes, 1 MB … 10 KB (240 … 24 000 units).
    let mut g = c.benchmark_group("mck_unit_bytes");
    let objects = synthetic_objects(PAPER_OBJECTS, PAPER_CONFIGS);
    for unit in [1_000_000u64, 500_000, 100_000, 50_000, 20_000, 10_000] {
        let units = (PAPER_BUDGET.0 / unit) as usize;
        let mut heap = Heap::new(PAPER_OBJECTS, PAPER_CONFIGS, units);
        g.bench_with_input(BenchmarkId::from_parameter(unit), &objects, |b, o| {
            b.iter(|| heap.solve(black_box(o), PAPER_BUDGET, Bytes(unit)))
        });
    }
    g.finish();
}

criterion_group!(benches, paper, growth);
criterion_main!(benches);
