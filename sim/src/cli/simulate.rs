//! `nerflex simulate` (under construction).

/// Flags of `nerflex simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex simulate`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex simulate` is not implemented yet")
}
