//! `nerflex scene`: built-in captures in the NeRF-synthetic layout.

use crate::procedural::{
    arrange, complexity_quads, make_capture, portrait, ranked, CaptureSpec, Layout, ObjectKind,
    Preset, RenderOptions, COMPLEXITY_GRID,
};
use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

/// Flags of `nerflex scene`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Render a capture (RGBA views, instance masks, transforms, scene.json).
    Make(MakeArgs),
    /// List the procedural objects with their geometric complexity.
    List,
    /// Write a small portrait PNG of every object (for the documentation).
    Pictures(PicturesArgs),
}

/// Flags of `nerflex scene make`.
#[derive(Debug, clap::Args)]
struct MakeArgs {
    /// Objects by name, comma-separated (see `nerflex scene list`).
    #[arg(
        long,
        value_delimiter = ',',
        required_unless_present = "preset",
        conflicts_with = "preset"
    )]
    objects: Vec<ObjectKind>,
    /// One of the paper's scenes: scene1 (5 simplest), scene2 (5 most
    /// complex), scene3 (5 at random, fixed seed), scene4 (5 spread over the
    /// complexity range).
    #[arg(long)]
    preset: Option<Preset>,
    /// Arrangement of several objects: row, ring or random.
    #[arg(long, default_value = "ring")]
    layout: Layout,
    /// Seed of the random layout and of the cameras.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Training views.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    views: u32,
    /// Held-out test views.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=10_000))]
    test_views: u32,
    /// Image width and height, pixels.
    #[arg(long, default_value_t = 400, value_parser = clap::value_parser!(u32).range(8..=8192))]
    size: u32,
    /// Output folder (created; existing frames are replaced file by file).
    #[arg(long)]
    out: PathBuf,
    /// Texture frequency multiplier (1 = each object's nominal detail).
    #[arg(long, default_value_t = 1.0)]
    detail: f32,
    /// Draft quality: no supersampling, shadows or ambient occlusion.
    #[arg(long)]
    draft: bool,
}

/// Flags of `nerflex scene pictures`.
#[derive(Debug, clap::Args)]
struct PicturesArgs {
    /// Picture width and height, pixels.
    #[arg(long, default_value_t = 160, value_parser = clap::value_parser!(u32).range(16..=2048))]
    size: u32,
    /// Output folder; writes `<object>.png` for every object and
    /// `all-objects.png`, a contact sheet of them in complexity order.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `nerflex scene`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Make(a) => make(a),
        Command::List => {
            list();
            Ok(())
        }
        Command::Pictures(a) => pictures(a),
    }
}

fn make(a: MakeArgs) -> anyhow::Result<()> {
    if !(a.detail.is_finite() && a.detail > 0.0 && a.detail <= 100.0) {
        bail!("--detail {}: must be a number in (0, 100]", a.detail);
    }
    let kinds = match a.preset {
        Some(p) => p.kinds(),
        None => a.objects.clone(),
    };
    if kinds.is_empty() {
        bail!("--objects: give at least one object name (see `nerflex scene list`)");
    }
    if kinds.len() > 255 {
        bail!(
            "--objects: {} objects, a scene holds at most 255",
            kinds.len()
        );
    }
    let objects = arrange(&kinds, a.layout, a.seed, a.detail);
    let render = if a.draft {
        RenderOptions {
            edge_samples: 0,
            texture_samples: 0,
            shadows: false,
            ambient_occlusion: false,
            ..RenderOptions::default()
        }
    } else {
        RenderOptions::default()
    };
    let layout = if kinds.len() == 1 {
        "single"
    } else {
        a.layout.name()
    };
    let spec = CaptureSpec {
        objects,
        layout: layout.into(),
        preset: a.preset,
        seed: a.seed,
        train_views: a.views as usize,
        test_views: a.test_views as usize,
        size: a.size,
        render,
    };
    let bar = ProgressBar::new(u64::from(a.views + a.test_views));
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} rendering [{bar:32}] {pos}/{len} views  {elapsed_precise}",
        )
        .context("progress bar template")?
        .progress_chars("=> "),
    );
    let report = make_capture(&spec, &a.out, &|| bar.inc(1))
        .with_context(|| format!("writing capture to {}", a.out.display()))?;
    bar.finish_and_clear();
    let name = a
        .preset
        .map_or_else(|| "scene".to_string(), |p| p.name().to_string());
    println!(
        "{name}: {} object(s), layout {layout}, seed {}, {} train + {} test views at {}×{} → {}",
        report.scene.objects.len(),
        a.seed,
        a.views,
        a.test_views,
        a.size,
        a.size,
        report.dir.display()
    );
    println!(
        "  {:>4}  {:<11} {:>10}  {:>9}  world bounds (min → max)",
        "mask",
        "object",
        format!("quads@{COMPLEXITY_GRID}"),
        "tex cyc/u"
    );
    for o in &report.scene.objects {
        let f = |v: [f64; 3]| format!("({:+.2}, {:+.2}, {:+.2})", v[0], v[1], v[2]);
        println!(
            "  {:>4}  {:<11} {:>10}  {:>9.1}  {} → {}",
            o.mask_value,
            o.name,
            o.complexity_quads.unwrap_or(0),
            o.texture_frequency.unwrap_or(0.0),
            f(o.bounds_min),
            f(o.bounds_max)
        );
    }
    println!(
        "rendered and wrote {} views in {:.2} s ({:.3} s/view, {} threads)",
        report.views,
        report.seconds,
        report.seconds / report.views.max(1) as f64,
        rayon::current_num_threads()
    );
    Ok(())
}

