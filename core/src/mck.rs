//! Exact multiple-choice knapsack (MCK) configuration selector.
//!
//! Chooses **exactly one** configuration per object so that the total
//! predicted quality (SSIM, [`QualityQ`]) is maximal and the total size is at
//! most the budget H. This is NeRFlex's DP-based configuration selector, done
//! so that it is exact and cannot fail on any input:
//!
//! - **Quantized budget.** Sizes are rounded *up* to the budget unit `u` and
//!   the budget *down* (`⌊H/u⌋` units), so the true total in bytes never
//!   exceeds H whatever the unit. The DP is exact for those rounded sizes.
//! - **Exact quality.** Qualities are summed as integers (Q1.31 values into a
//!   `u64`), so there is no floating-point order dependence.
//! - **Dominated configurations** (more units and not better) are removed
//!   per object before its DP layer; only the Pareto frontier is iterated.
//! - **Reconstruction.** A choice table per object and capacity records the
//!   configuration used; backtracking starts at the *smallest* capacity that
//!   reaches the optimum, so every object gets exactly one configuration
//!   (the paper's Algorithm 1 backtracks every object from H and can leave
//!   one without a configuration; this does not).
//! - **Tie-break.** Among plans of equal total quality the one with the
//!   smallest total in budget units is returned (exact, at the unit's
//!   resolution); remaining ties go to the configuration of smaller size in
//!   bytes, then of smaller index. Deterministic.
//! - **Capacity.** Only capacities up to `min(⌊H/u⌋, Σ_i max units_i)` are
//!   tabulated: beyond that every capacity has the same answer, so huge
//!   budgets cost nothing.
//!
//! Time: `O(objects × capacity × frontier size)` plus
//! `O(objects × configs²)` worst case for the frontier's insertion sort.
//!
//! # Memory
//!
//! No allocation: the caller provides the tables, either as a
//! [`Solver<OBJ, CFG, UNITS>`] (arrays sized by const generics; put it in a
//! `static` on a microcontroller) or as slices through [`Tables`] (the host
//! sizes them per problem). With `N` objects, `C` configurations per object
//! and `U` budget units (the maximal `⌊H/u⌋`), the tables take
//!
//! ```text
//! bytes = 8·U        (best quality per capacity, u64, one row updated in place)
//!       + N·U        (choice per object and capacity, u8)
//!       + 24·C       (the current object's frontier, Item = u64 + 2·u32 + u8, padded)
//!       + N          (the chosen index per object, u8)
//! ```
//!
//! ([`memory_bytes`]). The paper-sized problem — 5 objects × 45 configurations,
//! H = 240 MB in our 0.1 MB units (U = 2400; the unit and the 45 are our
//! choices, the paper gives neither) — needs 19 200 + 12 000 + 1 080 + 5
//! = **32 285 bytes** (`Solver::<5, 45, 2400>::MEMORY_BYTES`). Capacity 0 is
//! kept in a scalar, so `U` is exactly the number of budget units.
//!
//! At most [`MAX_CONFIGS`] = 256 configurations per object (the choice table
//! stores `u8` indices) and 2^32 objects (so the quality sum cannot overflow).

use crate::units::{Bytes, QualityQ, QualitySum};
use core::fmt;

/// Most configurations one object may have: choices are stored as `u8`.
pub const MAX_CONFIGS: usize = 256;

/// Most objects: `2^32 · 2^31` still fits the `u64` quality sum.
const MAX_OBJECTS: usize = if usize::BITS > 32 {
    1 << 32
} else {
    usize::MAX
};

/// Marks a capacity no combination of configurations fits in.
const NONE: u64 = u64::MAX;

/// One configuration of one object: its size and predicted quality.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Config {
    /// Size of the baked data in bytes.
    pub size: Bytes,
    /// Predicted SSIM.
    pub quality: QualityQ,
}

