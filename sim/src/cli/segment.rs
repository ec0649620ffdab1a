//! `nerflex segment` (under construction).

/// Flags of `nerflex segment`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex segment`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex segment` is not implemented yet")
}
