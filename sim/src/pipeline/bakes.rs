//! Bakes that keep their assets: every (views, g, p, geometry) is baked
//! once, written in the MobileNeRF export layout under a cache folder keyed
//! like the bake sweep's cache (content hash of the views, g, p, bake
//! settings, baker and measure versions), and measured on the views'
//! held-out images. A second
//! request — another method choosing the same configuration, a profiler
//! sample point that the planner picks, a re-run — loads it from there.
//!
//! Layout: `ROOT/<key>/asset/` (the export) and `ROOT/<key>/sample.json`
//! (the measured sample), written into `ROOT/.<key>.partial/` and renamed
//! when complete, so an interrupted bake is never mistaken for a finished one.
//! A trained bake also keeps `bake.json` (the trained baker's counts and
//! stage times). Entries written since session 9 also keep `views.json`,
//! each held-out view's SSIM and PSNR, so a run can tell a difference
//! between two sample bakes from the scatter of its views
//! ([`super::range`]).
//!
//! Two bakers ([`Baker`]): the visual hull ([`crate::bake::bake`]) and the
//! trained baker ([`crate::bake::trained::bake`]) from a radiance field
//! that the field store beside the bakes (`ROOT/fields/`,
//! [`super::fields`]) trains once per (views, training settings). A trained
//! bake's key adds the field's key, the trained baker's version and its
//! settings to the hull key's inputs and has another shape
//! (`<name>-g<g>-p<p>-t<hash>`), so the two bakers never share an entry.
//!
//! **Feature lattice.** By default the trained baker chooses each object's
//! feature lattice once, on training views held back from three bakes at
//! (64, 9) ([`crate::bake::trained::lattice_choice`]), keeps the choice in
//! `ROOT/lattices/` and bakes every configuration of the object with it;
//! such keys add where the lattice was chosen. A fixed lattice
//! ([`Baker::trained_fixed_lattice`], `--feature-res N`) keeps the keys
//! of before.
//!
//! **Geometry.** A request names its [`Geometry`]. A planes bake (every
//! bake before the geometry was part of a request) keeps exactly the key
//! and folder it had, so stored entries stay valid. A mesh bake comes from
//! the trained baker only (the hull bakes planes; asking it for a mesh is an
//! error naming the object), with the store's settings but
//! `--surface mesh`'s geometry and its default visibility rounds
//! ([`GeometryKind::default_visibility_rounds`]: none), as `nerflex bake
//! --surface mesh` bakes it; its key hashes those settings and names the
//! geometry: `<name>-g<g>-p<p>-mesh-t<hash>`.

use super::fields::{FieldStore, StoredField};
use super::stages::{Progress, Quiet};
use crate::asset::Asset;
use crate::bake::sweep::{self, Cache, Fnv64, ObjectViews, Sample};
use crate::bake::trained::{
    self, lattice_choice, GeometryKind, TrainedParams, TRAINED_BAKER_VERSION,
};
use crate::bake::{self, BakeParams, BakedObject};
use crate::geometry::Geometry;
use crate::metrics::Lpips;
use crate::train::trainer::TrainSettings;
use anyhow::Context as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Each held-out view's scores in a store entry ([`HeldOutScores`]).
const VIEWS_FILE: &str = "views.json";
/// A store entry's measured sample (its presence marks a finished entry).
const SAMPLE_FILE: &str = "sample.json";

/// Hull bakes at once by default (this machine has two cores).
pub const DEFAULT_HULL_JOBS: usize = 2;

/// The visual-hull baker's name in reports ([`crate::bake::bake`]).
pub const HULL_BAKER: &str = "hull";

/// The trained baker's name in reports ([`crate::bake::trained::bake`]).
pub const TRAINED_BAKER: &str = "trained";

/// Which baker a store's assets come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Baker {
    /// The visual hull: silhouettes and colours of the views, no training.
    Hull,
    /// A radiance field trained on the views, baked and fine-tuned.
    Trained(Box<TrainedBaker>),
}

/// The trained baker's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainedBaker {
    /// How each network's field is trained.
    pub train: TrainSettings,
    /// How a field is baked; its `grid` and `patch` are set per bake.
    pub bake: TrainedParams,
    /// Choose each object's feature lattice first, at this (g, p), on
    /// training views held back from the bake
    /// ([`crate::bake::trained::lattice_choice`]; kept in `ROOT/lattices/`
    /// and serving every bake of the object); `None`: `bake.feature_res`.
    /// An object with fewer than three training views keeps the default.
    pub choose_lattice_at: Option<(u32, u32)>,
}

