//! Sphere-traced rendering of placed procedural objects to RGBA + instance mask.
//!
//! - **Culling**: each ray is moved into every object's local frame and
//!   clipped against the object's local bounds (slab test); only objects it
//!   enters are marched, nearest entry first, and an object whose entry lies
//!   beyond the best hit so far is skipped.
//! - **Marching**: sphere tracing with the object's step factor; a hit is a
//!   distance below half a pixel's footprint at that depth, so thin features
//!   resolve to the image's own resolution.
//! - **Shading**: procedural material at the local hit point; a warm key
//!   light with soft shadows (cast by all objects), a cool fill, a rim light,
//!   a sky/ground ambient with ambient occlusion, Blinn–Phong highlights and
//!   a Fresnel-weighted sky reflection (view-dependent), then an ACES-style
//!   tone curve and the sRGB transfer curve.
//! - **Antialiasing**: one ray per pixel centre first; pixels whose 3×3
//!   neighbourhood changes object (silhouettes) get `edge_samples²` more
//!   rays, pixels with colour contrast above `contrast` get
//!   `texture_samples²`. Alpha is the fraction of rays that hit, colour the
//!   mean of the hits (straight alpha), the mask value the object most rays hit.

use super::complexity::{stats, Occupancy};
use super::layout::{PlacedObject, Placement};
use super::objects::{Aabb, ObjectKind};
use crate::camera::Camera;
use glam::Vec3;
use image::{GrayImage, Luma, Rgba, RgbaImage};
use rayon::prelude::*;

/// Quality knobs of [`SceneRenderer::render`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Rays per axis in silhouette pixels (4 → 16 extra rays).
    pub edge_samples: u32,
    /// Rays per axis in high-contrast texture pixels (3 → 9 extra rays).
    pub texture_samples: u32,
    /// Display-value difference to a neighbour (0–1) that triggers texture supersampling.
    pub contrast: f32,
    /// Soft shadows from the key light.
    pub shadows: bool,
    /// Ambient occlusion.
    pub ambient_occlusion: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            edge_samples: 4,
            texture_samples: 3,
            contrast: 0.06,
            shadows: true,
            ambient_occlusion: true,
        }
    }
}

/// One rendered view.
#[derive(Debug, Clone)]
pub struct RenderedView {
    /// Straight-alpha RGBA, alpha = coverage.
    pub image: RgbaImage,
    /// Instance mask: 0 background, k = object index + 1.
    pub mask: GrayImage,
}

struct Prepared {
    kind: ObjectKind,
    /// Cached cell-centre distances for the far-field bound.
    field: &'static Occupancy,
    placement: Placement,
    bounds: Aabb,
    step: f32,
    detail: f32,
}

impl Prepared {
    /// The object's distance bound: the cached far-field bound when it is
    /// at least a cell, else the exact function (near the surface).
    #[inline]
    fn dist(&self, p: Vec3) -> f32 {
        match self.field.distance_bound(p) {
            Some(lb) if lb > self.field.voxel => lb,
            _ => self.kind.sdf(p),
        }
    }
}

/// A scene ready to render from any camera.
pub struct SceneRenderer {
    objects: Vec<Prepared>,
}

/// Slowly varying lighting terms of a shaded point.
#[derive(Debug, Clone, Copy)]
struct Light {
    /// Ambient occlusion, 0–1.
    ao: f32,
    /// Key-light visibility, 0–1.
    shadow: f32,
}

impl Default for Light {
    fn default() -> Self {
        Self {
            ao: 1.0,
            shadow: 1.0,
        }
    }
}

struct Hit {
    obj: usize,
    /// Local hit point.
    p: Vec3,
    /// Half the pixel footprint at the hit (local units): the normal's
    /// difference step and the shadow ray's offset scale.
    eps: f32,
}

const MAX_STEPS: u32 = 320;

// Lights (world space, z up). Directions point toward the light.
const KEY_DIR: Vec3 = Vec3::new(0.478, -0.382, 0.791);
const KEY_RGB: Vec3 = Vec3::new(2.35, 2.2, 2.0);
const FILL_DIR: Vec3 = Vec3::new(-0.73, 0.61, 0.31);
const FILL_RGB: Vec3 = Vec3::new(0.32, 0.38, 0.48);
const RIM_DIR: Vec3 = Vec3::new(-0.2, 0.9, 0.39);
const RIM_RGB: Vec3 = Vec3::new(0.3, 0.3, 0.3);
const SKY: Vec3 = Vec3::new(0.42, 0.48, 0.58);
const GROUND: Vec3 = Vec3::new(0.2, 0.18, 0.16);

