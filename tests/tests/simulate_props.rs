//! Property tests of the device model and the simulator: a plan over the
//! device's hard limit is always a load failure; FPS is always finite and
//! ≥ 0; more shaded pixels (or quads) never make a frame faster.

use nerflex_core::units::Bytes;
use nerflex_sim::baselines::{plan, Budget, Method};
use nerflex_sim::camera::Camera;
use nerflex_sim::device::{Device, FrameWork};
use nerflex_sim::scene_file::{ConfigEntry, Scene, SceneObject};
use nerflex_sim::simulate::{
    simulate, CoverageSource, LoadItem, SimOptions, Turntable, TurntableSpec, ViewCoverage,
};
use proptest::prelude::*;

/// A device with random but valid figures (`hard`/`soft` limits optional).
fn device() -> impl Strategy<Value = Device> {
    (
        (1.0f64..2000.0, prop::option::of(0.0f64..2000.0)),
        prop::option::of((0.0f64..2000.0, 0.0f64..100.0)),
        (1e6f64..1e13, 1e3f64..1e10, 0.0f64..100.0),
        (0.01f64..1e4, prop::option::of(0.01f64..1e4)),
        (1.0f64..240.0, 1u32..4000, 1u32..4000),
    )
        .prop_map(
            |((budget, hard), soft, (mac, quads, ovh), (load, decode), (hz, w, h))| {
                let mut d = Device::builtin("pixel4").unwrap();
                d.name = "random".into();
                d.budget_mb = budget;
                d.hard_limit_mb = hard;
                d.soft_limit = soft
                    .map(|(mb, fps_penalty)| nerflex_sim::device::SoftLimit { mb, fps_penalty });
                d.throughput.mac_per_s = mac;
                d.throughput.quads_per_s = quads;
                d.throughput.frame_overhead_ms = ovh;
                d.throughput.load_mb_per_s = load;
                d.throughput.decode_mb_per_s = decode;
                d.display.refresh_hz = hz;
                d.viewer = Some(nerflex_sim::device::Viewer {
                    width_px: w,
                    height_px: h,
                });
                d
            },
        )
}

/// Coverage that depends on the angle and the objects loaded, from a table.
struct Table {
    objects: usize,
    /// Per object: (quads drawn, visible, pixels) at the front; it varies
    /// with the azimuth by up to ±50 %.
    per_object: Vec<(u64, u64, u64)>,
    /// Multiplies every pixel count.
    pixel_scale: u64,
}

impl CoverageSource for Table {
    fn objects(&self) -> usize {
        self.objects
    }
    fn coverage(&self, loaded: usize, camera: &Camera) -> anyhow::Result<ViewCoverage> {
        let p = camera.position();
        let wobble = 1.0 + 0.5 * (p.x.atan2(-p.y)).sin() as f64;
        let mut c = ViewCoverage::default();
        for &(q, v, px) in self.per_object.iter().take(loaded) {
            c.quads_in_view += (q as f64 * wobble) as u64;
            c.quads_drawn += (q as f64 * wobble) as u64;
            c.quads_visible += (v as f64 * wobble) as u64;
            c.pixels_covered += (px as f64 * wobble) as u64 * self.pixel_scale;
        }
        Ok(c)
    }
}

fn objects() -> impl Strategy<Value = Vec<(u64, u64, u64, u64)>> {
    // (file bytes, quads, visible, pixels)
    prop::collection::vec(
        (
            0u64..400_000_000,
            0u64..2_000_000,
            0u64..500_000,
            0u64..25_600,
        ),
        0..6,
    )
}

