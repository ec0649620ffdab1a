//! Sparse ("lazy") Adam over the grid's records: only the slots some
//! worker touched in this step are read, updated and cleared, so a step
//! costs what the batch touched, not the size of the grid.

use rayon::prelude::*;

use super::march::GradBuf;

/// Adam's moments, one pair per stored float, kept beside each other
/// per record (`[m; len]` then `[v; len]`): a record's two moment lines
/// are adjacent, so one miss brings both (the spatial prefetcher pairs
/// 128-byte-aligned lines).
#[derive(Debug, Clone)]
pub struct Adam {
    mv: Vec<f32>,
    step: u32,
    /// β₁, β₂.
    pub betas: (f32, f32),
    /// ε.
    pub eps: f32,
    /// Update every slot each step (moments carry on without a
    /// gradient), not only the touched ones.
    pub dense: bool,
}

/// Slots per parallel block of the optimiser's pass.
const BLOCK: usize = 2048;

/// Touched slots ahead of the one being updated whose lines are
/// prefetched: a touched slot's five lines (value, two moments, two
/// workers' gradients) are scattered over the grid, so the pass waits on
/// memory unless it asks early.
pub(super) const AHEAD: usize = 8;

impl Adam {
    /// Zero moments for `n` floats.
    pub fn new(n: usize) -> Self {
        Adam {
            mv: vec![0.0; 2 * n],
            step: 0,
            betas: (0.9, 0.99),
            eps: 1e-8,
            dense: std::env::var_os("NERFLEX_DENSE_ADAM").is_some(),
        }
    }

    /// One step: sums the workers' gradients of every touched slot,
    /// updates `values` with learning rate `lr_density` for the record's
    /// first float and `lr_color` for the rest, and clears the slots'
    /// touched flags (the gradient records are left as they are: a
    /// worker's next touch overwrites them, see `GradBuf`).
    pub fn step(
        &mut self,
        values: &mut [f32],
        len: usize,
        grads: &mut [GradBuf],
        lr_density: f32,
        lr_color: f32,
    ) {
        if len == 0 || len > 32 {
            // Records are 4, 16 or 32 floats (SH degree 0–2).
            return;
        }
        self.step += 1;
        let (b1, b2) = self.betas;
        let bc1 = 1.0 - b1.powi(self.step as i32);
        let bc2 = 1.0 - b2.powi(self.step as i32);
        let eps = self.eps;
        let dense = self.dense;
        // Blocks of slots, each with its slice of every worker's buffer,
        // so the pass is parallel.
        let workers = grads.len();
        let mut blocks: Vec<Vec<(&[f32], &mut [bool])>> = Vec::new();
        for g in grads.iter_mut() {
            for (b, (gc, mc)) in g
                .grad
                .chunks(BLOCK * len)
                .zip(g.mark.chunks_mut(BLOCK))
                .enumerate()
            {
                if blocks.len() <= b {
                    blocks.push(Vec::with_capacity(workers));
                }
                blocks[b].push((gc, mc));
            }
        }
        values
            .par_chunks_mut(BLOCK * len)
            .zip(self.mv.par_chunks_mut(BLOCK * 2 * len))
            .zip(blocks.into_par_iter())
            .for_each(|((val, mv), mut bufs)| {
                let slots = val.len() / len;
                // The block's touched slots, in increasing order.
                let mut idx = [0u16; BLOCK];
                let mut n = 0;
                for o in 0..slots {
                    if dense
                        || bufs
                            .iter()
                            .any(|(_, mk)| mk.get(o).copied().unwrap_or(false))
                    {
                        if let Some(at) = idx.get_mut(n) {
                            *at = o as u16;
                            n += 1;
                        }
                    }
                }
                let idx = &idx[..n];
                for (k, &o) in idx.iter().enumerate() {
                    if let Some(&a) = idx.get(k + AHEAD) {
                        let a = a as usize;
                        prefetch(val.get(a * len..(a + 1) * len));
                        prefetch(mv.get(2 * a * len..2 * (a + 1) * len));
                        for (gb, mk) in bufs.iter() {
                            if mk.get(a).copied().unwrap_or(false) {
                                prefetch(gb.get(a * len..(a + 1) * len));
                            }
                        }
                    }
                    let o = o as usize;
                    let mut g = [0.0f32; 32];
                    let g = &mut g[..len];
                    for (gb, mk) in bufs.iter_mut() {
                        if let (Some(m), Some(r)) = (mk.get_mut(o), gb.get(o * len..(o + 1) * len))
                        {
                            if *m {
                                for (acc, x) in g.iter_mut().zip(r) {
                                    *acc += *x;
                                }
                                *m = false;
                            }
                        }
                    }
                    let (Some(x), Some(mv)) = (
                        val.get_mut(o * len..(o + 1) * len),
                        mv.get_mut(2 * o * len..2 * (o + 1) * len),
                    ) else {
                        continue;
                    };
                    let (m, v) = mv.split_at_mut(len);
                    for (i, (((x, m), v), g)) in
                        x.iter_mut().zip(m).zip(v).zip(g.iter()).enumerate()
                    {
                        let lr = if i == 0 { lr_density } else { lr_color };
                        *m = b1 * *m + (1.0 - b1) * g;
                        *v = b2 * *v + (1.0 - b2) * g * g;
                        *x -= lr * (*m / bc1) / ((*v / bc2).sqrt() + eps);
                    }
                }
            });
    }
}

