//! Line and scatter charts.

use super::axis::{Axis, Scale};
use super::canvas::{text_width, Canvas, Fonts};
use super::frame::{self, decor_methods, Area, Decor, MARGIN};
use super::legend::{self, Entry};
use super::{check_size, PlotError, Rgb, PALETTE};
use tiny_skia::Pixmap;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesKind {
    /// Points joined by a line, in the order given.
    Line,
    /// Markers only.
    Points,
    /// A line with a marker on each point.
    LinePoints,
}

/// One named data series of a [`Chart`].
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    name: String,
    points: Vec<(f64, f64)>,
    kind: SeriesKind,
    dashed: bool,
    color: Option<Rgb>,
    width: f32,
    /// A horizontal line at this y across the whole x range.
    horizontal: Option<f64>,
}

impl Series {
    fn new(
        name: impl Into<String>,
        points: impl IntoIterator<Item = (f64, f64)>,
        kind: SeriesKind,
    ) -> Self {
        Self {
            name: name.into(),
            points: points.into_iter().collect(),
            kind,
            dashed: false,
            color: None,
            width: 2.0,
            horizontal: None,
        }
    }

    /// Points (x, y) joined by a line in the order given.
    pub fn line(name: impl Into<String>, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        Self::new(name, points, SeriesKind::Line)
    }

    /// Markers only (measured samples).
    pub fn scatter(name: impl Into<String>, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        Self::new(name, points, SeriesKind::Points)
    }

    /// A line with a marker on every point.
    pub fn line_points(
        name: impl Into<String>,
        points: impl IntoIterator<Item = (f64, f64)>,
    ) -> Self {
        Self::new(name, points, SeriesKind::LinePoints)
    }

    /// A horizontal line at `y` spanning the x axis (e.g. an average;
    /// combine with [`Series::dashed`]).
    pub fn horizontal(name: impl Into<String>, y: f64) -> Self {
        let mut s = Self::new(name, [], SeriesKind::Line);
        s.horizontal = Some(y);
        s
    }

    /// Draws the line dashed.
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }

    /// Adds a marker on every point of a line.
    pub fn with_markers(mut self) -> Self {
        if self.kind == SeriesKind::Line {
            self.kind = SeriesKind::LinePoints;
        }
        self
    }

    /// Sets the colour (default: the palette colour of the series' index).
    pub fn color(mut self, color: Rgb) -> Self {
        self.color = Some(color);
        self
    }

    /// Sets the line width (pixels, default 2).
    pub fn width(mut self, px: f32) -> Self {
        self.width = px.max(0.5);
        self
    }

    /// The series' name (shown in the legend; empty = not listed).
    pub fn name(&self) -> &str {
        &self.name
    }

    fn has_line(&self) -> bool {
        self.kind != SeriesKind::Points
    }

    fn has_markers(&self) -> bool {
        self.kind != SeriesKind::Line
    }
}

/// A chart of line and scatter series. Build it, then [`Chart::render`] or
/// [`Chart::save`].
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    decor: Decor,
    series: Vec<Series>,
    x_scale: Scale,
    y_scale: Scale,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
}

/// Where a [`Chart`] puts things, for a given picture size: the plot area and
/// the mapping from data to pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Left edge of the plot area (pixels).
    pub left: f32,
    /// Top edge of the plot area (pixels).
    pub top: f32,
    /// Right edge of the plot area (pixels).
    pub right: f32,
    /// Bottom edge of the plot area (pixels).
    pub bottom: f32,
    x: Axis,
    y: Axis,
}

impl Layout {
    /// Pixel position of a data point (`None` where a log axis cannot show
    /// it). Points outside the axis ranges map outside the plot area.
    pub fn to_pixel(&self, x: f64, y: f64) -> Option<(f32, f32)> {
        let area = self.area();
        Some((area.x_at(self.x.frac(x)?), area.y_at(self.y.frac(y)?)))
    }

