//! Many (g, p) bakes of many objects, measured, cached, written as the
//! profiler's samples CSV.
//!
//! Each (object, g, p) is baked, encoded in the export layout (file bytes),
//! rendered from the object's held-out test views and compared with the
//! ground truth ([`crate::metrics`]). Bakes run a few at a time (each bake
//! is itself parallel), largest first, with a progress bar. Every finished
//! sample is stored in a cache folder under a key made of the capture's
//! content hash, the object, g, p, the bake settings and [`BAKER_VERSION`]
//! / [`MEASURE_VERSION`], so re-running a sweep only bakes what changed and
//! an interrupted sweep resumes where it stopped.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{bail, Context as _};
use image::RgbaImage;
use serde::{Deserialize, Serialize};

use super::{BakeParams, BakeView, BAKER_VERSION};
use crate::asset::Asset;
use crate::camera::Camera;
use crate::capture::Capture;
use crate::metrics::{Lpips, Metrics, Scores};

/// Version of the measurement (renderer + metrics use); part of the cache
/// key like [`BAKER_VERSION`]. 2: the renderer supersamples 2 × 2 (session
/// 6), so samples measured with one sample per pixel are not reused.
pub const MEASURE_VERSION: u32 = 3;

/// Version of the carving's treatment of other objects' pixels (unknown,
/// not background); part of the cache key of objects whose views show
/// other objects only.
pub const OCCLUDERS_UNKNOWN: u32 = 1;

/// The header of the samples CSV.
pub const CSV_HEADER: &str = "object,g,p,size_bytes,gpu_bytes,quads,ssim,psnr,lpips";

/// One measured bake: a row of the samples CSV.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Object name.
    pub object: String,
    /// Grid g (voxels per edge).
    pub g: u32,
    /// Patch p (texels per quad edge).
    pub p: u32,
    /// File bytes of the export (OBJ + PNG + mlp.json).
    pub size_bytes: u64,
    /// GPU-resident bytes (both atlases decoded as RGBA8).
    pub gpu_bytes: u64,
    /// Quads drawn.
    pub quads: u64,
    /// Mean SSIM over the test views.
    pub ssim: f64,
    /// Mean PSNR over the test views, dB.
    pub psnr: f64,
    /// Mean LPIPS over the test views (`None` without LPIPS weights).
    pub lpips: Option<f64>,
}

impl Sample {
    /// The CSV line (no newline).
    pub fn csv_line(&self) -> String {
        format!(
            "{},{},{},{},{},{},{:.6},{:.4},{}",
            self.object,
            self.g,
            self.p,
            self.size_bytes,
            self.gpu_bytes,
            self.quads,
            self.ssim,
            self.psnr,
            self.lpips.map_or(String::new(), |l| format!("{l:.6}"))
        )
    }
}

/// Writes samples as CSV (via a temporary file and a rename).
pub fn write_csv(path: &Path, samples: &[Sample]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
    }
    let mut text = String::from(CSV_HEADER);
    text.push('\n');
    for s in samples {
        text.push_str(&s.csv_line());
        text.push('\n');
    }
    crate::output::write_file(path, text.as_bytes())?;
    Ok(())
}

/// Reads a samples CSV; errors name the line and the field.
pub fn read_csv(path: &Path) -> anyhow::Result<Vec<Sample>> {
    let text = crate::validate::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == CSV_HEADER => {}
        _ => bail!("{}: line 1: header must be `{CSV_HEADER}`", path.display()),
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let n = i + 1;
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 9 {
            bail!(
                "{}: line {n}: {} fields, expected 9",
                path.display(),
                f.len()
            );
        }
        let bad = |name: &str| format!("{}: line {n}: bad {name} `{}`", path.display(), line);
        out.push(Sample {
            object: f[0].to_string(),
            g: f[1].parse().with_context(|| bad("g"))?,
            p: f[2].parse().with_context(|| bad("p"))?,
            size_bytes: f[3].parse().with_context(|| bad("size_bytes"))?,
            gpu_bytes: f[4].parse().with_context(|| bad("gpu_bytes"))?,
            quads: f[5].parse().with_context(|| bad("quads"))?,
            ssim: f[6].parse().with_context(|| bad("ssim"))?,
            psnr: f[7].parse().with_context(|| bad("psnr"))?,
            lpips: if f[8].is_empty() {
                None
            } else {
                Some(f[8].parse().with_context(|| bad("lpips"))?)
            },
        });
    }
    Ok(out)
}

/// 64-bit FNV-1a, for content keys (not cryptographic; a collision only
/// costs a stale cache entry).
#[derive(Debug, Clone, Copy)]
pub struct Fnv64(u64);

