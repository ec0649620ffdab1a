//! Placing objects in a scene: layouts (row, ring, random), the paper's four
//! preset scenes, and the `scene.json` description.
//!
//! Objects keep their relative sizes, stand on a common floor and are then
//! scaled together so the whole scene fits a sphere of radius
//! [`SCENE_RADIUS`] about the origin: a camera at [`CAMERA_DISTANCE`] looking
//! at the origin with the NeRF-synthetic field of view then sees every object
//! whole, from any direction.

use super::complexity::{ranked, stats};
use super::objects::{Aabb, ObjectKind};
use crate::capture::{ObjectInfo, Placement as PlacementInfo, SceneInfo};
use glam::{Vec2, Vec3};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Camera distance from the origin, as in NeRF-synthetic (4.0311 units).
pub const CAMERA_DISTANCE: f32 = 4.031_129;
/// Horizontal field of view of NeRF-synthetic (radians).
pub const CAMERA_ANGLE_X: f64 = 0.691_111_207_008_361_8;
/// Radius about the origin the scene is scaled into. A sphere of radius r
/// seen from distance D spans a half-angle asin(r/D); with D = 4.03 and half
/// the field of view 0.3456 rad the limit is 1.366, so 1.25 leaves a margin.
pub const SCENE_RADIUS: f32 = 1.25;

/// Where an object sits: `world = translation + scale · Rz(rotation_z_deg) · local`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// World position of the local origin.
    pub translation: Vec3,
    /// Turn about world +z, degrees.
    pub rotation_z_deg: f32,
    /// Uniform scale.
    pub scale: f32,
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            translation: Vec3::ZERO,
            rotation_z_deg: 0.0,
            scale: 1.0,
        }
    }
}

impl Placement {
    fn rot(&self) -> (f32, f32) {
        let a = self.rotation_z_deg.to_radians();
        (a.sin(), a.cos())
    }

    /// Local point to world.
    pub fn to_world(&self, p: Vec3) -> Vec3 {
        let (s, c) = self.rot();
        self.translation + self.scale * Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z)
    }

    /// Local direction to world (unit stays unit).
    pub fn dir_to_world(&self, d: Vec3) -> Vec3 {
        let (s, c) = self.rot();
        Vec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z)
    }

    /// World point to local.
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        let (s, c) = self.rot();
        let q = (p - self.translation) / self.scale;
        Vec3::new(c * q.x + s * q.y, -s * q.x + c * q.y, q.z)
    }

    /// World direction to local.
    pub fn dir_to_local(&self, d: Vec3) -> Vec3 {
        let (s, c) = self.rot();
        Vec3::new(c * d.x + s * d.y, -s * d.x + c * d.y, d.z)
    }

    /// As recorded in `scene.json`.
    pub fn to_info(&self) -> PlacementInfo {
        PlacementInfo {
            translation: self.translation.as_dvec3().to_array(),
            rotation_z_deg: self.rotation_z_deg as f64,
            scale: self.scale as f64,
        }
    }
}

/// One object of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedObject {
    /// Unique name in the scene.
    pub name: String,
    /// Which object.
    pub kind: ObjectKind,
    /// Where it is.
    pub placement: Placement,
    /// Texture frequency multiplier (1 = nominal).
    pub detail: f32,
}

impl PlacedObject {
    /// World-space bounds holding the whole object: its surface cells at
    /// the complexity grid, placed, each grown by its rotated half-diagonal.
    pub fn world_bounds(&self) -> Aabb {
        let occ = stats(self.kind);
        // The cube of half-edge h rotated about z reaches at most h·√2 in x/y.
        let pad = (occ.voxel * (0.5 * 2f32.sqrt() + 1.5)) * self.placement.scale;
        let mut b = Aabb::EMPTY;
        for &c in &occ.surface {
            b = b.with_point(self.placement.to_world(c));
        }
        if occ.surface.is_empty() {
            for c in self.kind.bounds().corners() {
                b = b.with_point(self.placement.to_world(c));
            }
        }
        b.padded(pad)
    }

    /// Radius about the world origin of a sphere holding the whole object
    /// (its surface cells at the complexity grid, placed, plus their reach).
    pub fn bounding_radius(&self) -> f32 {
        let occ = stats(self.kind);
        let pad = occ.voxel * (0.5 * 3f32.sqrt() + 1.0) * self.placement.scale;
        if occ.surface.is_empty() {
            return self
                .kind
                .bounds()
                .corners()
                .iter()
                .map(|&c| self.placement.to_world(c).length())
                .fold(0.0, f32::max);
        }
        occ.surface
            .iter()
            .map(|&c| self.placement.to_world(c).length())
            .fold(0.0, f32::max)
            + pad
    }

    /// As recorded in `scene.json`; `index` is its position in the scene.
    pub fn to_info(&self, index: usize) -> ObjectInfo {
        let b = self.world_bounds();
        ObjectInfo {
            name: self.name.clone(),
            kind: self.kind.name().into(),
            mask_value: u8::try_from(index + 1).unwrap_or(u8::MAX),
            placement: self.placement.to_info(),
            bounds_min: b.min.as_dvec3().to_array(),
            bounds_max: b.max.as_dvec3().to_array(),
            complexity_quads: Some(stats(self.kind).quads),
            texture_frequency: Some((self.kind.texture_frequency() * self.detail) as f64),
            extra: Default::default(),
        }
    }
}

