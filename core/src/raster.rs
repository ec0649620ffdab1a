//! Tile-based rasterization of textured quads with deferred shading, in
//! fixed-size buffers, for a microcontroller as well as the host.
//!
//! A frame is cut into `W × H`-pixel tiles. For each tile a
//! [`TileRenderer`] rasterizes the quads that touch it into a G-buffer
//! (depth, texel address, quad id): perspective-correct texture
//! coordinates, nearest texel, alpha test (a texel is empty iff its
//! `feat0.R == 0`, MobileNeRF's `discard`), depth test. Then every covered
//! pixel is shaded exactly once by its part's [`FixedMlp`] (deferred
//! shading, as MobileNeRF does) and the tile is handed to an
//! `embedded-graphics` [`DrawTarget`], composited over white.
//!
//! Conventions:
//! - positions are in the z-up world frame of the cameras; [`View`] holds an
//!   OpenGL camera (looks down −z, y up) and pinhole intrinsics in pixels;
//!   pixel `(i, j)` is sampled at its centre `(i + ½, j + ½)`, `j` down.
//! - `uv` are OBJ texture coordinates of the atlas: `u = x / width`,
//!   `v = 1 − y / height` with `(x, y)` in texels, `y` down.
//! - a [`Quad`] is the two triangles (0, 1, 3) and (0, 3, 2) of its corners,
//!   the order of the MobileNeRF OBJ export; a `single_triangle` quad is
//!   just (0, 1, 2) (exports drop the empty half of some quads).
//! - screen positions are snapped to 1/256 pixel and edge functions are
//!   exact `i64`, with a tie rule that gives every pixel on an edge shared by
//!   two triangles to exactly one of them (no cracks, no double shading).
//!   Vertices closer than [`NEAR`] to the camera plane, or farther than
//!   [`GUARD_PX`] pixels off-screen, make their triangle skipped (counted in
//!   [`TileStats::triangles_clipped`]): there is no clipping.
//!
//! Setup and interpolation use `f32` (the Cortex-M4F has an FPU); the
//! shading pass — view direction and MLP — uses integers only.
//!
//! For the baker, [`TileRenderer::draw_behind`] peels the layer behind
//! the front samples, and [`TwoLayers`] draws both layers in one pass
//! with the same result.

use crate::shader::{FixedMlp, ViewDir};
/// Re-exported: the `DrawTarget` API this module renders into.
pub use embedded_graphics_core;
use embedded_graphics_core::draw_target::DrawTarget;
use embedded_graphics_core::geometry::{Point, Size};
use embedded_graphics_core::pixelcolor::Rgb888;
use embedded_graphics_core::primitives::Rectangle;
/// Re-exported: [`View::new`] takes a `glam::Mat4`.
pub use glam;
use glam::Mat4;

/// Sub-pixel bits of snapped screen positions (1/256 pixel).
pub const SUBPIXEL_BITS: u32 = 8;
/// Nearest depth drawn, world units along the view axis.
pub const NEAR: f32 = 1.0e-3;
/// Vertices farther than this many pixels outside the image skip their triangle.
pub const GUARD_PX: f32 = 1_048_576.0;
/// Largest image or atlas side, pixels / texels.
pub const MAX_SIDE: u32 = 16_384;
/// Background colour: MobileNeRF's viewer composites over white.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];

/// Why a frame cannot be set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RasterError {
    /// Atlas side 0 or above [`MAX_SIDE`], or a page's byte length is not `width·height·4`.
    BadAtlas,
    /// The camera is unusable (names the problem).
    BadView(&'static str),
    /// More than `u32::MAX` quads in one frame.
    TooManyQuads,
    /// A caller-provided buffer is too small.
    BufferTooSmall {
        /// Elements needed.
        needed: usize,
        /// Elements given.
        got: usize,
    },
}

impl core::fmt::Display for RasterError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RasterError::BadAtlas => write!(
                f,
                "atlas pages must be width·height·4 bytes, sides 1..={MAX_SIDE}"
            ),
            RasterError::BadView(why) => write!(f, "bad camera: {why}"),
            RasterError::TooManyQuads => write!(f, "more than 2^32 quads in one frame"),
            RasterError::BufferTooSmall { needed, got } => {
                write!(f, "buffer too small: {got} elements, {needed} needed")
            }
        }
    }
}

impl core::error::Error for RasterError {}

/// A quad corner: world position (z-up) and OBJ texture coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vertex {
    /// World position.
    pub pos: [f32; 3],
    /// `(u, v)`, `u = x/width`, `v = 1 − y/height` (texels, y down).
    pub uv: [f32; 2],
}

impl Vertex {
    /// A corner at texel coordinates `(x, y)` (texel `(i, j)` has its centre
    /// at `(i + ½, j + ½)`) of an atlas of `width × height` texels.
    pub fn at_texel(pos: [f32; 3], x: f32, y: f32, width: u32, height: u32) -> Self {
        Self {
            pos,
            uv: [x / width as f32, 1.0 - y / height as f32],
        }
    }
}

/// A textured quad (two triangles) or a lone triangle; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Quad {
    /// Corners 0..4; triangles (0, 1, 3) and (0, 3, 2).
    pub corners: [Vertex; 4],
    /// Only triangle (0, 1, 2) exists; corner 3 is unused.
    pub single_triangle: bool,
}

/// Corner indices of a quad's two triangles.
pub const QUAD_TRIANGLES: [[usize; 3]; 2] = [[0, 1, 3], [0, 3, 2]];

impl Quad {
    /// A full quad.
    pub const fn new(corners: [Vertex; 4]) -> Self {
        Self {
            corners,
            single_triangle: false,
        }
    }

    /// A lone triangle.
    pub const fn triangle(a: Vertex, b: Vertex, c: Vertex) -> Self {
        Self {
            corners: [a, b, c, c],
            single_triangle: true,
        }
    }

