//! `nerflex render` (under construction).

/// Flags of `nerflex render`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex render`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex render` is not implemented yet")
}
