//! The `nerflex bake` flags of the trained baker (`--baker`, `--field`,
//! `--epochs`, `--surface-alpha`) and loading the field they name.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};

use crate::bake::trained::{
    self, analytic::Builtin, sampling::FinetuneSampling, GeometryKind, TrainedParams,
};
use crate::bake::{BakeView, BakedObject};
use crate::capture::SceneInfo;
use crate::train::field::RadianceField;

/// Which baker makes the export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Baker {
    /// From a radiance field, fine-tuned on the capture (`bake::trained`).
    Trained,
    /// From the capture's silhouettes and colours (visual hull).
    Hull,
}

/// Flags of the trained baker.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct TrainedArgs {
    /// Baker: `trained` (from `--field`, fine-tuned on the capture) or
    /// `hull` (visual hull, no field). Default: trained when `--field` is
    /// given, else hull.
    #[arg(long, value_parser = parse_baker)]
    pub baker: Option<Baker>,
    /// The radiance field to bake from: a file saved by `nerflex train`, or
    /// `builtin` for the analytic field of a built-in capture's object
    /// (from its `scene.json`; a stand-in with known geometry).
    #[arg(long)]
    pub field: Option<PathBuf>,
    /// Fine-tune passes over the training pixels, split over the
    /// visibility rounds' fine-tunes (3 until baker version 11).
    #[arg(long, default_value_t = 2.5)]
    pub epochs: f32,
    /// Adam's learning rate on the feature lattice (decays ×0.1 over the
    /// fine-tune; 0.03 until baker version 10: at 0.015 lego (128, 17)
    /// +0.0010 SSIM at the same PSNR over three seeds, chair +0.08 dB,
    /// docs/baking.md, "Session 29").
    #[arg(long, default_value_t = 0.015)]
    pub feature_lr: f32,
    /// Adam's learning rate on the MLP's weights (decays ×0.1 over the
    /// fine-tune).
    #[arg(long, default_value_t = 3e-3)]
    pub mlp_lr: f32,
    /// Seed of the fine-tune's pixel order (its spread over seeds is the
    /// bake's noise: docs/baking.md, "Session 29").
    #[arg(long, default_value_t = 7)]
    pub finetune_seed: u64,
    /// Runs of this many neighbouring training pixels keep together in the
    /// fine-tune's shuffled order (fewer cache misses; 1: every pixel on
    /// its own, the default; docs/baking.md, "Session 53").
    #[arg(long, default_value_t = 1)]
    pub finetune_run: u32,
    /// Rounds of the depth carve: texels that training rays reach in
    /// front of the field's median depth (by more than
    /// --depth-carve-margin voxels) are emptied; 0: off.
    #[arg(long, default_value_t = 0)]
    pub depth_carve: u32,
    /// Slack of the depth carve, voxels.
    #[arg(long, default_value_t = 1.0)]
    pub depth_carve_margin: f32,
    /// Opacity over half a field cell at which a point is inside (0.5
    /// finds almost nothing in a trained field whose surface spreads over
    /// a few cells; 0.05 keeps lego's surface, see docs/baking.md).
    #[arg(long, default_value_t = 0.05)]
    pub surface_alpha: f32,
    /// The share of the photos' object pixels whose rays may miss the
    /// inside: where more peak below --surface-alpha's density, the
    /// threshold comes down to reach them (0: never; docs/baking.md,
    /// "Session 27").
    #[arg(long, default_value_t = 0.02)]
    pub surface_miss: f32,
    /// After the last fine-tune, rasterize every N-th training view at the
    /// renderer's 2 × 2 subsamples; where a subsample of a pixel the photo
    /// shows as object (3 px from any background) meets no opaque texel,
    /// the nearest transparent texel on its ray becomes opaque. 0: off
    /// (lego (128, 17): 1 is +0.09 dB for 19 s, 3 is +0.06 dB for 6 s;
    /// docs/baking.md, "Session 28").
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub fill_holes: u32,
    /// A voxel side gets a quad when it sees this fraction of the surface
    /// its best side sees (1: one quad per voxel).
    #[arg(long, default_value_t = 0.5)]
    pub surface_keep: f32,
    /// Quads overlap their neighbours by this fraction of a voxel.
    #[arg(long, default_value_t = 0.125)]
    pub surface_grow: f32,
    /// A plane sits where the field's opacity, accumulated inward from the
    /// surface's entry, reaches this value (0.5: the volume renderer's
    /// median depth; the default 0.2 scores best, docs/baking.md).
    #[arg(long, default_value_t = 0.2)]
    pub surface_depth: f32,
    /// A texel is opaque when its line enters the surface within its
    /// voxel's slab widened by this fraction of a voxel on both ends
    /// (0: the slab alone, baker version 8): stacked planes of a sloped
    /// surface overlap instead of opening cracks between the training
    /// views (lego (128, 17): +0.14 dB, docs/baking.md, "Session 28").
    #[arg(long, default_value_t = 0.25)]
    pub surface_reach: f32,
    /// Rounds of texel opacity learnt from the photos: after a fine-tune,
    /// every shown texel whose removal lowers its pixels' error (what lies
    /// behind it shows instead) is made transparent, then the views are
    /// rasterized and fine-tuned again; `--epochs` is split over the
    /// rounds' fine-tunes [default: 2 on the planes, 0 on the mesh; 1
    /// until baker version 11]. On lego (128, 17) one round gains +0.39
    /// dB and two 0.11 dB more for 20 s more (version 10: two rounds take
    /// lego to 30.00 dB, 1.98 below its field, and chair +0.02 dB, for 12 s
    /// more, "Session 29"; with --visibility-tune-share 0.25 and 2.5
    /// epochs, version 11's default, 30.02 dB over three seeds, "Session
    /// 30");
    /// on the mesh a round loses (lego (256, 5): −0.16 dB), as its quads
    /// hide little (docs/baking.md, "Session 16").
    #[arg(long)]
    pub visibility_rounds: Option<u32>,
    /// A texel goes when its removal lowers its pixels' summed squared
    /// error (RGB in [0, 1]) by more than this.
    #[arg(long, default_value_t = 0.01)]
    pub visibility_margin: f32,
    /// The visibility rounds also make transparent texels opaque: where one
    /// lies in front of what training pixels show and showing it lowers
    /// their summed squared error by more than this margin (off unless
    /// given; 0.4 suggested). Lego (128, 17): +0.09 dB with one round,
    /// +0.12 dB with two, for one more rasterized layer (docs/baking.md,
    /// "Session 24").
    #[arg(long, value_name = "MARGIN")]
    pub visibility_grow: Option<f32>,
    /// The visibility rounds judge texels in blocks of B × B of their patch:
    /// a texel flips when the summed change of the shown texels of its
    /// state in its block passes the margin (1: texel by texel). 0
    /// (default): automatic, the most texels per side whose block spans at
    /// most a pixel of the training views (lego (128, 17): B = 3, +0.08 dB;
    /// (256, 17): B = 6, +0.25 dB at 1 epoch; 1 where a texel spans more
    /// than half a pixel; docs/baking.md, "Session 25" and "Session 26").
    #[arg(long, value_name = "B", default_value_t = 0)]
    pub visibility_block: u32,
    /// Each visibility round's fine-tune before the last takes this share
    /// of the last one's epochs (1: `--epochs` split evenly, the default
    /// until baker version 11). Lego (128, 17), two rounds of 2.5 epochs
    /// at 0.25 against version 10's one round of 3 at 1: 30.02 dB against
    /// 29.80 over seeds 7, 1 and 2, 1.96 below its field; chair −0.05 dB
    /// (docs/baking.md, "Session 30").
    #[arg(long, value_name = "S", default_value_t = 0.25)]
    pub visibility_tune_share: f32,
    /// Keep the quads the training pixels' layer behind lies on, not only
    /// those they show first: a held-out view sees them through the gaps
    /// between the front quads. Gear (256, 13): holes 19.3 % → 7.9 % of
    /// the squared error, +0.27 dB, for 42 % more GPU bytes; (128, 13):
    /// +0.05 dB for 36 % more (docs/baking.md, "Session 32").
    #[arg(long)]
    pub keep_behind: bool,
    /// Keep the quads a virtual camera between the training views shows
    /// first as well (one per training view, at the angular midpoint to
    /// its nearest neighbour; one pass before the first round): the
    /// quads a novel view sees through the gaps between the front planes.
    /// Gear (128, 13): +0.19 dB, holes 14.8 % → 8.2 % of the squared
    /// error, for 9 % more GPU bytes; (256, 13): +0.28 dB for 10 % more;
    /// lego (128, 17): +0.02 dB for 4 % more and 1.03 times the time
    /// (docs/baking.md, "Session 33").
    #[arg(long)]
    pub keep_novel: bool,
    /// The trained baker's quads: `planes` (per voxel, planar quads
    /// tilted onto the surface), `mesh` (one connected mesh, MobileNeRF's
    /// topology; g ≤ 512) or `mesh+planes` (the mesh, and planes in the
    /// voxels a feature thinner than a voxel crosses without a vertex).
    #[arg(long = "surface", value_parser = parse_geometry, default_value = "planes")]
    pub surface_kind: GeometryKind,
    /// Before the hull carve, a transparent texel with at least this many
    /// opaque neighbours (of its 8) in its patch becomes opaque: pinholes
    /// and slivers a texel or two wide, which the renderer's subsamples
    /// find as white specks; 0: off [default: 3 on the planes, 0 on the
    /// mesh] (lego (128, 17) +0.27 dB, docs/baking.md, "Session 18").
    #[arg(long)]
    pub surface_close: Option<u32>,
    /// Keep texels outside the training views' visual hull.
    #[arg(long)]
    pub no_hull_carve: bool,
    /// Extract the quads from the field's inside alone, not bounded by
    /// the training views' visual hull (baker version 11). The bound puts
    /// the planes on the hull where the field's soft surface reaches past
    /// the photos' contour, and the hull carve no longer empties planes
    /// with nothing behind them: pawn (256, 9) 33.00 → 41.05 dB held out,
    /// lego (128, 17) +0.08 dB over three seeds (docs/baking.md,
    /// "Session 35").
    #[arg(long)]
    pub no_hull_surface: bool,
    /// The hull carve's window: a texel goes when some view shows
    /// background on every pixel whose centre lies within this many pixels
    /// (in x and in y) of its projection; at least ½ [default: 1 on the
    /// planes, 2 on the mesh] (lego (128, 17): 1.0 is +0.51 dB over 1.5,
    /// docs/baking.md, "Session 23"; lego mesh (256, 5): 2 is +2.8 dB over
    /// 1, "Session 25").
    #[arg(long)]
    pub hull_radius: Option<f32>,
    /// Move the quads onto the field's half-transmittance depth (one more
    /// G-buffer pass; +0.03 dB on lego, docs/baking.md).
    #[arg(long)]
    pub depth_correct: bool,
    /// Fine-tune through the renderer's 2 × 2 supersampling (up to four
    /// texels per training pixel) at any g. Default: only where a voxel
    /// spans fewer than 4 pixels of the training views (chair (256, 17)
    /// +0.0028 SSIM, lego +0.0038). At g = 128 it gains +0.25 dB on lego
    /// and chair for twice the bake time (docs/baking.md, "Session 20").
    #[arg(long, conflicts_with = "no_train_supersample")]
    pub train_supersample: bool,
    /// Fine-tune at one sample per pixel at any g (see
    /// `--train-supersample`).
    #[arg(long)]
    pub no_train_supersample: bool,
    /// Rounds of dropping quads the training views show mostly against the
    /// background (one G-buffer pass each; the hull carve leaves little).
    #[arg(long, default_value_t = 0)]
    pub carve_rounds: u32,
    /// Cells per edge of the feature lattice the fine-tune learns and the
    /// texels sample, fixed (0: one cell per two pixels of the object as
    /// the training views see it). Default: that resolution for a single
    /// bake; chosen per object for `--sweep` (see `--choose-feature-res`).
    #[arg(long, conflicts_with = "choose_feature_res")]
    pub feature_res: Option<u32>,
    /// Choose the feature lattice's resolution for this object first: bake
    /// from all but every 8th training view at the default resolution and
    /// at a half and a quarter of it, keep the one that renders the held-back
    /// views best (SSIM; the finer of two within 0.002, the bake's seed
    /// noise), then bake from every view with it
    /// (`bake::trained::lattice_choice`; four bakes in all, so a single
    /// bake does it only when asked). `--sweep` always chooses unless
    /// `--feature-res` is given: once per object at (64, 9), the choice
    /// then serving every (g, p) and cached beside the samples.
    #[arg(long)]
    pub choose_feature_res: bool,
    /// Before baking, print how well the extracted geometry's texel points
    /// carry the training images (`gbuffer::probe`: the field's colour at
    /// each shown texel's point against the pixel; a parallax measure).
    #[arg(long)]
    pub probe: bool,
}

