//! The `nerflex` command line: one module a subcommand, each a thin layer
//! that parses flags, calls the library and prints.

pub mod bake;
pub mod bake_trained;
pub mod eval;
pub mod metrics;
pub mod plan;
pub mod profile;
pub mod render;
pub mod run;
pub mod scene;
pub mod segment;
pub mod simulate;
pub mod train;