impl Baker {
    /// The trained baker with these settings, each object's feature
    /// lattice chosen first at [`lattice_choice::SWEEP_CONFIG`] (the
    /// default since session 37: ball +0.0058 SSIM over its whole sweep,
    /// lego keeps its default; docs/baking.md, "Session 36").
    pub fn trained(train: TrainSettings, bake: TrainedParams) -> Baker {
        Baker::Trained(Box::new(TrainedBaker {
            train,
            bake,
            choose_lattice_at: Some(lattice_choice::SWEEP_CONFIG),
        }))
    }

    /// The trained baker with `bake`'s feature lattice for every object
    /// (no choice; `bake.feature_res` 0 is the default resolution).
    pub fn trained_fixed_lattice(train: TrainSettings, bake: TrainedParams) -> Baker {
        Baker::Trained(Box::new(TrainedBaker {
            train,
            bake,
            choose_lattice_at: None,
        }))
    }

    /// Its name in reports: [`HULL_BAKER`] or [`TRAINED_BAKER`].
    pub fn name(&self) -> &'static str {
        match self {
            Baker::Hull => HULL_BAKER,
            Baker::Trained(_) => TRAINED_BAKER,
        }
    }
}

/// A store entry's sample and (if stored) per-view scores; `None` when
/// the entry has no readable sample.
fn read_entry(dir: &Path) -> Option<(Sample, Option<HeldOutScores>)> {
    let sample = std::fs::read_to_string(dir.join(SAMPLE_FILE))
        .ok()
        .and_then(|t| serde_json::from_str::<Sample>(&t).ok())?;
    let views = std::fs::read_to_string(dir.join(VIEWS_FILE))
        .ok()
        .and_then(|t| serde_json::from_str::<HeldOutScores>(&t).ok());
    Some((sample, views))
}

/// A finished bake.
#[derive(Clone, Debug)]
pub struct Baked {
    /// The measured sample (file bytes, GPU bytes, quads, SSIM, PSNR, LPIPS).
    pub sample: Sample,
    /// The asset folder.
    pub dir: PathBuf,
    /// Seconds spent baking, writing and measuring now, training excluded
    /// (0 when cached).
    pub seconds: f64,
    /// Whether it came from the cache.
    pub cached: bool,
    /// Seconds spent training (and saving) its field now: 0 for the hull
    /// baker, a stored bake, or a field already in the field store.
    pub train_s: f64,
    /// Whether its field was trained by this request.
    pub field_trained: bool,
    /// Each held-out view's scores, in the views' order (`None` for an
    /// entry stored before they were kept).
    pub views: Option<HeldOutScores>,
}

/// Each held-out view's SSIM and PSNR of one bake (`views.json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeldOutScores {
    /// SSIM per view.
    pub ssim: Vec<f64>,
    /// PSNR per view, dB (capped at 100).
    pub psnr: Vec<f64>,
}

impl Baked {
    /// Loads the asset.
    pub fn load(&self) -> anyhow::Result<Asset> {
        Asset::load(&self.dir).with_context(|| format!("loading {}", self.dir.display()))
    }
}

/// The folder of kept bakes (and, for the trained baker, of the fields
/// they come from).
#[derive(Clone)]
pub struct BakeStore {
    root: PathBuf,
    baker: Baker,
    fields: FieldStore,
    /// The last field used, so the sample bakes of one network load it once.
    last_field: Arc<Mutex<Option<StoredField>>>,
    /// Hull bakes [`BakeStore::get_or_bake_many`] runs at once.
    jobs: usize,
}

/// One bake of [`BakeStore::get_or_bake_many`].
#[derive(Clone, Copy)]
pub struct BakeRequest<'a> {
    /// The views to bake from.
    pub views: &'a ObjectViews,
    /// Grid g.
    pub g: u32,
    /// Patch p.
    pub p: u32,
    /// The geometry (planes unless the plan chose another).
    pub geometry: Geometry,
}

impl<'a> BakeRequest<'a> {
    /// A planes bake of `views` at (g, p).
    pub fn planes(views: &'a ObjectViews, g: u32, p: u32) -> Self {
        Self::new(views, g, p, Geometry::Planes)
    }

    /// A bake of `views` at (g, p) as `geometry`.
    pub fn new(views: &'a ObjectViews, g: u32, p: u32, geometry: Geometry) -> Self {
        Self {
            views,
            g,
            p,
            geometry,
        }
    }

    /// "`name` at g=G p=P", and "as mesh" for a non-planes bake (in
    /// errors and progress notes).
    pub fn describe(&self) -> String {
        let what = format!("{} at g={} p={}", self.views.name, self.g, self.p);
        if self.geometry.is_planes() {
            what
        } else {
            format!("{what} as {}", self.geometry)
        }
    }
}

impl std::fmt::Debug for BakeStore {
    // Not the field in memory (millions of values).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BakeStore")
            .field("root", &self.root)
            .field("baker", &self.baker)
            .field("fields", &self.fields)
            .finish_non_exhaustive()
    }
}

