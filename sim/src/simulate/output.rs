//! Writing a simulation: per-frame CSV, JSON, and the FPS plot the paper
//! draws (real-time FPS as a line, the average dashed).

use super::timeline::Simulation;
use crate::plot::{Chart, LegendPosition, Series};
use anyhow::Context as _;
use std::path::Path;

/// The header of the per-frame CSV.
pub const CSV_HEADER: &str =
    "frame,t_s,frame_ms,fps,objects_loaded,quads,quads_visible,pixels_shaded,stall_ms";

/// The per-frame CSV text.
pub fn csv_text(sim: &Simulation) -> String {
    let mut s = String::with_capacity(64 * (sim.frames.len() + 1));
    s.push_str(CSV_HEADER);
    s.push('\n');
    for (i, f) in sim.frames.iter().enumerate() {
        s.push_str(&format!(
            "{i},{:.6},{:.4},{:.4},{},{:.0},{:.0},{:.0},{:.4}\n",
            f.t_s,
            f.frame_s * 1e3,
            f.fps,
            f.objects_loaded,
            f.quads,
            f.quads_visible,
            f.pixels_shaded,
            f.stall_s * 1e3
        ));
    }
    s
}

/// Writes `text` to `path` through a temporary file and a rename, so an
/// interrupted write never leaves a truncated file.
pub fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    crate::output::create_parent(path)?;
    crate::output::write_file(path, text.as_bytes())?;
    Ok(())
}

/// Writes the per-frame CSV.
pub fn write_csv(sim: &Simulation, path: &Path) -> anyhow::Result<()> {
    write_text(path, &csv_text(sim))
}

/// Writes the whole simulation as JSON.
pub fn write_json(sim: &Simulation, path: &Path) -> anyhow::Result<()> {
    let mut text = serde_json::to_string_pretty(sim)?;
    text.push('\n');
    write_text(path, &text)
}

/// The FPS chart of one or more simulations (one line and one dashed mean
/// each), e.g. NeRFlex and Single-NeRF on one device, as in the paper.
pub fn fps_chart(title: &str, runs: &[(&str, &Simulation)]) -> Chart {
    let mut chart = Chart::new(title)
        .x_label("frame")
        .y_label("FPS")
        .legend(LegendPosition::TopRight);
    let mut top: f64 = 1.0;
    let mut frames = 1usize;
    for (i, (name, sim)) in runs.iter().enumerate() {
        let color = crate::plot::PALETTE[i % crate::plot::PALETTE.len()];
        let label = match &sim.load_failure {
            Some(_) => format!("{name} (fails to load)"),
            None => (*name).to_string(),
        };
        chart = chart
            .series(
                Series::line(
                    label,
                    sim.frames
                        .iter()
                        .enumerate()
                        .map(|(k, f)| (k as f64, f.fps)),
                )
                .color(color)
                .width(1.0),
            )
            .series(
                Series::horizontal(format!("{name} mean {:.1}", sim.mean_fps), sim.mean_fps)
                    .dashed()
                    .color(color),
            );
        top = sim.frames.iter().map(|f| f.fps).fold(top, f64::max);
        frames = frames.max(sim.frames.len());
    }
    chart
        .x_range(0.0, frames.saturating_sub(1).max(1) as f64)
        .y_range(0.0, (top * 1.1).ceil())
}

/// Saves the FPS chart of one simulation.
pub fn write_plot(sim: &Simulation, title: &str, path: &Path) -> anyhow::Result<()> {
    fps_chart(title, &[("FPS", sim)])
        .save(path)
        .with_context(|| format!("{}: cannot draw the FPS plot", path.display()))
}
