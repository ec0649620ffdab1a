use super::*;
use crate::shader::{FixedMlp, MlpWeights};
use embedded_graphics_core::geometry::OriginDimensions;
use embedded_graphics_core::Pixel;
use glam::Vec3;
use std::vec;
use std::vec::Vec;

/// Camera on +y... at `eye` looking at the origin, z up, square image.
fn view(eye: Vec3, size: u32, fov_deg: f32) -> View {
    let back = eye.normalize();
    let right = Vec3::Z.cross(back).normalize();
    let up = back.cross(right);
    let c2w = Mat4::from_cols(
        right.extend(0.0),
        up.extend(0.0),
        back.extend(0.0),
        eye.extend(1.0),
    );
    let f = 0.5 * size as f32 / (0.5 * fov_deg.to_radians()).tan();
    View::new(c2w, f, f, 0.5 * size as f32, 0.5 * size as f32, size, size).unwrap()
}

/// Quad in the plane y = `y`, x ∈ [x0, x1], z ∈ [z0, z1], mapping the whole
/// `n × n` atlas (texel centres at the corners, as the export does).
fn quad(y: f32, x0: f32, x1: f32, z0: f32, z1: f32, n: u32) -> Quad {
    let t0 = 0.5;
    let t1 = n as f32 - 0.5;
    // Corner order of the export: 0 = (0,0), 1 = (0,1), 2 = (1,0), 3 = (1,1) in (x, y) texels.
    Quad::new([
        Vertex::at_texel([x0, y, z1], t0, t0, n, n),
        Vertex::at_texel([x0, y, z0], t0, t1, n, n),
        Vertex::at_texel([x1, y, z1], t1, t0, n, n),
        Vertex::at_texel([x1, y, z0], t1, t1, n, n),
    ])
}

/// An `n × n` atlas: feat0 = (x+1, y+1, 0, 0) so the texel is readable back.
fn atlas_pages(n: u32, empty: impl Fn(u32, u32) -> bool) -> (Vec<u8>, Vec<u8>) {
    let mut f0 = vec![0u8; (n * n * 4) as usize];
    let f1 = vec![128u8; (n * n * 4) as usize];
    for y in 0..n {
        for x in 0..n {
            let o = ((y * n + x) * 4) as usize;
            if !empty(x, y) {
                f0[o] = (x + 1) as u8;
                f0[o + 1] = (y + 1) as u8;
            }
        }
    }
    (f0, f1)
}

fn mlp() -> FixedMlp {
    FixedMlp::from_weights(&MlpWeights::ZERO).unwrap()
}

struct Fb {
    w: u32,
    h: u32,
    px: Vec<[u8; 3]>,
    writes: Vec<u32>,
}

impl OriginDimensions for Fb {
    fn size(&self) -> Size {
        Size::new(self.w, self.h)
    }
}

impl DrawTarget for Fb {
    type Color = Rgb888;
    type Error = core::convert::Infallible;
    fn draw_iter<I: IntoIterator<Item = Pixel<Rgb888>>>(
        &mut self,
        it: I,
    ) -> Result<(), Self::Error> {
        use embedded_graphics_core::pixelcolor::RgbColor;
        for Pixel(p, c) in it {
            let i = (p.y as u32 * self.w + p.x as u32) as usize;
            self.px[i] = [c.r(), c.g(), c.b()];
            self.writes[i] += 1;
        }
        Ok(())
    }
}

/// Rasterizes all quads into one full-frame tile list; returns samples.
fn raster(v: &View, parts: &[Part]) -> (Vec<Option<Sample>>, TileStats) {
    let mut out = vec![None; (v.width() * v.height()) as usize];
    let mut tile = TileRenderer::<16, 8>::new();
    let mut stats = TileStats::default();
    let _ = for_each_tile::<16, 8, ()>(&mut tile, v, parts, |t| {
        t.for_each_sample(|x, y, s| out[(y * v.width() + x) as usize] = s);
        stats.add(&t.stats());
        Ok(())
    });
    (out, stats)
}

