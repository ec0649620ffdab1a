//! Does the segmentation's measure predict what a dedicated network gains?
//!
//! For every scene object: its maximum detail frequency in two readings —
//! the **current** measure (cycles per object diameter in a fixed band,
//! `segment::frequency`) and the paper's **in-image** reading (cycles per
//! pixel of the view, the same spectrum's 75 % radius before it is scaled
//! by the object's diameter; maximum over the training views) — against
//! the measured gain of a dedicated network over a shared one: the
//! object's SSIM in its box of each held-out view, Block-NeRF (one network
//! per object) − Single-NeRF (one network for the scene), both at the same
//! (g, p), paired over views. Spearman's ρ of each reading against the
//! gains, over every object of every scene, says which one ranks objects
//! the way the gains do.

use super::compare::{measured, paired_object};
use super::stats::{spearman_test, Interval, RankCorrelation};
use super::EvalReport;
use crate::baselines::Method;
use crate::procedural::ObjectKind;
use crate::segment::{Decision, Segmentation};
use serde::{Deserialize, Serialize};

/// One scene object as the segmentation saw it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectDetail {
    /// Scene object name.
    pub name: String,
    /// Its network (the segmentation's folder).
    pub network: String,
    /// Whether the network is its own.
    pub dedicated: bool,
    /// Geometric complexity: quad faces at a 64³ grid (built-in objects only).
    pub complexity_quads: Option<u64>,
    /// The current measure: maximum over training views, cycles per object diameter.
    pub max_cycles_per_diameter: f64,
    /// The paper's in-image reading: maximum over training views, cycles per pixel.
    pub max_cycles_per_pixel: Option<f64>,
}

/// The per-object records of a segmentation (complexity for built-in
/// objects, whose names are their kinds).
pub fn object_details(seg: &Segmentation) -> Vec<ObjectDetail> {
    seg.objects
        .iter()
        .map(|o| ObjectDetail {
            name: o.name.clone(),
            network: o.folder.clone(),
            dedicated: o.decision == Decision::Dedicated,
            complexity_quads: o
                .name
                .parse::<ObjectKind>()
                .ok()
                .map(crate::procedural::complexity::complexity_quads),
            max_cycles_per_diameter: o.max_frequency,
            max_cycles_per_pixel: o
                .per_image
                .iter()
                .filter_map(|i| i.cycles_per_pixel)
                .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v)))),
        })
        .collect()
}

/// One object's readings and gain.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectGain {
    /// Scene.
    pub scene: String,
    /// Object.
    pub object: String,
    /// Whether the segmentation gave it its own network.
    pub dedicated: bool,
    /// Current measure, cycles per object diameter.
    pub cycles_per_diameter: f64,
    /// In-image reading, cycles per pixel.
    pub cycles_per_pixel: Option<f64>,
    /// SSIM in its box, Block-NeRF − Single-NeRF, over the held-out views.
    pub gain: Interval,
}

/// The whole comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct DetailAnalysis {
    /// Every object with a measured gain.
    pub gains: Vec<ObjectGain>,
    /// ρ of the current measure against the gains.
    pub current: Option<RankCorrelation>,
    /// ρ of the in-image reading against the gains (objects that have one).
    pub in_image: Option<RankCorrelation>,
    /// The device whose rows were used (Single and Block are the same
    /// bakes on every device).
    pub device: Option<String>,
}

/// Which reading ranks the objects more like their gains.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Better {
    /// Cycles per object diameter.
    Current,
    /// Cycles per pixel.
    InImage,
    /// The same ρ.
    Tie,
}

impl DetailAnalysis {
    /// The reading with the larger ρ (a positive ρ is the prediction:
    /// more detail, more gain); `None` when either is undefined.
    pub fn better(&self) -> Option<Better> {
        let (c, i) = (self.current?.rho, self.in_image?.rho);
        Some(if (c - i).abs() < 1e-12 {
            Better::Tie
        } else if c > i {
            Better::Current
        } else {
            Better::InImage
        })
    }
}

