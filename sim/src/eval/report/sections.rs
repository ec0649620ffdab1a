//! The report's statistical and honesty sections: paired differences,
//! Scene 4 per object, the paper's claims, the segmentation measure, the
//! substitutions and the figures the paper does not give.

use super::super::compare::{
    devices, measured, object_series, paired, paired_object, same_plan, scored_objects, Metric,
};
use super::super::detail::{self, Better};
use super::super::plots::method_label;
use super::super::stats::{bootstrap_mean, Significance};
use super::super::{honesty, verdicts, EvalReport, SceneReport, METHODS};
use crate::baselines::Method;
use crate::pipeline::bakes::HULL_BAKER;
use std::fmt::Write as _;

/// `yes (+)`, `yes (−)` or `no`.
fn sig_word(s: Significance) -> &'static str {
    match s {
        Significance::Positive => "**yes**, DP higher",
        Significance::Negative => "**yes**, DP lower",
        Significance::NotSignificant => "no",
    }
}

/// The warning at the top when the run is not the paper-scale one.
pub fn scope_note(r: &EvalReport, size: Option<u32>, out: &mut String) {
    let hull = r.baker == HULL_BAKER;
    let small = size.is_some_and(|s| s < honesty::PAPER_SIZE_PX);
    if hull || small {
        let _ = writeln!(
            out,
            "> **Scope.** This run uses {}{}. Its intervals and verdicts describe these assets \
             only; they are not the paper-scale result (800 × 800 captures on trained assets), \
             which a later run of `nerflex eval` regenerates.\n",
            if hull {
                "visual-hull bakes (no trained field)"
            } else {
                "trained assets"
            },
            match size {
                Some(s) if s < honesty::PAPER_SIZE_PX => format!(" at {s} × {s} pixels"),
                _ => String::new(),
            }
        );
    }
}

/// Means with intervals per (device, method) of one scene.
pub fn interval_table(s: &SceneReport, out: &mut String) {
    if s.rows.iter().all(|r| r.views.is_empty()) {
        return;
    }
    let _ = writeln!(
        out,
        "Means over the held-out views with 95 % bootstrap intervals (views resampled, seed fixed):\n"
    );
    let _ = writeln!(out, "| device | method | views | SSIM | PSNR dB | LPIPS |");
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    for row in s.rows.iter().filter(|r| !r.views.is_empty()) {
        let cell = |m: Metric| {
            super::super::compare::interval(row, m).map_or("–".into(), |i| i.show(m.digits()))
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} |",
            row.device,
            method_label(row.method),
            row.views.len(),
            cell(Metric::Ssim),
            cell(Metric::Psnr),
            cell(Metric::Lpips)
        );
    }
    let _ = writeln!(out);
}

/// Paired differences NeRFlex (DP) − each other method of one scene.
pub fn paired_table(s: &SceneReport, out: &mut String) {
    let mut lines = Vec::new();
    for d in devices(s) {
        let Some(dp) = measured(s, &d, Method::Dp) else {
            continue;
        };
        for &m in METHODS.iter().filter(|m| **m != Method::Dp) {
            let Some(other) = measured(s, &d, m) else {
                continue;
            };
            if same_plan(dp, other) {
                lines.push(format!(
                    "| {d} | {} | same plan as the DP | | | |",
                    method_label(m)
                ));
                continue;
            }
            let cell = |metric: Metric| {
                paired(dp, other, metric).map_or("–".into(), |i| i.show_signed(metric.digits()))
            };
            let sig = paired(dp, other, Metric::Ssim).map_or("–", |i| sig_word(i.significance()));
            lines.push(format!(
                "| {d} | {} | {} | {} | {} | {sig} |",
                method_label(m),
                cell(Metric::Ssim),
                cell(Metric::Psnr),
                cell(Metric::Lpips)
            ));
        }
    }
    if lines.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "NeRFlex (DP) − each other method, paired over the same held-out views (95 % bootstrap \
         interval of the mean difference; significant = the SSIM interval excludes 0):\n"
    );
    let _ = writeln!(
        out,
        "| device | DP − | ΔSSIM | ΔPSNR dB | ΔLPIPS | significant (SSIM) |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    for l in lines {
        let _ = writeln!(out, "{l}");
    }
    let _ = writeln!(out);
}

/// Scene 4 per object: SSIM in the object's box with intervals, the bytes
/// of its network, and DP − Fairness / SLSQP paired per object.
pub fn scene4_objects(s: &SceneReport, out: &mut String) {
    let objects = scored_objects(s);
    if objects.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "Each object's SSIM in its own box of every held-out view (the ground truth's mask box, \
         4 px margin), mean [95 % interval], and the baked MB of the network that holds it \
         (shared networks hold several objects):\n"
    );
    let selectors = [Method::Dp, Method::Fairness, Method::Slsqp];
    let _ = writeln!(
        out,
        "| device | object | network | DP | Fairness | SLSQP | DP − Fairness | DP − SLSQP |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
    for d in devices(s) {
        for o in &objects {
            let network = s
                .objects
                .iter()
                .find(|x| &x.name == o)
                .map_or(o.as_str(), |x| x.network.as_str());
            let cell = |m: Method| {
                let Some(row) = measured(s, &d, m) else {
                    return "–".to_string();
                };
                let mb = row
                    .objects
                    .iter()
                    .find(|x| x.name == network)
                    .map_or("–".into(), |x| {
                        format!("{:.1} MB", x.file_bytes as f64 / 1e6)
                    });
                bootstrap_mean(&object_series(row, o))
                    .map_or("–".into(), |i| format!("{} · {mb}", i.show(4)))
            };
            let diff = |m: Method| -> String {
                let (Some(a), Some(b)) = (measured(s, &d, Method::Dp), measured(s, &d, m)) else {
                    return "–".into();
                };
                if same_plan(a, b) {
                    return "same plan".into();
                }
                paired_object(a, b, o).map_or("–".into(), |i| {
                    let star = if i.significance() == Significance::NotSignificant {
                        ""
                    } else {
                        " *"
                    };
                    format!("{}{star}", i.show_signed(4))
                })
            };
            let _ = writeln!(
                out,
                "| {d} | {o} | {network} | {} | {} | {} | {} | {} |",
                cell(selectors[0]),
                cell(selectors[1]),
                cell(selectors[2]),
                diff(Method::Fairness),
                diff(Method::Slsqp)
            );
        }
    }
    let _ = writeln!(out, "\n`*`: the interval excludes 0.\n");
}

