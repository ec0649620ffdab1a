//! `nerflex`: resource-aware multi-object NeRF rendering for phones.

use clap::{Parser, Subcommand};
use nerflex_sim::cli;

#[derive(Debug, Parser)]
#[command(
    name = "nerflex",
    version,
    about = "NeRFlex: plan, bake, render and simulate multi-object NeRF scenes on phones"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Choose one (g, p) configuration per object under a device budget.
    Plan(cli::plan::Args),
    /// Render a MobileNeRF-format asset with the fixed-point shader.
    Render(cli::render::Args),
    /// Generate built-in captures in the NeRF-synthetic layout.
    Scene(cli::scene::Args),
    /// Compare two images: SSIM, PSNR, LPIPS.
    Metrics(cli::metrics::Args),
    /// Bake MobileNeRF-format assets from a posed capture.
    Bake(cli::bake::Args),
    /// Learn one object's radiance field from its posed photos.
    Train(cli::train::Args),
    /// Profiler: sample points and curve fitting.
    Profile(cli::profile::Args),
    /// Detail-based segmentation of a multi-object capture.
    Segment(cli::segment::Args),
    /// Simulate a plan on a device: load, FPS over a turntable.
    Simulate(cli::simulate::Args),
    /// The whole NeRFlex pipeline on one capture.
    Run(cli::run::Args),
    /// The NeRFlex paper's evaluation, regenerated.
    Eval(cli::eval::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Plan(a) => cli::plan::run(a),
        Command::Render(a) => cli::render::run(a),
        Command::Scene(a) => cli::scene::run(a),
        Command::Metrics(a) => cli::metrics::run(a),
        Command::Bake(a) => cli::bake::run(a),
        Command::Train(a) => cli::train::run(a),
        Command::Profile(a) => cli::profile::run(a),
        Command::Segment(a) => cli::segment::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
        Command::Run(a) => cli::run::run(a),
        Command::Eval(a) => cli::eval::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