impl Default for Fnv64 {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv64 {
    /// Adds bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// Content hash of files (their names relative to nothing, and bytes).
pub fn hash_files(files: &[PathBuf]) -> anyhow::Result<u64> {
    let mut h = Fnv64::default();
    for f in files {
        let bytes =
            crate::validate::read(f).with_context(|| format!("{}: cannot read", f.display()))?;
        h.write(&(bytes.len() as u64).to_le_bytes());
        h.write(&bytes);
    }
    Ok(h.finish())
}

/// One owned training view: camera, image, optional (instance mask, label).
pub type TrainView = (Camera, RgbaImage, Option<(image::GrayImage, u8)>);

/// The training and test views of one object, owned.
pub struct ObjectViews {
    /// Object name (the CSV's `object`).
    pub name: String,
    /// Content hash of everything the views were read from.
    pub content_hash: u64,
    /// Training views: camera, image, optional (instance mask, label).
    pub train: Vec<TrainView>,
    /// Held-out views: camera and ground-truth image of the object alone.
    pub test: Vec<(Camera, RgbaImage)>,
    /// Per held-out view, the pixels another object covers (nonzero), where
    /// this object's appearance is unknown: [`ObjectViews::measure`] does
    /// not score them. Empty when no held-out view has such pixels.
    pub test_hidden: Vec<Option<image::GrayImage>>,
    /// Where to look for the object (from `scene.json`), if known.
    pub search_box: Option<super::Aabb>,
}

impl ObjectViews {
    /// One object of a loaded capture. With `scene.json`, `object` names it
    /// (optional when the scene has one object) and its instance mask value
    /// selects its pixels; its bounds, grown by 10 %, are the search box.
    /// Without, the capture is one object (alpha = silhouette) named after
    /// its folder. Held-out images keep only the object's pixels.
    pub fn from_capture(cap: &Capture, object: Option<&str>) -> anyhow::Result<Self> {
        let folder = cap
            .dir
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or("object")
            .to_string();
        let (name, label, search_box) = match (&cap.scene, object) {
            (Some(scene), want) => {
                let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
                let info = match want {
                    Some(w) => scene.object(w).with_context(|| {
                        format!(
                            "{}: no object `{w}` in scene.json (it has: {})",
                            cap.dir.display(),
                            names.join(", ")
                        )
                    })?,
                    None if scene.objects.len() == 1 => &scene.objects[0],
                    None => bail!(
                        "{}: the scene has {} objects ({}); pick one with --object NAME",
                        cap.dir.display(),
                        names.len(),
                        names.join(", ")
                    ),
                };
                let (lo, hi) = (
                    info.bounds_min.map(|v| v as f32),
                    info.bounds_max.map(|v| v as f32),
                );
                let (lo, hi) = (glam::Vec3::from_array(lo), glam::Vec3::from_array(hi));
                let margin = 0.1 * (hi - lo).max_element() + 0.01;
                let b = super::Aabb { min: lo, max: hi }.grown(margin);
                (info.name.clone(), Some(info.mask_value), Some(b))
            }
            (None, Some(w)) if w != folder => bail!(
                "{}: no scene.json, so the capture is one object (`{folder}`), not `{w}`",
                cap.dir.display()
            ),
            (None, _) => (folder, None, None),
        };
        let mut h = Fnv64::default();
        h.write(name.as_bytes());
        let mut hash_frame = |cam: &Camera, img: &RgbaImage, mask: Option<&image::GrayImage>| {
            h.write(format!("{cam:?}").as_bytes());
            h.write(img.as_raw());
            if let Some(m) = mask {
                h.write(m.as_raw());
            }
        };
        for f in cap.train.iter().chain(&cap.test) {
            hash_frame(&f.camera, &f.image, f.mask.as_ref());
        }
        h.write(format!("{label:?} {search_box:?}").as_bytes());
        let content_hash = h.finish();
        let train = cap
            .train
            .iter()
            .map(|f| {
                let mask = match (label, &f.mask) {
                    (Some(l), Some(m)) => Some((m.clone(), l)),
                    _ => None,
                };
                (f.camera, f.image.clone(), mask)
            })
            .collect();
        let test = cap
            .test
            .iter()
            .map(|f| {
                let mut img = f.image.clone();
                if let (Some(l), Some(m)) = (label, &f.mask) {
                    for (p, mv) in img.pixels_mut().zip(m.pixels()) {
                        if mv.0[0] != l {
                            p.0 = [0; 4];
                        }
                    }
                }
                (f.camera, img)
            })
            .collect();
        // Another object in front (or, in a segmentation's group folder,
        // any pixel marked 255) hides what this object looks like there.
        let hidden: Vec<Option<image::GrayImage>> = cap
            .test
            .iter()
            .map(|f| match (label, &f.mask) {
                (Some(l), Some(m)) if m.pixels().any(|v| v.0[0] != 0 && v.0[0] != l) => {
                    Some(map_mask(m, |v| u8::from(v != 0 && v != l)))
                }
                _ => None,
            })
            .collect();
        let test_hidden = if hidden.iter().any(Option::is_some) {
            hidden
        } else {
            Vec::new()
        };
        Ok(Self {
            name,
            content_hash,
            train,
            test,
            test_hidden,
            search_box,
        })
    }

    /// Whether some training view shows another object (an instance-mask
    /// value other than 0 and the object's label): such pixels are unknown
    /// to the carving (see [`super::carve`]) since [`OCCLUDERS_UNKNOWN`].
    pub fn has_other_objects(&self) -> bool {
        self.train.iter().any(|(_, _, mask)| {
            mask.as_ref()
                .is_some_and(|(m, label)| m.as_raw().iter().any(|&v| v != 0 && v != *label))
        })
    }