fn run(
    device: &Device,
    objs: &[(u64, u64, u64, u64)],
    pixel_scale: u64,
    frames: usize,
) -> nerflex_sim::simulate::Simulation {
    let table = Table {
        objects: objs.len(),
        per_object: objs.iter().map(|&(_, q, v, p)| (q, v.min(q), p)).collect(),
        pixel_scale,
    };
    let items: Vec<LoadItem> = objs
        .iter()
        .enumerate()
        .map(|(i, &(bytes, q, _, _))| LoadItem {
            name: format!("o{i}"),
            file_bytes: bytes,
            resident_bytes: bytes.saturating_mul(3) + q * 120,
        })
        .collect();
    let spec = TurntableSpec {
        angles: 12,
        coverage_width: 160,
        ..TurntableSpec::DEFAULT
    };
    let tt = Turntable::new(spec, device.viewer(), &table);
    simulate(
        device,
        &items,
        &tt,
        SimOptions {
            frames,
            period_s: 7.5,
        },
    )
    .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// Data over the hard limit never loads: a failure naming the sizes,
    /// every frame at FPS 0; data within it always loads.
    #[test]
    fn over_the_hard_limit_is_a_load_failure(d in device(), objs in objects()) {
        let sim = run(&d, &objs, 1, 50);
        let data: u64 = objs.iter().map(|o| o.0).sum();
        let over = d.hard_limit().is_some_and(|h| Bytes(data) > h);
        prop_assert_eq!(sim.load_failure.is_some(), over);
        if let Some(f) = &sim.load_failure {
            prop_assert_eq!(f.data_bytes, data);
            prop_assert!(sim.frames.iter().all(|f| f.fps == 0.0));
            prop_assert_eq!(sim.mean_fps, 0.0);
        }
    }

    /// Plans the planner makes (Block-NeRF, which ignores the budget, and the
    /// DP under a budget above the device's limit) are load failures exactly
    /// when their total is over the iPhone 13's 240 MB.
    #[test]
    fn plans_over_the_limit_fail_to_load(
        sizes in prop::collection::vec((1u64..150_000_000, 1u64..150_000_000), 1..6),
        budget_mb in 1.0f64..600.0,
    ) {
        let d = Device::builtin("iphone13").unwrap();
        let scene = Scene {
            objects: sizes.iter().enumerate().map(|(i, &(a, b))| SceneObject {
                name: format!("o{i}"),
                configs: vec![
                    ConfigEntry::planes(128, 17, Bytes(a.max(b)), 0.9),
                    ConfigEntry::planes(64, 9, Bytes(a.min(b)), 0.8),
                ],
                profile: None,
                mesh_profile: None,
            }).collect(),
            single: None,
        };
        for method in [Method::Block, Method::Dp] {
            let Ok(p) = plan(method, &scene, Budget::new(Bytes::from_mb(budget_mb).unwrap())) else {
                continue;
            };
            let objs: Vec<(u64, u64, u64, u64)> =
                p.objects.iter().map(|o| (o.size_bytes, 1000, 500, 100)).collect();
            let sim = run(&d, &objs, 1, 20);
            prop_assert_eq!(sim.load_failure.is_some(), p.total_size_bytes > 240_000_000);
        }
    }

    /// Every frame's FPS and every summary is finite and ≥ 0, for any valid
    /// device and any workload.
    #[test]
    fn fps_is_finite_and_non_negative(d in device(), objs in objects(), scale in 1u64..50) {
        let sim = run(&d, &objs, scale, 300);
        prop_assert_eq!(sim.frames.len(), 300);
        for f in &sim.frames {
            prop_assert!(f.fps.is_finite() && f.fps >= 0.0, "{:?}", f);
            prop_assert!(f.fps <= d.display.refresh_hz + 1e-9);
            prop_assert!(f.frame_s.is_finite() && f.frame_s > 0.0);
        }
        for v in [sim.mean_fps, sim.steady_fps, sim.min_fps] {
            prop_assert!(v.is_finite() && v >= 0.0);
        }
    }

    /// More shaded pixels (or more quads) never make a frame faster.
    #[test]
    fn more_pixels_never_faster(
        d in device(),
        quads in 0.0f64..1e7,
        pixels in 0.0f64..1e8,
        extra_px in 0.0f64..1e8,
        extra_quads in 0.0f64..1e7,
        over_soft in any::<bool>(),
    ) {
        let a = FrameWork { quads, pixels_shaded: pixels };
        let b = FrameWork { quads, pixels_shaded: pixels + extra_px };
        let c = FrameWork { quads: quads + extra_quads, pixels_shaded: pixels };
        let (ta, tb, tc) = (
            d.frame_cost(&a).total_s(),
            d.frame_cost(&b).total_s(),
            d.frame_cost(&c).total_s(),
        );
        prop_assert!(tb >= ta && tc >= ta);
        prop_assert!(d.fps(tb, over_soft) <= d.fps(ta, over_soft));
        prop_assert!(d.fps(tc, over_soft) <= d.fps(ta, over_soft));
    }
}

/// The same scene with every pixel count doubled is slower on average once
/// loaded (steady state), on the built-in devices (refresh cap lifted so
/// the comparison does not depend on how close they run to it).
#[test]
fn doubling_pixels_lowers_steady_fps() {
    for name in ["iphone13", "pixel4"] {
        let mut d = Device::builtin(name).unwrap();
        d.display.refresh_hz = 1e6;
        let objs = [(20_000_000, 200_000, 60_000, 6_000); 4];
        let one = run(&d, &objs, 1, 600);
        let two = run(&d, &objs, 2, 600);
        assert!(
            two.steady_fps < one.steady_fps,
            "{name}: {} vs {}",
            two.steady_fps,
            one.steady_fps
        );
    }
}
