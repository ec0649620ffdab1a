//! The Markdown report of an evaluation.

use super::plots::{find, method_label, overhead_means};
use super::{EvalReport, Row, SceneReport, METHODS, PAPER_OVERHEAD_S};
use crate::baselines::Method;
use nerflex_core::units::Bytes;
use std::fmt::Write as _;

mod sections;

fn mb(b: u64) -> String {
    format!("{:.1}", Bytes(b).as_mb())
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.digits$}"))
}

/// The calibration check of a row, if it is the calibration cell (its FPS
/// matches the paper by construction once the device file is calibrated).
fn calibrated<'a>(r: &'a EvalReport, row: &Row) -> Option<&'a super::calibrate::Calibration> {
    if row.method != Method::Dp {
        return None;
    }
    r.calibration
        .iter()
        .find(|c| c.device == row.device && c.against == format!("{} dp", row.scene))
}

fn fps_cell(r: &Row, calibration: Option<&super::calibrate::Calibration>) -> String {
    let tag = match calibration {
        Some(c) if c.matched() => " (calibrated)".to_string(),
        // The calibration cell, but the device file no longer matches it
        // (the bakes changed since it was calibrated): say so, not "calibrated".
        Some(c) => format!(
            " (calibration cell; the device file is off: ×{:.3} would match)",
            c.scale
        ),
        None => String::new(),
    };
    if r.error.is_some() {
        "no plan".into()
    } else if r.load_failure.is_some() {
        "**load fails** (0)".into()
    } else if r.over_soft_limit {
        format!("{:.1} (over soft limit){tag}", r.mean_fps)
    } else {
        format!("{:.1}{tag}", r.mean_fps)
    }
}

/// The table of one scene: device × method.
fn scene_table(rep: &EvalReport, s: &SceneReport, out: &mut String) {
    let _ = writeln!(
        out,
        "| device | method | SSIM | PSNR dB | LPIPS | predicted MB | baked MB | mean FPS (predicted) |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
    for r in &s.rows {
        let q = r.quality;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            r.device,
            method_label(r.method),
            opt(q.map(|q| q.ssim), 4),
            opt(q.map(|q| q.psnr), 2),
            opt(q.and_then(|q| q.lpips), 4),
            if r.error.is_some() {
                "–".into()
            } else {
                mb(r.predicted_bytes)
            },
            if r.error.is_some() {
                "–".into()
            } else {
                mb(r.file_bytes)
            },
            fps_cell(r, calibrated(rep, r))
        );
    }
    for r in s.rows.iter().filter(|r| r.error.is_some()) {
        let _ = writeln!(
            out,
            "\n{} on {}: no plan — {}",
            method_label(r.method),
            r.device,
            r.error.as_deref().unwrap_or("")
        );
    }
}

