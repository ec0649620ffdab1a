//! Shader throughput on one core: the exact fixed-point shader, the narrow
//! one (16-bit, per pixel and batched: portable and AVX2), `f32` and the
//! `f64` reference, in million shaded pixels per second, and the
//! multiply-adds per second that implies (the MLP is 480 multiply-adds per
//! pixel), beside this machine's peak for the batched shader's instruction
//! (`vpmaddwd`: 16 multiply-adds per instruction, 2 per cycle on the
//! Zen/Skylake ports, at the clock `/proc/cpuinfo` reports).
//!
//! Inputs are real occupied texels of the drums atlas with the drums MLP
//! when `../shared/data` is present, else pseudo-random texels and weights.
//!
//! `cargo bench -p nerflex-hostbench --bench shader`

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use nerflex_core::shader::narrow::batch::{self, BatchInput, LANES};
use nerflex_core::shader::narrow::{NarrowMlp, WeightBits, INPUT_PAIRS};
use nerflex_core::shader::{shade_f32, shade_f64, FixedMlp, MlpWeights, ViewDir, MACS_PER_PIXEL};
use std::hint::black_box;
use std::time::Instant;

const N: usize = 4096;

struct Input {
    weights: MlpWeights,
    texels: Vec<([u8; 4], [u8; 4])>,
    dirs_q: Vec<ViewDir>,
    dirs_f32: Vec<[f32; 3]>,
    dirs_f64: Vec<[f64; 3]>,
    source: &'static str,
}

fn lcg(s: &mut u64) -> u64 {
    *s = s
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    *s >> 33
}

fn input() -> Input {
    let mut seed = 42u64;
    let real = nerflex_sim::data::shared_data_dir().and_then(|d| {
        let dir = d.join("mobilenerf/drums");
        let (w, _) = nerflex_sim::asset::mlp_json::read(&dir.join("mlp.json")).ok()?;
        let f0 = nerflex_sim::asset::png_io::read_rgba8(&dir.join("shape2.pngfeat0.png")).ok()?;
        let f1 = nerflex_sim::asset::png_io::read_rgba8(&dir.join("shape2.pngfeat1.png")).ok()?;
        let occ: Vec<_> = f0
            .pixels()
            .zip(f1.pixels())
            .filter(|(a, _)| a.0[0] != 0)
            .map(|(a, b)| (a.0, b.0))
            .collect();
        let step = (occ.len() / N).max(1);
        Some((w, occ.into_iter().step_by(step).take(N).collect::<Vec<_>>()))
    });
    let (weights, texels, source) = match real {
        Some((w, t)) => (w, t, "real drums texels + drums MLP"),
        None => {
            let mut w = MlpWeights::ZERO;
            let mut r = || (lcg(&mut seed) % 2001) as f32 / 1000.0 - 1.0;
            w.w0.iter_mut().flatten().for_each(|v| *v = r());
            w.w1.iter_mut().flatten().for_each(|v| *v = r());
            w.w2.iter_mut().flatten().for_each(|v| *v = r());
            let t = (0..N)
                .map(|_| {
                    let v = lcg(&mut seed).to_le_bytes();
                    ([v[0] | 1, v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]])
                })
                .collect();
            (w, t, "pseudo-random texels and weights (no shared data)")
        }
    };
    let dirs_f64: Vec<[f64; 3]> = (0..N)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / N as f64;
            let r = (1.0 - z * z).sqrt();
            let a = 2.399963 * i as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect();
    Input {
        weights,
        texels,
        dirs_q: dirs_f64
            .iter()
            .map(|&d| ViewDir::from_f64(d).unwrap())
            .collect(),
        dirs_f32: dirs_f64.iter().map(|d| d.map(|v| v as f32)).collect(),
        dirs_f64,
        source,
    }
}

/// A plain timed loop, printed beside criterion's numbers: Mpix/s and MAC/s.
fn report(name: &str, mut f: impl FnMut() -> u64) -> f64 {
    let _ = f(); // warm up
    let t = Instant::now();
    let mut n = 0u64;
    let mut reps = 0;
    while t.elapsed().as_secs_f64() < 1.0 {
        n += f();
        reps += 1;
    }
    let s = t.elapsed().as_secs_f64();
    let mpix = n as f64 / s / 1e6;
    println!(
        "{name:>22}: {mpix:7.2} Mpix/s on one core = {:6.2} G multiply-adds/s ({MACS_PER_PIXEL} per pixel; {reps} reps)",
        mpix * MACS_PER_PIXEL as f64 / 1e3
    );
    mpix
}

