use super::batch::{self, BatchInput, LANES};
use super::*;
use crate::shader::{FixedMlp, MlpWeights, ShaderError};
use proptest::prelude::*;

/// A deterministic pseudo-random weight set with weights in ±`scale`.
fn weights(seed: u64, scale: f32) -> MlpWeights {
    let mut s = seed;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
    };
    let mut w = MlpWeights::ZERO;
    w.w0.iter_mut().flatten().for_each(|v| *v = next());
    w.b0.iter_mut().for_each(|v| *v = next() * 0.3);
    w.w1.iter_mut().flatten().for_each(|v| *v = next());
    w.b1.iter_mut().for_each(|v| *v = next() * 0.3);
    w.w2.iter_mut().flatten().for_each(|v| *v = next());
    w.b2.iter_mut().for_each(|v| *v = next() * 0.3);
    w
}

#[test]
fn dual_mac_is_two_signed_16_bit_products_mod_2_32() {
    let cases = [
        (0i32, 0x8000_8000u32, 0x8000_8000u32),
        (i32::MAX, 0x7FFF_7FFF, 0x7FFF_7FFF),
        (-5, 0x1234_FFFF, 0xFFFF_0003),
    ];
    for (a, x, w) in cases {
        let want = (i64::from(a)
            + i64::from(x as u16 as i16) * i64::from(w as u16 as i16)
            + i64::from((x >> 16) as i16) * i64::from((w >> 16) as i16)) as i32;
        assert_eq!(dual_mac_portable(a, x, w), want);
        assert_eq!(dual_mac(a, x, w), want);
    }
}

#[test]
fn random_weights_pass_the_check_and_track_the_exact_shader() {
    for seed in [3u64, 7, 11] {
        let w = weights(seed, 1.5);
        let (m, h) = NarrowMlp::choose(&w, || check_samples(512, 8))
            .unwrap()
            .expect("16-bit tables pass");
        assert_eq!(m.weight_max, i16::MAX, "8-bit weights are too coarse here");
        assert!(h.passes(), "{h:?}");
        // Against the exact fixed-point shader: within a step nearly always.
        let exact = FixedMlp::from_weights(&w).unwrap();
        let mut far = 0;
        for (f0, f1, d) in check_samples(256, 4) {
            let (a, b) = (m.shade(f0, f1, d), exact.shade(f0, f1, d));
            let e = a.iter().zip(b).map(|(x, y)| x.abs_diff(y)).max().unwrap();
            assert!(e <= 2, "{a:?} vs {b:?}");
            far += usize::from(e > 1);
        }
        assert!(far <= 1, "{far} samples 2 steps from the exact shader");
    }
}

#[test]
fn eight_bit_weights_are_built_and_judged_by_the_same_check() {
    let w = weights(5, 1.0);
    let m = NarrowMlp::from_weights(&w, WeightBits::Eight).unwrap();
    let max = |v: u32| {
        (v as u16 as i16)
            .unsigned_abs()
            .max(((v >> 16) as u16 as i16).unsigned_abs())
    };
    assert!(m.l1.w.iter().flatten().flatten().all(|&v| max(v) <= 127));
    let h = m.error_histogram(&w, check_samples(256, 4));
    assert_eq!(h.total(), 1024);
    // q7 weights: coarse, and the check says so.
    assert!(!h.passes(), "{h:?}");
}

#[test]
fn bad_weights_are_rejected_and_zero_weights_give_grey() {
    let mut w = weights(1, 1.0);
    w.w1[2][5] = f32::NAN;
    assert_eq!(
        NarrowMlp::from_weights(&w, WeightBits::Sixteen),
        Err(ShaderError::NonFinite {
            layer: 1,
            param: crate::shader::Param::Weight { row: 2, col: 5 }
        })
    );
    let m = NarrowMlp::from_weights(&MlpWeights::ZERO, WeightBits::Sixteen).unwrap();
    assert_eq!(
        m.shade([9, 8, 7, 6], [5, 4, 3, 2], ViewDir::default()),
        [128; 3]
    );
    // Huge output weights: logits saturate, nothing panics.
    let mut w = weights(3, 1.0);
    w.w2.iter_mut().flatten().for_each(|v| *v *= 1.0e6);
    let m = NarrowMlp::from_weights(&w, WeightBits::Sixteen).unwrap();
    let _ = m.shade([255; 4], [255; 4], ViewDir::from_bits([i32::MIN; 3]));
    let mut s = std::string::String::new();
    m.write_rust(&mut s, "NARROW").unwrap();
    assert!(s.starts_with("pub const NARROW: NarrowMlp = NarrowMlp {"));
    assert!(s.contains("logit_lshift: "));
}

