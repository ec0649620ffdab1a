//! What line and bar charts share: margins, the y axis, grid, frame, titles.

use super::axis::Axis;
use super::canvas::{text_height, text_width, Canvas, Fonts, HAlign, VAlign};
use super::legend::LegendPosition;
use super::{Rgb, DEFAULT_SIZE};

/// Tick mark length (pixels), outside the frame.
pub(crate) const TICK: f32 = 5.0;
/// Space between a tick and its label (pixels).
const TICK_GAP: f32 = 3.0;
/// Outer margin (pixels).
pub(crate) const MARGIN: f32 = 12.0;

/// Pixels of the plot area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Area {
    pub left: f32,
    pub top: f32,
    pub right: f32,
    pub bottom: f32,
}

impl Area {
    pub fn tuple(&self) -> (f32, f32, f32, f32) {
        (self.left, self.top, self.right, self.bottom)
    }

    /// Pixel row of a y-axis fraction (0 = bottom).
    pub fn y_at(&self, frac: f64) -> f32 {
        self.bottom - (frac as f32) * (self.bottom - self.top)
    }

    /// Pixel column of an x-axis fraction (0 = left).
    pub fn x_at(&self, frac: f64) -> f32 {
        self.left + (frac as f32) * (self.right - self.left)
    }
}

/// The texts and placement every chart kind shares: titles, legend corner
/// and default picture size.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Decor {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub legend: LegendPosition,
    pub size: (u32, u32),
}

impl Decor {
    pub fn new(title: String) -> Self {
        Self {
            title,
            x_label: String::new(),
            y_label: String::new(),
            legend: LegendPosition::Auto,
            size: DEFAULT_SIZE,
        }
    }

    /// Top and bottom pixel rows of the plot area in a picture `height` tall.
    pub fn rows(&self, fonts: &Fonts, height: f32) -> (f32, f32) {
        (
            top_margin(fonts, &self.title),
            height - bottom_margin(fonts, &self.x_label),
        )
    }

    /// The frame, y ticks and titles (see [`axes`]).
    pub fn axes(&self, canvas: &mut Canvas<'_>, fonts: &Fonts, area: &Area, y: &Axis) {
        axes(
            canvas,
            fonts,
            area,
            y,
            &self.title,
            &self.x_label,
            &self.y_label,
        );
    }
}

/// The builder setters of [`Decor`]'s fields and `save`, for a chart type
/// with a `decor: Decor` field and a `render(width, height)` method.
macro_rules! decor_methods {
    ($chart:ident) => {
        /// The x axis title (include the unit, e.g. "size (MB)").
        pub fn x_label(mut self, label: impl Into<String>) -> Self {
            self.decor.x_label = label.into();
            self
        }

        /// The y axis title.
        pub fn y_label(mut self, label: impl Into<String>) -> Self {
            self.decor.y_label = label.into();
            self
        }

        /// Where the legend goes (default: the emptiest inside corner).
        pub fn legend(mut self, position: $crate::plot::LegendPosition) -> Self {
            self.decor.legend = position;
            self
        }

        #[doc = concat!("Picture size used by [`", stringify!($chart), "::save`] (pixels, default 800×500).")]
        pub fn size(mut self, width: u32, height: u32) -> Self {
            self.decor.size = (width, height);
            self
        }

        /// Renders at the chart's size and writes a PNG (errors name the file).
        pub fn save(&self, path: &std::path::Path) -> Result<(), $crate::plot::PlotError> {
            let pixmap = self.render(self.decor.size.0, self.decor.size.1)?;
            $crate::plot::save_png(&pixmap, path)
        }
    };
}
pub(crate) use decor_methods;

/// Top margin: room for the title.
pub(crate) fn top_margin(fonts: &Fonts, title: &str) -> f32 {
    if title.is_empty() {
        MARGIN + 4.0
    } else {
        MARGIN + text_height(fonts.title) + 12.0
    }
}