impl SceneRenderer {
    /// Prepares `objects` (object `i` gets mask value `i + 1`; at most 255).
    pub fn new(objects: &[PlacedObject]) -> Self {
        Self {
            objects: objects
                .iter()
                .take(255)
                .map(|o| Prepared {
                    kind: o.kind,
                    field: stats(o.kind),
                    placement: o.placement,
                    bounds: o.kind.bounds(),
                    step: o.kind.march_step(),
                    detail: o.detail,
                })
                .collect(),
        }
    }

    /// Display colour (each channel in [0, 1]) of object `obj`'s surface at
    /// world point `world` seen along unit direction `dir` (camera → point),
    /// shaded as [`Self::render`] shades a hit there (`world` should lie on
    /// the surface). For analytic stand-ins of trained radiance fields.
    pub fn surface_colour(&self, obj: usize, world: Vec3, dir: Vec3, opts: &RenderOptions) -> Vec3 {
        let Some(ob) = self.objects.get(obj) else {
            return Vec3::ZERO;
        };
        let hit = Hit {
            obj,
            p: ob.placement.to_local(world),
            eps: 1e-3,
        };
        display(self.shade(&hit, dir, opts, None).0)
    }

    /// Renders the view of `camera` at its intrinsics' size. Rows are
    /// rendered in parallel (rayon).
    pub fn render(&self, camera: &Camera, opts: &RenderOptions) -> RenderedView {
        let k = camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let pix = 1.0 / k.fx.min(k.fy).max(1e-6);
        // Pass 1: one ray through each pixel centre.
        let mut lin = vec![Vec3::ZERO; w * h];
        let mut ids = vec![0u8; w * h];
        let mut light = vec![Light::default(); w * h];
        lin.par_chunks_mut(w.max(1))
            .zip(ids.par_chunks_mut(w.max(1)))
            .zip(light.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(y, ((lrow, irow), grow))| {
                for x in 0..w {
                    let (c, id, l) =
                        self.sample(camera, x as f32 + 0.5, y as f32 + 0.5, pix, opts, None);
                    lrow[x] = c;
                    irow[x] = id;
                    grow[x] = l;
                }
            });
        let disp: Vec<Vec3> = lin.par_iter().map(|&c| display(c)).collect();
        // Pass 2: refine silhouettes and high-contrast texture.
        let mut image = RgbaImage::new(k.width, k.height);
        let mut mask = GrayImage::new(k.width, k.height);
        let rows: Vec<(Vec<[u8; 4]>, Vec<u8>)> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut px = Vec::with_capacity(w);
                let mut mk = Vec::with_capacity(w);
                for x in 0..w {
                    let i = y * w + x;
                    let n = self.refinement(&ids, &disp, w, h, x, y, opts);
                    if n == 0 {
                        let id = ids[i];
                        if id == 0 {
                            px.push([0, 0, 0, 0]);
                        } else {
                            px.push(to_rgba8(disp[i], 1.0));
                        }
                        mk.push(id);
                        continue;
                    }
                    let mut counts = [0u32; 256];
                    let mut sum = Vec3::ZERO;
                    let mut hits = 0u32;
                    // The centre ray counts as one of the samples.
                    if ids[i] != 0 {
                        counts[ids[i] as usize] += 1;
                        sum += lin[i];
                        hits += 1;
                    }
                    for sy in 0..n {
                        for sx in 0..n {
                            let fx = x as f32 + (sx as f32 + 0.5) / n as f32;
                            let fy = y as f32 + (sy as f32 + 0.5) / n as f32;
                            // Occlusion and shadow vary slowly: reuse the
                            // centre ray's where the same object is hit.
                            let reuse = (ids[i] != 0).then_some((ids[i], light[i]));
                            let (c, id, _) = self.sample(camera, fx, fy, pix, opts, reuse);
                            if id != 0 {
                                counts[id as usize] += 1;
                                sum += c;
                                hits += 1;
                            }
                        }
                    }
                    let total = n * n + 1;
                    if hits == 0 {
                        px.push([0, 0, 0, 0]);
                        mk.push(0);
                    } else {
                        let alpha = hits as f32 / total as f32;
                        px.push(to_rgba8(display(sum / hits as f32), alpha));
                        let best = (1..256)
                            .max_by_key(|&v| (counts[v], std::cmp::Reverse(v)))
                            .unwrap_or(0);
                        mk.push(best as u8);
                    }
                }
                (px, mk)
            })
            .collect();
        for (y, (px, mk)) in rows.into_iter().enumerate() {
            for (x, (p, m)) in px.into_iter().zip(mk).enumerate() {
                image.put_pixel(x as u32, y as u32, Rgba(p));
                mask.put_pixel(x as u32, y as u32, Luma([m]));
            }
        }
        RenderedView { image, mask }
    }

    /// Rays per axis for pixel (x, y): 0 keeps the centre ray alone.
    #[allow(clippy::too_many_arguments)]
    fn refinement(
        &self,
        ids: &[u8],
        disp: &[Vec3],
        w: usize,
        h: usize,
        x: usize,
        y: usize,
        opts: &RenderOptions,
    ) -> u32 {
        let i = y * w + x;
        let mut contrast = 0.0f32;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if ids[j] != ids[i] {
                    return opts.edge_samples;
                }
                if ids[i] != 0 {
                    contrast = contrast.max((disp[j] - disp[i]).abs().max_element());
                }
            }
        }
        if contrast > opts.contrast {
            opts.texture_samples
        } else {
            0
        }
    }

    /// Linear radiance, mask value (0 = background) and lighting terms of
    /// the ray through continuous pixel coordinates; `reuse` supplies the
    /// lighting terms for hits on the object with that mask value.
    fn sample(
        &self,
        camera: &Camera,
        px: f32,
        py: f32,
        pix: f32,
        opts: &RenderOptions,
        reuse: Option<(u8, Light)>,
    ) -> (Vec3, u8, Light) {
        let (o, d) = camera.ray(px, py);
        match self.trace(o, d, pix) {
            Some(hit) => {
                let id = (hit.obj + 1) as u8;
                let known = reuse.and_then(|(rid, l)| (rid == id).then_some(l));
                let (c, l) = self.shade(&hit, d, opts, known);
                (c, id, l)
            }
            None => (Vec3::ZERO, 0, Light::default()),
        }
    }

    /// The nearest surface along the world ray `o + t·d` (d unit).
    fn trace(&self, o: Vec3, d: Vec3, pix: f32) -> Option<Hit> {
        let mut cands: Vec<(f32, usize, Vec3, Vec3, f32)> = Vec::with_capacity(self.objects.len());
        for (i, ob) in self.objects.iter().enumerate() {
            let ro = ob.placement.to_local(o);
            let rd = ob.placement.dir_to_local(d);
            if let Some((t0, t1)) = ob.bounds.ray(ro, rd.recip()) {
                cands.push((t0 * ob.placement.scale, i, ro, rd, t1));
            }
        }
        cands.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best: Option<(f32, Hit)> = None;
        for (t0w, i, ro, rd, t1) in cands {
            if best.as_ref().is_some_and(|(bt, _)| t0w >= *bt) {
                break;
            }
            let ob = &self.objects[i];
            let s = ob.placement.scale;
            if let Some((t, eps)) = march(ob, ro, rd, t0w / s, t1, pix) {
                let tw = t * s;
                if best.as_ref().is_none_or(|(bt, _)| tw < *bt) {
                    best = Some((
                        tw,
                        Hit {
                            obj: i,
                            p: ro + rd * t,
                            eps,
                        },
                    ));
                }
            }
        }
        best.map(|(_, h)| h)
    }

    fn shade(
        &self,
        hit: &Hit,
        d: Vec3,
        opts: &RenderOptions,
        known: Option<Light>,
    ) -> (Vec3, Light) {
        let ob = &self.objects[hit.obj];
        let nl = normal(ob.kind, hit.p, hit.eps.max(4e-4));
        let m = ob.kind.material(hit.p, nl, ob.detail);
        let n = ob.placement.dir_to_world(nl);
        let v = -d;
        let pw = ob.placement.to_world(hit.p);
        let Light {
            ao,
            shadow: key_shadow,
        } = known.unwrap_or_else(|| Light {
            ao: if opts.ambient_occlusion {
                ambient_occlusion(ob, hit.p, nl)
            } else {
                1.0
            },
            shadow: if opts.shadows && n.dot(KEY_DIR) > 0.0 {
                let bias = hit.eps.max(2e-3) * ob.placement.scale;
                self.soft_shadow(pw + n * bias, KEY_DIR)
            } else {
                1.0
            },
        });
        let spec_rgb = Vec3::splat(m.specular).lerp(m.albedo, m.metal);
        let diffuse_rgb = m.albedo * (1.0 - 0.85 * m.metal);
        let norm = (m.shininess + 8.0) / (8.0 * std::f32::consts::PI);
        let mut diffuse = Vec3::ZERO;
        let mut spec = Vec3::ZERO;
        for (l, c, sh) in [
            (KEY_DIR, KEY_RGB, key_shadow),
            (FILL_DIR, FILL_RGB, 1.0),
            (RIM_DIR, RIM_RGB, 1.0),
        ] {
            let ndl = n.dot(l).max(0.0);
            if ndl <= 0.0 {
                continue;
            }
            let hv = (l + v).normalize_or_zero();
            let ndh = n.dot(hv).max(0.0);
            diffuse += c * ndl * sh;
            spec += c * (ndl * sh * norm * ndh.powf(m.shininess));
        }
        let ambient = GROUND.lerp(SKY, 0.5 + 0.5 * n.z) * ao;
        // Sky seen in the mirror direction, stronger at grazing angles.
        let r = d - 2.0 * d.dot(n) * n;
        let fresnel = (1.0 - n.dot(v).clamp(0.0, 1.0)).powi(5);
        let gloss = m.shininess / (m.shininess + 40.0);
        let env = GROUND.lerp(SKY, 0.5 + 0.5 * r.z) * ao * gloss;
        let env_w = spec_rgb + (Vec3::ONE - spec_rgb) * fresnel * m.specular.max(0.04);
        let c = diffuse_rgb * (diffuse + ambient) + spec_rgb * spec + env * env_w;
        (
            c,
            Light {
                ao,
                shadow: key_shadow,
            },
        )
    }

    /// Key-light visibility from world point `p` along `l`: 0 shadowed,
    /// 1 lit, soft in between (Quílez's penumbra estimate).
    fn soft_shadow(&self, p: Vec3, l: Vec3) -> f32 {
        let mut res = 1.0f32;
        for ob in &self.objects {
            let ro = ob.placement.to_local(p);
            let rd = ob.placement.dir_to_local(l);
            let Some((t0, t1)) = ob.bounds.ray(ro, rd.recip()) else {
                continue;
            };
            let mut t = t0.max(0.01 / ob.placement.scale);
            for _ in 0..64 {
                if t > t1 {
                    break;
                }
                let h = ob.dist(ro + rd * t);
                res = res.min(10.0 * h / t);
                if res < 0.01 {
                    return 0.0;
                }
                t += h.clamp(0.005, 0.25) * ob.step;
            }
        }
        let r = res.clamp(0.0, 1.0);
        r * r * (3.0 - 2.0 * r)
    }
}

