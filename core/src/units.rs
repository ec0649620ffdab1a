//! Quantities with their unit in the type, so a reader never guesses.
//!
//! - [`Bytes`]: a data size in bytes (`u64`). **1 MB = 10^6 bytes** everywhere
//!   in nerflex (the paper's 240 MB budget is 240 000 000 bytes); MiB are
//!   never used implicitly.
//! - [`QualityQ`]: one SSIM value in `[0, 1]` as unsigned fixed point
//!   **Q1.31** in a `u32` (`raw / 2^31`; 1.0 is `2^31` exactly, the step is
//!   2^-31 ≈ 4.7e-10, far below any SSIM difference that matters).
//! - [`QualitySum`]: a sum of [`QualityQ`] values, same scale in a `u64`
//!   (Q33.31), so summing up to 2^32 objects is exact integer arithmetic.
//!
//! Conversions from `f64` validate (returning [`UnitError`]) or saturate;
//! none panics.

use core::fmt;

/// Number of bytes in one MB (decimal megabyte, 10^6 bytes).
pub const BYTES_PER_MB: u64 = 1_000_000;

/// Why an `f64` could not be turned into a unit type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnitError {
    /// NaN or ±infinity.
    NotFinite(f64),
    /// A negative value where only non-negative ones make sense.
    Negative(f64),
    /// A value above the largest representable one.
    TooLarge(f64),
    /// A quality outside `[0, 1]`.
    OutOfUnitRange(f64),
}

impl fmt::Display for UnitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitError::NotFinite(v) => write!(f, "not a finite number ({v})"),
            UnitError::Negative(v) => write!(f, "negative value {v}"),
            UnitError::TooLarge(v) => write!(f, "value {v} is too large"),
            UnitError::OutOfUnitRange(v) => write!(f, "value {v} is outside [0, 1]"),
        }
    }
}

impl core::error::Error for UnitError {}

/// A data size in bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Bytes(pub u64);

/// 2^64 as f64: the first value that no longer fits a `u64`.
const TWO_POW_64: f64 = 18_446_744_073_709_551_616.0;

impl Bytes {
    /// Zero bytes.
    pub const ZERO: Bytes = Bytes(0);
    /// The largest size.
    pub const MAX: Bytes = Bytes(u64::MAX);

    /// `mb` MB (10^6 bytes each), saturating at [`Bytes::MAX`].
    pub const fn from_mb_u64(mb: u64) -> Bytes {
        Bytes(mb.saturating_mul(BYTES_PER_MB))
    }

    /// `mb` MB (10^6 bytes each), rounded to the nearest byte.
    ///
    /// Errors on NaN/infinity, negative values and values of 2^64 bytes or more.
    pub fn from_mb(mb: f64) -> Result<Bytes, UnitError> {
        if !mb.is_finite() {
            return Err(UnitError::NotFinite(mb));
        }
        Bytes::from_f64_round(mb * BYTES_PER_MB as f64).map_err(|e| match e {
            UnitError::TooLarge(_) => UnitError::TooLarge(mb),
            UnitError::Negative(_) => UnitError::Negative(mb),
            other => other,
        })
    }

    /// A byte count given as `f64`, rounded to the nearest byte.
    pub fn from_f64_round(bytes: f64) -> Result<Bytes, UnitError> {
        Bytes::checked_from_f64(libm::round(bytes), bytes)
    }

    /// A byte count given as `f64`, rounded *up* to whole bytes (sizes that
    /// come from a model must not be underestimated).
    pub fn from_f64_ceil(bytes: f64) -> Result<Bytes, UnitError> {
        Bytes::checked_from_f64(libm::ceil(bytes), bytes)
    }

    fn checked_from_f64(whole: f64, original: f64) -> Result<Bytes, UnitError> {
        if !whole.is_finite() {
            return Err(UnitError::NotFinite(original));
        }
        if whole < 0.0 {
            // -0.4 rounds to -0.0, which is fine; anything below is negative.
            return Err(UnitError::Negative(original));
        }
        if whole >= TWO_POW_64 {
            return Err(UnitError::TooLarge(original));
        }
        // In range [0, 2^64): the cast is exact for whole numbers.
        Ok(Bytes(whole as u64))
    }