    /// Renders `asset` from every held-out view and scores it against the
    /// ground truth, leaving out the pixels another object hides
    /// ([`ObjectViews::test_hidden`]).
    pub fn measure(
        &self,
        asset: &Asset,
        render: &RenderFn<'_>,
        lpips: Option<&Lpips>,
        keep_renders: bool,
    ) -> anyhow::Result<Measured> {
        measure_views_hiding(
            asset,
            &self.test,
            &self.test_hidden,
            render,
            lpips,
            keep_renders,
        )
    }

    /// The training views as the baker takes them.
    pub fn bake_views(&self) -> Vec<BakeView<'_>> {
        self.train
            .iter()
            .map(|(camera, image, mask)| BakeView {
                camera: *camera,
                image,
                silhouette: match mask {
                    Some((mask, label)) => super::Silhouette::Instance {
                        mask,
                        label: *label,
                    },
                    None => super::Silhouette::Alpha,
                },
            })
            .collect()
    }
}

/// Renders an asset from a camera.
pub type RenderFn<'a> = dyn Fn(&Asset, &Camera) -> anyhow::Result<RgbaImage> + Sync + 'a;

/// The renderer of `nerflex render` (fixed-point shader), as a [`RenderFn`].
pub fn fixed_point_render(asset: &Asset, camera: &Camera) -> anyhow::Result<RgbaImage> {
    let opts = crate::render::RenderOptions::default();
    crate::render::try_render_scene(&[asset], camera, &opts)
        .map(|(img, _)| img)
        .map_err(|e| anyhow::anyhow!("the renderer rejected the camera: {e}"))
}

/// Image quality of a bake over the test views (means).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quality {
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean PSNR, dB.
    pub psnr: f64,
    /// Mean LPIPS, if computed.
    pub lpips: Option<f64>,
}

/// Renders every test view and compares it with the ground truth (both
/// composited over white by the metrics); returns the means and, if asked,
/// the renders.
pub fn measure(
    obj: &Asset,
    test: &[(Camera, RgbaImage)],
    render: &RenderFn<'_>,
    lpips: Option<&Lpips>,
    keep_renders: bool,
) -> anyhow::Result<(Quality, Vec<RgbaImage>)> {
    let m = measure_views(obj, test, render, lpips, keep_renders)?;
    Ok((m.mean, m.renders))
}

/// What [`measure_views`] found: the means, each view's scores and, if
/// asked, the renders.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Means over the test views (as in the samples CSV).
    pub mean: Quality,
    /// Each test view's scores, in order (PSNR capped at 100 dB).
    pub views: Vec<Quality>,
    /// The renders, if asked for.
    pub renders: Vec<RgbaImage>,
}

/// [`measure`] with each view's scores kept.
pub fn measure_views(
    obj: &Asset,
    test: &[(Camera, RgbaImage)],
    render: &RenderFn<'_>,
    lpips: Option<&Lpips>,
    keep_renders: bool,
) -> anyhow::Result<Measured> {
    measure_views_hiding(obj, test, &[], render, lpips, keep_renders)
}

/// The mask `m` with every value `v` replaced by `f(v)`.
pub fn map_mask(m: &image::GrayImage, f: impl Fn(u8) -> u8) -> image::GrayImage {
    let (w, h) = m.dimensions();
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([f(m.get_pixel(x, y).0[0])]))
}

/// Copies the ground truth into `render` where `hidden` is nonzero: those
/// pixels then score as perfect in every metric, so what another object
/// hides in a held-out view (the object may well be there, behind it)
/// neither rewards nor penalises a bake. The score of a view that is mostly
/// hidden is high for every bake alike; the differences between bakes come
/// from the visible pixels.
pub fn hide_unknown(render: &mut RgbaImage, truth: &RgbaImage, hidden: Option<&image::GrayImage>) {
    let Some(h) = hidden else { return };
    if h.dimensions() != render.dimensions() || truth.dimensions() != render.dimensions() {
        return; // Metrics::compare reports the size mismatch.
    }
    for ((r, t), m) in render.pixels_mut().zip(truth.pixels()).zip(h.pixels()) {
        if m.0[0] != 0 {
            *r = *t;
        }
    }
}

/// [`measure_views`] leaving out each view's `hidden` pixels (one entry per
/// view, or an empty slice for none).
pub fn measure_views_hiding(
    obj: &Asset,
    test: &[(Camera, RgbaImage)],
    hidden: &[Option<image::GrayImage>],
    render: &RenderFn<'_>,
    lpips: Option<&Lpips>,
    keep_renders: bool,
) -> anyhow::Result<Measured> {
    if test.is_empty() {
        bail!("no test views to measure against");
    }
    // Views in waves of one per core: their renders, SSIM and LPIPS each
    // leave a core idle in places (LPIPS's last layers, the render's
    // setup), so views side by side fill it; a wave bounds the metrics'
    // buffers in flight. Each view's scores do not depend on the order,
    // and the sums below run in view order: the same figures as one by
    // one, and the first failing view's error.
    let wave = rayon::current_num_threads().max(1);
    let mut scored: Vec<anyhow::Result<(Scores, RgbaImage)>> = Vec::with_capacity(test.len());
    for (w, chunk) in test.chunks(wave).enumerate() {
        use rayon::prelude::*;
        let part: Vec<_> = chunk
            .par_iter()
            .enumerate()
            .map(|(j, (cam, gt))| {
                let i = w * wave + j;
                let mut img =
                    render(obj, cam).with_context(|| format!("rendering test view {i}"))?;
                hide_unknown(&mut img, gt, hidden.get(i).and_then(Option::as_ref));
                let s = Metrics::compare(&img, gt, lpips)
                    .with_context(|| format!("measuring test view {i}"))?;
                Ok((s, img))
            })
            .collect();
        scored.extend(part);
    }
    let mut sums = (0.0, 0.0, 0.0);
    let mut renders = Vec::new();
    let mut views = Vec::with_capacity(test.len());
    for r in scored {
        let (s, img) = r?;
        let psnr = s.psnr.min(100.0); // identical images: cap inf at 100 dB
        sums.0 += s.ssim;
        sums.1 += psnr;
        sums.2 += s.lpips.unwrap_or(0.0);
        views.push(Quality {
            ssim: s.ssim,
            psnr,
            lpips: s.lpips,
        });
        if keep_renders {
            renders.push(img);
        }
    }
    let n = test.len() as f64;
    Ok(Measured {
        mean: Quality {
            ssim: sums.0 / n,
            psnr: sums.1 / n,
            lpips: lpips.map(|_| sums.2 / n),
        },
        views,
        renders,
    })
}