#[test]
fn a_facing_quad_covers_its_projection_without_cracks_or_overlap() {
    // Camera on −y looking at +y; the quad at y = 0 spans x, z ∈ [−1, 1].
    let v = view(Vec3::new(0.0, -4.0, 0.0), 64, 40.0);
    let (f0, f1) = atlas_pages(16, |_, _| false);
    let quads = [quad(0.0, -1.0, 1.0, -1.0, 1.0, 16)];
    let m = mlp();
    let parts = [Part {
        quads: &quads,
        atlas: Atlas::new(16, 16, &f0, &f1).unwrap(),
        mlp: &m,
    }];
    let (samples, stats) = raster(&v, &parts);
    // Projected square: half-size f·1/4 pixels around the centre.
    let f = 32.0 / (20f32.to_radians()).tan();
    let half = f / 4.0;
    let mut expect = 0;
    for y in 0..64 {
        for x in 0..64 {
            let inside =
                ((x as f32 + 0.5) - 32.0).abs() < half && ((y as f32 + 0.5) - 32.0).abs() < half;
            let got = samples[y * 64 + x].is_some();
            if inside {
                expect += 1;
            }
            // Away from the boundary (sub-pixel), coverage must match exactly.
            let dist = (((x as f32 + 0.5) - 32.0).abs() - half)
                .abs()
                .min((((y as f32 + 0.5) - 32.0).abs() - half).abs());
            if dist > 0.01 {
                assert_eq!(got, inside, "pixel {x},{y}");
            }
        }
    }
    let covered = samples.iter().filter(|s| s.is_some()).count();
    assert!(
        (covered as i32 - expect).abs() <= 2,
        "{covered} vs {expect}"
    );
    // Two triangles, shared diagonal: every covered pixel written exactly once.
    assert_eq!(stats.fragments as usize, covered);
    assert_eq!(stats.discarded, 0);
}

#[test]
fn texture_lookup_is_perspective_correct() {
    // A floor quad seen at a grazing angle: compare each pixel's texel with
    // the ray–plane intersection.
    let eye = Vec3::new(0.3, -3.0, 1.2);
    let v = view(eye, 96, 50.0);
    let n = 64;
    let (f0, f1) = atlas_pages(n, |_, _| false);
    // Plane z = 0, x ∈ [−1, 1], y ∈ [−1, 1] (texel x ↔ world x, texel y ↔ −world y).
    let t0 = 0.5;
    let t1 = n as f32 - 0.5;
    let q = Quad::new([
        Vertex::at_texel([-1.0, 1.0, 0.0], t0, t0, n, n),
        Vertex::at_texel([-1.0, -1.0, 0.0], t0, t1, n, n),
        Vertex::at_texel([1.0, 1.0, 0.0], t1, t0, n, n),
        Vertex::at_texel([1.0, -1.0, 0.0], t1, t1, n, n),
    ]);
    let quads = [q];
    let m = mlp();
    let parts = [Part {
        quads: &quads,
        atlas: Atlas::new(n, n, &f0, &f1).unwrap(),
        mlp: &m,
    }];
    let (samples, _) = raster(&v, &parts);
    let mut checked = 0;
    let mut off = 0;
    for y in 0..96u32 {
        for x in 0..96u32 {
            let Some(s) = samples[(y * 96 + x) as usize] else {
                continue;
            };
            let d = v.pixel_dir_f32(x, y);
            let t = -eye.z / d[2];
            let (wx, wy) = (eye.x + t * d[0], eye.y + t * d[1]);
            // Texel coordinate: x from 0.5 at −1 to n − 0.5 at +1.
            let tx = t0 + (wx + 1.0) / 2.0 * (t1 - t0);
            let ty = t0 + (1.0 - wy) / 2.0 * (t1 - t0);
            let (ex, ey) = (tx.floor() as i64, ty.floor() as i64);
            let (gx, gy) = (s.texel[0] as i64, s.texel[1] as i64);
            // Only texel-boundary cases may differ, by one texel.
            assert!(
                (gx - ex).abs() <= 1 && (gy - ey).abs() <= 1,
                "pixel {x},{y}: {gx},{gy} vs {ex},{ey}"
            );
            if (gx, gy) != (ex, ey) {
                off += 1;
            }
            checked += 1;
        }
    }
    assert!(checked > 1000, "{checked}");
    assert!(off * 100 < checked, "{off} of {checked} off by one texel");
}

