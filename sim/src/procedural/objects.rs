//! The catalogue of procedural objects: geometry (signed distance), local
//! bounds and surface material (procedural textures), in local object units
//! that fit the NeRF-synthetic unit-cube convention (z up, about [−1, 1]³).

use super::noise::{cellular, fbm, value};
use super::sdf::*;
use super::text::page;
use super::tree::tree;
use glam::{Vec2, Vec3, Vec3Swizzles};
use std::f32::consts::{PI, TAU};

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The box `[min, max]`.
    pub const fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The empty box (union identity).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::MAX),
        max: Vec3::splat(f32::MIN),
    };

    /// Centre point.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Edge lengths.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// The smallest box holding both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb::new(self.min.min(o.min), self.max.max(o.max))
    }

    /// The box grown to hold `p`.
    pub fn with_point(&self, p: Vec3) -> Aabb {
        Aabb::new(self.min.min(p), self.max.max(p))
    }

    /// The box grown by `d` on every side.
    pub fn padded(&self, d: f32) -> Aabb {
        Aabb::new(self.min - Vec3::splat(d), self.max + Vec3::splat(d))
    }

    /// The eight corners.
    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }

    /// Whether `p` is inside (boundary included).
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Entry and exit distances of the ray `o + t·d` (slab test), if it hits
    /// the box at some t ≥ 0.
    #[inline]
    pub fn ray(&self, o: Vec3, inv_d: Vec3) -> Option<(f32, f32)> {
        let t0 = (self.min - o) * inv_d;
        let t1 = (self.max - o) * inv_d;
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element();
        (near <= far).then_some((near, far))
    }
}

/// Surface appearance at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Diffuse colour, linear RGB in [0, 1].
    pub albedo: Vec3,
    /// Specular strength (reflectance at normal incidence), [0, 1].
    pub specular: f32,
    /// Blinn–Phong exponent: higher is glossier.
    pub shininess: f32,
    /// 0 dielectric (white highlights), 1 metal (highlights tinted by albedo).
    pub metal: f32,
}

/// sRGB hex colour to linear RGB.
fn rgb(hex: u32) -> Vec3 {
    let c = |s: u32| ((hex >> s) & 0xff) as f32 / 255.0;
    let lin = |v: f32| {
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    Vec3::new(lin(c(16)), lin(c(8)), lin(c(0)))
}

fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn mat(albedo: Vec3, specular: f32, shininess: f32) -> Material {
    Material {
        albedo,
        specular,
        shininess,
        metal: 0.0,
    }
}

fn metal(albedo: Vec3, shininess: f32) -> Material {
    Material {
        albedo,
        specular: 0.8,
        shininess,
        metal: 1.0,
    }
}

/// The procedural objects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ObjectKind {
    /// A glossy beach ball: a sphere with six coloured gores.
    Ball,
    /// A smooth hollow vase with a plain celadon glaze.
    Vase,
    /// A wooden box: rounded cube, wood grain and plank seams.
    Box,
    /// A marble chess pawn (surface of revolution).
    Pawn,
    /// A frosted donut with sprinkles.
    Torus,
    /// A polka-dot mug with a handle.
    Mug,
    /// A framed sign on legs, printed with lines of small text.
    TextPanel,
    /// A steel coil spring between two plates with a guide rod.
    Spring,
    /// Three stacked gears (36, 24 and 14 teeth) with windows, axle and nut.
    Gear,
    /// A potted tree: recursive branches and noisy foliage clumps.
    Tree,
    /// A 5×5×5 lattice of rods and joints.
    Lattice,
    /// A level-3 Menger sponge in sandstone.
    Sponge,
}

impl ObjectKind {
    /// Every object, in catalogue order.
    pub const ALL: [ObjectKind; 12] = [
        ObjectKind::Ball,
        ObjectKind::Vase,
        ObjectKind::Box,
        ObjectKind::Pawn,
        ObjectKind::Torus,
        ObjectKind::Mug,
        ObjectKind::TextPanel,
        ObjectKind::Spring,
        ObjectKind::Gear,
        ObjectKind::Tree,
        ObjectKind::Lattice,
        ObjectKind::Sponge,
    ];