/// Bakes, encodes and measures one configuration.
pub fn bake_and_measure(
    obj: &ObjectViews,
    params: &BakeParams,
    render: &RenderFn<'_>,
    lpips: Option<&Lpips>,
) -> anyhow::Result<Sample> {
    let views = obj.bake_views();
    let mut params = params.clone();
    if params.search_box.is_none() {
        params.search_box = obj.search_box;
    }
    let params = &params;
    let baked = super::bake(&views, params).with_context(|| {
        format!(
            "baking {} at g={} p={}",
            obj.name, params.grid, params.patch
        )
    })?;
    drop(views);
    measure_baked(obj, baked, render, lpips)
}

/// Bakes one object from its radiance field with the trained baker
/// (`bake::trained`) at `params`' (g, p) and measures it.
pub fn bake_and_measure_trained(
    obj: &ObjectViews,
    field: &dyn crate::train::field::RadianceField,
    params: &super::trained::TrainedParams,
    render: &RenderFn<'_>,
    lpips: Option<&Lpips>,
) -> anyhow::Result<Sample> {
    let views = obj.bake_views();
    let baked = super::trained::bake(field, &views, params)
        .with_context(|| {
            format!(
                "baking {} from its field at g={} p={}",
                obj.name, params.grid, params.patch
            )
        })?
        .baked;
    drop(views);
    measure_baked(obj, baked, render, lpips)
}

/// Sizes and held-out quality of a baked object.
fn measure_baked(
    obj: &ObjectViews,
    baked: super::BakedObject,
    render: &RenderFn<'_>,
    lpips: Option<&Lpips>,
) -> anyhow::Result<Sample> {
    let (g, p) = (baked.params.grid, baked.params.patch);
    let (quads, gpu_bytes) = (baked.quads.len() as u64, baked.gpu_bytes());
    let asset = baked.into_asset()?;
    let size_bytes = super::file_bytes(&asset)?;
    let q = obj.measure(&asset, render, lpips, false)?.mean;
    Ok(Sample {
        object: obj.name.clone(),
        g,
        p,
        size_bytes,
        gpu_bytes,
        quads,
        ssim: q.ssim,
        psnr: q.psnr,
        lpips: q.lpips,
    })
}

/// The cache of measured samples: one small JSON file per key.
#[derive(Debug, Clone)]
pub struct Cache {
    dir: PathBuf,
}

#[derive(Serialize, Deserialize)]
struct CacheEntry {
    key: String,
    sample: Sample,
}

impl Cache {
    /// A cache in `dir` (created on first store).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// The key of one sample: everything its numbers depend on.
    pub fn key(obj: &ObjectViews, params: &BakeParams, with_lpips: bool) -> String {
        let mut h = Fnv64::default();
        h.write(&obj.content_hash.to_le_bytes());
        h.write(obj.name.as_bytes());
        h.write(format!("{params:?} {:?}", obj.search_box).as_bytes());
        h.write(&BAKER_VERSION.to_le_bytes());
        h.write(&MEASURE_VERSION.to_le_bytes());
        h.write(&[u8::from(with_lpips)]);
        h.write(&(obj.train.len() as u64).to_le_bytes());
        h.write(&(obj.test.len() as u64).to_le_bytes());
        // Only captures with other objects' pixels bake differently since
        // they count as unknown: their keys change, single-object keys (and
        // the samples cached under them) stay.
        if obj.has_other_objects() {
            h.write(&OCCLUDERS_UNKNOWN.to_le_bytes());
        }
        format!(
            "{}-g{}-p{}-{:016x}",
            obj.name,
            params.grid,
            params.patch,
            h.finish()
        )
    }

    /// A stored sample, if any (unreadable entries count as absent).
    pub fn get(&self, key: &str) -> Option<Sample> {
        let text = std::fs::read_to_string(self.dir.join(format!("{key}.json"))).ok()?;
        let e: CacheEntry = serde_json::from_str(&text).ok()?;
        (e.key == key).then_some(e.sample)
    }

