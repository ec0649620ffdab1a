//! `nerflex train` on a small built-in object (a mug, whose inside the
//! visual hull fills): the trained field's held-out PSNR must clearly beat
//! the visual-hull baker's on the same capture, and the saved field must
//! load back bit for bit.

use std::path::{Path, PathBuf};

use nerflex_sim::bake::sweep::{bake_and_measure, fixed_point_render, ObjectViews};
use nerflex_sim::bake::BakeParams;
use nerflex_sim::capture::Capture;
use nerflex_sim::metrics::Metrics;
use nerflex_sim::procedural::ObjectKind;
use nerflex_sim::train::io;
use nerflex_sim::train::trainer::{train, Level, TrainSettings};
use nerflex_sim::train::view::render_view;

/// One mug, 24 training and 4 held-out views at 64 px.
fn capture(dir: &Path) -> PathBuf {
    nerflex_tests::small_capture(dir, "mug", &[ObjectKind::Mug], 3, (24, 4), 64)
}

/// Held-out PSNR margin of the field over the hull baker (dB). Measured
/// with the default settings of session 4 (colour lr 0.3, DVGO's
/// per-sample and entropy losses, TV, pruning): field 27.08 dB vs hull
/// baker 25.05 dB (+2.0 dB; +1.3 dB before those changes,
/// `docs/training.md`); the margin leaves room for float-order noise.
const MARGIN_DB: f64 = 1.5;

#[test]
fn trained_field_beats_the_hull_baker_and_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let cap = Capture::load(capture(dir.path())).unwrap();
    let views = ObjectViews::from_capture(&cap, None).unwrap();

    let settings = TrainSettings {
        levels: vec![
            Level {
                res: 32,
                iters: 300,
            },
            Level {
                res: 64,
                iters: 300,
            },
        ],
        batch: 2048,
        ..TrainSettings::default()
    };
    let (grid, report) = train(&views, &settings, &|_, _, _, _| {}).unwrap();
    let field_psnr: f64 = views
        .test
        .iter()
        .map(|(cam, truth)| {
            let img = render_view(&grid, cam, settings.step);
            Metrics::compare(&img, truth, None).unwrap().psnr
        })
        .sum::<f64>()
        / views.test.len() as f64;

    let hull = bake_and_measure(&views, &BakeParams::new(64, 5), &fixed_point_render, None)
        .unwrap()
        .psnr;
    eprintln!(
        "field {field_psnr:.2} dB vs hull baker {hull:.2} dB (training {:.1} s)",
        report.total_s
    );
    assert!(
        field_psnr >= hull + MARGIN_DB,
        "field {field_psnr:.2} dB is not {MARGIN_DB} dB above the hull baker's {hull:.2} dB"
    );

    // The saved field loads back bit for bit.
    let path = dir.path().join("mug.safetensors");
    io::save(&path, &grid, &settings, &report).unwrap();
    let back = io::load(&path).unwrap();
    assert_eq!(back.grid, grid);
    assert_eq!(back.settings.as_ref(), Some(&settings));
}