impl BakeStore {
    /// A store of visual-hull bakes at `root` (created on first bake).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self::with_baker(root, Baker::Hull)
    }

    /// A store at `root` whose bakes come from `baker`; trained fields are
    /// kept in `root/fields/`.
    pub fn with_baker(root: impl Into<PathBuf>, baker: Baker) -> Self {
        let root = root.into();
        Self {
            fields: FieldStore::new(root.join("fields")),
            root,
            baker,
            last_field: Arc::new(Mutex::new(None)),
            jobs: DEFAULT_HULL_JOBS,
        }
    }

    /// The same store running `jobs` hull bakes at once in
    /// [`BakeStore::get_or_bake_many`] (at least 1).
    pub fn with_jobs(mut self, jobs: usize) -> Self {
        self.jobs = jobs.max(1);
        self
    }

    /// Bakes running at once in [`BakeStore::get_or_bake_many`] (the
    /// store's `jobs`). The trained baker runs them at once only after every
    /// field they need is trained, so no two bakes ever train one field; a
    /// trained bake keeps about 1.7 of two cores busy (its measuring,
    /// encoding and gathers are partly serial).
    pub fn jobs(&self) -> usize {
        self.jobs
    }

    /// Every request's bake, in the order given, [`BakeStore::jobs`] at a
    /// time (when more than one: largest, g²·p², first, so the last ones to
    /// finish are short);
    /// `progress` steps once per bake with `label(i)`. After a failure no
    /// new bake starts; the first failure in request order is returned once
    /// the started bakes have finished.
    ///
    /// Why: a hull bake keeps about 1.5 of two cores busy (its encoding and
    /// measuring are partly serial); two at once took `nerflex eval --quick`
    /// from 914 s to the figure in `docs/evaluation.md`. The trained baker
    /// first trains, one at a time, every field its missing bakes need,
    /// then bakes `jobs` at a time, a network's bakes together (requests on
    /// one network share its `views`); each bake holds its own G-buffers (a
    /// 50-view 800-px sample bake peaked at 2.0 GB, a (128, 17) Block-NeRF
    /// bake of the sponge about 7 GB).
    pub fn get_or_bake_many(
        &self,
        reqs: &[BakeRequest<'_>],
        lpips: Option<&Lpips>,
        progress: &dyn Progress,
        label: &(dyn Fn(usize) -> String + Sync),
    ) -> anyhow::Result<Vec<Baked>> {
        // Before any bake starts: the hull cannot bake another geometry.
        if let Some(r) = reqs.iter().find(|r| !self.can_bake(r.geometry)) {
            return Err(self.cannot_bake(r));
        }
        // And before any field is trained: the trained baker's settings of
        // every request (a mesh above its largest g, say).
        for r in reqs {
            self.check_trained(r)?;
        }
        let mut results: Vec<Option<anyhow::Result<Baked>>> =
            (0..reqs.len()).map(|_| None).collect();
        // A repeated request is baked once: two workers baking one key at
        // once would race to put the same store entry in place.
        let dirs: Vec<PathBuf> = reqs
            .iter()
            .map(|r| self.entry_dir(r, lpips.is_some()))
            .collect();
        let first_of: Vec<usize> = (0..reqs.len())
            .map(|i| dirs.iter().position(|d| *d == dirs[i]).unwrap_or(i))
            .collect();
        let unique: Vec<usize> = (0..reqs.len()).filter(|&i| first_of[i] == i).collect();
        match self.baker {
            Baker::Hull => {
                self.bake_group(
                    reqs,
                    &unique,
                    self.jobs,
                    lpips,
                    progress,
                    label,
                    &mut results,
                );
            }
            Baker::Trained(ref t) => {
                let missing: Vec<usize> = unique
                    .iter()
                    .copied()
                    .filter(|&i| !self.is_stored(&reqs[i], lpips.is_some()))
                    .collect();
                let jobs = if missing.len() > 1 { self.jobs } else { 1 };
                // Every field the missing bakes need, trained (or found)
                // first, one at a time: training keeps both cores busy, and
                // no two bakes may then train the same field.
                let mut trained: Vec<(usize, f64)> = Vec::new();
                if jobs > 1 {
                    let mut seen: Vec<&ObjectViews> = Vec::new();
                    for &i in &missing {
                        let views = reqs[i].views;
                        if seen.iter().any(|&v| std::ptr::eq(v, views)) {
                            continue;
                        }
                        seen.push(views);
                        if !self.fields.contains(views, &t.train) {
                            match self.field(views, progress) {
                                Ok(f) if f.trained_now => trained.push((i, f.train_s)),
                                Ok(_) => {}
                                Err(e) => return Err(e),
                            }
                        }
                        // Its lattice too: one choice, before the bakes
                        // that read it run side by side.
                        self.lattice(views, progress)?;
                    }
                }
                self.bake_group(reqs, &unique, jobs, lpips, progress, label, &mut results);
                // A field's training belongs to its network's first missing
                // bake, as it would one at a time.
                for (i, train_s) in trained {
                    if let Some(Some(Ok(b))) = results.get_mut(i) {
                        b.train_s += train_s;
                        b.field_trained = true;
                    }
                }
            }
        }
        // Repeats take their first request's bake, as found in the store.
        for i in 0..reqs.len() {
            let f = first_of[i];
            if f != i {
                results[i] = Some(match &results[f] {
                    Some(Ok(b)) => Ok(Baked {
                        seconds: 0.0,
                        cached: true,
                        train_s: 0.0,
                        field_trained: false,
                        ..b.clone()
                    }),
                    _ => Err(anyhow::anyhow!(
                        "bake {} of the batch is bake {}'s, which did not finish",
                        i + 1,
                        f + 1
                    )),
                });
                // One step per request, as callers size their bars.
                progress.step(&label(i));
            }
        }
        // The first failure in request order, not a bake it kept from running.
        if let Some(i) = results.iter().position(|b| matches!(b, Some(Err(_)))) {
            if let Some(Some(Err(e))) = results.get_mut(i).map(Option::take) {
                return Err(e);
            }
        }
        results
            .into_iter()
            .enumerate()
            .map(|(i, b)| {
                b.unwrap_or_else(|| Err(anyhow::anyhow!("bake {} of the batch did not run", i + 1)))
            })
            .collect()
    }

    /// The store entry of the bake `r`.
    fn entry_dir(&self, r: &BakeRequest<'_>, with_lpips: bool) -> PathBuf {
        self.root
            .join(self.key_of(r.views, r.g, r.p, r.geometry, with_lpips))
    }

    /// Whether the store holds `r`'s bake (measured with LPIPS or not).
    fn is_stored(&self, r: &BakeRequest<'_>, with_lpips: bool) -> bool {
        self.entry_dir(r, with_lpips).join(SAMPLE_FILE).is_file()
    }

    /// Whether the store's baker can bake `geometry` (the hull: planes only).
    pub fn can_bake(&self, geometry: Geometry) -> bool {
        geometry.is_planes() || matches!(self.baker, Baker::Trained(_))
    }

    /// Checks the trained baker's settings of `r` (nothing for the hull).
    fn check_trained(&self, r: &BakeRequest<'_>) -> anyhow::Result<()> {
        match self.trained_params(r.g, r.p, r.geometry) {
            Some((_, params)) => params
                .validate()
                .map_err(|e| anyhow::anyhow!("baking {}: {e}", r.describe())),
            None => Ok(()),
        }
    }

    /// The error for a request the store's baker cannot bake.
    fn cannot_bake(&self, r: &BakeRequest<'_>) -> anyhow::Error {
        anyhow::anyhow!(
            "cannot bake {}: the {} baker bakes planes only; a {} bake needs the trained baker (`--baker trained`)",
            r.describe(),
            self.baker.name(),
            r.geometry
        )
    }

    /// Bakes the requests `group` (indices into `reqs`), `jobs` at a time,
    /// into `results`; stops starting new ones after a failure.
    #[allow(clippy::too_many_arguments)]
    fn bake_group(
        &self,
        reqs: &[BakeRequest<'_>],
        group: &[usize],
        jobs: usize,
        lpips: Option<&Lpips>,
        progress: &dyn Progress,
        label: &(dyn Fn(usize) -> String + Sync),
        results: &mut [Option<anyhow::Result<Baked>>],
    ) {
        let jobs = jobs.clamp(1, group.len().max(1));
        let mut order = group.to_vec();
        // One at a time keeps the given order, so consecutive bakes of one
        // network share the field kept in memory.
        if jobs > 1 {
            // The trained baker keeps a network's bakes together, so the
            // workers mostly share one field in memory.
            let trained = matches!(self.baker, Baker::Trained(_));
            let network = |i: usize| {
                if trained {
                    reqs.iter()
                        .position(|r| std::ptr::eq(r.views, reqs[i].views))
                        .unwrap_or(i)
                } else {
                    0
                }
            };
            order.sort_by_key(|&i| {
                let r = &reqs[i];
                (
                    network(i),
                    std::cmp::Reverse(u64::from(r.g).pow(2) * u64::from(r.p).pow(2)),
                )
            });
        }
        let queue = Mutex::new(order.into_iter());
        let out: Mutex<Vec<(usize, anyhow::Result<Baked>)>> = Mutex::new(Vec::new());
        // After a failure no new bake starts (the batch fails anyway).
        let failed = std::sync::atomic::AtomicBool::new(false);
        let work = || loop {
            if failed.load(std::sync::atomic::Ordering::Relaxed) {
                break;
            }
            let next = queue.lock().map(|mut q| q.next()).ok().flatten();
            let Some(i) = next else { break };
            let b = self.get_or_bake_with(&reqs[i], lpips, progress);
            if b.is_err() {
                failed.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            progress.step(&label(i));
            if let Ok(mut v) = out.lock() {
                v.push((i, b));
            }
        };
        if jobs <= 1 {
            work();
        } else {
            std::thread::scope(|s| {
                for _ in 0..jobs {
                    s.spawn(work);
                }
            });
        }
        // A poisoned lock means a bake thread panicked: its slots stay
        // empty and read as "did not run".
        if let Ok(v) = out.into_inner() {
            for (i, b) in v {
                if let Some(slot) = results.get_mut(i) {
                    *slot = Some(b);
                }
            }
        }
    }

    /// The folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The baker behind [`BakeStore::get_or_bake`]: the one place a run's
    /// assets come from, so reports name it.
    pub fn baker(&self) -> &'static str {
        self.baker.name()
    }

    /// The baker and its settings.
    pub fn baker_settings(&self) -> &Baker {
        &self.baker
    }

    /// The field store beside the bakes.
    pub fn fields(&self) -> &FieldStore {
        &self.fields
    }

    /// The trained baker's parameters at (g, p) as `geometry` (`None` for
    /// the hull): the store's settings; for a geometry other than theirs,
    /// that geometry with its default visibility rounds, as `nerflex bake
    /// --surface` sets them when `--visibility-rounds` is not given. (The
    /// store's own geometry, planes in every pipeline, keeps its settings
    /// untouched, so a planes bake's key is what it was.)
    fn trained_params(
        &self,
        g: u32,
        p: u32,
        geometry: Geometry,
    ) -> Option<(&TrainSettings, TrainedParams)> {
        match &self.baker {
            Baker::Hull => None,
            Baker::Trained(t) => {
                let mut params = t.bake.clone();
                params.grid = g;
                params.patch = p;
                let kind = GeometryKind::from(geometry);
                if params.geometry != kind {
                    params.geometry = kind;
                    params.visibility.rounds = kind.default_visibility_rounds();
                    params.close = kind.default_close();
                    params.hull_radius = kind.default_hull_radius();
                }
                Some((&t.train, params))
            }
        }
    }

    /// The store key of the planes bake of `obj` at (g, p): the bake
    /// sweep's key for the hull; for the trained baker that key's inputs
    /// plus the field's key, the trained baker's version and settings.
    pub fn key(&self, obj: &ObjectViews, g: u32, p: u32, with_lpips: bool) -> String {
        self.key_of(obj, g, p, Geometry::Planes, with_lpips)
    }

    /// The store key of the bake of `obj` at (g, p) as `geometry`: for
    /// planes [`BakeStore::key`] (unchanged by the geometry's arrival); for
    /// the mesh the trained key of the mesh's settings, named
    /// `<name>-g<g>-p<p>-mesh-t<hash>` (the hull, which never bakes a mesh,
    /// gets its planes key with `-mesh` appended, so the two never meet).
    pub fn key_of(
        &self,
        obj: &ObjectViews,
        g: u32,
        p: u32,
        geometry: Geometry,
        with_lpips: bool,
    ) -> String {
        let key = Cache::key(obj, &BakeParams::new(g, p), with_lpips);
        let tag = if geometry.is_planes() {
            String::new()
        } else {
            format!("-{geometry}")
        };
        let Some((train, params)) = self.trained_params(g, p, geometry) else {
            return format!("{key}{tag}");
        };
        let mut h = Fnv64::default();
        h.write(key.as_bytes());
        h.write(
            format!(
                "trained v{TRAINED_BAKER_VERSION} field {} {params:?}",
                FieldStore::key(obj, train)
            )
            .as_bytes(),
        );
        // Only a chosen lattice adds to the key: a fixed one's entries keep
        // the keys they had. (The choice is a function of the field, the
        // views and the settings, all in the key already, and of the rule
        // that reads its stored scores: see below.)
        if let Some(at) = self.lattice_choice_at() {
            h.write(format!("lattice chosen at {at:?}").as_bytes());
            // A stored choice the tie rule reads as another (one made
            // before session 45): the entries under the plain key were
            // baked at the stored cells, so the new lattice keys its own.
            if let Some(c) = self
                .stored_lattice(obj)
                .filter(|c| c.stored_cells.is_some())
            {
                h.write(format!(" as {} cells", c.cells).as_bytes());
            }
        }
        format!("{}-g{g}-p{p}{tag}-t{:016x}", obj.name, h.finish())
    }

    /// Where the trained baker chooses each object's feature lattice
    /// (`None`: the hull, or a fixed lattice).
    pub fn lattice_choice_at(&self) -> Option<(u32, u32)> {
        match &self.baker {
            Baker::Trained(t) => t.choose_lattice_at,
            Baker::Hull => None,
        }
    }

    /// The folder of the lattice choices (`ROOT/lattices/`).
    fn lattices(&self) -> Cache {
        Cache::new(self.root.join("lattices"))
    }

    /// The feature lattice chosen for `obj` if `ROOT/lattices/` holds the
    /// choice (never made here).
    pub fn stored_lattice(&self, obj: &ObjectViews) -> Option<sweep::LatticeChosen> {
        let (Baker::Trained(t), Some(at)) = (&self.baker, self.lattice_choice_at()) else {
            return None;
        };
        let field_id = FieldStore::key(obj, &t.train);
        sweep::stored_lattice(obj, &field_id, &t.bake, at, &self.lattices())
    }

    /// The stored lattice choice of each of `views` that has one, in
    /// order (what a run's or an evaluation's report records).
    pub fn stored_lattices<'a>(
        &self,
        views: impl IntoIterator<Item = &'a ObjectViews>,
    ) -> Vec<sweep::LatticeChosen> {
        views
            .into_iter()
            .filter_map(|v| self.stored_lattice(v))
            .collect()
    }

    /// The feature lattice chosen for `obj`: from `ROOT/lattices/`, or
    /// chosen now (its field trained or loaded first, then three bakes at
    /// the choice's (g, p), [`sweep::chosen_lattice`]). `None` for the
    /// hull, a fixed lattice, or an object with fewer than three training
    /// views.
    pub fn lattice(
        &self,
        obj: &ObjectViews,
        progress: &dyn Progress,
    ) -> anyhow::Result<Option<sweep::LatticeChosen>> {
        let (Baker::Trained(t), Some(at)) = (&self.baker, self.lattice_choice_at()) else {
            return Ok(None);
        };
        if lattice_choice::held_back(obj.train.len()).is_empty() {
            return Ok(None);
        }
        // A stored choice needs no field in memory.
        if let Some(c) = self.stored_lattice(obj) {
            return Ok(Some(c));
        }
        let field_id = FieldStore::key(obj, &t.train);
        let cache = self.lattices();
        let field = self.field(obj, progress)?;
        progress.note(&format!(
            "choosing the feature lattice of {} at g={} p={}",
            obj.name, at.0, at.1
        ));
        sweep::chosen_lattice(
            obj,
            field.grid.as_ref(),
            &field_id,
            &t.bake,
            at,
            Some(&cache),
            &sweep::fixed_point_render,
        )
    }

    /// The trained field of `obj` (the trained baker only): the one used
    /// last, or from the field store, or trained now.
    pub fn field(&self, obj: &ObjectViews, progress: &dyn Progress) -> anyhow::Result<StoredField> {
        let Baker::Trained(t) = &self.baker else {
            anyhow::bail!("the hull baker uses no field");
        };
        let key = FieldStore::key(obj, &t.train);
        if let Ok(last) = self.last_field.lock() {
            if let Some(f) = last.as_ref().filter(|f| f.key == key) {
                let mut f = f.clone();
                (f.trained_now, f.train_s, f.load_s) = (false, 0.0, 0.0);
                return Ok(f);
            }
        }
        // Drop the last field before training or loading the next.
        if let Ok(mut last) = self.last_field.lock() {
            *last = None;
        }
        if !self.fields.contains(obj, &t.train) {
            progress.note(&format!("training the field of {}", obj.name));
        }
        let name = obj.name.as_str();
        let field = self
            .fields
            .get_or_train(obj, &t.train, &|level, step, steps, psnr| {
                progress.note(&format!(
                    "training {name}: level {} step {step}/{steps}, batch PSNR {psnr:.2} dB",
                    level + 1
                ));
            })?;
        if let Ok(mut last) = self.last_field.lock() {
            *last = Some(field.clone());
        }
        Ok(field)
    }

    /// The bake `r`: from the store, or baked, written and measured now
    /// (training its field first if the trained baker needs one that is not
    /// in the field store). A geometry the baker cannot bake is an error
    /// naming the object and the geometry.
    pub fn get_or_bake(&self, r: &BakeRequest<'_>, lpips: Option<&Lpips>) -> anyhow::Result<Baked> {
        self.get_or_bake_with(r, lpips, &Quiet)
    }

    /// [`BakeStore::get_or_bake`], telling `progress` how training goes.
    pub fn get_or_bake_with(
        &self,
        r: &BakeRequest<'_>,
        lpips: Option<&Lpips>,
        progress: &dyn Progress,
    ) -> anyhow::Result<Baked> {
        if !self.can_bake(r.geometry) {
            return Err(self.cannot_bake(r));
        }
        let (obj, g, p) = (r.views, r.g, r.p);
        let dir = self.entry_dir(r, lpips.is_some());
        if let Some((sample, views)) = read_entry(&dir) {
            return Ok(Baked {
                sample,
                dir: dir.join("asset"),
                seconds: 0.0,
                cached: true,
                train_s: 0.0,
                field_trained: false,
                views,
            });
        }
        let t0 = Instant::now();
        let (baked, details, field_s, field_trained) = match self.trained_params(g, p, r.geometry) {
            None => {
                let mut params = BakeParams::new(g, p);
                params.search_box = obj.search_box;
                let views = obj.bake_views();
                let baked = bake::bake(&views, &params)
                    .with_context(|| format!("baking {} at g={g} p={p}", obj.name))?;
                (baked, None, (0.0, 0.0), false)
            }
            Some((_, mut params)) => {
                self.check_trained(r)?;
                // The field first: its training time is this bake's to
                // report (the choice then finds it in memory).
                let field = self.field(obj, progress)?;
                let lattice = self.lattice(obj, progress)?;
                if let Some(l) = &lattice {
                    params.feature_res = l.cells;
                }
                progress.note(&format!("baking {} from its field", r.describe()));
                let views = obj.bake_views();
                let tb =
                    trained::bake(field.grid.as_ref(), &views, &params).with_context(|| {
                        format!(
                            "baking {} from its field {}",
                            r.describe(),
                            field.path.display()
                        )
                    })?;
                let details = trained_details(&tb.stats, &field, r.geometry, lattice.as_ref());
                let field_s = (field.train_s, field.load_s);
                (tb.baked, Some(details), field_s, field.trained_now)
            }
        };
        let (sample, views) = self.write_and_measure(obj, baked, &dir, details, lpips)?;
        Ok(Baked {
            sample,
            views: Some(views),
            dir: dir.join("asset"),
            // Loading a stored field counts as baking; training does not.
            seconds: (t0.elapsed().as_secs_f64() - field_s.0).max(0.0),
            cached: false,
            train_s: field_s.0,
            field_trained,
        })
    }

    /// Writes the export and its measured sample into the store entry `dir`.
    fn write_and_measure(
        &self,
        obj: &ObjectViews,
        baked: BakedObject,
        dir: &Path,
        details: Option<serde_json::Value>,
        lpips: Option<&Lpips>,
    ) -> anyhow::Result<(Sample, HeldOutScores)> {
        let (g, p) = (baked.params.grid, baked.params.patch);
        let (quads, gpu_bytes) = (baked.quads.len() as u64, baked.gpu_bytes());
        let asset = baked.into_asset()?;
        // Built under a name unique to this writer: two runs baking the
        // same key do not share a temporary folder.
        let stage = crate::output::StagedDir::new(dir)?;
        let tmp = stage.path().to_path_buf();
        let size_bytes = asset
            .write(&tmp.join("asset"))
            .with_context(|| format!("writing {}", tmp.display()))?;
        let m = obj
            .measure(&asset, &sweep::fixed_point_render, lpips, false)
            .with_context(|| format!("measuring {} at g={g} p={p}", obj.name))?;
        let q = m.mean;
        let views = HeldOutScores {
            ssim: m.views.iter().map(|v| v.ssim).collect(),
            psnr: m.views.iter().map(|v| v.psnr).collect(),
        };
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
            tmp.join(SAMPLE_FILE),
            serde_json::to_string_pretty(&sample)?,
        )
        .with_context(|| format!("{}: cannot write", tmp.display()))?;
        std::fs::write(tmp.join(VIEWS_FILE), serde_json::to_string(&views)?)
            .with_context(|| format!("{}: cannot write", tmp.display()))?;
        if let Some(d) = details {
            std::fs::write(tmp.join("bake.json"), serde_json::to_string_pretty(&d)?)
                .with_context(|| format!("{}: cannot write", tmp.display()))?;
        }
        let committed = stage.commit(
            &|n| n == "asset" || n == SAMPLE_FILE || n == "bake.json" || n == VIEWS_FILE,
            "a bake store entry holds only asset/, sample.json, views.json and bake.json",
        );
        if let Err(e) = committed {
            // Another writer of the same key (a repeated request baking
            // beside this one, or another run) got there first: bakes are
            // deterministic, so its entry is this bake; ours is dropped.
            return match read_entry(dir) {
                Some((sample, Some(views))) => Ok((sample, views)),
                _ => Err(e.into()),
            };
        }
        Ok((sample, views))
    }
}

