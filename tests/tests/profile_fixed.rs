//! `nerflex_core::profiler`: the fixed-point evaluation matches the `f64`
//! reference within `max(0.1 %, 1 byte)` on size and 1e-4 on SSIM, with no
//! error (overflow) anywhere in the documented range of g, p and parameters
//! (every family, the quads family's per-quad term `c` included), and a
//! size is never below the `f64` value of its quantised parameters (sizes
//! round up).

use nerflex_core::mck::Config;
use nerflex_core::profiler::{
    ConfigSpace, Family, Params, Profile, QualityModel, SizeModel, MAX_G, MAX_G_BASE, MAX_P,
    MAX_P_BASE, MAX_QUALITY_K, MAX_QUALITY_M, MAX_SIZE_C, MAX_SIZE_K, MAX_SIZE_M, MIN_BASE,
};
use nerflex_core::units::{Bytes, QualityQ};
use proptest::prelude::*;

/// `2^u` for `u` uniform in `[lo, hi]`: covers every order of magnitude.
fn log2_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo..=hi).prop_map(f64::exp2)
}

/// A value in `[0, max]`, log-uniform over `[2^lo, max]`, sometimes exactly 0 or max.
fn magnitude(lo: f64, max: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => Just(0.0),
        1 => Just(max),
        8 => log2_uniform(lo, max.log2()),
    ]
}

fn family() -> impl Strategy<Value = Family> {
    prop_oneof![
        Just(Family::Volume),
        Just(Family::Surface),
        Just(Family::Quads)
    ]
}

/// A base `G` or `P` in `[0.5, max]`, log-uniform, sometimes at the ends.
fn base(max: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => Just(MIN_BASE),
        1 => Just(max),
        8 => log2_uniform(MIN_BASE.log2(), max.log2()),
    ]
}

/// (g, p, size params, quality params) with `g + a` and `p + b` in range.
fn case() -> impl Strategy<Value = (u32, u32, Params, Params)> {
    (
        1..=MAX_G,
        1..=MAX_P,
        (
            base(MAX_G_BASE),
            base(MAX_P_BASE),
            base(MAX_G_BASE),
            base(MAX_P_BASE),
        ),
        (
            magnitude(-40.0, MAX_SIZE_K),
            magnitude(-20.0, MAX_SIZE_M),
            family(),
            magnitude(-20.0, MAX_SIZE_C),
        ),
        (
            magnitude(-40.0, MAX_QUALITY_K),
            -MAX_QUALITY_M..=MAX_QUALITY_M,
            family(),
        ),
    )
        .prop_map(|(g, p, (gs, ps, gq, pq), (ks, ms, fs, cs), (kq, mq, fq))| {
            let size = Params {
                k: ks,
                a: gs - g as f64,
                b: ps - p as f64,
                c: cs,
                m: ms,
                family: fs,
            };
            let quality = Params {
                k: kq,
                a: gq - g as f64,
                b: pq - p as f64,
                c: 0.0,
                m: mq,
                family: fq,
            };
            (g, p, size, quality)
        })
}

fn size_ok(got: Bytes, params: &Params, g: u32, p: u32) -> Result<(), TestCaseError> {
    let want = params.size_f64(g as f64, p as f64).ceil();
    let tol = (1e-3 * want).max(1.0);
    prop_assert!(
        (got.0 as f64 - want).abs() <= tol,
        "size at (g {g}, p {p}) {params:?}: fixed {} vs f64 {want}",
        got.0
    );
    // Never below the exact value of the parameters it evaluates (the
    // quantised ones): every rounding of the size path goes up. The slack
    // covers f64's own rounding (a few ulps).
    let quantised = SizeModel::from_params(params).unwrap().params();
    let floor = quantised.size_f64(g as f64, p as f64);
    prop_assert!(
        got.0 as f64 >= floor * (1.0 - 1e-12),
        "size at (g {g}, p {p}) {quantised:?}: fixed {} below f64 {floor}",
        got.0
    );
    Ok(())
}