#[test]
fn depth_test_keeps_the_nearest_quad_in_any_order_and_alpha_test_discards() {
    let v = view(Vec3::new(0.0, -4.0, 0.0), 32, 40.0);
    let (fa0, fa1) = atlas_pages(8, |_, _| false);
    // The near quad's left half is empty: the far quad shows through there.
    let (fb0, fb1) = atlas_pages(8, |x, _| x < 4);
    let far = [quad(0.5, -1.0, 1.0, -1.0, 1.0, 8)];
    let near = [quad(-0.5, -1.0, 1.0, -1.0, 1.0, 8)];
    let m = mlp();
    let a = Atlas::new(8, 8, &fa0, &fa1).unwrap();
    let b = Atlas::new(8, 8, &fb0, &fb1).unwrap();
    for order in [[0, 1], [1, 0]] {
        let all = [
            Part {
                quads: &far,
                atlas: a,
                mlp: &m,
            },
            Part {
                quads: &near,
                atlas: b,
                mlp: &m,
            },
        ];
        let parts = [all[order[0]], all[order[1]]];
        let near_index = order.iter().position(|&i| i == 1).unwrap() as u16;
        let (samples, stats) = raster(&v, &parts);
        assert!(stats.discarded > 0);
        let row = 16 * 32;
        let left = samples[row + 12].unwrap();
        let right = samples[row + 20].unwrap();
        assert_ne!(
            left.part, near_index,
            "empty texels of the near quad are discarded"
        );
        assert_eq!(
            right.part, near_index,
            "the near quad wins where it is opaque"
        );
    }
}

#[test]
fn pixel_dir_matches_float_rays_and_is_unit() {
    let v = view(Vec3::new(1.0, -3.0, 2.0), 200, 60.0);
    for (x, y) in [(0, 0), (199, 0), (0, 199), (100, 100), (37, 150)] {
        let q = v.pixel_dir(x, y).to_f64();
        let f = v.pixel_dir_f32(x, y);
        let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-8, "{len}");
        for k in 0..3 {
            assert!((q[k] - f[k] as f64).abs() < 1e-6, "{q:?} {f:?}");
        }
    }
    // The centre pixel looks at the origin (the camera's target).
    let c = v.pixel_dir_f32(100, 100);
    let want = Vec3::new(-1.0, 3.0, -2.0).normalize();
    assert!((Vec3::from(c) - want).length() < 0.01);
}

#[test]
fn render_frame_and_coverage_agree_and_fill_every_pixel_once() {
    let v = view(Vec3::new(2.0, -3.0, 1.5), 50, 45.0);
    let (f0, f1) = atlas_pages(16, |x, y| (x + y) % 5 == 0);
    let quads = [
        quad(0.0, -1.0, 1.0, -1.0, 1.0, 16),
        quad(0.3, -0.5, 0.7, -0.2, 1.3, 16),
        Quad::triangle(
            Vertex::at_texel([-1.0, -0.5, -1.0], 0.5, 0.5, 16, 16),
            Vertex::at_texel([1.0, -0.5, -1.0], 15.5, 0.5, 16, 16),
            Vertex::at_texel([0.0, -0.5, 0.8], 8.0, 15.5, 16, 16),
        ),
    ];
    let m = mlp();
    let parts = [Part {
        quads: &quads,
        atlas: Atlas::new(16, 16, &f0, &f1).unwrap(),
        mlp: &m,
    }];
    let mut fb = Fb {
        w: 50,
        h: 50,
        px: vec![[0; 3]; 2500],
        writes: vec![0; 2500],
    };
    let mut tile = TileRenderer::<8, 16>::new();
    let stats = render_frame(&mut tile, &v, &parts, &mut fb).unwrap();
    assert!(fb.writes.iter().all(|&w| w == 1));
    let grey = fb.px.iter().filter(|p| **p == [128; 3]).count();
    let white = fb.px.iter().filter(|p| **p == [255; 3]).count();
    assert_eq!(grey + white, 2500);
    assert_eq!(grey as u32, stats.pixels_shaded);
    assert!(grey > 300 && white > 300);
    let mut bits = [0u32; 1];
    let cov = coverage(&mut tile, &v, &parts, &mut bits).unwrap();
    assert_eq!(cov.pixels_covered, stats.pixels_shaded);
    assert_eq!(cov.quads_drawn, 3);
    assert_eq!(stats.quads_drawn, 3);
    assert_eq!(cov.quads_visible, 3);
    assert_eq!(bits[0], 0b111);
    assert_eq!(
        coverage(&mut tile, &v, &parts, &mut []),
        Err(RasterError::BufferTooSmall { needed: 1, got: 0 })
    );
}

