//! Baked assets as the simulator's scene: their coverage comes from the
//! host renderer's coverage-only pass ([`crate::render::coverage_scene`]),
//! their load items from their files and decoded sizes.
//!
//! On disk a planned scene's assets live at
//! `ROOT/<object>/g<g>_p<p>/` (planes) or `ROOT/<object>/g<g>_p<p>_mesh/`
//! (a mesh bake) in the MobileNeRF export layout ([`asset_dir`]);
//! `nerflex run` writes them there.

use super::timeline::LoadItem;
use super::turntable::{CoverageSource, ViewCoverage};
use crate::asset::Asset;
use crate::baselines::Plan;
use crate::camera::Camera;
use crate::device::resident_bytes;
use crate::geometry::Geometry;
use anyhow::Context as _;
use std::path::{Path, PathBuf};

/// Where the asset of `object` at (g, p) as `geometry` lives under
/// `root`: `g<g>_p<p>` for planes (the layout's name since before the
/// geometry was a choice), `g<g>_p<p>_<geometry>` otherwise.
pub fn asset_dir(root: &Path, object: &str, g: u32, p: u32, geometry: Geometry) -> PathBuf {
    let name = if geometry.is_planes() {
        format!("g{g}_p{p}")
    } else {
        format!("g{g}_p{p}_{geometry}")
    };
    root.join(object).join(name)
}

/// The objects of a scene, in load order, with their data sizes.
pub struct AssetScene {
    /// Object names.
    pub names: Vec<String>,
    /// The assets.
    pub assets: Vec<Asset>,
    /// File bytes of each object's data (what the limits count).
    pub file_bytes: Vec<u64>,
}

impl AssetScene {
    /// Assets in memory with their data sizes (e.g. from the baker).
    pub fn new(names: Vec<String>, assets: Vec<Asset>, file_bytes: Vec<u64>) -> Self {
        Self {
            names,
            assets,
            file_bytes,
        }
    }

    /// Loads the assets of a plan from `root` ([`asset_dir`] layout). The data
    /// size of each object is the bytes of its files on disk.
    pub fn load_plan(plan: &Plan, root: &Path) -> anyhow::Result<AssetScene> {
        let mut names = Vec::new();
        let mut assets = Vec::new();
        let mut bytes = Vec::new();
        for o in &plan.objects {
            // Each geometry has its own folder: a mesh choice never loads
            // the planes asset of its (g, p).
            let dir = asset_dir(root, &o.name, o.g, o.p, o.geometry);
            if !dir.is_dir() {
                let what = if o.geometry.is_planes() {
                    String::new()
                } else {
                    format!(" as {}", o.geometry)
                };
                anyhow::bail!(
                    "{}: no baked asset for `{}` at (g {}, p {}){what} (`nerflex run` writes assets in this layout; `nerflex bake --out` writes one)",
                    dir.display(),
                    o.name,
                    o.g,
                    o.p
                );
            }
            let a = Asset::load(&dir).with_context(|| format!("loading {}", dir.display()))?;
            names.push(o.name.clone());
            bytes.push(a.file_bytes);
            assets.push(a);
        }
        Ok(AssetScene {
            names,
            assets,
            file_bytes: bytes,
        })
    }

    /// The load items, one per object: its file bytes, and resident bytes =
    /// decoded atlas pages + vertex buffers.
    pub fn load_items(&self) -> Vec<LoadItem> {
        self.assets
            .iter()
            .zip(&self.names)
            .zip(&self.file_bytes)
            .map(|((a, name), &file_bytes)| {
                let atlas: u64 = a.shapes.iter().map(|s| s.atlas.gpu_bytes()).sum();
                let quads: u64 = a.shapes.iter().map(|s| s.quads.len() as u64).sum();
                LoadItem {
                    name: name.clone(),
                    file_bytes,
                    resident_bytes: resident_bytes(atlas, quads).0,
                }
            })
            .collect()
    }

    /// Quads of all objects.
    pub fn quads(&self) -> u64 {
        self.assets
            .iter()
            .flat_map(|a| &a.shapes)
            .map(|s| s.quads.len() as u64)
            .sum()
    }
}

