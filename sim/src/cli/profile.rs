//! `nerflex profile` (under construction).

/// Flags of `nerflex profile`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex profile`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex profile` is not implemented yet")
}