/// What `bake.json` keeps of a trained bake: its field and the baker's
/// counts and stage times.
fn trained_details(
    s: &trained::TrainedStats,
    field: &StoredField,
    geometry: Geometry,
    lattice: Option<&sweep::LatticeChosen>,
) -> serde_json::Value {
    let t = &s.times;
    serde_json::json!({
        "geometry": geometry,
        "lattice_res": s.lattice_res,
        "lattice_choice": lattice,
        "baker": TRAINED_BAKER,
        "baker_version": TRAINED_BAKER_VERSION,
        "field": field.key,
        "field_train_s": field.report.as_ref().map(|r| r.total_s),
        "shell_voxels": s.shell_voxels,
        "full_voxels": s.full_voxels,
        "extracted_quads": s.extracted_quads,
        "kept_quads": s.kept_quads,
        "opaque_texels": s.opaque_texels,
        "trained_texels": s.trained_texels,
        "lattice_vertices": s.lattice_vertices,
        "reached_vertices": s.reached_vertices,
        "train_pixels": s.train_pixels,
        "voxel_px": s.voxel_px,
        "supersampled": s.supersampled,
        "fit_mse": s.fit_mse,
        "finetune": {
            "steps": s.finetune.steps,
            "pixel_steps": s.finetune.pixel_steps,
            "psnr_before": s.finetune.psnr_before,
            "psnr_after": s.finetune.psnr_after,
        },
        "seconds": {
            "extract": t.extract_s,
            "gbuffer": t.gbuffer_s,
            "init": t.init_s,
            "finetune": t.finetune_s,
            "atlas": t.atlas_s,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::bake_trained::TrainedArgs;
    use clap::Parser as _;

    /// `nerflex bake`'s trained-baker flags, parsed as the CLI parses them.
    #[derive(clap::Parser)]
    struct Flags {
        #[command(flatten)]
        trained: TrainedArgs,
    }

    fn cli_params(args: &[&str], g: u32, p: u32) -> TrainedParams {
        let argv = std::iter::once("nerflex-bake").chain(args.iter().copied());
        Flags::try_parse_from(argv).unwrap().trained.params(g, p)
    }

    /// `nerflex bake`'s flag defaults are the library's: the CLI repeats
    /// them as clap defaults, so a default changed in one place only (as
    /// baker version 11's rounds, share and epochs were, in both) fails here.
    #[test]
    fn the_cli_defaults_are_the_trained_params_defaults() {
        for (g, p) in [(16, 5), (128, 17)] {
            assert_eq!(cli_params(&[], g, p), TrainedParams::new(g, p));
        }
    }

    #[test]
    fn a_mesh_request_is_baked_as_nerflex_bake_surface_mesh_bakes_it() {
        // A store whose settings are `nerflex bake`'s defaults (planes).
        let planes = cli_params(&[], 16, 5);
        assert_eq!(planes.geometry, GeometryKind::Planes);
        let store = BakeStore::with_baker(
            "unused",
            Baker::trained(TrainSettings::default(), planes.clone()),
        );
        let (_, p) = store.trained_params(16, 5, Geometry::Planes).unwrap();
        assert_eq!(p, planes, "a planes request keeps the store's settings");
        let (_, m) = store.trained_params(16, 5, Geometry::Mesh).unwrap();
        assert_eq!(m, cli_params(&["--surface", "mesh"], 16, 5));
        assert_eq!(
            (m.geometry, m.visibility.rounds, m.hull_radius),
            (GeometryKind::Mesh, 0, 2.0)
        );
        assert_eq!(planes.hull_radius, 1.0);
        // `--hull-radius` overrides either geometry's default.
        let told = cli_params(&["--surface", "mesh", "--hull-radius", "1.5"], 16, 5);
        assert_eq!(told.hull_radius, 1.5);
        // Other settings of the store carry over to its mesh bakes, as the
        // same flags would with `--surface mesh`.
        let mut tuned = cli_params(&["--epochs", "1.5", "--surface-alpha", "0.1"], 16, 5);
        let store = BakeStore::with_baker(
            "unused",
            Baker::trained(TrainSettings::default(), tuned.clone()),
        );
        let (_, m) = store.trained_params(16, 5, Geometry::Mesh).unwrap();
        assert_eq!(
            m,
            cli_params(
                &[
                    "--epochs",
                    "1.5",
                    "--surface-alpha",
                    "0.1",
                    "--surface",
                    "mesh"
                ],
                16,
                5
            )
        );
        // The planes' own rounds (not the default) do not reach the mesh.
        tuned.visibility.rounds = 2;
        let store =
            BakeStore::with_baker("unused", Baker::trained(TrainSettings::default(), tuned));
        let (_, m2) = store.trained_params(16, 5, Geometry::Mesh).unwrap();
        assert_eq!(m2, m);
        // The hull has no trained settings and cannot bake a mesh.
        let hull = BakeStore::new("unused");
        assert!(hull.trained_params(16, 5, Geometry::Mesh).is_none());
        assert!(hull.can_bake(Geometry::Planes) && !hull.can_bake(Geometry::Mesh));
        assert!(store.can_bake(Geometry::Mesh));
    }
}
