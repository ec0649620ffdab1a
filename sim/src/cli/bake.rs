//! `nerflex bake`: bake MobileNeRF-format assets from posed captures, one
//! (g, p) or a sweep, optionally measured against the held-out views.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context as _};

use crate::bake::sweep::{self, Cache, ObjectViews, SweepOptions};
use crate::bake::{self, carve::VoxelTest, compare, BakeParams, Geometry};
use crate::capture::Capture;
use crate::metrics::Lpips;

/// Default folder of the sweep's sample cache (inside cargo's ignored
/// `target/`: a cache, not a result).
pub const DEFAULT_CACHE: &str = "target/bake-cache";

/// Flags of `nerflex bake`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Capture folder in the NeRF-synthetic layout (`transforms_train.json`,
    /// `transforms_test.json`, images); with `--sweep`, repeat for more objects.
    #[arg(long, required = true)]
    pub capture: Vec<PathBuf>,
    /// Object(s) of a multi-object capture (`scene.json` names), comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub object: Vec<String>,
    /// Grid g (voxels per edge); with `--sweep`, a comma-separated list.
    #[arg(long, value_delimiter = ',', required_unless_present = "configs")]
    pub grid: Vec<u32>,
    /// Patch p (texels per quad edge); with `--sweep`, a comma-separated list
    /// (the sweep bakes every g with every p).
    #[arg(long, value_delimiter = ',', required_unless_present = "configs")]
    pub patch: Vec<u32>,
    /// With `--sweep`, instead of `--grid` × `--patch`: exactly these
    /// configurations, `G:P` comma-separated (e.g. the profiler's samples);
    /// with `--compare`, the bakes to compare.
    #[arg(long, value_delimiter = ',', value_parser = parse_config)]
    pub configs: Vec<(u32, u32)>,
    /// Output folder of the asset (MobileNeRF export layout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Render the held-out test views and report SSIM, PSNR, LPIPS.
    #[arg(long)]
    pub measure: bool,
    /// With `--measure`: also write each test view's render and ground
    /// truth (`test_{i}.png`, `truth_{i}.png`, over white) here.
    #[arg(long)]
    pub renders: Option<PathBuf>,
    /// Side (pixels) the `--renders` pictures are scaled down to (default:
    /// full size).
    #[arg(long)]
    pub renders_size: Option<u32>,
    /// Bake and measure every (capture, g, p) into a samples CSV.
    #[arg(long)]
    pub sweep: bool,
    /// The samples CSV of `--sweep`.
    #[arg(long, default_value = "results/bake/samples.csv")]
    pub csv: PathBuf,
    /// With `--sweep`: also draw size-vs-g and SSIM-vs-g pictures, one per
    /// object, into this folder.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Cache folder of measured samples (default: target/bake-cache).
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Bake everything again, ignoring the cache.
    #[arg(long)]
    pub no_cache: bool,
    /// Bakes running at once during a sweep (each bake is parallel inside).
    #[arg(long, default_value_t = 2)]
    pub jobs: usize,
    /// Use only the first N training views.
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Use only the first N test views for `--measure` / `--sweep`.
    #[arg(long)]
    pub max_test_views: Option<usize>,
    /// Exponent k of the frontal weighting cos(θ)^k of a view's colour.
    #[arg(long, default_value_t = 1.0)]
    pub frontal_power: f32,
    /// Quad placement: shell (faces of every voxel the hull's surface
    /// crosses, texel alpha from the hull) or boundary (faces between
    /// carved and empty voxels).
    #[arg(long, default_value = "shell", value_parser = parse_geometry)]
    pub geometry: Geometry,
    /// With `--geometry boundary`: which voxels survive carving (centre,
    /// any-point or footprint).
    #[arg(long, default_value = "centre", value_parser = parse_voxel_test)]
    pub voxel_test: VoxelTest,
    /// Comparison pictures and tables (boxed: keeps the CLI's enum small).
    #[command(flatten)]
    pub reports: Box<Reports>,
    /// The trained baker's flags (`--baker`, `--field`, …).
    #[command(flatten)]
    pub trained: Box<super::bake_trained::TrainedArgs>,
    /// LPIPS weights (default: `lpips/` in the shared data folder; LPIPS is
    /// left out if absent).
    #[arg(long)]
    pub lpips_weights: Option<PathBuf>,
}