#[test]
fn quads_behind_or_beside_the_camera_are_not_drawn_and_bad_input_does_not_panic() {
    let v = view(Vec3::new(0.0, -4.0, 0.0), 32, 40.0);
    let behind = quad(-5.0, -1.0, 1.0, -1.0, 1.0, 8);
    assert!(ScreenQuad::project(&v, &behind, 0, 0).is_none());
    let beside = quad(0.0, 10.0, 11.0, -1.0, 1.0, 8);
    assert!(ScreenQuad::project(&v, &beside, 0, 0).is_none());
    // Straddling the camera plane: the triangle with a corner behind is skipped.
    let mut straddle = quad(0.0, -1.0, 1.0, -1.0, 1.0, 8);
    straddle.corners[1].pos = [-1.0, -5.0, -1.0];
    let sq = ScreenQuad::project(&v, &straddle, 0, 0).unwrap();
    assert_eq!(sq.clipped, 1);
    let _ = sq;
    let mut nan = quad(0.0, -1.0, 1.0, -1.0, 1.0, 8);
    nan.corners[0].pos[0] = f32::NAN;
    nan.corners[2].uv[0] = f32::INFINITY;
    let (f0, f1) = atlas_pages(8, |_, _| false);
    let m = mlp();
    let quads = [nan];
    let parts = [Part {
        quads: &quads,
        atlas: Atlas::new(8, 8, &f0, &f1).unwrap(),
        mlp: &m,
    }];
    let _ = raster(&v, &parts);
    assert_eq!(
        Atlas::new(8, 8, &f0, &f1[1..]).unwrap_err(),
        RasterError::BadAtlas
    );
    assert_eq!(
        Atlas::new(0, 8, &[], &[]).unwrap_err(),
        RasterError::BadAtlas
    );
    assert!(View::new(Mat4::IDENTITY, 0.0, 1.0, 0.0, 0.0, 8, 8).is_err());
    assert!(View::new(Mat4::ZERO, 10.0, 10.0, 4.0, 4.0, 8, 8).is_err());
    assert!(View::new(Mat4::IDENTITY, 10.0, 10.0, 4.0, 4.0, 0, 8).is_err());
}

#[test]
fn g_buffer_is_16_bytes_per_pixel() {
    assert_eq!(core::mem::size_of::<GPixel>(), 16);
    assert!(core::mem::size_of::<TileRenderer<16, 8>>() < 16 * 8 * 16 + 64);
}

#[test]
fn the_mean_texel_rounds_and_survives_empty_input() {
    assert_eq!(mean_texel(&[]), ([0; 4], [0; 4]));
    let a = ([10, 20, 30, 255], [0, 1, 2, 3]);
    let b = ([11, 20, 31, 255], [1, 1, 3, 3]);
    assert_eq!(mean_texel(&[a]), a);
    // (10 + 11) / 2 = 10.5 rounds up; 255s stay 255.
    assert_eq!(mean_texel(&[a, b]), ([11, 20, 31, 255], [1, 1, 3, 3]));
    let full = ([255; 4], [255; 4]);
    assert_eq!(mean_texel(&[full, full, full, full]), full);
}

/// The two-layer properties' quads: `(plane, tilt, steps, x, x, z, z,
/// id)` each, in planes a hair, a margin's width or far apart, some
/// crossing; ids repeat (the peel skips the front's quad by id).
type LayerQuad = (usize, usize, i32, u8, u8, u8, u8, u32);