/// Why no plan was returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MckError {
    /// The budget unit is zero bytes.
    ZeroUnit,
    /// There are no objects to plan.
    NoObjects,
    /// Object `object` (index into the input) has no configuration.
    NoConfigs {
        /// Index of the object.
        object: usize,
    },
    /// More objects than the tables hold.
    TooManyObjects {
        /// Objects given.
        objects: usize,
        /// Objects the tables hold.
        capacity: usize,
    },
    /// An object has more configurations than the tables hold.
    TooManyConfigs {
        /// Index of the object.
        object: usize,
        /// Its number of configurations.
        configs: usize,
        /// Configurations the tables hold per object.
        capacity: usize,
    },
    /// The budget has more units than the tables hold: use a coarser unit.
    TooManyUnits {
        /// Units the problem needs (`min(⌊H/u⌋, Σ max units)`).
        units: u64,
        /// Units the tables hold.
        capacity: usize,
    },
    /// Even the cheapest configuration of every object does not fit.
    Infeasible {
        /// Bytes the cheapest plan needs.
        cheapest_total: Bytes,
        /// The budget.
        budget: Bytes,
    },
    /// The cheapest plan fits in bytes but not once sizes are rounded up to
    /// the unit: use a finer unit.
    UnitTooCoarse {
        /// Bytes the cheapest plan needs.
        cheapest_total: Bytes,
        /// The same plan with each size rounded up to the unit.
        cheapest_rounded: Bytes,
        /// The budget.
        budget: Bytes,
        /// The budget unit.
        unit: Bytes,
    },
    /// An internal invariant failed. Never returned; it exists so that no
    /// code path can panic.
    Internal,
}

impl fmt::Display for MckError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            MckError::ZeroUnit => write!(f, "the budget unit is zero bytes"),
            MckError::NoObjects => write!(f, "there are no objects to plan"),
            MckError::NoConfigs { object } => {
                write!(f, "object {object} has no configuration")
            }
            MckError::TooManyObjects { objects, capacity } => write!(
                f,
                "{objects} objects, but the solver holds at most {capacity}"
            ),
            MckError::TooManyConfigs {
                object,
                configs,
                capacity,
            } => write!(
                f,
                "object {object} has {configs} configurations, but the solver holds at most {capacity}"
            ),
            MckError::TooManyUnits { units, capacity } => write!(
                f,
                "the budget spans {units} units, but the solver holds at most {capacity}: use a coarser unit"
            ),
            MckError::Infeasible {
                cheapest_total,
                budget,
            } => write!(
                f,
                "infeasible: the cheapest plan needs {} bytes, over the budget of {} bytes",
                cheapest_total.0, budget.0
            ),
            MckError::UnitTooCoarse {
                cheapest_total,
                cheapest_rounded,
                budget,
                unit,
            } => write!(
                f,
                "infeasible at this unit: the cheapest plan needs {} bytes, {} bytes once each size is rounded up to the {}-byte unit, over the budget of {} bytes: use a finer unit",
                cheapest_total.0, cheapest_rounded.0, unit.0, budget.0
            ),
            MckError::Internal => write!(f, "internal error in the MCK solver"),
        }
    }
}

impl core::error::Error for MckError {}

/// A configuration on the current object's Pareto frontier (DP scratch).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Item {
    bytes: u64,
    units: u32,
    quality: u32,
    index: u8,
}

impl Item {
    /// An unused slot.
    pub const EMPTY: Item = Item {
        bytes: 0,
        units: 0,
        quality: 0,
        index: 0,
    };

    /// Frontier order: fewer units first, then higher quality, then fewer
    /// bytes, then lower index.
    fn before(&self, other: &Item) -> bool {
        (self.units, other.quality, self.bytes, self.index)
            < (other.units, self.quality, other.bytes, other.index)
    }
}

/// Bytes of tables the solver needs for `objects` objects, `configs`
/// configurations per object and `units` budget units (see the module docs).
pub const fn memory_bytes(objects: usize, configs: usize, units: usize) -> usize {
    8usize
        .saturating_mul(units)
        .saturating_add(objects.saturating_mul(units))
        .saturating_add(core::mem::size_of::<Item>().saturating_mul(configs))
        .saturating_add(objects)
}

/// Slice lengths [`Tables::new`] needs for a problem size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TableLens {
    /// Length of `best` (`u64`): the budget units.
    pub best: usize,
    /// Length of `choice` (`u8`): objects × units.
    pub choice: usize,
    /// Length of `items`: configurations per object.
    pub items: usize,
    /// Length of `picked` (`u8`): objects.
    pub picked: usize,
}