/// The accumulator bound holds: the extreme inputs reproduce the `i64` sum.
#[test]
fn accumulators_never_wrap_for_any_input() {
    let w = weights(13, 2.0);
    let m = NarrowMlp::from_weights(&w, WeightBits::Sixteen).unwrap();
    let wide = |l: &[u32], b: i32, x: &[u32]| -> i64 {
        let mut s = i64::from(b);
        for (&xp, &wp) in x.iter().zip(l) {
            s += i64::from(xp as u16 as i16) * i64::from(wp as u16 as i16);
            s += i64::from((xp >> 16) as i16) * i64::from((wp >> 16) as i16);
        }
        s
    };
    for f in [[0u8; 4], [255; 4], [255, 0, 255, 0], [0, 255, 0, 255]] {
        for d in [[i32::MIN; 3], [i32::MAX; 3], [i32::MIN, i32::MAX, i32::MIN]] {
            let x = input_pairs(f, f, ViewDir::from_bits(d));
            for n in 0..HIDDEN_GROUPS {
                let acc = m.l0.group(n, &x);
                for (g, &a) in acc.iter().enumerate() {
                    let row: Vec<u32> = m.l0.w[n].iter().map(|p| p[g]).collect();
                    assert_eq!(i64::from(a), wide(&row, m.l0.bias[n][g], &x));
                }
            }
        }
    }
}

fn random_tables(seed: u64) -> NarrowMlp {
    let mut s = seed;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 32) as u32
    };
    let mut m = NarrowMlp::from_weights(&MlpWeights::ZERO, WeightBits::Sixteen).unwrap();
    m.l0.w
        .iter_mut()
        .flatten()
        .flatten()
        .for_each(|v| *v = next());
    m.l1.w
        .iter_mut()
        .flatten()
        .flatten()
        .for_each(|v| *v = next());
    m.l2.w
        .iter_mut()
        .flatten()
        .flatten()
        .for_each(|v| *v = next());
    m.l0.bias
        .iter_mut()
        .flatten()
        .for_each(|v| *v = next() as i32);
    m.l1.bias
        .iter_mut()
        .flatten()
        .for_each(|v| *v = next() as i32);
    m.l2.bias
        .iter_mut()
        .flatten()
        .for_each(|v| *v = next() as i32);
    m.logit_lshift = if seed % 2 == 0 {
        (next() % 40) as u8
    } else {
        next() as u8
    };
    m
}

fn check_batches_equal_scalar(m: &NarrowMlp, px: &[([u8; 4], [u8; 4], [i32; 3]); LANES]) {
    let mut x: BatchInput = [[0; LANES]; INPUT_PAIRS];
    for (lane, &(f0, f1, d)) in px.iter().enumerate() {
        batch::set_lane(&mut x, lane, f0, f1, ViewDir::from_bits(d));
    }
    let want: Vec<[u8; 3]> = px
        .iter()
        .map(|&(f0, f1, d)| m.shade(f0, f1, ViewDir::from_bits(d)))
        .collect();
    assert_eq!(batch::shade_portable(m, &x).to_vec(), want);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 detected.
        #[allow(unsafe_code)]
        let got = unsafe { batch::avx2::shade(m, &x) };
        assert_eq!(got.to_vec(), want);
    }
}

proptest! {
    /// Bit-identity of the batch paths with the scalar shader, on real
    /// tables and on arbitrary ones (wrapping sums, any shifts).
    #[test]
    fn batches_equal_the_scalar_shader(
        seed in any::<u64>(),
        px in proptest::array::uniform8((any::<[u8; 4]>(), any::<[u8; 4]>(), any::<[i32; 3]>())),
        real in any::<bool>(),
    ) {
        let m = if real {
            NarrowMlp::from_weights(&weights(seed, 1.5), WeightBits::Sixteen).unwrap()
        } else {
            random_tables(seed)
        };
        check_batches_equal_scalar(&m, &px);
    }
}

#[test]
fn bucketed_sigmoid_equals_the_threshold_search_everywhere() {
    use crate::shader::sigmoid_u8;
    // Every z of the bucketed range, then the extremes.
    for z in -(1i32 << 27)..(1 << 27) {
        assert_eq!(sigmoid_bucketed(z), sigmoid_u8(z), "z = {z}");
    }
    for z in [
        i32::MIN,
        i32::MIN + 1,
        -(1 << 27) - 1,
        1 << 27,
        (1 << 27) + 1,
        i32::MAX,
    ] {
        assert_eq!(sigmoid_bucketed(z), sigmoid_u8(z), "z = {z}");
    }
}