    /// Corner indices of its triangles (one or two).
    pub fn triangles(&self) -> &'static [[usize; 3]] {
        if self.single_triangle {
            &[[0, 1, 2]]
        } else {
            &QUAD_TRIANGLES
        }
    }
}

/// Two RGBA8 feature pages of equal size, row-major, borrowed.
#[derive(Debug, Clone, Copy)]
pub struct Atlas<'a> {
    width: u32,
    height: u32,
    feat0: &'a [u8],
    feat1: &'a [u8],
}

impl<'a> Atlas<'a> {
    /// Checks the sizes (`width·height·4` bytes each).
    pub fn new(
        width: u32,
        height: u32,
        feat0: &'a [u8],
        feat1: &'a [u8],
    ) -> Result<Self, RasterError> {
        let ok_side = |s: u32| (1..=MAX_SIDE).contains(&s);
        let len = (width as usize)
            .checked_mul(height as usize)
            .and_then(|n| n.checked_mul(4));
        if !ok_side(width)
            || !ok_side(height)
            || len != Some(feat0.len())
            || len != Some(feat1.len())
        {
            return Err(RasterError::BadAtlas);
        }
        Ok(Self {
            width,
            height,
            feat0,
            feat1,
        })
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    #[inline]
    fn offset(&self, x: u32, y: u32) -> usize {
        let x = x.min(self.width - 1) as usize; // width ≥ 1 (checked in new)
        let y = y.min(self.height - 1) as usize;
        (y * self.width as usize + x) * 4
    }

    /// The two feature texels at `(x, y)` (clamped to the page).
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> ([u8; 4], [u8; 4]) {
        let o = self.offset(x, y);
        (rgba(self.feat0, o), rgba(self.feat1, o))
    }

    /// `feat0.R` at `(x, y)` (clamped): 0 means empty.
    #[inline]
    pub fn feat0_r(&self, x: u32, y: u32) -> u8 {
        self.feat0.get(self.offset(x, y)).copied().unwrap_or(0)
    }
}

/// What the rasterizer's alpha test reads of a part's atlas: the page size
/// (texel coordinates scale with it) and which texels are empty.
pub trait AlphaTest {
    /// Width in texels (≥ 1).
    fn width(&self) -> u32;
    /// Height in texels (≥ 1).
    fn height(&self) -> u32;
    /// Whether texel `(x, y)` (clamped to the page) is empty: a fragment
    /// there is discarded.
    fn empty(&self, x: u32, y: u32) -> bool;
}

impl AlphaTest for Atlas<'_> {
    #[inline]
    fn width(&self) -> u32 {
        self.width
    }
    #[inline]
    fn height(&self) -> u32 {
        self.height
    }
    #[inline]
    fn empty(&self, x: u32, y: u32) -> bool {
        self.feat0_r(x, y) == 0
    }
}

/// An atlas page's alpha test as one bit per texel (1: `feat0.R ≠ 0`),
/// rows of `width.div_ceil(64)` words: 1/32 of the page's feat0 bytes, so
/// a pass that only needs coverage (a G-buffer) reads it from cache.
#[derive(Debug, Clone, Copy)]
pub struct AlphaBits<'a> {
    width: u32,
    height: u32,
    bits: &'a [u64],
}

impl<'a> AlphaBits<'a> {
    /// Words per row of a page `width` texels wide.
    pub const fn row_words(width: u32) -> usize {
        width.div_ceil(64) as usize
    }

    /// Checks the sizes (`row_words(width) · height` words).
    pub fn new(width: u32, height: u32, bits: &'a [u64]) -> Result<Self, RasterError> {
        let ok_side = |s: u32| (1..=MAX_SIDE).contains(&s);
        if !ok_side(width)
            || !ok_side(height)
            || Self::row_words(width).checked_mul(height as usize) != Some(bits.len())
        {
            return Err(RasterError::BadAtlas);
        }
        Ok(Self {
            width,
            height,
            bits,
        })
    }
}

impl AlphaTest for AlphaBits<'_> {
    #[inline]
    fn width(&self) -> u32 {
        self.width
    }
    #[inline]
    fn height(&self) -> u32 {
        self.height
    }
    #[inline]
    fn empty(&self, x: u32, y: u32) -> bool {
        // Clamped as `Atlas::feat0_r` clamps (width, height ≥ 1).
        let x = x.min(self.width - 1) as usize;
        let y = y.min(self.height - 1) as usize;
        let w = self
            .bits
            .get(y * Self::row_words(self.width) + x / 64)
            .copied()
            .unwrap_or(0);
        (w >> (x % 64)) & 1 == 0
    }
}

#[inline]
fn rgba(page: &[u8], o: usize) -> [u8; 4] {
    match page.get(o..o + 4) {
        Some(&[r, g, b, a]) => [r, g, b, a],
        _ => [0; 4],
    }
}

/// One object part: its quads, its atlas and its MLP.
#[derive(Debug, Clone, Copy)]
pub struct Part<'a> {
    /// The quads.
    pub quads: &'a [Quad],
    /// Their feature atlas.
    pub atlas: Atlas<'a>,
    /// The view-dependent MLP.
    pub mlp: &'a FixedMlp,
}

/// A camera prepared for rasterization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// World-to-camera, first three rows.
    w2c: [[f32; 4]; 3],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: u32,
    height: u32,
    /// Unnormalised world ray direction of pixel (0, 0) and its steps per
    /// pixel in x and y, Q30.
    dir0: [i64; 3],
    dir_dx: [i64; 3],
    dir_dy: [i64; 3],
}

