use super::*;
use proptest::prelude::*;

fn cfg(size: u64, q: f64) -> Config {
    Config {
        size: Bytes(size),
        quality: QualityQ::from_f64(q).unwrap(),
    }
}

/// Exhaustive reference on the rounded problem: (quality sum, units) of the
/// best plan (max quality, then min units), or None if nothing fits.
fn brute(objects: &[Vec<Config>], budget: u64, unit: u64) -> Option<(u64, u64)> {
    let cap = budget / unit;
    let mut best: Option<(u64, u64)> = None;
    let mut idx = vec![0usize; objects.len()];
    loop {
        let units: u64 = idx
            .iter()
            .zip(objects)
            .map(|(&j, o)| o[j].size.0.div_ceil(unit))
            .sum();
        let q: u64 = idx
            .iter()
            .zip(objects)
            .map(|(&j, o)| o[j].quality.raw() as u64)
            .sum();
        if units <= cap {
            best = match best {
                Some((bq, bu)) if (bq, std::cmp::Reverse(bu)) >= (q, std::cmp::Reverse(units)) => {
                    best
                }
                _ => Some((q, units)),
            };
        }
        let mut k = 0;
        loop {
            if k == idx.len() {
                return best;
            }
            idx[k] += 1;
            if idx[k] < objects[k].len() {
                break;
            }
            idx[k] = 0;
            k += 1;
        }
    }
}

fn solve_vec(
    objects: &[Vec<Config>],
    budget: u64,
    unit: u64,
) -> Result<(Vec<u8>, Solution<'static>), MckError> {
    let cells = objects
        .iter()
        .map(|o| {
            o.iter()
                .map(|c| c.size.0.div_ceil(unit.max(1)))
                .max()
                .unwrap_or(0)
        })
        .sum::<u64>()
        .min(budget / unit.max(1)) as usize;
    let lens = TableLens::new(
        objects.len(),
        objects.iter().map(Vec::len).max().unwrap_or(0),
        cells,
    );
    let best = vec![0u64; lens.best].leak();
    let choice = vec![0u8; lens.choice].leak();
    let items = vec![Item::EMPTY; lens.items].leak();
    let picked = vec![0u8; lens.picked].leak();
    let s = Tables::new(best, choice, items, picked).solve(objects, Bytes(budget), Bytes(unit))?;
    Ok((s.choices.to_vec(), s))
}

#[test]
fn picks_the_best_combination() {
    // Two objects, budget 10 units of 1 byte.
    let objects = [
        [cfg(2, 0.5), cfg(5, 0.8), cfg(8, 0.9)],
        [cfg(3, 0.6), cfg(5, 0.7), cfg(7, 0.95)],
    ];
    let mut s = Solver::<2, 3, 10>::new();
    let sol = s.solve(&objects, Bytes(10), Bytes(1)).unwrap();
    // Options within 10: (5,5)=1.5, (2,7)=1.45, (5,3)=1.4, (2,5)=1.2 ...
    assert_eq!(sol.choices, &[1, 1]);
    assert_eq!(sol.total_size, Bytes(10));
    assert_eq!(sol.total_units, 10);
    let expect = QualityQ::from_f64(0.8).unwrap().raw() as u64
        + QualityQ::from_f64(0.7).unwrap().raw() as u64;
    assert_eq!(sol.total_quality.0, expect);
}

#[test]
fn every_object_gets_a_configuration_even_when_budget_is_slack() {
    // The paper's backtracking from H can skip objects; ours cannot.
    let objects = [[cfg(1, 0.1)], [cfg(1, 0.2)], [cfg(1, 0.3)]];
    let mut s = Solver::<3, 1, 100>::new();
    let sol = s.solve(&objects, Bytes(100), Bytes(1)).unwrap();
    assert_eq!(sol.choices, &[0, 0, 0]);
    assert_eq!(sol.total_size, Bytes(3));
    assert_eq!(sol.total_units, 3);
}