fn parse_geometry(s: &str) -> Result<GeometryKind, String> {
    match s {
        "planes" => Ok(GeometryKind::Planes),
        "mesh" => Ok(GeometryKind::Mesh),
        "mesh+planes" => Ok(GeometryKind::MeshFilled),
        _ => Err(format!(
            "`{s}` is not a --surface (planes, mesh, mesh+planes)"
        )),
    }
}

fn parse_baker(s: &str) -> Result<Baker, String> {
    match s {
        "trained" => Ok(Baker::Trained),
        "hull" => Ok(Baker::Hull),
        _ => Err(format!("`{s}` is not a baker (trained, hull)")),
    }
}

impl TrainedArgs {
    /// The baker the flags choose.
    pub fn baker(&self) -> anyhow::Result<Baker> {
        match (self.baker, &self.field) {
            (Some(Baker::Trained), None) => bail!(
                "--baker trained needs --field FILE (a field saved by `nerflex train`, or `builtin` on a built-in capture)"
            ),
            (Some(Baker::Hull), Some(f)) => bail!(
                "--field {} is only read by --baker trained",
                f.display()
            ),
            (Some(b), _) => Ok(b),
            (None, Some(_)) => Ok(Baker::Trained),
            (None, None) => Ok(Baker::Hull),
        }
    }

