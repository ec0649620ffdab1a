//! The baker's two-layer rasterization (`raster::TwoLayers`, one draw)
//! against the two passes it replaces (`TileRenderer::draw` then
//! `draw_behind`), on a synthetic planes scene like the trained baker's: a
//! two nested spheres' surface voxels on a 192³ grid, each with the plane facing its
//! normal's main axis and, where the normal leans, the second one (grown
//! by an eighth of a voxel into their neighbours, so coplanar overlaps and
//! crossing planes are common), seen at 1600 × 1600 (the bake's 2 × 2
//! supersampled 800 × 800 view) from two opposite sides. One core,
//! every tile. `one_draw_near_first` is the baker's order since session
//! 31: each tile's quads nearest first, the hidden ones skipped.
//!
//! `cargo bench -p nerflex-hostbench --bench peel`

use criterion::{criterion_group, criterion_main, Criterion};
use nerflex_core::raster::glam::Vec3;
use nerflex_core::raster::{Atlas, Quad, ScreenQuad, TileRenderer, TwoLayers, Vertex, View};
use nerflex_sim::camera::{Camera, Intrinsics};
use nerflex_sim::render::view_of;
use std::hint::black_box;

const TILE: usize = 32;
const SIDE: u32 = 1600;
const GRID: i32 = 192;
const TEXELS: u32 = 8;

/// The plane through voxel centre `c` facing axis `axis`, half-size `h`.
fn plane(c: Vec3, axis: usize, h: f32) -> Quad {
    let (u, v) = match axis {
        0 => (Vec3::Y, Vec3::Z),
        1 => (Vec3::Z, Vec3::X),
        _ => (Vec3::X, Vec3::Y),
    };
    let (t0, t1) = (0.5, TEXELS as f32 - 0.5);
    let at = |su: f32, sv: f32| (c + h * (su * u + sv * v)).to_array();
    Quad::new([
        Vertex::at_texel(at(-1.0, 1.0), t0, t0, TEXELS, TEXELS),
        Vertex::at_texel(at(-1.0, -1.0), t0, t1, TEXELS, TEXELS),
        Vertex::at_texel(at(1.0, 1.0), t1, t0, TEXELS, TEXELS),
        Vertex::at_texel(at(1.0, -1.0), t1, t1, TEXELS, TEXELS),
    ])
}

fn scene() -> Vec<Quad> {
    let voxel = 2.4 / GRID as f32;
    let h = 0.5 * voxel * 1.25;
    let mut quads = Vec::new();
    for i in 0..GRID {
        for j in 0..GRID {
            for k in 0..GRID {
                let c = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * voxel - 1.2;
                // Two nested shells: four surfaces deep through the middle.
                if [1.0, 0.6]
                    .iter()
                    .all(|r| (c.length() - r).abs() > 0.5 * voxel)
                {
                    continue;
                }
                let n = c.normalize().abs().to_array();
                let mut axes = [0usize, 1, 2];
                axes.sort_by(|&a, &b| n[b].total_cmp(&n[a]));
                quads.push(plane(c, axes[0], h));
                if n[axes[1]] > 0.5 * n[axes[0]] {
                    quads.push(plane(c, axes[1], h));
                }
            }
        }
    }
    quads
}

/// A 40° camera on an orbit at `azimuth` degrees, 30° up, looking at the origin.
fn view(azimuth: f32) -> View {
    let k = Intrinsics::from_fov_x(40f32.to_radians(), SIDE, SIDE);
    view_of(&Camera::orbit(azimuth, 30.0, 3.8, Vec3::ZERO, k)).expect("a valid view")
}

fn bench(c: &mut Criterion) {
    let quads = scene();
    // Seen from two opposite sides: the quads' grid order is then back to
    // front in one view and front to back in the other.
    let views = [40.0, 220.0].map(view);
    let projected: Vec<Vec<ScreenQuad>> = views
        .iter()
        .map(|v| {
            quads
                .iter()
                .enumerate()
                .filter_map(|(i, q)| ScreenQuad::project(v, q, 0, i as u32))
                .collect()
        })
        .collect();
    let f0 = vec![255u8; (TEXELS * TEXELS * 4) as usize];
    let f1 = f0.clone();
    let atlas = Atlas::new(TEXELS, TEXELS, &f0, &f1).expect("an atlas");
    let t = TILE as u32;
    type Tile<'a> = (&'a View, u32, u32, Vec<&'a ScreenQuad>);
    let tiles: Vec<Tile> = views
        .iter()
        .zip(&projected)
        .flat_map(|(v, projected)| {
            (0..SIDE / t)
                .flat_map(|ty| (0..SIDE / t).map(move |tx| (tx * t, ty * t)))
                .map(move |(x0, y0)| {
                    let bin: Vec<&ScreenQuad> = projected
                        .iter()
                        .filter(|q| q.overlaps(x0, y0, x0 + t - 1, y0 + t - 1))
                        .collect();
                    (v, x0, y0, bin)
                })
        })
        .filter(|(_, _, _, bin)| !bin.is_empty())
        .collect();
    let mut front = Box::new(TileRenderer::<TILE, TILE>::new());
    let mut behind = Box::new(TileRenderer::<TILE, TILE>::new());
    let mut two = Box::new(TwoLayers::<TILE, TILE>::new());
    let mut redrawn = 0;
    for (v, x0, y0, bin) in &tiles {
        two.begin(v, *x0, *y0);
        for q in bin {
            two.draw(q, &atlas);
        }
        redrawn += usize::from(two.resolve(bin.iter().map(|q| (*q, &atlas))));
    }
    println!(
        "peel scene: {} quads, {} tiles drawn, {} redrawn by peeling",
        quads.len(),
        tiles.len(),
        redrawn
    );
    let mut g = c.benchmark_group("peel_sphere_1600");
    g.sample_size(20);
    g.bench_function("two_passes", |b| {
        b.iter(|| {
            for (v, x0, y0, bin) in &tiles {
                front.begin(v, *x0, *y0);
                behind.begin(v, *x0, *y0);
                for q in bin {
                    front.draw(q, &atlas);
                }
                for q in bin {
                    behind.draw_behind(q, &atlas, &front);
                }
                black_box(behind.covered());
            }
        })
    });
    g.bench_function("one_draw", |b| {
        b.iter(|| {
            for (v, x0, y0, bin) in &tiles {
                two.begin(v, *x0, *y0);
                for q in bin {
                    two.draw(q, &atlas);
                }
                two.resolve(bin.iter().map(|q| (*q, &atlas)));
                black_box(two.back().covered());
            }
        })
    });
    // The baker's order (`bake::trained::gbuffer::near_first`): each
    // tile's quads sorted nearest first (the sort timed too), each drawn
    // at its place in the bin's order, the hidden ones skipped.
    let mut keyed: Vec<(u32, u32)> = Vec::new();
    g.bench_function("one_draw_near_first", |b| {
        b.iter(|| {
            for (v, x0, y0, bin) in &tiles {
                two.begin(v, *x0, *y0);
                keyed.clear();
                keyed.extend(
                    bin.iter()
                        .enumerate()
                        .map(|(i, q)| (!q.nearest().to_bits(), i as u32)),
                );
                keyed.sort_unstable();
                for &(near, i) in &keyed {
                    let q = bin[i as usize];
                    if !two.hides(q, f32::from_bits(!near)) {
                        two.draw_at(q, &atlas, i);
                    }
                }
                two.resolve(bin.iter().map(|q| (*q, &atlas)));
                black_box(two.back().covered());
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