    /// The name used on the command line and in `scene.json`.
    pub fn name(self) -> &'static str {
        match self {
            ObjectKind::Ball => "ball",
            ObjectKind::Vase => "vase",
            ObjectKind::Box => "box",
            ObjectKind::Pawn => "pawn",
            ObjectKind::Torus => "torus",
            ObjectKind::Mug => "mug",
            ObjectKind::TextPanel => "text-panel",
            ObjectKind::Spring => "spring",
            ObjectKind::Gear => "gear",
            ObjectKind::Tree => "tree",
            ObjectKind::Lattice => "lattice",
            ObjectKind::Sponge => "sponge",
        }
    }

    /// The object with this name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// One line saying what it is.
    pub fn description(self) -> &'static str {
        match self {
            ObjectKind::Ball => "glossy beach ball, six coloured gores",
            ObjectKind::Vase => "hollow vase, plain celadon glaze",
            ObjectKind::Box => "wooden box, grain rings and plank seams",
            ObjectKind::Pawn => "marble chess pawn",
            ObjectKind::Torus => "frosted donut with sprinkles",
            ObjectKind::Mug => "polka-dot mug with handle",
            ObjectKind::TextPanel => "framed sign printed with small text",
            ObjectKind::Spring => "steel coil spring between plates",
            ObjectKind::Gear => "three stacked gears, 36/24/14 teeth",
            ObjectKind::Tree => "potted tree, branches and foliage",
            ObjectKind::Lattice => "5x5x5 lattice of rods and joints",
            ObjectKind::Sponge => "level-3 Menger sponge, sandstone",
        }
    }

    /// Nominal frequency of the texture's finest intended pattern, cycles
    /// per local unit length, at detail 1 (the `detail` argument of
    /// [`ObjectKind::material`] multiplies it).
    pub fn texture_frequency(self) -> f32 {
        match self {
            ObjectKind::Ball => 1.3,       // 6 gores around a 4.7-unit girth
            ObjectKind::Vase => 0.5,       // plain glaze, slow gradient
            ObjectKind::Box => 6.0,        // grain rings
            ObjectKind::Pawn => 3.0,       // marble veins
            ObjectKind::Torus => 14.0,     // sprinkles
            ObjectKind::Mug => 5.0,        // polka dots
            ObjectKind::TextPanel => 25.0, // character pitch of the small text
            ObjectKind::Spring => 2.0,     // plate brushing, plain steel
            ObjectKind::Gear => 8.0,       // machining rings
            ObjectKind::Tree => 80.0,      // leaf veining (leaf balls: 20 per unit)
            ObjectKind::Lattice => 1.0,    // one colour per rod axis
            ObjectKind::Sponge => 10.0,    // sandstone grain
        }
    }

    /// Conservative local bounds: the surface lies inside.
    pub fn bounds(self) -> Aabb {
        let b = |x: f32, y: f32, z0: f32, z1: f32| {
            Aabb::new(Vec3::new(-x, -y, z0), Vec3::new(x, y, z1))
        };
        match self {
            ObjectKind::Ball => b(0.76, 0.76, -0.76, 0.76),
            ObjectKind::Vase => b(0.68, 0.68, -0.91, 0.91),
            ObjectKind::Box => b(0.71, 0.51, -0.41, 0.41),
            ObjectKind::Pawn => b(0.56, 0.56, -0.91, 0.88),
            ObjectKind::Torus => b(0.86, 0.86, -0.3, 0.33),
            ObjectKind::Mug => Aabb::new(Vec3::new(-0.5, -0.5, -0.56), Vec3::new(0.8, 0.5, 0.56)),
            ObjectKind::TextPanel => b(0.88, 0.26, -0.8, 0.8),
            ObjectKind::Spring => b(0.61, 0.61, -0.81, 0.81),
            ObjectKind::Gear => b(0.88, 0.88, -0.48, 0.45),
            ObjectKind::Tree => {
                let t = tree();
                Aabb::new(t.min, t.max)
                    .padded(0.02)
                    .union(&b(0.45, 0.45, -0.96, -0.6))
            }
            ObjectKind::Lattice => b(0.83, 0.83, -0.83, 0.83),
            ObjectKind::Sponge => b(0.76, 0.76, -0.76, 0.76),
        }
    }

    /// Fraction of the distance bound to advance per sphere-tracing step
    /// (below 1 where the distance is only a bound with a larger slope).
    pub fn march_step(self) -> f32 {
        match self {
            ObjectKind::Ball | ObjectKind::Box | ObjectKind::Lattice | ObjectKind::Sponge => 1.0,
            ObjectKind::TextPanel | ObjectKind::Mug | ObjectKind::Gear => 0.95,
            ObjectKind::Vase | ObjectKind::Pawn | ObjectKind::Spring => 0.85,
            ObjectKind::Torus => 0.8,
            ObjectKind::Tree => 0.85,
        }
    }

    /// Signed distance (bound) at local point `p`: negative inside.
    #[inline]
    pub fn sdf(self, p: Vec3) -> f32 {
        match self {
            ObjectKind::Ball => sphere(p, 0.75),
            ObjectKind::Vase => vase(p),
            ObjectKind::Box => round_box(p, Vec3::new(0.7, 0.5, 0.4), 0.05),
            ObjectKind::Pawn => pawn(p),
            ObjectKind::Torus => donut(p),
            ObjectKind::Mug => mug(p).0,
            ObjectKind::TextPanel => text_panel(p).0,
            ObjectKind::Spring => spring(p).0,
            ObjectKind::Gear => gear(p).0,
            ObjectKind::Tree => potted_tree(p).0,
            ObjectKind::Lattice => lattice(p).0,
            ObjectKind::Sponge => sponge(p),
        }
    }

    /// Material at local surface point `p` with local unit normal `n`;
    /// `detail` scales texture frequencies (1 = nominal).
    pub fn material(self, p: Vec3, n: Vec3, detail: f32) -> Material {
        let f = detail.max(0.05);
        match self {
            ObjectKind::Ball => ball_mat(p, n, f),
            ObjectKind::Vase => vase_mat(p, f),
            ObjectKind::Box => box_mat(p, n, f),
            ObjectKind::Pawn => pawn_mat(p, f),
            ObjectKind::Torus => donut_mat(p, f),
            ObjectKind::Mug => mug_mat(p, f),
            ObjectKind::TextPanel => text_panel_mat(p, n, f),
            ObjectKind::Spring => spring_mat(p, f),
            ObjectKind::Gear => gear_mat(p, f),
            ObjectKind::Tree => tree_mat(p, f),
            ObjectKind::Lattice => lattice_mat(p),
            ObjectKind::Sponge => sponge_mat(p, f),
        }
    }
}