/// A permutation of `0..n` from `seed` (Fisher–Yates on a 64-bit LCG);
/// seed 0 is the reverse order.
fn permutation(n: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).rev().collect();
    let mut r = seed;
    for i in (1..order.len()).rev() {
        if seed == 0 {
            break;
        }
        r = r
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        order.swap(i, (r >> 33) as usize % (i + 1));
    }
    order
}

/// 1 to 13 of the two-layer properties' quads, ids 0–5.
fn layer_quad_list() -> impl proptest::strategy::Strategy<Value = Vec<LayerQuad>> {
    proptest::collection::vec(
        (
            0usize..4,
            0usize..4,
            -4i32..=4,
            0u8..6,
            0u8..6,
            0u8..6,
            0u8..6,
            0u32..6,
        ),
        1..14,
    )
}

/// Texels per side of the two-layer properties' atlas.
const LAYER_ATLAS: u32 = 8;

/// The two-layer properties' scene: the view, the atlas pages (`holes`
/// of every 5 texels empty) and the quads projected.
fn layer_scene(quads: &[LayerQuad], holes: u32) -> (View, (Vec<u8>, Vec<u8>), Vec<ScreenQuad>) {
    let v = view(Vec3::new(0.0, -4.0, 0.3), 24, 40.0);
    let n = LAYER_ATLAS;
    let pages = atlas_pages(n, |x, y| holes > 0 && (x * 7 + y * 3) % 5 < holes);
    let sq = layer_quads(&v, quads, n);
    (v, pages, sq)
}

fn layer_quads(v: &View, quads: &[LayerQuad], n: u32) -> Vec<ScreenQuad> {
    let ys = [0.0f32, 1e-6, 3e-5, 0.25];
    let tilts = [0.0f32, 0.0, 0.3, -0.4];
    let ext = |e: u8| -1.2 + 0.45 * f32::from(e);
    quads
        .iter()
        .enumerate()
        .filter_map(|(i, &(yi, ti, dz, xa, xb, za, zb, id))| {
            let (x0, x1) = (ext(xa.min(xb)), ext(xa.max(xb)) + 0.3);
            let (z0, z1) = (ext(za.min(zb)), ext(za.max(zb)) + 0.3);
            let y = ys[yi] + dz as f32 * 0.125;
            let q = tilted_quad(y, tilts[ti], x0, x1, z0, z1, n);
            ScreenQuad::project(v, &q, (i % 2) as u16, id)
        })
        .collect()
}

proptest::proptest! {
    /// `span` keeps exactly the steps a per-pixel edge test keeps.
    #[test]
    fn span_equals_the_per_pixel_test(
        last in 0i64..40,
        e in proptest::array::uniform3(-(1i64 << 40)..(1i64 << 40)),
        d in proptest::array::uniform3(-(1i64 << 38)..(1i64 << 38)),
        small in proptest::array::uniform3(-300i64..300),
        use_small in proptest::bool::ANY,
    ) {
        // Small values make edges cross inside the run; large ones test range.
        let e = if use_small { small } else { e };
        let d = if use_small { [small[1] / 7, small[2] / 11, small[0] / 13] } else { d };
        let edges = [(e[0], d[0]), (e[1], d[1]), (e[2], d[2])];
        let inside: Vec<i64> = (0..=last)
            .filter(|&k| edges.iter().all(|&(e, d)| e - k * d >= 0))
            .collect();
        let got: Vec<i64> = match span(last, edges) {
            Some((k0, k1)) => (k0..=k1).collect(),
            None => Vec::new(),
        };
        proptest::prop_assert_eq!(got, inside);
    }
}

