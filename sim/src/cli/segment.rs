//! `nerflex segment`: detail-based segmentation of a multi-object capture.

use crate::segment::compose::{compose_dirs, resize_capture};
use crate::segment::{
    segment, AlphaSource, EnlargeOptions, FrequencyOptions, SegCapture, SegmentOptions,
    Segmentation,
};
use anyhow::Context;
use image::imageops::FilterType;
use std::path::PathBuf;

/// Flags of `nerflex segment`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["capture", "compose"])))]
pub struct Args {
    /// Capture folder (NeRF-synthetic layout, instance masks or alpha).
    #[arg(long, value_name = "DIR")]
    pub capture: Option<PathBuf>,
    /// Compose separate captures side by side into one multi-object capture
    /// (e.g. the real lego and chair), each source's alpha as its mask.
    #[arg(long, value_name = "DIR,DIR", value_delimiter = ',', num_args = 1..)]
    pub compose: Vec<PathBuf>,
    /// Resize the input first: each composed source to SIZE×SIZE, or a
    /// capture to SIZE pixels wide (aspect kept).
    #[arg(long, value_name = "PIXELS")]
    pub size: Option<u32>,
    /// Threshold α in cycles per object diameter: objects whose maximum
    /// frequency exceeds it get a dedicated NeRF (default: the lowest
    /// maximum, so every object gets a network).
    #[arg(long, value_name = "X")]
    pub alpha: Option<f64>,
    /// Share of spectral energy below the reported frequency.
    #[arg(long, default_value_t = 0.75, value_name = "SHARE")]
    pub energy_share: f64,
    /// Band of frequencies counted, cycles per object diameter (`inf`: up to
    /// the pixel grid, which makes values depend on the image size).
    #[arg(long, default_value_t = 32.0, value_name = "CYCLES")]
    pub band: f64,
    /// Views where an object covers fewer pixels give no frequency.
    #[arg(long, default_value_t = 64, value_name = "PIXELS")]
    pub min_pixels: u32,
    /// Border added around an object's mask box before enlarging, as a
    /// fraction of the box's longer side.
    #[arg(long, default_value_t = 0.0, value_name = "FRACTION")]
    pub margin: f32,
    /// Interpolation of the enlargement.
    #[arg(long, value_enum, default_value_t = Filter::Lanczos3)]
    pub filter: Filter,
    /// Output folder: one training folder per network and segmentation.json.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// Interpolation filters for the enlargement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Filter {
    /// Lanczos with 3 lobes.
    Lanczos3,
    /// Catmull–Rom (bicubic).
    CatmullRom,
}

/// Runs `nerflex segment`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.energy_share > 0.0 && args.energy_share < 1.0) {
        anyhow::bail!(
            "--energy-share {}: must lie strictly between 0 and 1",
            args.energy_share
        );
    }
    if args.band.is_nan() || args.band <= 0.0 {
        anyhow::bail!(
            "--band {}: must be a positive number of cycles per object diameter (or inf)",
            args.band
        );
    }
    if !(args.margin.is_finite() && args.margin >= 0.0) {
        anyhow::bail!("--margin {}: must be a finite fraction ≥ 0", args.margin);
    }
    if args.size == Some(0) {
        anyhow::bail!("--size 0: must be a positive number of pixels");
    }
    let cap = load(&args)?;
    let opts = SegmentOptions {
        alpha: args.alpha,
        frequency: FrequencyOptions {
            energy_share: args.energy_share,
            min_pixels: args.min_pixels,
            band: args.band.is_finite().then_some(args.band),
            ..FrequencyOptions::default()
        },
        enlarge: EnlargeOptions {
            filter: match args.filter {
                Filter::Lanczos3 => FilterType::Lanczos3,
                Filter::CatmullRom => FilterType::CatmullRom,
            },
            margin: args.margin,
        },
    };
    let seg =
        segment(&cap, &opts, &args.out).with_context(|| format!("segmenting {}", cap.source))?;
    // Written (not `print!`ed) so a closed pipe is an error, not a panic.
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    write!(out, "{}", table(&seg))?;
    writeln!(
        out,
        "wrote {} ({} network{}) in {:.2} s (analysis {:.2} s, views {:.2} s)",
        args.out.join(crate::segment::SEGMENTATION_FILE).display(),
        seg.groups.len(),
        if seg.groups.len() == 1 { "" } else { "s" },
        seg.timings.total_s,
        seg.timings.analyse_s,
        seg.timings.views_s
    )?;
    Ok(())
}

fn load(args: &Args) -> anyhow::Result<SegCapture> {
    if !args.compose.is_empty() {
        let dirs: Vec<&std::path::Path> = args.compose.iter().map(|p| p.as_path()).collect();
        return compose_dirs(&dirs, args.size).context("--compose");
    }
    let dir = args
        .capture
        .as_ref()
        .context("give --capture DIR or --compose DIR,DIR")?;
    let cap = SegCapture::load(dir).with_context(|| format!("--capture {}", dir.display()))?;
    match args.size {
        Some(w) => {
            let (w0, h0) = cap.image_size();
            let h = ((h0 as u64 * w as u64 + w0 as u64 / 2) / w0.max(1) as u64).max(1) as u32;
            Ok(resize_capture(&cap, w, h)?)
        }
        None => Ok(cap),
    }
}

/// The table `nerflex segment` prints: objects by decreasing frequency.
pub fn table(seg: &Segmentation) -> String {
    let mut rows: Vec<&crate::segment::output::ObjectRecord> = seg.objects.iter().collect();
    rows.sort_by(|a, b| b.max_frequency.total_cmp(&a.max_frequency));
    let name_w = rows.iter().map(|o| o.name.len()).max().unwrap_or(6).max(6);
    let peak_w = rows
        .iter()
        .map(|o| o.peak_image.len())
        .max()
        .unwrap_or(10)
        .max(10);
    let mut s = format!(
        "{:<name_w$}  {:>10}  {:<peak_w$}  {:<9}  folder\n",
        "object", "max freq", "peak image", "decision"
    );
    for o in rows {
        s += &format!(
            "{:<name_w$}  {:>10.2}  {:<peak_w$}  {:<9}  {}\n",
            o.name,
            o.max_frequency,
            o.peak_image,
            match o.decision {
                crate::segment::Decision::Dedicated => "dedicated",
                crate::segment::Decision::Shared => "shared",
            },
            o.folder
        );
    }
    s += &format!(
        "frequencies in {}; α = {:.2} ({})\n",
        seg.measure.unit,
        seg.alpha,
        match seg.alpha_source {
            AlphaSource::User => "--alpha",
            AlphaSource::LowestMaximum => "default: the lowest maximum",
        }
    );
    s
}
