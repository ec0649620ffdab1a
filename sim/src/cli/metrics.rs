//! `nerflex metrics` (under construction).

/// Flags of `nerflex metrics`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex metrics`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex metrics` is not implemented yet")
}