fn quality_ok(got: QualityQ, params: &Params, g: u32, p: u32) -> Result<(), TestCaseError> {
    let want = params.quality_f64(g as f64, p as f64).clamp(0.0, 1.0);
    prop_assert!(
        (got.to_f64() - want).abs() <= 1e-4,
        "quality at (g {g}, p {p}) {params:?}: fixed {} vs f64 {want}",
        got.to_f64()
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(20_000))]

    #[test]
    fn fixed_point_matches_f64((g, p, size, quality) in case()) {
        let profile = Profile::from_params(&size, &quality);
        prop_assert!(profile.is_ok(), "{size:?} {quality:?}: {profile:?}");
        let profile = profile.unwrap();
        let config = profile.config(g, p);
        prop_assert!(config.is_ok(), "(g {g}, p {p}) {size:?} {quality:?}: {config:?}");
        let config = config.unwrap();
        size_ok(config.size, &size, g, p)?;
        quality_ok(config.quality, &quality, g, p)?;
    }
}

/// Lists of distinct values in `1..=max`, each with an offset keeping the
/// base in range.
fn space_and_offsets() -> impl Strategy<Value = (Vec<u32>, Vec<u32>, f64, f64)> {
    (
        proptest::collection::btree_set(1..=MAX_G, 1..=16),
        proptest::collection::btree_set(1..=MAX_P, 1..=16),
        0.0f64..=1.0,
        0.0f64..=1.0,
    )
        .prop_map(|(gs, ps, ta, tb)| {
            let gs: Vec<u32> = gs.into_iter().collect();
            let ps: Vec<u32> = ps.into_iter().collect();
            // a in [0.5 − g_min, MAX_G_BASE − g_max]: every G in range.
            let (gmin, gmax) = (gs[0] as f64, *gs.last().unwrap() as f64);
            let (pmin, pmax) = (ps[0] as f64, *ps.last().unwrap() as f64);
            let a = (MIN_BASE - gmin) + ta * (MAX_G_BASE - gmax - (MIN_BASE - gmin));
            let b = (MIN_BASE - pmin) + tb * (MAX_P_BASE - pmax - (MIN_BASE - pmin));
            (gs, ps, a, b)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn full_tables_never_fail_in_range(
        (gs, ps, a, b) in space_and_offsets(),
        (ks, ms, kq, mq, cs) in (magnitude(-40.0, MAX_SIZE_K), magnitude(-20.0, MAX_SIZE_M),
                             magnitude(-40.0, MAX_QUALITY_K), -MAX_QUALITY_M..=MAX_QUALITY_M,
                             magnitude(-20.0, MAX_SIZE_C)),
        (fs, fq) in (family(), family()),
    ) {
        let size = Params { k: ks, a, b, c: cs, m: ms, family: fs };
        let quality = Params { k: kq, a, b, c: 0.0, m: mq, family: fq };
        let profile = Profile::from_params(&size, &quality).unwrap();
        let space = ConfigSpace::new(&gs, &ps).unwrap();
        let mut out = [Config { size: Bytes(0), quality: QualityQ::ZERO }; 256];
        let table = profile.fill_table(&space, &mut out);
        prop_assert!(table.is_ok(), "{table:?}");
        let table = table.unwrap();
        prop_assert_eq!(table.len(), gs.len() * ps.len());
        for (i, c) in table.iter().enumerate() {
            let (g, p) = space.get(i).unwrap();
            size_ok(c.size, &size, g, p)?;
            quality_ok(c.quality, &quality, g, p)?;
        }
    }
}

#[test]
fn quantised_parameters_round_trip() {
    let size = Params {
        k: 0.173,
        a: -7.25,
        b: 1.5,
        c: 0.0,
        m: 2_000_000.3,
        family: Family::Surface,
    };
    let back = SizeModel::from_params(&size).unwrap().params();
    assert!((back.k / size.k - 1.0).abs() < 1e-9);
    let quads = Params {
        c: 1234.567,
        family: Family::Quads,
        ..size
    };
    let back_quads = SizeModel::from_params(&quads).unwrap().params();
    assert!((back_quads.c / quads.c - 1.0).abs() < 1e-9);
    assert_eq!(back_quads.family, Family::Quads);
    assert!((back.a - size.a).abs() < 1e-9 && (back.b - size.b).abs() < 1e-9);
    assert!((back.m - size.m).abs() < 1e-4);
    assert_eq!(back.family, Family::Surface);
    let quality = Params {
        k: 3.2e6,
        a: 32.0,
        b: 4.0,
        c: 0.0,
        m: 0.953,
        family: Family::Volume,
    };
    let back = QualityModel::from_params(&quality).unwrap().params();
    assert!((back.m - 0.953).abs() < 1e-9 && (back.k / 3.2e6 - 1.0).abs() < 1e-9);
}