impl View {
    /// `c2w`: camera-to-world (OpenGL camera); intrinsics in pixels.
    pub fn new(
        c2w: Mat4,
        fx: f32,
        fy: f32,
        cx: f32,
        cy: f32,
        width: u32,
        height: u32,
    ) -> Result<Self, RasterError> {
        if !(1..=MAX_SIDE).contains(&width) || !(1..=MAX_SIDE).contains(&height) {
            return Err(RasterError::BadView("image side must be 1..=16384 pixels"));
        }
        if !(fx.is_finite()
            && fy.is_finite()
            && fx > 0.0
            && fy > 0.0
            && cx.is_finite()
            && cy.is_finite())
        {
            return Err(RasterError::BadView(
                "focal lengths must be positive, principal point finite",
            ));
        }
        // Keep ray slopes within ±512 so the Q30 ray fits comfortably in i64.
        let span_x = libm::fmaxf(libm::fabsf(cx), libm::fabsf(width as f32 - cx)) / fx;
        let span_y = libm::fmaxf(libm::fabsf(cy), libm::fabsf(height as f32 - cy)) / fy;
        if !(span_x < 512.0 && span_y < 512.0) {
            return Err(RasterError::BadView("field of view too wide"));
        }
        let w2c = c2w.inverse();
        let cols = c2w.to_cols_array_2d();
        if !(w2c.is_finite() && c2w.is_finite()) {
            return Err(RasterError::BadView("camera-to-world is not invertible"));
        }
        let m = w2c.to_cols_array_2d();
        // Checked access: `r`, `c`, `k` are constants below 4, but no
        // indexing in the core may be able to panic.
        let at = |a: &[[f32; 4]; 4], c: usize, k: usize| {
            a.get(c).and_then(|col| col.get(k)).copied().unwrap_or(0.0)
        };
        let row = |r: usize| [at(&m, 0, r), at(&m, 1, r), at(&m, 2, r), at(&m, 3, r)];
        // World ray of pixel centre (px + ½, py + ½): R·((px+½−cx)/fx, −(py+½−cy)/fy, −1).
        let (fx64, fy64) = (fx as f64, fy as f64);
        let r = |c: usize, k: usize| at(&cols, c, k) as f64;
        let q30 = |v: f64| libm::round(v * (1u64 << 30) as f64) as i64;
        let a = (0.5 - cx as f64) / fx64;
        let b = -(0.5 - cy as f64) / fy64;
        let mut dir0 = [0i64; 3];
        let mut dir_dx = [0i64; 3];
        let mut dir_dy = [0i64; 3];
        for k in 0..3 {
            let (rx, ry, rz) = (r(0, k), r(1, k), r(2, k));
            if let (Some(d0), Some(dx), Some(dy)) =
                (dir0.get_mut(k), dir_dx.get_mut(k), dir_dy.get_mut(k))
            {
                *d0 = q30(rx * a + ry * b - rz);
                *dx = q30(rx / fx64);
                *dy = q30(-ry / fy64);
            }
        }
        let lim = 1i64 << 44;
        if dir0
            .iter()
            .chain(&dir_dx)
            .chain(&dir_dy)
            .any(|v| v.abs() > lim)
        {
            return Err(RasterError::BadView("camera rotation is not a rotation"));
        }
        Ok(Self {
            w2c: [row(0), row(1), row(2)],
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            dir0,
            dir_dx,
            dir_dy,
        })
    }

    /// Image width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Continuous pixel coordinates and depth (along the view axis) of a
    /// world point; `None` closer than [`NEAR`] or not finite.
    #[inline]
    pub fn project(&self, p: [f32; 3]) -> Option<[f32; 3]> {
        let t = |r: &[f32; 4]| r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
        let [r0, r1, r2] = &self.w2c;
        let (x, y, depth) = (t(r0), t(r1), -t(r2));
        if depth.is_nan() || depth < NEAR {
            return None;
        }
        let inv = 1.0 / depth;
        let sx = self.cx + self.fx * x * inv;
        let sy = self.cy - self.fy * y * inv;
        (sx.is_finite() && sy.is_finite()).then_some([sx, sy, depth])
    }

    /// The unit world-frame view direction through the centre of pixel
    /// `(px, py)`, in Q2.30 — integers only.
    #[inline]
    pub fn pixel_dir(&self, px: u32, py: u32) -> ViewDir {
        let (px, py) = (i64::from(px.min(MAX_SIDE)), i64::from(py.min(MAX_SIDE)));
        let mut d = [0i64; 3];
        for (k, dk) in d.iter_mut().enumerate() {
            let g = |a: &[i64; 3]| a.get(k).copied().unwrap_or(0);
            *dk = g(&self.dir0)
                .wrapping_add(px.wrapping_mul(g(&self.dir_dx)))
                .wrapping_add(py.wrapping_mul(g(&self.dir_dy)));
        }
        // Bring the largest component under 2^31 so the squares sum in u64.
        let m = d.iter().map(|v| v.unsigned_abs()).max().unwrap_or(0);
        let shift = (64 - m.leading_zeros()).saturating_sub(31);
        let d = d.map(|v| v >> shift);
        let len2: u64 = d.iter().map(|v| v.unsigned_abs().pow(2)).sum();
        let len = len2.isqrt() as i64; // ≥ 2^29: the −z part of the ray is 1 (Q30)
        if len == 0 {
            return ViewDir::default();
        }
        let q = |v: i64| {
            let n = v << 30; // |v| < 2^31: fits
            let r = if n >= 0 {
                (n + len / 2) / len
            } else {
                (n - len / 2) / len
            };
            r.clamp(i32::MIN as i64, i32::MAX as i64) as i32
        };
        ViewDir::from_bits(d.map(q))
    }

    /// The same direction in `f32` (for the float renderer).
    pub fn pixel_dir_f32(&self, px: u32, py: u32) -> [f32; 3] {
        let (px, py) = (px as f64, py as f64);
        let s = 1.0 / (1u64 << 30) as f64;
        let mut d = [0f64; 3];
        for (k, dk) in d.iter_mut().enumerate() {
            let g = |a: &[i64; 3]| a.get(k).copied().unwrap_or(0) as f64 * s;
            *dk = g(&self.dir0) + px * g(&self.dir_dx) + py * g(&self.dir_dy);
        }
        let len = libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if len > 0.0 {
            d.map(|v| (v / len) as f32)
        } else {
            [0.0; 3]
        }
    }
}

