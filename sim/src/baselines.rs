//! Configuration selection: NeRFlex's exact DP and the paper's baselines.
//!
//! Every method solves the same problem: one configuration (g, p) per object,
//! total size within the budget. A configuration also names its bake
//! geometry ([`Geometry`]); when an object has configurations of both
//! geometries, the choice is over their union, so the geometry is chosen
//! per object like g and p (see "Geometry" below). Sizes are rounded **up** to the budget unit
//! and the budget down (see [`Budget`]), the same way for every method, so
//! "feasible" means the same thing everywhere and always implies that the
//! true total in bytes fits. Qualities are compared as exact fixed-point
//! sums ([`QualitySum`]). Hence the DP's quality is at least that of any
//! feasible plan another method finds from the scene's configurations.
//!
//! | method | what |
//! |---|---|
//! | `dp` | exact multiple-choice knapsack ([`nerflex_core::mck`]) |
//! | `fairness` | H split equally; each object gets its best configuration inside its share |
//! | `slsqp` | continuous relaxation in (g, p) solved with SLSQP, mapped back to configurations |
//! | `greedy` | LP / convex-hull order: upgrades by quality gained per unit |
//! | `block` | Block-NeRF: every object at (128, 17), whatever the budget |
//! | `single` | Single-NeRF: one network for the whole scene at (128, 17) |
//! | `brute` | exhaustive search (small cases; used by the tests) |
//!
//! Each maximises the sum of the objects' predicted SSIM (the paper's
//! objective) unless given per-object weights ([`plan_weighted`],
//! [`Objective::Area`]: each network counted per pixel of the frame).
//!
//! `block` and `single` do not optimise: they always return their plan,
//! with `feasible: false` when it does not fit. The others return an error
//! when they find no feasible plan.
//!
//! **Geometry.** `dp`, `brute`, `greedy` and `fairness` treat each
//! object's configurations of every geometry as one list, so they pick
//! (g, p, geometry) with no special case (the DP stays exact over the
//! union). `slsqp` relaxes g and p only: it solves one continuous problem
//! per assignment of a geometry to each object and keeps the best
//! feasible rounded plan (see its module). `block` and `single` use
//! MobileNeRF's default, planes at (128, 17).

mod brute;
mod dp;
mod fairness;
mod fixed;
mod greedy;
mod objective;
mod problem;
mod slsqp;

pub use fixed::effective_grid;
pub use objective::{plan_weighted, Objective};

use crate::geometry::Geometry;
use crate::scene_file::Scene;
use nerflex_core::units::{Bytes, QualitySum};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The MobileNeRF default configuration used by Block-NeRF and Single-NeRF.
pub const DEFAULT_G: u32 = 128;
/// See [`DEFAULT_G`].
pub const DEFAULT_P: u32 = 17;

/// A configuration selection method.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Hash,
    PartialOrd,
    Ord,
    Serialize,
    Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// NeRFlex: exact DP over a quantized budget.
    Dp,
    /// Equal share of the budget per object.
    Fairness,
    /// Continuous relaxation solved with SLSQP.
    Slsqp,
    /// Greedy in LP (convex-hull) order.
    Greedy,
    /// Block-NeRF: every object at (128, 17).
    Block,
    /// Single-NeRF: one network at (128, 17).
    Single,
    /// Exhaustive search.
    Brute,
}

impl Method {
    /// Every method.
    pub const ALL: [Method; 7] = [
        Method::Dp,
        Method::Fairness,
        Method::Slsqp,
        Method::Greedy,
        Method::Block,
        Method::Single,
        Method::Brute,
    ];

    /// The name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Dp => "dp",
            Method::Fairness => "fairness",
            Method::Slsqp => "slsqp",
            Method::Greedy => "greedy",
            Method::Block => "block",
            Method::Single => "single",
            Method::Brute => "brute",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A memory budget and the unit it is planned in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    /// The budget H.
    pub total: Bytes,
    /// The planning unit: sizes are rounded up to it, H down.
    pub unit: Bytes,
}

