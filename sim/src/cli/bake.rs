//! `nerflex bake` (under construction).

/// Flags of `nerflex bake`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex bake`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex bake` is not implemented yet")
}
