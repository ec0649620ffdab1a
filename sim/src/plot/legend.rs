//! The legend box: one row per series, placed in a corner of the plot area.

use super::canvas::{text_height, text_width, Canvas, Fonts, HAlign, VAlign};
use super::Rgb;

/// Where the legend goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LegendPosition {
    /// The inside corner that covers the fewest data points (top right first).
    #[default]
    Auto,
    /// Inside the plot area, top left.
    TopLeft,
    /// Inside the plot area, top right.
    TopRight,
    /// Inside the plot area, bottom left.
    BottomLeft,
    /// Inside the plot area, bottom right.
    BottomRight,
    /// No legend.
    Hidden,
}

/// How one legend row shows its series.
#[derive(Debug, Clone)]
pub(crate) struct Entry {
    pub name: String,
    pub color: Rgb,
    pub line: bool,
    pub dashed: bool,
    pub marker: bool,
    /// A filled square (bars).
    pub swatch: bool,
}

const PAD: f32 = 8.0;
const SAMPLE: f32 = 28.0;
const GAP: f32 = 6.0;
/// Distance of the legend box from the plot frame (pixels).
pub(crate) const INSET: f32 = 10.0;
const ROW_GAP: f32 = 5.0;

/// Width and height of the legend box (pixels); (0, 0) when nothing is listed.
pub(crate) fn size(fonts: &Fonts, entries: &[Entry], position: LegendPosition) -> (f32, f32) {
    let listed: Vec<&Entry> = entries.iter().filter(|e| !e.name.is_empty()).collect();
    if listed.is_empty() || position == LegendPosition::Hidden {
        return (0.0, 0.0);
    }
    let font = fonts.tick;
    let text_w = listed
        .iter()
        .map(|e| text_width(font, &e.name))
        .fold(0.0, f32::max);
    let row = text_height(font) + ROW_GAP;
    (
        PAD + SAMPLE + GAP + text_w + PAD,
        PAD + row * listed.len() as f32 - ROW_GAP + PAD,
    )
}

/// Draws the legend inside `plot` = (left, top, right, bottom), avoiding
/// `obstacles` (pixel positions of data) when the position is automatic.
pub(crate) fn draw(
    canvas: &mut Canvas<'_>,
    fonts: &Fonts,
    entries: &[Entry],
    plot: (f32, f32, f32, f32),
    position: LegendPosition,
    obstacles: &[(f32, f32)],
) {
    let (w, h) = size(fonts, entries, position);
    let entries: Vec<&Entry> = entries.iter().filter(|e| !e.name.is_empty()).collect();
    if entries.is_empty() || position == LegendPosition::Hidden {
        return;
    }
    let font = fonts.tick;
    let row = text_height(font) + ROW_GAP;
    let (l, t, r, b) = plot;
    let corner = |p: LegendPosition| match p {
        LegendPosition::TopLeft => (l + INSET, t + INSET),
        LegendPosition::BottomLeft => (l + INSET, b - INSET - h),
        LegendPosition::BottomRight => (r - INSET - w, b - INSET - h),
        _ => (r - INSET - w, t + INSET),
    };
    let (x0, y0) = match position {
        LegendPosition::Auto => {
            let candidates = [
                LegendPosition::TopRight,
                LegendPosition::TopLeft,
                LegendPosition::BottomRight,
                LegendPosition::BottomLeft,
            ];
            let covered = |p: LegendPosition| {
                let (x, y) = corner(p);
                obstacles
                    .iter()
                    .filter(|(px, py)| {
                        *px >= x - 6.0 && *px <= x + w + 6.0 && *py >= y - 6.0 && *py <= y + h + 6.0
                    })
                    .count()
            };
            let best = candidates
                .iter()
                .copied()
                .min_by_key(|&p| covered(p))
                .unwrap_or(LegendPosition::TopRight);
            corner(best)
        }
        p => corner(p),
    };
    canvas.rect(x0, y0, x0 + w, y0 + h, Rgb::WHITE, None);
    canvas.rect_outline(x0, y0, x0 + w, y0 + h, Rgb(0xbb, 0xbb, 0xbb));
    for (i, e) in entries.iter().enumerate() {
        let cy = y0 + PAD + row * i as f32 + text_height(font) / 2.0;
        let sx0 = x0 + PAD;
        let sx1 = sx0 + SAMPLE;
        if e.swatch {
            canvas.rect(sx0 + 6.0, cy - 6.0, sx1 - 6.0, cy + 6.0, e.color, None);
        }
        if e.line {
            canvas.polyline(&[(sx0, cy), (sx1, cy)], e.color, 2.0, e.dashed, None);
        }
        if e.marker {
            canvas.marker((sx0 + sx1) / 2.0, cy, 3.5, e.color, None);
        }
        canvas.text(
            &e.name,
            font,
            (sx1 + GAP, cy),
            (HAlign::Left, VAlign::Middle),
            Rgb::DARK,
        );
    }
}