/// The alpha test as bits answers as the atlas does, clamping included,
/// and a tile drawn through either holds the same samples and counters.
#[test]
fn alpha_bits_test_as_the_atlas_does() {
    // Not a multiple of 64 wide, so rows end mid-word.
    let (w, h) = (70u32, 37u32);
    let mut seed = 0x9e37_79b9_u32;
    let mut empty = vec![false; (w * h) as usize];
    for e in empty.iter_mut() {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        *e = seed >> 30 == 0; // a quarter of the texels
    }
    let mut f0 = vec![0u8; (w * h * 4) as usize];
    let f1 = vec![7u8; (w * h * 4) as usize];
    let words = AlphaBits::row_words(w);
    let mut bits = vec![0u64; words * h as usize];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if !empty[i] {
                f0[i * 4] = 1 + (x % 200) as u8;
                bits[y as usize * words + x as usize / 64] |= 1 << (x % 64);
            }
        }
    }
    let atlas = Atlas::new(w, h, &f0, &f1).unwrap();
    let mask = AlphaBits::new(w, h, &bits).unwrap();
    assert!(AlphaBits::new(w, h, &bits[1..]).is_err());
    for y in 0..h + 3 {
        for x in 0..w + 70 {
            assert_eq!(
                AlphaTest::empty(&mask, x, y),
                AlphaTest::empty(&atlas, x, y),
                "({x}, {y})"
            );
        }
    }
    // Overlapping quads at several depths, each over the whole page.
    let v = view(Vec3::new(0.3, -4.0, 0.2), 64, 40.0);
    let quads: Vec<Quad> = (0..6)
        .map(|i| {
            let d = 0.1 * i as f32;
            let tex = |x: f32, y: f32| (0.5 + x * (w - 1) as f32, 0.5 + y * (h - 1) as f32);
            let c = [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)];
            let pos = |k: usize| {
                let (u, t) = c[k];
                [-1.0 + d + 1.5 * u, d - 0.3, 1.0 - d - 1.7 * t]
            };
            Quad::new(core::array::from_fn(|k| {
                let (tx, ty) = tex(c[k].0, c[k].1);
                Vertex::at_texel(pos(k), tx, ty, w, h)
            }))
        })
        .collect();
    let mut a = TileRenderer::<32, 32>::new();
    let mut b = TileRenderer::<32, 32>::new();
    let mut discarded = 0;
    for (x0, y0) in [(0, 0), (32, 0), (0, 32), (32, 32)] {
        a.begin(&v, x0, y0);
        b.begin(&v, x0, y0);
        for (id, q) in quads.iter().enumerate() {
            if let Some(sq) = ScreenQuad::project(&v, q, 0, id as u32) {
                a.draw(&sq, &atlas);
                b.draw(&sq, &mask);
            }
        }
        assert_eq!(a.stats(), b.stats());
        discarded += a.stats().discarded;
        for y in 0..32 {
            for x in 0..32 {
                assert_eq!(a.sample(x, y), b.sample(x, y));
            }
        }
    }
    assert!(discarded > 0);
}

#[test]
fn peeling_shows_what_lies_behind_the_front_sample() {
    let v = view(Vec3::new(0.0, -4.0, 0.0), 32, 40.0);
    let (f0, f1) = atlas_pages(8, |_, _| false);
    let a = Atlas::new(8, 8, &f0, &f1).unwrap();
    // Three parallel quads, drawn in a scrambled order: near, middle, far.
    let ys = [0.0f32, -0.5, 0.5];
    let sq: Vec<ScreenQuad> = ys
        .iter()
        .enumerate()
        .map(|(i, &y)| {
            ScreenQuad::project(&v, &quad(y, -1.0, 1.0, -1.0, 1.0, 8), i as u16, i as u32).unwrap()
        })
        .collect();
    let mut front = TileRenderer::<32, 32>::new();
    let mut behind = TileRenderer::<32, 32>::new();
    front.begin(&v, 0, 0);
    behind.begin(&v, 0, 0);
    for q in &sq {
        front.draw(q, &a);
    }
    for q in &sq {
        behind.draw_behind(q, &a, &front);
    }
    let (x, y) = (16, 16);
    assert_eq!(
        front.sample(x, y).unwrap().quad,
        1,
        "the near quad in front"
    );
    assert_eq!(
        behind.sample(x, y).unwrap().quad,
        0,
        "the middle one behind it"
    );
    // Where nothing is in front, nothing is behind either.
    assert!(front.sample(0, 0).is_none() && behind.sample(0, 0).is_none());
    // Peeling the peeled layer reaches the far quad, then nothing.
    let mut third = TileRenderer::<32, 32>::new();
    third.begin(&v, 0, 0);
    for q in &sq {
        third.draw_behind(q, &a, &behind);
    }
    assert_eq!(third.sample(x, y).unwrap().quad, 2);
    let mut fourth = TileRenderer::<32, 32>::new();
    fourth.begin(&v, 0, 0);
    for q in &sq {
        fourth.draw_behind(q, &a, &third);
    }
    assert!(fourth.sample(x, y).is_none());
    // Nearer than: the front layer before the one behind it, never the
    // reverse nor itself; a covered pixel before an empty one; outside the
    // tile, nothing.
    assert!(front.nearer_than(&behind, x, y));
    assert!(!behind.nearer_than(&front, x, y));
    assert!(!front.nearer_than(&front, x, y));
    assert!(third.nearer_than(&fourth, x, y));
    assert!(!fourth.nearer_than(&third, x, y));
    assert!(!front.nearer_than(&behind, 0, 0));
    assert!(!front.nearer_than(&behind, 32, 16) && !front.nearer_than(&behind, u32::MAX, 0));
}