/// Sphere tracing of one object in its local frame from `t0` to `t1`
/// (local units along the unit direction `rd` from the camera-side origin
/// `ro`). Returns the hit distance and the tolerance used there.
#[inline]
fn march(ob: &Prepared, ro: Vec3, rd: Vec3, t0: f32, t1: f32, pix: f32) -> Option<(f32, f32)> {
    let step = ob.step;
    let mut t = t0;
    let mut last = (f32::MAX, 0.0);
    for _ in 0..MAX_STEPS {
        let d = ob.dist(ro + rd * t);
        // A fifth of the pixel footprint: a looser test would swell
        // silhouettes by the tolerance. The footprint is returned for the
        // normal's difference step (smooth at the image's resolution).
        let eps = (0.2 * pix * t).max(1e-4);
        if d < eps {
            return Some((t, 2.5 * eps));
        }
        last = (d, 2.5 * eps);
        t += d * step;
        if t > t1 {
            return None;
        }
    }
    // Out of steps while grazing a surface: close enough counts as a hit.
    (last.0 < last.1).then_some((t, last.1))
}

/// Unit normal by the tetrahedral difference of the distance (step `h`).
#[inline]
fn normal(kind: ObjectKind, p: Vec3, h: f32) -> Vec3 {
    let k = [
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(-1.0, -1.0, 1.0),
        Vec3::new(-1.0, 1.0, -1.0),
        Vec3::new(1.0, 1.0, 1.0),
    ];
    let g = k
        .iter()
        .fold(Vec3::ZERO, |acc, &e| acc + e * kind.sdf(p + e * h));
    g.normalize_or(Vec3::Z)
}