#[test]
fn ties_go_to_the_smaller_total() {
    // Same quality at 4 and 6 bytes: the 4-byte one is chosen.
    let objects = [[cfg(6, 0.9), cfg(4, 0.9)], [cfg(3, 0.5), cfg(3, 0.5)]];
    let mut s = Solver::<2, 2, 20>::new();
    let sol = s.solve(&objects, Bytes(20), Bytes(1)).unwrap();
    assert_eq!(sol.choices, &[1, 0]);
    assert_eq!(sol.total_size, Bytes(7));
}

#[test]
fn tie_break_prefers_fewer_units_among_equal_quality_plans() {
    // Plans with quality 0.8: (a1,b0) = 5+1 units, (a0,b1) = 1+2 units.
    let objects = [[cfg(1, 0.2), cfg(5, 0.6)], [cfg(1, 0.2), cfg(2, 0.6)]];
    let mut s = Solver::<2, 2, 20>::new();
    let sol = s.solve(&objects, Bytes(20), Bytes(1)).unwrap();
    // With budget 20 the best is (a1, b1) = 1.2.
    assert_eq!(sol.choices, &[1, 1]);
    let sol = s.solve(&objects, Bytes(6), Bytes(1)).unwrap();
    // Budget 6: 1.2 needs 7; 0.8 reachable with 3 units (a0,b1) or 6 (a1,b0).
    assert_eq!(sol.choices, &[0, 1]);
    assert_eq!(sol.total_units, 3);
}

#[test]
fn sizes_round_up_so_bytes_never_exceed_the_budget() {
    // Each 101-byte config takes 2 units of 100: only one fits in 300 bytes.
    let objects = [[cfg(101, 0.9), cfg(50, 0.1)], [cfg(101, 0.9), cfg(50, 0.1)]];
    let mut s = Solver::<2, 2, 3>::new();
    let sol = s.solve(&objects, Bytes(300), Bytes(100)).unwrap();
    assert!(sol.total_size.0 <= 300);
    assert_eq!(sol.total_units, 3);
    assert_eq!(sol.total_size, Bytes(151));
}

#[test]
fn zero_sized_configurations_and_zero_budget() {
    let objects = [[cfg(0, 0.3), cfg(1, 0.9)], [cfg(0, 0.4), cfg(0, 0.2)]];
    let mut s = Solver::<2, 2, 4>::new();
    let sol = s.solve(&objects, Bytes(0), Bytes(1)).unwrap();
    assert_eq!(sol.choices, &[0, 0]);
    assert_eq!(sol.total_size, Bytes(0));
    let sol = s.solve(&objects, Bytes(1), Bytes(1)).unwrap();
    assert_eq!(sol.choices, &[1, 0]);
    // Budget 0 with a 1-byte cheapest: infeasible, naming the bytes needed.
    let objects = [[cfg(1, 0.3)]];
    assert_eq!(
        s.solve(&objects, Bytes(0), Bytes(1)).unwrap_err(),
        MckError::Infeasible {
            cheapest_total: Bytes(1),
            budget: Bytes(0)
        }
    );
}

