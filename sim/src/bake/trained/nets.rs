//! MobileNeRF's mesh from a field: one vertex per voxel the surface
//! crosses, one quad around each grid edge the surface crosses, joining
//! the vertices of the edge's four voxels (the topology of MobileNeRF's
//! grid mesh, also known as surface nets). MobileNeRF learns its vertices'
//! offsets within their voxels; here each vertex is placed from the field
//! directly: the mean of the points where the field's surface crosses the
//! voxel's edges.
//!
//! Unlike the per-voxel planes of [`super::extract::extract_with`],
//! neighbouring quads share their corners: the surface is one connected
//! sheet, so a pixel sees one surface whatever the view (the planes
//! overlap against cracks and take turns being in front). A feature
//! thinner than a voxel that no lattice corner falls inside is lost, as
//! in MobileNeRF at the same g.
//!
//! Quads are no longer planar (the corners of a mesh quad need not be
//! coplanar): [`Quad::twist`] carries the bend, and texel points follow
//! the renderer's two triangles ([`Quad::point`]).

use glam::Vec3;
use rayon::prelude::*;

use super::super::carve::VoxelClass;
use super::super::quads::Quad;
use super::extract::{classify, object_cube, voxel_quads, Geometry, Surface, SurfaceSettings};

/// No vertex in this voxel.
const NONE: u32 = u32::MAX;

/// Largest g of the mesh (its vertex index is a g³ array of `u32`: 0.5 GB
/// at 512; the hull baker's carve stops at the same g).
pub const MAX_MESH_GRID: u32 = 512;

