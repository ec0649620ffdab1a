//! The evaluation's figures (small PNGs), drawn from the report.

use super::{EvalReport, Row, SceneReport, METHODS};
use crate::baselines::Method;
use crate::plot::{BarChart, Chart, LegendPosition, Series, PALETTE};
use anyhow::Context as _;
use nerflex_core::units::Bytes;
use std::path::Path;

/// Picture size (pixels).
const SIZE: (u32, u32) = (640, 360);

/// The label of a method in figures and tables.
pub fn method_label(m: Method) -> &'static str {
    match m {
        Method::Single => "Single-NeRF",
        Method::Block => "Block-NeRF",
        Method::Dp => "NeRFlex (DP)",
        Method::Fairness => "Fairness",
        Method::Slsqp => "SLSQP",
        Method::Greedy => "Greedy",
        Method::Brute => "Brute force",
    }
}

fn color(m: Method) -> crate::plot::Rgb {
    let i = METHODS.iter().position(|x| *x == m).unwrap_or(5);
    PALETTE[i % PALETTE.len()]
}

/// The row of (scene, device, method).
pub fn find<'a>(s: &'a SceneReport, device: &str, m: Method) -> Option<&'a Row> {
    s.rows.iter().find(|r| r.device == device && r.method == m)
}

fn devices(r: &EvalReport) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for s in &r.scenes {
        for row in &s.rows {
            if !v.contains(&row.device) {
                v.push(row.device.clone());
            }
        }
    }
    v
}