#[test]
fn errors() {
    let mut s = Solver::<2, 2, 10>::new();
    let empty: [&[Config]; 0] = [];
    assert_eq!(
        s.solve(&empty, Bytes(5), Bytes(1)).unwrap_err(),
        MckError::NoObjects
    );
    let objs: [&[Config]; 2] = [&[cfg(1, 0.5)], &[]];
    assert_eq!(
        s.solve(&objs, Bytes(5), Bytes(1)).unwrap_err(),
        MckError::NoConfigs { object: 1 }
    );
    let objs: [&[Config]; 1] = [&[cfg(1, 0.5)]];
    assert_eq!(
        s.solve(&objs, Bytes(5), Bytes(0)).unwrap_err(),
        MckError::ZeroUnit
    );
    let three: [&[Config]; 3] = [&[cfg(1, 0.5)], &[cfg(1, 0.5)], &[cfg(1, 0.5)]];
    assert_eq!(
        s.solve(&three, Bytes(5), Bytes(1)).unwrap_err(),
        MckError::TooManyObjects {
            objects: 3,
            capacity: 2
        }
    );
    let wide: [&[Config]; 1] = [&[cfg(1, 0.5), cfg(2, 0.6), cfg(3, 0.7)]];
    assert_eq!(
        s.solve(&wide, Bytes(5), Bytes(1)).unwrap_err(),
        MckError::TooManyConfigs {
            object: 0,
            configs: 3,
            capacity: 2
        }
    );
    let big: [&[Config]; 1] = [&[cfg(100, 0.5)]];
    assert_eq!(
        s.solve(&big, Bytes(100), Bytes(1)).unwrap_err(),
        MckError::TooManyUnits {
            units: 100,
            capacity: 10
        }
    );
    // Fits in bytes (2 + 2 <= 5) but not in units of 3 (1 + 1 > 1).
    let two: [&[Config]; 2] = [&[cfg(2, 0.5)], &[cfg(2, 0.5)]];
    assert_eq!(
        s.solve(&two, Bytes(5), Bytes(3)).unwrap_err(),
        MckError::UnitTooCoarse {
            cheapest_total: Bytes(4),
            cheapest_rounded: Bytes(6),
            budget: Bytes(5),
            unit: Bytes(3)
        }
    );
}

#[test]
fn huge_budgets_and_sizes_do_not_overflow() {
    let objects = [
        [cfg(u64::MAX, 0.9), cfg(1, 0.1)],
        [cfg(u64::MAX / 2, 0.9), cfg(1, 0.5)],
    ];
    let mut s = Solver::<2, 2, 64>::new();
    let sol = s
        .solve(&objects, Bytes(u64::MAX), Bytes(u64::MAX / 32))
        .unwrap();
    assert_eq!(sol.choices, &[1, 0]);
    assert_eq!(sol.total_units, 1 + 17);
    // The cheapest plan overflows u64: infeasible, not a wrap-around.
    let objects = [[cfg(u64::MAX, 0.9)], [cfg(2, 0.9)]];
    assert_eq!(
        s.solve(&objects, Bytes(u64::MAX), Bytes(u64::MAX / 32))
            .unwrap_err(),
        MckError::Infeasible {
            cheapest_total: Bytes::MAX,
            budget: Bytes::MAX
        }
    );
    // Everything fits when the unit is the whole budget and sizes are tiny.
    let small = [[cfg(1, 0.9)], [cfg(1, 0.8)]];
    let sol = s
        .solve(&small, Bytes(u64::MAX), Bytes(u64::MAX))
        .unwrap_err();
    assert!(matches!(sol, MckError::UnitTooCoarse { .. }));
}

#[test]
fn paper_size_memory() {
    assert_eq!(core::mem::size_of::<Item>(), 24);
    assert_eq!(Solver::<5, 45, 2400>::MEMORY_BYTES, 32_285);
    assert_eq!(memory_bytes(5, 45, 2400), 32_285);
}

#[test]
fn paper_size_problem_is_solved_within_budget() {
    // 5 objects × 45 configurations on a 9 × 5 (g, p) grid, H = 240 MB in 0.1 MB units.
    let gs = [32.0, 48.0, 64.0, 80.0, 96.0, 112.0, 128.0, 144.0, 160.0];
    let ps = [5.0, 9.0, 13.0, 17.0, 21.0];
    let objects: Vec<Vec<Config>> = (0..5)
        .map(|o| {
            let k = 0.12 + 0.03 * o as f64;
            gs.iter()
                .flat_map(|&g| ps.iter().map(move |&p| (g, p)))
                .map(|(g, p): (f64, f64)| {
                    let size = k * g * g * g * p * p + 2.0e6;
                    let q = 0.953 - 3.2e6 / ((g + 32.0).powi(3) * (p + 4.0).powi(2));
                    cfg(size as u64, q)
                })
                .collect()
        })
        .collect();
    let mut s = Solver::<5, 45, 2400>::new();
    let sol = s
        .solve(&objects, Bytes(240_000_000), Bytes(100_000))
        .unwrap();
    assert!(sol.total_size.0 <= 240_000_000);
    assert_eq!(sol.choices.len(), 5);
    let (q, _) = brute_pruned(&objects, 240_000_000, 100_000);
    assert_eq!(sol.total_quality.0, q);
}