    /// A stored lattice choice, if any, decided again from its stored
    /// scores ([`super::trained::lattice_choice::pick`]): choices stored
    /// before the tie rule (session 45) follow it too.
    pub fn get_lattice(&self, key: &str) -> Option<LatticeChosen> {
        let text = std::fs::read_to_string(self.dir.join(format!("{key}.json"))).ok()?;
        let mut c: LatticeChosen = serde_json::from_str(&text).ok()?;
        let scored: Vec<(u32, f64)> = c.candidates.iter().map(|&(k, s, _)| (k, s)).collect();
        if let Some(cells) = super::trained::lattice_choice::pick(&scored) {
            c.stored_cells = (cells != c.cells).then_some(c.cells);
            c.cells = cells;
        }
        Some(c)
    }

    /// Stores a lattice choice.
    pub fn put_lattice(&self, key: &str, chosen: &LatticeChosen) -> anyhow::Result<()> {
        let path = self.dir.join(format!("{key}.json"));
        crate::output::create_parent(&path)?;
        crate::output::write_file(&path, serde_json::to_string(chosen)?.as_bytes())?;
        Ok(())
    }

    /// Stores a sample (a temporary name unique to this writer, then a
    /// rename: concurrent sweeps storing the same key do not collide).
    pub fn put(&self, key: &str, sample: &Sample) -> anyhow::Result<()> {
        let path = self.dir.join(format!("{key}.json"));
        let text = serde_json::to_string(&CacheEntry {
            key: key.to_string(),
            sample: sample.clone(),
        })?;
        crate::output::create_parent(&path)?;
        crate::output::write_file(&path, text.as_bytes())?;
        Ok(())
    }
}

/// Every (g, p) of `grids` × `patches`.
pub fn product(grids: &[u32], patches: &[u32]) -> Vec<(u32, u32)> {
    grids
        .iter()
        .flat_map(|&g| patches.iter().map(move |&p| (g, p)))
        .collect()
}

/// Sweep settings.
pub struct SweepOptions<'a> {
    /// The (g, p) configurations to bake for every object (see [`product`]).
    pub configs: Vec<(u32, u32)>,
    /// Bake settings other than g and p.
    pub base: BakeParams,
    /// Bakes running at once (each is parallel inside).
    pub jobs: usize,
    /// Sample cache (`None`: always bake).
    pub cache: Option<Cache>,
    /// LPIPS network, if the weights are available.
    pub lpips: Option<&'a Lpips>,
    /// Show a progress bar.
    pub progress: bool,
    /// Bake from radiance fields instead of the hull (`None`: hull).
    pub trained: Option<TrainedSweep<'a>>,
}

/// The trained baker's part of a sweep.
pub struct TrainedSweep<'a> {
    /// One field per object, in the order of the objects.
    pub fields: Vec<&'a dyn crate::train::field::RadianceField>,
    /// What identifies each field's content (e.g. its file's hash), for the
    /// cache keys.
    pub field_ids: Vec<String>,
    /// Settings other than g and p.
    pub params: super::trained::TrainedParams,
    /// Choose each object's feature lattice first, at this (g, p)
    /// ([`super::trained::lattice_choice`]); the chosen resolution then
    /// serves every configuration of the object (the lattice does not
    /// depend on g or p). `None`: `params.feature_res` for all, as for an
    /// object with too few training views to hold one back.
    pub choose_lattice_at: Option<(u32, u32)>,
}

/// One object's feature lattice as a sweep chose it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatticeChosen {
    /// The object.
    pub object: String,
    /// Cells per edge chosen.
    pub cells: u32,
    /// Each candidate: cells, held-back SSIM and PSNR.
    pub candidates: Vec<(u32, f64, f64)>,
    /// Taken from the cache.
    #[serde(skip)]
    pub reused: bool,
    /// The cells stored with the choice when the tie rule, reading its
    /// scores again, chose others (a choice made before session 45): what
    /// bakes made at the time used ([`Cache::get_lattice`]).
    #[serde(skip)]
    pub stored_cells: Option<u32>,
}

/// What a sweep did.
#[derive(Debug, Clone, Default)]
pub struct SweepReport {
    /// Every sample, ordered by object, g, p.
    pub samples: Vec<Sample>,
    /// Samples taken from the cache.
    pub reused: usize,
    /// Samples baked now.
    pub baked: usize,
    /// The feature lattices chosen per object, if asked.
    pub lattices: Vec<LatticeChosen>,
}

/// The feature lattice of `obj` chosen at `at` = (g, p) from `field`
/// ([`super::trained::lattice_choice`]; `params` otherwise as given),
/// from `cache` if chosen before (keyed by the views' content, `field_id`,
/// the settings and the baker's and measure's versions), else measured
/// now and stored there. `None` when `obj` has too few training views to
/// hold one back ([`super::trained::lattice_choice::held_back`]): the
/// default lattice then serves.
pub fn chosen_lattice(
    obj: &ObjectViews,
    field: &dyn crate::train::field::RadianceField,
    field_id: &str,
    params: &super::trained::TrainedParams,
    at: (u32, u32),
    cache: Option<&Cache>,
    render: &RenderFn<'_>,
) -> anyhow::Result<Option<LatticeChosen>> {
    if super::trained::lattice_choice::held_back(obj.train.len()).is_empty() {
        return Ok(None);
    }
    if let Some(c) = cache.and_then(|c| stored_lattice(obj, field_id, params, at, c)) {
        return Ok(Some(c));
    }
    let key = lattice_key(obj, field_id, params, at);
    let (g, p) = at;
    let mut tp = params.clone();
    tp.grid = g;
    tp.patch = p;
    let views = obj.bake_views();
    let c = super::trained::lattice_choice::choose(field, &views, &tp, render)
        .with_context(|| format!("choosing {}'s feature lattice at g={g} p={p}", obj.name))?;
    let chosen = LatticeChosen {
        object: obj.name.clone(),
        cells: c.chosen,
        candidates: c
            .candidates
            .iter()
            .map(|k| (k.cells, k.ssim, k.psnr))
            .collect(),
        reused: false,
        stored_cells: None,
    };
    if let Some(c) = cache {
        c.put_lattice(&key, &chosen)?;
    }
    Ok(Some(chosen))
}

