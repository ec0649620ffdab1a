//! The profiler's dynamic range against its own noise.
//!
//! A planner can only trade bytes for quality if quality moves with the
//! configuration by more than its measurement scatters. For each network
//! this compares its largest sample bake (most bytes) with its smallest on
//! the same held-out views: the paired difference of their SSIM with a 95 %
//! bootstrap interval over the views. When the interval excludes zero the
//! range exceeds the noise of the views; when it does not, the fitted curve
//! is flat within its noise and the plan's choices for that network are
//! not backed by the measurements.

use super::bakes::Baked;
use crate::eval::stats::{paired_difference, Interval};
use std::fmt::Write as _;

/// One network's range.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NetworkRange {
    /// The network (the sample bakes' object name).
    pub network: String,
    /// (g, p) of the sample with the fewest file bytes.
    pub low: (u32, u32),
    /// (g, p) of the sample with the most file bytes.
    pub high: (u32, u32),
    /// SSIM(high) − SSIM(low) paired over the held-out views; `None` when
    /// either bake has no per-view scores (stored before they were kept)
    /// or their views differ in number.
    pub ssim: Option<Interval>,
    /// SSIM(high) − SSIM(low) of the means (always known).
    pub mean_diff: f64,
}

impl NetworkRange {
    /// Whether the interval excludes zero.
    pub fn significant(&self) -> Option<bool> {
        self.ssim.map(|i| i.lo > 0.0 || i.hi < 0.0)
    }
}

/// Each network's range, in the order the networks first appear in
/// `samples`. A network with a single sample is left out.
pub fn ranges(samples: &[Baked]) -> Vec<NetworkRange> {
    let mut names: Vec<&str> = Vec::new();
    for b in samples {
        if !names.contains(&b.sample.object.as_str()) {
            names.push(&b.sample.object);
        }
    }
    names
        .into_iter()
        .filter_map(|name| {
            let mine: Vec<&Baked> = samples.iter().filter(|b| b.sample.object == name).collect();
            // Ties in bytes: the larger (g, p) is the richer configuration.
            let key = |b: &&Baked| (b.sample.size_bytes, b.sample.g, b.sample.p);
            let low = mine.iter().copied().min_by_key(key)?;
            let high = mine.iter().copied().max_by_key(key)?;
            if std::ptr::eq(low, high) {
                return None;
            }
            let ssim = match (&high.views, &low.views) {
                (Some(h), Some(l)) if !h.ssim.is_empty() => paired_difference(&h.ssim, &l.ssim),
                _ => None,
            };
            Some(NetworkRange {
                network: name.to_string(),
                low: (low.sample.g, low.sample.p),
                high: (high.sample.g, high.sample.p),
                ssim,
                mean_diff: high.sample.ssim - low.sample.ssim,
            })
        })
        .collect()
}

/// The report's lines: one per network and a verdict line.
pub fn lines(ranges: &[NetworkRange]) -> String {
    let mut s = String::new();
    if ranges.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "profiler range against its noise: SSIM of the largest minus the smallest sample bake, paired over the held-out views [95 % interval]:"
    );
    for r in ranges {
        let cell = match (r.ssim, r.significant()) {
            (Some(i), Some(true)) => format!("{} exceeds the views' noise", i.show_signed(4)),
            (Some(i), _) => format!("{} within the views' noise", i.show_signed(4)),
            (None, _) => format!(
                "{:+.4} (no per-view scores: stored before they were kept)",
                r.mean_diff
            ),
        };
        let _ = writeln!(
            s,
            "  {:<12} ({}, {}) − ({}, {}): {}",
            r.network, r.high.0, r.high.1, r.low.0, r.low.1, cell
        );
    }
    let known = ranges.iter().filter(|r| r.ssim.is_some()).count();
    let above = ranges
        .iter()
        .filter(|r| r.significant() == Some(true))
        .count();
    let _ = writeln!(
        s,
        "  {above} of {known} networks with per-view scores have a range that exceeds their noise"
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::sweep::Sample;
    use crate::pipeline::bakes::HeldOutScores;
    use std::path::PathBuf;

    fn baked(object: &str, g: u32, p: u32, bytes: u64, ssim: &[f64]) -> Baked {
        let mean = ssim.iter().sum::<f64>() / ssim.len() as f64;
        Baked {
            sample: Sample {
                object: object.into(),
                g,
                p,
                size_bytes: bytes,
                gpu_bytes: bytes,
                quads: 1,
                ssim: mean,
                psnr: 20.0,
                lpips: None,
            },
            dir: PathBuf::from("x"),
            seconds: 0.0,
            cached: true,
            train_s: 0.0,
            field_trained: false,
            views: Some(HeldOutScores {
                ssim: ssim.to_vec(),
                psnr: vec![20.0; ssim.len()],
            }),
        }
    }

    #[test]
    fn a_consistent_gain_exceeds_the_noise_and_a_scatter_does_not() {
        let samples = vec![
            baked("a", 16, 3, 100, &[0.70, 0.60, 0.80, 0.65]),
            baked("a", 64, 17, 900, &[0.75, 0.66, 0.85, 0.71]),
            baked("a", 32, 9, 400, &[0.72, 0.62, 0.82, 0.68]),
            baked("b", 16, 3, 100, &[0.70, 0.60, 0.80, 0.65]),
            baked("b", 64, 17, 900, &[0.80, 0.55, 0.85, 0.60]),
        ];
        let r = ranges(&samples);
        assert_eq!(r.len(), 2);
        assert_eq!((r[0].low, r[0].high), ((16, 3), (64, 17)));
        assert_eq!(r[0].significant(), Some(true));
        assert!((r[0].mean_diff - 0.055).abs() < 1e-9);
        // b's views move both ways: its mean gain of +0.0125 is noise.
        assert_eq!(r[1].significant(), Some(false));
        let text = lines(&r);
        assert!(text.contains("1 of 2 networks"), "{text}");
        assert!(
            text.contains("exceeds") && text.contains("within"),
            "{text}"
        );
    }

    #[test]
    fn stored_entries_without_views_say_so_and_single_samples_are_left_out() {
        let mut old = baked("a", 16, 3, 100, &[0.7]);
        old.views = None;
        let samples = vec![
            old,
            baked("a", 64, 17, 900, &[0.8]),
            baked("c", 16, 3, 1, &[0.5]),
        ];
        let r = ranges(&samples);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].significant(), None);
        assert!(lines(&r).contains("stored before"), "{}", lines(&r));
        assert!(lines(&[]).is_empty());
    }
}
