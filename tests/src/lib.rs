//! Integration and property tests of nerflex live in `tests/tests/`.
//! This library holds what they share.

pub use nerflex_sim::data::{require_data, shared_data_dir};