/// [`chosen_lattice`]'s choice if `cache` holds it (marked reused): no
/// field needed.
pub fn stored_lattice(
    obj: &ObjectViews,
    field_id: &str,
    params: &super::trained::TrainedParams,
    at: (u32, u32),
    cache: &Cache,
) -> Option<LatticeChosen> {
    let mut c = cache.get_lattice(&lattice_key(obj, field_id, params, at))?;
    c.reused = true;
    Some(c)
}

/// The cache key of [`chosen_lattice`]'s choice: everything it depends on.
pub fn lattice_key(
    obj: &ObjectViews,
    field_id: &str,
    params: &super::trained::TrainedParams,
    at: (u32, u32),
) -> String {
    let (g, p) = at;
    let mut tp = params.clone();
    tp.grid = g;
    tp.patch = p;
    let mut h = Fnv64::default();
    h.write(&obj.content_hash.to_le_bytes());
    h.write(
        format!(
            "lattice choice v{} {field_id} {:?} {:?} {} {}",
            super::trained::TRAINED_BAKER_VERSION,
            tp,
            obj.search_box,
            obj.train.len(),
            MEASURE_VERSION
        )
        .as_bytes(),
    );
    format!("lattice-{}-g{g}-p{p}-{:016x}", obj.name, h.finish())
}

/// The trained parameters of object `oi`: the sweep's, with its feature
/// lattice chosen first if asked (the choice cached beside the samples).
fn object_params(
    obj: &ObjectViews,
    oi: usize,
    t: &TrainedSweep<'_>,
    cache: Option<&Cache>,
    render: &RenderFn<'_>,
) -> anyhow::Result<(super::trained::TrainedParams, Option<LatticeChosen>)> {
    let mut tp = t.params.clone();
    let Some(at) = t.choose_lattice_at else {
        return Ok((tp, None));
    };
    let Some((field, id)) = t.fields.get(oi).zip(t.field_ids.get(oi)) else {
        bail!("no field for object `{}`", obj.name);
    };
    let chosen = chosen_lattice(obj, *field, id, &tp, at, cache, render)?;
    if let Some(c) = &chosen {
        tp.feature_res = c.cells;
    }
    Ok((tp, chosen))
}

/// Runs the sweep over `objects` × grids × patches.
pub fn run(
    objects: &[ObjectViews],
    opts: &SweepOptions<'_>,
    render: &RenderFn<'_>,
) -> anyhow::Result<SweepReport> {
    for (i, o) in objects.iter().enumerate() {
        if o.name.is_empty() || o.name.contains([',', '\n', '"']) {
            bail!("object name `{}` cannot go in a CSV field", o.name);
        }
        if objects[..i].iter().any(|p| p.name == o.name) {
            bail!("object `{}` is given twice", o.name);
        }
    }
    let mut todo: Vec<(usize, BakeParams, String)> = Vec::new();
    let mut done: BTreeMap<(String, u32, u32), Sample> = BTreeMap::new();
    let mut reused = 0;
    // Per object: the trained settings (its lattice chosen first if asked).
    let mut tparams = Vec::new();
    let mut lattices = Vec::new();
    if let Some(t) = &opts.trained {
        for (oi, obj) in objects.iter().enumerate() {
            let (tp, chosen) = object_params(obj, oi, t, opts.cache.as_ref(), render)?;
            tparams.push(tp);
            lattices.extend(chosen);
        }
    }
    for (oi, obj) in objects.iter().enumerate() {
        {
            for &(g, p) in &opts.configs {
                let mut params = opts.base.clone();
                params.grid = g;
                params.patch = p;
                let mut key = Cache::key(obj, &params, opts.lpips.is_some());
                if let Some(t) = &opts.trained {
                    let Some(id) = t.field_ids.get(oi) else {
                        bail!("no field for object `{}`", obj.name);
                    };
                    let mut h = Fnv64::default();
                    h.write(key.as_bytes());
                    h.write(
                        format!(
                            "trained v{} {id} {:?}",
                            super::trained::TRAINED_BAKER_VERSION,
                            tparams.get(oi).unwrap_or(&t.params)
                        )
                        .as_bytes(),
                    );
                    key = format!("{}-g{g}-p{p}-t{:016x}", obj.name, h.finish());
                }
                match opts.cache.as_ref().and_then(|c| c.get(&key)) {
                    Some(s) => {
                        reused += 1;
                        done.insert((obj.name.clone(), g, p), s);
                    }
                    None => todo.push((oi, params, key)),
                }
            }
        }
    }
    // Largest bakes first, so the last ones to finish are short.
    todo.sort_by_key(|(_, p, _)| {
        std::cmp::Reverse(u64::from(p.grid).pow(2) * u64::from(p.patch).pow(2))
    });
    let bar = if opts.progress {
        let b = indicatif::ProgressBar::new(todo.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} bakes (eta {eta}) {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    let baked = todo.len();
    let queue = Mutex::new(todo.into_iter());
    let results: Mutex<Vec<anyhow::Result<Sample>>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.max(1) {
            s.spawn(|| loop {
                let next = queue.lock().map(|mut q| q.next()).ok().flatten();
                let Some((oi, params, key)) = next else { break };
                let obj = &objects[oi];
                bar.set_message(format!("{} g={} p={}", obj.name, params.grid, params.patch));
                let r = match &opts.trained {
                    Some(t) => {
                        let mut tp = tparams.get(oi).unwrap_or(&t.params).clone();
                        tp.grid = params.grid;
                        tp.patch = params.patch;
                        match t.fields.get(oi) {
                            Some(f) => bake_and_measure_trained(obj, *f, &tp, render, opts.lpips),
                            None => Err(anyhow::anyhow!("no field for object `{}`", obj.name)),
                        }
                    }
                    None => bake_and_measure(obj, &params, render, opts.lpips),
                }
                .and_then(|sample| {
                    if let Some(c) = &opts.cache {
                        c.put(&key, &sample)?;
                    }
                    Ok(sample)
                });
                bar.inc(1);
                if let Ok(mut v) = results.lock() {
                    v.push(r);
                }
            });
        }
    });
    bar.finish_and_clear();
    let results = results
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a bake thread panicked"))?;
    for r in results {
        let s = r?;
        done.insert((s.object.clone(), s.g, s.p), s);
    }
    // Objects in the order given, then g, then p.
    let mut samples: Vec<Sample> = Vec::with_capacity(done.len());
    for obj in objects {
        samples.extend(
            done.iter()
                .filter(|((o, _, _), _)| o == &obj.name)
                .map(|(_, s)| s.clone()),
        );
    }
    Ok(SweepReport {
        samples,
        reused,
        baked,
        lattices,
    })
}