impl std::fmt::Display for ObjectKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ObjectKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::from_name(s.trim()).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|k| k.name()).collect();
            format!("unknown object {s:?}; known objects: {}", names.join(", "))
        })
    }
}

// ---------------------------------------------------------------- ball

fn ball_mat(p: Vec3, n: Vec3, f: f32) -> Material {
    const GORES: [u32; 6] = [0xe63b2e, 0xf5c518, 0x2a6fdb, 0xf2f2f2, 0x3fae49, 0xf28c28];
    let gores = (6.0 * f).round().max(1.0);
    let a = (p.y.atan2(p.x) / TAU + 0.5) * gores;
    let idx = (a.floor() as usize) % GORES.len();
    let cap = smoothstep(0.9, 0.91, n.z.abs());
    let c = rgb(GORES[idx]).lerp(rgb(0xf4f4f0), cap);
    mat(c, 0.35, 90.0)
}

// ---------------------------------------------------------------- vase

/// Vase radius at height z (local units) and its slope.
fn vase_profile(z: f32) -> (f32, f32) {
    let r = |z: f32| {
        let t = (z + 0.9) / 1.8;
        0.2 + 0.36 * (-((t - 0.36) / 0.26).powi(2)).exp()
            + 0.12 * (1.0 - t)
            + 0.1 * (-((t - 1.0) / 0.08).powi(2)).exp()
    };
    let h = 1e-3;
    (r(z), (r(z + h) - r(z - h)) / (2.0 * h))
}

fn vase(p: Vec3) -> f32 {
    let (r, dr) = vase_profile(p.z);
    let outer = lathe(p, r, dr).max(p.z.abs() - 0.9);
    // Open at the top, hollow down into the shoulder.
    let inner = lathe(p, r - 0.045, dr).max(-(p.z - 0.45));
    outer.max(-inner)
}

fn vase_mat(p: Vec3, f: f32) -> Material {
    let glaze = rgb(0x7fb0a2);
    let deep = rgb(0x4f8a7e);
    let t = smoothstep(-0.9, 0.9, p.z);
    let mut c = deep.lerp(glaze, t);
    // A glaze pools very slightly: slow variation.
    c *= 0.94 + 0.06 * value(p * (1.5 * f));
    let inside = p.xy().length() < vase_profile(p.z).0 - 0.03 && p.z > 0.44;
    if inside {
        c *= 0.8;
    }
    if p.z < -0.86 {
        return mat(rgb(0xb8a48a), 0.05, 10.0); // unglazed foot
    }
    mat(c, 0.45, 120.0)
}

