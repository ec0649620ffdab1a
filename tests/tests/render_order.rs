//! The host renderer draws each tile's quads nearest first and skips those
//! already hidden; the microcontroller's `render_frame` draws them in asset
//! order. Both must give the same image: on a made-up asset of many
//! overlapping quads with holey texel opacity, exact depth ties between
//! coplanar quads, and cameras close enough that quads cross the camera
//! plane and leave the frame. No data needed.

use nerflex_core::raster::{glam, render_frame, Quad, TileRenderer, Vertex};
use nerflex_core::shader::MlpWeights;
use nerflex_sim::asset::image::{Rgba, RgbaImage};
use nerflex_sim::asset::{Asset, AtlasPair, Mlp, Shape};
use nerflex_sim::camera::{Camera, Intrinsics};
use nerflex_sim::render::{render, view_of, RenderOptions};
use nerflex_tests::Fb;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Cells of `P` texels per side, `COLS` to an atlas row.
const P: u32 = 5;
const COLS: u32 = 20;

/// `n` quads in a unit cube, each in its own atlas cell; every fourth is
/// a copy of an earlier one (the same plane: exact depth ties), a few are
/// lone triangles; about a third of the texels are transparent.
fn asset(n: u32, seed: u64) -> Asset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let rows = n.div_ceil(COLS);
    let (w, h) = (COLS * P, rows * P);
    let mut quads: Vec<Quad> = Vec::new();
    let mut planes: Vec<[[f32; 3]; 4]> = Vec::new();
    for i in 0..n {
        let (cx, cy) = ((i % COLS * P) as f32, (i / COLS * P) as f32);
        let corners = if i % 4 == 3 {
            planes[rng.random_range(0..planes.len())]
        } else {
            let o: [f32; 3] = std::array::from_fn(|_| rng.random_range(-0.5..0.5));
            let (a, b) = (rng.random_range(0..3usize), rng.random_range(1..3usize));
            let (u, v) = (a, (a + b) % 3);
            let (su, sv) = (rng.random_range(0.1..0.6), rng.random_range(0.1..0.6));
            let at = |du: f32, dv: f32| {
                let mut p = o;
                p[u] += du;
                p[v] += dv;
                p
            };
            [at(0.0, 0.0), at(0.0, sv), at(su, 0.0), at(su, sv)]
        };
        planes.push(corners);
        let v = |k: usize, tx: f32, ty: f32| Vertex::at_texel(corners[k], cx + tx, cy + ty, w, h);
        let hi = P as f32 - 0.5;
        quads.push(if i % 9 == 5 {
            Quad::triangle(v(0, 0.5, 0.5), v(2, hi, 0.5), v(1, 0.5, hi))
        } else {
            Quad::new([v(0, 0.5, 0.5), v(1, 0.5, hi), v(2, hi, 0.5), v(3, hi, hi)])
        });
    }
    let f0 = RgbaImage::from_fn(w, h, |_, _| {
        let alpha = if rng.random_range(0..3) == 0 { 0 } else { 255 };
        Rgba([rng.random(), rng.random(), rng.random(), alpha])
    });
    let f1 = RgbaImage::from_fn(w, h, |_, _| Rgba(rng.random()));
    let mut weights = MlpWeights::ZERO;
    for (k, row) in weights.w0.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = ((k * 16 + j) % 7) as f32 * 0.1 - 0.3;
        }
    }
    for row in weights.w1.iter_mut() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (j % 5) as f32 * 0.2 - 0.4;
        }
    }
    for row in weights.w2.iter_mut() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (j % 3) as f32 * 0.3 - 0.2;
        }
    }
    Asset {
        mlp: Mlp::new(weights).unwrap(),
        obj_num: 1,
        shapes: vec![Shape {
            index: 0,
            quads,
            atlas: AtlasPair::new(f0, f1).unwrap(),
        }],
        file_bytes: 0,
    }
}

const ONE_SAMPLE: RenderOptions = RenderOptions {
    float: false,
    supersample: false,
};

#[test]
fn nearest_first_draws_equal_the_in_order_tile_path() {
    for seed in 0..3 {
        let a = asset(400, seed);
        let parts = nerflex_tests::core_parts(&a);
        // From outside, at the cube's edge, and inside it.
        for (k, eye) in [[2.5f32, 1.0, 0.8], [0.3, -0.9, 0.4], [0.05, 0.1, -0.02]]
            .into_iter()
            .enumerate()
        {
            let cam = Camera::look_at(
                glam::Vec3::from(eye),
                glam::Vec3::new(0.02, -0.01, 0.0),
                glam::Vec3::Z,
                Intrinsics::from_fov_x(1.1, 120, 90),
            );
            let (host, s) = render(&a, &cam, &ONE_SAMPLE);
            assert!(s.camera_error.is_none());
            assert!(s.pixels_shaded > 500, "seed {seed} camera {k}: {s:?}");
            let view = view_of(&cam).unwrap();
            let mut fb = Fb(RgbaImage::from_pixel(120, 90, Rgba([1, 2, 3, 0])));
            let mut tile = Box::new(TileRenderer::<16, 8>::new());
            let fs = render_frame(&mut tile, &view, &parts, &mut fb).unwrap();
            assert_eq!(u64::from(fs.pixels_shaded), s.pixels_shaded);
            for (i, (h, d)) in host.pixels().zip(fb.0.pixels()).enumerate() {
                if h.0[3] > 0 {
                    assert_eq!(h.0[..3], d.0[..3], "seed {seed} camera {k} pixel {i}");
                }
            }
            // Supersampled frames run through the same tile loop.
            let (ss, s2) = render(&a, &cam, &RenderOptions::default());
            assert!(s2.pixels_shaded >= s.pixels_shaded / 2);
            assert_eq!(ss.dimensions(), (120, 90));
        }
    }
}