/// How several objects are arranged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Side by side along x.
    Row,
    /// Evenly around a circle.
    Ring,
    /// Random non-overlapping positions and turns (seeded).
    Random,
}

impl Layout {
    /// The flag value.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Row => "row",
            Layout::Ring => "ring",
            Layout::Random => "random",
        }
    }
}

impl std::str::FromStr for Layout {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "row" => Ok(Layout::Row),
            "ring" => Ok(Layout::Ring),
            "random" => Ok(Layout::Random),
            _ => Err(format!("unknown layout {s:?}; use row, ring or random")),
        }
    }
}

/// The NeRFlex paper's four evaluation scenes, five objects each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// The five objects of lowest geometric complexity.
    Scene1,
    /// The five of highest geometric complexity.
    Scene2,
    /// Five chosen at random with a fixed seed ([`SCENE3_SEED`]).
    Scene3,
    /// Five mutually different ones: evenly spread over the complexity ranking.
    Scene4,
}

/// The fixed seed that picks Scene 3's objects.
pub const SCENE3_SEED: u64 = 3;

impl Preset {
    /// All presets.
    pub const ALL: [Preset; 4] = [
        Preset::Scene1,
        Preset::Scene2,
        Preset::Scene3,
        Preset::Scene4,
    ];

    /// The flag value (`scene1` …).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Scene1 => "scene1",
            Preset::Scene2 => "scene2",
            Preset::Scene3 => "scene3",
            Preset::Scene4 => "scene4",
        }
    }

    /// The preset's five objects, least complex first.
    pub fn kinds(self) -> Vec<ObjectKind> {
        let r: Vec<ObjectKind> = ranked().into_iter().map(|(k, _)| k).collect();
        let n = r.len();
        let mut kinds = match self {
            Preset::Scene1 => r[..5].to_vec(),
            Preset::Scene2 => r[n - 5..].to_vec(),
            Preset::Scene3 => {
                let mut rng = ChaCha8Rng::seed_from_u64(SCENE3_SEED);
                let mut all = ObjectKind::ALL.to_vec();
                all.shuffle(&mut rng);
                all.truncate(5);
                all
            }
            // Ranks 0, n/4, n/2, 3n/4, n−1: one per complexity band.
            Preset::Scene4 => (0..5).map(|i| r[(i * (n - 1) + 2) / 4]).collect(),
        };
        kinds.sort_by_key(|k| r.iter().position(|x| x == k));
        kinds
    }
}

impl std::str::FromStr for Preset {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown preset {s:?}; use scene1, scene2, scene3 or scene4"))
    }
}

/// Unique names: the kind's name, with `-2`, `-3` … for repeats.
fn names(kinds: &[ObjectKind]) -> Vec<String> {
    let mut out = Vec::new();
    for (i, k) in kinds.iter().enumerate() {
        let before = kinds[..i].iter().filter(|x| *x == k).count();
        out.push(if before == 0 {
            k.name().to_string()
        } else {
            format!("{}-{}", k.name(), before + 1)
        });
    }
    out
}

/// Places `kinds` by `layout` (the seed matters for `Random` only), resting
/// on a common floor, centred on the origin and scaled into [`SCENE_RADIUS`].
/// A single object is only centred (and shrunk if it would not fit).
pub fn arrange(kinds: &[ObjectKind], layout: Layout, seed: u64, detail: f32) -> Vec<PlacedObject> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let tight: Vec<Aabb> = kinds.iter().map(|&k| stats(k).tight).collect();
    // Footprint radius in the xy plane about the local origin (any turn).
    let foot: Vec<f32> = tight
        .iter()
        .map(|b| {
            b.corners()
                .iter()
                .map(|c| Vec2::new(c.x, c.y).length())
                .fold(0.0, f32::max)
        })
        .collect();
    let n = kinds.len();
    let gap = 0.08 * foot.iter().sum::<f32>() / n.max(1) as f32;
    let mut spots: Vec<(Vec2, f32)> = Vec::with_capacity(n); // (xy, turn degrees)
    match (n, layout) {
        (0, _) => {}
        (1, _) => spots.push((Vec2::ZERO, 0.0)),
        (_, Layout::Row) => {
            // Pack along x by each object's own x extent.
            let mut x = 0.0;
            for b in &tight {
                spots.push((Vec2::new(x - b.min.x, 0.0), 0.0));
                x += b.size().x + gap;
            }
        }
        (_, Layout::Ring) => {
            // Radius so neighbouring footprints do not touch.
            let half = std::f32::consts::PI / n as f32;
            let rho = (0..n)
                .map(|i| (foot[i] + foot[(i + 1) % n] + gap) / (2.0 * half.sin()))
                .fold(0.0, f32::max);
            for i in 0..n {
                let a = i as f32 * 2.0 * half;
                spots.push((rho * Vec2::new(a.cos(), a.sin()), 0.0));
            }
        }
        (_, Layout::Random) => {
            let mut radius = foot.iter().sum::<f32>() * 0.45;
            for i in 0..n {
                let mut tries = 0;
                loop {
                    let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
                    let r: f32 = radius * rng.random::<f32>().sqrt();
                    let p = r * Vec2::new(a.cos(), a.sin());
                    let free = spots
                        .iter()
                        .enumerate()
                        .all(|(j, (q, _))| (p - *q).length() >= foot[i] + foot[j] + gap);
                    if free {
                        spots.push((p, rng.random_range(0.0..360.0)));
                        break;
                    }
                    tries += 1;
                    if tries % 64 == 0 {
                        radius *= 1.1;
                    }
                }
            }
        }
    }
    let names = names(kinds);
    let mut objects: Vec<PlacedObject> = kinds
        .iter()
        .zip(spots)
        .zip(names)
        .zip(&tight)
        .map(|(((&kind, (xy, turn)), name), b)| PlacedObject {
            name,
            kind,
            // Stand on the floor z = 0 (moved to the centre below).
            placement: Placement {
                translation: Vec3::new(xy.x, xy.y, if n > 1 { -b.min.z } else { 0.0 }),
                rotation_z_deg: turn,
                scale: 1.0,
            },
            detail,
        })
        .collect();
    fit(&mut objects);
    objects
}