    /// Parameters of a trained bake at (g, p).
    pub fn params(&self, grid: u32, patch: u32) -> TrainedParams {
        let mut p = TrainedParams::new(grid, patch);
        p.finetune.epochs = self.epochs;
        p.finetune.lr_features = self.feature_lr;
        p.finetune.lr_mlp = self.mlp_lr;
        p.finetune.seed = self.finetune_seed;
        p.finetune.run = self.finetune_run;
        p.depth_carve_rounds = self.depth_carve;
        p.depth_carve_margin = self.depth_carve_margin;
        p.surface_alpha = self.surface_alpha;
        p.surface_miss = self.surface_miss;
        p.fill_holes = self.fill_holes;
        p.feature_res = self.feature_res.unwrap_or(0);
        p.depth_correct = self.depth_correct;
        p.sampling = match (self.train_supersample, self.no_train_supersample) {
            (true, _) => FinetuneSampling::Supersampled,
            (_, true) => FinetuneSampling::OnePerPixel,
            _ => FinetuneSampling::Auto,
        };
        p.carve_rounds = self.carve_rounds;
        p.hull_carve = !self.no_hull_carve;
        p.hull_surface = !self.no_hull_surface;
        p.hull_radius = self
            .hull_radius
            .unwrap_or(self.surface_kind.default_hull_radius());
        p.close = self
            .surface_close
            .unwrap_or(self.surface_kind.default_close());
        p.geometry = self.surface_kind;
        p.surface.keep = self.surface_keep;
        p.surface.grow = self.surface_grow;
        p.surface.depth = self.surface_depth;
        p.surface.reach = self.surface_reach;
        p.visibility.rounds = self
            .visibility_rounds
            .unwrap_or(self.surface_kind.default_visibility_rounds());
        p.visibility.margin = self.visibility_margin;
        p.visibility.grow = self.visibility_grow;
        p.visibility.block = self.visibility_block;
        p.visibility.tune_share = self.visibility_tune_share;
        p.visibility.keep_behind = self.keep_behind;
        p.visibility.keep_novel = self.keep_novel;
        p
    }
}

