//! Grouped bar charts: one group per category (scene), one bar per series
//! (method), e.g. an evaluation table drawn as a picture.

use super::axis::{Axis, Scale};
use super::canvas::{text_height, text_width, Canvas, Fonts, HAlign, VAlign};
use super::frame::{self, decor_methods, Area, Decor, MARGIN};
use super::legend::{self, Entry};
use super::{check_size, PlotError, Rgb, PALETTE};
use tiny_skia::Pixmap;

/// Fraction of a group's width taken by its bars (the rest separates groups).
const GROUP_FILL: f32 = 0.8;

#[derive(Debug, Clone, PartialEq)]
struct BarSeries {
    name: String,
    values: Vec<f64>,
    color: Option<Rgb>,
}

/// A grouped bar chart. Values that are not finite (NaN) are missing bars,
/// marked "n/a" when value labels are on.
#[derive(Debug, Clone, PartialEq)]
pub struct BarChart {
    decor: Decor,
    categories: Vec<String>,
    series: Vec<BarSeries>,
    y_range: Option<(f64, f64)>,
    value_labels: bool,
}

/// Where a [`BarChart`] puts things for a given picture size.
#[derive(Debug, Clone, PartialEq)]
pub struct BarLayout {
    /// Left edge of the plot area (pixels).
    pub left: f32,
    /// Top edge of the plot area (pixels).
    pub top: f32,
    /// Right edge of the plot area (pixels).
    pub right: f32,
    /// Bottom edge of the plot area (pixels).
    pub bottom: f32,
    y: Axis,
    categories: usize,
    series: usize,
}

impl BarLayout {
    /// Pixel row of value `v` on the y axis.
    pub fn y_pixel(&self, v: f64) -> Option<f32> {
        Some(self.area().y_at(self.y.frac(v)?))
    }

    /// Left and right pixel columns of bar `series` in group `category`.
    pub fn bar_columns(&self, series: usize, category: usize) -> Option<(f32, f32)> {
        if series >= self.series || category >= self.categories {
            return None;
        }
        let gw = (self.right - self.left) / self.categories as f32;
        let bw = gw * GROUP_FILL / self.series as f32;
        let x0 =
            self.left + gw * category as f32 + gw * (1.0 - GROUP_FILL) / 2.0 + bw * series as f32;
        Some((x0, x0 + bw))
    }

    /// The y ticks: value and label.
    pub fn y_ticks(&self) -> &[(f64, String)] {
        &self.y.ticks
    }

    fn area(&self) -> Area {
        Area {
            left: self.left,
            top: self.top,
            right: self.right,
            bottom: self.bottom,
        }
    }
}

impl BarChart {
    /// An empty bar chart with a title.
    pub fn new(title: impl Into<String>) -> Self {
        Self {
            decor: Decor::new(title.into()),
            categories: Vec::new(),
            series: Vec::new(),
            y_range: None,
            value_labels: false,
        }
    }

    decor_methods!(BarChart);

    /// The group names along the x axis (e.g. scenes).
    pub fn categories<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> Self {
        self.categories = names.into_iter().map(Into::into).collect();
        self
    }

    /// Adds a series (e.g. a method): one value per category, in order.
    pub fn series(
        mut self,
        name: impl Into<String>,
        values: impl IntoIterator<Item = f64>,
    ) -> Self {
        self.series.push(BarSeries {
            name: name.into(),
            values: values.into_iter().collect(),
            color: None,
        });
        self
    }

    /// Adds a series with a given colour.
    pub fn series_colored(
        mut self,
        name: impl Into<String>,
        values: impl IntoIterator<Item = f64>,
        color: Rgb,
    ) -> Self {
        self = self.series(name, values);
        if let Some(s) = self.series.last_mut() {
            s.color = Some(color);
        }
        self
    }

    /// Fixes the y range (default: from 0 to the data, padded).
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    /// Writes each bar's value above it (where it fits).
    pub fn value_labels(mut self, on: bool) -> Self {
        self.value_labels = on;
        self
    }

    fn entries(&self) -> Vec<Entry> {
        self.series
            .iter()
            .enumerate()
            .map(|(si, s)| Entry {
                name: s.name.clone(),
                color: s.color.unwrap_or(PALETTE[si % PALETTE.len()]),
                line: false,
                dashed: false,
                marker: false,
                swatch: true,
            })
            .collect()
    }

    fn value(&self, series: usize, category: usize) -> Option<f64> {
        let v = *self.series.get(series)?.values.get(category)?;
        v.is_finite().then_some(v)
    }