/// A projected corner: snapped position and perspective-divided attributes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ScreenVertex {
    /// x in 1/256 pixel.
    pub x: i64,
    /// y in 1/256 pixel (down).
    pub y: i64,
    /// 1 / depth.
    pub inv_w: f32,
    /// `u / depth`.
    pub s_w: f32,
    /// `(1 − v) / depth` (texel rows grow downward).
    pub t_w: f32,
}

/// A quad projected for one view.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ScreenQuad {
    /// Projected corners.
    pub v: [ScreenVertex; 4],
    /// Bit `i` set: corner `i` projected (in front of [`NEAR`], inside the guard band).
    pub valid: u8,
    /// As [`Quad::single_triangle`].
    pub single_triangle: bool,
    /// Covered pixel box, inclusive: `[x0, y0, x1, y1]`, clipped to the image.
    pub bbox: [u32; 4],
    /// Index of its part.
    pub part: u16,
    /// Frame-wide quad id (for visibility counts).
    pub id: u32,
    /// Triangles skipped because a corner did not project.
    pub clipped: u8,
}

impl ScreenQuad {
    /// The largest `1/w` of its projected corners (0 if none): its
    /// fragments' `1/w`, interpolated between them, is at most this, up to
    /// rounding ([`TwoLayers::hides`]).
    pub fn nearest(&self) -> f32 {
        self.v
            .iter()
            .enumerate()
            .filter(|&(i, _)| self.valid & (1 << i) != 0)
            .fold(0.0, |m, (_, v)| m.max(v.inv_w))
    }

    /// Projects a quad; `None` if no triangle of it can touch the image.
    pub fn project(view: &View, quad: &Quad, part: u16, id: u32) -> Option<Self> {
        let mut out = ScreenQuad {
            single_triangle: quad.single_triangle,
            part,
            id,
            ..Default::default()
        };
        let scale = (1u32 << SUBPIXEL_BITS) as f32;
        let (w, h) = (view.width as f32, view.height as f32);
        for (i, (c, sv)) in quad.corners.iter().zip(out.v.iter_mut()).enumerate() {
            if quad.single_triangle && i == 3 {
                break;
            }
            let Some([x, y, depth]) = view.project(c.pos) else {
                continue;
            };
            if !(x > -GUARD_PX && x < w + GUARD_PX && y > -GUARD_PX && y < h + GUARD_PX) {
                continue;
            }
            let inv_w = 1.0 / depth;
            let (s, t) = (c.uv[0], 1.0 - c.uv[1]);
            if !(s.is_finite() && t.is_finite()) {
                continue;
            }
            *sv = ScreenVertex {
                x: libm::roundf(x * scale) as i64,
                y: libm::roundf(y * scale) as i64,
                inv_w,
                s_w: s * inv_w,
                t_w: t * inv_w,
            };
            out.valid |= 1 << i;
        }
        let (mut x0, mut y0, mut x1, mut y1) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
        let mut any = false;
        for tri in quad.triangles() {
            if !tri.iter().all(|&i| out.valid & (1 << i) != 0) {
                out.clipped = out.clipped.saturating_add(1);
                continue;
            }
            any = true;
            for &i in tri {
                if let Some(v) = out.v.get(i) {
                    x0 = x0.min(v.x);
                    y0 = y0.min(v.y);
                    x1 = x1.max(v.x);
                    y1 = y1.max(v.y);
                }
            }
        }
        if !any {
            return None;
        }
        let [px0, py0] = [first_centre(x0), first_centre(y0)].map(|v| v.max(0));
        let px1 = last_centre(x1).min(view.width as i64 - 1);
        let py1 = last_centre(y1).min(view.height as i64 - 1);
        if px0 > px1 || py0 > py1 {
            return None;
        }
        out.bbox = [px0 as u32, py0 as u32, px1 as u32, py1 as u32];
        Some(out)
    }

    /// Whether its box meets the pixel rectangle `[x0, x1] × [y0, y1]` (inclusive).
    #[inline]
    pub fn overlaps(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> bool {
        let [a0, b0, a1, b1] = self.bbox;
        a0 <= x1 && a1 >= x0 && b0 <= y1 && b1 >= y0
    }
}

/// One G-buffer entry.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct GPixel {
    /// 1/depth of the nearest kept fragment; 0 = empty.
    inv_w: f32,
    part: u16,
    tx: u16,
    ty: u16,
    quad: u32,
}

/// What a covered pixel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sample {
    /// Part index.
    pub part: u16,
    /// Texel `(x, y)` in the part's atlas.
    pub texel: [u16; 2],
    /// Frame-wide quad id.
    pub quad: u32,
}

/// Subsamples per pixel side of the supersampled resolve (2 × 2, as
/// MobileNeRF's viewer rasterizes its G-buffer at twice the output size).
pub const SUPERSAMPLE: u32 = 2;

/// The texel bytes a supersampled pixel shades for one part: the rounded
/// mean of its covered subsamples' bytes (`texels`; zeros when empty).
/// Features are averaged before the MLP, once per pixel and part, as
/// MobileNeRF's viewer filters its G-buffer; the byte mean keeps the
/// shader's 8-bit inputs.
pub fn mean_texel(texels: &[([u8; 4], [u8; 4])]) -> ([u8; 4], [u8; 4]) {
    let n = texels.len() as u64;
    let mut s0 = [0u64; 4];
    let mut s1 = [0u64; 4];
    for (a, b) in texels {
        for (acc, &v) in s0.iter_mut().zip(a) {
            *acc += u64::from(v);
        }
        for (acc, &v) in s1.iter_mut().zip(b) {
            *acc += u64::from(v);
        }
    }
    // Round half up; the mean of bytes is a byte (zeros when empty).
    let mean = |sum: u64| (2 * sum + n).checked_div(2 * n).unwrap_or(0).min(255) as u8;
    (s0.map(mean), s1.map(mean))
}