/// The paper's claims, one line each.
pub fn claims(r: &EvalReport, out: &mut String) {
    let _ = writeln!(out, "## The paper's claims\n");
    let _ = writeln!(
        out,
        "A cell is one (scene, device); it confirms when the 95 % interval of the paired \
         difference lies on the claim's side of 0, contradicts when it lies on the other, and is \
         not significant otherwise. A claim is confirmed when at least half its cells confirm \
         and none contradicts, contradicted when at least half contradict and none confirms, \
         else not significant (`eval::verdicts`).\n"
    );
    let no_views = r
        .scenes
        .iter()
        .flat_map(|s| &s.rows)
        .all(|row| row.views.is_empty());
    if no_views {
        let _ = writeln!(
            out,
            "This `eval.json` has no per-view scores (it predates them): the quality claims have \
             no interval to test until `nerflex eval` is run again.\n"
        );
    }
    for v in verdicts::verdicts(r) {
        let _ = writeln!(out, "{}", v.line());
    }
    let _ = writeln!(out);
}

/// The segmentation measure against the measured gains.
pub fn segmentation_measure(r: &EvalReport, out: &mut String) {
    let a = detail::analyse(r);
    let _ = writeln!(
        out,
        "## Does the segmentation's measure predict what a dedicated network gains?\n"
    );
    if a.gains.is_empty() {
        let _ = writeln!(
            out,
            "No object has a measured gain (needs Single-NeRF and Block-NeRF rows with per-view \
             object scores).\n"
        );
        return;
    }
    let _ = writeln!(
        out,
        "Gain = the object's SSIM in its box, Block-NeRF (a network of its own) − Single-NeRF \
         (one network for the scene), both at the baseline (g, p), paired over the held-out \
         views{}. Current measure: the segmentation's maximum detail frequency in cycles per \
         object diameter; in-image reading (the paper's): the maximum over views of the same \
         spectrum's frequency in cycles per pixel.\n",
        a.device
            .as_deref()
            .map_or(String::new(), |d| format!(" (rows of {d})"))
    );
    let _ = writeln!(
        out,
        "| scene | object | network | cycles / diameter | cycles / pixel | gain ΔSSIM |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    for g in &a.gains {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.2} | {} | {} |",
            g.scene,
            g.object,
            if g.dedicated { "dedicated" } else { "shared" },
            g.cycles_per_diameter,
            g.cycles_per_pixel.map_or("–".into(), |c| format!("{c:.4}")),
            g.gain.show_signed(4)
        );
    }
    let show = |c: Option<super::super::stats::RankCorrelation>| {
        c.map_or("undefined".into(), |c| {
            format!(
                "ρ = {:+.3} over {} objects, p = {:.3} ({})",
                c.rho,
                c.n,
                c.p,
                if c.exact {
                    "exact"
                } else {
                    "10 000 seeded permutations"
                }
            )
        })
    };
    let _ = writeln!(
        out,
        "\nSpearman's rank correlation with the gain: current measure {}; in-image reading {}.\n",
        show(a.current),
        show(a.in_image)
    );
    let verdict = match a.better() {
        Some(Better::Current) => {
            "The current measure (cycles per object diameter) ranks objects more like their gains; it stays the default."
        }
        Some(Better::InImage) => {
            "The in-image reading (cycles per pixel) ranks objects more like their gains on these assets. The default stays cycles per object diameter until the paper-scale run on trained assets repeats this; if it agrees, the segmentation's default should switch."
        }
        Some(Better::Tie) => "The two readings rank objects alike; the default (cycles per object diameter) stays.",
        None => "One of the correlations is undefined (a constant reading or gain); no choice is made.",
    };
    let _ = writeln!(out, "{verdict}\n");
}

/// The substitutions, the figures not from the paper.
pub fn substitutions(r: &EvalReport, out: &mut String) {
    let _ = writeln!(out, "## What this evaluation substitutes for the paper's\n");
    let _ = writeln!(out, "| the paper | here | what it may change |");
    let _ = writeln!(out, "|---|---|---|");
    for s in honesty::substitutions(r) {
        let _ = writeln!(out, "| {} | {} | {} |", s.paper, s.ours, s.may_change);
    }
    let _ = writeln!(out, "\nFigures used here that the paper does not give:\n");
    for (what, whence) in honesty::NOT_FROM_THE_PAPER {
        let _ = writeln!(out, "- {what}: {whence}.");
    }
    let _ = writeln!(out);
}
