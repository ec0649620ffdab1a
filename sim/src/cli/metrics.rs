//! `nerflex metrics A.png B.png [--lpips-weights FILE] [--json]`: SSIM, PSNR
//! and LPIPS of two images composited over white.

use crate::metrics::{self, format_psnr, Lpips, Metrics, Scores};
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `nerflex metrics`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// First image (PNG, RGBA or RGB; composited over white).
    #[arg(value_name = "A.png")]
    pub a: PathBuf,
    /// Second image, same size as the first.
    #[arg(value_name = "B.png")]
    pub b: PathBuf,
    /// LPIPS AlexNet weights (safetensors). Default: the shared data folder's
    /// `lpips/alexnet_lpips_v0.1.safetensors`; LPIPS is skipped if absent.
    #[arg(long, value_name = "FILE")]
    pub lpips_weights: Option<PathBuf>,
    /// Print one JSON object instead of text (PSNR of identical images: null).
    #[arg(long)]
    pub json: bool,
}

/// Runs `nerflex metrics`.
pub fn run(args: Args) -> anyhow::Result<()> {
    print!("{}", report(&args)?);
    Ok(())
}

/// What `nerflex metrics` prints, as a string (text or JSON, per `--json`).
pub fn report(args: &Args) -> anyhow::Result<String> {
    let a = metrics::read_png(&args.a)?;
    let b = metrics::read_png(&args.b)?;
    if a.dimensions() != b.dimensions() {
        anyhow::bail!(
            "{} is {}×{} but {} is {}×{}: the images must have the same size",
            args.a.display(),
            a.width(),
            a.height(),
            args.b.display(),
            b.width(),
            b.height()
        );
    }
    let (lpips, skipped) = match &args.lpips_weights {
        Some(path) => (Some(Lpips::load(path)?), None),
        None => match Lpips::default_path() {
            Some(path) => (Some(Lpips::load(path)?), None),
            None => (
                None,
                Some(format!(
                    "LPIPS weights not found (no lpips/{} in the shared data folder; \
                     set {} or pass --lpips-weights FILE)",
                    metrics::LPIPS_WEIGHTS_FILE,
                    crate::data::DATA_ENV
                )),
            ),
        },
    };
    let scores = Metrics::compare(&a, &b, lpips.as_ref())
        .with_context(|| format!("comparing {} with {}", args.a.display(), args.b.display()))?;
    let weights = lpips.as_ref().map(|l| l.path().to_owned());
    Ok(if args.json {
        json_report(args, a.dimensions(), &scores, weights, skipped)? + "\n"
    } else {
        text_report(args, a.dimensions(), &scores, weights, skipped)
    })
}

fn text_report(
    args: &Args,
    (w, h): (u32, u32),
    s: &Scores,
    weights: Option<PathBuf>,
    skipped: Option<String>,
) -> String {
    let mut out = format!(
        "A      {}\nB      {}  ({w}×{h}, composited over white)\nSSIM   {:.6}\nPSNR   {} dB\n",
        args.a.display(),
        args.b.display(),
        s.ssim,
        format_psnr(s.psnr)
    );
    match (s.lpips, weights, skipped) {
        (Some(l), Some(path), _) => {
            out += &format!("LPIPS  {l:.6}  (AlexNet v0.1, {})\n", path.display())
        }
        (_, _, Some(why)) => out += &format!("LPIPS  skipped: {why}\n"),
        _ => {}
    }
    out
}

fn json_report(
    args: &Args,
    (w, h): (u32, u32),
    s: &Scores,
    weights: Option<PathBuf>,
    skipped: Option<String>,
) -> anyhow::Result<String> {
    // serde_json writes non-finite floats as null: PSNR of identical images.
    let v = serde_json::json!({
        "a": args.a,
        "b": args.b,
        "width": w,
        "height": h,
        "ssim": s.ssim,
        "psnr": s.psnr,
        "lpips": s.lpips,
        "lpips_weights": weights,
        "lpips_skipped": skipped,
    });
    Ok(serde_json::to_string_pretty(&v)?)
}
