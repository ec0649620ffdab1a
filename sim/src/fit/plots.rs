//! Fitted curves over the measured points, one picture per object and curve.
//!
//! `<object>_ssim.png` and `<object>_size.png`: the quantity against g (log₂
//! axis; size on a log₁₀ axis), one colour per p; dots are measurements, lines the fitted profile
//! evaluated in fixed point (`nerflex_core::profiler`) on a dense g grid.

use super::object::ObjectFit;
use super::samples::Sample;
use crate::plot::{Chart, LegendPosition, PlotError, Scale, Series, PALETTE};
use nerflex_core::profiler::Profile;
use std::path::{Path, PathBuf};

/// Dense g values from `lo` to `hi` (geometric, 48 steps, integers).
fn dense(lo: u32, hi: u32) -> Vec<u32> {
    let (l, h) = (lo.max(1) as f64, hi.max(lo).max(1) as f64);
    let mut v: Vec<u32> = (0..=48)
        .map(|i| (l * (h / l).powf(i as f64 / 48.0)).round() as u32)
        .collect();
    v.dedup();
    v
}

/// A file-name-safe version of an object name.
fn slug(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Draws `<dir>/<object>_ssim.png` and `<dir>/<object>_size.png`; returns
/// the paths written.
pub fn draw(fit: &ObjectFit, samples: &[&Sample], dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    let mut patches: Vec<u32> = samples.iter().map(|s| s.p).collect();
    patches.sort_unstable();
    patches.dedup();
    let profile: Option<Profile> = fit.profile().ok();
    let gs = dense(fit.domain.g_min, fit.domain.g_max);
    let mut ssim = Chart::new(format!(
        "{}: SSIM vs grid (dots measured, lines fitted)",
        fit.name
    ))
    .x_label("grid g (voxels per axis)")
    .y_label("SSIM")
    .x_log2()
    .legend(LegendPosition::BottomRight);
    let mut size = Chart::new(format!(
        "{}: size vs grid (dots measured, lines fitted)",
        fit.name
    ))
    .x_label("grid g (voxels per axis)")
    .y_label("size (MB, log scale)")
    .x_log2()
    .y_scale(Scale::Log10)
    .legend(LegendPosition::TopLeft);
    for (i, &p) in patches.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let measured = samples.iter().filter(|s| s.p == p);
        ssim = ssim.series(
            Series::scatter(
                format!("p = {p}"),
                measured.clone().map(|s| (s.g as f64, s.ssim)),
            )
            .color(color),
        );
        size = size.series(
            Series::scatter(
                format!("p = {p}"),
                measured.map(|s| (s.g as f64, s.size.as_mb())),
            )
            .color(color),
        );
        if let Some(prof) = &profile {
            let curve = gs
                .iter()
                .filter_map(|&g| prof.config(g, p).ok().map(|c| (g, c)));
            ssim = ssim.series(
                Series::line(
                    "",
                    curve.clone().map(|(g, c)| (g as f64, c.quality.to_f64())),
                )
                .color(color),
            );
            size = size.series(
                Series::line("", curve.map(|(g, c)| (g as f64, c.size.as_mb()))).color(color),
            );
        }
    }
    let base = dir.join(slug(&fit.name));
    let ssim_path = base.with_file_name(format!("{}_ssim.png", slug(&fit.name)));
    let size_path = base.with_file_name(format!("{}_size.png", slug(&fit.name)));
    ssim.save(&ssim_path)?;
    size.save(&size_path)?;
    Ok(vec![ssim_path, size_path])
}
