//! Fixed-point parameters and their integer-only evaluation.
//!
//! Every operation is checked: an input outside the documented range gives a
//! [`ProfileError`], never a panic or a wrapped value.

use super::{
    ConfigSpace, Curve, Family, Field, Params, ProfileError, MAX_G, MAX_G_BASE, MAX_P, MAX_P_BASE,
    MAX_QUALITY_K, MAX_QUALITY_M, MAX_SIZE_C, MAX_SIZE_K, MAX_SIZE_M,
};
use crate::mck::Config;
use crate::units::{Bytes, QualityQ};

/// Fraction bits of the offsets and of `G`, `P` and `G^e·P²`.
const FRAC: u32 = 32;
/// `0.5` in Q32: the smallest `G` and `P`.
const MIN_BASE_Q32: u64 = 1 << (FRAC - 1);
/// The quality term `k/(G^e·P²)` is capped at 2^9 (Q31): far above any
/// asymptote `m ≤ 2`, so a capped term still clamps the quality to 0.
const TERM_CAP_Q31: u128 = 1 << 40;

/// A signed offset (`a` or `b`) in Q31.32: `raw / 2^32`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Offset(i64);

impl Offset {
    /// From the raw Q31.32 value.
    pub const fn from_raw(raw: i64) -> Offset {
        Offset(raw)
    }

    /// The raw Q31.32 value.
    pub const fn raw(self) -> i64 {
        self.0
    }

    /// The offset as `f64` (exact).
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / (1u64 << FRAC) as f64
    }

    /// `v` rounded to the nearest 2^-32, if finite and within `[min, max]`
    /// (`|min|, |max| < 2^31`).
    fn from_f64(
        v: f64,
        curve: Curve,
        field: Field,
        min: f64,
        max: f64,
    ) -> Result<Offset, ProfileError> {
        check_range(v, curve, field, min, max)?;
        // |v| < 2^31, so |v·2^32| < 2^63: the cast is exact after rounding.
        Ok(Offset(libm::round(v * (1u64 << FRAC) as f64) as i64))
    }
}

/// A non-negative scale `k = mantissa · 2^exponent` with a 32-bit mantissa
/// (normalised to `[2^31, 2^32)` unless zero): relative precision 2^-32 over
/// any magnitude.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Scale {
    mantissa: u32,
    exponent: i16,
}

impl Scale {
    /// Zero.
    pub const ZERO: Scale = Scale {
        mantissa: 0,
        exponent: 0,
    };

    /// `mantissa · 2^exponent`.
    pub const fn from_raw(mantissa: u32, exponent: i16) -> Scale {
        Scale { mantissa, exponent }
    }

    /// The mantissa.
    pub const fn mantissa(self) -> u32 {
        self.mantissa
    }

    /// The binary exponent.
    pub const fn exponent(self) -> i16 {
        self.exponent
    }

    /// The scale as `f64` (exact for exponents within `f64`'s range).
    pub fn to_f64(self) -> f64 {
        libm::ldexp(self.mantissa as f64, i32::from(self.exponent))
    }

    /// `v` rounded to 32 significant bits, if finite and within `[0, max]`.
    fn from_f64(v: f64, curve: Curve, field: Field, max: f64) -> Result<Scale, ProfileError> {
        check_range(v, curve, field, 0.0, max)?;
        if v == 0.0 {
            return Ok(Scale::ZERO);
        }
        // v = f·2^e, f in [0.5, 1); f·2^32 in [2^31, 2^32].
        let (f, e) = libm::frexp(v);
        let m = libm::round(f * 4_294_967_296.0);
        let (mantissa, e) = if m >= 4_294_967_296.0 {
            (1u32 << 31, e.saturating_add(1))
        } else {
            (m as u32, e)
        };
        // e in [-1073, 1025] for finite f64: fits i16 after the shift.
        let exponent = i16::try_from(e.saturating_sub(32)).unwrap_or(i16::MIN);
        Ok(Scale { mantissa, exponent })
    }
}