/// The mesh of `s` on a `g`³ grid over the object's cube, every texel of
/// its p×p patches opaque. `refine` bisection steps find where each
/// crossing edge enters the inside; a voxel's vertex is the mean of its
/// edges' entries. (Moving each entry on to where the opacity accumulated
/// along the edge reaches ½, as the planes do, shrank lego's silhouettes
/// by a pixel or two and cost 2.1 dB: `docs/baking.md`, "Session 13".)
/// `None` when no point of the field is inside.
///
/// With `fill`, voxels the surface crosses between the lattice's corners
/// (a feature thinner than a voxel: no edge of the voxel crosses, so the
/// mesh has no vertex there) get the per-voxel planes of
/// [`super::extract::extract_with`] with those settings, their texel
/// opacity from the field.
pub fn extract_nets(
    s: &Surface<'_>,
    g: u32,
    p: u32,
    refine: u32,
    fill: Option<&SurfaceSettings>,
) -> Option<Geometry> {
    let cube = object_cube(s)?;
    let gu = g.max(1) as usize;
    let n = gu + 1;
    let h = (cube.max - cube.min).max_element() / gu as f32;
    let origin = cube.min;
    let corner = |c: [usize; 3]| origin + h * Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
    let inside: Vec<bool> = (0..n * n * n)
        .into_par_iter()
        .map(|c| s.inside(corner([c % n, c / n % n, c / (n * n)])))
        .collect();
    let at = |c: [usize; 3]| inside[(c[2] * n + c[1]) * n + c[0]];

    // Where the surface crosses the edge from corner `c` along `axis`
    // (the two ends differ).
    let crossing = |c: [usize; 3], axis: usize| -> Vec3 {
        let mut d = c;
        d[axis] += 1;
        let (end_out, end_in) = if at(c) {
            (corner(d), corner(c))
        } else {
            (corner(c), corner(d))
        };
        let (mut x_out, mut x_in) = (end_out, end_in);
        for _ in 0..refine {
            let mid = 0.5 * (x_out + x_in);
            if s.inside(mid) {
                x_in = mid;
            } else {
                x_out = mid;
            }
        }
        0.5 * (x_out + x_in)
    };

    // One vertex per voxel with a crossing edge: the mean of its crossings.
    // Only the voxels with a vertex are kept (a g³ array of positions
    // would be 2 GB at g = 512): one layer of voxels per task.
    let layers: Vec<Vec<(u32, Vec3)>> = (0..gu)
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..gu {
                for i in 0..gu {
                    let mut sum = Vec3::ZERO;
                    let mut count = 0u32;
                    for axis in 0..3 {
                        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                        for (o1, o2) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let mut c = [i, j, k];
                            c[a1] += o1;
                            c[a2] += o2;
                            let mut d = c;
                            d[axis] += 1;
                            if at(c) != at(d) {
                                sum += crossing(c, axis);
                                count += 1;
                            }
                        }
                    }
                    if count > 0 {
                        out.push((((k * gu + j) * gu + i) as u32, sum / count as f32));
                    }
                }
            }
            out
        })
        .collect();
    let mut vid = vec![NONE; gu * gu * gu];
    let mut points = Vec::new();
    for (v, x) in layers.into_iter().flatten() {
        vid[v as usize] = points.len() as u32;
        points.push(x);
    }
    let shell_voxels = points.len() as u64;
    // Voxels without a crossing are wholly inside or wholly outside.
    let full_voxels = (0..gu * gu * gu)
        .filter(|&v| vid[v] == NONE && at([v % gu, v / gu % gu, v / (gu * gu)]))
        .count() as u64;

    // One quad per crossing edge whose four voxels all lie in the grid,
    // in corner scan order (neighbouring quads in neighbouring atlas
    // cells).
    let voxel_at = |c: [usize; 3]| vid[(c[2] * gu + c[1]) * gu + c[0]];
    let quad_layers: Vec<Vec<Quad>> = (0..gu)
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..n {
                for i in 0..n {
                    for axis in 0..3 {
                        let c = [i, j, k];
                        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                        // The edge's four voxels must lie in the grid.
                        if c[axis] >= gu || !(1..gu).contains(&c[a1]) || !(1..gu).contains(&c[a2]) {
                            continue;
                        }
                        let mut d = c;
                        d[axis] += 1;
                        let (lo_in, hi_in) = (at(c), at(d));
                        if lo_in == hi_in {
                            continue;
                        }
                        // The four voxels around the edge: A (−1, −1), B
                        // (0, −1), C (0, 0), D (−1, 0) in (a1, a2).
                        let vox = |o1: usize, o2: usize| {
                            let mut v = c;
                            v[a1] = v[a1] + o1 - 1;
                            v[a2] = v[a2] + o2 - 1;
                            v
                        };
                        let ids = [vox(0, 0), vox(1, 0), vox(1, 1), vox(0, 1)].map(voxel_at);
                        if ids.contains(&NONE) {
                            continue;
                        }
                        let [a, b, cc, dd] = ids.map(|id| points[id as usize]);
                        // Outward is +axis when the low end is inside: then
                        // u = D − A, v = B − A gives u × v = −normal.
                        let (c1, c2) = if lo_in { (b, dd) } else { (dd, b) };
                        let (u, v) = (c2 - a, c1 - a);
                        let twist = cc - c2 - c1 + a;
                        let mut axis_n = Vec3::ZERO;
                        axis_n[axis] = if lo_in { 1.0 } else { -1.0 };
                        let normal = (c1 - c2).cross(cc - a).normalize_or(axis_n);
                        let cv = vox(1, 1);
                        out.push(Quad {
                            origin: a,
                            u,
                            v,
                            normal,
                            voxel: cv.map(|x| x.min(gu - 1) as u32),
                            twist,
                        });
                    }
                }
            }
            out
        })
        .collect();
    let mut quads: Vec<Quad> = quad_layers.into_iter().flatten().collect();
    let mut opacity = vec![true; quads.len() * (p * p) as usize];
    if let Some(set) = fill {
        let grid = classify(s, &cube, gu as u32);
        let thin: Vec<[u32; 3]> = (0..gu * gu * gu)
            .filter(|&v| vid[v] == NONE)
            .map(|v| [v % gu, v / gu % gu, v / (gu * gu)].map(|x| x as u32))
            .filter(|&[i, j, k]| grid.class(i.into(), j.into(), k.into()) == VoxelClass::Shell)
            .collect();
        let per: Vec<Vec<(Quad, Vec<bool>)>> = thin
            .par_iter()
            .map(|&[i, j, k]| voxel_quads(s, grid.corner(i, j, k), h, [i, j, k], p, set))
            .collect();
        for (q, occ) in per.into_iter().flatten() {
            quads.push(q);
            opacity.extend(occ);
        }
    }
    Some(Geometry {
        cube,
        voxel: h,
        shell_voxels,
        full_voxels,
        quads,
        opacity,
    })
}

#[cfg(test)]
mod tests {
    use super::super::analytic::Sphere;
    use super::super::extract::texel_point;
    use super::*;