impl TableLens {
    /// Lengths for `objects` objects, `configs` configurations per object and
    /// `units` budget units (saturating).
    pub const fn new(objects: usize, configs: usize, units: usize) -> TableLens {
        TableLens {
            best: units,
            choice: objects.saturating_mul(units),
            items: configs,
            picked: objects,
        }
    }
}

/// The solver's tables, borrowed from the caller.
///
/// Capacities follow from the lengths: `best.len()` budget units,
/// `min(picked.len(), choice.len() / best.len())` objects,
/// `min(items.len(), 256)` configurations per object.
#[derive(Debug)]
pub struct Tables<'a> {
    /// `best[c - 1]`: best quality sum with at most `c` units (capacity 0 is a scalar).
    best: &'a mut [u64],
    /// `choice[i · best.len() + c - 1]`: configuration of object `i` used at capacity `c`.
    choice: &'a mut [u8],
    /// The current object's frontier.
    items: &'a mut [Item],
    /// The answer: chosen configuration per object.
    picked: &'a mut [u8],
}

/// A plan: one configuration per object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Solution<'a> {
    /// `choices[i]` is the index of object `i`'s chosen configuration.
    pub choices: &'a [u8],
    /// Total size in bytes (at most the budget).
    pub total_size: Bytes,
    /// Total size in budget units (sizes rounded up), at most `⌊H/u⌋`.
    pub total_units: u64,
    /// Total predicted quality.
    pub total_quality: QualitySum,
}