fn check_range(v: f64, curve: Curve, field: Field, min: f64, max: f64) -> Result<(), ProfileError> {
    if !v.is_finite() {
        return Err(ProfileError::NotFinite {
            curve,
            field,
            value: v,
        });
    }
    if v < min || v > max {
        return Err(ProfileError::ParamOutOfRange {
            curve,
            field,
            value: v,
            min,
            max,
        });
    }
    Ok(())
}

/// Offsets accepted when building a model: `a ∈ [−MAX_G, MAX_G_BASE]`,
/// `b ∈ [−MAX_P, MAX_P_BASE]` (whether `g + a` is a valid base is checked
/// per configuration).
fn offsets(params: &Params, curve: Curve) -> Result<(Offset, Offset), ProfileError> {
    let a = Offset::from_f64(params.a, curve, Field::A, -(MAX_G as f64), MAX_G_BASE)?;
    let b = Offset::from_f64(params.b, curve, Field::B, -(MAX_P as f64), MAX_P_BASE)?;
    Ok((a, b))
}

/// How a Q32 product or root drops its extra bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Round {
    /// Truncate (the quality path).
    Down,
    /// Round up (the size path: a size is never underestimated).
    Up,
}

/// `G = g + a` and `P = p + b` in Q32 for (g, p), or why not.
fn bases_q32(g: u32, p: u32, a: Offset, b: Offset) -> Result<(u128, u128), ProfileError> {
    if g == 0 || g > MAX_G {
        return Err(ProfileError::GridOutOfRange { g });
    }
    if p == 0 || p > MAX_P {
        return Err(ProfileError::PatchOutOfRange { p });
    }
    let out_of_range = ProfileError::BaseOutOfRange { g, p };
    let gb = base_q32(g, a, MAX_G_BASE as u64).ok_or(out_of_range)?;
    let pb = base_q32(p, b, MAX_P_BASE as u64).ok_or(out_of_range)?;
    Ok((gb, pb))
}

/// `x·y` for Q32 `x`, `y`, in Q32 (`None` on overflow).
fn mul_q32(x: u128, y: u128, round: Round) -> Option<u128> {
    let v = x.checked_mul(y)?;
    let whole = v >> FRAC;
    let rest = v & ((1u128 << FRAC) - 1);
    Some(whole + u128::from(round == Round::Up && rest != 0))
}

/// `√x` for Q32 `x < 2^96`, in Q32.
fn sqrt_q32(x: u128, round: Round) -> Option<u128> {
    // √(x/2^32)·2^32 = √(x·2^32); x·2^32 < 2^128.
    let v = x.checked_shl(FRAC).filter(|v| v >> FRAC == x)?;
    let r = v.isqrt();
    // r < 2^64, so r·r cannot overflow.
    Some(r + u128::from(round == Round::Up && r * r < v))
}

/// `G^e` in Q32 for `G` in Q32 (`G < 2^44`, so `G³ < 2^68`).
fn g_pow_q32(gb: u128, family: Family, round: Round) -> Option<u128> {
    match family {
        Family::Volume => mul_q32(mul_q32(gb, gb, round)?, gb, round),
        Family::Surface => mul_q32(gb, gb, round),
        Family::Quads => mul_q32(gb, sqrt_q32(gb, round)?, round),
    }
}

/// `G^e · P²` in Q32 from `G`, `P` in Q32 (`G < 2^44`, `P < 2^40`: the
/// widest product is `G³ (< 2^68) · P² (< 2^48) < 2^116`).
fn volume_q32(
    gb: u128,
    pb: u128,
    family: Family,
    round: Round,
    err: ProfileError,
) -> Result<u128, ProfileError> {
    let ge = g_pow_q32(gb, family, round).ok_or(err)?;
    let p2 = mul_q32(pb, pb, round).ok_or(err)?;
    mul_q32(ge, p2, round).ok_or(err)
}