/// Occlusion from the object itself, probing along the normal.
#[inline]
fn ambient_occlusion(ob: &Prepared, p: Vec3, n: Vec3) -> f32 {
    let (mut occ, mut w) = (0.0, 1.0);
    for i in 0..5 {
        let h = 0.01 + 0.04 * i as f32;
        occ += (h - ob.kind.sdf(p + n * h)).max(0.0) * w;
        w *= 0.8;
    }
    (1.0 - 2.2 * occ).clamp(0.0, 1.0)
}

/// Linear radiance to display values in [0, 1]: exposure, ACES-fitted tone
/// curve (Narkowicz), sRGB transfer.
#[inline]
pub fn display(c: Vec3) -> Vec3 {
    let x = c * 0.8;
    let t = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    let enc = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
    };
    Vec3::new(enc(t.x), enc(t.y), enc(t.z))
}

fn to_rgba8(c: Vec3, alpha: f32) -> [u8; 4] {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [q(c.x), q(c.y), q(c.z), q(alpha)]
}

#[cfg(test)]
mod tests {
    use super::super::layout::{arrange, Layout};
    use super::*;
    use crate::camera::Intrinsics;

    #[test]
    fn a_ball_renders_as_a_disc_with_soft_edges() {
        let objs = arrange(&[ObjectKind::Ball], Layout::Row, 0, 1.0);
        let r = SceneRenderer::new(&objs);
        let cam = Camera::orbit(
            30.0,
            20.0,
            4.0,
            Vec3::ZERO,
            Intrinsics::from_fov_x(0.69, 48, 48),
        );
        let v = r.render(&cam, &RenderOptions::default());
        // The centre is opaque object 1, the corners background.
        assert_eq!(v.image.get_pixel(24, 24).0[3], 255);
        assert_eq!(v.mask.get_pixel(24, 24).0[0], 1);
        assert_eq!(v.image.get_pixel(0, 0).0, [0, 0, 0, 0]);
        assert_eq!(v.mask.get_pixel(0, 0).0[0], 0);
        // Some silhouette pixels are partially covered, and mask > 0 exactly where alpha > 0.
        let partial = v
            .image
            .pixels()
            .filter(|p| p.0[3] > 0 && p.0[3] < 255)
            .count();
        assert!(partial > 20, "{partial}");
        for (p, m) in v.image.pixels().zip(v.mask.pixels()) {
            assert_eq!(p.0[3] > 0, m.0[0] > 0);
        }
        // Its projected radius matches the geometry: r = 0.75 at distance 4.
        let covered: f32 = v.image.pixels().map(|p| p.0[3] as f32 / 255.0).sum();
        let fx = cam.intrinsics.fx;
        let expect = std::f32::consts::PI * (fx * (0.75f32 / (16.0f32 - 0.5625).sqrt())).powi(2);
        assert!(
            (covered - expect).abs() / expect < 0.05,
            "{covered} vs {expect}"
        );
    }

    #[test]
    fn specular_highlights_move_with_the_view() {
        // The same surface point seen from two directions differs in colour.
        let objs = arrange(&[ObjectKind::Vase], Layout::Row, 0, 1.0);
        let r = SceneRenderer::new(&objs);
        let k = Intrinsics::from_fov_x(0.69, 64, 64);
        let p = Vec3::new(0.0, -0.55, 0.0) + objs[0].placement.translation;
        let mut colours = Vec::new();
        for az in [-40.0f32, 0.0, 40.0] {
            let cam = Camera::orbit(az, 30.0, 4.0, Vec3::ZERO, k);
            let (x, y, _) = cam.project(p).unwrap();
            let v = r.render(&cam, &RenderOptions::default());
            colours.push(v.image.get_pixel(x as u32, y as u32).0);
        }
        let diff = |a: [u8; 4], b: [u8; 4]| {
            (0..3)
                .map(|i| (a[i] as i32 - b[i] as i32).abs())
                .max()
                .unwrap()
        };
        assert!(
            diff(colours[0], colours[2]) > 3 || diff(colours[0], colours[1]) > 3,
            "{colours:?}"
        );
    }
}