/// Draws one picture per object of `samples` into `dir`
/// (`{object}.png`): GPU bytes, file bytes and SSIM against g, one line
/// per p, g on a log₂ axis and sizes on a log₁₀ axis. Returns the files.
pub fn plot_objects(samples: &[Sample], dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use crate::plot::{Chart, LegendPosition, Scale, Series};
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let mut objects: Vec<&str> = Vec::new();
    for s in samples {
        if !objects.contains(&s.object.as_str()) {
            objects.push(&s.object);
        }
    }
    let (w, h) = (360u32, 280u32);
    let mut written = Vec::new();
    for obj in objects {
        let mine: Vec<&Sample> = samples.iter().filter(|s| s.object == obj).collect();
        let mut ps: Vec<u32> = mine.iter().map(|s| s.p).collect();
        ps.sort_unstable();
        ps.dedup();
        let series = |f: &dyn Fn(&Sample) -> f64| -> Vec<Series> {
            ps.iter()
                .map(|&p| {
                    let mut pts: Vec<(f64, f64)> = mine
                        .iter()
                        .filter(|s| s.p == p)
                        .map(|s| (f64::from(s.g), f(s)))
                        .collect();
                    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                    Series::line_points(format!("p = {p}"), pts)
                })
                .collect()
        };
        let mib = 1024.0 * 1024.0;
        let charts = [
            (
                "GPU size",
                "GPU MiB (log)",
                series(&|s| s.gpu_bytes as f64 / mib),
                true,
            ),
            (
                "file size",
                "file MiB (log)",
                series(&|s| s.size_bytes as f64 / mib),
                true,
            ),
            ("quality", "SSIM", series(&|s| s.ssim), false),
        ];
        let mut sheet = tiny_skia::Pixmap::new(w * 3, h).context("picture size")?;
        sheet.fill(tiny_skia::Color::WHITE);
        for (i, (title, ylabel, lines, log)) in charts.into_iter().enumerate() {
            let mut chart = Chart::new(format!("{obj}: {title}"))
                .x_label("grid g")
                .y_label(ylabel)
                .x_log2()
                .legend(if log {
                    LegendPosition::TopLeft
                } else {
                    LegendPosition::BottomRight
                });
            if log {
                chart = chart.y_scale(Scale::Log10);
            }
            for s in lines {
                chart = chart.series(s);
            }
            let pm = chart.render(w, h)?;
            sheet.draw_pixmap(
                (i as u32 * w) as i32,
                0,
                pm.as_ref(),
                &tiny_skia::PixmapPaint::default(),
                tiny_skia::Transform::identity(),
                None,
            );
        }
        let path = dir.join(format!("{obj}.png"));
        crate::plot::save_png(&sheet, &path)?;
        written.push(path);
    }
    Ok(written)
}

