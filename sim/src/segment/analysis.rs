//! Per-object maximum detail frequency over the training views, and the
//! dedicated-vs-shared decision.

use super::frequency::{detail_frequency, DetailFrequency, FrequencyOptions};
use super::input::{SegCapture, SegmentError};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The detail frequencies of one object.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectFrequency {
    /// Object name.
    pub name: String,
    /// Its label in the instance masks (index + 1).
    pub label: u8,
    /// Per training view: the view's `file_path` and its measure (`None`
    /// when the object covers fewer than `min_pixels` pixels there).
    pub per_image: Vec<(String, Option<DetailFrequency>)>,
    /// The maximum over views, cycles per object diameter.
    pub max_frequency: f64,
    /// The view where the maximum is reached.
    pub peak_image: String,
}

/// The frequency analysis of a capture.
#[derive(Debug, Clone, PartialEq)]
pub struct Analysis {
    /// One entry per object, in the capture's order.
    pub objects: Vec<ObjectFrequency>,
}

impl Analysis {
    /// Object indices sorted by decreasing maximum frequency (ties by index).
    pub fn ranking(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.objects.len()).collect();
        idx.sort_by(|&a, &b| {
            self.objects[b]
                .max_frequency
                .total_cmp(&self.objects[a].max_frequency)
                .then(a.cmp(&b))
        });
        idx
    }
}

/// Measures every object in every training view (in parallel over views)
/// and keeps each object's maximum. An object measurable in no view is an
/// error naming it.
pub fn analyse(cap: &SegCapture, opts: &FrequencyOptions) -> Result<Analysis, SegmentError> {
    cap.validate()?;
    let n = cap.objects.len();
    // per_frame[f][o]
    let per_frame: Vec<Vec<Option<DetailFrequency>>> = cap
        .train
        .par_iter()
        .map(|f| {
            (0..n)
                .map(|o| detail_frequency(&f.image, &f.mask, (o + 1) as u8, opts))
                .collect()
        })
        .collect();
    let mut objects = Vec::with_capacity(n);
    for (o, name) in cap.objects.iter().enumerate() {
        let per_image: Vec<(String, Option<DetailFrequency>)> = cap
            .train
            .iter()
            .zip(&per_frame)
            .map(|(f, v)| (f.file_path.clone(), v[o]))
            .collect();
        let peak = per_image
            .iter()
            .filter_map(|(p, d)| d.map(|d| (p, d.cycles_per_diameter)))
            .fold(None::<(&String, f64)>, |best, (p, v)| match best {
                Some((_, bv)) if bv >= v => best,
                _ => Some((p, v)),
            });
        let Some((peak_image, max_frequency)) = peak.map(|(p, v)| (p.clone(), v)) else {
            return Err(SegmentError::Invalid(format!(
                "{}: object {name:?} (mask label {}) covers fewer than {} pixels in every training view; \
                 lower the minimum (--min-pixels) or drop the object",
                cap.source,
                o + 1,
                opts.min_pixels
            )));
        };
        objects.push(ObjectFrequency {
            name: name.clone(),
            label: (o + 1) as u8,
            per_image,
            max_frequency,
            peak_image,
        });
    }
    Ok(Analysis { objects })
}

/// Whether an object gets its own network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Decision {
    /// Its own NeRF, trained on its enlarged views.
    Dedicated,
    /// One NeRF shared by every such object, trained on the original views
    /// with the dedicated objects removed.
    Shared,
}

/// Where the threshold came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlphaSource {
    /// Given by the user (`--alpha`).
    User,
    /// The default: the lowest maximum frequency among the objects (the
    /// NeRFlex paper's evaluation setting).
    LowestMaximum,
}

/// The threshold and the decision for each object.
#[derive(Debug, Clone, PartialEq)]
pub struct Decisions {
    /// Threshold α, cycles per object diameter.
    pub alpha: f64,
    /// Where α came from.
    pub alpha_source: AlphaSource,
    /// One per object, in the analysis' order.
    pub decisions: Vec<Decision>,
}

/// Applies the NeRFlex rule: an object whose maximum frequency **exceeds**
/// α gets a dedicated NeRF; the others share one. With the default α (the
/// lowest maximum) the lowest object(s) form the shared group on their own,
/// so every object still gets a network of its own when the maxima differ.
pub fn decide(analysis: &Analysis, alpha: Option<f64>) -> Result<Decisions, SegmentError> {
    let (alpha, alpha_source) = match alpha {
        Some(a) if a.is_finite() && a >= 0.0 => (a, AlphaSource::User),
        Some(a) => {
            return Err(SegmentError::Invalid(format!(
                "--alpha {a}: the threshold must be a finite frequency ≥ 0 (cycles per object diameter)"
            )))
        }
        None => (
            analysis
                .objects
                .iter()
                .map(|o| o.max_frequency)
                .fold(f64::INFINITY, f64::min),
            AlphaSource::LowestMaximum,
        ),
    };
    if !alpha.is_finite() {
        return Err(SegmentError::Invalid("no objects to decide on".into()));
    }
    let decisions = analysis
        .objects
        .iter()
        .map(|o| {
            if o.max_frequency > alpha {
                Decision::Dedicated
            } else {
                Decision::Shared
            }
        })
        .collect();
    Ok(Decisions {
        alpha,
        alpha_source,
        decisions,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn analysis(maxima: &[f64]) -> Analysis {
        Analysis {
            objects: maxima
                .iter()
                .enumerate()
                .map(|(i, &m)| ObjectFrequency {
                    name: format!("o{i}"),
                    label: (i + 1) as u8,
                    per_image: Vec::new(),
                    max_frequency: m,
                    peak_image: String::new(),
                })
                .collect(),
        }
    }

    #[test]
    fn default_alpha_is_the_lowest_maximum_and_the_rule_is_strict() {
        let a = analysis(&[12.0, 5.0, 30.0]);
        let d = decide(&a, None).unwrap();
        assert_eq!(d.alpha, 5.0);
        assert_eq!(d.alpha_source, AlphaSource::LowestMaximum);
        use Decision::*;
        assert_eq!(d.decisions, vec![Dedicated, Shared, Dedicated]);
        assert_eq!(a.ranking(), vec![2, 0, 1]);
    }

    #[test]
    fn user_alpha_groups_the_rest_and_bad_alpha_is_an_error() {
        let a = analysis(&[12.0, 5.0, 30.0]);
        let d = decide(&a, Some(12.0)).unwrap();
        use Decision::*;
        assert_eq!(d.decisions, vec![Shared, Shared, Dedicated]);
        assert_eq!(d.alpha_source, AlphaSource::User);
        let d = decide(&a, Some(100.0)).unwrap();
        assert!(d.decisions.iter().all(|&x| x == Shared));
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let e = decide(&a, Some(bad)).unwrap_err().to_string();
            assert!(e.contains("--alpha"), "{e}");
        }
        assert!(decide(&analysis(&[]), None).is_err());
    }
}
