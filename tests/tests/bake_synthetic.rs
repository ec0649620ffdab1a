//! The baker on small synthetic captures whose truth is known: a sphere
//! with a red top and a blue bottom, and an axis-aligned box, rendered here
//! by ray casting (8 views at 128 px).

use glam::Vec3;
use image::{GrayImage, Luma, Rgba, RgbaImage};
use nerflex_core::shader::shade_f64;
use nerflex_sim::bake::carve::{self, Silhouettes, VoxelClass};
use nerflex_sim::bake::{
    self, atlas::AtlasLayout, quads, BakeError, BakeParams, BakeView, Geometry, Silhouette,
};
use nerflex_sim::camera::{Camera, Intrinsics};

const RED: [u8; 3] = [200, 40, 30];
const BLUE: [u8; 3] = [30, 60, 190];

/// A scene: a signed-distance-like inside test and a surface colour.
trait Scene: Sync {
    /// Ray hit distance, if any.
    fn hit(&self, o: Vec3, d: Vec3) -> Option<f32>;
    fn colour(&self, p: Vec3) -> [u8; 3];
}

struct Sphere(f32);

impl Scene for Sphere {
    fn hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        let b = o.dot(d);
        let c = o.length_squared() - self.0 * self.0;
        let disc = b * b - c;
        (disc >= 0.0).then(|| -b - disc.sqrt()).filter(|&t| t > 0.0)
    }
    fn colour(&self, p: Vec3) -> [u8; 3] {
        if p.z > 0.0 {
            RED
        } else {
            BLUE
        }
    }
}

struct Cube(f32);