// ---------------------------------------------------------------- box

fn wood(p: Vec3, f: f32, light: Vec3, dark: Vec3) -> Vec3 {
    let r = (p.yz() + Vec2::new(0.35, 1.9)).length();
    let warp = fbm(p * Vec3::new(0.7, 2.5, 2.5), 3);
    let ring = (r * 6.0 * f + 1.6 * warp).fract();
    let t = smoothstep(0.0, 0.55, ring) * (1.0 - smoothstep(0.7, 1.0, ring));
    let grain = value(p * Vec3::new(3.0, 70.0, 70.0) * f);
    dark.lerp(light, t) * (0.88 + 0.2 * grain)
}

fn box_mat(p: Vec3, n: Vec3, f: f32) -> Material {
    let mut c = wood(p, f, rgb(0xd2a064), rgb(0x94602e));
    // Plank seams every 0.35 units along x, on the faces they cross.
    if n.x.abs() < 0.5 {
        let s = 0.35 / f;
        let u = ((p.x / s + 0.5).fract() - 0.5).abs() * s;
        c *= 0.45 + 0.55 * smoothstep(0.004, 0.009, u);
    }
    mat(c, 0.12, 24.0)
}

// ---------------------------------------------------------------- pawn

fn pawn(p: Vec3) -> f32 {
    let base = cylinder_z(p, 0.52, -0.9, -0.74, 0.04);
    let ring = torus_z(p - Vec3::new(0.0, 0.0, -0.7), 0.41, 0.08);
    let slope = (0.15 - 0.36) / 1.04;
    let rz = 0.36 + (p.z + 0.72) * slope;
    let body = lathe(p, rz, slope).max((p.z + 0.19).abs() - 0.54);
    let collar = cylinder_z(p, 0.28, 0.27, 0.37, 0.03);
    let head = sphere(p - Vec3::new(0.0, 0.0, 0.6), 0.27);
    let d = smin(base, ring, 0.04);
    let d = smin(d, body, 0.08);
    let d = smin(d, collar, 0.03);
    smin(d, head, 0.04)
}

fn pawn_mat(p: Vec3, f: f32) -> Material {
    let q = p * f;
    let v = (q.x * 3.0 + q.z * 2.0 + 5.0 * fbm(q * 1.8, 4)).sin();
    let vein = (1.0 - v.abs()).powf(10.0);
    let base = rgb(0xeeeae2) * (0.93 + 0.07 * fbm(q * 6.0, 2));
    mat(base.lerp(rgb(0x6f7378), 0.7 * vein), 0.5, 140.0)
}

// ---------------------------------------------------------------- torus (donut)

/// Height of the frosting's lower edge at this point (wavy drips).
fn frosting_edge(p: Vec3) -> f32 {
    let a = p.y.atan2(p.x);
    -0.02 + 0.05 * (5.0 * a + 2.5 * value(p * 3.0)).sin() - 0.03 * value(p * 7.0)
}

fn donut(p: Vec3) -> f32 {
    let t = torus_z(p, 0.55, 0.26);
    let m = smoothstep(0.0, 0.03, p.z - frosting_edge(p));
    t - 0.028 * m
}

fn donut_mat(p: Vec3, f: f32) -> Material {
    if p.z > frosting_edge(p) + 0.01 {
        let (d, h) = cellular(p * (14.0 * f));
        if d < 0.2 {
            const SPRINKLES: [u32; 6] =
                [0xfff5e1, 0x3b82f6, 0xfacc15, 0x22c55e, 0xef4444, 0xa855f7];
            return mat(rgb(SPRINKLES[(h % 6) as usize]), 0.4, 60.0);
        }
        let c = rgb(0xf29bb8) * (0.95 + 0.05 * value(p * 9.0));
        return mat(c, 0.45, 70.0);
    }
    // Dough, toasted darker around its outer equator.
    let rho = p.xy().length();
    let toast = smoothstep(0.55, 0.8, rho) * (1.0 - smoothstep(0.0, 0.2, p.z.abs()));
    let c = rgb(0xe0ad6b).lerp(rgb(0x9b5a22), 0.7 * toast) * (0.9 + 0.15 * fbm(p * 20.0 * f, 2));
    mat(c, 0.08, 12.0)
}

// ---------------------------------------------------------------- mug