impl Budget {
    /// What a plan is made against when its sizes may be under-predicted
    /// by up to `margin_pct` % (`(predicted − measured)/measured ≥
    /// −margin`): a plan predicted within `total × (1 − margin)` then
    /// measures at most `total`. Rounded down to the byte; `None` unless
    /// `margin_pct` is in `[0, 100)`.
    pub fn less_size_margin(total: Bytes, margin_pct: f64) -> Option<Bytes> {
        if !margin_pct.is_finite() || !(0.0..100.0).contains(&margin_pct) {
            return None;
        }
        if margin_pct == 0.0 {
            return Some(total);
        }
        // The float product is at most `total` up to rounding; the cast
        // saturates and the `min` keeps the result within `total`.
        let kept = (total.0 as f64 * (1.0 - margin_pct / 100.0)).floor();
        Some(Bytes((kept as u64).min(total.0)))
    }

    /// The default unit, 0.1 MB: our choice for the paper's budgets (the
    /// paper states 240 and 150 MB, not the unit its DP counts in).
    pub const PAPER_UNIT: Bytes = Bytes(100_000);
    /// Fewest units the default unit gives (finer than 0.1 MB for budgets
    /// under 100 MB).
    pub const MIN_UNITS: u64 = 1_000;
    /// Most units the default unit gives (coarser than 0.1 MB above 6.55 GB).
    pub const MAX_UNITS: u64 = 65_536;

    /// `total` in the default unit ([`Budget::default_unit`]).
    pub fn new(total: Bytes) -> Budget {
        Budget {
            total,
            unit: Budget::default_unit(total),
        }
    }

    /// `total` in a given unit.
    pub fn with_unit(total: Bytes, unit: Bytes) -> Budget {
        Budget { total, unit }
    }

    /// 0.1 MB ([`PAPER_UNIT`](Self::PAPER_UNIT): 240 MB → 2400 units), unless that gives fewer
    /// than [`MIN_UNITS`](Self::MIN_UNITS) units (then `⌊H/1000⌋`, at least 1 byte) or more
    /// than [`MAX_UNITS`](Self::MAX_UNITS) (then `⌈H/65536⌉`).
    pub fn default_unit(total: Bytes) -> Bytes {
        let h = total.0;
        if h / Budget::PAPER_UNIT.0 < Budget::MIN_UNITS {
            Bytes((h / Budget::MIN_UNITS).max(1))
        } else if h.div_ceil(Budget::PAPER_UNIT.0) > Budget::MAX_UNITS {
            Bytes(h.div_ceil(Budget::MAX_UNITS))
        } else {
            Budget::PAPER_UNIT
        }
    }

    /// `⌊H / unit⌋` (0 for a zero unit).
    pub fn units(&self) -> u64 {
        self.total.units_floor(self.unit).unwrap_or(0)
    }
}

/// A plan. Serializes to exactly
/// `{"method", "device", "budget_bytes", "feasible", "objects": [{"name", "g", "p", "size_bytes", "quality"}], "total_size_bytes", "total_quality"}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The method that made it.
    pub method: Method,
    /// The device it was made for (`None` when planned for a bare budget).
    pub device: Option<String>,
    /// The budget H.
    pub budget_bytes: u64,
    /// Whether the plan fits the budget (sizes rounded up to the unit).
    pub feasible: bool,
    /// One entry per object (one entry in total for Single-NeRF).
    pub objects: Vec<PlannedObject>,
    /// Sum of the objects' sizes.
    pub total_size_bytes: u64,
    /// Sum of the objects' predicted SSIM (for Single-NeRF: its SSIM counted
    /// once per scene object, so totals compare across methods).
    pub total_quality: f64,
    /// `total_quality` as an exact fixed-point sum (what methods are compared by).
    #[serde(skip)]
    pub total_quality_q: QualitySum,
    /// Total in budget units (each object's size rounded up).
    #[serde(skip)]
    pub total_units: u64,
    /// `⌊H / unit⌋`.
    #[serde(skip)]
    pub budget_units: u64,
    /// The planning unit in bytes.
    #[serde(skip)]
    pub unit_bytes: u64,
}

/// One object's configuration in a plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedObject {
    /// Object name (`single` or the scene's `single` entry name for Single-NeRF).
    pub name: String,
    /// Grid resolution.
    pub g: u32,
    /// Patch size.
    pub p: u32,
    /// Size of its baked data.
    pub size_bytes: u64,
    /// Predicted SSIM.
    pub quality: f64,
    /// The geometry it is baked with. Left out of JSON when `planes` (and
    /// read as `planes` when absent), so planes-only plans serialize as
    /// before.
    #[serde(default, skip_serializing_if = "Geometry::is_planes")]
    pub geometry: Geometry,
    /// Index into the scene object's `configs` (for Single-NeRF: into the
    /// scene's `single.configs`, `None` when derived). Not serialized.
    #[serde(skip)]
    pub config_index: Option<usize>,
}

