//! `nerflex plan` (under construction).

/// Flags of `nerflex plan`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex plan`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex plan` is not implemented yet")
}