/// The field `spec` names for `object` of the capture in `capture` and a
/// string identifying its content (for sweep cache keys). A folder `spec`
/// holds one field per object: `{spec}/{object}.safetensors`.
pub fn load_field_with_id(
    spec: &Path,
    capture: &Path,
    object: &str,
) -> anyhow::Result<(Box<dyn RadianceField>, String)> {
    if spec.as_os_str() == "builtin" {
        let scene = capture.join("scene.json");
        let id = format!(
            "builtin {:016x}",
            crate::bake::sweep::hash_files(std::slice::from_ref(&scene))?
        );
        let name = SceneInfo::read(&scene)
            .ok()
            .and_then(|s| (s.objects.len() > 1).then(|| object.to_string()));
        return Ok((load_field(spec, capture, name.as_deref())?, id));
    }
    let file = if spec.is_dir() {
        spec.join(format!("{object}.safetensors"))
    } else {
        spec.to_path_buf()
    };
    let id = format!(
        "{} {:016x}",
        file.display(),
        crate::bake::sweep::hash_files(std::slice::from_ref(&file))
            .with_context(|| format!("--field: cannot read {}", file.display()))?
    );
    Ok((load_field(&file, capture, Some(object))?, id))
}

/// Loads the field `spec` names for `object` of the capture in `capture`.
pub fn load_field(
    spec: &Path,
    capture: &Path,
    object: Option<&str>,
) -> anyhow::Result<Box<dyn RadianceField>> {
    if spec.as_os_str() == "builtin" {
        let path = capture.join("scene.json");
        let scene = SceneInfo::read(&path).with_context(|| {
            format!(
                "--field builtin needs a built-in capture with scene.json: {}",
                path.display()
            )
        })?;
        let info = match object {
            Some(name) => scene
                .object(name)
                .with_context(|| format!("{}: no object `{name}`", path.display()))?,
            None => match scene.objects.as_slice() {
                [one] => one,
                _ => bail!(
                    "{}: several objects; pick one with --object",
                    path.display()
                ),
            },
        };
        let field = Builtin::from_info(info).with_context(|| {
            format!(
                "{}: `{}` is not a built-in object kind",
                path.display(),
                info.kind
            )
        })?;
        return Ok(Box::new(field));
    }
    if !spec.exists() {
        bail!("--field {}: no such file", spec.display());
    }
    crate::train::load_field(spec).with_context(|| format!("--field {}", spec.display()))
}

