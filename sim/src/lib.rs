//! nerflex-sim: the host side of NeRFlex.
//!
//! Data flows one way: captures/assets → plan → render → measure.
//! Each module has one job; the `nerflex` binary (`src/main.rs`) is a thin
//! layer over them (`cli`).
#![warn(missing_docs)]

pub mod asset;
pub mod bake;
pub mod baselines;
pub mod camera;
pub mod capture;
pub mod cli;
pub mod data;
pub mod device;
pub mod eval;
pub mod fit;
pub mod geometry;
pub mod memory;
pub mod metrics;
pub mod output;
pub mod pipeline;
pub mod plot;
mod prefetch;
pub mod procedural;
pub mod render;
pub mod rounding;
pub mod scene_file;
pub mod segment;
pub mod simulate;
pub mod train;
pub mod validate;