/// A quad for the two-layer property: in a plane near `y` (tilted by
/// `tilt` along x), over x ∈ [x0, x1], z ∈ [z0, z1].
fn tilted_quad(y: f32, tilt: f32, x0: f32, x1: f32, z0: f32, z1: f32, n: u32) -> Quad {
    let (t0, t1) = (0.5, n as f32 - 0.5);
    let at = |x: f32| y + tilt * x;
    Quad::new([
        Vertex::at_texel([x0, at(x0), z1], t0, t0, n, n),
        Vertex::at_texel([x0, at(x0), z0], t0, t1, n, n),
        Vertex::at_texel([x1, at(x1), z1], t1, t0, n, n),
        Vertex::at_texel([x1, at(x1), z0], t1, t1, n, n),
    ])
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(1024))]

    /// One draw of both layers gives what a front pass and a peeling pass
    /// give, pixel for pixel, whatever the order, near-coplanar stacks,
    /// crossing planes, empty texels and repeated quad ids.
    #[test]
    fn two_layers_in_one_draw_equal_the_two_passes(
        quads in layer_quad_list(),
        holes in 0u32..4,
    ) {
        let (v, (f0, f1), sq) = layer_scene(&quads, holes);
        let a = Atlas::new(LAYER_ATLAS, LAYER_ATLAS, &f0, &f1).unwrap();
        let mut front = TileRenderer::<16, 16>::new();
        let mut behind = TileRenderer::<16, 16>::new();
        let mut two = TwoLayers::<16, 16>::new();
        for (tx, ty) in [(0, 0), (16, 0), (0, 16), (16, 16)] {
            front.begin(&v, tx, ty);
            behind.begin(&v, tx, ty);
            two.begin(&v, tx, ty);
            for q in &sq {
                front.draw(q, &a);
                two.draw(q, &a);
            }
            for q in &sq {
                behind.draw_behind(q, &a, &front);
            }
            proptest::prop_assert_eq!(two.front().stats(), front.stats());
            let decided = !two.undecided();
            let mut same_back = true;
            for y in 0..16 {
                for x in 0..16 {
                    proptest::prop_assert_eq!(two.front().sample(x, y), front.sample(x, y));
                    same_back &= two.back().sample(x, y) == behind.sample(x, y);
                }
            }
            // Decided in one pass: already exact.
            proptest::prop_assert!(!decided || same_back, "decided but different");
            two.resolve(sq.iter().map(|q| (q, &a)));
            for y in 0..16 {
                for x in 0..16 {
                    proptest::prop_assert_eq!(two.back().sample(x, y), behind.sample(x, y));
                }
            }
        }
    }

    /// One layer drawn in any order by id, skipping the quads it already
    /// hides, is the in-order draw's.
    #[test]
    fn a_layer_drawn_by_id_in_any_order_equals_the_in_order_draw(
        quads in layer_quad_list(),
        holes in 0u32..4,
        shuffle in proptest::prelude::any::<u64>(),
    ) {
        let (v, (f0, f1), mut sq) = layer_scene(&quads, holes);
        let a = Atlas::new(LAYER_ATLAS, LAYER_ATLAS, &f0, &f1).unwrap();
        // Distinct ids in the draw order.
        for (i, q) in sq.iter_mut().enumerate() {
            q.id = i as u32;
        }
        let order = permutation(sq.len(), shuffle);
        let mut in_order = TileRenderer::<16, 16>::new();
        let mut any = TileRenderer::<16, 16>::new();
        let mut skipping = TileRenderer::<16, 16>::new();
        for (tx, ty) in [(0, 0), (16, 0), (0, 16), (16, 16)] {
            in_order.begin(&v, tx, ty);
            any.begin(&v, tx, ty);
            skipping.begin(&v, tx, ty);
            for q in &sq {
                in_order.draw(q, &a);
            }
            for &i in &order {
                any.draw_by_id(&sq[i], &a);
                if !skipping.hides(&sq[i], sq[i].nearest()) {
                    skipping.draw_by_id(&sq[i], &a);
                }
            }
            for y in 0..16 {
                for x in 0..16 {
                    let f = in_order.sample(x, y);
                    proptest::prop_assert_eq!(any.sample(x, y), f);
                    proptest::prop_assert_eq!(skipping.sample(x, y), f);
                }
            }
        }
    }

    /// Drawn in any order at their places in the draw order, the layers
    /// are the in-order ones (equal depths go to the earlier place), and
    /// so the two passes'; so are they when the quads the layers already
    /// hide are skipped.
    #[test]
    fn two_layers_drawn_in_any_order_equal_the_in_order_draw(
        quads in layer_quad_list(),
        holes in 0u32..4,
        shuffle in proptest::prelude::any::<u64>(),
    ) {
        let (v, (f0, f1), sq) = layer_scene(&quads, holes);
        let a = Atlas::new(LAYER_ATLAS, LAYER_ATLAS, &f0, &f1).unwrap();
        let order = permutation(sq.len(), shuffle);
        let mut in_order = TwoLayers::<16, 16>::new();
        let mut any = TwoLayers::<16, 16>::new();
        // … also skipping the quads the layers hide when their turn comes.
        let mut skipping = TwoLayers::<16, 16>::new();
        for (tx, ty) in [(0, 0), (16, 0), (0, 16), (16, 16)] {
            in_order.begin(&v, tx, ty);
            any.begin(&v, tx, ty);
            skipping.begin(&v, tx, ty);
            for q in &sq {
                in_order.draw(q, &a);
            }
            for &i in &order {
                any.draw_at(&sq[i], &a, i as u32);
                if !skipping.hides(&sq[i], sq[i].nearest()) {
                    skipping.draw_at(&sq[i], &a, i as u32);
                }
            }
            for y in 0..16 {
                for x in 0..16 {
                    let f = in_order.front().sample(x, y);
                    proptest::prop_assert_eq!(any.front().sample(x, y), f);
                    proptest::prop_assert_eq!(skipping.front().sample(x, y), f);
                }
            }
            for two in [&mut in_order, &mut any, &mut skipping] {
                two.resolve(sq.iter().map(|q| (q, &a)));
            }
            for y in 0..16 {
                for x in 0..16 {
                    let b = in_order.back().sample(x, y);
                    proptest::prop_assert_eq!(any.back().sample(x, y), b);
                    proptest::prop_assert_eq!(skipping.back().sample(x, y), b);
                }
            }
        }
    }
}

#[test]
fn two_layers_decide_a_plain_stack_in_one_pass() {
    // The scrambled three-quad stack of the peeling test, in one draw.
    let v = view(Vec3::new(0.0, -4.0, 0.0), 32, 40.0);
    let (f0, f1) = atlas_pages(8, |_, _| false);
    let a = Atlas::new(8, 8, &f0, &f1).unwrap();
    let mut two = TwoLayers::<32, 32>::new();
    two.begin(&v, 0, 0);
    for (i, y) in [0.0f32, -0.5, 0.5].into_iter().enumerate() {
        let q = quad(y, -1.0, 1.0, -1.0, 1.0, 8);
        two.draw(&ScreenQuad::project(&v, &q, 0, i as u32).unwrap(), &a);
    }
    assert!(!two.undecided());
    assert_eq!(two.front().sample(16, 16).unwrap().quad, 1);
    assert_eq!(two.back().sample(16, 16).unwrap().quad, 0);
    assert!(two.front().sample(0, 0).is_none() && two.back().sample(0, 0).is_none());
}