    /// The x ticks: value and label.
    pub fn x_ticks(&self) -> &[(f64, String)] {
        &self.x.ticks
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

impl Chart {
    /// An empty chart with a title (may be empty).
    pub fn new(title: impl Into<String>) -> Self {
        Self {
            decor: Decor::new(title.into()),
            series: Vec::new(),
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            x_range: None,
            y_range: None,
        }
    }

    decor_methods!(Chart);

    /// Adds a series; its default colour is the palette entry of its index.
    pub fn series(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    /// Sets the x axis scale.
    pub fn x_scale(mut self, scale: Scale) -> Self {
        self.x_scale = scale;
        self
    }

    /// Sets the y axis scale.
    pub fn y_scale(mut self, scale: Scale) -> Self {
        self.y_scale = scale;
        self
    }

    /// A log₂ x axis with ticks at powers of two (grid sizes g = 16…512).
    pub fn x_log2(self) -> Self {
        self.x_scale(Scale::Log2)
    }

    /// Fixes the x range instead of fitting the data (data outside is clipped).
    pub fn x_range(mut self, lo: f64, hi: f64) -> Self {
        self.x_range = Some((lo, hi));
        self
    }

    /// Fixes the y range instead of fitting the data (data outside is clipped).
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    /// Lays the chart out in a `width`×`height` picture.
    pub fn layout(&self, width: u32, height: u32) -> Result<Layout, PlotError> {
        check_size(width, height)?;
        let fonts = Fonts::for_size(width, height);
        let (w, h) = (width as f32, height as f32);
        let (top, bottom) = self.decor.rows(&fonts, h);
        let xs = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0));
        let ys = self.series.iter().flat_map(|s| {
            s.points
                .iter()
                .filter(|p| self.x_scale.fwd(p.0).is_some())
                .map(|p| p.1)
                .chain(s.horizontal)
        });
        let y = Axis::new(
            self.y_scale,
            ys,
            self.y_range,
            frame::max_ticks(bottom - top, 38.0),
            false,
        );
        let left = frame::left_margin(&fonts, &self.decor.y_label, &y);
        // First guess of the right margin, then room for the last x label.
        let x_guess = Axis::new(self.x_scale, xs.clone(), self.x_range, 8, false);
        let widest = x_guess
            .ticks
            .iter()
            .map(|(_, s)| text_width(fonts.tick, s))
            .fold(0.0, f32::max);
        let right = w - MARGIN.max(widest / 2.0 + 6.0) - 8.0;
        let x = Axis::new(
            self.x_scale,
            xs,
            self.x_range,
            frame::max_ticks(right - left, widest + 30.0),
            false,
        );
        Ok(Layout {
            left,
            top,
            right,
            bottom,
            x,
            y,
        })
    }

    /// Draws the chart into a new `width`×`height` picture.
    pub fn render(&self, width: u32, height: u32) -> Result<Pixmap, PlotError> {
        let layout = self.layout(width, height)?;
        let mut pixmap = check_size(width, height)?;
        let fonts = Fonts::for_size(width, height);
        let area = layout.area();
        let mut canvas = Canvas::new(&mut pixmap);

        let x_cols: Vec<(f32, &str)> = layout
            .x
            .ticks
            .iter()
            .filter_map(|(v, s)| Some((area.x_at(layout.x.frac(*v)?), s.as_str())))
            .filter(|(px, _)| *px >= area.left - 0.5 && *px <= area.right + 0.5)
            .collect();
        let cols: Vec<f32> = x_cols.iter().map(|c| c.0).collect();
        frame::grid(&mut canvas, &area, &layout.y, &cols);

        let clip = canvas.clip(area.left, area.top, area.right, area.bottom);
        let mut obstacles = Vec::new();
        let mut entries = Vec::new();
        for (i, s) in self.series.iter().enumerate() {
            let color = s.color.unwrap_or(PALETTE[i % PALETTE.len()]);
            let pixels: Vec<Option<(f32, f32)>> = match s.horizontal {
                Some(yv) => match layout.y.frac(yv) {
                    Some(f) => {
                        let py = area.y_at(f);
                        vec![Some((area.left, py)), Some((area.right, py))]
                    }
                    None => Vec::new(),
                },
                None => s
                    .points
                    .iter()
                    .map(|&(x, y)| layout.to_pixel(x, y))
                    .collect(),
            };
            if s.has_line() {
                // Undrawable points (log of ≤ 0, NaN) break the line.
                for run in pixels.split(Option::is_none) {
                    let run: Vec<(f32, f32)> = run.iter().flatten().copied().collect();
                    canvas.polyline(&run, color, s.width, s.dashed, clip.as_ref());
                    obstacles.extend(sample_segments(&run));
                }
            }
            if s.has_markers() {
                for &(px, py) in pixels.iter().flatten() {
                    canvas.marker(px, py, 3.5, color, clip.as_ref());
                    obstacles.push((px, py));
                }
            }
            entries.push(Entry {
                name: s.name.clone(),
                color,
                line: s.has_line(),
                dashed: s.dashed,
                marker: s.has_markers(),
                swatch: false,
            });
        }

        self.decor.axes(&mut canvas, &fonts, &area, &layout.y);
        for (px, label) in x_cols {
            frame::x_tick(&mut canvas, &fonts, &area, px, label);
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

/// Points every ~12 pixels along a polyline, so the legend avoids lines too.
fn sample_segments(run: &[(f32, f32)]) -> Vec<(f32, f32)> {
    let mut out = Vec::new();
    for w in run.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        let len = ((x1 - x0).powi(2) + (y1 - y0).powi(2)).sqrt();
        let n = (len / 12.0).ceil().clamp(1.0, 1000.0) as usize;
        for k in 0..=n {
            let t = k as f32 / n as f32;
            out.push((x0 + t * (x1 - x0), y0 + t * (y1 - y0)));
        }
    }
    out
}