fn list() {
    println!(
        "{:<11} {:>10}  {:>9}  description",
        "object",
        format!("quads@{COMPLEXITY_GRID}"),
        "tex cyc/u"
    );
    for (k, q) in ranked() {
        println!(
            "{:<11} {:>10}  {:>9.1}  {}",
            k.name(),
            q,
            k.texture_frequency(),
            k.description()
        );
    }
    println!();
    for p in Preset::ALL {
        let names: Vec<&str> = p.kinds().iter().map(|k| k.name()).collect();
        println!("{}: {}", p.name(), names.join(", "));
    }
}

fn pictures(a: PicturesArgs) -> anyhow::Result<()> {
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let order: Vec<ObjectKind> = ranked().into_iter().map(|(k, _)| k).collect();
    let cols = 6u32;
    let rows = (order.len() as u32).div_ceil(cols);
    let mut sheet =
        image::RgbaImage::from_pixel(cols * a.size, rows * a.size, image::Rgba([255; 4]));
    for (i, &k) in order.iter().enumerate() {
        let img = portrait(k, a.size);
        let (x, y) = ((i as u32 % cols) * a.size, (i as u32 / cols) * a.size);
        image::imageops::overlay(&mut sheet, &img, i64::from(x), i64::from(y));
        let path = a.out.join(format!("{}.png", k.name()));
        crate::capture::write_png(&path, &image::DynamicImage::ImageRgba8(img))?;
        println!(
            "{}  ({} quads@{COMPLEXITY_GRID})",
            path.display(),
            complexity_quads(k)
        );
    }
    let path = a.out.join("all-objects.png");
    crate::capture::write_png(&path, &image::DynamicImage::ImageRgba8(sheet))?;
    println!("{}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::Capture;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(subcommand)]
        cmd: Top,
    }

    #[derive(clap::Subcommand)]
    enum Top {
        Scene(Args),
    }

    fn parse(args: &[&str]) -> Result<Args, clap::Error> {
        Cli::try_parse_from(std::iter::once("nerflex").chain(args.iter().copied())).map(|c| match c
            .cmd
        {
            Top::Scene(a) => a,
        })
    }

    #[test]
    fn make_accepts_the_documented_flags_and_writes_a_capture() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s4");
        let o = out.to_str().unwrap();
        run(parse(&[
            "scene",
            "make",
            "--preset",
            "scene4",
            "--views",
            "2",
            "--test-views",
            "1",
            "--size",
            "24",
            "--out",
            o,
        ])
        .unwrap())
        .unwrap();
        let c = Capture::load(&out).unwrap();
        assert_eq!((c.train.len(), c.test.len(), c.size()), (2, 1, (24, 24)));
        let s = c.scene.unwrap();
        assert_eq!(s.preset.as_deref(), Some("scene4"));
        assert_eq!(s.objects.len(), 5);

        let out2 = dir.path().join("two");
        let o2 = out2.to_str().unwrap();
        run(parse(&[
            "scene",
            "make",
            "--objects",
            "gear,ball",
            "--layout",
            "random",
            "--seed",
            "7",
            "--views",
            "1",
            "--size",
            "16",
            "--out",
            o2,
            "--draft",
        ])
        .unwrap())
        .unwrap();
        let c = Capture::load(&out2).unwrap();
        let s = c.scene.unwrap();
        assert_eq!(s.layout.as_deref(), Some("random"));
        assert_eq!(s.seed, Some(7));
        assert_eq!(
            s.objects
                .iter()
                .map(|o| o.name.as_str())
                .collect::<Vec<_>>(),
            ["gear", "ball"]
        );
    }

    #[test]
    fn bad_flags_name_the_flag_and_the_problem() {
        let e = parse(&["scene", "make", "--objects", "teapot", "--out", "x"])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("teapot") && e.contains("known objects") && e.contains("--objects"),
            "{e}"
        );
        let e = parse(&["scene", "make", "--preset", "scene9", "--out", "x"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("scene9") && e.contains("--preset"), "{e}");
        let e = parse(&[
            "scene",
            "make",
            "--objects",
            "ball",
            "--preset",
            "scene1",
            "--out",
            "x",
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("cannot be used with"), "{e}");
        let e = parse(&["scene", "make", "--out", "x"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("--objects") || e.contains("--preset"), "{e}");
        let e = parse(&[
            "scene",
            "make",
            "--objects",
            "ball",
            "--views",
            "0",
            "--out",
            "x",
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("--views"), "{e}");
        let e = parse(&[
            "scene",
            "make",
            "--objects",
            "ball",
            "--layout",
            "spiral",
            "--out",
            "x",
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("spiral") && e.contains("ring"), "{e}");
        let e = run(parse(&[
            "scene",
            "make",
            "--objects",
            "ball",
            "--detail=-1",
            "--out",
            "x",
        ])
        .unwrap())
        .unwrap_err()
        .to_string();
        assert!(e.contains("--detail"), "{e}");
    }
}