impl Plan {
    /// Mean predicted SSIM per scene object.
    pub fn mean_quality(&self, scene_objects: usize) -> f64 {
        self.total_quality / scene_objects.max(1) as f64
    }
}

fn mb(b: Bytes) -> String {
    format!("{:.2} MB ({} bytes)", b.as_mb(), b.0)
}

/// Why a method returned no plan.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// The scene has no objects.
    #[error("the scene has no objects")]
    EmptyScene,
    /// An object has no configurations.
    #[error("object `{object}` has no configurations")]
    NoConfigs {
        /// The object.
        object: String,
    },
    /// An object has more configurations than the solver supports.
    #[error("object `{object}` has {configs} configurations; at most 256 are supported")]
    TooManyConfigs {
        /// The object.
        object: String,
        /// How many it has.
        configs: usize,
    },
    /// A quality is not an SSIM in [0, 1].
    #[error("object `{object}` (g {g}, p {p}): quality {value} is not an SSIM in [0, 1]")]
    BadQuality {
        /// The object.
        object: String,
        /// Its g.
        g: u32,
        /// Its p.
        p: u32,
        /// The value.
        value: f64,
    },
    /// The planning unit is zero.
    #[error("the budget unit is zero bytes")]
    ZeroUnit,
    /// Even the cheapest configuration of every object does not fit.
    #[error("infeasible: the cheapest plan needs {}, over the budget of {}", mb(*cheapest_total), mb(*budget))]
    Infeasible {
        /// Bytes the cheapest plan needs.
        cheapest_total: Bytes,
        /// The budget.
        budget: Bytes,
    },
    /// The cheapest plan fits in bytes but not with sizes rounded up to the unit.
    #[error(
        "infeasible at this unit: the cheapest plan needs {}, {} with each size rounded up to the {}-byte unit, over the budget of {}: use a finer unit (`--unit-bytes` on the command line)",
        mb(*cheapest_total), mb(*cheapest_rounded), unit.0, mb(*budget)
    )]
    UnitTooCoarse {
        /// Bytes the cheapest plan needs.
        cheapest_total: Bytes,
        /// The same with sizes rounded up to the unit.
        cheapest_rounded: Bytes,
        /// The budget.
        budget: Bytes,
        /// The unit.
        unit: Bytes,
    },
    /// The budget has too many units for the DP's tables.
    #[error("the budget spans {units} units of {unit} bytes, too many for the DP's tables: use a coarser unit")]
    TooManyUnits {
        /// Units.
        units: u64,
        /// The unit in bytes.
        unit: u64,
    },
    /// Fairness: an object has no configuration inside its equal share.
    #[error("fairness: object `{object}` has no configuration within its equal share of {}", mb(*share))]
    ShareTooSmall {
        /// The object.
        object: String,
        /// Its share.
        share: Bytes,
    },
    /// A fixed-configuration method needs a configuration the object lacks.
    #[error("{method}: object `{object}` has no configuration (g {g}, p {p})")]
    MissingConfig {
        /// The method.
        method: Method,
        /// The object.
        object: String,
        /// g wanted.
        g: u32,
        /// p wanted.
        p: u32,
    },
    /// SLSQP found no plan.
    #[error("slsqp: {0}")]
    Slsqp(String),
    /// Too many combinations for brute force.
    #[error("brute: {combinations} combinations, more than the limit of {limit}")]
    BruteTooLarge {
        /// Combinations of fitting configurations.
        combinations: u128,
        /// The limit.
        limit: u128,
    },
    /// A bug.
    #[error("internal error: {0}")]
    Internal(String),
}

/// Plans `scene` within `budget` with `method`.
pub fn plan(method: Method, scene: &Scene, budget: Budget) -> Result<Plan, PlanError> {
    let problem = problem::Problem::new(scene, budget)?;
    match method {
        Method::Dp => dp::plan(&problem),
        Method::Fairness => fairness::plan(&problem),
        Method::Slsqp => slsqp::plan(&problem),
        Method::Greedy => greedy::plan(&problem),
        Method::Block => fixed::block(&problem),
        Method::Single => fixed::single(&problem),
        Method::Brute => brute::plan(&problem, brute::DEFAULT_LIMIT),
    }
}
