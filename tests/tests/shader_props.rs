//! Property tests of the fixed-point shader on random weights and inputs.

use nerflex_core::shader::{shade_f64, FixedMlp, MlpWeights, ViewDir};
use proptest::prelude::*;

fn fill(w: &mut MlpWeights, vals: &[f32]) {
    let mut it = vals.iter().copied().cycle();
    let mut next = || it.next().unwrap_or(0.0);
    w.w0.iter_mut().flatten().for_each(|v| *v = next());
    w.b0.iter_mut().for_each(|v| *v = next());
    w.w1.iter_mut().flatten().for_each(|v| *v = next());
    w.b1.iter_mut().for_each(|v| *v = next());
    w.w2.iter_mut().flatten().for_each(|v| *v = next());
    w.b2.iter_mut().for_each(|v| *v = next());
}

/// Weights of trained-MLP magnitude (|w| ≤ `scale`).
fn weights(scale: f32) -> impl Strategy<Value = MlpWeights> {
    prop::collection::vec(-scale..scale, 467).prop_map(|v| {
        let mut w = MlpWeights::ZERO;
        fill(&mut w, &v);
        w
    })
}

fn direction() -> impl Strategy<Value = [f64; 3]> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
        .prop_filter("non-zero", |(x, y, z)| x * x + y * y + z * z > 1e-6)
        .prop_map(|(x, y, z)| [x, y, z])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Fixed point vs the rounded f64 reference: never more than one step,
    /// over 64 random texels and directions per random weight set.
    #[test]
    fn fixed_is_within_one_step_of_f64(
        w in weights(3.0),
        samples in prop::collection::vec((any::<[u8; 4]>(), any::<[u8; 4]>(), direction()), 64),
    ) {
        let m = FixedMlp::from_weights(&w).unwrap();
        for (f0, f1, d) in samples {
            let got = m.shade(f0, f1, ViewDir::from_f64(d).unwrap());
            let want = shade_f64(&w, f0, f1, d);
            for (g, r) in got.iter().zip(want) {
                prop_assert!((*g as i32 - r as i32).abs() <= 1, "{:?} vs {:?}", got, want);
            }
        }
    }

    /// Any f32 weights (NaN, ±inf, huge, tiny): conversion returns Ok or an
    /// error, and an Ok table shades any input without panicking.
    #[test]
    fn any_weights_convert_or_error_without_panic(
        vals in prop::collection::vec(any::<f32>(), 1..467),
        f0 in any::<[u8; 4]>(),
        f1 in any::<[u8; 4]>(),
        bits in any::<[i32; 3]>(),
    ) {
        let mut w = MlpWeights::ZERO;
        fill(&mut w, &vals);
        match FixedMlp::from_weights(&w) {
            Ok(m) => { let _ = m.shade(f0, f1, ViewDir::from_bits(bits)); }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }

    /// Hand-made (firmware) tables with arbitrary integers never panic.
    #[test]
    fn arbitrary_tables_never_panic(
        w0 in any::<[i32; 16]>(),
        b in any::<[i64; 16]>(),
        shifts in any::<[u8; 3]>(),
        f0 in any::<[u8; 4]>(),
        bits in any::<[i32; 3]>(),
    ) {
        let mut m = FixedMlp::from_weights(&MlpWeights::ZERO).unwrap();
        m.l0.weights.iter_mut().for_each(|r| *r = w0);
        m.l1.bias = b;
        m.l1.weights.iter_mut().for_each(|r| *r = w0);
        m.l2.weights.iter_mut().for_each(|r| r.copy_from_slice(&w0[..3]));
        m.l0.shift = shifts[0];
        m.l1.shift = shifts[1];
        m.l2.shift = shifts[2];
        let _ = m.shade(f0, f0, ViewDir::from_bits(bits));
    }
}
