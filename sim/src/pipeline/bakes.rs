//! Bakes that keep their assets: every (views, g, p) is baked once, written
//! in the MobileNeRF export layout under a cache folder keyed like the bake
//! sweep's cache (content hash of the views, g, p, bake settings, baker and
//! measure versions), and measured on the views' held-out images. A second
//! request — another method choosing the same configuration, a profiler
//! sample point that the planner picks, a re-run — loads it from there.
//!
//! Layout: `ROOT/<key>/asset/` (the export) and `ROOT/<key>/sample.json`
//! (the measured sample), written into `ROOT/.<key>.partial/` and renamed
//! when complete, so an interrupted bake is never mistaken for a finished one.

use crate::asset::Asset;
use crate::bake::sweep::{self, Cache, ObjectViews, Sample};
use crate::bake::{self, BakeParams};
use crate::metrics::Lpips;
use anyhow::Context as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The visual-hull baker's name in reports ([`crate::bake::bake`]).
pub const HULL_BAKER: &str = "hull";

/// A finished bake.
#[derive(Clone, Debug)]
pub struct Baked {
    /// The measured sample (file bytes, GPU bytes, quads, SSIM, PSNR, LPIPS).
    pub sample: Sample,
    /// The asset folder.
    pub dir: PathBuf,
    /// Seconds spent baking, writing and measuring now (0 when cached).
    pub seconds: f64,
    /// Whether it came from the cache.
    pub cached: bool,
}

impl Baked {
    /// Loads the asset.
    pub fn load(&self) -> anyhow::Result<Asset> {
        Asset::load(&self.dir).with_context(|| format!("loading {}", self.dir.display()))
    }
}

/// The folder of kept bakes.
#[derive(Clone, Debug)]
pub struct BakeStore {
    root: PathBuf,
}

impl BakeStore {
    /// A store at `root` (created on first bake).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }

    /// The folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The baker behind [`BakeStore::get_or_bake`]: the one place a run's
    /// assets come from, so reports name it (a trained baker plugs in here).
    pub fn baker(&self) -> &'static str {
        HULL_BAKER
    }

    /// The bake of `obj` at (g, p): from the store, or baked, written and
    /// measured now.
    pub fn get_or_bake(
        &self,
        obj: &ObjectViews,
        g: u32,
        p: u32,
        lpips: Option<&Lpips>,
    ) -> anyhow::Result<Baked> {
        let params = BakeParams::new(g, p);
        let key = Cache::key(obj, &params, lpips.is_some());
        let dir = self.root.join(&key);
        let sample_path = dir.join("sample.json");
        if let Some(sample) = std::fs::read_to_string(&sample_path)
            .ok()
            .and_then(|t| serde_json::from_str::<Sample>(&t).ok())
        {
            return Ok(Baked {
                sample,
                dir: dir.join("asset"),
                seconds: 0.0,
                cached: true,
            });
        }
        let t0 = Instant::now();
        let mut params = params;
        params.search_box = obj.search_box;
        let views = obj.bake_views();
        let baked = bake::bake(&views, &params)
            .with_context(|| format!("baking {} at g={g} p={p}", obj.name))?;
        drop(views);
        let (quads, gpu_bytes) = (baked.quads.len() as u64, baked.gpu_bytes());
        let asset = baked.into_asset()?;
        // Built under a name unique to this writer: two runs baking the
        // same key do not share a temporary folder.
        let stage = crate::output::StagedDir::new(&dir)?;
        let tmp = stage.path().to_path_buf();
        let size_bytes = asset
            .write(&tmp.join("asset"))
            .with_context(|| format!("writing {}", tmp.display()))?;
        let (q, _) = sweep::measure(&asset, &obj.test, &sweep::fixed_point_render, lpips, false)
            .with_context(|| format!("measuring {} at g={g} p={p}", obj.name))?;
        let sample = Sample {
            object: obj.name.clone(),
            g,
            p,
            size_bytes,
            gpu_bytes,
            quads,
            ssim: q.ssim,
            psnr: q.psnr,
            lpips: q.lpips,
        };
        std::fs::write(
            tmp.join("sample.json"),
            serde_json::to_string_pretty(&sample)?,
        )
        .with_context(|| format!("{}: cannot write", tmp.display()))?;
        stage.commit(
            &|n| n == "asset" || n == "sample.json",
            "a bake store entry holds only asset/ and sample.json",
        )?;
        Ok(Baked {
            sample,
            dir: dir.join("asset"),
            seconds: t0.elapsed().as_secs_f64(),
            cached: false,
        })
    }
}