/// Work counters of one tile (or, summed, a frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TileStats {
    /// Triangles set up (touching the tile).
    pub triangles: u32,
    /// Triangles skipped: a corner behind [`NEAR`] or outside the guard band.
    pub triangles_clipped: u32,
    /// Fragments that passed the depth test and the alpha test (written).
    pub fragments: u32,
    /// Fragments discarded by the alpha test (empty texel).
    pub discarded: u32,
}

impl TileStats {
    /// Field-wise sum (saturating: counters never wrap or panic).
    pub fn add(&mut self, o: &TileStats) {
        self.triangles = self.triangles.saturating_add(o.triangles);
        self.triangles_clipped = self.triangles_clipped.saturating_add(o.triangles_clipped);
        self.fragments = self.fragments.saturating_add(o.fragments);
        self.discarded = self.discarded.saturating_add(o.discarded);
    }
}

/// A peeled fragment's `1/w` must be below this fraction of the front
/// sample's (depth more than 10⁻⁵ relatively behind it).
const PEEL_MARGIN: f32 = 1.0 - 1e-5;

/// The per-tile G-buffer and rasterizer; `W × H` pixels, no heap
/// (`16·W·H` bytes: 16 KiB for 32 × 32).
#[derive(Debug, Clone)]
pub struct TileRenderer<const W: usize, const H: usize> {
    g: [[GPixel; W]; H],
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    stats: TileStats,
}

impl<const W: usize, const H: usize> Default for TileRenderer<W, H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const H: usize> TileRenderer<W, H> {
    /// An empty renderer.
    pub const fn new() -> Self {
        Self {
            g: [[GPixel {
                inv_w: 0.0,
                part: 0,
                tx: 0,
                ty: 0,
                quad: 0,
            }; W]; H],
            x0: 0,
            y0: 0,
            w: 0,
            h: 0,
            stats: TileStats {
                triangles: 0,
                triangles_clipped: 0,
                fragments: 0,
                discarded: 0,
            },
        }
    }

    /// Starts the tile whose top-left pixel is `(x0, y0)` (clipped to the image).
    pub fn begin(&mut self, view: &View, x0: u32, y0: u32) {
        self.restart(
            x0,
            y0,
            view.width.saturating_sub(x0),
            view.height.saturating_sub(y0),
        );
    }

    /// Starts over on the rectangle `(x0, y0, w, h)` of an earlier
    /// [`TileRenderer::begin`].
    fn restart(&mut self, x0: u32, y0: u32, w: u32, h: u32) {
        self.x0 = x0;
        self.y0 = y0;
        self.w = w.min(W as u32);
        self.h = h.min(H as u32);
        self.stats = TileStats::default();
        for row in self.g.iter_mut() {
            for p in row.iter_mut() {
                p.inv_w = 0.0;
            }
        }
    }

    /// The tile's pixel rectangle `(x0, y0, width, height)`.
    pub fn rect(&self) -> (u32, u32, u32, u32) {
        (self.x0, self.y0, self.w, self.h)
    }

    /// Counters since [`TileRenderer::begin`].
    pub fn stats(&self) -> TileStats {
        self.stats
    }

    /// Whether a projected quad can touch this tile.
    #[inline]
    pub fn touches(&self, sq: &ScreenQuad) -> bool {
        self.w > 0
            && self.h > 0
            && sq.overlaps(self.x0, self.y0, self.x0 + self.w - 1, self.y0 + self.h - 1)
    }

    /// Rasterizes a projected quad into the G-buffer (depth + alpha test);
    /// `atlas` is its part's atlas (or just its alpha test).
    pub fn draw<A: AlphaTest + ?Sized>(&mut self, sq: &ScreenQuad, atlas: &A) {
        self.draw_over(sq, atlas, None, false);
    }

    /// [`TileRenderer::draw`] of quads drawn in any order, with the
    /// samples [`TileRenderer::draw`] gives in ascending id order: equal
    /// depths go to the lower id (ids must be distinct; the counters
    /// depend on the order). Near quads first lets most hidden fragments
    /// skip their alpha test, and whole quads be skipped
    /// ([`TileRenderer::hides`]).
    pub fn draw_by_id<A: AlphaTest + ?Sized>(&mut self, sq: &ScreenQuad, atlas: &A) {
        self.draw_over(sq, atlas, None, true);
    }

    /// Whether drawing `sq` now would change no sample: every pixel of its
    /// box in this tile is already covered nearer than `nearest`, a bound
    /// of its `1/w` ([`ScreenQuad::nearest`]; a relative 10⁻⁴ is added for
    /// the interpolation's rounding), so all of its fragments would fail
    /// the depth test.
    pub fn hides(&self, sq: &ScreenQuad, nearest: f32) -> bool {
        let bound = nearest * (1.0 + 1e-4);
        let (x0, y0, w, h) = self.rect();
        let [bx0, by0, bx1, by1] = sq.bbox;
        let (cx0, cy0) = (bx0.max(x0), by0.max(y0));
        let (cx1, cy1) = (
            bx1.min((x0 + w).saturating_sub(1)),
            by1.min((y0 + h).saturating_sub(1)),
        );
        if w == 0 || h == 0 || cx0 > cx1 || cy0 > cy1 {
            // Off the tile: drawing it does nothing.
            return true;
        }
        (cy0..=cy1).all(|y| {
            self.g.get((y - y0) as usize).is_some_and(|row| {
                (cx0..=cx1).all(|x| row.get((x - x0) as usize).is_some_and(|g| g.inv_w > bound))
            })
        })
    }

    /// [`TileRenderer::draw`] of the second layer (depth peeling): only
    /// fragments strictly behind what `front` (the same tile, drawn with
    /// the same quads) shows at their pixel, and not of that quad, pass.
    /// What a pixel shows once its front texel is made transparent.
    pub fn draw_behind<A: AlphaTest + ?Sized>(&mut self, sq: &ScreenQuad, atlas: &A, front: &Self) {
        self.draw_over(sq, atlas, Some(&front.g), false);
    }