/// Draws every figure into `out`; returns (file name, caption) pairs.
pub fn draw(r: &EvalReport, out: &Path) -> anyhow::Result<Vec<(String, String)>> {
    let mut files = Vec::new();
    let mut save = |name: String, caption: String, draw: &dyn Fn(&Path) -> anyhow::Result<()>| {
        let path = out.join(&name);
        draw(&path).with_context(|| format!("drawing {}", path.display()))?;
        files.push((name, caption));
        anyhow::Ok(())
    };
    let scenes: Vec<String> = r.scenes.iter().map(|s| s.scene.clone()).collect();
    for d in devices(r) {
        let bars = |title: String, y: &str, methods: &[Method], f: &dyn Fn(&Row) -> Option<f64>| {
            let mut c = BarChart::new(title)
                .categories(scenes.clone())
                .y_label(y)
                .legend(LegendPosition::TopRight)
                .size(SIZE.0, SIZE.1);
            for &m in methods {
                let vals: Vec<f64> = r
                    .scenes
                    .iter()
                    .map(|s| find(s, &d, m).and_then(f).unwrap_or(f64::NAN))
                    .collect();
                c = c.series_colored(method_label(m), vals, color(m));
            }
            c
        };
        let ssim = |row: &Row| row.quality.map(|q| q.ssim);
        let c = bars(
            format!("Whole-scene SSIM on {d}"),
            "SSIM",
            &[Method::Single, Method::Block, Method::Dp],
            &ssim,
        )
        .y_range(0.5, 1.0);
        save(
            format!("quality_{d}.png"),
            format!("SSIM of the whole scene on its held-out views, {d} budget"),
            &|p| Ok(c.save(p)?),
        )?;
        let c = bars(
            format!("Data size on {d} (MB)"),
            "MB",
            &[Method::Single, Method::Block, Method::Dp],
            &|row| (row.file_bytes > 0).then(|| Bytes(row.file_bytes).as_mb()),
        );
        save(
            format!("size_{d}.png"),
            format!(
                "baked data per scene on {d} (budget {:.0} MB)",
                budget_mb(r, &d)
            ),
            &|p| Ok(c.save(p)?),
        )?;
        let c = bars(
            format!("Configuration selectors on {d}: SSIM"),
            "SSIM",
            &[Method::Dp, Method::Fairness, Method::Slsqp],
            &ssim,
        )
        .y_range(0.5, 1.0);
        save(
            format!("selectors_{d}.png"),
            format!("whole-scene SSIM of the three selectors on {d}"),
            &|p| Ok(c.save(p)?),
        )?;
        // FPS curves (the paper's FPS figure).
        let curves: Vec<_> = r.fps.iter().filter(|c| c.device == d).collect();
        if !curves.is_empty() {
            let mut chart = Chart::new(format!("{} on {d}: real-time FPS", curves[0].scene))
                .x_label("frame")
                .y_label("FPS")
                .legend(LegendPosition::TopRight)
                .size(SIZE.0, SIZE.1);
            let mut top: f64 = 1.0;
            for c in &curves {
                if !matches!(c.method, Method::Dp | Method::Single | Method::Block) {
                    continue;
                }
                let col = color(c.method);
                let label = if c.load_failure.is_some() {
                    format!("{} (fails to load)", method_label(c.method))
                } else {
                    method_label(c.method).to_string()
                };
                chart = chart
                    .series(
                        Series::line(label, c.fps.iter().enumerate().map(|(i, &v)| (i as f64, v)))
                            .color(col)
                            .width(1.0),
                    )
                    .series(
                        Series::horizontal(format!("mean {:.1}", c.mean_fps), c.mean_fps)
                            .dashed()
                            .color(col),
                    );
                top = c.fps.iter().copied().fold(top, f64::max);
            }
            let frames = curves.iter().map(|c| c.fps.len()).max().unwrap_or(1);
            let chart = chart
                .x_range(0.0, frames.saturating_sub(1).max(1) as f64)
                .y_range(0.0, (top * 1.1).ceil());
            save(
                format!("fps_{d}.png"),
                format!("per-frame FPS of {} on {d}; dashed: means", curves[0].scene),
                &|p| Ok(chart.save(p)?),
            )?;
        }
    }
    // Scene 4 per object.
    if let Some(s4) = r.scenes.iter().find(|s| s.scene == "scene4") {
        let names: Vec<String> = s4.networks.iter().map(|(n, _)| n.clone()).collect();
        for d in devices(r) {
            let per_object =
                |title: String, y: &str, f: &dyn Fn(&crate::pipeline::RealisedObject) -> f64| {
                    let mut c = BarChart::new(title)
                        .categories(names.clone())
                        .y_label(y)
                        .legend(LegendPosition::TopRight)
                        .size(SIZE.0, SIZE.1);
                    for m in [Method::Dp, Method::Fairness, Method::Slsqp] {
                        let vals: Vec<f64> = names
                            .iter()
                            .map(|n| {
                                find(s4, &d, m)
                                    .and_then(|row| row.objects.iter().find(|o| &o.name == n))
                                    .map_or(f64::NAN, f)
                            })
                            .collect();
                        c = c.series_colored(method_label(m), vals, color(m));
                    }
                    c
                };
            let c = per_object(format!("Scene 4 per network on {d}: SSIM"), "SSIM", &|o| {
                o.ssim
            });
            save(
                format!("scene4_ssim_{d}.png"),
                format!("Scene 4: each network's SSIM on its own held-out views, {d}"),
                &|p| Ok(c.save(p)?),
            )?;
            let c = per_object(format!("Scene 4 per network on {d}: MB"), "MB", &|o| {
                Bytes(o.file_bytes).as_mb()
            });
            save(
                format!("scene4_size_{d}.png"),
                format!("Scene 4: data size allocated to each network, {d}"),
                &|p| Ok(c.save(p)?),
            )?;
        }
    }
    // Overhead.
    let ours = overhead_means(r);
    let c = BarChart::new("Overhead: paper vs this implementation (seconds, value on each bar)")
        .categories(super::PAPER_OVERHEAD_S.iter().map(|(n, _)| *n))
        .series("paper", super::PAPER_OVERHEAD_S.iter().map(|(_, s)| *s))
        .series("this implementation", ours)
        .y_label("s")
        .value_labels(true)
        .legend(LegendPosition::TopRight)
        .size(SIZE.0, SIZE.1);
    save(
        "overhead.png".into(),
        "segmentation, profiler (sample points + fits) and DP times: paper vs measured (mean over scenes)".into(),
        &|p| Ok(c.save(p)?),
    )?;
    Ok(files)
}

fn budget_mb(r: &EvalReport, d: &str) -> f64 {
    r.scenes
        .iter()
        .flat_map(|s| &s.rows)
        .find(|row| row.device == d)
        .map_or(0.0, |row| Bytes(row.budget_bytes).as_mb())
}

/// Mean seconds over the built-in scenes: segmentation, profiler, DP (the
/// DP's mean over devices).
pub fn overhead_means(r: &EvalReport) -> [f64; 3] {
    let n = r.scenes.len().max(1) as f64;
    let seg = r.scenes.iter().map(|s| s.timings.segment_s).sum::<f64>() / n;
    let prof = r.scenes.iter().map(|s| s.timings.profile_s).sum::<f64>() / n;
    let dps: Vec<f64> = r
        .scenes
        .iter()
        .flat_map(|s| &s.rows)
        .filter(|row| row.method == Method::Dp && row.error.is_none())
        .map(|row| row.plan_s)
        .collect();
    let dp = dps.iter().sum::<f64>() / dps.len().max(1) as f64;
    [seg, prof, dp]
}
