//! Training: a capture in, a radiance field out.
//!
//! `field` defines what every consumer of a trained field reads (the
//! [`field::RadianceField`] trait: density and view-dependent colour at a
//! world point); the trainer that produces one lives beside it.

pub mod field;
pub mod adam;
pub mod grid;
pub mod march;
pub mod pixels;
pub mod sh;
pub mod trainer;
