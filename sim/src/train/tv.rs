//! Total variation over the lattice's edges (Plenoxels' regulariser, in
//! its squared form): `λ Σ_edges (x_a − x_b)²` over the raw density and,
//! with its own weight, the SH coefficients. It smooths what few rays
//! constrain — the floaters in lego's shadowed tracks — and is applied
//! lazily: only the slots a step touched get its gradient, as only they
//! get an Adam update.

use rayon::prelude::*;

use super::adam::{prefetch, AHEAD};
use super::grid::{SparseGrid, EMPTY};
use super::march::GradBuf;

/// The six lattice neighbours of every slot (−x, +x, −y, +y, −z, +z),
/// `EMPTY` where the neighbour stores nothing or lies outside.
#[derive(Debug, Clone, Default)]
pub struct Neighbours {
    /// Per slot.
    pub slots: Vec<[u32; 6]>,
}

impl Neighbours {
    /// The table of `grid`.
    pub fn of(grid: &SparseGrid) -> Self {
        let n = grid.res as i64 + 1;
        let slots = grid
            .vertex
            .par_iter()
            .map(|&v| {
                let (i, j, k) = grid.vertex_ijk(v);
                let (i, j, k) = (i as i64, j as i64, k as i64);
                let at = |a: i64, b: i64, c: i64| {
                    if (0..n).contains(&a) && (0..n).contains(&b) && (0..n).contains(&c) {
                        grid.index[((c * n + b) * n + a) as usize]
                    } else {
                        EMPTY
                    }
                };
                [
                    at(i - 1, j, k),
                    at(i + 1, j, k),
                    at(i, j - 1, k),
                    at(i, j + 1, k),
                    at(i, j, k - 1),
                    at(i, j, k + 1),
                ]
            })
            .collect();
        Neighbours { slots }
    }
}

/// Weights of the total variation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TvWeights {
    /// On the raw density.
    pub density: f32,
    /// On every SH coefficient.
    pub color: f32,
}

impl TvWeights {
    /// Whether there is anything to do.
    pub fn is_off(&self) -> bool {
        self.density == 0.0 && self.color == 0.0
    }
}

/// Adds the gradient of the total variation at every slot some worker
/// touched, `2λ Σ_nb (x_v − x_nb)` per float, to the first worker's
/// buffer. `values` are read, not changed.
pub fn add_grad(values: &[f32], len: usize, nb: &Neighbours, w: TvWeights, grads: &mut [GradBuf]) {
    if w.is_off() || len == 0 {
        return;
    }
    let Some((first, rest)) = grads.split_first_mut() else {
        return;
    };
    let rest: &[GradBuf] = rest;
    const BLOCK: usize = 4096;
    first
        .grad
        .par_chunks_mut(BLOCK * len)
        .zip(first.mark.par_chunks_mut(BLOCK))
        .enumerate()
        .for_each(|(b, (grad, mark))| {
            // The block's slots some worker touched, in increasing order.
            let mut idx = [0u16; BLOCK];
            let mut n = 0;
            for (o, m) in mark.iter().enumerate() {
                let s = b * BLOCK + o;
                if *m || rest.iter().any(|g| g.mark.get(s).copied().unwrap_or(false)) {
                    if let Some(at) = idx.get_mut(n) {
                        *at = o as u16;
                        n += 1;
                    }
                }
            }
            let idx = &idx[..n];
            for (k, &o) in idx.iter().enumerate() {
                // The ±y and ±z neighbours lie far away in the slot order:
                // ask for their records a few touched slots ahead (their
                // indices a few more ahead).
                if let Some(&a) = idx.get(k + 2 * AHEAD) {
                    prefetch(nb.slots.get(b * BLOCK + a as usize).map(|x| &x[..]));
                }
                if let Some(nbs) = idx
                    .get(k + AHEAD)
                    .and_then(|&a| nb.slots.get(b * BLOCK + a as usize))
                {
                    for &t in &[nbs[2], nbs[3], nbs[4], nbs[5]] {
                        if t != EMPTY {
                            prefetch(values.get(t as usize * len..(t as usize + 1) * len));
                        }
                    }
                }
                let o = o as usize;
                let s = b * BLOCK + o;
                let (Some(nbs), Some(own), Some(g), Some(m)) = (
                    nb.slots.get(s),
                    values.get(s * len..(s + 1) * len),
                    grad.get_mut(o * len..(o + 1) * len),
                    mark.get_mut(o),
                ) else {
                    continue;
                };
                if !*m {
                    // Stale until this worker touches it (`GradBuf`).
                    *m = true;
                    g.fill(0.0);
                }
                for &t in nbs {
                    if t == EMPTY {
                        continue;
                    }
                    let Some(other) = values.get(t as usize * len..(t as usize + 1) * len) else {
                        continue;
                    };
                    g[0] += 2.0 * w.density * (own[0] - other[0]);
                    if w.color != 0.0 {
                        for i in 1..len {
                            g[i] += 2.0 * w.color * (own[i] - other[i]);
                        }
                    }
                }
            }
        });
}

