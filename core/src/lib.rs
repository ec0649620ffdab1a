//! nerflex-core: the part of NeRFlex that runs on the device.
//!
//! `no_std`, no heap, no panics on any input: every capacity is a const
//! generic, every fallible operation returns an error.
#![cfg_attr(not(test), no_std)]
// Unsafe only where the hardware needs it: `SMLAD` (inline assembly) and
// the AVX2 batch (intrinsics), each item allowed explicitly.
#![deny(unsafe_code)]
#![warn(missing_docs)]
// The no-panic promise, checked by clippy outside tests.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]

pub mod mck;
pub mod profiler;
pub mod raster;
pub mod shader;
pub mod units;