    /// With `by_id`, equal depths go to the lower quad id instead of the
    /// sample already there.
    fn draw_over<A: AlphaTest + ?Sized>(
        &mut self,
        sq: &ScreenQuad,
        atlas: &A,
        front: Option<&[[GPixel; W]; H]>,
        by_id: bool,
    ) {
        if !self.touches(sq) {
            return;
        }
        let rect = self.rect();
        let (g, stats) = (&mut self.g, &mut self.stats);
        for_each_triangle(sq, stats, |tri, stats| {
            tri.scan(rect, stats, |ry, rx, iw, l, stats| {
                let Some(row) = g.get_mut(ry) else { return };
                if let Some(fr) = front.and_then(|f| f.get(ry)) {
                    // Peeling: strictly behind the front sample (a relative
                    // margin, so the front quad's own depth never passes).
                    let Some(f) = fr.get(rx) else { return };
                    if !peels(f, sq.id, iw) {
                        return;
                    }
                }
                if let Some(g) = row.get_mut(rx) {
                    // (`iw > 0` when `g` is empty, so its stale id is never
                    // compared.)
                    if iw > g.inv_w || (by_id && iw == g.inv_w && sq.id < g.quad && iw > 0.0) {
                        if let Some(px) = tri.fragment(sq, atlas, iw, l, stats) {
                            *g = px;
                        }
                    }
                }
            });
        });
    }

    /// Covered pixels of the tile.
    pub fn covered(&self) -> u32 {
        self.g
            .iter()
            .take(self.h as usize)
            .flat_map(|r| r.iter().take(self.w as usize))
            .filter(|g| g.inv_w > 0.0)
            .count() as u32
    }

    /// The sample at tile-local pixel `(x, y)`, if covered.
    #[inline]
    pub fn sample(&self, x: u32, y: u32) -> Option<Sample> {
        let g = self.g.get(y as usize)?.get(x as usize)?;
        (g.inv_w > 0.0 && x < self.w && y < self.h).then_some(Sample {
            part: g.part,
            texel: [g.tx, g.ty],
            quad: g.quad,
        })
    }

    /// Whether tile-local pixel `(x, y)` shows a fragment here that lies in
    /// front of what `behind` (the same tile, drawn with the same quads
    /// under another alpha test) shows there, by more than the peel's
    /// margin and on another quad; where `behind` is empty, whether this
    /// one is covered. `false` outside the tile.
    #[inline]
    pub fn nearer_than(&self, behind: &Self, x: u32, y: u32) -> bool {
        if x >= self.w || y >= self.h {
            return false;
        }
        let at = |t: &Self| t.g.get(y as usize).and_then(|r| r.get(x as usize)).copied();
        let (Some(f), Some(b)) = (at(self), at(behind)) else {
            return false;
        };
        f.inv_w > 0.0 && (b.inv_w <= 0.0 || peels(&f, b.quad, b.inv_w))
    }

    /// Calls `f(x, y, sample)` for every pixel of the tile, row-major, with
    /// image coordinates.
    pub fn for_each_sample(&self, mut f: impl FnMut(u32, u32, Option<Sample>)) {
        for y in 0..self.h {
            for x in 0..self.w {
                f(self.x0 + x, self.y0 + y, self.sample(x, y));
            }
        }
    }

    /// Fixed-point colour of tile-local pixel `(x, y)`: `None` when empty
    /// (background) or its part index is unknown.
    #[inline]
    pub fn shade_pixel(&self, view: &View, parts: &[Part], x: u32, y: u32) -> Option<[u8; 3]> {
        let s = self.sample(x, y)?;
        let part = parts.get(s.part as usize)?;
        let (f0, f1) = part
            .atlas
            .texel(u32::from(s.texel[0]), u32::from(s.texel[1]));
        let dir = view.pixel_dir(self.x0 + x, self.y0 + y);
        Some(part.mlp.shade(f0, f1, dir))
    }

    /// Sets bit `quad` of `bits` for every quad that owns a pixel of the tile.
    pub fn mark_visible(&self, bits: &mut [u32]) {
        for y in 0..self.h {
            for x in 0..self.w {
                if let Some(s) = self.sample(x, y) {
                    if let Some(word) = bits.get_mut((s.quad / 32) as usize) {
                        *word |= 1 << (s.quad % 32);
                    }
                }
            }
        }
    }
}

/// Whether a fragment of quad `quad` at `iw` passes the peel behind the
/// front sample `f`: `f` covered, another quad, and more than
/// [`PEEL_MARGIN`] behind it.
#[inline(always)]
fn peels(f: &GPixel, quad: u32, iw: f32) -> bool {
    !(f.inv_w <= 0.0 || f.quad == quad || iw >= f.inv_w * PEEL_MARGIN)
}

/// Calls `f` with each drawable triangle of `sq` set up (clipped ones are
/// counted and skipped).
#[inline(always)]
fn for_each_triangle(
    sq: &ScreenQuad,
    stats: &mut TileStats,
    mut f: impl FnMut(&Triangle, &mut TileStats),
) {
    let tris: &[[usize; 3]] = if sq.single_triangle {
        &[[0, 1, 2]]
    } else {
        &QUAD_TRIANGLES
    };
    for tri in tris {
        if !tri.iter().all(|&i| sq.valid & (1 << i) != 0) {
            stats.triangles_clipped = stats.triangles_clipped.saturating_add(1);
            continue;
        }
        let [a, b, c] = tri.map(|i| sq.v.get(i).copied().unwrap_or_default());
        if let Some(t) = Triangle::new(a, b, c) {
            f(&t, stats);
        }
    }
}

/// A triangle set up for scanning: counter-clockwise corners and the
/// inverse of its doubled area (`None` when degenerate).
struct Triangle {
    a: ScreenVertex,
    b: ScreenVertex,
    c: ScreenVertex,
    area: i64,
    inv_area: f32,
}

