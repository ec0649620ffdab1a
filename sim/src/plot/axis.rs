//! Axis ranges, scales and tick positions/labels.

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Evenly spaced values.
    #[default]
    Linear,
    /// log₂, ticks at powers of two (grid sizes 16…512); values ≤ 0 are not drawn.
    Log2,
    /// log₁₀, ticks at powers of ten; values ≤ 0 are not drawn.
    Log10,
}

impl Scale {
    /// Value → scale space (`None` where the scale is undefined).
    pub(crate) fn fwd(self, v: f64) -> Option<f64> {
        if !v.is_finite() {
            return None;
        }
        match self {
            Scale::Linear => Some(v),
            Scale::Log2 => (v > 0.0).then(|| v.log2()),
            Scale::Log10 => (v > 0.0).then(|| v.log10()),
        }
    }

    fn inv(self, t: f64) -> f64 {
        match self {
            Scale::Linear => t,
            Scale::Log2 => t.exp2(),
            Scale::Log10 => 10f64.powf(t),
        }
    }
}

/// One laid-out axis: its range in scale space and its ticks.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Axis {
    pub scale: Scale,
    /// Range in scale space (e.g. log₂ of the values for `Log2`).
    pub t_lo: f64,
    pub t_hi: f64,
    /// Tick values (data space) and their labels.
    pub ticks: Vec<(f64, String)>,
}

/// Fraction of the span added on each side of auto ranges, so that points
/// at the extremes do not sit on the frame.
const PAD: f64 = 0.05;

impl Axis {
    /// Lays out an axis over `values` (or over `fixed` when given), with at
    /// most about `max_ticks` ticks. `from_zero` forces a linear range to
    /// include 0 (bar charts).
    pub fn new(
        scale: Scale,
        values: impl IntoIterator<Item = f64>,
        fixed: Option<(f64, f64)>,
        max_ticks: usize,
        from_zero: bool,
    ) -> Self {
        let max_ticks = max_ticks.max(2);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for t in values.into_iter().filter_map(|v| scale.fwd(v)) {
            lo = lo.min(t);
            hi = hi.max(t);
        }
        if from_zero && scale == Scale::Linear {
            lo = lo.min(0.0);
            hi = hi.max(0.0);
        }
        let fixed_t = fixed.and_then(|(a, b)| Some((scale.fwd(a)?, scale.fwd(b)?)));
        let (t_lo, t_hi) = match fixed_t {
            Some((a, b)) if a < b => (a, b),
            Some((a, b)) if a > b => (b, a),
            _ => {
                if lo > hi {
                    // No drawable data: a unit range.
                    (lo, hi) = match scale {
                        Scale::Linear => (0.0, 1.0),
                        _ => (0.0, 1.0), // 1…base
                    };
                } else if lo == hi {
                    let d = if scale == Scale::Linear {
                        (lo.abs() * 0.1).max(1e-9)
                    } else {
                        0.5
                    };
                    (lo, hi) = (lo - d, hi + d);
                    if from_zero && lo < 0.0 && hi > 0.0 && scale == Scale::Linear {
                        lo = lo.max(0.0);
                    }
                }
                let pad = PAD * (hi - lo);
                let data_lo = lo;
                let mut lo = lo - pad;
                let hi = hi + pad;
                // A non-negative linear quantity keeps 0 as its floor rather
                // than showing a meaningless negative tick.
                if scale == Scale::Linear && data_lo >= 0.0 && lo < 0.0 {
                    lo = 0.0;
                }
                if from_zero && data_lo >= 0.0 {
                    lo = lo.max(0.0);
                }
                (lo, hi)
            }
        };
        let ticks = match scale {
            Scale::Linear => linear_ticks(t_lo, t_hi, max_ticks),
            Scale::Log2 | Scale::Log10 => log_ticks(scale, t_lo, t_hi, max_ticks),
        };
        Self {
            scale,
            t_lo,
            t_hi,
            ticks,
        }
    }

    /// Position of `v` along the axis, 0 at the low end, 1 at the high end
    /// (outside [0, 1] when out of range); `None` if the scale cannot show it.
    pub fn frac(&self, v: f64) -> Option<f64> {
        let t = self.scale.fwd(v)?;
        Some((t - self.t_lo) / (self.t_hi - self.t_lo))
    }
}

/// 1, 2 or 5 × 10^k, the smallest at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let p = 10f64.powf(raw.log10().floor());
    let m = raw / p;
    let nice = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * p
}