/// Every pair of neighbouring configurations of one object (next g at the
/// same p, next p at the same g) in `samples`, with the parameter that
/// changed (`"g"` or `"p"`).
fn neighbour_pairs(samples: &[Sample]) -> Vec<(&'static str, &Sample, &Sample)> {
    let find = |o: &str, g: u32, p: u32| {
        samples
            .iter()
            .find(|s| s.object == o && s.g == g && s.p == p)
    };
    let mut gs: Vec<u32> = samples.iter().map(|s| s.g).collect();
    let mut ps: Vec<u32> = samples.iter().map(|s| s.p).collect();
    gs.sort_unstable();
    gs.dedup();
    ps.sort_unstable();
    ps.dedup();
    let mut out = Vec::new();
    for a in samples {
        let next_g = gs
            .iter()
            .find(|&&g| g > a.g)
            .and_then(|&g| find(&a.object, g, a.p));
        let next_p = ps
            .iter()
            .find(|&&p| p > a.p)
            .and_then(|&p| find(&a.object, a.g, p));
        for (what, b) in [("g", next_g), ("p", next_p)] {
            if let Some(b) = b {
                out.push((what, a, b));
            }
        }
    }
    out
}

/// Where a sweep's samples break "size grows and quality rises with g and
/// with p": one line per pair of neighbouring configurations (next g at
/// the same p, next p at the same g) whose size does not grow or whose SSIM
/// falls by more than `ssim_tolerance`.
pub fn monotonicity_report(samples: &[Sample], ssim_tolerance: f64) -> Vec<String> {
    let mut out = Vec::new();
    for (what, a, b) in neighbour_pairs(samples) {
        let step = format!("{} ({}, {}) → ({}, {})", a.object, a.g, a.p, b.g, b.p);
        if b.gpu_bytes <= a.gpu_bytes || b.size_bytes <= a.size_bytes {
            out.push(format!(
                "{step}: size does not grow with {what} (GPU {} → {}, file {} → {})",
                a.gpu_bytes, b.gpu_bytes, a.size_bytes, b.size_bytes
            ));
        }
        if b.ssim < a.ssim - ssim_tolerance {
            out.push(format!(
                "{step}: SSIM falls with {what} ({:.6} → {:.6}, by {:.6})",
                a.ssim,
                b.ssim,
                a.ssim - b.ssim
            ));
        }
    }
    out
}

/// Counts over the neighbouring pairs of [`monotonicity_report`] along
/// one parameter (g or p).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepSummary {
    /// Neighbouring configuration pairs.
    pub pairs: usize,
    /// Pairs where both file and GPU bytes grow.
    pub size_grows: usize,
    /// Pairs where SSIM falls.
    pub ssim_falls: usize,
    /// Pairs where SSIM falls by more than 0.001.
    pub ssim_falls_over_1e3: usize,
    /// The largest SSIM drop (0 if none).
    pub max_ssim_drop: f64,
    /// Where that drop is, `object (g, p) → (g, p)`.
    pub max_drop_at: Option<String>,
}

/// [`StepSummary`] along g (same p) and along p (same g).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MonotonicitySummary {
    /// Next g at the same p.
    pub g: StepSummary,
    /// Next p at the same g.
    pub p: StepSummary,
}

/// Summarises how monotone the samples are (see [`monotonicity_report`]).
pub fn monotonicity_summary(samples: &[Sample]) -> MonotonicitySummary {
    let mut m = MonotonicitySummary::default();
    for (what, a, b) in neighbour_pairs(samples) {
        let s = if what == "g" { &mut m.g } else { &mut m.p };
        s.pairs += 1;
        if b.gpu_bytes > a.gpu_bytes && b.size_bytes > a.size_bytes {
            s.size_grows += 1;
        }
        let drop = a.ssim - b.ssim;
        if drop > 0.0 {
            s.ssim_falls += 1;
            if drop > 1e-3 {
                s.ssim_falls_over_1e3 += 1;
            }
            if drop > s.max_ssim_drop {
                s.max_ssim_drop = drop;
                s.max_drop_at = Some(format!(
                    "{} ({}, {}) → ({}, {})",
                    a.object, a.g, a.p, b.g, b.p
                ));
            }
        }
    }
    m
}

/// A markdown table of the samples at `configs`, one row per object (in
/// sample order) and configuration: quads, file and GPU MB (10⁶ bytes),
/// SSIM, PSNR, LPIPS. Configurations an object has no sample for are left
/// out.
pub fn markdown_table(samples: &[Sample], configs: &[(u32, u32)]) -> String {
    let mut objects: Vec<&str> = Vec::new();
    for s in samples {
        if !objects.contains(&s.object.as_str()) {
            objects.push(&s.object);
        }
    }
    let mut t = String::from(
        "| object | g | p | quads | file MB | GPU MB | SSIM | PSNR dB | LPIPS |\n\
         |---|--:|--:|--:|--:|--:|--:|--:|--:|\n",
    );
    for o in objects {
        for &(g, p) in configs {
            let Some(s) = samples
                .iter()
                .find(|s| s.object == o && s.g == g && s.p == p)
            else {
                continue;
            };
            t.push_str(&format!(
                "| {o} | {g} | {p} | {} | {:.2} | {:.2} | {:.4} | {:.2} | {} |\n",
                s.quads,
                s.size_bytes as f64 / 1e6,
                s.gpu_bytes as f64 / 1e6,
                s.ssim,
                s.psnr,
                s.lpips.map_or("–".to_string(), |l| format!("{l:.4}"))
            ));
        }
    }
    t
}