impl Triangle {
    #[inline(always)]
    fn new(a: ScreenVertex, b: ScreenVertex, c: ScreenVertex) -> Option<Self> {
        let mut area = edge(&a, &b, c.x, c.y);
        let (b, c) = if area < 0 {
            area = -area;
            (c, b)
        } else {
            (b, c)
        };
        (area != 0).then(|| Self {
            a,
            b,
            c,
            area,
            inv_area: 1.0 / area as f32,
        })
    }

    /// Calls `frag(row, column, 1/w, barycentrics, stats)` for every pixel
    /// of the tile `rect` whose centre the triangle covers (tile-local
    /// row and column), row by row.
    #[inline(always)]
    fn scan(
        &self,
        rect: (u32, u32, u32, u32),
        stats: &mut TileStats,
        mut frag: impl FnMut(usize, usize, f32, [f32; 3], &mut TileStats),
    ) {
        let (a, b, c) = (&self.a, &self.b, &self.c);
        let (x0, y0, w, h) = rect;
        debug_assert!(self.area > 0);
        // Triangle box ∩ tile, in pixels whose centres can be inside.
        let px0 = first_centre(a.x.min(b.x).min(c.x)).max(x0 as i64);
        let py0 = first_centre(a.y.min(b.y).min(c.y)).max(y0 as i64);
        let px1 = last_centre(a.x.max(b.x).max(c.x)).min((x0 + w) as i64 - 1);
        let py1 = last_centre(a.y.max(b.y).max(c.y)).min((y0 + h) as i64 - 1);
        if px0 > px1 || py0 > py1 {
            return;
        }
        stats.triangles = stats.triangles.saturating_add(1);
        let bias = |p: &ScreenVertex, q: &ScreenVertex| {
            let (dx, dy) = (q.x - p.x, q.y - p.y);
            if dy > 0 || (dy == 0 && dx < 0) {
                0
            } else {
                -1
            }
        };
        let (bias_bc, bias_ca, bias_ab) = (bias(b, c), bias(c, a), bias(a, b));
        let step = 1i64 << SUBPIXEL_BITS;
        let half = step >> 1;
        let inv_area = self.inv_area;
        let (d_bc, d_ca, d_ab) = ((c.y - b.y) * step, (a.y - c.y) * step, (b.y - a.y) * step);
        for py in py0..=py1 {
            let sy = py * step + half;
            let sx = px0 * step + half;
            let (e_bc, e_ca, e_ab) = (edge(b, c, sx, sy), edge(c, a, sx, sy), edge(a, b, sx, sy));
            // The row's inside pixels, solved exactly from the integer edge
            // functions: the same pixels the per-pixel test takes, without
            // walking (and mispredicting on) the box's outside ones.
            let Some((k0, k1)) = span(
                px1 - px0,
                [
                    (e_bc + bias_bc, d_bc),
                    (e_ca + bias_ca, d_ca),
                    (e_ab + bias_ab, d_ab),
                ],
            ) else {
                continue;
            };
            let ry = (py - y0 as i64) as usize;
            for k in k0..=k1 {
                let l = [
                    (e_bc - k * d_bc) as f32 * inv_area,
                    (e_ca - k * d_ca) as f32 * inv_area,
                    (e_ab - k * d_ab) as f32 * inv_area,
                ];
                let iw = l[0] * a.inv_w + l[1] * b.inv_w + l[2] * c.inv_w;
                let rx = (px0 + k - x0 as i64) as usize;
                frag(ry, rx, iw, l, stats);
            }
        }
    }

    /// The G-buffer entry of a fragment at `1/w = iw` and barycentrics `l`
    /// after the alpha test (`None`: its texel is empty); counted in `stats`.
    #[inline(always)]
    fn fragment<A: AlphaTest + ?Sized>(
        &self,
        sq: &ScreenQuad,
        atlas: &A,
        iw: f32,
        l: [f32; 3],
        stats: &mut TileStats,
    ) -> Option<GPixel> {
        let (a, b, c) = (&self.a, &self.b, &self.c);
        let (aw, ah) = (atlas.width(), atlas.height());
        let s = (l[0] * a.s_w + l[1] * b.s_w + l[2] * c.s_w) / iw;
        let t = (l[0] * a.t_w + l[1] * b.t_w + l[2] * c.t_w) / iw;
        let tx = texel_index(s * aw as f32, aw);
        let ty = texel_index(t * ah as f32, ah);
        if atlas.empty(tx, ty) {
            stats.discarded = stats.discarded.saturating_add(1);
            None
        } else {
            stats.fragments = stats.fragments.saturating_add(1);
            Some(GPixel {
                inv_w: iw,
                part: sq.part,
                tx: tx as u16,
                ty: ty as u16,
                quad: sq.id,
            })
        }
    }
}

/// First pixel whose centre `(p + ½)·256` is ≥ `v` (1/256 px).
#[inline(always)]
fn first_centre(v: i64) -> i64 {
    (v - (1 << (SUBPIXEL_BITS - 1)) + (1 << SUBPIXEL_BITS) - 1) >> SUBPIXEL_BITS
}

/// Last pixel whose centre is ≤ `v` (1/256 px).
#[inline(always)]
fn last_centre(v: i64) -> i64 {
    (v - (1 << (SUBPIXEL_BITS - 1))) >> SUBPIXEL_BITS
}

/// The steps `k0..=k1` of `0..=last` at which every `e − k·d ≥ 0` (an
/// edge value and its decrement per pixel), or `None`: integer-exact, so it
/// keeps the pixels a per-pixel test would. Values are bounded by the guard
/// band (|e| < 2⁵⁸, |d| < 2³⁸), so nothing overflows.
#[inline(always)]
fn span(last: i64, edges: [(i64, i64); 3]) -> Option<(i64, i64)> {
    let (mut k0, mut k1) = (0i64, last);
    for (e, d) in edges {
        if d > 0 {
            // Falling: inside up to floor(e / d); skip the division when
            // the whole run is inside.
            if e < 0 {
                return None;
            }
            if e - k1 * d < 0 {
                k1 = e / d;
            }
        } else if d < 0 {
            // Rising: inside from ceil(−e / −d).
            if e < 0 {
                let n = -d;
                k0 = k0.max((-e + n - 1) / n);
            }
        } else if e < 0 {
            return None;
        }
    }
    (k0 <= k1).then_some((k0, k1))
}