impl Scene for Cube {
    fn hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        let (mut t0, mut t1) = (f32::MIN, f32::MAX);
        for a in 0..3 {
            let inv = 1.0 / d[a];
            let (mut ta, mut tb) = ((-self.0 - o[a]) * inv, (self.0 - o[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        (t0 <= t1 && t0 > 0.0).then_some(t0)
    }
    fn colour(&self, _p: Vec3) -> [u8; 3] {
        [120, 180, 90]
    }
}

fn cameras(n: usize, size: u32) -> Vec<Camera> {
    let k = Intrinsics::from_fov_x(0.69, size, size);
    (0..n)
        .map(|i| {
            let az = 360.0 * i as f32 / n as f32;
            let el = if i % 2 == 0 { 35.0 } else { -25.0 };
            Camera::orbit(az, el, 3.5, Vec3::ZERO, k)
        })
        .collect()
}

/// Renders RGBA with 2×2 supersampled coverage.
fn render(scene: &dyn Scene, cam: &Camera) -> RgbaImage {
    let k = cam.intrinsics;
    RgbaImage::from_fn(k.width, k.height, |x, y| {
        let mut rgb = [0f32; 3];
        let mut cov = 0f32;
        for (sx, sy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
            let (o, d) = cam.ray(x as f32 + sx, y as f32 + sy);
            if let Some(t) = scene.hit(o, d) {
                let c = scene.colour(o + t * d);
                for i in 0..3 {
                    rgb[i] += f32::from(c[i]);
                }
                cov += 1.0;
            }
        }
        if cov == 0.0 {
            return Rgba([0, 0, 0, 0]);
        }
        Rgba([
            (rgb[0] / cov).round() as u8,
            (rgb[1] / cov).round() as u8,
            (rgb[2] / cov).round() as u8,
            (255.0 * cov / 4.0).round() as u8,
        ])
    })
}

fn capture(scene: &dyn Scene, n: usize, size: u32) -> (Vec<Camera>, Vec<RgbaImage>) {
    let cams = cameras(n, size);
    let imgs = cams.iter().map(|c| render(scene, c)).collect();
    (cams, imgs)
}

fn views<'a>(cams: &[Camera], imgs: &'a [RgbaImage]) -> Vec<BakeView<'a>> {
    cams.iter()
        .zip(imgs)
        .map(|(c, i)| BakeView {
            camera: *c,
            image: i,
            silhouette: Silhouette::Alpha,
        })
        .collect()
}

/// The colour the shader produces for a texel (view-independent).
fn texel_colour(obj: &bake::BakedObject, q: usize, tx: u32, ty: u32) -> Option<[u8; 3]> {
    let cell = obj.atlas.layout.cell(q)?;
    let page = &obj.atlas.pages[cell.page];
    let f0 = page.feat0.get_pixel(cell.x + tx, cell.y + ty).0;
    let f1 = page.feat1.get_pixel(cell.x + tx, cell.y + ty).0;
    (f0[0] != 0).then(|| shade_f64(&obj.mlp, f0, f1, [0.0, 0.0, -1.0]))
}

#[test]
fn sphere_hull_contains_the_sphere_and_stays_close() {
    let (cams, imgs) = capture(&Sphere(0.6), 8, 128);
    let v = views(&cams, &imgs);
    let sil = Silhouettes::new(&v);
    let cube = carve::object_cube(&sil, &carve::NERF_SYNTHETIC_BOX).unwrap();
    // The cube is about the sphere's bounding cube (coarse carve + margin).
    assert!(
        (cube.max - cube.min).max_element() < 2.0 * 0.6 + 0.3,
        "{cube:?}"
    );
    assert!(cube.min.cmple(Vec3::splat(-0.6)).all() && cube.max.cmpge(Vec3::splat(0.6)).all());
    let g = 16;
    let grid = carve::shell(&sil, &cube, g);
    let h = grid.voxel;
    for k in 0..g {
        for j in 0..g {
            for i in 0..g {
                let c = grid.corner(i, j, k) + Vec3::splat(0.5 * h);
                let class = grid.class(i as i64, j as i64, k as i64);
                // Inside the sphere by more than a voxel: full.
                if c.length() < 0.6 - h {
                    assert_eq!(class, VoxelClass::Full, "voxel {i},{j},{k}");
                }
                // Every voxel the sphere's surface crosses is in the shell.
                if (c.length() - 0.6).abs() < 0.3 * h {
                    assert_eq!(class, VoxelClass::Shell, "voxel {i},{j},{k}");
                }
                // 8 views carve a sphere's hull to within a few voxels.
                if c.length() > 0.6 + 0.25 + h {
                    assert_eq!(class, VoxelClass::Empty, "voxel {i},{j},{k} at {c}");
                }
            }
        }
    }
}

#[test]
fn quads_are_grid_faces_with_consistent_winding() {
    let (cams, imgs) = capture(&Cube(0.45), 8, 128);
    let v = views(&cams, &imgs);
    let obj = bake::bake(&v, &BakeParams::new(12, 5)).unwrap();
    let h = (obj.cube.max - obj.cube.min).max_element() / 12.0;
    assert!(!obj.quads.is_empty());
    for q in &obj.quads {
        // Edges are axis-aligned voxel edges; u × v = −normal.
        assert!((q.u.length() - h).abs() < 1e-4 && (q.v.length() - h).abs() < 1e-4);
        assert!((q.u.cross(q.v) / (h * h) + q.normal).length() < 1e-4);
        for c in q.corners() {
            let g = (c - obj.cube.min) / h;
            assert!(
                (g - g.round()).abs().max_element() < 1e-3,
                "corner {c} off the grid"
            );
        }
    }
    // Most occupied texels lie within a voxel and a half of the box's
    // surface (8 views leave some wedges of the visual hull beyond it).
    let (mut near, mut all) = (0, 0);
    for (qi, q) in obj.quads.iter().enumerate() {
        for (tx, ty) in [(0, 0), (2, 2), (4, 4), (0, 4), (4, 0)] {
            if texel_colour(&obj, qi, tx, ty).is_some() {
                let x = q.point(tx as f32 / 4.0, ty as f32 / 4.0);
                all += 1;
                near += usize::from((x.abs().max_element() - 0.45).abs() < 1.5 * h);
            }
        }
    }
    assert!(near * 10 > all * 8, "{near} of {all} texels near the box");
}

#[test]
fn texel_colours_follow_the_surface() {
    let (cams, imgs) = capture(&Sphere(0.6), 8, 128);
    let v = views(&cams, &imgs);
    let obj = bake::bake(&v, &BakeParams::new(16, 5)).unwrap();
    let p = obj.params.patch;
    let (mut checked, mut bad) = (0, 0);
    for (qi, q) in obj.quads.iter().enumerate() {
        for ty in 0..p {
            for tx in 0..p {
                let Some(rgb) = texel_colour(&obj, qi, tx, ty) else {
                    continue;
                };
                let x = q.point(tx as f32 / (p - 1) as f32, ty as f32 / (p - 1) as f32);
                // Away from the equator (where views mix both colours).
                if x.z.abs() < 0.15 {
                    continue;
                }
                let want = if x.z > 0.0 { RED } else { BLUE };
                checked += 1;
                let err = (0..3)
                    .map(|c| (i32::from(rgb[c]) - i32::from(want[c])).abs())
                    .max()
                    .unwrap();
                if err > 24 {
                    bad += 1;
                }
            }
        }
    }
    assert!(checked > 500, "{checked}");
    // Nearly every texel has its hemisphere's colour.
    assert!(bad * 50 < checked, "{bad} of {checked} texels off");
}

#[test]
fn empty_texels_are_outside_the_hull_and_occupied_ones_inside() {
    let (cams, imgs) = capture(&Sphere(0.6), 8, 128);
    let v = views(&cams, &imgs);
    let obj = bake::bake(&v, &BakeParams::new(8, 9)).unwrap();
    let sil = Silhouettes::new(&v);
    let p = obj.params.patch;
    let (mut empty, mut full) = (0, 0);
    for (qi, q) in obj.quads.iter().enumerate() {
        let cell = obj.atlas.layout.cell(qi).unwrap();
        let page = &obj.atlas.pages[cell.page];
        for ty in 0..p {
            for tx in 0..p {
                let x = q.point(tx as f32 / (p - 1) as f32, ty as f32 / (p - 1) as f32);
                let r = page.feat0.get_pixel(cell.x + tx, cell.y + ty).0[0];
                assert_eq!(r != 0, sil.inside(x), "quad {qi} texel {tx},{ty} at {x}");
                if r == 0 {
                    empty += 1;
                } else {
                    full += 1;
                }
            }
        }
    }
    // At g = 8 the sphere's shape comes from texel alpha.
    assert!(empty > 0 && full > 0);
    assert_eq!(obj.stats.empty_texels, empty);
}

#[test]
fn both_geometries_bake_and_shell_has_sub_voxel_alpha() {
    let (cams, imgs) = capture(&Sphere(0.6), 8, 96);
    let v = views(&cams, &imgs);
    let mut params = BakeParams::new(10, 5);
    params.geometry = Geometry::Boundary;
    let boundary = bake::bake(&v, &params).unwrap();
    params.geometry = Geometry::Shell;
    let shell = bake::bake(&v, &params).unwrap();
    assert!(!boundary.quads.is_empty() && !shell.quads.is_empty());
    assert!(shell.stats.empty_texels > 0);
    // Every quad has at least one occupied texel.
    for obj in [&boundary, &shell] {
        for qi in 0..obj.quads.len() {
            let any = (0..5).any(|ty| (0..5).any(|tx| texel_colour(obj, qi, tx, ty).is_some()));
            assert!(any, "quad {qi} is empty");
        }
    }
}

#[test]
fn atlas_layout_matches_the_quads_and_page_limits() {
    let (cams, imgs) = capture(&Sphere(0.6), 6, 96);
    let v = views(&cams, &imgs);
    let obj = bake::bake(&v, &BakeParams::new(12, 17)).unwrap();
    assert_eq!(obj.atlas.layout.quads(), obj.quads.len());
    assert_eq!(obj.atlas.layout, AtlasLayout::new(obj.quads.len(), 17));
    let mut gpu = 0u64;
    for (i, page) in obj.atlas.pages.iter().enumerate() {
        let (w, h) = obj.atlas.layout.page_size(i);
        assert_eq!(page.feat0.dimensions(), (w, h));
        assert_eq!(page.feat1.dimensions(), (w, h));
        assert!(w <= 4096 && h <= 4096 && w % 17 == 0 && h % 17 == 0);
        gpu += 2 * 4 * u64::from(w) * u64::from(h);
    }
    assert_eq!(obj.gpu_bytes(), gpu);
}

#[test]
fn quality_settings_change_size_as_expected() {
    // More grid → more quads; more patch → same quads, bigger atlas.
    let (cams, imgs) = capture(&Sphere(0.6), 8, 96);
    let v = views(&cams, &imgs);
    let a = bake::bake(&v, &BakeParams::new(8, 5)).unwrap();
    let b = bake::bake(&v, &BakeParams::new(16, 5)).unwrap();
    let c = bake::bake(&v, &BakeParams::new(16, 9)).unwrap();
    assert!(
        b.quads.len() > 2 * a.quads.len(),
        "{} vs {}",
        b.quads.len(),
        a.quads.len()
    );
    assert!(c.gpu_bytes() > 2 * b.gpu_bytes());
    // Occupancy at p = 9 refines p = 5's: similar quad counts.
    let ratio = c.quads.len() as f64 / b.quads.len() as f64;
    assert!((0.9..1.1).contains(&ratio), "{ratio}");
}

#[test]
fn instance_masks_select_one_object() {
    // Two spheres side by side; the mask labels them 1 and 2.
    struct Two;
    impl Scene for Two {
        fn hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
            let a = Sphere(0.35).hit(o - Vec3::new(-0.5, 0.0, 0.0), d);
            let b = Sphere(0.35).hit(o - Vec3::new(0.5, 0.0, 0.0), d);
            match (a, b) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            }
        }
        fn colour(&self, p: Vec3) -> [u8; 3] {
            if p.x < 0.0 {
                RED
            } else {
                BLUE
            }
        }
    }
    let (cams, imgs) = capture(&Two, 8, 128);
    let masks: Vec<GrayImage> = imgs
        .iter()
        .map(|img| {
            GrayImage::from_fn(img.width(), img.height(), |x, y| {
                let p = img.get_pixel(x, y).0;
                Luma([if p[3] < 128 {
                    0
                } else if p[0] > p[2] {
                    1
                } else {
                    2
                }])
            })
        })
        .collect();
    let v: Vec<BakeView<'_>> = cams
        .iter()
        .zip(&imgs)
        .zip(&masks)
        .map(|((c, i), m)| BakeView {
            camera: *c,
            image: i,
            silhouette: Silhouette::Instance { mask: m, label: 2 },
        })
        .collect();
    let obj = bake::bake(&v, &BakeParams::new(16, 5)).unwrap();
    // Only the right (blue) sphere is baked.
    for q in &obj.quads {
        assert!(q.origin.x > 0.0, "{:?}", q.origin);
    }
    let c = texel_colour(&obj, obj.quads.len() / 2, 2, 2).unwrap_or(BLUE);
    assert!(c[2] > c[0], "{c:?}");
}

