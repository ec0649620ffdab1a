//! Compositing over white: the common first step of every metric.

use image::RgbaImage;

/// An image composited over a white background: RGB in [0, 1], row-major,
/// interleaved (`rgb[(y·width + x)·3 + c]`).
#[derive(Debug, Clone, PartialEq)]
pub struct WhiteComposite {
    width: u32,
    height: u32,
    rgb: Vec<f64>,
}

impl WhiteComposite {
    /// Composites `img` over white: `c/255 · a/255 + 1 − a/255` per channel.
    pub fn new(img: &RgbaImage) -> Self {
        let rgb = img
            .pixels()
            .flat_map(|p| {
                let a = f64::from(p.0[3]) / 255.0;
                let over = move |c: u8| f64::from(c) / 255.0 * a + (1.0 - a);
                [over(p.0[0]), over(p.0[1]), over(p.0[2])]
            })
            .collect();
        Self {
            width: img.width(),
            height: img.height(),
            rgb,
        }
    }

    /// Wraps interleaved RGB values in [0, 1]; `None` if the length is not
    /// `width · height · 3`.
    pub fn from_rgb(width: u32, height: u32, rgb: Vec<f64>) -> Option<Self> {
        let n = (width as usize)
            .checked_mul(height as usize)?
            .checked_mul(3)?;
        (rgb.len() == n).then_some(Self { width, height, rgb })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// `(width, height)` in pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Interleaved RGB values in [0, 1].
    pub fn rgb(&self) -> &[f64] {
        &self.rgb
    }
}