fn linear_ticks(lo: f64, hi: f64, max_ticks: usize) -> Vec<(f64, String)> {
    let step = nice_step((hi - lo) / max_ticks as f64);
    if !(step.is_finite() && step > 0.0) {
        return Vec::new();
    }
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    let values: Vec<f64> = (first..=last).map(|i| i as f64 * step).collect();
    let labels = format_linear(&values, step);
    values.into_iter().zip(labels).collect()
}

/// Labels with as many decimals as the step needs; scientific notation for
/// very large or very small magnitudes.
fn format_linear(values: &[f64], step: f64) -> Vec<String> {
    let max_abs = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let step_exp = step.log10().floor() as i32;
    if max_abs >= 1e6 || (max_abs > 0.0 && max_abs < 1e-3) {
        let exp = max_abs.log10().floor() as i32;
        let decimals = (exp - step_exp).max(0) as usize;
        return values
            .iter()
            .map(|&v| {
                if v.abs() < step * 1e-6 {
                    "0".to_owned()
                } else {
                    format!("{v:.decimals$e}")
                }
            })
            .collect();
    }
    let decimals = (-step_exp).max(0) as usize;
    values
        .iter()
        .map(|&v| {
            let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
            format!("{v:.decimals$}")
        })
        .collect()
}

fn log_ticks(scale: Scale, t_lo: f64, t_hi: f64, max_ticks: usize) -> Vec<(f64, String)> {
    let first = (t_lo - 1e-9).ceil() as i64;
    let last = (t_hi + 1e-9).floor() as i64;
    let powers: Vec<i64> = (first..=last).collect();
    if powers.len() < 2 {
        // Less than one power in view: plain ticks over the values.
        let (lo, hi) = (scale.inv(t_lo), scale.inv(t_hi));
        return linear_ticks(lo, hi, max_ticks)
            .into_iter()
            .filter(|(v, _)| *v > 0.0)
            .collect();
    }
    let every = powers.len().div_ceil(max_ticks).max(1);
    powers
        .iter()
        .filter(|e| (*e - first) % every as i64 == 0)
        .map(|&e| {
            let v = scale.inv(e as f64);
            (v, format_power(v))
        })
        .collect()
}

/// "16", "512", "0.25", "1e6", "1e-4": short labels for powers.
fn format_power(v: f64) -> String {
    if (1e-3..1e6).contains(&v) {
        let s = format!("{v:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(a: &Axis) -> Vec<&str> {
        a.ticks.iter().map(|(_, s)| s.as_str()).collect()
    }

    #[test]
    fn linear_ticks_are_round_numbers() {
        let a = Axis::new(Scale::Linear, [0.61, 0.94], None, 6, false);
        assert_eq!(labels(&a), ["0.6", "0.7", "0.8", "0.9"]);
        assert!(a.frac(0.61).unwrap() > 0.0 && a.frac(0.94).unwrap() < 1.0);
        let b = Axis::new(Scale::Linear, [0.0, 3.2e7], None, 5, false);
        assert_eq!(b.t_lo, 0.0, "non-negative data keeps a 0 floor");
        assert_eq!(labels(&b)[..3], ["0", "1e7", "2e7"]);
    }

    #[test]
    fn log2_ticks_at_powers_of_two() {
        let a = Axis::new(
            Scale::Log2,
            [16.0, 32.0, 64.0, 128.0, 256.0, 512.0],
            None,
            10,
            false,
        );
        assert_eq!(labels(&a), ["16", "32", "64", "128", "256", "512"]);
        let (f16, f32_, f512) = (
            a.frac(16.0).unwrap(),
            a.frac(32.0).unwrap(),
            a.frac(512.0).unwrap(),
        );
        assert!(
            (f32_ - f16 - (f512 - f16) / 5.0).abs() < 1e-12,
            "equal spacing per doubling"
        );
        assert_eq!(a.frac(0.0), None);
    }

    #[test]
    fn degenerate_ranges_still_have_ticks() {
        let a = Axis::new(Scale::Linear, [5.0, 5.0], None, 5, false);
        assert!(a.t_lo < 5.0 && a.t_hi > 5.0 && !a.ticks.is_empty());
        let b = Axis::new(Scale::Linear, std::iter::empty(), None, 5, false);
        assert!(b.t_lo < b.t_hi && !b.ticks.is_empty());
        let c = Axis::new(Scale::Log2, [20.0, 30.0], None, 5, false);
        assert!(!c.ticks.is_empty());
    }
}
