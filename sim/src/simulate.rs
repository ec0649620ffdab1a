//! The device simulator: a scene's objects load into a phone's web viewer
//! and turn on a turntable (7.5 s per revolution) for 2000 frames; every
//! frame's time comes from the device model ([`crate::device`]) applied to
//! the work that frame really has — quads drawn and pixels covered, found by
//! rasterizing the loaded objects at that turntable angle (coverage only, at
//! a reduced resolution, scaled to the viewer's).
//!
//! - [`turntable`]: the camera ring and the per-angle coverage of each load
//!   stage (objects 0..k loaded), measured lazily through a
//!   [`CoverageSource`] and interpolated between angles;
//! - [`timeline`]: the frame loop — asynchronous file reads, decoding on the
//!   main thread (the loading stutter), the soft and hard memory limits;
//! - [`output`]: CSV, JSON and the FPS plot (real-time line + dashed average).
//!
//! The model and its calibration: `docs/device.md`.

pub mod assets;
pub mod output;
pub mod timeline;
pub mod turntable;

pub use output::{write_csv, write_json, write_plot};
pub use timeline::{check_frames, simulate, FrameRecord, LoadItem, SimOptions, Simulation};
pub use turntable::{CoverageSource, Turntable, TurntableSpec, ViewCoverage};