/// Asks for the cache lines of `r` (no-op off x86-64 or for `None`).
#[inline(always)]
pub(super) fn prefetch<T>(r: Option<&[T]>) {
    if let Some(r) = r {
        crate::prefetch::prefetch(r);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Minimises a quadratic through sparse gradients split over two
    /// workers; untouched slots stay as they were.
    #[test]
    fn converges_on_a_quadratic_and_leaves_untouched_slots() {
        let len = 2;
        let mut values = vec![5.0, -3.0, 7.0, 7.0];
        let mut adam = Adam::new(values.len());
        let mut bufs = vec![GradBuf::new(2, len), GradBuf::new(2, len)];
        for _ in 0..2000 {
            // Worker 0 sees half the gradient of slot 0, worker 1 the rest.
            for (w, buf) in bufs.iter_mut().enumerate() {
                buf.mark[0] = true;
                for (i, (g, x)) in buf.grad.iter_mut().zip(&values).take(len).enumerate() {
                    *g = *x - (w as f32 + i as f32);
                }
                // Slot 1 is never touched: its stale record is not read.
                buf.grad[len..].fill(100.0);
            }
            adam.step(&mut values, len, &mut bufs, 0.05, 0.05);
            assert!(bufs.iter().all(|b| !b.mark.iter().any(|&m| m)));
        }
        // Minimum of Σ_w (x − (w + i))² is the mean, i + 0.5.
        assert!((values[0] - 0.5).abs() < 1e-2, "{values:?}");
        assert!((values[1] - 1.5).abs() < 1e-2, "{values:?}");
        assert_eq!(&values[2..], &[7.0, 7.0]);
    }

    /// Over several blocks and steps with a random sparse touch pattern,
    /// the pass equals a plain per-slot Adam on the summed gradients.
    #[test]
    fn matches_a_plain_adam_over_blocks() {
        let len = 4;
        let slots = 2 * BLOCK + 77;
        let mut x = 99u64;
        let mut rnd = move || {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1442695040888963407);
            (x >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut values: Vec<f32> = (0..slots * len).map(|_| rnd() - 0.5).collect();
        let mut plain = values.clone();
        let (mut m, mut v) = (vec![0.0f32; slots * len], vec![0.0f32; slots * len]);
        let mut adam = Adam::new(values.len());
        let mut bufs = vec![GradBuf::new(slots, len), GradBuf::new(slots, len)];
        for step in 1..=3 {
            let mut sum = vec![0.0f32; slots * len];
            let mut touched = vec![false; slots];
            for b in bufs.iter_mut() {
                for s in 0..slots {
                    if rnd() < 0.2 {
                        let g: Vec<f32> = (0..len).map(|_| rnd() - 0.5).collect();
                        let r = b.record_mut(s, len).unwrap();
                        for i in 0..len {
                            r[i] += g[i];
                            sum[s * len + i] += g[i];
                        }
                        touched[s] = true;
                    }
                }
            }
            adam.step(&mut values, len, &mut bufs, 0.1, 0.02);
            let (b1, b2) = adam.betas;
            let (bc1, bc2) = (1.0 - b1.powi(step), 1.0 - b2.powi(step));
            for s in (0..slots).filter(|&s| touched[s]) {
                for i in 0..len {
                    let k = s * len + i;
                    let g = 0.0 + sum[k];
                    let lr = if i == 0 { 0.1 } else { 0.02 };
                    m[k] = b1 * m[k] + (1.0 - b1) * g;
                    v[k] = b2 * v[k] + (1.0 - b2) * g * g;
                    plain[k] -= lr * (m[k] / bc1) / ((v[k] / bc2).sqrt() + adam.eps);
                }
            }
            assert_eq!(values, plain, "step {step}");
        }
    }
}