/// `n + offset` in Q32 if it lies in `[0.5, max]`.
fn base_q32(n: u32, offset: Offset, max: u64) -> Option<u128> {
    let v = (i64::from(n) << FRAC).checked_add(offset.0)?;
    let v = u64::try_from(v).ok()?;
    let max_q32 = max.checked_shl(FRAC)?;
    (MIN_BASE_Q32..=max_q32)
        .contains(&v)
        .then_some(u128::from(v))
}

/// Fraction bits of the size constant `m` and of the size before rounding.
const SIZE_FRAC: u32 = 16;

/// The size model `S = k·G^e·P² + c·G² + m` in fixed point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct SizeModel {
    /// Bytes per unit of `G^e·P²`.
    pub k: Scale,
    /// Offset added to g.
    pub a: Offset,
    /// Offset added to p.
    pub b: Offset,
    /// Bytes per unit of `G²` (the per-quad term; zero outside the quads
    /// family).
    pub c: Scale,
    /// Constant part (MLP, headers) in bytes, Q16 (`raw / 2^16` bytes), so
    /// that the sum is rounded up to whole bytes once.
    pub m_q16: u64,
    /// Power of `G`.
    pub family: Family,
}

impl SizeModel {
    /// Quantises fitted parameters; errors outside the documented range.
    pub fn from_params(params: &Params) -> Result<SizeModel, ProfileError> {
        let c = Curve::Size;
        let k = Scale::from_f64(params.k, c, Field::K, MAX_SIZE_K)?;
        let (a, b) = offsets(params, c)?;
        let per_quad = Scale::from_f64(params.c, c, Field::C, MAX_SIZE_C)?;
        check_range(params.m, c, Field::M, 0.0, MAX_SIZE_M)?;
        // m in [0, 2^40]: m·2^16 ≤ 2^56 is exact in u64 after rounding.
        let m_q16 = libm::round(params.m * (1u64 << SIZE_FRAC) as f64) as u64;
        Ok(SizeModel {
            k,
            a,
            b,
            c: per_quad,
            m_q16,
            family: params.family,
        })
    }

    /// The parameters back as `f64` (after quantisation).
    pub fn params(&self) -> Params {
        Params {
            k: self.k.to_f64(),
            a: self.a.to_f64(),
            b: self.b.to_f64(),
            c: self.c.to_f64(),
            m: self.m_q16 as f64 / (1u64 << SIZE_FRAC) as f64,
            family: self.family,
        }
    }

    /// Predicted size at (g, p), rounded up to whole bytes: every product,
    /// root and shift rounds up, so the result is never below the exact
    /// value of the quantised parameters.
    pub fn size(&self, g: u32, p: u32) -> Result<Bytes, ProfileError> {
        let overflow = ProfileError::SizeOverflow { g, p };
        let (gb, pb) = bases_q32(g, p, self.a, self.b)?;
        let x = volume_q32(gb, pb, self.family, Round::Up, overflow)?;
        let kx_q16 = scaled_q16(x, self.k).ok_or(overflow)?;
        let cx_q16 = if self.c.mantissa == 0 {
            0
        } else {
            let g2 = mul_q32(gb, gb, Round::Up).ok_or(overflow)?;
            scaled_q16(g2, self.c).ok_or(overflow)?
        };
        let total_q16 = kx_q16
            .checked_add(cx_q16)
            .and_then(|v| v.checked_add(u128::from(self.m_q16)))
            .ok_or(overflow)?;
        let ceil = total_q16.div_ceil(1 << SIZE_FRAC);
        u64::try_from(ceil).map(Bytes).map_err(|_| overflow)
    }
}

/// `scale · x` in Q16 for a Q32 `x`, rounded up (`None` on overflow).
fn scaled_q16(x: u128, scale: Scale) -> Option<u128> {
    // x < 2^84, mantissa < 2^32: no overflow in range; checked outside it.
    let prod = x.checked_mul(u128::from(scale.mantissa))?;
    // scale·x in Q16 = prod · 2^(exponent − 32 + 16), rounded up.
    let shift = i32::from(scale.exponent) - (FRAC - SIZE_FRAC) as i32;
    shl_or_ceil_shr(prod, shift)
}

