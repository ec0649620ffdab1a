//! One way to write outputs: build beside the destination, rename into
//! place only when everything has succeeded.
//!
//! - [`write_file`]: a file through a temporary name unique to this writer
//!   (process id, a per-process counter and the clock), synced, then renamed
//!   over the destination. A failure removes the temporary and leaves the
//!   old file byte-identical.
//! - [`StagedDir`]: a folder built under a hidden unique name beside its
//!   destination. [`StagedDir::commit`] swaps it in whole: the old folder is
//!   moved aside, the new one renamed into place, then the old one removed
//!   (moved back if the second rename fails). Dropped without a commit, the
//!   staging folder is removed and the destination never touched.
//! - Never delete what we did not create: a destination folder is replaced
//!   only if every entry in it is one the caller recognises as its own
//!   output ([`check_replaceable`], also called by the commit).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Errors of writing an output; each names the path.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A file or folder could not be written, renamed or removed.
    #[error("{}: {action}: {cause}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The cause.
        cause: std::io::Error,
    },
    /// The destination holds something this command did not write.
    #[error("{}: {what}; {hint}", path.display())]
    NotOurs {
        /// The destination (or the foreign entry in it).
        path: PathBuf,
        /// What is there.
        what: String,
        /// How to proceed.
        hint: String,
    },
}

impl OutputError {
    fn io(path: &Path, action: &'static str) -> impl FnOnce(std::io::Error) -> OutputError {
        let path = path.to_path_buf();
        move |cause| OutputError::Io {
            path,
            action,
            cause,
        }
    }
}

impl OutputError {
    /// The underlying I/O error (for callers whose errors name the path
    /// themselves); other errors become `io::Error::other` of the message.
    pub fn into_io(self) -> std::io::Error {
        match self {
            OutputError::Io { cause, .. } => cause,
            other => std::io::Error::other(other.to_string()),
        }
    }
}

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A hidden name beside `dest` no other writer uses: `.{name}.{tag}-{pid}-{n}-{ns}`.
pub fn unique_sibling(dest: &Path, tag: &str) -> PathBuf {
    let name = dest
        .file_name()
        .map_or_else(|| "out".to_string(), |n| n.to_string_lossy().into_owned());
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    dest.with_file_name(format!(".{name}.{tag}-{}-{n}-{ns}", std::process::id()))
}

/// Writes `bytes` to `path` atomically (unique temporary, then rename).
/// The parent folder must exist ([`create_parent`]). Returns the bytes
/// written.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<u64, OutputError> {
    use std::io::Write as _;
    if path.is_dir() {
        return Err(OutputError::NotOurs {
            path: path.to_path_buf(),
            what: "is a folder, not a file".into(),
            hint: "choose a file name".into(),
        });
    }
    let tmp = unique_sibling(path, "tmp");
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        // No fsync: the guarantee is about failed commands (a full disk
        // fails `write_all`), not power loss, and captures write thousands.
        f.write_all(bytes)?;
        f.flush()
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(OutputError::io(path, "cannot write")(e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        OutputError::io(path, "cannot rename into place")(e)
    })?;
    Ok(bytes.len() as u64)
}

/// Creates the parent folder of `path` (and its parents) if needed.
pub fn create_parent(path: &Path) -> Result<(), OutputError> {
    match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => {
            std::fs::create_dir_all(parent).map_err(OutputError::io(parent, "cannot create"))
        }
        None => Ok(()),
    }
}

/// Checks that `dest` can be replaced: absent, or a folder every entry of
/// which `ours` recognises (or a leftover temporary of ours). Names the
/// first foreign entry otherwise; `hint` says how to proceed.
pub fn check_replaceable(
    dest: &Path,
    ours: &dyn Fn(&str) -> bool,
    hint: &str,
) -> Result<(), OutputError> {
    let meta = match std::fs::symlink_metadata(dest) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(OutputError::io(dest, "cannot inspect")(e)),
    };
    if !meta.is_dir() {
        return Err(OutputError::NotOurs {
            path: dest.to_path_buf(),
            what: "exists and is not a folder".into(),
            hint: hint.into(),
        });
    }
    for e in std::fs::read_dir(dest).map_err(OutputError::io(dest, "cannot list"))? {
        let e = e.map_err(OutputError::io(dest, "cannot list"))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if !ours(&name) {
            return Err(OutputError::NotOurs {
                path: e.path(),
                what: "was not written by this command, so it is not replaced".into(),
                hint: hint.into(),
            });
        }
    }
    Ok(())
}

