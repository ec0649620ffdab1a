//! Device files and the device model: the issue-2 format still loads, the
//! simulator's optional fields are validated, and the model's terms behave
//! as documented (docs/device.md).

use nerflex_core::units::Bytes;
use nerflex_sim::device::{
    resident_bytes, Device, FrameWork, Viewer, DEFAULT_DECODE_MB_PER_S, MLP_MACS_PER_PIXEL,
    VERTEX_BYTES_PER_QUAD,
};

/// A device file in the format `nerflex plan` shipped with (no simulator
/// fields).
const ISSUE2_FORMAT: &str = r#"
name = "tablet"
budget_mb = 500.0
hard_limit_mb = 600.0
[soft_limit]
mb = 450.0
fps_penalty = 5.0
[throughput]
mac_per_s = 1.0e11
quads_per_s = 1.0e8
frame_overhead_ms = 4.0
load_mb_per_s = 50.0
[display]
refresh_hz = 120.0
width_px = 2000
height_px = 1500
"#;

#[test]
fn issue2_format_loads_with_defaults() {
    let d = Device::from_toml_str(ISSUE2_FORMAT, "tablet.toml").unwrap();
    assert_eq!(d.viewer(), Viewer::DEFAULT);
    assert_eq!(d.decode_mb_per_s(), DEFAULT_DECODE_MB_PER_S);
    assert_eq!(d.budget(), Bytes(500_000_000));
    assert_eq!(d.gbuffer_bytes(), Bytes(800 * 800 * 12));
}

#[test]
fn simulator_fields_are_read_and_checked() {
    let with = format!("{ISSUE2_FORMAT}\n[viewer]\nwidth_px = 640\nheight_px = 480\n").replace(
        "load_mb_per_s = 50.0",
        "load_mb_per_s = 50.0\ndecode_mb_per_s = 123.0",
    );
    let d = Device::from_toml_str(&with, "t.toml").unwrap();
    assert_eq!(
        d.viewer(),
        Viewer {
            width_px: 640,
            height_px: 480
        }
    );
    assert_eq!(d.decode_mb_per_s(), 123.0);

    let e = Device::from_toml_str(&with.replace("123.0", "0.0"), "t.toml").unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.toml: throughput.decode_mb_per_s: must be a positive number, got 0"
    );
    let e = Device::from_toml_str(&with.replace("width_px = 640", "width_px = 0"), "t.toml")
        .unwrap_err();
    assert!(e.to_string().starts_with("t.toml: viewer: "), "{e}");
    let e = Device::from_toml_str(&format!("{with}depth = 3\n"), "t.toml").unwrap_err();
    assert!(
        e.to_string()
            .contains("viewer.depth: unknown field `depth`"),
        "{e}"
    );
}

#[test]
fn frame_cost_has_the_three_terms() {
    let d = Device::from_toml_str(ISSUE2_FORMAT, "t.toml").unwrap();
    let c = d.frame_cost(&FrameWork {
        quads: 1e6,
        pixels_shaded: 1e5,
    });
    assert!((c.overhead_s - 0.004).abs() < 1e-15);
    assert!((c.raster_s - 0.01).abs() < 1e-15);
    assert!((c.shade_s - 1e5 * 480.0 / 1e11).abs() < 1e-15);
    assert_eq!(MLP_MACS_PER_PIXEL, 480);
    // NaN and negative work count as none.
    let none = d.frame_cost(&FrameWork {
        quads: f64::NAN,
        pixels_shaded: -5.0,
    });
    assert_eq!(none.total_s(), 0.004);
}

#[test]
fn fps_caps_penalises_and_floors() {
    let d = Device::from_toml_str(ISSUE2_FORMAT, "t.toml").unwrap();
    assert_eq!(d.fps(0.0, false), 120.0);
    assert_eq!(d.fps(0.02, false), 50.0);
    assert_eq!(d.fps(0.02, true), 45.0);
    assert_eq!(d.fps(1.0, true), 0.0);
    assert_eq!(d.fps(f64::INFINITY, false), 0.0);
    assert_eq!(d.fps(f64::NAN, false), 120.0);
    assert!(d.over_soft_limit(Bytes(450_000_001)));
    assert!(!d.over_soft_limit(Bytes(450_000_000)));
}

#[test]
fn load_check_and_resident_bytes() {
    let d = Device::builtin("iphone13").unwrap();
    assert!(d.load_check(Bytes(240_000_000)).is_ok());
    let f = d.load_check(Bytes(240_000_001)).unwrap_err();
    assert_eq!(
        f.to_string(),
        "240.00 MB of data is over the 240.00 MB that iphone13 can load (the viewer fails to load it)"
    );
    // The Pixel 4 loads up to 400 MB (slowly above 150 MB).
    let p = Device::builtin("pixel4").unwrap();
    assert!(p.load_check(Bytes(400_000_000)).is_ok());
    assert!(p.load_check(Bytes(400_000_001)).is_err());
    assert!(p.over_soft_limit(Bytes(150_000_001)));
    assert_eq!(
        resident_bytes(1000, 10),
        Bytes(1000 + 10 * VERTEX_BYTES_PER_QUAD)
    );
    assert_eq!(resident_bytes(u64::MAX, 10), Bytes(u64::MAX));
}
