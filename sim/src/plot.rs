//! Small, readable charts drawn with `tiny-skia`, text with
//! `embedded-graphics` mono fonts, saved as PNG.
//!
//! Two kinds of chart cover what the reports need:
//! - [`Chart`]: line and scatter series on linear or log axes (size-vs-g and
//!   SSIM-vs-g curves, fitted curves over measured points, per-frame FPS with
//!   a dashed average from [`Series::horizontal`]);
//! - [`BarChart`]: grouped bars, one group per category (scene) and one bar
//!   per series (method).
//!
//! ```no_run
//! use nerflex_sim::plot::{Chart, Series};
//! let chart = Chart::new("SSIM vs grid")
//!     .x_label("grid g")
//!     .y_label("SSIM")
//!     .x_log2()
//!     .series(Series::line_points("p = 17", [(16.0, 0.80), (64.0, 0.90), (256.0, 0.93)]))
//!     .series(Series::horizontal("target", 0.9).dashed());
//! chart.save("ssim.png".as_ref())?;
//! # Ok::<(), nerflex_sim::plot::PlotError>(())
//! ```

mod axis;
mod bars;
mod canvas;
mod chart;
mod frame;
mod legend;

use std::path::{Path, PathBuf};

pub use axis::Scale;
pub use bars::{BarChart, BarLayout};
pub use chart::{Chart, Layout, Series, SeriesKind};
pub use legend::LegendPosition;
pub use tiny_skia::Pixmap;

/// Default picture size (pixels) used by `save`.
pub const DEFAULT_SIZE: (u32, u32) = (800, 500);

/// What can go wrong while drawing or saving a chart.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The picture size is zero or too small to hold the axes.
    #[error("cannot draw a {width}×{height} chart (at least {min}×{min} pixels)")]
    InvalidSize {
        /// Requested width (pixels).
        width: u32,
        /// Requested height (pixels).
        height: u32,
        /// Smallest side accepted (pixels).
        min: u32,
    },
    /// The PNG could not be encoded or written.
    #[error("cannot write chart {}: {message}", path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

/// Smallest side of a chart (pixels): below it axes and labels do not fit.
pub const MIN_SIDE: u32 = 120;

/// An opaque sRGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// Black.
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    /// Dark grey, for axes and text.
    pub const DARK: Rgb = Rgb(0x33, 0x33, 0x33);
    /// Light grey, for grid lines.
    pub const GRID: Rgb = Rgb(0xe3, 0xe3, 0xe3);
    /// White.
    pub const WHITE: Rgb = Rgb(0xff, 0xff, 0xff);
}

/// Series colours in order (Tableau 10: distinct, colour-blind friendly).
pub const PALETTE: [Rgb; 10] = [
    Rgb(0x4e, 0x79, 0xa7),
    Rgb(0xf2, 0x8e, 0x2b),
    Rgb(0xe1, 0x57, 0x59),
    Rgb(0x59, 0xa1, 0x4f),
    Rgb(0xb0, 0x7a, 0xa1),
    Rgb(0x76, 0xb7, 0xb2),
    Rgb(0xed, 0xc9, 0x48),
    Rgb(0x9c, 0x75, 0x5f),
    Rgb(0xff, 0x9d, 0xa7),
    Rgb(0xba, 0xb0, 0xac),
];

/// Writes `pixmap` as a PNG to `path` via a temporary file beside it, so a
/// failed write never leaves a truncated picture behind.
pub fn save_png(pixmap: &Pixmap, path: &Path) -> Result<(), PlotError> {
    let fail = |message: String| PlotError::Write {
        path: path.to_owned(),
        message,
    };
    let bytes = pixmap.encode_png().map_err(|e| fail(e.to_string()))?;
    crate::output::write_file(path, &bytes)
        .map(|_| ())
        .map_err(|e| fail(e.to_string()))
}

fn check_size(width: u32, height: u32) -> Result<Pixmap, PlotError> {
    let err = PlotError::InvalidSize {
        width,
        height,
        min: MIN_SIDE,
    };
    if width < MIN_SIDE || height < MIN_SIDE {
        return Err(err);
    }
    let mut pixmap = Pixmap::new(width, height).ok_or(err)?;
    pixmap.fill(tiny_skia::Color::WHITE);
    Ok(pixmap)
}
