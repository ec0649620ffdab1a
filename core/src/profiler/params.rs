//! The fitted parameters in `f64` and the `f64` reference evaluation.

/// The power of `G = g + a` in a model: how the data grows with the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Family {
    /// `G³`: one unit per voxel of the g³ grid (the NeRFlex paper's form).
    #[default]
    Volume,
    /// `G²`: one unit per surface cell (quads cover the object's surface,
    /// whose cell count grows with g²).
    Surface,
    /// `G^{3/2}`: the texel term of the *quads* size law
    /// `S = k·G^{3/2}·P² + c·G² + m` — quads grow like the surface, `G²`,
    /// each carries a constant `c` bytes per unit of `G²` (geometry,
    /// per-quad overhead) and p² texels whose compressed bytes per texel
    /// fall like `G^{-1/2}` as the cells shrink.
    Quads,
}

impl Family {
    /// Every family, the paper's first.
    pub const ALL: [Family; 3] = [Family::Volume, Family::Surface, Family::Quads];

    /// Twice the power `e` of `G`: 6, 4 or 3 (an integer for every family).
    pub const fn g_power_halves(self) -> u32 {
        match self {
            Family::Volume => 6,
            Family::Surface => 4,
            Family::Quads => 3,
        }
    }

    /// The power `e` of `G`: 3, 2 or 1.5.
    pub fn g_power(self) -> f64 {
        f64::from(self.g_power_halves()) / 2.0
    }

    /// The family with power `e` of `G`, if any (3, 2 or 1.5).
    pub fn from_g_power(e: f64) -> Option<Family> {
        Family::ALL.into_iter().find(|f| f.g_power() == e)
    }

    /// Lower-case name: `volume`, `surface` or `quads`.
    pub const fn name(self) -> &'static str {
        match self {
            Family::Volume => "volume",
            Family::Surface => "surface",
            Family::Quads => "quads",
        }
    }

    /// `G^e` in `f64`.
    pub fn g_pow_f64(self, gg: f64) -> f64 {
        match self {
            Family::Volume => gg * gg * gg,
            Family::Surface => gg * gg,
            Family::Quads => gg * libm::sqrt(gg),
        }
    }
}

impl core::fmt::Display for Family {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// One fitted curve: `k`, `a`, `b`, `c`, `m` and the family.
///
/// The same numbers serve both models; which formula applies is the
/// caller's choice ([`Params::size_f64`] or [`Params::quality_f64`]). The
/// per-quad term `c` is the size model's only (the quality model requires
/// `c = 0`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Params {
    /// Scale `k` (bytes per unit of `G^e·P²` for size; SSIM·unit for quality).
    pub k: f64,
    /// Offset `a` added to `g`.
    pub a: f64,
    /// Offset `b` added to `p`.
    pub b: f64,
    /// Size only: bytes per unit of `G²` that do not scale with `P²` (a
    /// per-quad overhead: quads grow like `G²`). 0 in the volume and
    /// surface families and in profiles written before it existed.
    pub c: f64,
    /// Constant term (size, bytes) or asymptote (quality, SSIM).
    pub m: f64,
    /// Power of `G`.
    pub family: Family,
}

impl Params {
    /// `G^e · P²` at (g, p), in `f64`.
    pub fn volume_f64(&self, g: f64, p: f64) -> f64 {
        let gg = g + self.a;
        let pp = p + self.b;
        self.family.g_pow_f64(gg) * pp * pp
    }

    /// `G²` at g, in `f64` (the per-quad term's unit).
    pub fn quads_f64(&self, g: f64) -> f64 {
        let gg = g + self.a;
        gg * gg
    }

    /// Size reference `k·G^e·P² + c·G² + m` (bytes, not rounded).
    pub fn size_f64(&self, g: f64, p: f64) -> f64 {
        self.k * self.volume_f64(g, p) + self.c * self.quads_f64(g) + self.m
    }

    /// Quality reference `m − k/(G^e·P²)` (SSIM, not clamped).
    pub fn quality_f64(&self, g: f64, p: f64) -> f64 {
        self.m - self.k / self.volume_f64(g, p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_formulas() {
        let s = Params {
            k: 0.5,
            a: 1.0,
            b: -1.0,
            c: 0.0,
            m: 1000.0,
            family: Family::Volume,
        };
        // (2+1)³·(3−1)² = 108.
        assert_eq!(s.volume_f64(2.0, 3.0), 108.0);
        assert_eq!(s.size_f64(2.0, 3.0), 1054.0);
        // Quads: (3+1)^{3/2}·(3−1)² = 32, plus c·(3+1)² = 2·16.
        let quads = Params {
            c: 2.0,
            family: Family::Quads,
            ..s
        };
        assert_eq!(quads.volume_f64(3.0, 3.0), 32.0);
        assert_eq!(quads.size_f64(3.0, 3.0), 0.5 * 32.0 + 32.0 + 1000.0);
        let q = Params {
            k: 54.0,
            m: 0.9,
            family: Family::Surface,
            ..s
        };
        // (2+1)²·(3−1)² = 36.
        assert_eq!(q.quality_f64(2.0, 3.0), 0.9 - 1.5);
        assert_eq!(Family::from_g_power(2.0), Some(Family::Surface));
        assert_eq!(Family::from_g_power(1.5), Some(Family::Quads));
        assert_eq!(Family::from_g_power(4.0), None);
        assert_eq!(Family::Volume.g_power(), 3.0);
        assert_eq!(Family::Quads.g_power_halves(), 3);
    }
}