/// `v · 2^shift`: a left shift (`None` on overflow) or a right shift
/// rounded up (so a size is never underestimated).
fn shl_or_ceil_shr(v: u128, shift: i32) -> Option<u128> {
    let s = shift.unsigned_abs();
    if shift >= 0 {
        if v != 0 && (s >= 128 || v.leading_zeros() < s) {
            return None;
        }
        Some(v.checked_shl(s).unwrap_or(0))
    } else {
        let whole = v.checked_shr(s).unwrap_or(0);
        let rest = match 1u128.checked_shl(s) {
            Some(one) => v & one.wrapping_sub(1),
            None => v,
        };
        Some(whole.saturating_add(u128::from(rest != 0)))
    }
}

/// The quality model `Q = m − k/(G^e·P²)` in fixed point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct QualityModel {
    /// Scale of the decaying term.
    pub k: Scale,
    /// Offset added to g.
    pub a: Offset,
    /// Offset added to p.
    pub b: Offset,
    /// Asymptote, signed Q31 (`raw / 2^31`).
    pub m_q31: i64,
    /// Power of `G`.
    pub family: Family,
}

impl QualityModel {
    /// Quantises fitted parameters; errors outside the documented range.
    pub fn from_params(params: &Params) -> Result<QualityModel, ProfileError> {
        let c = Curve::Quality;
        let k = Scale::from_f64(params.k, c, Field::K, MAX_QUALITY_K)?;
        let (a, b) = offsets(params, c)?;
        // The per-quad term is the size model's only.
        check_range(params.c, c, Field::C, 0.0, 0.0)?;
        check_range(params.m, c, Field::M, -MAX_QUALITY_M, MAX_QUALITY_M)?;
        // |m| ≤ 2: |m·2^31| ≤ 2^32, exact in i64.
        let m_q31 = libm::round(params.m * (1u64 << 31) as f64) as i64;
        Ok(QualityModel {
            k,
            a,
            b,
            m_q31,
            family: params.family,
        })
    }

    /// The parameters back as `f64` (after quantisation).
    pub fn params(&self) -> Params {
        Params {
            k: self.k.to_f64(),
            a: self.a.to_f64(),
            b: self.b.to_f64(),
            c: 0.0,
            m: self.m_q31 as f64 / (1u64 << 31) as f64,
            family: self.family,
        }
    }

    /// Predicted SSIM at (g, p), clamped to `[0, 1]`.
    pub fn quality(&self, g: u32, p: u32) -> Result<QualityQ, ProfileError> {
        let (gb, pb) = bases_q32(g, p, self.a, self.b)?;
        let x = volume_q32(
            gb,
            pb,
            self.family,
            Round::Down,
            ProfileError::BaseOutOfRange { g, p },
        )?;
        let term = self.term_q31(x);
        // term ≤ 2^40 and |m| ≤ 2^63 / 2: the difference cannot overflow
        // for models built by `from_params`; saturate for any other.
        let q = self.m_q31.saturating_sub(term as i64);
        let raw = q.clamp(0, i64::from(QualityQ::ONE.raw()));
        // raw in [0, 2^31]: from_raw accepts it.
        Ok(QualityQ::from_raw(raw as u32).unwrap_or(QualityQ::ZERO))
    }

    /// `k / x` in Q31 (x in Q32, x ≥ 2^27), capped at [`TERM_CAP_Q31`].
    fn term_q31(&self, x: u128) -> u128 {
        if self.k.mantissa == 0 {
            return 0;
        }
        // t = mantissa·2^95 / x = mantissa·2^63 / X  (mantissa·2^95 < 2^127).
        let Some(t) = (u128::from(self.k.mantissa) << 95).checked_div(x) else {
            return TERM_CAP_Q31;
        };
        // k/X in Q31 = t · 2^(exponent + 31 − 63) = t · 2^(exponent − 32).
        let shift = i32::from(self.k.exponent) - 32;
        let term = if shift >= 0 {
            let s = shift.unsigned_abs();
            if t != 0 && (s >= 128 || t.leading_zeros() < s) {
                TERM_CAP_Q31
            } else {
                t.checked_shl(s).unwrap_or(0)
            }
        } else {
            let s = shift.unsigned_abs();
            match 1u128.checked_shl(s.saturating_sub(1)) {
                // Round to nearest: t < 2^100, so adding half cannot overflow.
                Some(half) if s < 128 => t.saturating_add(half) >> s,
                _ => 0,
            }
        };
        term.min(TERM_CAP_Q31)
    }
}

