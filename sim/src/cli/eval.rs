//! `nerflex eval` (under construction).

/// Flags of `nerflex eval`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex eval`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex eval` is not implemented yet")
}