/// Mug distance and part (0 body, 1 handle).
fn mug(p: Vec3) -> (f32, u8) {
    let body = cylinder_z(p, 0.47, -0.55, 0.55, 0.03);
    let cavity = cylinder_z(p, 0.41, -0.47, 0.8, 0.03);
    let shell = body.max(-cavity);
    let q = p - Vec3::new(0.47, 0.0, 0.02);
    let handle = (Vec2::new(q.xz().length() - 0.25, q.y).length() - 0.055).max(0.44 - p.x);
    if handle < shell {
        (smin(shell, handle, 0.03), 1)
    } else {
        (smin(shell, handle, 0.03), 0)
    }
}

fn mug_mat(p: Vec3, f: f32) -> Material {
    let cream = rgb(0xefe7d6);
    let navy = rgb(0x1f3a7a);
    let (_, part) = mug(p);
    let rho = p.xy().length();
    if part == 1 || p.z > 0.49 {
        return mat(navy, 0.5, 90.0);
    }
    if rho < 0.445 && p.z > -0.48 {
        return mat(cream * 0.95, 0.5, 90.0); // inside
    }
    // Staggered polka dots on the outside, in (arc length, height).
    let u = p.y.atan2(p.x) * 0.47 * 5.0 * f;
    let v = p.z * 5.0 * f;
    let row = v.floor();
    let u = u + 0.5 * (row.rem_euclid(2.0));
    let d = Vec2::new(u - u.floor() - 0.5, v - row - 0.5).length();
    let c = if d < 0.26 { navy } else { cream };
    mat(c, 0.5, 90.0)
}

// ---------------------------------------------------------------- text panel

/// Sign distance and part (0 frame/legs, 1 printed board).
fn text_panel(p: Vec3) -> (f32, u8) {
    let c = p - Vec3::new(0.0, 0.0, 0.2);
    let frame = round_box(c, Vec3::new(0.86, 0.06, 0.58), 0.02).max(-round_box(
        c,
        Vec3::new(0.78, 0.2, 0.5),
        0.0,
    ));
    let board = round_box(c, Vec3::new(0.8, 0.03, 0.52), 0.005);
    let sx = Vec3::new(p.x.abs(), p.y, p.z);
    let leg = round_box(
        sx - Vec3::new(0.55, 0.0, -0.55),
        Vec3::new(0.035, 0.035, 0.2),
        0.01,
    );
    let foot = round_box(
        sx - Vec3::new(0.55, 0.0, -0.76),
        Vec3::new(0.05, 0.22, 0.025),
        0.01,
    );
    let wood = frame.min(leg).min(foot);
    if board < wood {
        (board, 1)
    } else {
        (wood, 0)
    }
}

fn text_panel_mat(p: Vec3, n: Vec3, f: f32) -> Material {
    let (_, part) = text_panel(p);
    if part == 0 {
        return mat(wood(p * 1.3, f, rgb(0x7a4a2a), rgb(0x4a2a16)), 0.25, 40.0);
    }
    let paper = rgb(0xf1ead8) * (0.96 + 0.04 * value(p * 40.0));
    if n.y.abs() < 0.5 {
        return mat(paper, 0.08, 12.0); // board edge
    }
    let mut u = (p.x + 0.78) / 1.56;
    if n.y > 0.0 {
        u = 1.0 - u; // the back reads correctly from behind
    }
    let v = (0.7 - p.z) / 1.0;
    let (u, v) = ((u * f).fract(), (v * f).fract());
    let (ink, red) = page().sample(u, v);
    let c = paper
        .lerp(rgb(0x1b1d2a), ink.clamp(0.0, 1.0) * 0.92)
        .lerp(rgb(0xb3261e), red.clamp(0.0, 1.0) * 0.95);
    mat(c, 0.08, 12.0)
}

// ---------------------------------------------------------------- spring

const COIL_R: f32 = 0.5;
const WIRE_R: f32 = 0.06;
const TURNS: f32 = 6.5;
const COIL_Z0: f32 = -0.68;
const COIL_Z1: f32 = 0.68;

