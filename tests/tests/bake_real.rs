//! The baker on the real NeRF-synthetic lego (reduced: 8 training views and
//! 2 held-out views at 200×200), end to end: bake, asset write/load,
//! fixed-point render, metrics.

use image::imageops::{self, FilterType};
use nerflex_sim::asset::Asset;
use nerflex_sim::bake::sweep::{self, ObjectViews};
use nerflex_sim::bake::{self, BakeParams};
use nerflex_sim::capture::Capture;

const SIZE: u32 = 200;

/// Real lego at 200 px, 8 training views spread over the 20, 2 test views.
fn lego_small() -> Option<ObjectViews> {
    let data = nerflex_tests::require_data("real lego bake")?;
    let mut cap = Capture::load(data.join("nerf_synthetic/lego")).unwrap();
    let train: Vec<_> = cap.train.iter().step_by(20 / 8 + 1).cloned().collect();
    cap.train = train;
    cap.test.truncate(2);
    for f in cap.train.iter_mut().chain(cap.test.iter_mut()) {
        // Premultiplied downsampling would be more exact; straight colour
        // resampling only darkens the outermost silhouette pixels a little.
        f.image = imageops::resize(&f.image, SIZE, SIZE, FilterType::Triangle);
        f.camera.intrinsics = f.camera.intrinsics.resized(SIZE, SIZE);
    }
    Some(ObjectViews::from_capture(&cap, None).unwrap())
}

#[test]
fn finer_bakes_of_real_lego_score_higher_and_weigh_more() {
    let Some(obj) = lego_small() else { return };
    assert_eq!(obj.name, "lego");
    assert!(obj.train.len() >= 6);
    let measure = |g, p| {
        let views = obj.bake_views();
        let baked = bake::bake(&views, &BakeParams::new(g, p)).unwrap();
        let gpu = baked.gpu_bytes();
        let asset = baked.into_asset().unwrap();
        let (q, _) =
            sweep::measure(&asset, &obj.test, &sweep::fixed_point_render, None, false).unwrap();
        (q, gpu)
    };
    let (coarse, coarse_gpu) = measure(8, 3);
    let (fine, fine_gpu) = measure(32, 9);
    println!("lego 200 px: (8, 3) {coarse:?} {coarse_gpu} B; (32, 9) {fine:?} {fine_gpu} B");
    assert!(fine.ssim > coarse.ssim + 0.01, "{fine:?} vs {coarse:?}");
    assert!(fine.psnr > coarse.psnr + 1.0, "{fine:?} vs {coarse:?}");
    assert!(fine_gpu > 10 * coarse_gpu);
    // Not a blank or garbage picture: the object is recognisably there.
    assert!(fine.ssim > 0.7 && fine.psnr > 15.0, "{fine:?}");
}

#[test]
fn a_baked_asset_writes_loads_and_renders_the_same() {
    let Some(obj) = lego_small() else { return };
    let views = obj.bake_views();
    let baked = bake::bake(&views, &BakeParams::new(24, 5)).unwrap();
    let (quads, gpu) = (baked.quads.len(), baked.gpu_bytes());
    let asset = baked.into_asset().unwrap();
    let predicted = bake::file_bytes(&asset).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let written = asset.write(dir.path()).unwrap();
    assert_eq!(
        written, predicted,
        "file_bytes must match what write writes"
    );
    let loaded = Asset::load(dir.path()).unwrap();
    let report = loaded.report();
    assert_eq!(report.quads, quads);
    assert_eq!(report.gpu_bytes, gpu);
    assert_eq!(report.file_bytes, written);
    assert!(report.missing_shapes.is_empty());
    let cam = &obj.test[0].0;
    let a = sweep::fixed_point_render(&asset, cam).unwrap();
    let b = sweep::fixed_point_render(&loaded, cam).unwrap();
    // OBJ coordinates are written with 6 decimals: at most an edge pixel
    // may differ.
    let differ = a.pixels().zip(b.pixels()).filter(|(x, y)| x != y).count();
    assert!(
        differ * 200 < (SIZE * SIZE) as usize,
        "{differ} pixels differ"
    );
}