/// Edge function of `p → q` at `(sx, sy)` (all in 1/256 px); exact.
#[inline(always)]
fn edge(p: &ScreenVertex, q: &ScreenVertex, sx: i64, sy: i64) -> i64 {
    (q.x - p.x) * (sy - p.y) - (q.y - p.y) * (sx - p.x)
}

/// Nearest texel index `floor(c)` clamped to `0..n`.
#[inline(always)]
fn texel_index(c: f32, n: u32) -> u32 {
    if c.is_nan() || c <= 0.0 {
        return 0; // also NaN
    }
    let i = c as u32; // truncation = floor for c > 0; saturates
    i.min(n - 1)
}

/// Frame-level counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameStats {
    /// Quads with at least one triangle projected onto the image (drawn).
    pub quads_drawn: u32,
    /// Pixels covered, each shaded once.
    pub pixels_shaded: u32,
    /// Summed tile counters (a quad spanning tiles is set up once per tile).
    pub tiles: TileStats,
}

/// Coverage-only counters of a view (no shading).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Coverage {
    /// Quads with at least one triangle projected onto the image.
    pub quads_drawn: u32,
    /// Distinct quads owning at least one final pixel.
    pub quads_visible: u32,
    /// Covered pixels (= pixels a deferred renderer shades).
    pub pixels_covered: u32,
    /// Summed tile counters.
    pub tiles: TileStats,
}

/// Total quads of the parts, as a `u32` id range.
pub fn quad_count(parts: &[Part]) -> Result<u32, RasterError> {
    let n: usize = parts.iter().map(|p| p.quads.len()).sum();
    u32::try_from(n).map_err(|_| RasterError::TooManyQuads)
}

/// Runs the raster pass over all tiles: for each tile, projects every quad
/// (no per-frame buffer: memory stays `O(tile)`), draws those touching it,
/// and calls `done(tile)`. A quad is counted drawn by the tile holding the
/// top-left corner of its box.
fn for_each_tile<const W: usize, const H: usize, E>(
    tile: &mut TileRenderer<W, H>,
    view: &View,
    parts: &[Part],
    mut done: impl FnMut(&TileRenderer<W, H>) -> Result<(), E>,
) -> Result<(u32, TileStats), E> {
    let mut drawn = 0u32;
    let mut stats = TileStats::default();
    let side = |n: usize| u32::try_from(n.max(1)).unwrap_or(u32::MAX);
    let (tw, th) = (side(W), side(H));
    let mut y0 = 0;
    while y0 < view.height {
        let mut x0 = 0;
        while x0 < view.width {
            tile.begin(view, x0, y0);
            let mut id = 0u32;
            for (pi, part) in parts.iter().enumerate() {
                for q in part.quads {
                    if let Some(sq) = ScreenQuad::project(view, q, pi as u16, id) {
                        if tile.touches(&sq) {
                            tile.draw(&sq, &part.atlas);
                            let [bx, by, _, _] = sq.bbox;
                            if bx >= x0 && bx < x0 + tw && by >= y0 && by < y0 + th {
                                drawn = drawn.saturating_add(1);
                            }
                        }
                    }
                    id = id.wrapping_add(1);
                }
            }
            stats.add(&tile.stats());
            done(tile)?;
            x0 = x0.saturating_add(tw);
        }
        y0 = y0.saturating_add(th);
    }
    Ok((drawn, stats))
}

/// Renders a frame tile by tile into `target` (fixed-point shading, white
/// background). The target should be `view.width() × view.height()`.
pub fn render_frame<D, const W: usize, const H: usize>(
    tile: &mut TileRenderer<W, H>,
    view: &View,
    parts: &[Part],
    target: &mut D,
) -> Result<FrameStats, D::Error>
where
    D: DrawTarget<Color = Rgb888>,
{
    let mut shaded = 0u32;
    let (quads_drawn, tiles) = for_each_tile(tile, view, parts, |t| {
        let (x0, y0, w, h) = t.rect();
        shaded = shaded.saturating_add(t.covered());
        let area = Rectangle::new(Point::new(x0 as i32, y0 as i32), Size::new(w, h));
        let colors = (0..h).flat_map(|y| {
            (0..w).map(move |x| {
                let [r, g, b] = t.shade_pixel(view, parts, x, y).unwrap_or(BACKGROUND);
                Rgb888::new(r, g, b)
            })
        });
        target.fill_contiguous(&area, colors)
    })?;
    Ok(FrameStats {
        quads_drawn,
        pixels_shaded: shaded,
        tiles,
    })
}

/// Coverage-only pass: covered pixels, quads drawn and distinct visible
/// quads of a view, without shading. `visible` is a bitset of at least
/// `ceil(quads / 32)` words (cleared here).
pub fn coverage<const W: usize, const H: usize>(
    tile: &mut TileRenderer<W, H>,
    view: &View,
    parts: &[Part],
    visible: &mut [u32],
) -> Result<Coverage, RasterError> {
    let n = quad_count(parts)? as usize;
    let words = n.div_ceil(32);
    if visible.len() < words {
        return Err(RasterError::BufferTooSmall {
            needed: words,
            got: visible.len(),
        });
    }
    visible.iter_mut().for_each(|w| *w = 0);
    let mut covered = 0u32;
    let (quads_drawn, tiles) = for_each_tile::<W, H, RasterError>(tile, view, parts, |t| {
        covered = covered.saturating_add(t.covered());
        t.mark_visible(visible);
        Ok(())
    })?;
    Ok(Coverage {
        quads_drawn,
        quads_visible: visible.iter().map(|w| w.count_ones()).sum(),
        pixels_covered: covered,
        tiles,
    })
}

mod peel;
pub use peel::TwoLayers;

#[cfg(test)]
mod tests;