impl CoverageSource for AssetScene {
    fn objects(&self) -> usize {
        self.assets.len()
    }

    fn coverage(&self, loaded: usize, camera: &Camera) -> anyhow::Result<ViewCoverage> {
        let refs: Vec<&Asset> = self.assets.iter().take(loaded).collect();
        let c = crate::render::coverage_scene(&refs, camera)
            .map_err(|e| anyhow::anyhow!("coverage pass: {e}"))?;
        Ok(ViewCoverage {
            quads_in_view: quads_in_view(&refs, camera),
            quads_drawn: u64::from(c.quads_drawn),
            quads_visible: u64::from(c.quads_visible),
            pixels_covered: c.pixels_covered,
        })
    }
}

/// Quads with at least one corner in front of the camera and inside its
/// image: the quads a GPU sets up for this view, whatever their size in
/// pixels (so the count does not depend on the coverage resolution).
pub fn quads_in_view(assets: &[&Asset], camera: &Camera) -> u64 {
    use rayon::prelude::*;
    let k = camera.intrinsics;
    let (w, h) = (k.width as f32, k.height as f32);
    let w2c = camera.w2c();
    let inside = |p: [f32; 3]| {
        let c = w2c.transform_point3(glam::Vec3::from(p));
        let depth = -c.z;
        if depth <= 1e-6 {
            return false;
        }
        let (x, y) = (k.cx + k.fx * c.x / depth, k.cy - k.fy * c.y / depth);
        (0.0..=w).contains(&x) && (0.0..=h).contains(&y)
    };
    assets
        .iter()
        .flat_map(|a| &a.shapes)
        .map(|s| {
            s.quads
                .par_iter()
                .filter(|q| {
                    let n = if q.single_triangle { 3 } else { 4 };
                    q.corners.iter().take(n).any(|c| inside(c.pos))
                })
                .count() as u64
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baselines::{Method, PlannedObject};
    use crate::geometry::Geometry;

    #[test]
    fn each_geometry_has_its_own_folder_and_a_mesh_never_loads_the_planes_one() {
        let root = Path::new("assets");
        // Planes keep the layout's folder name from before the geometry.
        assert_eq!(
            asset_dir(root, "lego", 256, 5, Geometry::Planes),
            root.join("lego").join("g256_p5")
        );
        assert_eq!(
            asset_dir(root, "lego", 256, 5, Geometry::Mesh),
            root.join("lego").join("g256_p5_mesh")
        );
        let dir = tempfile::tempdir().unwrap();
        // The planes asset folder of (256, 5) exists (empty), so only the
        // geometry keeps the mesh choice from it.
        std::fs::create_dir_all(asset_dir(dir.path(), "lego", 256, 5, Geometry::Planes)).unwrap();
        let mut plan = Plan {
            method: Method::Dp,
            device: None,
            budget_bytes: 1,
            feasible: true,
            objects: vec![PlannedObject {
                name: "lego".into(),
                g: 256,
                p: 5,
                size_bytes: 1,
                quality: 0.9,
                geometry: Geometry::Mesh,
                config_index: None,
            }],
            total_size_bytes: 1,
            total_quality: 0.9,
            total_quality_q: Default::default(),
            total_units: 0,
            budget_units: 0,
            unit_bytes: 1,
        };
        let e = AssetScene::load_plan(&plan, dir.path())
            .err()
            .unwrap()
            .to_string();
        let mesh_dir = asset_dir(dir.path(), "lego", 256, 5, Geometry::Mesh);
        assert_eq!(
            e,
            format!(
                "{}: no baked asset for `lego` at (g 256, p 5) as mesh (`nerflex run` writes assets in this layout; `nerflex bake --out` writes one)",
                mesh_dir.display()
            )
        );
        // The planes choice finds its folder (and fails only on loading
        // the empty folder as an asset).
        plan.objects[0].geometry = Geometry::Planes;
        let e = format!(
            "{:#}",
            AssetScene::load_plan(&plan, dir.path()).err().unwrap()
        );
        assert!(e.starts_with("loading "), "{e}");
    }
}