    /// The size in MB (10^6 bytes) as `f64`, for display.
    pub fn as_mb(self) -> f64 {
        self.0 as f64 / BYTES_PER_MB as f64
    }

    /// Sum, or `None` on overflow.
    pub const fn checked_add(self, other: Bytes) -> Option<Bytes> {
        match self.0.checked_add(other.0) {
            Some(v) => Some(Bytes(v)),
            None => None,
        }
    }

    /// Sum, saturating at [`Bytes::MAX`].
    pub const fn saturating_add(self, other: Bytes) -> Bytes {
        Bytes(self.0.saturating_add(other.0))
    }

    /// Difference, or `None` if `other` is larger.
    pub const fn checked_sub(self, other: Bytes) -> Option<Bytes> {
        match self.0.checked_sub(other.0) {
            Some(v) => Some(Bytes(v)),
            None => None,
        }
    }

    /// How many `unit`s this size occupies, rounded **up** (a size must never
    /// be underestimated); `None` if `unit` is zero.
    pub const fn units_ceil(self, unit: Bytes) -> Option<u64> {
        if unit.0 == 0 {
            return None;
        }
        Some(self.0.div_ceil(unit.0))
    }

    /// How many whole `unit`s fit in this size, rounded **down** (a budget
    /// must never be overestimated); `None` if `unit` is zero.
    pub const fn units_floor(self, unit: Bytes) -> Option<u64> {
        if unit.0 == 0 {
            return None;
        }
        Some(self.0 / unit.0)
    }
}

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} bytes", self.0)
    }
}

/// One SSIM value in `[0, 1]`, unsigned fixed point Q1.31 (`raw / 2^31`).
///
/// The raw value is at most [`QualityQ::ONE`]`.0` = 2^31 for every value
/// built through the constructors; [`QualityQ::from_raw`] rejects larger ones.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct QualityQ(u32);

impl QualityQ {
    /// Number of fractional bits.
    pub const FRAC_BITS: u32 = 31;
    /// Quality 0.
    pub const ZERO: QualityQ = QualityQ(0);
    /// Quality 1 (a perfect SSIM).
    pub const ONE: QualityQ = QualityQ(1 << 31);

    /// From the raw Q1.31 value; `None` above 2^31 (quality above 1).
    pub const fn from_raw(raw: u32) -> Option<QualityQ> {
        if raw <= QualityQ::ONE.0 {
            Some(QualityQ(raw))
        } else {
            None
        }
    }

    /// The raw Q1.31 value.
    pub const fn raw(self) -> u32 {
        self.0
    }

    /// From an SSIM value, rounded to the nearest step. Errors on NaN,
    /// infinity and values outside `[0, 1]`.
    pub fn from_f64(q: f64) -> Result<QualityQ, UnitError> {
        if !q.is_finite() {
            return Err(UnitError::NotFinite(q));
        }
        if !(0.0..=1.0).contains(&q) {
            return Err(UnitError::OutOfUnitRange(q));
        }
        Ok(QualityQ::saturating_from_f64(q))
    }

    /// From an SSIM value, clamped to `[0, 1]` (NaN becomes 0). For fitted
    /// curves that may overshoot 1 or dip below 0 slightly.
    pub fn saturating_from_f64(q: f64) -> QualityQ {
        if q.is_nan() || q <= 0.0 {
            return QualityQ::ZERO;
        }
        if q >= 1.0 {
            return QualityQ::ONE;
        }
        // q in (0, 1): the product is in (0, 2^31) and rounds to <= 2^31.
        let raw = libm::round(q * (1u64 << QualityQ::FRAC_BITS) as f64) as u32;
        QualityQ(raw.min(QualityQ::ONE.0))
    }

    /// The SSIM value as `f64` (exact: 31 bits fit the 53-bit mantissa).
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / (1u64 << QualityQ::FRAC_BITS) as f64
    }
}

impl fmt::Display for QualityQ {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6}", self.to_f64())
    }
}

/// A sum of [`QualityQ`] values, Q33.31 in a `u64` (same scale as
/// [`QualityQ`]): exact for up to 2^32 summands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct QualitySum(pub u64);

