//! Benchmarks: detail-based segmentation of twenty 800×800 views, printed
//! beside the NeRFlex paper's 3.8 s for twenty images (object recognition,
//! segmentation and interpolation).
//!
//! Input: the built-in five-object `scene4`, rendered once (not timed) with
//! 20 training views of 800×800 — our captures carry their instance masks,
//! so there is no recognition network to run. With `../shared/data`
//! present, the real lego + chair composite (20 views of 1600×800, i.e. 40
//! source images of 800×800) is timed too.
//!
//! The summary times whole runs (median of three, wall clock and this
//! process' CPU seconds, since the machine may be shared); criterion then
//! times the stages.

use criterion::{criterion_group, criterion_main, Criterion};
use nerflex_sim::procedural::{arrange, make_capture, CaptureSpec, Layout, Preset, RenderOptions};
use nerflex_sim::segment::compose::compose_dirs;
use nerflex_sim::segment::output::{for_each_view, plan_groups};
use nerflex_sim::segment::{
    analyse, decide, segment, EnlargeOptions, FrequencyOptions, SegCapture, SegmentOptions,
};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// The NeRFlex paper's segmentation time for twenty images, seconds.
const PAPER_SECONDS: f64 = 3.8;

/// User + system CPU seconds of this process so far (Linux), if readable.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses).
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let (utime, stime): (f64, f64) = (f.get(11)?.parse().ok()?, f.get(12)?.parse().ok()?);
    Some((utime + stime) / 100.0) // USER_HZ is 100 on Linux
}

/// Analysis and every group's views, in memory (no PNG encoding).
fn analyse_and_views(cap: &SegCapture) -> usize {
    let a = analyse(cap, &FrequencyOptions::default()).expect("analyse");
    let d = decide(&a, None).expect("decide");
    let opts = EnlargeOptions::default();
    plan_groups(cap, &d)
        .iter()
        .map(|g| {
            for_each_view(&cap.train, g, &opts, |v| {
                black_box(v);
                Ok(())
            })
            .expect("views")
        })
        .sum()
}

fn summary(name: &str, cap: &SegCapture) {
    let out = std::env::temp_dir().join(format!("nerflex-segment-bench-{}", std::process::id()));
    let mut runs = Vec::new();
    for _ in 0..3 {
        let (t, c) = (Instant::now(), cpu_seconds());
        let views = analyse_and_views(cap);
        let mem = (
            t.elapsed().as_secs_f64(),
            cpu_seconds().zip(c).map(|(b, a)| b - a),
        );
        let (t, c) = (Instant::now(), cpu_seconds());
        let seg = segment(cap, &SegmentOptions::default(), &out).expect("segment");
        let full = (
            t.elapsed().as_secs_f64(),
            cpu_seconds().zip(c).map(|(b, a)| b - a),
        );
        runs.push((mem, full, views, seg.timings.analyse_s, seg.groups.len()));
    }
    std::fs::remove_dir_all(&out).ok();
    runs.sort_by(|a, b| a.1 .0.total_cmp(&b.1 .0));
    let (mem, full, views, analyse_s, groups) = runs[1];
    let cpu = |c: Option<f64>| c.map_or_else(String::new, |c| format!(", {c:.2} s CPU"));
    let (w, h) = cap.image_size();
    println!(
        "segment [{name}]: {} views {w}×{h}, {} objects → {groups} networks, {views} views built",
        cap.train.len(),
        cap.objects.len()
    );
    println!("  frequency analysis          {analyse_s:>6.2} s");
    println!(
        "  analysis + views in memory  {:>6.2} s{}",
        mem.0,
        cpu(mem.1)
    );
    println!(
        "  whole stage with PNG output {:>6.2} s{}",
        full.0,
        cpu(full.1)
    );
    println!("  NeRFlex paper (20 images)   {PAPER_SECONDS:>6.2} s");
}

/// `nerflex scene make --preset scene4 --views 20 --test-views 0 --size 800`.
fn scene4(dir: &std::path::Path) -> SegCapture {
    let spec = CaptureSpec {
        objects: arrange(&Preset::Scene4.kinds(), Layout::Ring, 0, 1.0),
        layout: "ring".into(),
        preset: Some(Preset::Scene4),
        seed: 0,
        train_views: 20,
        test_views: 0,
        size: 800,
        render: RenderOptions::default(),
    };
    println!("rendering scene4, 20 views of 800×800 (setup, not timed)…");
    let report = make_capture(&spec, dir, &|| {}).expect("render scene4");
    SegCapture::load(&report.dir).expect("load scene4")
}

fn bench(c: &mut Criterion) {
    let tmp = std::env::temp_dir().join(format!("nerflex-segment-bench-s4-{}", std::process::id()));
    let scene = scene4(&tmp);
    std::fs::remove_dir_all(&tmp).ok();
    summary("scene4", &scene);
    if let Some(data) = nerflex_sim::data::require_data("segment benchmark on lego + chair") {
        let ns = data.join("nerf_synthetic");
        match compose_dirs(&[&ns.join("lego"), &ns.join("chair")], None) {
            Ok(mut real) => {
                real.test.clear();
                summary("lego + chair", &real);
            }
            Err(e) => println!("lego + chair: {e}"),
        }
    }

    let mut g = c.benchmark_group("segment_20x800x800");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(10));
    let opts = FrequencyOptions::default();
    g.bench_function("frequency_analysis_scene4", |b| {
        b.iter(|| analyse(black_box(&scene), &opts))
    });
    g.sampling_mode(criterion::SamplingMode::Flat);
    g.measurement_time(Duration::from_secs(20));
    g.bench_function("analysis_and_views_in_memory_scene4", |b| {
        b.iter(|| analyse_and_views(black_box(&scene)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