/// A folder being built beside its destination.
#[derive(Debug)]
pub struct StagedDir {
    staging: PathBuf,
    dest: PathBuf,
    done: bool,
}

impl StagedDir {
    /// Creates an empty staging folder beside `dest` (and `dest`'s parent).
    pub fn new(dest: &Path) -> Result<StagedDir, OutputError> {
        if let Some(parent) = dest.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(OutputError::io(parent, "cannot create"))?;
        }
        let staging = unique_sibling(dest, "new");
        std::fs::create_dir(&staging).map_err(OutputError::io(&staging, "cannot create"))?;
        Ok(StagedDir {
            staging,
            dest: dest.to_path_buf(),
            done: false,
        })
    }

    /// Where to build the new contents.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The destination.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Replaces the destination with the staged folder, whole. `ours` and
    /// `hint` as in [`check_replaceable`] (checked again here: the
    /// destination may have changed since the work began).
    pub fn commit(mut self, ours: &dyn Fn(&str) -> bool, hint: &str) -> Result<(), OutputError> {
        check_replaceable(&self.dest, ours, hint)?;
        let dest = self.dest.clone();
        if std::fs::symlink_metadata(&dest).is_ok() {
            let old = unique_sibling(&dest, "old");
            std::fs::rename(&dest, &old).map_err(OutputError::io(&dest, "cannot move aside"))?;
            if let Err(e) = std::fs::rename(&self.staging, &dest) {
                // Put the old folder back: the failed command leaves it as it was.
                let _ = std::fs::rename(&old, &dest);
                return Err(OutputError::io(&dest, "cannot rename into place")(e));
            }
            self.done = true;
            if let Err(e) = std::fs::remove_dir_all(&old) {
                eprintln!(
                    "warning: {}: the replaced folder could not be removed: {e}",
                    old.display()
                );
            }
        } else {
            std::fs::rename(&self.staging, &dest)
                .map_err(OutputError::io(&dest, "cannot rename into place"))?;
            self.done = true;
        }
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_stage_leaves_the_destination_alone() {
        let d = tempfile::tempdir().unwrap();
        let dest = d.path().join("out");
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("a"), "old").unwrap();
        {
            let s = StagedDir::new(&dest).unwrap();
            std::fs::write(s.path().join("a"), "new").unwrap();
        }
        assert_eq!(std::fs::read_to_string(dest.join("a")).unwrap(), "old");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_commit_replaces_the_folder_whole() {
        let d = tempfile::tempdir().unwrap();
        let dest = d.path().join("out");
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("a"), "old").unwrap();
        std::fs::write(dest.join("b"), "old").unwrap();
        let s = StagedDir::new(&dest).unwrap();
        std::fs::write(s.path().join("a"), "new").unwrap();
        s.commit(&|_| true, "").unwrap();
        assert_eq!(std::fs::read_to_string(dest.join("a")).unwrap(), "new");
        assert!(!dest.join("b").exists());
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_foreign_entry_is_never_replaced() {
        let d = tempfile::tempdir().unwrap();
        let dest = d.path().join("out");
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("notes.txt"), "mine").unwrap();
        let s = StagedDir::new(&dest).unwrap();
        let e = s.commit(&|n| n == "a", "move it away").unwrap_err();
        assert!(e.to_string().contains("notes.txt"), "{e}");
        assert!(e.to_string().contains("move it away"), "{e}");
        assert_eq!(
            std::fs::read_to_string(dest.join("notes.txt")).unwrap(),
            "mine"
        );
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn temporary_names_are_unique_and_hidden() {
        let p = Path::new("/x/out");
        let (a, b) = (unique_sibling(p, "tmp"), unique_sibling(p, "tmp"));
        assert_ne!(a, b);
        assert_eq!(a.parent(), p.parent());
        assert!(a
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with(".out.tmp-"));
    }

    #[test]
    fn write_file_replaces_atomically() {
        let d = tempfile::tempdir().unwrap();
        let f = d.path().join("sub/f.txt");
        assert!(write_file(&f, b"one").is_err(), "no parent folder");
        create_parent(&f).unwrap();
        write_file(&f, b"one").unwrap();
        write_file(&f, b"two").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(d.path().join("sub")).unwrap().count(), 1);
        assert!(write_file(d.path(), b"x").is_err());
    }
}
