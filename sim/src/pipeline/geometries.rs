//! Which geometries the pipeline's profiler samples and fits (`nerflex run
//! --geometry`, `nerflex eval --geometry`), and so which ones its planner
//! can choose.
//!
//! - [`Geometries::Planes`] (the default): planes sample bakes and planes
//!   profiles only, exactly as before the flag;
//! - [`Geometries::Both`]: the same sample points baked as planes and, by
//!   the trained baker, as mesh (each its own bake store entry), a profile
//!   fitted per object and geometry, and the planner's scene the union of
//!   both geometries' configurations, as `nerflex profile combine` joins
//!   them ([`crate::scene_file::union`]).
//!
//! The mesh has a largest grid ([`MAX_MESH_GRID`]): sample points and
//! planner grids above it are left out of the mesh's samples and profile
//! (the planner can still choose planes there); when no sample point is
//! left for the mesh the run stops with an error naming `--geometry both`.

use super::bakes::{BakeRequest, Baked, Baker};
use super::stages::Network;
use crate::bake::trained::nets::MAX_MESH_GRID;
use crate::fit;
use crate::geometry::Geometry;
use crate::scene_file::{self, Scene};
use anyhow::{bail, Context as _};
use serde_json::Value;

/// The geometries the profiler samples (`--geometry`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Geometries {
    /// Planes only (the default; the plan picks planes).
    #[default]
    Planes,
    /// Planes and mesh (the plan picks per object; needs the trained baker).
    Both,
}

impl Geometries {
    /// The geometries sampled, planes first.
    pub fn list(self) -> &'static [Geometry] {
        match self {
            Geometries::Planes => &[Geometry::Planes],
            Geometries::Both => &Geometry::ALL,
        }
    }

    /// An error naming `--geometry both` when `baker` cannot bake every
    /// geometry asked for (the hull bakes planes only).
    pub fn check(self, baker: &Baker) -> anyhow::Result<()> {
        if self == Geometries::Both && matches!(baker, Baker::Hull) {
            bail!(
                "--geometry both needs the trained baker, but the run bakes with the hull \
                 (--baker hull, or --quick's default), which bakes planes only; \
                 give --baker trained or --geometry planes"
            );
        }
        Ok(())
    }
}

/// The sample points a mesh bake accepts (g at most [`MAX_MESH_GRID`]).
pub fn mesh_points(points: &[(u32, u32)]) -> Vec<(u32, u32)> {
    points
        .iter()
        .copied()
        .filter(|&(g, _)| g <= MAX_MESH_GRID)
        .collect()
}

/// The profiler's sample bakes: every network at every point as planes (in
/// the order they always had), then, with [`Geometries::Both`], every
/// network at every [`mesh_points`] point as mesh.
pub fn sample_requests<'a>(
    networks: &'a [Network],
    points: &[(u32, u32)],
    geometries: Geometries,
) -> anyhow::Result<Vec<BakeRequest<'a>>> {
    let mut reqs = Vec::new();
    for &geometry in geometries.list() {
        let points = if geometry.is_planes() {
            points.to_vec()
        } else {
            mesh_points(points)
        };
        if points.is_empty() {
            bail!(
                "--geometry both: no profiler sample point has g ≤ {MAX_MESH_GRID}, the mesh's largest grid"
            );
        }
        reqs.extend(networks.iter().flat_map(|n| {
            points
                .iter()
                .map(move |&(g, p)| BakeRequest::new(&n.views, g, p, geometry))
        }));
    }
    Ok(reqs)
}

fn to_fit_sample(s: &crate::bake::sweep::Sample) -> fit::Sample {
    fit::Sample {
        object: s.object.clone(),
        g: s.g,
        p: s.p,
        size: nerflex_core::units::Bytes(s.size_bytes),
        gpu: Some(nerflex_core::units::Bytes(s.gpu_bytes)),
        quads: Some(s.quads),
        ssim: s.ssim,
        psnr: Some(s.psnr),
        lpips: s.lpips,
        line: 0,
    }
}

/// One geometry's profiles in profile form (as `nerflex profile fit` writes them).
fn fit_one(
    samples: &[Baked],
    points: &[(u32, u32)],
    space: &fit::profiles::Space,
) -> anyhow::Result<Value> {
    let fit_samples: Vec<fit::Sample> = samples.iter().map(|b| to_fit_sample(&b.sample)).collect();
    let fits = fit::fit_objects(&fit_samples, &[], None, fit::FamilyChoice::Auto)
        .context("fitting the profiles")?;
    fit::profiles::scene_json(&fits, |_| points.to_vec(), space).context("writing the profiles")
}

