//! The NeRFlex pipeline end to end, shared by `nerflex run` and
//! `nerflex eval`: capture → detail-based segmentation → profiler sample
//! bakes → curve fits → plan → bakes of the chosen configurations →
//! held-out views rendered and measured → device simulation.
//!
//! - [`bakes`]: bakes kept on disk (assets + measured samples), keyed like
//!   the bake sweep's cache, so a configuration is baked once across
//!   methods, devices and runs;
//! - [`fields`]: trained radiance fields kept on disk, one per (views,
//!   training settings), for the trained baker;
//! - [`stages`]: the stages as functions;
//! - [`geometries`]: which geometries the profiler samples (`--geometry`);
//! - [`one`]: one method on one device (`nerflex run`) and its report;
//! - [`range`]: the profiler's dynamic range against its views' noise;
//! - [`views`]: per-view scores of a rendered scene, whole and per object.

pub mod bakes;
pub mod fields;
pub mod geometries;
pub mod one;
pub mod range;
pub mod stages;
pub mod views;

pub use bakes::{BakeRequest, BakeStore, Baked, Baker, TrainedBaker};
pub use fields::{FieldStore, StoredField};
pub use geometries::Geometries;
pub use one::{method_plan, run_one, RunResult, RunTimes};
pub use stages::{
    baseline_plan, baseline_views, plan_for, prepare, realise, simulate_devices, simulate_on,
    Input, Network, Options, Prepared, Progress, Quiet, Realised, RealisedObject, SceneQuality,
    Timings,
};
