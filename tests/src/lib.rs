//! Integration and property tests of nerflex live in `tests/tests/`.
//! This library holds what they share.

pub use nerflex_sim::data::{require_data, shared_data_dir};

use nerflex_sim::procedural::{
    arrange, make_capture, CaptureSpec, Layout, ObjectKind, RenderOptions,
};
use std::path::{Path, PathBuf};

/// The suite's tiny profiler and planner grids: samples g ∈ {8, 24} ×
/// p ∈ {3, 4, 5}, planning over g ∈ {8, 12, 16, 24} × p ∈ {3, 4, 5}.
pub fn tiny_configs() -> nerflex_sim::eval::scale::Configs {
    nerflex_sim::eval::scale::Configs {
        sample_grid: (8, 24),
        sample_patch: (3, 5),
        sample_step: nerflex_sim::fit::sampling::Step::Triple,
        space_grid: vec![8, 12, 16, 24],
        space_patch: vec![3, 4, 5],
    }
}

/// The suite's tiny pipeline: hull baker (these tests check the
/// pipeline's machinery, not training), 48 × 48 captures with 6 training
/// and `test_views` held-out views, [`tiny_configs`], store in `store`.
pub fn tiny_pipeline(store: PathBuf, test_views: usize) -> nerflex_sim::pipeline::Options {
    let mut p = nerflex_sim::pipeline::Options::reduced(store);
    p.baker = nerflex_sim::pipeline::Baker::Hull;
    p.size = 48;
    p.train_views = 6;
    p.test_views = test_views;
    p.configs = tiny_configs();
    p
}

/// A few seconds of training at most: 16³ then 24³, `steps` each.
pub fn tiny_training(steps: u32) -> nerflex_sim::train::trainer::TrainSettings {
    use nerflex_sim::train::trainer::{Level, TrainSettings};
    TrainSettings {
        levels: vec![
            Level {
                res: 16,
                iters: steps,
            },
            Level {
                res: 24,
                iters: steps,
            },
        ],
        batch: 1024,
        ..TrainSettings::default()
    }
}

/// The trained baker at the suite's size: [`tiny_training`] (40 steps a
/// level) and the reduced scale's bake, fine-tuned one epoch.
pub fn tiny_baker() -> nerflex_sim::pipeline::Baker {
    let mut bake = nerflex_sim::eval::scale::Scale::Reduced.bake_settings();
    bake.finetune.epochs = 1.0;
    bake.fit.steps = 100;
    bake.fit_samples = 4096;
    nerflex_sim::pipeline::Baker::trained(tiny_training(40), bake)
}

/// A short device simulation for `p`: a turntable of `angles` coverage
/// passes `coverage_width` px wide and `frames` frames (7.5 s a turn).
pub fn tiny_simulation(
    p: &mut nerflex_sim::pipeline::Options,
    angles: usize,
    coverage_width: u32,
    frames: usize,
) {
    p.turntable = nerflex_sim::simulate::TurntableSpec {
        angles,
        coverage_width,
        ..nerflex_sim::simulate::TurntableSpec::DEFAULT
    };
    p.sim = nerflex_sim::simulate::SimOptions {
        frames,
        period_s: 7.5,
    };
}

/// Renders without the slow effects (edge and texture supersampling,
/// shadows, ambient occlusion): what the suite's small captures use.
pub fn fast_render() -> RenderOptions {
    RenderOptions {
        edge_samples: 0,
        texture_samples: 0,
        shadows: false,
        ambient_occlusion: false,
        ..RenderOptions::default()
    }
}

/// A small built-in capture of `kinds` in a row at `dir/name`: `train`
/// training and `test` held-out views of `size` px from `seed`, rendered
/// by [`fast_render`]. Panics on failure (tests only).
pub fn small_capture(
    dir: &Path,
    name: &str,
    kinds: &[ObjectKind],
    seed: u64,
    (train, test): (usize, usize),
    size: u32,
) -> PathBuf {
    let spec = CaptureSpec {
        objects: arrange(kinds, Layout::Row, 1, 1.0),
        layout: "row".into(),
        preset: None,
        seed,
        train_views: train,
        test_views: test,
        size,
        render: fast_render(),
    };
    let out = dir.join(name);
    make_capture(&spec, &out, &|| {}).expect("generating a test capture");
    out
}

/// An in-memory framebuffer for the core's `DrawTarget` path
/// (`nerflex_core::raster::render_frame`); pixels outside it are dropped.
pub struct Fb(pub nerflex_sim::asset::image::RgbaImage);

impl nerflex_core::raster::embedded_graphics_core::geometry::OriginDimensions for Fb {
    fn size(&self) -> nerflex_core::raster::embedded_graphics_core::geometry::Size {
        nerflex_core::raster::embedded_graphics_core::geometry::Size::new(
            self.0.width(),
            self.0.height(),
        )
    }
}

impl nerflex_core::raster::embedded_graphics_core::draw_target::DrawTarget for Fb {
    type Color = nerflex_core::raster::embedded_graphics_core::pixelcolor::Rgb888;
    type Error = std::convert::Infallible;
    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = nerflex_core::raster::embedded_graphics_core::Pixel<Self::Color>>,
    {
        use nerflex_core::raster::embedded_graphics_core::pixelcolor::RgbColor;
        use nerflex_core::raster::embedded_graphics_core::Pixel;
        for Pixel(p, c) in pixels {
            let (Ok(x), Ok(y)) = (u32::try_from(p.x), u32::try_from(p.y)) else {
                continue;
            };
            if x < self.0.width() && y < self.0.height() {
                let rgba = nerflex_sim::asset::image::Rgba([c.r(), c.g(), c.b(), 255]);
                self.0.put_pixel(x, y, rgba);
            }
        }
        Ok(())
    }
}

/// An asset's shapes as the core's frame renderer takes them.
pub fn core_parts(a: &nerflex_sim::asset::Asset) -> Vec<nerflex_core::raster::Part<'_>> {
    a.shapes
        .iter()
        .map(|sh| nerflex_core::raster::Part {
            quads: &sh.quads,
            atlas: sh.atlas.atlas(),
            mlp: a.mlp.fixed(),
        })
        .collect()
}
