//! White-box profiler: evaluates an object's fitted size and quality models
//! over its configuration space in **fixed point**, producing the
//! configuration tables of the [`mck`](crate::mck) solver directly — on the
//! host and on a microcontroller alike.
//!
//! # Models
//!
//! With `G = g + a`, `P = p + b` and the family's power `e` of `G`
//! ([`Family::Volume`]: `e = 3`, the paper's `g³` voxel count;
//! [`Family::Surface`]: `e = 2`, surface-like growth; [`Family::Quads`]:
//! `e = 3/2`, the texel term of a law with a per-quad term):
//!
//! ```text
//! size     S(g, p) = k · G^e · P² + c · G² + m   bytes, grows
//! quality  Q(g, p) = m − k / (G^e · P²)          SSIM, saturates towards m
//! ```
//!
//! (the NeRFlex paper prints the two formulas swapped; its size law is
//! `c = 0`). The per-quad term `c·G²` is bytes that grow with the quad
//! count (`∝ G²` on a surface) but not with the p² texels of each quad;
//! the volume and surface families leave it at 0, the quads family fits it. The fitted `f64`
//! parameters are [`Params`]; [`Params::size_f64`] and
//! [`Params::quality_f64`] are the `f64` reference the fixed-point code is
//! tested against.
//!
//! # Fixed point
//!
//! [`SizeModel`] / [`QualityModel`] hold the parameters quantised once:
//! offsets `a`, `b` as signed Q31.32 ([`Offset`]), the scale `k` as a 32-bit
//! mantissa with a binary exponent ([`Scale`], because fitted `k` spans
//! twenty orders of magnitude between families and units), the size constant
//! `m` in bytes as Q16 (so the sum is rounded once) and the quality asymptote
//! `m` as signed Q31 (`i64`). Evaluation is integer only (`u128` intermediates, no float,
//! no heap, no panic): `G^e·P²` is formed in Q32 (`G^{3/2} = G·√G` with an
//! integer square root), for the size with every product and root rounded
//! **up** and the sum rounded up to whole bytes (a size is never
//! underestimated by the arithmetic: it is at least the exact value of the
//! quantised parameters); for the quality truncated after each product,
//! and qualities rounded to nearest
//! [`QualityQ`](crate::units::QualityQ) and clamped
//! to `[0, 1]`.
//!
//! # Documented range
//!
//! Inside this range every evaluation succeeds (no overflow) and matches the
//! `f64` reference within `max(0.1 %, 1 byte)` on size and `1e-4` on SSIM
//! (`tests/tests/profile_fixed.rs` checks it by property testing):
//!
//! | quantity | range |
//! |---|---|
//! | grid `g` | `1..=1024` ([`MAX_G`]) |
//! | patch `p` | `1..=64` ([`MAX_P`]) |
//! | `G = g + a` | `[0.5, 4096]` ([`MIN_BASE`], [`MAX_G_BASE`]) |
//! | `P = p + b` | `[0.5, 256]` ([`MIN_BASE`], [`MAX_P_BASE`]) |
//! | `a`, `b` | `[−1024, 4096]`, `[−64, 256]` (so `G`, `P` can be in range) |
//! | size `k` | `[0, 2^10]` bytes per unit of `G^e·P²` ([`MAX_SIZE_K`]) |
//! | size `c` | `[0, 2^24]` bytes per unit of `G²` ([`MAX_SIZE_C`]) |
//! | size `m` | `[0, 2^40]` bytes ([`MAX_SIZE_M`]) |
//! | quality `k` | `[0, 2^60]` ([`MAX_QUALITY_K`]) |
//! | quality `m` | `[−2, 2]` ([`MAX_QUALITY_M`]) |
//! | quality `c` | `0` (the per-quad term is the size model's only) |
//!
//! `g`, `p`, `G` or `P` outside it are rejected with [`ProfileError`];
//! parameters outside it are rejected when the model is built. The fitter
//! (`nerflex_sim::fit`) bounds `a ∈ [−g_min/2, 2·g_max]`,
//! `b ∈ [−p_min/2, max(256 − 2·p_max, 2·p_max)]` and `c` to at most the
//! smallest `S/(g/2)²` measured, so fitted profiles evaluated on their
//! sampled range always fall inside.
//!
//! # Cost
//!
//! One configuration is a handful of `u128` multiplications and one `u128`
//! division; a 256-entry table needs no memory beyond the output slice.

mod fixed;
mod params;
mod space;

pub use fixed::{Offset, Profile, QualityModel, Scale, SizeModel};
pub use params::{Family, Params};
pub use space::ConfigSpace;

use core::fmt;