fn helix(p: Vec3) -> f32 {
    let pitch = (COIL_Z1 - COIL_Z0) / TURNS;
    let cos_a = 1.0 / (1.0 + (pitch / (TAU * COIL_R)).powi(2)).sqrt();
    let rho = p.xy().length();
    let u0 = p.y.atan2(p.x) / TAU; // turn fraction in (−½, ½]
    let k = ((p.z - COIL_Z0) / pitch - u0).round();
    let mut d = f32::MAX;
    for dk in -1..=1 {
        let u = u0 + k + dk as f32;
        if (0.0..=TURNS).contains(&u) {
            let dz = (p.z - (COIL_Z0 + pitch * u)) * cos_a;
            d = d.min(Vec2::new(rho - COIL_R, dz).length());
        }
    }
    // The wire's two ends.
    for u in [0.0, TURNS] {
        let a = u * TAU;
        let e = Vec3::new(COIL_R * a.cos(), COIL_R * a.sin(), COIL_Z0 + pitch * u);
        d = d.min((p - e).length());
    }
    d - WIRE_R
}

/// Spring distance and part (0 coil, 1 plates, 2 rod).
fn spring(p: Vec3) -> (f32, u8) {
    let coil = helix(p);
    let plates = cylinder_z(p, 0.6, -0.8, -0.74, 0.015).min(cylinder_z(p, 0.6, 0.74, 0.8, 0.015));
    let rod = cylinder_z(p, 0.05, -0.75, 0.75, 0.01);
    if coil <= plates && coil <= rod {
        (coil, 0)
    } else if plates <= rod {
        (coil.min(plates), 1)
    } else {
        (coil.min(rod), 2)
    }
}

fn spring_mat(p: Vec3, f: f32) -> Material {
    match spring(p).1 {
        0 => metal(rgb(0xa9afb8), 110.0),
        1 => {
            let brushed = value(Vec3::new(p.xy().length() * 2.0 * f * 20.0, 0.0, p.z * 3.0));
            mat(rgb(0x2b4c7e) * (0.9 + 0.15 * brushed), 0.4, 60.0)
        }
        _ => metal(rgb(0xc9a44c), 80.0),
    }
}

// ---------------------------------------------------------------- gear

fn gear_profile(
    q: Vec2,
    root: f32,
    tip: f32,
    teeth: u32,
    hole: f32,
    windows: Option<(u32, f32, f32)>,
) -> f32 {
    let (t, _) = polar_fold(q, teeth);
    let depth = tip - root;
    let sector = TAU / teeth as f32;
    let w_root = 0.28 * sector * root;
    let w_tip = 0.16 * sector * root;
    let tooth = trapezoid(
        Vec2::new(t.y, t.x - (root + 0.5 * depth - 0.02)),
        w_root,
        w_tip,
        0.5 * depth + 0.02,
    );
    let mut d = (q.length() - root).min(tooth);
    d = d.max(hole - q.length());
    if let Some((n, ring, r)) = windows {
        let rot = PI / n as f32;
        let q2 = Vec2::new(
            q.x * rot.cos() - q.y * rot.sin(),
            q.x * rot.sin() + q.y * rot.cos(),
        );
        let (w, _) = polar_fold(q2, n);
        d = d.max(r - (w - Vec2::new(ring, 0.0)).length());
    }
    d
}

fn hexagon(q: Vec2, r: f32) -> f32 {
    let k = Vec3::new(-0.866_025_4, 0.5, 0.577_350_26);
    let mut q = q.abs();
    q -= 2.0 * k.xy().dot(q).min(0.0) * k.xy();
    q -= Vec2::new(q.x.clamp(-k.z * r, k.z * r), r);
    q.length() * q.y.signum()
}

/// Gear distance and part (0 bottom gear, 1 middle gear, 2 top gear, 3 axle and nut).
fn gear(p: Vec3) -> (f32, u8) {
    let q = p.xy();
    // Profiles are eroded by 0.01 and re-grown after extrusion: rounded edges.
    let bottom = extrude(
        gear_profile(q, 0.68, 0.87, 36, 0.1, Some((8, 0.44, 0.11))) + 0.01,
        p.z,
        -0.44,
        -0.18,
    ) - 0.01;
    let middle = extrude(
        gear_profile(q, 0.46, 0.61, 24, 0.1, Some((6, 0.29, 0.07))) + 0.01,
        p.z,
        -0.14,
        0.1,
    ) - 0.01;
    let top = extrude(
        gear_profile(q, 0.25, 0.36, 14, 0.1, None) + 0.01,
        p.z,
        0.14,
        0.34,
    ) - 0.01;
    let axle = cylinder_z(p, 0.1, -0.47, 0.36, 0.01);
    let nut = extrude(hexagon(q, 0.15) + 0.01, p.z, 0.34, 0.44) - 0.01;
    let parts = [bottom, middle, top, axle.min(nut)];
    let mut best = (f32::MAX, 0u8);
    for (i, d) in parts.into_iter().enumerate() {
        if d < best.0 {
            best = (d, i as u8);
        }
    }
    best
}

