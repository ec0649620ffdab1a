//! `nerflex bake`: bake MobileNeRF-format assets from a posed capture, one
//! (g, p) or a sweep, optionally measured against the held-out views.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _};

use crate::bake::{self, export, BakeParams, BakeView, Silhouette};
use crate::camera::{Camera, Transforms};

/// Flags of `nerflex bake`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Capture folder in the NeRF-synthetic layout (`transforms_train.json`, …).
    #[arg(long)]
    pub capture: PathBuf,
    /// Grid g (voxels per edge); with `--sweep`, a comma-separated list.
    #[arg(long, value_delimiter = ',', required = true)]
    pub grid: Vec<u32>,
    /// Patch p (texels per quad edge); with `--sweep`, a comma-separated list.
    #[arg(long, value_delimiter = ',', required = true)]
    pub patch: Vec<u32>,
    /// Output folder of the asset (MobileNeRF export layout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Use only the first N training views.
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Exponent k of the frontal weighting cos(θ)^k.
    #[arg(long, default_value_t = 4.0)]
    pub frontal_power: f32,
}

/// A loaded capture: training views (camera, image).
struct Loaded {
    cameras: Vec<Camera>,
    images: Vec<image::RgbaImage>,
}

/// Reads the training split of a NeRF-synthetic folder.
fn load_train(dir: &Path, max_views: Option<usize>) -> anyhow::Result<Loaded> {
    let tpath = dir.join("transforms_train.json");
    let t = Transforms::read(&tpath)?;
    let n = max_views.unwrap_or(usize::MAX).min(t.frames.len());
    let mut cameras = Vec::new();
    let mut images = Vec::new();
    for i in 0..n {
        let f = &t.frames[i];
        let p = dir.join(format!("{}.png", f.file_path));
        let img = image::open(&p)
            .with_context(|| format!("{}: cannot read image", p.display()))?
            .to_rgba8();
        let cam = t
            .camera(i, img.width(), img.height())
            .with_context(|| format!("{}: frame {i} missing", tpath.display()))?;
        cameras.push(cam);
        images.push(img);
    }
    Ok(Loaded { cameras, images })
}

/// Runs `nerflex bake`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (&g, &p) = match (args.grid.as_slice(), args.patch.as_slice()) {
        ([g], [p]) => (g, p),
        _ => bail!("--grid and --patch take one value each without --sweep"),
    };
    let t0 = Instant::now();
    let cap = load_train(&args.capture, args.max_views)?;
    let views: Vec<BakeView<'_>> = cap
        .cameras
        .iter()
        .zip(&cap.images)
        .map(|(c, i)| BakeView {
            camera: *c,
            image: i,
            silhouette: Silhouette::Alpha,
        })
        .collect();
    let t_load = t0.elapsed().as_secs_f64();
    let mut params = BakeParams::new(g, p);
    params.frontal_power = args.frontal_power;
    let t1 = Instant::now();
    let obj = bake::bake(&views, &params)?;
    let t_bake = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let files = export::encode(&obj)?;
    let t_encode = t2.elapsed().as_secs_f64();
    if let Some(out) = &args.out {
        export::write(&files, out)?;
    }
    let s = &obj.stats;
    println!(
        "baked g={g} p={p} from {} views: {} quads, {} pages, {} occupied voxels, {} seen / {} unseen texels",
        views.len(),
        obj.quads.len(),
        obj.atlas.pages.len(),
        s.occupied_voxels,
        s.seen_texels,
        s.unseen_texels
    );
    println!(
        "file bytes {} , GPU bytes {}",
        export::file_bytes(&files),
        obj.gpu_bytes()
    );
    println!(
        "time: load {t_load:.2} s, carve {:.2} s, quads {:.2} s, views {:.2} s, texels {:.2} s, encode {t_encode:.2} s",
        s.times.carve_s, s.times.quads_s, s.times.views_s, s.times.texels_s
    );
    Ok(())
}