impl QualitySum {
    /// The empty sum.
    pub const ZERO: QualitySum = QualitySum(0);

    /// Adds one quality, `None` on overflow (needs more than 2^32 summands).
    pub const fn checked_add(self, q: QualityQ) -> Option<QualitySum> {
        match self.0.checked_add(q.0 as u64) {
            Some(v) => Some(QualitySum(v)),
            None => None,
        }
    }

    /// Adds one quality, saturating.
    pub const fn saturating_add(self, q: QualityQ) -> QualitySum {
        QualitySum(self.0.saturating_add(q.0 as u64))
    }

    /// The sum as `f64` (rounded to 53 bits when it exceeds them).
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / (1u64 << QualityQ::FRAC_BITS) as f64
    }
}

impl fmt::Display for QualitySum {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6}", self.to_f64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mb_is_decimal() {
        assert_eq!(Bytes::from_mb(240.0), Ok(Bytes(240_000_000)));
        assert_eq!(Bytes::from_mb_u64(150), Bytes(150_000_000));
        assert_eq!(Bytes::from_mb(0.1), Ok(Bytes(100_000)));
        assert_eq!(Bytes(104_857_600).as_mb(), 104.8576);
    }

    #[test]
    fn bytes_from_f64_validates() {
        assert!(matches!(Bytes::from_mb(-1.0), Err(UnitError::Negative(_))));
        assert!(matches!(
            Bytes::from_mb(f64::NAN),
            Err(UnitError::NotFinite(_))
        ));
        assert!(matches!(
            Bytes::from_mb(f64::INFINITY),
            Err(UnitError::NotFinite(_))
        ));
        assert!(matches!(Bytes::from_mb(1e20), Err(UnitError::TooLarge(_))));
        assert_eq!(Bytes::from_f64_ceil(1.2), Ok(Bytes(2)));
        assert_eq!(Bytes::from_f64_ceil(-0.0), Ok(Bytes(0)));
        assert_eq!(Bytes::from_f64_round(-0.4), Ok(Bytes(0)));
        assert!(Bytes::from_f64_ceil(TWO_POW_64).is_err());
        assert_eq!(
            Bytes::from_f64_round(18_446_744_073_709_549_568.0),
            Ok(Bytes(18_446_744_073_709_549_568))
        );
    }

    #[test]
    fn unit_rounding() {
        let unit = Bytes(100_000);
        assert_eq!(Bytes(100_001).units_ceil(unit), Some(2));
        assert_eq!(Bytes(100_000).units_ceil(unit), Some(1));
        assert_eq!(Bytes(0).units_ceil(unit), Some(0));
        assert_eq!(Bytes(199_999).units_floor(unit), Some(1));
        assert_eq!(Bytes(5).units_ceil(Bytes(0)), None);
        assert_eq!(Bytes(u64::MAX).units_ceil(Bytes(1)), Some(u64::MAX));
    }

    #[test]
    fn quality_fixed_point() {
        assert_eq!(QualityQ::from_f64(1.0), Ok(QualityQ::ONE));
        assert_eq!(QualityQ::from_f64(0.0), Ok(QualityQ::ZERO));
        assert_eq!(QualityQ::from_f64(0.5).map(QualityQ::raw), Ok(1 << 30));
        assert!(QualityQ::from_f64(1.0000001).is_err());
        assert!(QualityQ::from_f64(-0.1).is_err());
        assert!(QualityQ::from_f64(f64::NAN).is_err());
        assert_eq!(QualityQ::saturating_from_f64(1.5), QualityQ::ONE);
        assert_eq!(QualityQ::saturating_from_f64(f64::NAN), QualityQ::ZERO);
        assert_eq!(QualityQ::from_raw((1 << 31) + 1), None);
        let q = QualityQ::from_f64(0.951).unwrap();
        assert!((q.to_f64() - 0.951).abs() < 1e-9);
        let s = QualitySum::ZERO
            .checked_add(q)
            .unwrap()
            .checked_add(q)
            .unwrap();
        assert_eq!(s.0, 2 * q.raw() as u64);
    }
}