/// Flags of `nerflex bake` that write comparisons: a side-by-side picture
/// of bakes, a markdown table of a sweep.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct Reports {
    /// Bake every `--configs` entry of one object, measure each on every
    /// test view (per view and mean) and write a picture here: the ground
    /// truth of test view `--view` next to each bake's render, over white,
    /// scaled to `--renders-size` (default 400).
    #[arg(long, requires = "configs", conflicts_with = "sweep")]
    pub compare: Option<PathBuf>,
    /// The test view (index into `transforms_test.json`) `--compare` shows.
    #[arg(long, default_value_t = 0)]
    pub view: usize,
    /// With `--sweep`: also write a markdown table of the samples at
    /// `--table-configs` (one row per object and configuration) here.
    #[arg(long, requires = "sweep")]
    pub table: Option<PathBuf>,
    /// The configurations `--table` lists, `G:P` comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_config, default_value = "16:5,128:17,256:17")]
    pub table_configs: Vec<(u32, u32)>,
}

fn parse_config(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}` is not a configuration G:P (e.g. 128:17)");
    let (g, p) = s.split_once(':').ok_or_else(bad)?;
    Ok((
        g.trim().parse().map_err(|_| bad())?,
        p.trim().parse().map_err(|_| bad())?,
    ))
}

fn parse_geometry(s: &str) -> Result<Geometry, String> {
    match s {
        "shell" => Ok(Geometry::Shell),
        "boundary" => Ok(Geometry::Boundary),
        _ => Err(format!("`{s}` is not a geometry (shell, boundary)")),
    }
}

fn parse_voxel_test(s: &str) -> Result<VoxelTest, String> {
    match s {
        "centre" | "center" => Ok(VoxelTest::Centre),
        "any-point" => Ok(VoxelTest::AnyPoint),
        "footprint" => Ok(VoxelTest::Footprint),
        _ => Err(format!(
            "`{s}` is not a voxel test (centre, any-point, footprint)"
        )),
    }
}

/// Loads every object the flags name: each `--capture`, and in it each
/// `--object` (or its only object).
pub fn load_objects(args: &Args) -> anyhow::Result<Vec<ObjectViews>> {
    let mut out = Vec::new();
    for dir in &args.capture {
        let mut cap = Capture::load(dir)?;
        if let Some(n) = args.max_views {
            if n == 0 {
                bail!("--max-views 0: the bake needs at least 1 training view");
            }
            cap.train.truncate(n);
        }
        if let Some(n) = args.max_test_views {
            cap.test.truncate(n);
        }
        if args.object.is_empty() {
            out.push(ObjectViews::from_capture(&cap, None)?);
        }
        for name in &args.object {
            out.push(ObjectViews::from_capture(&cap, Some(name))?);
        }
    }
    Ok(out)
}

fn lpips(args: &Args) -> anyhow::Result<Option<Lpips>> {
    let path = match &args.lpips_weights {
        Some(p) => Some(p.clone()),
        None => Lpips::default_path(),
    };
    match path {
        Some(p) => Ok(Some(Lpips::load(&p)?)),
        None => {
            eprintln!("LPIPS weights not found: LPIPS is left out (pass --lpips-weights FILE)");
            Ok(None)
        }
    }
}

fn base_params(args: &Args) -> BakeParams {
    let mut p = BakeParams::new(0, 0);
    p.frontal_power = args.frontal_power;
    p.voxel_test = args.voxel_test;
    p.geometry = args.geometry;
    p
}

/// Runs `nerflex bake`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.trained.choose_feature_res && args.trained.baker()? == super::bake_trained::Baker::Hull
    {
        bail!("--choose-feature-res chooses the trained baker's lattice: give --field, drop --baker hull");
    }
    if args.sweep {
        return run_sweep(&args);
    }
    if args.reports.compare.is_some()
        && args.trained.baker()? == super::bake_trained::Baker::Trained
    {
        bail!("--compare bakes with the hull baker only; drop --field/--baker trained");
    }
    if !args.configs.is_empty() && args.reports.compare.is_none() {
        bail!("--configs needs --sweep or --compare");
    }
    if let Some(out) = &args.reports.compare {
        return run_compare(&args, out);
    }
    let (g, p) = match (args.grid.as_slice(), args.patch.as_slice()) {
        ([g], [p]) => (*g, *p),
        _ => bail!("without --sweep, --grid and --patch take one value each"),
    };
    if args.out.is_none() && !args.measure {
        bail!("nothing to do: give --out DIR to write the asset and/or --measure");
    }
    // Refuse outputs we may not replace before any work.
    if let Some(out) = &args.out {
        crate::output::check_replaceable(
            out,
            &crate::asset::is_asset_file,
            "--out: an asset folder is replaced whole; move that away or choose another --out",
        )?;
    }
    if let Some(dir) = args.renders.as_ref().filter(|_| args.measure) {
        crate::output::check_replaceable(dir, &is_render_file, RENDERS_HINT)?;
    }
    let t0 = Instant::now();
    let baker = args.trained.baker()?;
    let object = args.object.first().map(String::as_str);
    // The field (hundreds of MB read and indexed on one core) loads beside
    // the capture's photos; the capture's errors come first.
    let args = &args;
    let (objects, field) = std::thread::scope(|sc| {
        let field = match (baker, args.capture.first()) {
            (super::bake_trained::Baker::Trained, Some(capture)) => {
                Some(sc.spawn(move || super::bake_trained::load(&args.trained, capture, object)))
            }
            _ => None,
        };
        let objects = load_objects(args);
        let field = field.map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
        (objects, field)
    });
    let objects = objects?;
    let [obj] = objects.as_slice() else {
        bail!("without --sweep, bake one object: give one --capture and at most one --object");
    };
    let field = field.transpose()?;
    let t_load = t0.elapsed().as_secs_f64();
    let mut params = base_params(args);
    params.grid = g;
    params.patch = p;
    params.search_box = obj.search_box;
    let t1 = Instant::now();
    let views = obj.bake_views();
    let baked = match &field {
        None => bake::bake(&views, &params)?,
        Some(field) => super::bake_trained::bake(&args.trained, field, &views, g, p)?,
    };
    let t_bake = t1.elapsed().as_secs_f64();
    let s = baked.stats;
    let (quads, pages, gpu_bytes) = (
        baked.quads.len(),
        baked.atlas.pages.len(),
        baked.gpu_bytes(),
    );
    let asset = baked.into_asset()?;
    let net = if args.measure { lpips(args)? } else { None };
    // Encoding (one deflate stream per PNG, so a core idles at its tail)
    // and the measurement run side by side. The files are built beside
    // --out and moved into place only after the measurement.
    let write = || -> anyhow::Result<_> {
        let t2 = Instant::now();
        let (staged, file_bytes) = match &args.out {
            Some(out) => {
                let (s, b) = asset.write_staged(out)?;
                (Some(s), b)
            }
            None => (None, bake::file_bytes(&asset)?),
        };
        Ok((staged, file_bytes, t2.elapsed().as_secs_f64()))
    };
    // The renders are kept for the holes below, and written on request.
    let measure = || {
        args.measure
            .then(|| obj.measure(&asset, &sweep::fixed_point_render, net.as_ref(), true))
            .transpose()
    };
    let (written, measured) = rayon::join(write, measure);
    let (staged, file_bytes, t_write) = written?;
    let measured = measured?;
    println!(
        "{}: g={g} p={p} from {} views: {quads} quads, {pages} atlas page pair(s), {} occupied voxels",
        obj.name,
        views.len(),
        s.occupied_voxels,
    );
    println!(
        "texels: {} seen (from {:.2} views each on average), {} unseen, {} empty",
        s.seen_texels,
        s.view_samples as f64 / s.seen_texels.max(1) as f64,
        s.unseen_texels,
        s.empty_texels
    );
    println!(
        "size: {file_bytes} file bytes ({:.1} MiB), {gpu_bytes} GPU bytes ({:.1} MiB)",
        file_bytes as f64 / 1048576.0,
        gpu_bytes as f64 / 1048576.0
    );
    println!(
        "time: bake {t_bake:.2} s (carve {:.2}, quads {:.2}, views {:.2}, colour {:.2}, atlas {:.2}), encode+write {t_write:.2} s{}, load {t_load:.2} s",
        s.times.carve_s, s.times.quads_s, s.times.views_s, s.times.colour_s, s.times.atlas_s,
        if args.measure { " beside the measurement" } else { "" }
    );
    if let Some(m) = measured {
        let (q, renders) = (m.mean, m.renders);
        for (i, v) in m.views.iter().enumerate() {
            println!("  test view {i}: {}", quality_line(v));
        }
        let mut holes = crate::metrics::Holes::default();
        for (img, (_, truth)) in renders.iter().zip(&obj.test) {
            holes = holes + crate::metrics::interior_holes(img, truth, HOLE_MARGIN)?;
        }
        println!(
            "holes: {} of {} interior object pixels not fully covered ({} not at all), {:.1} % of the squared error",
            holes.pixels,
            holes.interior,
            holes.empty,
            holes.error_share_percent()
        );
        if let Some(dir) = &args.renders {
            let stage = crate::output::StagedDir::new(dir)?;
            for (i, (img, (_, truth))) in renders.iter().zip(&obj.test).enumerate() {
                for (name, pic) in [("test", img), ("truth", truth)] {
                    let path = stage.path().join(format!("{name}_{i}.png"));
                    compare::over_white(pic, args.renders_size)
                        .save(&path)
                        .with_context(|| format!("{}: cannot write", path.display()))?;
                }
            }
            stage.commit(&is_render_file, RENDERS_HINT)?;
        }
        println!(
            "quality over {} test views: {}",
            obj.test.len(),
            quality_line(&q)
        );
    }
    if let (Some(out), Some(staged)) = (&args.out, staged) {
        crate::asset::commit_asset_dir(staged)?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

/// Photo pixels within this many of the photo's background are silhouette,
/// not interior, for the `holes:` line (a 7 × 7 window).
const HOLE_MARGIN: u32 = 3;

const RENDERS_HINT: &str =
    "--renders: the folder is replaced whole; move that away or choose another --renders";

/// `test_{i}.png` / `truth_{i}.png`: what `--renders` writes.
fn is_render_file(name: &str) -> bool {
    ["test_", "truth_"].iter().any(|p| {
        name.strip_prefix(p)
            .and_then(|r| r.strip_suffix(".png"))
            .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
    })
}

fn quality_line(q: &sweep::Quality) -> String {
    format!(
        "SSIM {:.4}, PSNR {:.2} dB{}",
        q.ssim,
        q.psnr,
        q.lpips.map_or(String::new(), |l| format!(", LPIPS {l:.4}"))
    )
}

/// `--compare`: bake each configuration, measure it on every test view,
/// and draw the ground truth of one view beside each render.
fn run_compare(args: &Args, out: &std::path::Path) -> anyhow::Result<()> {
    let objects = load_objects(args)?;
    let [obj] = objects.as_slice() else {
        bail!("--compare bakes one object: give one --capture and at most one --object");
    };
    let Some((_, truth)) = obj.test.get(args.reports.view) else {
        bail!(
            "--view {}: the capture has {} test views (0..{})",
            args.reports.view,
            obj.test.len(),
            obj.test.len()
        );
    };
    let net = lpips(args)?;
    let mut renders = Vec::new();
    let mut captions = Vec::new();
    for &(g, p) in &args.configs {
        let mut params = base_params(args);
        params.grid = g;
        params.patch = p;
        params.search_box = obj.search_box;
        let t = Instant::now();
        let baked = bake::bake(&obj.bake_views(), &params)?;
        let t_bake = t.elapsed().as_secs_f64();
        let (quads, gpu) = (baked.quads.len(), baked.gpu_bytes());
        let asset = baked.into_asset()?;
        let file = bake::file_bytes(&asset)?;
        let m = obj.measure(&asset, &sweep::fixed_point_render, net.as_ref(), true)?;
        println!(
            "{} g={g} p={p}: {quads} quads, {file} file bytes, {gpu} GPU bytes, bake {t_bake:.2} s",
            obj.name
        );
        for (i, v) in m.views.iter().enumerate() {
            let mark = if i == args.reports.view {
                "  (shown)"
            } else {
                ""
            };
            println!("  test view {i}: {}{mark}", quality_line(v));
        }
        println!(
            "  mean of {} views: {}",
            m.views.len(),
            quality_line(&m.mean)
        );
        let shown = m.views[args.reports.view];
        captions.push(vec![
            format!("g={g} p={p}: {quads} quads"),
            format!("SSIM {:.3}  PSNR {:.1} dB", shown.ssim, shown.psnr),
            shown
                .lpips
                .map_or(String::new(), |l| format!("LPIPS {l:.3}")),
        ]);
        let mut r = m.renders;
        renders.push(r.swap_remove(args.reports.view));
    }
    let mut tiles = vec![compare::Tile {
        image: truth,
        caption: vec![
            format!("{}: ground truth", obj.name),
            format!("test view {}", args.reports.view),
        ],
    }];
    for (img, caption) in renders.iter().zip(captions) {
        tiles.push(compare::Tile {
            image: img,
            caption,
        });
    }
    let pic = compare::strip(&tiles, Some(args.renders_size.unwrap_or(400)));
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
    }
    let mut png = std::io::Cursor::new(Vec::new());
    pic.write_to(&mut png, image::ImageFormat::Png)
        .with_context(|| format!("{}: cannot encode", out.display()))?;
    crate::output::write_file(out, png.get_ref())?;
    println!("wrote {}", out.display());
    Ok(())
}

fn run_sweep(args: &Args) -> anyhow::Result<()> {
    let objects = load_objects(args)?;
    let net = lpips(args)?;
    let cache_dir = args
        .cache
        .clone()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_CACHE));
    let opts = SweepOptions {
        configs: if args.configs.is_empty() {
            sweep::product(&args.grid, &args.patch)
        } else {
            args.configs.clone()
        },
        base: base_params(args),
        jobs: args.jobs,
        cache: (!args.no_cache).then(|| Cache::new(&cache_dir)),
        lpips: net.as_ref(),
        progress: true,
        trained: None,
    };
    // The trained baker: one field per object, in load_objects' order.
    let fields = match (args.trained.baker()?, &args.trained.field) {
        (super::bake_trained::Baker::Trained, Some(spec)) => {
            let mut v = Vec::new();
            let mut oi = 0;
            for dir in &args.capture {
                let names: Vec<Option<&str>> = if args.object.is_empty() {
                    vec![None]
                } else {
                    args.object.iter().map(|n| Some(n.as_str())).collect()
                };
                for name in names {
                    let obj_name = name.unwrap_or(objects[oi].name.as_str());
                    v.push(super::bake_trained::load_field_with_id(
                        spec, dir, obj_name,
                    )?);
                    oi += 1;
                }
            }
            Some(v)
        }
        _ => None,
    };
    let opts = SweepOptions {
        trained: fields.as_ref().map(|v| sweep::TrainedSweep {
            fields: v.iter().map(|(f, _)| f.as_ref()).collect(),
            field_ids: v.iter().map(|(_, id)| id.clone()).collect(),
            params: args.trained.params(0, 0),
            // Chosen unless fixed by --feature-res (the sweep bakes each
            // object many times; one choice serves them all).
            choose_lattice_at: args
                .trained
                .feature_res
                .is_none()
                .then_some(crate::bake::trained::lattice_choice::SWEEP_CONFIG),
        }),
        ..opts
    };
    let t0 = Instant::now();
    let report = sweep::run(&objects, &opts, &sweep::fixed_point_render)?;
    for l in &report.lattices {
        let scores: Vec<String> = l
            .candidates
            .iter()
            .map(|(c, ssim, psnr)| format!("{c}³ {ssim:.4} / {psnr:.2} dB"))
            .collect();
        println!(
            "{}: feature lattice {}³ chosen on held-back training views{} (the finest within {} SSIM of the best: {})",
            l.object,
            l.cells,
            if l.reused { ", from the cache" } else { "" },
            crate::bake::trained::lattice_choice::TIE_SSIM,
            scores.join(", ")
        );
    }
    if fields.is_some() && args.trained.feature_res.is_none() {
        for o in &objects {
            if !report.lattices.iter().any(|l| l.object == o.name) {
                println!(
                    "{}: default feature lattice kept: {} training views are too few to hold one back",
                    o.name,
                    o.train.len()
                );
            }
        }
    }
    sweep::write_csv(&args.csv, &report.samples)?;
    if let Some(dir) = &args.plots {
        for p in sweep::plot_objects(&report.samples, dir)? {
            println!("wrote {}", p.display());
        }
    }
    if let Some(path) = &args.reports.table {
        let text = sweep::markdown_table(&report.samples, &args.reports.table_configs);
        crate::asset::write_atomic(path, text.as_bytes())
            .with_context(|| format!("{}: cannot write", path.display()))?;
        println!("wrote {}", path.display());
    }
    let breaks = sweep::monotonicity_report(&report.samples, 0.0);
    println!(
        "{} neighbouring configuration pairs where size does not grow or SSIM falls{}",
        breaks.len(),
        if breaks.is_empty() { "" } else { ":" }
    );
    for b in &breaks {
        println!("  {b}");
    }
    let m = sweep::monotonicity_summary(&report.samples);
    for (what, st) in [("g", &m.g), ("p", &m.p)] {
        println!(
            "next {what}: {} pairs, size grows in {}, SSIM falls in {} ({} by more than 0.001), largest drop {:.6}{}",
            st.pairs,
            st.size_grows,
            st.ssim_falls,
            st.ssim_falls_over_1e3,
            st.max_ssim_drop,
            st.max_drop_at
                .as_ref()
                .map_or(String::new(), |s| format!(" at {s}"))
        );
    }
    println!(
        "{} samples ({} baked, {} reused from {}) in {:.1} s → {}",
        report.samples.len(),
        report.baked,
        report.reused,
        cache_dir.display(),
        t0.elapsed().as_secs_f64(),
        args.csv.display()
    );
    Ok(())
}