/// Builds the comparison from a report's built-in scenes.
pub fn analyse(r: &EvalReport) -> DetailAnalysis {
    let mut gains = Vec::new();
    let mut device = None;
    for s in &r.scenes {
        // The first device on which both baselines were measured.
        let pair = super::compare::devices(s).into_iter().find_map(|d| {
            Some((
                measured(s, &d, Method::Block)?,
                measured(s, &d, Method::Single)?,
                d,
            ))
        });
        let Some((block, single, d)) = pair else {
            continue;
        };
        device.get_or_insert(d);
        for o in &s.objects {
            let Some(gain) = paired_object(block, single, &o.name) else {
                continue;
            };
            gains.push(ObjectGain {
                scene: s.scene.clone(),
                object: o.name.clone(),
                dedicated: o.dedicated,
                cycles_per_diameter: o.max_cycles_per_diameter,
                cycles_per_pixel: o.max_cycles_per_pixel,
                gain,
            });
        }
    }
    let y: Vec<f64> = gains.iter().map(|g| g.gain.mean).collect();
    let x: Vec<f64> = gains.iter().map(|g| g.cycles_per_diameter).collect();
    let current = spearman_test(&x, &y);
    let (xi, yi): (Vec<f64>, Vec<f64>) = gains
        .iter()
        .filter_map(|g| g.cycles_per_pixel.map(|c| (c, g.gain.mean)))
        .unzip();
    let in_image = spearman_test(&xi, &yi);
    DetailAnalysis {
        gains,
        current,
        in_image,
        device,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::compare::tests::row;
    use crate::eval::SceneReport;
    use crate::pipeline::views::ObjectScores;

    fn detail(name: &str, cpd: f64, cpp: f64) -> ObjectDetail {
        ObjectDetail {
            name: name.into(),
            network: name.into(),
            dedicated: true,
            complexity_quads: None,
            max_cycles_per_diameter: cpd,
            max_cycles_per_pixel: Some(cpp),
        }
    }

    /// A scene whose Block-NeRF gains over Single-NeRF are `gains` for
    /// objects o0, o1, …, in three views.
    fn scene(details: Vec<ObjectDetail>, gains: &[f64]) -> SceneReport {
        let mut single = row("pixel4", Method::Single, &[0.8, 0.8, 0.8]);
        let mut block = row("pixel4", Method::Block, &[0.8, 0.8, 0.8]);
        for (k, v) in single.views.iter_mut().enumerate() {
            v.objects = (0..gains.len())
                .map(|i| ObjectScores {
                    object: format!("o{i}"),
                    ssim: 0.7 + 0.01 * k as f64,
                    psnr: 20.0,
                    pixels: 100,
                })
                .collect();
        }
        for (k, v) in block.views.iter_mut().enumerate() {
            v.objects = gains
                .iter()
                .enumerate()
                .map(|(i, g)| ObjectScores {
                    object: format!("o{i}"),
                    ssim: 0.7 + 0.01 * k as f64 + g,
                    psnr: 20.0,
                    pixels: 100,
                })
                .collect();
        }
        SceneReport {
            scene: "s".into(),
            networks: Vec::new(),
            timings: Default::default(),
            samples: Vec::new(),
            rows: vec![single, block],
            objects: details,
            lattices: Vec::new(),
        }
    }

    #[test]
    fn the_reading_that_orders_objects_like_their_gains_wins() {
        // Gains rise o0 < o1 < o2 < o3 < o4; the current measure follows
        // them exactly, the in-image one reverses two pairs.
        let gains = [0.00, 0.01, 0.02, 0.03, 0.04];
        let details = vec![
            detail("o0", 10.0, 0.10),
            detail("o1", 11.0, 0.30),
            detail("o2", 12.0, 0.20),
            detail("o3", 13.0, 0.50),
            detail("o4", 14.0, 0.40),
        ];
        let r = EvalReport {
            settings: Vec::new(),
            scenes: vec![scene(details, &gains)],
            real: None,
            fps: Vec::new(),
            calibration: Vec::new(),
            wall_s: 0.0,
            baker: "hull".into(),
        };
        let a = analyse(&r);
        assert_eq!(a.gains.len(), 5);
        assert!((a.gains[3].gain.mean - 0.03).abs() < 1e-9);
        let (c, i) = (a.current.unwrap(), a.in_image.unwrap());
        assert!((c.rho - 1.0).abs() < 1e-12, "{c:?}");
        // Two adjacent swaps: Σd² = 4, ρ = 1 − 6·4/120 = 0.8.
        assert!((i.rho - 0.8).abs() < 1e-12, "{i:?}");
        assert_eq!(a.better(), Some(Better::Current));
        assert_eq!(a.device.as_deref(), Some("pixel4"));
    }
}
