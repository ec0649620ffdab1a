//! Cost of the device simulator: one frame of the model (the work at a
//! turntable angle, interpolated from the measured angles, and its cost and
//! FPS on the device), the 2000-frame loop on precomputed coverage (the
//! model's own overhead), and one coverage pass of a baked object at the
//! simulator's default 160-pixel width (what each measured turntable angle
//! costs; needs the shared data).
//!
//! `cargo bench -p nerflex-hostbench --bench simulate`

use criterion::{criterion_group, criterion_main, Criterion};
use nerflex_sim::camera::Camera;
use nerflex_sim::device::Device;
use nerflex_sim::simulate::{
    simulate, CoverageSource, LoadItem, SimOptions, Turntable, TurntableSpec, ViewCoverage,
};
use std::hint::black_box;

/// Five objects of fixed coverage (the frame loop only).
struct Fixed;

impl CoverageSource for Fixed {
    fn objects(&self) -> usize {
        5
    }
    fn coverage(&self, loaded: usize, _: &Camera) -> anyhow::Result<ViewCoverage> {
        let k = loaded as u64;
        Ok(ViewCoverage {
            quads_in_view: 150_000 * k,
            quads_drawn: 120_000 * k,
            quads_visible: 40_000 * k,
            pixels_covered: 1_500 * k,
        })
    }
}

fn frame_loop(c: &mut Criterion) {
    let device = Device::builtin("pixel4").expect("built-in device");
    let items: Vec<LoadItem> = (0..5)
        .map(|i| LoadItem {
            name: format!("o{i}"),
            file_bytes: 30_000_000,
            resident_bytes: 90_000_000,
        })
        .collect();
    let source = Fixed;
    let tt = Turntable::new(TurntableSpec::DEFAULT, device.viewer(), &source);
    // Measure every angle once so the loop below is the model alone.
    for k in 0..=5 {
        tt.measure_stage(k).expect("synthetic coverage");
    }
    c.bench_function("simulate/one frame of the model (work + cost + FPS)", |b| {
        let mut angle = 0.0f64;
        b.iter(|| {
            // Step the angle so the interpolation does not always hit one pair.
            angle = (angle + 0.013_7) % 1.0;
            let (work, _) = tt.work(5, black_box(angle)).expect("cached coverage");
            let cost = device.frame_cost(&work);
            black_box(device.fps(cost.total_s(), false))
        })
    });
    c.bench_function("simulate/2000 frames, 5 objects (coverage cached)", |b| {
        b.iter(|| {
            let sim = simulate(&device, black_box(&items), &tt, SimOptions::default())
                .expect("simulation");
            black_box(sim.mean_fps)
        })
    });
}

/// One measured turntable angle of the real drums shape at the simulator's
/// default coverage width (the coverage pass plus the quads-in-view count).
fn one_angle(c: &mut Criterion) {
    let Some(data) = nerflex_sim::data::require_data("simulate bench") else {
        return;
    };
    let asset = nerflex_sim::asset::Asset::load(&data.join("mobilenerf/drums")).expect("drums");
    let scene =
        nerflex_sim::simulate::assets::AssetScene::new(vec!["drums".into()], vec![asset], vec![0]);
    let spec = TurntableSpec::DEFAULT;
    let viewer = nerflex_sim::device::Viewer::DEFAULT;
    let cam = spec.camera(5, viewer);
    c.bench_function(
        "simulate/one angle of drums (160 px coverage + quads in view)",
        |b| b.iter(|| black_box(scene.coverage(1, &cam).expect("coverage"))),
    );
}

criterion_group!(benches, frame_loop, one_angle);
criterion_main!(benches);
