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
}

impl Family {
    /// Both families, the paper's first.
    pub const ALL: [Family; 2] = [Family::Volume, Family::Surface];

    /// The power `e` of `G`: 3 or 2.
    pub const fn g_power(self) -> u32 {
        match self {
            Family::Volume => 3,
            Family::Surface => 2,
        }
    }

    /// The family with power `e` of `G`, if any (2 or 3).
    pub const fn from_g_power(e: u32) -> Option<Family> {
        match e {
            3 => Some(Family::Volume),
            2 => Some(Family::Surface),
            _ => None,
        }
    }

    /// Lower-case name: `volume` or `surface`.
    pub const fn name(self) -> &'static str {
        match self {
            Family::Volume => "volume",
            Family::Surface => "surface",
        }
    }
}

impl core::fmt::Display for Family {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// One fitted curve: `k`, `a`, `b`, `m` and the family.
///
/// The same four numbers serve both models; which formula applies is the
/// caller's choice ([`Params::size_f64`] or [`Params::quality_f64`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Params {
    /// Scale `k` (bytes per unit of `G^e·P²` for size; SSIM·unit for quality).
    pub k: f64,
    /// Offset `a` added to `g`.
    pub a: f64,
    /// Offset `b` added to `p`.
    pub b: f64,
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
        let ge = match self.family {
            Family::Volume => gg * gg * gg,
            Family::Surface => gg * gg,
        };
        ge * pp * pp
    }

    /// Size reference `k·G^e·P² + m` (bytes, not rounded).
    pub fn size_f64(&self, g: f64, p: f64) -> f64 {
        self.k * self.volume_f64(g, p) + self.m
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
            m: 1000.0,
            family: Family::Volume,
        };
        // (2+1)³·(3−1)² = 108.
        assert_eq!(s.volume_f64(2.0, 3.0), 108.0);
        assert_eq!(s.size_f64(2.0, 3.0), 1054.0);
        let q = Params {
            k: 54.0,
            m: 0.9,
            family: Family::Surface,
            ..s
        };
        // (2+1)²·(3−1)² = 36.
        assert_eq!(q.quality_f64(2.0, 3.0), 0.9 - 1.5);
        assert_eq!(Family::from_g_power(2), Some(Family::Surface));
        assert_eq!(Family::from_g_power(4), None);
        assert_eq!(Family::Volume.g_power(), 3);
    }
}