/// An object's two fitted models in fixed point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Profile {
    /// Size model.
    pub size: SizeModel,
    /// Quality model.
    pub quality: QualityModel,
}

impl Profile {
    /// Quantises both models' fitted parameters.
    pub fn from_params(size: &Params, quality: &Params) -> Result<Profile, ProfileError> {
        Ok(Profile {
            size: SizeModel::from_params(size)?,
            quality: QualityModel::from_params(quality)?,
        })
    }

    /// The solver's configuration at (g, p).
    pub fn config(&self, g: u32, p: u32) -> Result<Config, ProfileError> {
        Ok(Config {
            size: self.size.size(g, p)?,
            quality: self.quality.quality(g, p)?,
        })
    }

    /// Evaluates every configuration of `space` into `out` (in the order of
    /// [`ConfigSpace::get`]) and returns the filled prefix.
    pub fn fill_table<'o>(
        &self,
        space: &ConfigSpace<'_>,
        out: &'o mut [Config],
    ) -> Result<&'o [Config], ProfileError> {
        let needed = space.len();
        let len = out.len();
        let table = out
            .get_mut(..needed)
            .ok_or(ProfileError::TableTooSmall { needed, len })?;
        for (slot, (g, p)) in table.iter_mut().zip(space.iter()) {
            *slot = self.config(g, p)?;
        }
        Ok(table)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profiler::MIN_BASE;

    fn size_params() -> Params {
        Params {
            k: 0.17,
            a: 2.5,
            b: -0.25,
            c: 0.0,
            m: 2.0e6,
            family: Family::Volume,
        }
    }

    fn quality_params() -> Params {
        Params {
            k: 3.2e6,
            a: 32.0,
            b: 4.0,
            c: 0.0,
            m: 0.953,
            family: Family::Volume,
        }
    }

    #[test]
    fn matches_reference_on_a_typical_profile() {
        let prof = Profile::from_params(&size_params(), &quality_params()).unwrap();
        for g in [16, 32, 64, 128, 256, 512, 1024] {
            for p in [1, 3, 5, 9, 17, 33, 64] {
                let (gf, pf) = (g as f64, p as f64);
                let s = prof.size.size(g, p).unwrap().0 as f64;
                let s_ref = libm::ceil(size_params().size_f64(gf, pf));
                assert!(
                    (s - s_ref).abs() <= 1.0f64.max(1e-9 * s_ref),
                    "{g} {p}: {s} vs {s_ref}"
                );
                let q = prof.quality.quality(g, p).unwrap().to_f64();
                let q_ref = quality_params().quality_f64(gf, pf).clamp(0.0, 1.0);
                assert!((q - q_ref).abs() < 1e-8, "{g} {p}: {q} vs {q_ref}");
            }
        }
    }

    #[test]
    fn exact_small_values() {
        let s = Params {
            k: 0.5,
            a: 0.0,
            b: 0.0,
            c: 0.0,
            m: 1000.0,
            family: Family::Volume,
        };
        let q = Params {
            k: 100.0,
            m: 0.95,
            ..s
        };
        let prof = Profile::from_params(&s, &q).unwrap();
        // S(2,1) = 0.5·8 + 1000; Q(2,1) = 0.95 − 12.5 → 0.
        assert_eq!(prof.config(2, 1).unwrap().size, Bytes(1004));
        assert_eq!(prof.config(2, 1).unwrap().quality, QualityQ::ZERO);
        // S(3,1) = 13.5 + 1000 rounds up to 1014.
        assert_eq!(prof.size.size(3, 1).unwrap(), Bytes(1014));
        let q43 = prof.quality.quality(4, 3).unwrap().to_f64();
        assert!((q43 - (0.95 - 100.0 / 576.0)).abs() < 1e-9);
        // Asymptote above 1 clamps to 1.
        let high = QualityModel::from_params(&Params {
            m: 1.5,
            k: 1.0,
            ..q
        })
        .unwrap();
        assert_eq!(high.quality(100, 10).unwrap(), QualityQ::ONE);
        // Flat models.
        let flat = Profile::from_params(&Params { k: 0.0, ..s }, &Params { k: 0.0, ..q }).unwrap();
        assert_eq!(flat.size.size(1024, 64).unwrap(), Bytes(1000));
        assert_eq!(
            flat.quality.quality(1, 1).unwrap().to_f64(),
            libm::round(0.95 * 2147483648.0) / 2147483648.0
        );
    }

    #[test]
    fn surface_family_uses_g_squared() {
        let s = Params {
            k: 2.0,
            a: 0.0,
            b: 0.0,
            c: 0.0,
            m: 0.0,
            family: Family::Surface,
        };
        let m = SizeModel::from_params(&s).unwrap();
        assert_eq!(m.size(10, 3).unwrap(), Bytes(2 * 100 * 9));
    }

    #[test]
    fn quads_family_adds_a_per_quad_term() {
        let s = Params {
            k: 2.0,
            a: 0.0,
            b: 0.0,
            c: 3.0,
            m: 10.0,
            family: Family::Quads,
        };
        let m = SizeModel::from_params(&s).unwrap();
        // 2·16^{3/2}·3² + 3·16² + 10 = 1152 + 768 + 10.
        assert_eq!(m.size(16, 3).unwrap(), Bytes(1930));
        // √2 is irrational: 2·2^{3/2}·1 = 5.657 → rounded up, never down.
        let exact = s.size_f64(2.0, 1.0);
        let got = m.size(2, 1).unwrap().0 as f64;
        assert!(got >= exact && got - exact < 1.0, "{got} vs {exact}");
        // The per-quad term is the size model's only.
        assert!(matches!(
            QualityModel::from_params(&Params { m: 0.9, ..s }),
            Err(ProfileError::ParamOutOfRange {
                curve: Curve::Quality,
                field: Field::C,
                ..
            })
        ));
        assert!(matches!(
            SizeModel::from_params(&Params { c: -1.0, ..s }),
            Err(ProfileError::ParamOutOfRange {
                curve: Curve::Size,
                field: Field::C,
                ..
            })
        ));
        assert!(matches!(
            SizeModel::from_params(&Params {
                c: f64::INFINITY,
                ..s
            }),
            Err(ProfileError::NotFinite {
                field: Field::C,
                ..
            })
        ));
        // A quality model of the quads family's power is valid (c = 0).
        let q = QualityModel::from_params(&Params {
            k: 8.0,
            c: 0.0,
            m: 1.0,
            ..s
        })
        .unwrap();
        // 1 − 8/(4^{3/2}·2²) = 0.75.
        assert!((q.quality(4, 2).unwrap().to_f64() - 0.75).abs() < 1e-9);
    }

    #[test]
    fn sizes_round_up_never_down() {
        // Square roots and products that are not exact in Q32.
        for family in Family::ALL {
            let s = Params {
                k: 0.3,
                a: 0.1,
                b: 0.7,
                c: 1.7,
                m: 0.1,
                family,
            };
            let model = SizeModel::from_params(&s).unwrap();
            let q = model.params();
            for g in [1, 3, 7, 100, 1023] {
                for p in [1, 2, 5, 63] {
                    let exact = q.size_f64(g as f64, p as f64);
                    let got = model.size(g, p).unwrap().0 as f64;
                    assert!(
                        got >= exact * (1.0 - 1e-15) && got <= exact + 1.0 + exact * 1e-9,
                        "{family:?} ({g}, {p}): {got} vs {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn extremes_of_the_documented_range_do_not_overflow() {
        let big = Params {
            k: MAX_SIZE_K,
            a: MAX_G_BASE - MAX_G as f64,
            b: MAX_P_BASE - MAX_P as f64,
            c: MAX_SIZE_C,
            m: MAX_SIZE_M,
            family: Family::Volume,
        };
        let s = SizeModel::from_params(&big)
            .unwrap()
            .size(MAX_G, MAX_P)
            .unwrap();
        assert_eq!(
            s.0,
            (1u64 << 10) * (1u64 << 36) * (1u64 << 16) + (1u64 << 24) * (1u64 << 24) + (1u64 << 40)
        );
        let quads = SizeModel::from_params(&Params {
            family: Family::Quads,
            ..big
        })
        .unwrap()
        .size(MAX_G, MAX_P)
        .unwrap();
        assert_eq!(
            quads.0,
            (1u64 << 10) * (1u64 << 18) * (1u64 << 16) + (1u64 << 24) * (1u64 << 24) + (1u64 << 40)
        );
        let tiny = Params {
            k: 1e-300,
            a: MIN_BASE - 1.0,
            b: MIN_BASE - 1.0,
            c: 0.0,
            m: 0.0,
            family: Family::Volume,
        };
        assert_eq!(
            SizeModel::from_params(&tiny).unwrap().size(1, 1).unwrap(),
            Bytes(1)
        );
        let steep = Params {
            k: MAX_QUALITY_K,
            m: MAX_QUALITY_M,
            ..tiny
        };
        let q = QualityModel::from_params(&steep).unwrap();
        assert_eq!(q.quality(1, 1).unwrap(), QualityQ::ZERO);
        let neg = QualityModel::from_params(&Params {
            m: -2.0,
            k: 0.0,
            ..tiny
        })
        .unwrap();
        assert_eq!(neg.quality(1, 1).unwrap(), QualityQ::ZERO);
    }

    #[test]
    fn out_of_range_inputs_are_errors() {
        let prof = Profile::from_params(&size_params(), &quality_params()).unwrap();
        assert_eq!(
            prof.config(0, 5),
            Err(ProfileError::GridOutOfRange { g: 0 })
        );
        assert_eq!(
            prof.config(1025, 5),
            Err(ProfileError::GridOutOfRange { g: 1025 })
        );
        assert_eq!(
            prof.config(16, 65),
            Err(ProfileError::PatchOutOfRange { p: 65 })
        );
        // g + a < 0.5.
        let neg = Params {
            a: -20.0,
            ..size_params()
        };
        let m = SizeModel::from_params(&neg).unwrap();
        assert_eq!(
            m.size(16, 5),
            Err(ProfileError::BaseOutOfRange { g: 16, p: 5 })
        );
        assert!(m.size(21, 5).is_ok());
        let err = SizeModel::from_params(&Params {
            k: f64::NAN,
            ..size_params()
        });
        assert!(matches!(
            err,
            Err(ProfileError::NotFinite {
                curve: Curve::Size,
                field: Field::K,
                ..
            })
        ));
        let err = SizeModel::from_params(&Params {
            m: -1.0,
            ..size_params()
        });
        assert!(matches!(
            err,
            Err(ProfileError::ParamOutOfRange {
                field: Field::M,
                ..
            })
        ));
        let err = QualityModel::from_params(&Params {
            k: -1.0,
            ..quality_params()
        });
        assert!(matches!(
            err,
            Err(ProfileError::ParamOutOfRange {
                curve: Curve::Quality,
                field: Field::K,
                ..
            })
        ));
        let err = QualityModel::from_params(&Params {
            b: 1e9,
            ..quality_params()
        });
        assert!(matches!(
            err,
            Err(ProfileError::ParamOutOfRange {
                field: Field::B,
                ..
            })
        ));
    }

    #[test]
    fn raw_models_outside_the_range_never_panic() {
        let wild = SizeModel {
            k: Scale::from_raw(u32::MAX, i16::MAX),
            a: Offset::from_raw(i64::MAX),
            b: Offset::from_raw(i64::MIN),
            c: Scale::from_raw(u32::MAX, i16::MAX),
            m_q16: u64::MAX,
            family: Family::Volume,
        };
        assert!(wild.size(1, 1).is_err());
        let huge = SizeModel {
            k: Scale::from_raw(u32::MAX, i16::MAX),
            a: Offset::from_raw(0),
            b: Offset::from_raw(0),
            c: Scale::ZERO,
            m_q16: 0,
            family: Family::Volume,
        };
        assert_eq!(
            huge.size(2, 2),
            Err(ProfileError::SizeOverflow { g: 2, p: 2 })
        );
        let tiny = SizeModel {
            k: Scale::from_raw(u32::MAX, i16::MIN),
            m_q16: u64::MAX,
            ..huge
        };
        // (2^64 − 1)/2^16 bytes plus a vanishing k·X, rounded up.
        assert_eq!(tiny.size(2, 2), Ok(Bytes(1 << 48)));
        for (mant, exp) in [
            (u32::MAX, i16::MAX),
            (u32::MAX, i16::MIN),
            (1, 0),
            (u32::MAX, 100),
        ] {
            for m_q31 in [i64::MAX, i64::MIN, 0] {
                let q = QualityModel {
                    k: Scale::from_raw(mant, exp),
                    a: Offset::from_raw(0),
                    b: Offset::from_raw(0),
                    m_q31,
                    family: Family::Surface,
                };
                let v = q.quality(1024, 64).unwrap();
                assert!(v <= QualityQ::ONE);
            }
        }
    }

    #[test]
    fn scale_round_trips() {
        for v in [1e-300, 1e-9, 0.17, 1.0, 3.2e6, 1e18, MAX_QUALITY_K] {
            let s = Scale::from_f64(v, Curve::Quality, Field::K, f64::MAX).unwrap();
            assert!((s.to_f64() / v - 1.0).abs() < 1e-9, "{v}");
            assert!(s.mantissa() >= 1 << 31);
        }
        // Rounds up into the next binade.
        let s = Scale::from_f64(1.0 - 1e-12, Curve::Size, Field::K, 2.0).unwrap();
        assert_eq!((s.mantissa(), s.exponent()), (1 << 31, -31));
        assert_eq!(
            Offset::from_f64(-0.25, Curve::Size, Field::A, -1.0, 1.0)
                .unwrap()
                .raw(),
            -(1 << 30)
        );
    }

    #[test]
    fn fills_a_table_in_space_order() {
        let prof = Profile::from_params(&size_params(), &quality_params()).unwrap();
        let gs = [16, 64, 256];
        let ps = [5, 17];
        let space = ConfigSpace::new(&gs, &ps).unwrap();
        let mut out = [Config {
            size: Bytes(0),
            quality: QualityQ::ZERO,
        }; 8];
        let table = prof.fill_table(&space, &mut out).unwrap();
        assert_eq!(table.len(), 6);
        for (i, c) in table.iter().enumerate() {
            let (g, p) = space.get(i).unwrap();
            assert_eq!(*c, prof.config(g, p).unwrap());
            assert_eq!(space.index_of(g, p), Some(i));
        }
        assert_eq!(space.get(6), None);
        let mut short = [Config {
            size: Bytes(0),
            quality: QualityQ::ZERO,
        }; 5];
        assert_eq!(
            prof.fill_table(&space, &mut short),
            Err(ProfileError::TableTooSmall { needed: 6, len: 5 })
        );
        assert!(ConfigSpace::new(&[], &ps).is_err());
        assert!(ConfigSpace::new(&[1; 17], &[1; 16]).is_err());
        assert_eq!(ConfigSpace::new(&[1; 16], &[1; 16]).unwrap().len(), 256);
    }
}