/// Largest grid resolution `g` accepted.
pub const MAX_G: u32 = 1024;
/// Largest patch size `p` accepted.
pub const MAX_P: u32 = 64;
/// Smallest `G = g + a` and `P = p + b` accepted.
pub const MIN_BASE: f64 = 0.5;
/// Largest `G = g + a` accepted.
pub const MAX_G_BASE: f64 = 4096.0;
/// Largest `P = p + b` accepted.
pub const MAX_P_BASE: f64 = 256.0;
/// Largest size scale `k` (bytes per unit of `G^e·P²`) accepted.
pub const MAX_SIZE_K: f64 = 1024.0;
/// Largest per-quad size scale `c` (bytes per unit of `G²`) accepted.
pub const MAX_SIZE_C: f64 = 16_777_216.0;
/// Largest size constant `m` accepted (bytes, 2^40 ≈ 1.1 TB).
pub const MAX_SIZE_M: f64 = 1_099_511_627_776.0;
/// Largest quality scale `k` accepted (2^60).
pub const MAX_QUALITY_K: f64 = 1_152_921_504_606_846_976.0;
/// Largest `|m|` of the quality model accepted.
pub const MAX_QUALITY_M: f64 = 2.0;

/// Which of the two models an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Curve {
    /// The size model.
    Size,
    /// The quality model.
    Quality,
}

impl fmt::Display for Curve {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Curve::Size => "size",
            Curve::Quality => "quality",
        })
    }
}

/// Which model parameter an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// The scale `k`.
    K,
    /// The offset `a` added to `g`.
    A,
    /// The offset `b` added to `p`.
    B,
    /// The per-quad scale `c` (size only).
    C,
    /// The constant / asymptote `m`.
    M,
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Field::K => "k",
            Field::A => "a",
            Field::B => "b",
            Field::C => "c",
            Field::M => "m",
        })
    }
}

/// Why a model could not be built or evaluated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProfileError {
    /// A parameter is NaN or infinite.
    NotFinite {
        /// Which model.
        curve: Curve,
        /// Which parameter.
        field: Field,
        /// Its value.
        value: f64,
    },
    /// A parameter is outside the documented range.
    ParamOutOfRange {
        /// Which model.
        curve: Curve,
        /// Which parameter.
        field: Field,
        /// Its value.
        value: f64,
        /// Smallest accepted value.
        min: f64,
        /// Largest accepted value.
        max: f64,
    },
    /// `g` is 0 or above [`MAX_G`].
    GridOutOfRange {
        /// The grid resolution.
        g: u32,
    },
    /// `p` is 0 or above [`MAX_P`].
    PatchOutOfRange {
        /// The patch size.
        p: u32,
    },
    /// `g + a` or `p + b` is outside `[MIN_BASE, MAX_*_BASE]` (the model
    /// has a pole or the product would overflow).
    BaseOutOfRange {
        /// The grid resolution.
        g: u32,
        /// The patch size.
        p: u32,
    },
    /// The predicted size does not fit a `u64` byte count (only possible
    /// outside the documented parameter range).
    SizeOverflow {
        /// The grid resolution.
        g: u32,
        /// The patch size.
        p: u32,
    },
    /// The output table is shorter than the configuration space.
    TableTooSmall {
        /// Configurations in the space.
        needed: usize,
        /// Length of the output slice.
        len: usize,
    },
    /// The configuration space has more than [`crate::mck::MAX_CONFIGS`]
    /// configurations or an empty `g` or `p` list.
    BadSpace {
        /// Number of `g` values.
        grids: usize,
        /// Number of `p` values.
        patches: usize,
    },
}

impl fmt::Display for ProfileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ProfileError::NotFinite {
                curve,
                field,
                value,
            } => write!(f, "{curve} {field} is not a finite number ({value})"),
            ProfileError::ParamOutOfRange {
                curve,
                field,
                value,
                min,
                max,
            } => write!(
                f,
                "{curve} {field} = {value} is outside the supported range [{min}, {max}]"
            ),
            ProfileError::GridOutOfRange { g } => {
                write!(f, "grid g = {g} is outside 1..={MAX_G}")
            }
            ProfileError::PatchOutOfRange { p } => {
                write!(f, "patch p = {p} is outside 1..={MAX_P}")
            }
            ProfileError::BaseOutOfRange { g, p } => write!(
                f,
                "at (g {g}, p {p}) g + a or p + b is outside [{MIN_BASE}, {MAX_G_BASE}] / [{MIN_BASE}, {MAX_P_BASE}]"
            ),
            ProfileError::SizeOverflow { g, p } => {
                write!(f, "predicted size at (g {g}, p {p}) does not fit 64 bits")
            }
            ProfileError::TableTooSmall { needed, len } => write!(
                f,
                "the output table holds {len} configurations, {needed} are needed"
            ),
            ProfileError::BadSpace { grids, patches } => write!(
                f,
                "{grids} g values × {patches} p values: need 1..={} configurations",
                crate::mck::MAX_CONFIGS
            ),
        }
    }
}

impl core::error::Error for ProfileError {}