/// The total variation itself (for tests and reports).
pub fn value(values: &[f32], len: usize, nb: &Neighbours, w: TvWeights) -> f64 {
    let mut sum = 0.0f64;
    for (s, nbs) in nb.slots.iter().enumerate() {
        // Each edge once: the +x, +y, +z neighbours.
        for &t in &[nbs[1], nbs[3], nbs[5]] {
            if t == EMPTY {
                continue;
            }
            let (a, b) = (s * len, t as usize * len);
            let d = f64::from(values[a] - values[b]);
            sum += f64::from(w.density) * d * d;
            for i in 1..len {
                let d = f64::from(values[a + i] - values[b + i]);
                sum += f64::from(w.color) * d * d;
            }
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::Aabb;
    use glam::Vec3;

    /// The gradient of every float of a small grid with some vertices
    /// missing matches finite differences of [`value`], and untouched
    /// slots get none.
    #[test]
    fn gradient_matches_finite_differences() {
        let cube = Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        let mut g = SparseGrid::new(3, cube, 1, |i, j, k| (i + 2 * j + k) % 5 != 0);
        let mut x = 17u64;
        for v in g.values.iter_mut() {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            *v = (x >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
        }
        let len = g.record_len();
        let nb = Neighbours::of(&g);
        let w = TvWeights {
            density: 0.3,
            color: 0.05,
        };
        let mut grads = vec![GradBuf::new(g.slots(), len), GradBuf::new(g.slots(), len)];
        // Every slot but slot 1 touched, by one worker or the other.
        for s in 0..g.slots() {
            if s != 1 {
                grads[s % 2].mark[s] = true;
            }
        }
        // Stale records where the first worker's flag is clear: the TV
        // must overwrite them, not add to them.
        for s in 0..g.slots() {
            if !grads[0].mark[s] {
                grads[0].grad[s * len..(s + 1) * len].fill(7.0);
            }
        }
        add_grad(&g.values, len, &nb, w, &mut grads);
        for i in 0..g.values.len() {
            let s = i / len;
            let an = f64::from(grads[0].grad[i]);
            if s == 1 {
                assert!(!grads[0].mark[1] && !grads[1].mark[1]);
                continue;
            }
            let h = 1e-2;
            let mut a = g.values.clone();
            a[i] += h;
            let mut b = g.values.clone();
            b[i] -= h;
            let fd = (value(&a, len, &nb, w) - value(&b, len, &nb, w)) / (2.0 * f64::from(h));
            assert!((fd - an).abs() < 1e-3, "float {i}: analytic {an}, fd {fd}");
        }
    }

    #[test]
    fn neighbours_are_symmetric() {
        let cube = Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        let g = SparseGrid::new(4, cube, 0, |i, j, k| (i * j + k) % 3 != 1);
        let nb = Neighbours::of(&g);
        for (s, nbs) in nb.slots.iter().enumerate() {
            for (d, &t) in nbs.iter().enumerate() {
                if t != EMPTY {
                    assert_eq!(nb.slots[t as usize][d ^ 1], s as u32);
                }
            }
        }
    }
}