/// Facts where the measurements differ from what the paper reports, found
/// in the numbers (the README explains why).
pub fn disagreements(r: &EvalReport) -> Vec<String> {
    let mut v = Vec::new();
    for s in &r.scenes {
        for row in &s.rows {
            let what = format!("{} on {}", s.scene, row.device);
            match row.method {
                Method::Block if row.error.is_none() && row.load_failure.is_none() => v.push(format!(
                    "Block-NeRF loads on {what} ({} MB); the paper's Block-NeRF fails on both phones",
                    mb(row.file_bytes)
                )),
                Method::Single
                    if row.device == "iphone13"
                        && row.error.is_none()
                        && row.load_failure.is_none() =>
                {
                    v.push(format!(
                        "Single-NeRF loads on {what} ({} MB); the paper's fails on the iPhone",
                        mb(row.file_bytes)
                    ))
                }
                Method::Dp if row.load_failure.is_some() => v.push(format!(
                    "NeRFlex (DP) fails to load on {what}: baked {} MB against the planner's {} MB",
                    mb(row.file_bytes),
                    mb(row.predicted_bytes)
                )),
                _ => {}
            }
            if row.replans > 0 {
                v.push(format!(
                    "{} on {what}: the first plan baked over the {} MB budget (predicted sizes are about ±5 % off); re-planned {}× against a smaller budget, now {} MB baked",
                    method_label(row.method),
                    mb(row.budget_bytes),
                    row.replans,
                    mb(row.file_bytes)
                ));
            }
            if matches!(row.method, Method::Slsqp | Method::Fairness) {
                if let (Some(q), Some(dp)) = (
                    row.quality,
                    find(s, &row.device, Method::Dp).and_then(|d| d.quality),
                ) {
                    if q.ssim > dp.ssim + 1e-4 {
                        v.push(format!(
                            "{} beats DP on {what}: SSIM {:.4} vs {:.4} (the DP maximises the profiles' predicted SSIM, not the measured one)",
                            method_label(row.method),
                            q.ssim,
                            dp.ssim
                        ));
                    }
                }
            }
        }
        if let (Some(single), Some(dp)) = (
            find(s, "pixel4", Method::Single),
            find(s, "pixel4", Method::Dp),
        ) {
            if single.load_failure.is_none() && dp.load_failure.is_none() && dp.mean_fps > 0.0 {
                let ratio = dp.mean_fps / single.mean_fps.max(1e-9);
                if !(1.5..=2.5).contains(&ratio) {
                    v.push(format!(
                        "on the Pixel 4, {} NeRFlex runs at {:.1}× Single-NeRF's FPS ({:.1} vs {:.1}); the paper reports about 2×",
                        s.scene, ratio, dp.mean_fps, single.mean_fps
                    ));
                }
            }
        }
    }
    v
}

