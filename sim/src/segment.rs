//! Detail-based segmentation (the NeRFlex paper's §"Detail-based
//! Segmentation"): which objects earn their own NeRF, and their enlarged
//! training sets.
//!
//! 1. [`frequency`]: the detail frequency of each object in each training
//!    view (a documented spectral measure, cycles per object diameter).
//! 2. [`analysis`]: each object's maximum over views and the view where it
//!    peaks; the threshold α (default: the lowest maximum) and the decision
//!    (dedicated iff the maximum exceeds α, else the shared group).
//! 3. [`mod@enlarge`]: each dedicated object's views cropped to its mask's
//!    bounding box and scaled back to full size, with adjusted cameras; the
//!    shared group's views with the dedicated objects removed.
//! 4. [`output`]: one NeRF-synthetic folder per network and
//!    `segmentation.json`.
//! 5. [`compose`]: a two-object capture composed from separate real
//!    captures (lego + chair), and resized copies of captures.
//!
//! Design notes: `docs/segmentation.md`.

pub mod analysis;
pub mod compose;
pub mod enlarge;
pub mod frequency;
pub mod input;
pub mod output;
pub mod testscene;

pub use analysis::{analyse, decide, AlphaSource, Analysis, Decision, Decisions, ObjectFrequency};
pub use enlarge::{enlarge, EnlargeOptions, Enlarged};
pub use frequency::{detail_frequency, DetailFrequency, FrequencyOptions};
pub use input::{SegCapture, SegFrame, SegmentError};
pub use output::{segment, SegmentOptions, Segmentation, SEGMENTATION_FILE};