/// The CPU clock `/proc/cpuinfo` reports (GHz), if any.
fn cpu_ghz() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("cpu MHz"))?;
    let mhz: f64 = line.split(':').nth(1)?.trim().parse().ok()?;
    Some(mhz / 1e3)
}

fn bench(c: &mut Criterion) {
    let inp = input();
    let fixed = FixedMlp::from_weights(&inp.weights).unwrap();
    println!(
        "shader inputs: {} ({} texels)",
        inp.source,
        inp.texels.len()
    );
    let run_fixed = || {
        let mut acc = 0u64;
        for (t, d) in inp.texels.iter().zip(&inp.dirs_q) {
            let c = fixed.shade(black_box(t.0), black_box(t.1), black_box(*d));
            acc += c[0] as u64;
        }
        black_box(acc);
        inp.texels.len() as u64
    };
    let run_f32 = || {
        let mut acc = 0u64;
        for (t, d) in inp.texels.iter().zip(&inp.dirs_f32) {
            let c = shade_f32(&inp.weights, black_box(t.0), black_box(t.1), black_box(*d));
            acc += c[0] as u64;
        }
        black_box(acc);
        inp.texels.len() as u64
    };
    let run_f64 = || {
        let mut acc = 0u64;
        for (t, d) in inp.texels.iter().zip(&inp.dirs_f64) {
            let c = shade_f64(&inp.weights, black_box(t.0), black_box(t.1), black_box(*d));
            acc += c[0] as u64;
        }
        black_box(acc);
        inp.texels.len() as u64
    };
    let narrow = NarrowMlp::from_weights(&inp.weights, WeightBits::Sixteen).unwrap();
    let run_narrow = || {
        let mut acc = 0u64;
        for (t, d) in inp.texels.iter().zip(&inp.dirs_q) {
            let c = narrow.shade(black_box(t.0), black_box(t.1), black_box(*d));
            acc += c[0] as u64;
        }
        black_box(acc);
        inp.texels.len() as u64
    };
    // Batches: inputs packed per pixel (as `render` does), then shaded.
    let run_batch = |simd: bool| {
        let mut acc = 0u64;
        let mut x: BatchInput = [[0; LANES]; INPUT_PAIRS];
        for (chunk, dirs) in inp.texels.chunks(LANES).zip(inp.dirs_q.chunks(LANES)) {
            for (lane, (t, d)) in chunk.iter().zip(dirs).enumerate() {
                batch::set_lane(&mut x, lane, black_box(t.0), black_box(t.1), black_box(*d));
            }
            #[allow(unsafe_code)]
            // SAFETY: `simd` is only set when AVX2 was detected.
            let c = if simd {
                unsafe { batch::avx2::shade(&narrow, &x) }
            } else {
                batch::shade_portable(&narrow, &x)
            };
            acc += c[0][0] as u64;
        }
        black_box(acc);
        inp.texels.len() as u64
    };
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    let fixed_mpix = report("fixed (exact)", run_fixed);
    report("narrow", run_narrow);
    report("narrow batch portable", || run_batch(false));
    if avx2 {
        let mpix = report("narrow batch AVX2", || run_batch(true));
        println!(
            "narrow batch AVX2 / fixed (exact): {:.2}× the pixels per second per core",
            mpix / fixed_mpix
        );
        if let Some(ghz) = cpu_ghz() {
            let peak = 32.0 * ghz;
            println!(
                "this machine's peak for vpmaddwd: 16 MAC × 2 per cycle × {ghz:.2} GHz = {peak:.0} G MAC/s per core; the AVX2 batch reaches {:.1} % of it",
                100.0 * mpix * MACS_PER_PIXEL as f64 / 1e3 / peak
            );
        }
    } else {
        println!("narrow batch AVX2: not run (this CPU has no AVX2)");
    }
    report("f32", run_f32);
    report("f64", run_f64);
    let mut g = c.benchmark_group("shader");
    g.throughput(Throughput::Elements(inp.texels.len() as u64));
    g.bench_function("fixed", |b| {
        b.iter_batched(|| (), |_| run_fixed(), BatchSize::SmallInput)
    });
    g.bench_function("narrow", |b| {
        b.iter_batched(|| (), |_| run_narrow(), BatchSize::SmallInput)
    });
    if avx2 {
        g.bench_function("narrow_batch_avx2", |b| {
            b.iter_batched(|| (), |_| run_batch(true), BatchSize::SmallInput)
        });
    }
    g.bench_function("f32", |b| {
        b.iter_batched(|| (), |_| run_f32(), BatchSize::SmallInput)
    });
    g.bench_function("f64_reference", |b| {
        b.iter_batched(|| (), |_| run_f64(), BatchSize::SmallInput)
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
