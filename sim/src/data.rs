//! Where the real, public data lives: `../shared/data/` beside the repository.
//!
//! The data is never copied into the repository. Tests and demos find it
//! through [`shared_data_dir`]; when it is absent they skip with a message
//! (CI always has it).

use std::path::{Path, PathBuf};

/// Environment variable that overrides the location of the shared data folder.
pub const DATA_ENV: &str = "NERFLEX_DATA";

/// The shared data folder, if it exists.
///
/// Looks at `$NERFLEX_DATA`, then for `shared/data` beside any ancestor of
/// the current directory and of this crate's manifest directory (so it works
/// from the repository root, a crate folder, or a git worktree beside it).
pub fn shared_data_dir() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os(DATA_ENV) {
        let p = PathBuf::from(p);
        return p.is_dir().then_some(p);
    }
    let mut starts: Vec<PathBuf> = Vec::new();
    if let Ok(cwd) = std::env::current_dir() {
        starts.push(cwd);
    }
    starts.push(PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    starts.iter().find_map(|s| find_upwards(s))
}

fn find_upwards(start: &Path) -> Option<PathBuf> {
    start.ancestors().find_map(|dir| {
        let candidate = dir.join("shared").join("data");
        candidate.join("README.md").is_file().then_some(candidate)
    })
}

/// The shared data folder, or `None` after printing why a data test is skipped.
///
/// Use at the top of every test that needs real data:
/// `let Some(data) = nerflex_sim::data::require_data("lpips reference") else { return };`
pub fn require_data(what: &str) -> Option<PathBuf> {
    let dir = shared_data_dir();
    if dir.is_none() {
        eprintln!(
            "SKIPPED {what}: ../shared/data not found (set {DATA_ENV} to its path); CI always has it"
        );
    }
    dir
}