impl<'a> Tables<'a> {
    /// Tables over caller-provided slices (see [`TableLens`] for the lengths).
    pub fn new(
        best: &'a mut [u64],
        choice: &'a mut [u8],
        items: &'a mut [Item],
        picked: &'a mut [u8],
    ) -> Tables<'a> {
        Tables {
            best,
            choice,
            items,
            picked,
        }
    }

    /// Solves one problem: `objects[i]` lists object `i`'s configurations;
    /// the total size must not exceed `budget`, planned in units of `unit`.
    pub fn solve<T: AsRef<[Config]>>(
        self,
        objects: &[T],
        budget: Bytes,
        unit: Bytes,
    ) -> Result<Solution<'a>, MckError> {
        let Tables {
            best,
            choice,
            items,
            picked,
        } = self;
        if unit.0 == 0 {
            return Err(MckError::ZeroUnit);
        }
        let n = objects.len();
        if n == 0 {
            return Err(MckError::NoObjects);
        }
        let cells = best.len().min(u32::MAX as usize);
        let object_capacity = choice
            .len()
            .checked_div(cells)
            .map_or(picked.len(), |rows| rows.min(picked.len()))
            .min(MAX_OBJECTS);
        if n > object_capacity {
            return Err(MckError::TooManyObjects {
                objects: n,
                capacity: object_capacity,
            });
        }
        let config_capacity = items.len().min(MAX_CONFIGS);
        let budget_units = budget.0 / unit.0;

        // Pass 1: validate, cheapest plan, largest useful capacity.
        let mut cheapest_bytes = Some(Bytes::ZERO);
        let mut cheapest_units: u64 = 0;
        let mut sum_max_units: u64 = 0;
        for (i, object) in objects.iter().enumerate() {
            let configs = object.as_ref();
            if configs.is_empty() {
                return Err(MckError::NoConfigs { object: i });
            }
            if configs.len() > config_capacity {
                return Err(MckError::TooManyConfigs {
                    object: i,
                    configs: configs.len(),
                    capacity: config_capacity,
                });
            }
            let mut min_bytes = u64::MAX;
            let mut min_units = u64::MAX;
            let mut max_units_fitting = 0;
            for c in configs {
                let u = units_of(c.size, unit);
                min_bytes = min_bytes.min(c.size.0);
                min_units = min_units.min(u);
                if u <= budget_units {
                    max_units_fitting = max_units_fitting.max(u);
                }
            }
            cheapest_bytes = cheapest_bytes.and_then(|b| b.checked_add(Bytes(min_bytes)));
            cheapest_units = cheapest_units.saturating_add(min_units);
            sum_max_units = sum_max_units.saturating_add(max_units_fitting);
        }
        if cheapest_units > budget_units {
            return Err(match cheapest_bytes {
                // The cheapest plan needs 2^64 bytes or more.
                None => MckError::Infeasible {
                    cheapest_total: Bytes::MAX,
                    budget,
                },
                Some(cheapest_total) if cheapest_total > budget => MckError::Infeasible {
                    cheapest_total,
                    budget,
                },
                Some(cheapest_total) => MckError::UnitTooCoarse {
                    cheapest_total,
                    cheapest_rounded: Bytes(cheapest_units.saturating_mul(unit.0)),
                    budget,
                    unit,
                },
            });
        }
        // Every object's fitting configurations have at most `cap` units.
        let cap64 = budget_units.min(sum_max_units);
        if cap64 > cells as u64 {
            return Err(MckError::TooManyUnits {
                units: cap64,
                capacity: cells,
            });
        }
        let cap = cap64 as usize; // <= cells <= u32::MAX

        // Layer 0 (no object yet): quality 0 at every capacity.
        best.get_mut(..cap).ok_or(MckError::Internal)?.fill(0);
        let mut best_zero: u64 = 0;

        for (i, object) in objects.iter().enumerate() {
            let live = frontier(object.as_ref(), unit, cap64, items)?;
            let row = i
                .checked_mul(cells)
                .and_then(|start| choice.get_mut(start..start.checked_add(cap)?))
                .ok_or(MckError::Internal)?;
            // Downward, in place: cell c reads only cells < c (and itself
            // for a 0-unit item) of the previous layer.
            for c in (1..=cap).rev() {
                let mut top = NONE;
                let mut pick = 0u8;
                for it in live.iter() {
                    let w = it.units as usize;
                    if w > c {
                        break; // the frontier is sorted by units
                    }
                    let prev = if w == c {
                        best_zero
                    } else {
                        *best.get(c - w - 1).ok_or(MckError::Internal)?
                    };
                    if prev == NONE {
                        continue;
                    }
                    let v = prev + it.quality as u64; // < 2^63: n <= 2^32
                    if top == NONE || v > top {
                        top = v;
                        pick = it.index;
                    }
                }
                *best.get_mut(c - 1).ok_or(MckError::Internal)? = top;
                *row.get_mut(c - 1).ok_or(MckError::Internal)? = pick;
            }
            best_zero = match live.first() {
                Some(it) if it.units == 0 && best_zero != NONE => best_zero + it.quality as u64,
                _ => NONE,
            };
        }

        let top = if cap == 0 {
            best_zero
        } else {
            *best.get(cap - 1).ok_or(MckError::Internal)?
        };
        if top == NONE {
            return Err(MckError::Internal); // the cheapest plan fits
        }
        // The smallest capacity that reaches the optimum.
        let mut c = if best_zero == top {
            0
        } else {
            best.get(..cap)
                .and_then(|b| b.iter().position(|&v| v == top))
                .ok_or(MckError::Internal)?
                + 1
        };

        let mut total_size = Bytes::ZERO;
        let mut total_units: u64 = 0;
        let mut total_quality = QualitySum::ZERO;
        for i in (0..n).rev() {
            let configs = objects.get(i).ok_or(MckError::Internal)?.as_ref();
            let index = if c == 0 {
                zero_unit_choice(configs, unit).ok_or(MckError::Internal)?
            } else {
                *choice
                    .get(i * cells + c - 1) // i < n <= choice.len() / cells
                    .ok_or(MckError::Internal)?
            };
            let config = configs.get(index as usize).ok_or(MckError::Internal)?;
            let w = units_of(config.size, unit);
            c = usize::try_from(w)
                .ok()
                .and_then(|w| c.checked_sub(w))
                .ok_or(MckError::Internal)?;
            *picked.get_mut(i).ok_or(MckError::Internal)? = index;
            total_size = total_size
                .checked_add(config.size)
                .ok_or(MckError::Internal)?;
            total_units += w; // <= cap
            total_quality = total_quality
                .checked_add(config.quality)
                .ok_or(MckError::Internal)?;
        }
        Ok(Solution {
            choices: picked.get(..n).ok_or(MckError::Internal)?,
            total_size,
            total_units,
            total_quality,
        })
    }
}

/// `size` in units, rounded up (`unit` is non-zero here).
fn units_of(size: Bytes, unit: Bytes) -> u64 {
    size.units_ceil(unit).unwrap_or(u64::MAX)
}

