//! Trained radiance fields kept on disk, beside the bake store: every
//! (views, training settings) is trained once, saved as
//! `ROOT/<key>.safetensors` (the format of `nerflex train`, written
//! atomically by [`crate::train::io::save`]) and loaded from there by every
//! later request — the next profiler sample bake of the same network, a
//! final bake, a re-run, or a run resumed after an interruption.
//!
//! The key is the views' name and content hash (which covers their images,
//! masks and cameras), their search box, the number of training views, the
//! training settings (as JSON) and [`FIELD_KEY_VERSION`], hashed. The
//! trainer is not deterministic across thread counts (rayon reduces the
//! workers' gradients in their order), so a field retrained after its file
//! was deleted may differ slightly from the one earlier bakes came from;
//! the bakes keyed by it are kept (they name the field by key, not by its
//! bytes).

use crate::bake::sweep::{Fnv64, ObjectViews};
use crate::train::grid::SparseGrid;
use crate::train::io;
use crate::train::trainer::{self, TrainReport, TrainSettings};
use anyhow::Context as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Part of every field key: raise it when the store's keying changes. The
/// trainer's own [`crate::train::trainer::TRAINER_VERSION`] is hashed too,
/// so a trainer that trains the same settings differently is not reused.
pub const FIELD_KEY_VERSION: u32 = 1;

/// A field from the store.
#[derive(Clone)]
pub struct StoredField {
    /// Its key (the file's stem).
    pub key: String,
    /// The file.
    pub path: PathBuf,
    /// The grid.
    pub grid: Arc<SparseGrid>,
    /// The training report saved with it, if readable.
    pub report: Option<TrainReport>,
    /// Whether this call trained it (false: loaded from the store).
    pub trained_now: bool,
    /// Seconds this call spent training and saving (0 when loaded).
    pub train_s: f64,
    /// Seconds this call spent loading it (0 when trained).
    pub load_s: f64,
}

impl std::fmt::Debug for StoredField {
    // The grid's size, not its values.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StoredField")
            .field("key", &self.key)
            .field("path", &self.path)
            .field("res", &self.grid.res)
            .field("slots", &self.grid.slots())
            .field("trained_now", &self.trained_now)
            .field("train_s", &self.train_s)
            .field("load_s", &self.load_s)
            .finish_non_exhaustive()
    }
}

/// Called while a field trains with (level, step, steps in level, batch PSNR).
pub type TrainProgress<'a> = trainer::Progress<'a>;

/// The folder of kept fields.
#[derive(Clone, Debug)]
pub struct FieldStore {
    root: PathBuf,
}

impl FieldStore {
    /// A store at `root` (created on the first field saved).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }

    /// The folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The key of the field `settings` train from `views`: everything the
    /// trainer reads, hashed, after the views' name.
    pub fn key(views: &ObjectViews, settings: &TrainSettings) -> String {
        let mut h = Fnv64::default();
        h.write(b"nerflex field");
        h.write(&FIELD_KEY_VERSION.to_le_bytes());
        h.write(&crate::train::trainer::TRAINER_VERSION.to_le_bytes());
        h.write(&views.content_hash.to_le_bytes());
        h.write(views.name.as_bytes());
        h.write(format!("{:?}", views.search_box).as_bytes());
        h.write(&(views.train.len() as u64).to_le_bytes());
        // Serialising plain numbers and vectors cannot fail; Debug is the
        // fallback all the same, so a key is always written.
        let s = serde_json::to_string(settings).unwrap_or_else(|_| format!("{settings:?}"));
        h.write(s.as_bytes());
        format!("{}-f{:016x}", sanitize(&views.name), h.finish())
    }

    /// Where the field of (views, settings) is kept.
    pub fn path(&self, views: &ObjectViews, settings: &TrainSettings) -> PathBuf {
        self.root
            .join(format!("{}.safetensors", Self::key(views, settings)))
    }

    /// Whether the store holds a file for (views, settings).
    pub fn contains(&self, views: &ObjectViews, settings: &TrainSettings) -> bool {
        self.path(views, settings).is_file()
    }

    /// The field of `views` trained with `settings`: loaded from the store
    /// when its file is there and reads back with the same settings, else
    /// trained now and saved (atomically: an interrupted run leaves no
    /// half file, and the next run trains it again). `progress` hears the
    /// trainer's steps.
    pub fn get_or_train(
        &self,
        views: &ObjectViews,
        settings: &TrainSettings,
        progress: &TrainProgress<'_>,
    ) -> anyhow::Result<StoredField> {
        settings
            .validate()
            .map_err(|e| anyhow::anyhow!("training settings for {}: {e}", views.name))?;
        let key = Self::key(views, settings);
        let path = self.root.join(format!("{key}.safetensors"));
        if path.is_file() {
            let t0 = Instant::now();
            // A file that does not read back (or was trained with other
            // settings under this name) is trained again and replaced.
            if let Ok(saved) = io::load(&path) {
                if saved.settings.as_ref() == Some(settings) {
                    return Ok(StoredField {
                        key,
                        path,
                        grid: Arc::new(saved.grid),
                        report: saved.report,
                        trained_now: false,
                        train_s: 0.0,
                        load_s: t0.elapsed().as_secs_f64(),
                    });
                }
            }
        }
        let t0 = Instant::now();
        let (grid, report) = trainer::train(views, settings, progress)
            .map_err(|e| anyhow::anyhow!("training the field of {}: {e}", views.name))?;
        std::fs::create_dir_all(&self.root)
            .with_context(|| format!("{}: cannot create", self.root.display()))?;
        io::save(&path, &grid, settings, &report)
            .with_context(|| format!("saving the field of {}", views.name))?;
        Ok(StoredField {
            key,
            path,
            grid: Arc::new(grid),
            report: Some(report),
            trained_now: true,
            train_s: t0.elapsed().as_secs_f64(),
            load_s: 0.0,
        })
    }
}

/// A name safe as a file-name prefix (the key's hash keeps it unique).
fn sanitize(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .take(64)
        .collect();
    if s.is_empty() {
        "field".into()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_become_safe_prefixes() {
        assert_eq!(sanitize("text-panel"), "text-panel");
        assert_eq!(sanitize("a/b c"), "a_b_c");
        assert_eq!(sanitize(""), "field");
    }
}