#[test]
fn bad_input_gives_clear_errors() {
    let (cams, imgs) = capture(&Sphere(0.6), 4, 64);
    let v = views(&cams, &imgs);
    let e = bake::bake(&v, &BakeParams::new(0, 5))
        .unwrap_err()
        .to_string();
    assert!(e.contains("--grid 0"), "{e}");
    let e = bake::bake(&v, &BakeParams::new(8, 1))
        .unwrap_err()
        .to_string();
    assert!(e.contains("--patch 1"), "{e}");
    let e = bake::bake(&[], &BakeParams::new(8, 5))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no training views"), "{e}");
    // An image that does not match its camera.
    let small = RgbaImage::new(32, 32);
    let mut bad = v.clone();
    bad[1].image = &small;
    let e = bake::bake(&bad, &BakeParams::new(8, 5))
        .unwrap_err()
        .to_string();
    assert!(e.contains("view 1") && e.contains("32×32"), "{e}");
    // Empty silhouettes carve everything away.
    let blank: Vec<RgbaImage> = imgs
        .iter()
        .map(|i| RgbaImage::new(i.width(), i.height()))
        .collect();
    let e = bake::bake(&views(&cams, &blank), &BakeParams::new(8, 5)).unwrap_err();
    assert!(matches!(e, BakeError::Empty), "{e}");
}