/// Centres the scene's bounds on the origin and scales it uniformly (about
/// the origin) so every object lies within [`SCENE_RADIUS`].
pub fn fit(objects: &mut [PlacedObject]) {
    if objects.is_empty() {
        return;
    }
    let all = objects
        .iter()
        .fold(Aabb::EMPTY, |a, o| a.union(&o.world_bounds()));
    let shift = all.center();
    for o in objects.iter_mut() {
        o.placement.translation -= shift;
    }
    let radius = objects
        .iter()
        .map(|o| o.bounding_radius())
        .fold(0.0, f32::max);
    if radius > SCENE_RADIUS {
        let s = SCENE_RADIUS / radius;
        for o in objects.iter_mut() {
            o.placement.translation *= s;
            o.placement.scale *= s;
        }
    }
}

/// The `scene.json` of these objects.
pub fn scene_info(
    objects: &[PlacedObject],
    layout: &str,
    seed: u64,
    preset: Option<Preset>,
) -> SceneInfo {
    let mut s = SceneInfo::new(
        objects
            .iter()
            .enumerate()
            .map(|(i, o)| o.to_info(i))
            .collect(),
    );
    s.layout = Some(layout.into());
    s.seed = Some(seed);
    s.preset = preset.map(|p| p.name().into());
    s.complexity_grid = Some(super::complexity::COMPLEXITY_GRID);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placement_round_trips() {
        let p = Placement {
            translation: Vec3::new(0.3, -0.2, 0.1),
            rotation_z_deg: 37.0,
            scale: 0.4,
        };
        let x = Vec3::new(0.5, 0.7, -0.2);
        assert!((p.to_local(p.to_world(x)) - x).length() < 1e-5);
        assert!((p.dir_to_local(p.dir_to_world(Vec3::X)) - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn layouts_fit_the_view_sphere_without_overlap() {
        let kinds = [
            ObjectKind::Gear,
            ObjectKind::Ball,
            ObjectKind::Tree,
            ObjectKind::Ball,
            ObjectKind::TextPanel,
        ];
        for layout in [Layout::Row, Layout::Ring, Layout::Random] {
            let objs = arrange(&kinds, layout, 11, 1.0);
            assert_eq!(objs[3].name, "ball-2");
            for o in &objs {
                let r = o.bounding_radius();
                assert!(r <= SCENE_RADIUS + 1e-3, "{layout:?} {}", o.name);
                // The sphere holds the whole surface.
                for &c in &stats(o.kind).surface {
                    assert!(o.placement.to_world(c).length() <= r);
                }
            }
            // Objects do not intersect: no surface cell of one lies inside another.
            for a in &objs {
                for b in &objs {
                    if a.name == b.name {
                        continue;
                    }
                    for &c in stats(a.kind).surface.iter().step_by(5) {
                        let p = b.placement.to_local(a.placement.to_world(c));
                        assert!(
                            b.kind.sdf(p) > -0.01,
                            "{layout:?}: {} inside {}",
                            a.name,
                            b.name
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn presets_follow_the_complexity_ranking() {
        let r = ranked();
        let s1 = Preset::Scene1.kinds();
        let s2 = Preset::Scene2.kinds();
        assert_eq!(s1, r[..5].iter().map(|x| x.0).collect::<Vec<_>>());
        assert_eq!(s2, r[r.len() - 5..].iter().map(|x| x.0).collect::<Vec<_>>());
        let s4 = Preset::Scene4.kinds();
        assert_eq!(s4.len(), 5);
        assert_eq!(s4[0], r[0].0);
        assert_eq!(s4[4], r[r.len() - 1].0);
        let mut u = s4.clone();
        u.dedup();
        assert_eq!(u.len(), 5);
        assert_eq!(Preset::Scene3.kinds(), Preset::Scene3.kinds());
    }
}