/// The whole report.
pub fn markdown(r: &EvalReport, pictures: &[(String, String)]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# NeRFlex evaluation\n");
    let _ = writeln!(
        s,
        "Produced by `nerflex eval` in {:.0} s. MB = 10^6 bytes. Quality is measured on the \
         held-out views: whole-scene SSIM/PSNR/LPIPS renders every object's asset together \
         from the capture's test cameras. FPS is the device simulator's mean over the \
         turntable (`docs/device.md`).\n",
        r.wall_s
    );
    let _ = writeln!(s, "## Settings\n");
    for (k, v) in &r.settings {
        let _ = writeln!(s, "- {k}: {v}");
    }
    // Reports since session 9 name the baker with its settings above;
    // older ones (no such line) still get its name.
    if !r.settings.iter().any(|(k, _)| k == "baker") {
        let _ = writeln!(s, "- baker: {}", r.baker);
    }
    let _ = writeln!(s);
    sections::scope_note(r, super::honesty::capture_size(r), &mut s);
    let _ = writeln!(s, "\n## Device model against the paper's FPS\n");
    let _ = writeln!(
        s,
        "| device | matched | paper FPS | simulated (device file) | factor that would match |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    for c in &r.calibration {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.4} |",
            c.device, c.against, c.target_fps, c.fps_with_file, c.scale
        );
    }
    let _ = writeln!(s, "\n{}", super::honesty::calibration_note(r));
    let _ = writeln!(
        s,
        "\nWhere the time of a steady frame goes (after loading), per device and method of the FPS scene:\n"
    );
    let _ = writeln!(
        s,
        "| scene | device | method | quads | raster ms | MLP ms | mean FPS |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for sc in &r.scenes {
        if !r.fps.iter().any(|c| c.scene == sc.scene) {
            continue;
        }
        for row in sc
            .rows
            .iter()
            .filter(|x| x.error.is_none() && x.load_failure.is_none())
        {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.2} | {:.2} | {:.1} |",
                sc.scene,
                row.device,
                method_label(row.method),
                row.quads,
                row.raster_ms,
                row.shade_ms,
                row.mean_fps
            );
        }
    }
    let _ = writeln!(s, "\n## Scenes\n");
    for sc in &r.scenes {
        let nets: Vec<String> = sc
            .networks
            .iter()
            .map(|(n, o)| {
                let mut name = if o.len() == 1 && &o[0] == n {
                    n.clone()
                } else {
                    format!("{n} ({})", o.join(", "))
                };
                if let Some(l) = sc.lattices.iter().find(|l| &l.object == n) {
                    let _ = write!(name, " [lattice {}³]", l.cells);
                }
                name
            })
            .collect();
        let _ = writeln!(s, "### {}\n\nnetworks: {}\n", sc.scene, nets.join(", "));
        scene_table(r, sc, &mut s);
        let _ = writeln!(s);
        sections::interval_table(sc, &mut s);
        sections::paired_table(sc, &mut s);
    }
    if let Some(s4) = r.scenes.iter().find(|x| x.scene == "scene4") {
        let _ = writeln!(s, "## Scene 4 per network\n");
        let _ = writeln!(
            s,
            "| device | network | DP (g, p) MB SSIM | Fairness (g, p) MB SSIM | SLSQP (g, p) MB SSIM |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|");
        let devices: Vec<String> = {
            let mut v: Vec<String> = Vec::new();
            for row in &s4.rows {
                if !v.contains(&row.device) {
                    v.push(row.device.clone());
                }
            }
            v
        };
        for d in &devices {
            for (n, _) in &s4.networks {
                let cell = |m: Method| {
                    find(s4, d, m)
                        .and_then(|row| row.objects.iter().find(|o| &o.name == n))
                        .map_or("–".into(), |o| {
                            let g = if o.geometry.is_planes() {
                                String::new()
                            } else {
                                format!(", {}", o.geometry)
                            };
                            format!("({}, {}{g}) {} {:.4}", o.g, o.p, mb(o.file_bytes), o.ssim)
                        })
                };
                let _ = writeln!(
                    s,
                    "| {d} | {n} | {} | {} | {} |",
                    cell(Method::Dp),
                    cell(Method::Fairness),
                    cell(Method::Slsqp)
                );
            }
        }
        let _ = writeln!(s);
        sections::scene4_objects(s4, &mut s);
    }
    sections::claims(r, &mut s);
    sections::segmentation_measure(r, &mut s);
    let _ = writeln!(s, "## Overhead\n");
    let ours = overhead_means(r);
    let _ = writeln!(
        s,
        "| stage | paper (s) | this implementation, mean over scenes (s) |"
    );
    let _ = writeln!(s, "|---|---|---|");
    for ((name, paper), o) in PAPER_OVERHEAD_S.iter().zip(ours) {
        let _ = writeln!(s, "| {name} | {paper} | {o:.4} |");
    }
    let _ = writeln!(
        s,
        "\nSample bakes (the profiler's measurements, standing for training, which the \
         paper leaves out; 0 s when every bake was already in the store): {}.\n",
        r.scenes
            .iter()
            .map(|x| format!("{} {:.0} s", x.scene, x.timings.sample_bakes_s))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if let Some(real) = &r.real {
        let _ = writeln!(s, "## Real capture: {}\n", real.scene);
        let _ = writeln!(
            s,
            "A side-by-side composite of separate real captures has no whole-scene view: \
             each object's asset is rendered from its own capture's held-out cameras (the same \
             views for every method) and the means are over every (object, view); there is no \
             Single-NeRF.\n"
        );
        scene_table(r, real, &mut s);
        let _ = writeln!(s);
        sections::interval_table(real, &mut s);
        sections::paired_table(real, &mut s);
    }
    sections::substitutions(r, &mut s);
    let _ = writeln!(s, "## Where the results differ from the paper's\n");
    let d = disagreements(r);
    if d.is_empty() {
        let _ = writeln!(s, "No difference was detected automatically.\n");
    }
    for x in d {
        let _ = writeln!(s, "- {x}");
    }
    let _ = writeln!(s, "\n## Figures\n");
    for (file, caption) in pictures {
        let _ = writeln!(s, "![{caption}]({file})\n");
    }
    let _ = writeln!(s, "Methods: {}.", METHODS.map(method_label).join(", "));
    s
}
