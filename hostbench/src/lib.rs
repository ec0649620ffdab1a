//! Shared helpers of the nerflex benchmarks and of the `summary` binary.

use nerflex_core::mck::Config;
use nerflex_core::units::{Bytes, QualityQ};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The paper's problem: objects, configurations per object, budget, unit.
pub const PAPER_OBJECTS: usize = 5;
/// 9 grid resolutions × 5 patch sizes.
pub const PAPER_CONFIGS: usize = 45;
/// iPhone 13's 240 MB.
pub const PAPER_BUDGET: Bytes = Bytes(240_000_000);
/// 0.1 MB.
pub const PAPER_UNIT: Bytes = Bytes(100_000);

/// Patch sizes cycled through by [`synthetic_objects`].
const PATCHES: [f64; 5] = [5.0, 9.0, 13.0, 17.0, 21.0];

/// Configuration tables shaped like real profiles, deterministic:
/// configuration k of an object has p = 5, 9, 13, 17, 21 (cycling) and
/// g = 32 + 16·⌊k/5⌋ (so 45 configurations form our 9 × 5 grid; the paper gives no grid),
/// size `k_s·g³·p² + 1.5 MB` with `k_s` chosen so (128, 17) is 40–110 MB,
/// quality `m − k_q/((g+32)³·(p+4)²)` from about 0.80 at (32, 5) to 0.93–0.96
/// at (128, 17), varying per object.
pub fn synthetic_objects(objects: usize, configs: usize) -> Vec<Vec<Config>> {
    (0..objects)
        .map(|i| {
            // Per-object variety without randomness.
            let t = ((i * 37) % 11) as f64 / 10.0;
            let s128 = 40e6 + 70e6 * t;
            let ks = (s128 - 1.5e6) / (128f64.powi(3) * 17f64.powi(2));
            let q128 = 0.93 + 0.03 * (1.0 - t);
            let d = |g: f64, p: f64| (g + 32.0).powi(3) * (p + 4.0).powi(2);
            let kq = (q128 - 0.80) / (1.0 / d(32.0, 5.0) - 1.0 / d(128.0, 17.0));
            let mq = q128 + kq / d(128.0, 17.0);
            (0..configs)
                .map(|k| {
                    let g = 32.0 + 16.0 * (k / PATCHES.len()) as f64;
                    let p = PATCHES[k % PATCHES.len()];
                    Config {
                        size: Bytes((ks * g.powi(3) * p * p + 1.5e6).ceil() as u64),
                        quality: QualityQ::saturating_from_f64(mq - kq / d(g, p)),
                    }
                })
                .collect()
        })
        .collect()
}

/// criterion's estimate of one benchmark's time per iteration, in
/// nanoseconds: the figure criterion prints (the slope of its linear
/// sampling when it has one, else the mean).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Time per iteration, ns.
    pub ns: f64,
    /// Lower bound of its confidence interval, ns.
    pub low_ns: f64,
    /// Upper bound, ns.
    pub high_ns: f64,
}

#[derive(Deserialize)]
struct Estimates {
    mean: PointEstimate,
    #[serde(default)]
    slope: Option<PointEstimate>,
}

#[derive(Deserialize)]
struct PointEstimate {
    point_estimate: f64,
    confidence_interval: Interval,
}

#[derive(Deserialize)]
struct Interval {
    lower_bound: f64,
    upper_bound: f64,
}

/// criterion's output folder: `$CARGO_TARGET_DIR/criterion` or the
/// workspace's `target/criterion`.
pub fn criterion_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(t) => PathBuf::from(t).join("criterion"),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/criterion"),
    }
}

/// Reads `<dir>/<bench>/new/estimates.json` (bench id as criterion writes
/// it, e.g. `mck/paper`); `Ok(None)` when that bench has not been run.
pub fn read_estimate(dir: &Path, bench: &str) -> anyhow::Result<Option<Estimate>> {
    let path = dir.join(bench).join("new").join("estimates.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(anyhow::anyhow!("{}: {e}", path.display())),
    };
    let e: Estimates = serde_json::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: not criterion estimates: {e}", path.display()))?;
    let p = e.slope.unwrap_or(e.mean);
    Ok(Some(Estimate {
        ns: p.point_estimate,
        low_ns: p.confidence_interval.lower_bound,
        high_ns: p.confidence_interval.upper_bound,
    }))
}

/// A duration in ns as a short human figure (`1.23 ms`).
pub fn human_ns(ns: f64) -> String {
    let (v, unit) = if ns >= 1e9 {
        (ns / 1e9, "s")
    } else if ns >= 1e6 {
        (ns / 1e6, "ms")
    } else if ns >= 1e3 {
        (ns / 1e3, "µs")
    } else {
        (ns, "ns")
    };
    format!("{v:.3} {unit}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_paper_instance_is_binding() {
        let objs = synthetic_objects(PAPER_OBJECTS, PAPER_CONFIGS);
        let dearest: u64 = objs
            .iter()
            .map(|o| o.iter().map(|c| c.size.0).max().unwrap())
            .sum();
        let cheapest: u64 = objs
            .iter()
            .map(|o| o.iter().map(|c| c.size.0).min().unwrap())
            .sum();
        assert!(cheapest < PAPER_BUDGET.0 && PAPER_BUDGET.0 < dearest);
    }

    #[test]
    fn estimates_are_read_or_missing() {
        let dir = std::env::temp_dir().join(format!("nerflex-hostbench-{}", std::process::id()));
        let bench = dir.join("g/x/new");
        std::fs::create_dir_all(&bench).unwrap();
        std::fs::write(
            bench.join("estimates.json"),
            r#"{"mean": {"point_estimate": 1500.0, "standard_error": 1.0, "confidence_level": 0.95,
                "confidence_interval": {"lower_bound": 1400.0, "upper_bound": 1600.0, "confidence_level": 0.95}},
                "slope": null}"#,
        )
        .unwrap();
        let e = read_estimate(&dir, "g/x").unwrap().unwrap();
        assert_eq!(e.ns, 1500.0);
        assert_eq!(read_estimate(&dir, "g/none").unwrap(), None);
        assert_eq!(human_ns(1500.0), "1.500 µs");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