/// A field `--field` names, loaded.
pub struct LoadedField {
    /// The field.
    pub field: Box<dyn RadianceField>,
    /// What `--field` said.
    pub spec: std::path::PathBuf,
    /// Wall time of the load, seconds.
    pub seconds: f64,
}

/// Loads the field `--field` names for `object` of the capture in
/// `capture` (a file, or `builtin`).
pub fn load(
    args: &TrainedArgs,
    capture: &Path,
    object: Option<&str>,
) -> anyhow::Result<LoadedField> {
    let spec = args
        .field
        .as_deref()
        .context("--baker trained needs --field")?;
    let t_load = std::time::Instant::now();
    let field = load_field(spec, capture, object)?;
    Ok(LoadedField {
        field,
        spec: spec.to_path_buf(),
        seconds: t_load.elapsed().as_secs_f64(),
    })
}

/// Bakes one object from its loaded field with the trained baker and
/// prints its counts.
pub fn bake(
    args: &TrainedArgs,
    loaded: &LoadedField,
    views: &[BakeView<'_>],
    grid: u32,
    patch: u32,
) -> anyhow::Result<BakedObject> {
    let field = &loaded.field;
    println!(
        "trained: field {} loaded in {:.2} s",
        loaded.spec.display(),
        loaded.seconds
    );
    if args.probe {
        probe(args, field.as_ref(), views, grid, patch)?;
    }
    let mut params = args.params(grid, patch);
    if args.choose_feature_res {
        let c = trained::lattice_choice::choose(
            field.as_ref(),
            views,
            &params,
            &crate::bake::sweep::fixed_point_render,
        )?;
        for k in &c.candidates {
            println!(
                "trained: feature lattice {}³ from {} views: {:.2} dB, SSIM {:.4} on the {} held back ({:.1} s)",
                k.cells, c.train_views, k.psnr, k.ssim, c.held_back, k.seconds
            );
        }
        println!("trained: feature lattice chosen: {}³ cells", c.chosen);
        params.feature_res = c.chosen;
    }
    let tb = trained::bake(field.as_ref(), views, &params)?;
    let s = &tb.stats;
    let t = &s.times;
    let th = &s.threshold;
    println!(
        "trained: surface density {:.1} per unit{}; {} of {} photo object rays peak below --surface-alpha's {:.1} before they are half opaque ({:.2} s)",
        th.sigma,
        if th.lowered() {
            format!(
                " (lowered to {:.0} % of --surface-alpha's: more than --surface-miss of the rays missed it)",
                100.0 * th.sigma / th.sigma_alpha
            )
        } else {
            String::new()
        },
        th.below,
        th.rays,
        th.sigma_alpha,
        th.seconds
    );
    if let Some(h) = &s.hull_bound {
        println!(
            "trained: hull bound on {}³ voxels: {} outside, {} inside, {} open, of which {} settled where the field stays within the hull ({:.2} s)",
            h.grid, h.outside, h.inside, h.open, h.settled, h.seconds
        );
    }
    println!(
        "trained: {} shell + {} full voxels, {} quads extracted, {} dropped (seen mostly against the background), {} kept (seen by a training pixel{})",
        s.shell_voxels,
        s.full_voxels,
        s.extracted_quads,
        s.carved_quads,
        s.kept_quads,
        match (params.visibility.keep_behind, params.visibility.keep_novel) {
            (false, false) => "",
            (true, false) => ", or behind one",
            (false, true) => ", or by a virtual camera",
            (true, true) => ", behind one or by a virtual camera",
        }
    );
    println!(
        "trained: {} opaque texels, {} shown by a training pixel; feature lattice {}³ cells, {} vertices, {} reached; {} training pixels; MLP's initial fit: MSE {:.5}",
        s.opaque_texels, s.trained_texels, s.lattice_res, s.lattice_vertices, s.reached_vertices, s.train_pixels, s.fit_mse
    );
    println!(
        "trained: {} covered training pixels show a quad from behind",
        s.backface_pixels
    );
    println!(
        "trained: a voxel spans {:.1} px of the training views: fine-tune at {}",
        s.voxel_px,
        if s.supersampled {
            "2 × 2 samples per pixel"
        } else {
            "one sample per pixel"
        }
    );
    if args.depth_carve > 0 {
        println!(
            "trained: depth carve: {} training pixels reached their texel in front of the field's median depth, {} texels emptied",
            s.depth_carve.pixels_against, s.depth_carve.texels_carved
        );
    }
    if args.depth_correct {
        println!(
            "trained: {} quads moved onto the field's half-transmittance depth (mean {:.2} voxels; {} pixels with a crossing)",
            s.depth.moved, s.depth.mean_shift, s.depth.crossings
        );
    }
    if params.close > 0 {
        println!(
            "trained: {} texels closed (at least {} of their 8 patch neighbours opaque)",
            s.closed_texels, params.close
        );
    }
    // The rounds that ran: the flag, or the geometry's default.
    if params.visibility.rounds > 0 {
        let v = &s.visibility;
        println!(
            "trained: visibility: {} texels made transparent, {} opaque (estimated error change {:.1} of {:.1}) in {b} × {b} blocks; last round judged {} texels and {} nearer ones over {} pixels; {} subsamples lost both layers, {} had theirs behind on an unshown quad; {} of {} tiles' layer behind redrawn by peeling; peel {:.2} s, judge {:.2} s",
            v.removed_texels, v.added_texels, v.error_change, v.error_before, v.shown_texels, v.nearer_texels, v.pixels, v.lost_subsamples, v.unkept_behind, v.peel_tiles.1, v.peel_tiles.0, v.peel_s, v.judge_s,
            b = v.block
        );
    }
    if params.visibility.keep_novel {
        let n = &s.novel;
        println!(
            "trained: keep novel: {} virtual cameras show {} quads first ({:.2} s)",
            n.cameras, n.quads, n.seconds
        );
    }
    if params.fill_holes > 0 {
        let f = &s.fill;
        println!(
            "trained: hole fill: {} subsamples of interior object pixels in {} training views met no opaque texel, {} of them a transparent one; {} texels made opaque ({:.2} s)",
            f.open_subsamples, f.views, f.reachable, f.filled_texels, f.seconds
        );
    }
    println!(
        "trained: fine-tune {} steps, {} pixel steps, training PSNR {:.2} → {:.2} dB",
        s.finetune.steps, s.finetune.pixel_steps, s.finetune.psnr_before, s.finetune.psnr_after
    );
    println!(
        "trained: time extract {:.2} s, G-buffers {:.2} s, init {:.2} s, fine-tune {:.2} s, visibility {:.2} s, atlas {:.2} s",
        t.extract_s, t.gbuffer_s, t.init_s, t.finetune_s, t.visibility_s, t.atlas_s
    );
    Ok(tb.baked)
}

/// Prints [`trained::gbuffer::probe`] of the geometry the bake would use.
fn probe(
    args: &TrainedArgs,
    field: &dyn RadianceField,
    views: &[BakeView<'_>],
    grid: u32,
    patch: u32,
) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    let params = args.params(grid, patch);
    params.validate()?;
    let th =
        trained::threshold::surface_sigma(field, views, params.surface_alpha, params.surface_miss);
    let surface = trained::extract::Surface::with_sigma(field, th.sigma);
    let sil = params
        .hull_surface
        .then(|| crate::bake::carve::Silhouettes::new(views).with_radius(params.hull_radius));
    let lookup = trained::hull_lookup(&surface, sil.as_ref(), &params);
    let surface = match &lookup {
        Some(l) => surface.bounded_by(&l.0),
        None => surface,
    };
    let geo = trained::extract_geometry(&surface, &params)
        .context("--probe: the field has no surface at this --surface-alpha")?;
    let pr = trained::gbuffer::probe(&surface, &geo, patch, views)?;
    println!(
        "probe: texel points {:.2} dB over {} covered of {} object pixels; on rays meeting the inside: texel points {:.2} dB, surface points {:.2} dB, {} texel points over a voxel off ({:.1} s)",
        pr.psnr,
        pr.pixels,
        pr.object_pixels,
        pr.hit_psnr,
        pr.surface_psnr,
        pr.far_pixels,
        t0.elapsed().as_secs_f64()
    );
    println!(
        "probe: against the field's median depth (transmittance ½; colour there {:.2} dB): texel > 1 voxel in front {} px ({:.2} dB), within a voxel {} px ({:.2} dB), > 1 voxel behind {} px ({:.2} dB)",
        pr.median_psnr,
        pr.by_depth[0],
        pr.by_depth_psnr[0],
        pr.by_depth[1],
        pr.by_depth_psnr[1],
        pr.by_depth[2],
        pr.by_depth_psnr[2],
    );
    Ok(())
}