fn gear_mat(p: Vec3, f: f32) -> Material {
    let rings = 0.85 + 0.15 * value(Vec3::new(p.xy().length() * 8.0 * f * 6.0, 0.5, 0.5));
    match gear(p).1 {
        0 => metal(rgb(0xc8a24a) * rings, 70.0),
        1 => metal(rgb(0xb4b9c0) * rings, 90.0),
        2 => metal(rgb(0xb87333) * rings, 80.0),
        _ => metal(rgb(0x5d6168), 50.0),
    }
}

// ---------------------------------------------------------------- tree

/// Leaf balls per unit length.
const LEAF_FREQ: f32 = 20.0;
/// Leaf ball radius.
const LEAF_R: f32 = 0.034;

/// Potted tree distance and part (0 pot, 1 soil, 2 wood, 3 foliage).
fn potted_tree(p: Vec3) -> (f32, u8) {
    let slope = 0.1 / 0.3;
    let r = 0.30 + (p.z + 0.95) * slope;
    let outer = lathe(p, r, slope).max((p.z + 0.8).abs() - 0.15);
    let rim = torus_z(p - Vec3::new(0.0, 0.0, -0.65), 0.4, 0.03);
    let cavity = lathe(p, r - 0.035, slope).max(-(p.z + 0.69));
    let pot = smin(outer, rim, 0.02).max(-cavity);
    let (wood, clump) = tree().eval(p);
    // Foliage: balls of leaves at cellular feature points, kept inside the
    // clumps (both are distance bounds, so is their maximum; far from the
    // clumps the clump distance alone is a bound).
    // Clamping the leaf distance at the switch keeps the function continuous.
    const NEAR: f32 = 0.08;
    let leaf = if clump < NEAR {
        let (f1, _) = cellular(p * LEAF_FREQ);
        clump.max((f1 / LEAF_FREQ - LEAF_R).min(NEAR))
    } else {
        clump
    };
    let d = pot.min(wood).min(leaf);
    let part = if d == pot {
        if p.z > -0.7 && p.xy().length() < r - 0.03 {
            1
        } else {
            0
        }
    } else if d == wood {
        2
    } else {
        3
    };
    (d, part)
}

fn tree_mat(p: Vec3, f: f32) -> Material {
    match potted_tree(p).1 {
        0 => {
            let c = rgb(0x27467a) * (0.92 + 0.08 * value(p * 12.0));
            mat(c, 0.5, 100.0)
        }
        1 => mat(rgb(0x3b2a1e) * (0.7 + 0.5 * value(p * 60.0 * f)), 0.02, 5.0),
        2 => {
            let streak = value(Vec3::new(p.x * 30.0 * f, p.y * 30.0 * f, p.z * 4.0));
            mat(rgb(0x5b4330) * (0.7 + 0.45 * streak), 0.06, 10.0)
        }
        _ => {
            // One green per leaf ball, veined by fine noise.
            let (_, h) = cellular(p * LEAF_FREQ);
            const GREENS: [u32; 5] = [0x2f6b2f, 0x4c8c2b, 0x6aa84f, 0x3d7a3a, 0x7fae4a];
            let vein = value(p * (LEAF_FREQ * 4.0 * f));
            let c = rgb(GREENS[(h % 5) as usize]) * (0.75 + 0.35 * vein);
            mat(c, 0.2, 30.0)
        }
    }
}

// ---------------------------------------------------------------- lattice

const LATTICE_STEP: f32 = 0.375;
const LATTICE_HALF: f32 = 0.75;

/// Lattice distance and part (0 x rods, 1 y rods, 2 z rods, 3 joints).
fn lattice(p: Vec3) -> (f32, u8) {
    let s = LATTICE_STEP;
    let snap = |v: Vec2| (v / s).round().clamp(Vec2::splat(-2.0), Vec2::splat(2.0)) * s;
    let rod = |across: Vec2, along: f32| {
        ((across - snap(across)).length() - 0.035).max(along.abs() - LATTICE_HALF)
    };
    let rx = rod(p.yz(), p.x);
    let ry = rod(p.xz(), p.y);
    let rz = rod(p.xy(), p.z);
    let c = (p / s).round().clamp(Vec3::splat(-2.0), Vec3::splat(2.0)) * s;
    let joint = (p - c).length() - 0.065;
    let d = rx.min(ry).min(rz).min(joint);
    let part = if d == joint {
        3
    } else if d == rx {
        0
    } else if d == ry {
        1
    } else {
        2
    };
    (d, part)
}

