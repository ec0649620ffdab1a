//! The trained baker (`bake::trained`) on built-in objects whose analytic
//! fields stand in for trained ones: it beats the visual-hull baker on the
//! same capture, its export round-trips through the loader, and the phone
//! renderer reproduces the fine-tune's shader.

use std::path::{Path, PathBuf};

use nerflex_sim::asset::Asset;
use nerflex_sim::bake::sweep::{self, ObjectViews};
use nerflex_sim::bake::trained::{self, analytic::Builtin, TrainedParams};
use nerflex_sim::bake::{self, BakeParams};
use nerflex_sim::capture::Capture;
use nerflex_sim::procedural::{
    arrange, make_capture, CaptureSpec, Layout, ObjectKind, RenderOptions,
};
use nerflex_sim::render::{render, RenderOptions as DrawOptions};

/// One built-in object: 16 training and 4 held-out views at 64 px.
fn capture(dir: &Path, kind: ObjectKind, size: u32) -> PathBuf {
    let spec = CaptureSpec {
        objects: arrange(&[kind], Layout::Row, 1, 1.0),
        layout: "row".into(),
        preset: None,
        seed: 3,
        train_views: std::env::var("VIEWS").ok().and_then(|v| v.parse().ok()).unwrap_or(16),
        test_views: 4,
        size,
        render: RenderOptions {
            edge_samples: 2,
            texture_samples: 0,
            ..RenderOptions::default()
        },
    };
    let out = dir.join(kind.name());
    make_capture(&spec, &out, &|| {}).unwrap();
    out
}

fn field_of(cap: &Capture) -> Builtin {
    let scene = cap.scene.as_ref().expect("built-in captures have scene.json");
    Builtin::from_info(&scene.objects[0]).expect("a built-in kind")
}

fn psnr_of(asset: &Asset, obj: &ObjectViews) -> f64 {
    sweep::measure_views(asset, &obj.test, &sweep::fixed_point_render, None, false)
        .unwrap()
        .mean
        .psnr
}

#[test]
fn the_trained_baker_beats_the_hull_baker_on_a_mug() {
    let tmp = tempfile::tempdir().unwrap();
    let kind = std::env::var("KIND").ok().and_then(|k| ObjectKind::from_name(&k)).unwrap_or(ObjectKind::Mug);
    let size = std::env::var("SIZE").ok().and_then(|v| v.parse().ok()).unwrap_or(64);
    let dir = capture(tmp.path(), kind, size);
    let cap = Capture::load(&dir).unwrap();
    let obj = ObjectViews::from_capture(&cap, None).unwrap();
    let views = obj.bake_views();
    let g = std::env::var("G").ok().and_then(|v| v.parse().ok()).unwrap_or(32);
    let p = std::env::var("P").ok().and_then(|v| v.parse().ok()).unwrap_or(5);
    let mut hp = BakeParams::new(g, p);
    hp.search_box = obj.search_box;
    let hull = bake::bake(&views, &hp).unwrap().into_asset().unwrap();
    let field = field_of(&cap);
    let t = std::time::Instant::now();
    let mut tp = TrainedParams::new(g, p);
    if let Ok(e) = std::env::var("EPOCHS") { tp.finetune.epochs = e.parse().unwrap(); }
    if let Ok(e) = std::env::var("BATCH") { tp.finetune.batch = e.parse().unwrap(); }
    if let Ok(e) = std::env::var("LRF") { tp.finetune.lr_features = e.parse().unwrap(); }
    if let Ok(e) = std::env::var("LRM") { tp.finetune.lr_mlp = e.parse().unwrap(); }
    let tb = trained::bake(&field, &views, &tp).unwrap();
    eprintln!("trained bake {:.2} s: {:?}", t.elapsed().as_secs_f64(), tb.stats);
    let ours = tb.baked.into_asset().unwrap();
    if let Ok(d) = std::env::var("NERFLEX_DUMP") {
        let mh = sweep::measure_views(&hull, &obj.test, &sweep::fixed_point_render, None, true).unwrap();
        let mt = sweep::measure_views(&ours, &obj.test, &sweep::fixed_point_render, None, true).unwrap();
        let (w, h) = obj.test[0].1.dimensions();
        let mut out = image::RgbaImage::from_pixel(3 * w * 4, obj.test.len() as u32 * h * 4, image::Rgba([255; 4]));
        for i in 0..obj.test.len() {
            for (c, im) in [&obj.test[i].1, &mh.renders[i], &mt.renders[i]].iter().enumerate() {
                let over = nerflex_sim::bake::compare::over_white(im, None);
                let big = image::imageops::resize(&over, w * 4, h * 4, image::imageops::FilterType::Nearest);
                image::imageops::overlay(&mut out, &big, (c as u32 * w * 4) as i64, (i as u32 * h * 4) as i64);
            }
        }
        out.save(format!("{d}/cmp.png")).unwrap();
    }
    let (ph, pt) = (psnr_of(&hull, &obj), psnr_of(&ours, &obj));
    eprintln!("held-out PSNR: hull {ph:.2} dB, trained {pt:.2} dB");
    assert!(pt >= ph + 2.0, "trained {pt:.2} dB vs hull {ph:.2} dB");
}
