//! nerflex-core: the part of NeRFlex that runs on the device.
//!
//! `no_std`, no heap, no panics on any input: every capacity is a const
//! generic, every fallible operation returns an error.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod mck;
pub mod profiler;
pub mod raster;
pub mod shader;
pub mod units;
