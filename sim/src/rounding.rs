//! `f32` floor and ceil with the same bits as `std`'s on every input,
//! inlined.
//!
//! Baseline x86-64 has no rounding instruction (SSE4.1's `roundss`), so
//! `f32::floor` and `f32::ceil` compile to calls into libm; in the bake's
//! hot loops (the hull's point test, the texel lines, the feature
//! lattice's taps) the calls and the register spills around them were
//! about 2 % of a lego (128, 17) bake's CPU time. These go through a
//! truncating conversion instead (`cvttss2si`), exact below 2²³ where
//! every `f32` with a fraction lives; the sign is copied from the input
//! so that zeros keep theirs as `std`'s do. (`f32::round` stays `std`'s:
//! its callers are inlined into the `avx2` fine-tune and judgement, where
//! LLVM already rounds in registers and vectorises; this module's
//! version, per lane, made the fine-tune 5 % slower.)

/// 2²³: every `f32` at or above it in magnitude is an integer.
const INTEGRAL: f32 = 8_388_608.0;

/// `x.trunc()` for |x| < 2²³ (the conversion is exact there).
#[inline(always)]
fn trunc_small(x: f32) -> f32 {
    x as i32 as f32
}

/// `x.floor()`, the same bits.
#[inline(always)]
pub fn floor(x: f32) -> f32 {
    if x.abs() < INTEGRAL {
        let t = trunc_small(x);
        let f = if t > x { t - 1.0 } else { t };
        f.copysign(x)
    } else {
        x // integral, infinite or NaN: std returns it as it is
    }
}

/// `x.ceil()`, the same bits.
#[inline(always)]
pub fn ceil(x: f32) -> f32 {
    if x.abs() < INTEGRAL {
        let t = trunc_small(x);
        let c = if t < x { t + 1.0 } else { t };
        c.copysign(x)
    } else {
        x
    }
}

/// [`floor`] of each component.
#[inline(always)]
pub fn floor3(v: glam::Vec3) -> glam::Vec3 {
    glam::Vec3::new(floor(v.x), floor(v.y), floor(v.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn same(bits: u32) {
        let x = f32::from_bits(bits);
        if x.is_nan() {
            // std's payload may differ (libm may quiet it); NaN stays NaN.
            assert!(floor(x).is_nan() && ceil(x).is_nan());
            return;
        }
        assert_eq!(
            floor(x).to_bits(),
            x.floor().to_bits(),
            "floor {x:e} ({bits:#x})"
        );
        assert_eq!(
            ceil(x).to_bits(),
            x.ceil().to_bits(),
            "ceil {x:e} ({bits:#x})"
        );
    }

    /// Zeros, halves, the ends of the fast path, infinities and NaN.
    #[test]
    fn edge_cases_match_std() {
        let edges = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            0.49999997,
            -0.49999997,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.99999994,
            -0.99999994,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            INTEGRAL,
            -INTEGRAL,
            INTEGRAL - 0.5,
            -(INTEGRAL - 0.5),
            INTEGRAL - 1.5,
            16_777_216.0,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for x in edges {
            same(x.to_bits());
        }
    }

    /// Every `f32` whose magnitude lies in [1/4, 4) (2²⁴ of them each
    /// side, walked at a stride): the fractions that decide them.
    #[test]
    fn small_magnitudes_match_std() {
        let lo = 0.25f32.to_bits();
        let hi = 4.0f32.to_bits();
        for bits in (lo..hi).step_by(97) {
            same(bits);
            same(bits | 0x8000_0000);
        }
    }

    proptest! {
        #[test]
        fn any_bits_match_std(bits in any::<u32>()) {
            same(bits);
        }

        #[test]
        fn pixel_range_matches_std(x in -5000.0f32..5000.0) {
            same(x.to_bits());
        }
    }
}