#[test]
fn boundary_quads_of_a_single_voxel_are_its_six_faces() {
    let (cams, imgs) = capture(&Cube(0.3), 8, 96);
    let v = views(&cams, &imgs);
    let sil = Silhouettes::new(&v);
    // A 1³ grid over the cube's bounds: one occupied voxel, six faces.
    let cube = bake::Aabb {
        min: Vec3::splat(-0.3),
        max: Vec3::splat(0.3),
    };
    let grid = carve::carve(&sil, &cube, 1, carve::VoxelTest::Centre);
    assert_eq!(grid.occupied_count(), 1);
    let qs = quads::boundary_quads(&grid);
    assert_eq!(qs.len(), 6);
    let mut normals: Vec<[i32; 3]> = qs
        .iter()
        .map(|q| q.normal.round().as_ivec3().to_array())
        .collect();
    normals.sort();
    normals.dedup();
    assert_eq!(normals.len(), 6);
}

#[test]
fn the_renderer_reproduces_the_baked_colours() {
    // One flat colour everywhere: every drawn pixel of the fixed-point
    // render must show it (the texel code and MLP are exact to 1 level;
    // allow 2 for the colour average of edge texels).
    struct Flat;
    impl Scene for Flat {
        fn hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
            Sphere(0.6).hit(o, d)
        }
        fn colour(&self, _p: Vec3) -> [u8; 3] {
            [150, 90, 201]
        }
    }
    let (cams, imgs) = capture(&Flat, 8, 96);
    let v = views(&cams, &imgs);
    let asset = bake::bake(&v, &BakeParams::new(12, 5))
        .unwrap()
        .into_asset()
        .unwrap();
    let img = nerflex_sim::bake::sweep::fixed_point_render(&asset, &cams[3]).unwrap();
    let mut drawn = 0;
    for p in img.pixels().filter(|p| p.0[3] == 255) {
        drawn += 1;
        for (c, want) in p.0[..3].iter().zip([150u8, 90, 201]) {
            assert!(c.abs_diff(want) <= 2, "pixel {:?}", p.0);
        }
    }
    assert!(drawn > 1000, "{drawn} pixels drawn");
}