/// The planner's scene fitted to the sample bakes, and its JSON. With no
/// mesh samples: the planes profiles alone, as always. With mesh samples
/// (at `mesh_points(points)`): both geometries' profiles per object, the
/// configurations their union (mesh grids above [`MAX_MESH_GRID`] left
/// out), and each object's `"fit"` diagnostics as `{"planes": …, "mesh": …}`.
pub fn fit_scene(
    planes: &[Baked],
    mesh: &[Baked],
    points: &[(u32, u32)],
    space: &fit::profiles::Space,
) -> anyhow::Result<(Scene, Value)> {
    let planes_json = fit_one(planes, points, space)?;
    let planes_scene = scene_file::parse(&planes_json.to_string(), "fitted profiles")
        .context("reading the fitted profiles back as a scene")?;
    if mesh.is_empty() {
        return Ok((planes_scene, planes_json));
    }
    let mut mesh_space = space.clone();
    mesh_space.grids.retain(|&g| g <= MAX_MESH_GRID);
    if !space.grids.is_empty() && mesh_space.grids.is_empty() {
        bail!("--geometry both: no planner grid is ≤ {MAX_MESH_GRID}, the mesh's largest grid");
    }
    let mesh_json = fit_one(mesh, &mesh_points(points), &mesh_space)
        .context("--geometry both: the mesh profiles")?;
    let mesh_scene = scene_file::parse(&mesh_json.to_string(), "fitted mesh profiles")
        .context("reading the fitted mesh profiles back as a scene")?;
    let union = scene_file::union(
        (&planes_scene, "the planes profiles"),
        (&mesh_scene, "the mesh profiles"),
    )
    .map_err(anyhow::Error::msg)
    .context("joining the planes and mesh profiles")?;
    let mut json = union.to_json();
    let fit_of = |v: &Value, name: &str| {
        v["objects"]
            .as_array()
            .and_then(|a| a.iter().find(|o| o["name"] == name))
            .map(|o| o["fit"].clone())
            .unwrap_or(Value::Null)
    };
    if let Some(objects) = json["objects"].as_array_mut() {
        for o in objects {
            let name = o["name"].as_str().unwrap_or_default().to_string();
            o["fit"] = serde_json::json!({
                "planes": fit_of(&planes_json, &name),
                "mesh": fit_of(&mesh_json, &name),
            });
        }
    }
    // The scene is what the JSON reads as, so `scene.json` plans the same.
    let scene = scene_file::parse(&json.to_string(), "fitted profiles (planes + mesh)")
        .context("reading the joined profiles back as a scene")?;
    Ok((scene, json))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::sweep::ObjectViews;

    fn network(name: &str) -> Network {
        Network {
            name: name.into(),
            objects: vec![name.into()],
            views: ObjectViews {
                name: name.into(),
                content_hash: 0,
                train: Vec::new(),
                test: Vec::new(),
                test_hidden: Vec::new(),
                search_box: None,
            },
        }
    }

    #[test]
    fn planes_requests_are_as_before_and_both_adds_the_mesh_within_its_grid() {
        let nets = [network("a"), network("b")];
        let points = [(16, 3), (64, 17), (600, 5)];
        let planes = sample_requests(&nets, &points, Geometries::Planes).unwrap();
        let got: Vec<_> = planes
            .iter()
            .map(|r| (r.views.name.as_str(), r.g, r.p, r.geometry))
            .collect();
        let before: Vec<_> = nets
            .iter()
            .flat_map(|n| {
                points
                    .iter()
                    .map(|&(g, p)| (n.name.as_str(), g, p, Geometry::Planes))
            })
            .collect();
        assert_eq!(got, before);

        let both = sample_requests(&nets, &points, Geometries::Both).unwrap();
        assert_eq!(both.len(), 6 + 4);
        assert!(both[..6]
            .iter()
            .zip(&planes)
            .all(|(a, b)| (a.g, a.p, a.geometry) == (b.g, b.p, b.geometry)));
        let mesh: Vec<_> = both[6..]
            .iter()
            .map(|r| (r.views.name.as_str(), r.g, r.p, r.geometry))
            .collect();
        assert_eq!(
            mesh,
            [
                ("a", 16, 3, Geometry::Mesh),
                ("a", 64, 17, Geometry::Mesh),
                ("b", 16, 3, Geometry::Mesh),
                ("b", 64, 17, Geometry::Mesh)
            ]
        );
        let e = sample_requests(&nets, &[(600, 5)], Geometries::Both)
            .err()
            .unwrap();
        assert!(format!("{e}").contains("--geometry both"), "{e}");
    }

    #[test]
    fn the_hull_refuses_both_by_flag() {
        assert!(Geometries::Planes.check(&Baker::Hull).is_ok());
        let e = Geometries::Both.check(&Baker::Hull).unwrap_err();
        let e = format!("{e}");
        assert!(
            e.contains("--geometry both") && e.contains("--baker hull"),
            "{e}"
        );
        let trained = crate::eval::scale::Scale::Reduced.baker();
        assert!(Geometries::Both.check(&trained).is_ok());
    }
}
