//! `nerflex`: resource-aware multi-object NeRF rendering for phones.

use clap::{Parser, Subcommand};
use nerflex_sim::cli;

/// The system allocator with large blocks on transparent huge pages
/// (`nerflex_sim::memory::HugePageAlloc`).
#[global_allocator]
static ALLOC: nerflex_sim::memory::HugePageAlloc = nerflex_sim::memory::HugePageAlloc;

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

/// Exit status of a command whose reader closed its output early, as a
/// shell reports a process killed by SIGPIPE (128 + 13).
const BROKEN_PIPE_EXIT: i32 = 141;

/// Output piped into a reader that stops early (`nerflex plan --json |
/// head -1`) makes `println!` panic; end quietly as C tools do, with the
/// status a shell gives them, and leave every other panic to the default
/// hook.
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if is_broken_pipe(msg) {
            std::process::exit(BROKEN_PIPE_EXIT);
        }
        default(info);
    }));
}

/// Whether a panic message is `println!`'s on a closed pipe
/// (`failed printing to stdout: Broken pipe (os error 32)`).
fn is_broken_pipe(msg: &str) -> bool {
    msg.starts_with("failed printing to std") && msg.contains("Broken pipe")
}

fn main() -> std::process::ExitCode {
    quiet_on_broken_pipe();
    nerflex_sim::memory::keep_freed_pages();
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

#[cfg(test)]
mod tests {
    use super::is_broken_pipe;

    #[test]
    fn only_a_closed_pipe_ends_quietly() {
        // std's message (library/std/src/io/stdio.rs, `print_to`).
        assert!(is_broken_pipe(
            "failed printing to stdout: Broken pipe (os error 32)"
        ));
        assert!(is_broken_pipe(
            "failed printing to stderr: Broken pipe (os error 32)"
        ));
        assert!(!is_broken_pipe(
            "failed printing to stdout: No space left on device (os error 28)"
        ));
        assert!(!is_broken_pipe("index out of bounds: Broken pipe"));
        assert!(!is_broken_pipe(""));
    }
}
