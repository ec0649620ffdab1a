//! `nerflex scene` (under construction).

/// Flags of `nerflex scene`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `nerflex scene`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`nerflex scene` is not implemented yet")
}
