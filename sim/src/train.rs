//! Training: a capture in, a radiance field out.
//!
//! `field` defines what every consumer of a trained field reads (the
//! [`field::RadianceField`] trait: density and view-dependent colour at a
//! world point); the trainer that produces one lives beside it.

pub mod adam;
pub mod field;
pub mod grid;
pub mod io;
pub mod march;
pub mod pixels;
pub mod sh;
pub mod trainer;
pub mod tv;
pub mod view;

/// Loads a field saved by `nerflex train` (errors name the file).
pub fn load_field(path: &std::path::Path) -> anyhow::Result<Box<dyn field::RadianceField>> {
    Ok(Box::new(io::load(path)?.grid))
}
