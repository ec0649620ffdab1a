//! One validation per kind of input: numbers that become `f32`, sizes
//! against the memory they imply, duplicate checks, and files that must be
//! regular files before they are read.
//!
//! Every check returns a message naming the limit and why; callers add the
//! file or flag.

use std::path::Path;

/// Largest magnitude accepted for a coordinate, focal length or principal
/// point read from a file. The code works in `f32`; products of two such
/// values (projection, squared distances) must stay finite there, and
/// (1e8)² = 1e16 is far below `f32::MAX` ≈ 3.4e38. Real scenes are a few
/// units across, with focal lengths of thousands of pixels.
pub const MAX_MAGNITUDE: f64 = 1e8;

/// Checks that `v` is finite and at most [`MAX_MAGNITUDE`] in magnitude, so
/// it stays finite (and usable in products) once converted to `f32`.
pub fn f32_value(what: &str, v: f64) -> Result<f32, String> {
    if !v.is_finite() {
        return Err(format!("{what} = {v} is not a finite number"));
    }
    if v.abs() > MAX_MAGNITUDE {
        return Err(format!(
            "{what} = {v:e} exceeds ±{MAX_MAGNITUDE:e} (values become f32, whose products must stay finite)"
        ));
    }
    Ok(v as f32)
}

/// [`f32_value`] for a value already in `f32`.
pub fn f32_finite(what: &str, v: f32) -> Result<f32, String> {
    f32_value(what, f64::from(v))
}

/// Environment variable overriding the memory limit (bytes), e.g. to test
/// the size checks without a machine of that size.
pub const MEMORY_LIMIT_ENV: &str = "NERFLEX_MEMORY_LIMIT";

/// The memory one command may plan to allocate, bytes: half the machine's
/// physical memory (`MemTotal` of `/proc/meminfo`; 16 GiB where that is
/// unknown), leaving the rest to the system and other work, or
/// [`MEMORY_LIMIT_ENV`]. Beyond it an allocation may fail, and a failed
/// allocation aborts the process instead of giving an error.
pub fn memory_limit() -> u64 {
    if let Some(v) = std::env::var(MEMORY_LIMIT_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
    {
        return v;
    }
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find_map(|l| l.strip_prefix("MemTotal:"))
                .and_then(|r| r.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(8 << 30, |kib| kib * 1024 / 2)
}

/// Checks that `bytes` (what `what` implies: e.g. `--frames 10⁹ × 64 B per
/// frame`) fits in [`memory_limit`]. `why` says what the memory is for.
pub fn memory(what: &str, bytes: u128, why: &str) -> Result<(), String> {
    let limit = memory_limit();
    if bytes > u128::from(limit) {
        return Err(format!(
            "{what} needs {} of memory for {why}, more than the limit of {} (half this machine's memory; {MEMORY_LIMIT_ENV} overrides)",
            human(bytes),
            human(u128::from(limit))
        ));
    }
    Ok(())
}

fn human(bytes: u128) -> String {
    const GIB: f64 = (1u64 << 30) as f64;
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", bytes as f64 / GIB)
    } else {
        format!("{:.1} MiB", bytes as f64 / (1u64 << 20) as f64)
    }
}

/// The first value that occurs twice, in O(n log n) (sort of references).
pub fn first_duplicate<T: Ord>(items: &[T]) -> Option<&T> {
    let mut sorted: Vec<&T> = items.iter().collect();
    sorted.sort_unstable();
    sorted.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
}

/// Refuses what is not a regular file (FIFO, socket, device, folder) before
/// it is opened: opening a FIFO blocks until a writer comes, reading a
/// device never ends.
pub fn regular_file(path: &Path) -> std::io::Result<()> {
    let meta = std::fs::metadata(path)?;
    if meta.is_file() {
        return Ok(());
    }
    let kind = if meta.is_dir() {
        "a folder"
    } else {
        "a FIFO, socket or device"
    };
    Err(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!("not a regular file ({kind}); refused before reading"),
    ))
}

/// [`std::fs::read`] of a regular file only.
pub fn read(path: &Path) -> std::io::Result<Vec<u8>> {
    regular_file(path)?;
    std::fs::read(path)
}

/// [`std::fs::read_to_string`] of a regular file only.
pub fn read_to_string(path: &Path) -> std::io::Result<String> {
    regular_file(path)?;
    std::fs::read_to_string(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_that_overflow_f32_are_refused() {
        assert_eq!(f32_value("x", 2.5), Ok(2.5));
        for v in [1e39, -1e39, f64::NAN, f64::INFINITY, 1e9] {
            let e = f32_value("tx", v).unwrap_err();
            assert!(e.starts_with("tx = "), "{e}");
        }
    }

    #[test]
    fn duplicates_are_found_in_any_order() {
        assert_eq!(first_duplicate(&[3, 1, 2]), None);
        assert_eq!(first_duplicate(&[3, 1, 2, 1]), Some(&1));
        let big: Vec<u32> = (0..2_000_000).collect();
        assert_eq!(first_duplicate(&big), None);
    }

    #[test]
    fn sizes_beyond_the_limit_name_it() {
        let e = memory("--frames 4294967296", 1 << 70, "the frame log").unwrap_err();
        assert!(e.contains("--frames") && e.contains("limit"), "{e}");
        assert!(memory("x", 1024, "y").is_ok());
    }

    #[test]
    fn folders_are_not_regular_files() {
        let d = tempfile::tempdir().unwrap();
        assert!(read(d.path()).is_err());
        let f = d.path().join("f");
        std::fs::write(&f, "x").unwrap();
        assert_eq!(read(&f).unwrap(), b"x");
    }
}