/// Fills `items` with the Pareto frontier of `configs` among those of at
/// most `max_units` units: sorted by units, each strictly better than the
/// previous. Returns the frontier.
fn frontier<'i>(
    configs: &[Config],
    unit: Bytes,
    max_units: u64,
    items: &'i mut [Item],
) -> Result<&'i [Item], MckError> {
    let mut m = 0;
    for (j, c) in configs.iter().enumerate() {
        let u = units_of(c.size, unit);
        if u > max_units {
            continue;
        }
        let item = Item {
            bytes: c.size.0,
            units: u32::try_from(u).map_err(|_| MckError::Internal)?,
            quality: c.quality.raw(),
            index: u8::try_from(j).map_err(|_| MckError::Internal)?,
        };
        // Insertion sort (no allocation; at most 256 items): `slot[..m]` is
        // sorted; rotate `item` into place.
        let slot = items.get_mut(..=m).ok_or(MckError::Internal)?;
        let k = slot
            .get(..m)
            .ok_or(MckError::Internal)?
            .partition_point(|x| !item.before(x));
        let tail = slot.get_mut(k..).ok_or(MckError::Internal)?;
        tail.rotate_right(1);
        *tail.first_mut().ok_or(MckError::Internal)? = item;
        m += 1;
    }
    // Keep an item only if it is strictly better than every cheaper one.
    let sorted = items.get_mut(..m).ok_or(MckError::Internal)?;
    let mut kept = 0;
    let mut last_quality: Option<u32> = None;
    for k in 0..m {
        let it = *sorted.get(k).ok_or(MckError::Internal)?;
        if last_quality.is_none_or(|q| it.quality > q) {
            *sorted.get_mut(kept).ok_or(MckError::Internal)? = it;
            kept += 1;
            last_quality = Some(it.quality);
        }
    }
    items.get(..kept).ok_or(MckError::Internal)
}

/// The configuration a 0-unit capacity uses: among 0-unit configurations,
/// the best quality, then fewest bytes, then lowest index (the frontier's rule).
fn zero_unit_choice(configs: &[Config], unit: Bytes) -> Option<u8> {
    let mut best: Option<(usize, &Config)> = None;
    for (j, c) in configs.iter().enumerate() {
        if units_of(c.size, unit) != 0 {
            continue;
        }
        best = match best {
            Some((_, b)) if (b.quality, c.size) >= (c.quality, b.size) => best,
            _ => Some((j, c)),
        };
    }
    best.and_then(|(j, _)| u8::try_from(j).ok())
}

/// The solver with its tables inline, capacities fixed by the type:
/// `OBJ` objects, `CFG` configurations per object (at most 256), `UNITS`
/// budget units. Holds [`Solver::MEMORY_BYTES`] bytes of tables.
#[derive(Debug)]
pub struct Solver<const OBJ: usize, const CFG: usize, const UNITS: usize> {
    best: [u64; UNITS],
    choice: [[u8; UNITS]; OBJ],
    items: [Item; CFG],
    picked: [u8; OBJ],
}

impl<const OBJ: usize, const CFG: usize, const UNITS: usize> Default for Solver<OBJ, CFG, UNITS> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const OBJ: usize, const CFG: usize, const UNITS: usize> Solver<OBJ, CFG, UNITS> {
    /// Compile-time check of the capacities.
    const VALID: () = assert!(
        CFG <= MAX_CONFIGS && UNITS <= u32::MAX as usize,
        "mck::Solver: CFG must be <= 256 and UNITS <= u32::MAX"
    );

    /// Bytes of tables this solver holds (see the module docs).
    pub const MEMORY_BYTES: usize = memory_bytes(OBJ, CFG, UNITS);

    /// An empty solver (the tables need no initialisation between solves).
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID;
        Solver {
            best: [0; UNITS],
            choice: [[0; UNITS]; OBJ],
            items: [Item::EMPTY; CFG],
            picked: [0; OBJ],
        }
    }

    /// Solves one problem (see [`Tables::solve`]).
    pub fn solve<T: AsRef<[Config]>>(
        &mut self,
        objects: &[T],
        budget: Bytes,
        unit: Bytes,
    ) -> Result<Solution<'_>, MckError> {
        Tables::new(
            &mut self.best,
            self.choice.as_flattened_mut(),
            &mut self.items,
            &mut self.picked,
        )
        .solve(objects, budget, unit)
    }
}

#[cfg(test)]
mod tests;
