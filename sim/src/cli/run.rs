//! `nerflex run` (under construction).

/// Flags of `nerflex run`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex run`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex run` is not implemented yet")
}