fn lattice_mat(p: Vec3) -> Material {
    match lattice(p).1 {
        0 => mat(rgb(0xc8372d), 0.5, 80.0),
        1 => mat(rgb(0x2f9e4f), 0.5, 80.0),
        2 => mat(rgb(0x2e5bb8), 0.5, 80.0),
        _ => metal(rgb(0xd9dce1), 120.0),
    }
}

// ---------------------------------------------------------------- sponge

const SPONGE_HALF: f32 = 0.75;

fn sponge(p: Vec3) -> f32 {
    let q = p / SPONGE_HALF;
    let mut d = round_box(q, Vec3::ONE, 0.0);
    let mut s = 1.0;
    for _ in 0..3 {
        let a = (q * s).rem_euclid(Vec3::splat(2.0)) - Vec3::ONE;
        s *= 3.0;
        let r = (Vec3::ONE - 3.0 * a.abs()).abs();
        let da = r.x.max(r.y);
        let db = r.y.max(r.z);
        let dc = r.z.max(r.x);
        let c = (da.min(db).min(dc) - 1.0) / s;
        d = d.max(c);
    }
    d * SPONGE_HALF
}

fn sponge_mat(p: Vec3, f: f32) -> Material {
    // One tint per level-1 sub-cube, grain noise on top.
    let cell = ((p / SPONGE_HALF + Vec3::ONE) * 1.5).floor();
    let tint = value(cell * 1.7 + Vec3::splat(0.3));
    let base = rgb(0xd4a373).lerp(rgb(0xb5835a), tint);
    let grain = fbm(p * 10.0 * f, 3);
    mat(base * (0.8 + 0.35 * grain), 0.06, 12.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The local bounds hold the surface: every point on the bounds' faces
    /// is outside the object.
    #[test]
    fn bounds_contain_every_object() {
        for kind in ObjectKind::ALL {
            let b = kind.bounds();
            let n = 40;
            let mut inside_seen = false;
            for i in 0..=n {
                for j in 0..=n {
                    let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                    for axis in 0..3 {
                        for side in [b.min, b.max] {
                            let mut p = b.min + (b.max - b.min) * Vec3::new(u, v, u);
                            match axis {
                                0 => {
                                    p.x = side.x;
                                    p.y = b.min.y + (b.max.y - b.min.y) * u;
                                    p.z = b.min.z + (b.max.z - b.min.z) * v;
                                }
                                1 => {
                                    p.y = side.y;
                                    p.x = b.min.x + (b.max.x - b.min.x) * u;
                                    p.z = b.min.z + (b.max.z - b.min.z) * v;
                                }
                                _ => {
                                    p.z = side.z;
                                    p.x = b.min.x + (b.max.x - b.min.x) * u;
                                    p.y = b.min.y + (b.max.y - b.min.y) * v;
                                }
                            }
                            assert!(
                                kind.sdf(p) > 0.0,
                                "{kind}: surface reaches the bounds at {p}"
                            );
                        }
                    }
                    let c = b.center() + 0.5 * (b.max - b.min) * Vec3::new(u - 0.5, v - 0.5, 0.0);
                    inside_seen |= kind.sdf(c) < 0.0;
                }
            }
            assert!(
                inside_seen || kind == ObjectKind::Lattice,
                "{kind}: nothing inside"
            );
            // Fits the unit-cube convention.
            assert!(
                b.min.cmpge(Vec3::splat(-1.0)).all() && b.max.cmple(Vec3::splat(1.0)).all(),
                "{kind} {b:?}"
            );
        }
    }

    #[test]
    fn names_round_trip_and_materials_are_valid() {
        for kind in ObjectKind::ALL {
            assert_eq!(kind.name().parse::<ObjectKind>(), Ok(kind));
            for k in 0..50 {
                let p = Vec3::new(
                    (k as f32 * 0.71).sin(),
                    (k as f32 * 1.3).cos(),
                    (k as f32 * 0.37).sin(),
                ) * 0.7;
                let m = kind.material(p, Vec3::Z, 1.0);
                assert!(
                    m.albedo.cmpge(Vec3::ZERO).all() && m.albedo.cmple(Vec3::splat(1.2)).all(),
                    "{kind} {m:?}"
                );
            }
        }
        assert!("teapot".parse::<ObjectKind>().unwrap_err().contains("gear"));
    }
}