/// Bottom margin: ticks, tick labels and the x title.
pub(crate) fn bottom_margin(fonts: &Fonts, x_label: &str) -> f32 {
    let mut m = TICK + TICK_GAP + text_height(fonts.tick) + MARGIN;
    if !x_label.is_empty() {
        m += text_height(fonts.label) + 8.0;
    }
    m
}

/// Left margin: the y title and the widest y tick label.
pub(crate) fn left_margin(fonts: &Fonts, y_label: &str, y: &Axis) -> f32 {
    let widest = y
        .ticks
        .iter()
        .map(|(_, s)| text_width(fonts.tick, s))
        .fold(0.0, f32::max);
    let mut m = MARGIN + widest + TICK_GAP + TICK;
    if !y_label.is_empty() {
        m += text_height(fonts.label) + 10.0;
    }
    m
}

/// How many ticks fit along `len` pixels with labels about `label_px` apart.
pub(crate) fn max_ticks(len: f32, label_px: f32) -> usize {
    ((len / label_px).floor() as usize).clamp(2, 12)
}

/// Background grid lines at the y ticks (and at `x_ticks` pixel columns).
pub(crate) fn grid(canvas: &mut Canvas<'_>, area: &Area, y: &Axis, x_cols: &[f32]) {
    for (v, _) in &y.ticks {
        if let Some(f) = y.frac(*v) {
            let py = area.y_at(f);
            if py >= area.top - 0.5 && py <= area.bottom + 0.5 {
                canvas.hairline(area.left, py, area.right, py, Rgb::GRID);
            }
        }
    }
    for &px in x_cols {
        canvas.hairline(px, area.top, px, area.bottom, Rgb::GRID);
    }
}

/// The frame, y ticks with labels, the titles.
pub(crate) fn axes(
    canvas: &mut Canvas<'_>,
    fonts: &Fonts,
    area: &Area,
    y: &Axis,
    title: &str,
    x_label: &str,
    y_label: &str,
) {
    canvas.rect_outline(area.left, area.top, area.right, area.bottom, Rgb::DARK);
    for (v, label) in &y.ticks {
        let Some(f) = y.frac(*v) else { continue };
        let py = area.y_at(f);
        if py < area.top - 0.5 || py > area.bottom + 0.5 {
            continue;
        }
        canvas.hairline(area.left - TICK, py, area.left, py, Rgb::DARK);
        canvas.text(
            label,
            fonts.tick,
            (area.left - TICK - TICK_GAP, py),
            (HAlign::Right, VAlign::Middle),
            Rgb::DARK,
        );
    }
    let (w, h) = {
        let p = &canvas.pixmap;
        (p.width() as f32, p.height() as f32)
    };
    if !title.is_empty() {
        canvas.text(
            title,
            fonts.title,
            (w / 2.0, MARGIN),
            (HAlign::Center, VAlign::Top),
            Rgb::BLACK,
        );
    }
    if !x_label.is_empty() {
        canvas.text(
            x_label,
            fonts.label,
            ((area.left + area.right) / 2.0, h - MARGIN),
            (HAlign::Center, VAlign::Bottom),
            Rgb::DARK,
        );
    }
    if !y_label.is_empty() {
        canvas.text_vertical(
            y_label,
            fonts.label,
            MARGIN + text_height(fonts.label) / 2.0,
            (area.top + area.bottom) / 2.0,
            Rgb::DARK,
        );
    }
}

/// A tick below the frame at pixel column `px` with its label.
pub(crate) fn x_tick(canvas: &mut Canvas<'_>, fonts: &Fonts, area: &Area, px: f32, label: &str) {
    canvas.hairline(px, area.bottom, px, area.bottom + TICK, Rgb::DARK);
    canvas.text(
        label,
        fonts.tick,
        (px, area.bottom + TICK + TICK_GAP),
        (HAlign::Center, VAlign::Top),
        Rgb::DARK,
    );
}