/// Depth-first exhaustive search with feasibility pruning (exact on the
/// rounded problem); fast enough for 45^5 with a binding budget.
fn brute_pruned(objects: &[Vec<Config>], budget: u64, unit: u64) -> (u64, u64) {
    fn go(
        objects: &[Vec<Config>],
        unit: u64,
        left: u64,
        q: u64,
        units: u64,
        best: &mut (u64, u64),
    ) {
        match objects.split_first() {
            None => {
                if q > best.0 || (q == best.0 && units < best.1) {
                    *best = (q, units);
                }
            }
            Some((first, rest)) => {
                for c in first {
                    let u = c.size.0.div_ceil(unit);
                    if u <= left {
                        go(
                            rest,
                            unit,
                            left - u,
                            q + c.quality.raw() as u64,
                            units + u,
                            best,
                        );
                    }
                }
            }
        }
    }
    let mut best = (0, u64::MAX);
    go(objects, unit, budget / unit, 0, 0, &mut best);
    best
}

fn arb_objects(
    max_objects: usize,
    max_configs: usize,
    max_size: u64,
) -> impl Strategy<Value = Vec<Vec<Config>>> {
    prop::collection::vec(
        prop::collection::vec(
            (0..=max_size, 0u32..=(1 << 31)).prop_map(|(s, q)| Config {
                size: Bytes(s),
                quality: QualityQ::from_raw(q).unwrap(),
            }),
            1..=max_configs,
        ),
        1..=max_objects,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn matches_brute_force_on_the_rounded_problem(
        objects in arb_objects(4, 5, 40),
        budget in 0u64..120,
        unit in 1u64..7,
    ) {
        let expect = brute(&objects, budget, unit);
        match solve_vec(&objects, budget, unit) {
            Ok((choices, sol)) => {
                let (q, u) = expect.expect("brute force found nothing but the DP did");
                prop_assert_eq!(sol.total_quality.0, q);
                prop_assert_eq!(sol.total_units, u);
                prop_assert!(sol.total_size.0 <= budget);
                // The reported totals are those of the chosen configurations.
                let size: u64 = choices.iter().zip(&objects).map(|(&j, o)| o[j as usize].size.0).sum();
                let units: u64 = choices.iter().zip(&objects).map(|(&j, o)| o[j as usize].size.0.div_ceil(unit)).sum();
                let qual: u64 = choices.iter().zip(&objects).map(|(&j, o)| o[j as usize].quality.raw() as u64).sum();
                prop_assert_eq!(sol.total_size.0, size);
                prop_assert_eq!(sol.total_units, units);
                prop_assert_eq!(sol.total_quality.0, qual);
            }
            Err(MckError::Infeasible { .. }) | Err(MckError::UnitTooCoarse { .. }) => {
                prop_assert!(expect.is_none());
            }
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
    }

    #[test]
    fn never_panics_on_any_input(
        objects in arb_objects(6, 8, u64::MAX),
        budget in any::<u64>(),
        unit in any::<u64>(),
    ) {
        let mut s = Solver::<4, 6, 300>::new();
        if let Ok(sol) = s.solve(&objects, Bytes(budget), Bytes(unit)) {
            prop_assert!(sol.total_size.0 <= budget);
            prop_assert_eq!(sol.choices.len(), objects.len());
        }
    }
}