    /// On a sphere the mesh is closed, faces outward, and every texel
    /// point lies within a fraction of a voxel of the sphere.
    #[test]
    fn a_sphere_gives_a_closed_outward_mesh_on_its_surface() {
        let f = Sphere::new(Vec3::new(0.1, -0.05, 0.0), 0.6);
        let s = Surface::new(&f, 0.5);
        let (g, p) = (16, 5);
        let geo = extract_nets(&s, g, p, 6, None).expect("a sphere has an inside");
        assert!(!geo.quads.is_empty());
        assert_eq!(geo.opacity.len(), geo.quads.len() * 25);
        let mut worst = 0.0f32;
        for q in &geo.quads {
            let centre = q.point(0.5, 0.5);
            assert!(
                q.normal.dot((centre - f.centre).normalize()) > 0.5,
                "a quad faces inward: {q:?}"
            );
            for t in 0..p * p {
                let x = texel_point(q, p, t % p, t / p);
                worst = worst.max(((x - f.centre).length() - f.radius).abs());
            }
        }
        assert!(worst < 0.35 * geo.voxel, "{worst} vs voxel {}", geo.voxel);
        // Closed: every quad edge is shared by exactly two quads.
        let key = |x: Vec3| (x * 1e4).round().as_ivec3().to_array();
        let mut edges = std::collections::HashMap::new();
        for q in &geo.quads {
            let c = q.corners();
            for (a, b) in [(0, 1), (1, 3), (3, 2), (2, 0)] {
                let (ka, kb) = (key(c[a]), key(c[b]));
                let e = if ka < kb { (ka, kb) } else { (kb, ka) };
                *edges.entry(e).or_insert(0u32) += 1;
            }
        }
        assert!(edges.values().all(|&k| k == 2), "open or non-manifold mesh");
        // With the planes' fill (`--surface mesh+planes`) the mesh comes
        // first, unchanged, with its texels opaque; planes follow.
        let set = SurfaceSettings::default();
        let filled = extract_nets(&s, g, p, 6, Some(&set)).expect("inside");
        assert_eq!(&filled.quads[..geo.quads.len()], &geo.quads[..]);
        assert_eq!(filled.opacity.len(), filled.quads.len() * 25);
        assert!(filled.opacity[..geo.opacity.len()].iter().all(|&o| o));
    }

    /// The renderer's G-buffer and `Quad::point` agree on a strongly bent
    /// quad: the point of the texel each pixel shows lies on that pixel's
    /// ray (within a texel and a pixel's footprint).
    #[test]
    fn the_gbuffer_texel_of_a_bent_quad_lies_on_its_pixel_ray() {
        use crate::bake::trained::gbuffer;
        use crate::bake::{Aabb, BakeView, Silhouette};
        use crate::camera::{Camera, Intrinsics};
        // A unit quad in the x–z plane facing −y (towards the camera),
        // corner 3 pulled 0.4 towards the camera.
        let q = Quad {
            origin: Vec3::new(-0.5, 0.0, -0.5),
            u: Vec3::new(0.0, 0.0, 1.0),
            v: Vec3::new(1.0, 0.0, 0.0),
            normal: -Vec3::Y,
            voxel: [0; 3],
            twist: Vec3::new(0.0, -0.4, 0.0),
        };
        assert!(q.u.cross(q.v).dot(q.normal) < 0.0, "u × v = −normal");
        let p = 17;
        let geo = Geometry {
            cube: Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            },
            voxel: 1.0,
            shell_voxels: 1,
            full_voxels: 0,
            quads: vec![q],
            opacity: vec![true; (p * p) as usize],
        };
        let size = 96;
        let k = Intrinsics::from_fov_x(0.5, size, size);
        let cam = Camera::look_at(Vec3::new(0.8, -3.0, 0.6), Vec3::ZERO, Vec3::Z, k);
        let image = image::RgbaImage::from_pixel(size, size, image::Rgba([0, 0, 0, 255]));
        let views = [BakeView {
            camera: cam,
            image: &image,
            silhouette: Silhouette::Alpha,
        }];
        let gb = gbuffer::of_geometry(&geo, p, &views, false).unwrap();
        assert!(gb.pixels.len() > 500, "{} pixels", gb.pixels.len());
        // A texel spans 1/16 of the quad; a pixel about 0.03 units here.
        let tol = 0.5 * (1.0f32 / 16.0) * 2f32.sqrt() + 0.03;
        let worst = gb
            .pixel_rays(&geo, p, &views)
            .map(|(_, [o, d, x])| (x - o).cross(d).length())
            .reduce(|| 0.0, f32::max);
        assert!(
            worst < tol,
            "a texel point {worst} off its pixel's ray (tol {tol})"
        );
    }

    /// `Quad::point` follows the two triangles: the corners, and points
    /// of each triangle affine in (s, t).
    #[test]
    fn twisted_quads_map_texels_onto_their_two_triangles() {
        let q = Quad {
            origin: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::Y,
            normal: Vec3::Z,
            voxel: [0; 3],
            twist: Vec3::new(0.0, 0.0, 0.4),
        };
        let c = q.corners();
        assert_eq!(q.point(0.0, 0.0), c[0]);
        assert_eq!(q.point(0.0, 1.0), c[1]);
        assert_eq!(q.point(1.0, 0.0), c[2]);
        assert_eq!(q.point(1.0, 1.0), c[3]);
        // Triangle (0, 3, 2) (s ≥ t): barycentric mix of its corners.
        let (s, t) = (0.7, 0.2);
        let bary = c[0] * (1.0 - s) + c[2] * (s - t) + c[3] * t;
        assert!((q.point(s, t) - bary).length() < 1e-6);
        let (s, t) = (0.2, 0.7);
        let bary = c[0] * (1.0 - t) + c[1] * (t - s) + c[3] * s;
        assert!((q.point(s, t) - bary).length() < 1e-6);
    }
}