    /// Lays the chart out in a `width`×`height` picture.
    pub fn layout(&self, width: u32, height: u32) -> Result<BarLayout, PlotError> {
        check_size(width, height)?;
        let fonts = Fonts::for_size(width, height);
        let (w, h) = (width as f32, height as f32);
        let (top, bottom) = self.decor.rows(&fonts, h);
        let values: Vec<f64> = self
            .series
            .iter()
            .flat_map(|s| s.values.iter().take(self.categories.len()).copied())
            .filter(|v| v.is_finite())
            .collect();
        let ticks = frame::max_ticks(bottom - top, 38.0);
        let range = self.y_range.or_else(|| {
            // Bars start at 0; leave room above the tallest bar for its value
            // label and the legend, so neither hides a bar.
            let hi = values.iter().fold(0.0f64, |m, &v| m.max(v));
            let lo = values.iter().fold(0.0f64, |m, &v| m.min(v));
            let span = if hi > lo { hi - lo } else { 1.0 };
            let lo = if lo < 0.0 { lo - 0.05 * span } else { 0.0 };
            let label_px = if self.value_labels {
                text_height(fonts.small) + 4.0
            } else {
                0.0
            };
            let legend_px = legend::size(&fonts, &self.entries(), self.decor.legend).1;
            let room_px = label_px + legend_px + 2.0 * legend::INSET + 4.0;
            let f = f64::from((room_px / (bottom - top)).clamp(0.05, 0.5));
            let hi = if hi > lo { hi } else { lo + 1.0 };
            Some((lo, hi + f / (1.0 - f) * (hi - lo)))
        });
        let y = Axis::new(Scale::Linear, values, range, ticks, true);
        let left = frame::left_margin(&fonts, &self.decor.y_label, &y);
        Ok(BarLayout {
            left,
            top,
            right: w - MARGIN - 8.0,
            bottom,
            y,
            categories: self.categories.len().max(1),
            series: self.series.len().max(1),
        })
    }

    /// Draws the chart into a new `width`×`height` picture.
    pub fn render(&self, width: u32, height: u32) -> Result<Pixmap, PlotError> {
        let layout = self.layout(width, height)?;
        let mut pixmap = check_size(width, height)?;
        let fonts = Fonts::for_size(width, height);
        let area = layout.area();
        let mut canvas = Canvas::new(&mut pixmap);
        frame::grid(&mut canvas, &area, &layout.y, &[]);
        let clip = canvas.clip(area.left, area.top, area.right, area.bottom);
        let base = layout
            .y_pixel(0.0)
            .unwrap_or(area.bottom)
            .clamp(area.top, area.bottom);

        let mut obstacles = Vec::new();
        for (si, s) in self.series.iter().enumerate() {
            let color = s.color.unwrap_or(PALETTE[si % PALETTE.len()]);
            for ci in 0..self.categories.len() {
                let Some((x0, x1)) = layout.bar_columns(si, ci) else {
                    continue;
                };
                // One pixel of white between neighbouring bars.
                let (x0, x1) = (x0.round() + 1.0, x1.round());
                let value = self.value(si, ci);
                let top = value.and_then(|v| layout.y_pixel(v));
                if let Some(top) = top {
                    canvas.rect(x0, top, x1, base, color, clip.as_ref());
                    // The whole bar is an obstacle for the legend.
                    let (t, b) = (top.min(base).max(area.top), top.max(base).min(area.bottom));
                    let mut y = t;
                    while y <= b {
                        obstacles.extend([(x0, y), ((x0 + x1) / 2.0, y), (x1, y)]);
                        y += 8.0;
                    }
                }
                if self.value_labels {
                    let label = value.map_or("n/a".to_owned(), format_value);
                    let fits = text_width(fonts.small, &label) <= (x1 - x0) + 6.0;
                    if fits {
                        let y = top
                            .unwrap_or(base)
                            .clamp(area.top + text_height(fonts.small) + 2.0, area.bottom);
                        let above = value.is_none_or(|v| v >= 0.0);
                        let (y, v) = if above {
                            (y - 2.0, VAlign::Bottom)
                        } else {
                            (y + 2.0, VAlign::Top)
                        };
                        canvas.text(
                            &label,
                            fonts.small,
                            ((x0 + x1) / 2.0, y),
                            (HAlign::Center, v),
                            Rgb::DARK,
                        );
                        obstacles.push(((x0 + x1) / 2.0, y - text_height(fonts.small)));
                    }
                }
            }
        }
        let entries = self.entries();
        canvas.hairline(area.left, base, area.right, base, Rgb::DARK);
        self.decor.axes(&mut canvas, &fonts, &area, &layout.y);
        let gw = (area.right - area.left) / layout.categories as f32;
        for (ci, name) in self.categories.iter().enumerate() {
            let cx = area.left + gw * (ci as f32 + 0.5);
            let label = fit_label(name, &fonts, gw - 4.0);
            frame::x_tick(&mut canvas, &fonts, &area, cx, &label);
        }
        legend::draw(
            &mut canvas,
            &fonts,
            &entries,
            area.tuple(),
            self.decor.legend,
            &obstacles,
        );
        Ok(pixmap)
    }
}

/// Three significant digits, without needless zeros.
fn format_value(v: f64) -> String {
    let a = v.abs();
    if a >= 1e5 || (a > 0.0 && a < 1e-3) {
        format!("{v:.2e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// A category label shortened with ".." if it is wider than `max_px`.
fn fit_label(name: &str, fonts: &Fonts, max_px: f32) -> String {
    if text_width(fonts.tick, name) <= max_px {
        return name.to_owned();
    }
    let mut s: String = name.to_owned();
    while !s.is_empty() && text_width(fonts.tick, &format!("{s}..")) > max_px {
        s.pop();
    }
    format!("{s}..")
}
