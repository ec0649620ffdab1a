//! Sparse ("lazy") Adam over the grid's records: only the slots some
//! worker touched in this step are read, updated and cleared, so a step
//! costs what the batch touched, not the size of the grid.

use rayon::prelude::*;

use super::march::GradBuf;

/// Adam's moments, one pair per stored float.
#[derive(Debug, Clone)]
pub struct Adam {
    m: Vec<f32>,
    v: Vec<f32>,
    step: u32,
    /// β₁, β₂.
    pub betas: (f32, f32),
    /// ε.
    pub eps: f32,
    /// Update every slot each step (moments carry on without a
    /// gradient), not only the touched ones.
    pub dense: bool,
}

impl Adam {
    /// Zero moments for `n` floats.
    pub fn new(n: usize) -> Self {
        Adam {
            m: vec![0.0; n],
            v: vec![0.0; n],
            step: 0,
            betas: (0.9, 0.99),
            eps: 1e-8,
            dense: std::env::var_os("NERFLEX_DENSE_ADAM").is_some(),
        }
    }

    /// One step: sums the workers' gradients of every touched slot,
    /// updates `values` with learning rate `lr_density` for the record's
    /// first float and `lr_color` for the rest, and zeroes the buffers in
    /// the same pass (the lines are in cache then; a separate clear was
    /// 6 % of a 256³ step).
    pub fn step(
        &mut self,
        values: &mut [f32],
        len: usize,
        grads: &mut [GradBuf],
        lr_density: f32,
        lr_color: f32,
    ) {
        self.step += 1;
        let (b1, b2) = self.betas;
        let bc1 = 1.0 - b1.powi(self.step as i32);
        let bc2 = 1.0 - b2.powi(self.step as i32);
        let eps = self.eps;
        let dense = self.dense;
        // Blocks of slots, each with its slice of every worker's buffer,
        // so the pass is parallel and zeroes as it reads.
        const BLOCK: usize = 2048;
        let workers = grads.len();
        let mut blocks: Vec<Vec<(&mut [f32], &mut [bool])>> = Vec::new();
        for g in grads.iter_mut() {
            for (b, (gc, mc)) in g
                .grad
                .chunks_mut(BLOCK * len)
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
            .zip(self.m.par_chunks_mut(BLOCK * len))
            .zip(self.v.par_chunks_mut(BLOCK * len))
            .zip(blocks.into_par_iter())
            .for_each(|(((val, m), v), mut bufs)| {
                let slots = val.len() / len;
                for s in 0..slots {
                    let touched = bufs.iter().any(|(_, mk)| mk[s]);
                    if !dense && !touched {
                        continue;
                    }
                    let r = s * len..(s + 1) * len;
                    // Records are 4, 16 or 32 floats (SH degree 0–2).
                    let mut g = [0.0f32; 32];
                    let g = &mut g[..len.min(32)];
                    if touched {
                        for (gb, mk) in bufs.iter_mut() {
                            if mk[s] {
                                for (acc, x) in g.iter_mut().zip(&mut gb[r.clone()]) {
                                    *acc += *x;
                                    *x = 0.0;
                                }
                                mk[s] = false;
                            }
                        }
                    }
                    for (i, ((x, m), v)) in val[r.clone()]
                        .iter_mut()
                        .zip(&mut m[r.clone()])
                        .zip(&mut v[r])
                        .enumerate()
                    {
                        let g = g[i];
                        let lr = if i == 0 { lr_density } else { lr_color };
                        *m = b1 * *m + (1.0 - b1) * g;
                        *v = b2 * *v + (1.0 - b2) * g * g;
                        *x -= lr * (*m / bc1) / ((*v / bc2).sqrt() + eps);
                    }
                }
            });
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
            }
            adam.step(&mut values, len, &mut bufs, 0.05, 0.05);
            assert!(bufs
                .iter()
                .all(|b| !b.mark.iter().any(|&m| m) && b.grad.iter().all(|&g| g == 0.0)));
        }
        // Minimum of Σ_w (x − (w + i))² is the mean, i + 0.5.
        assert!((values[0] - 0.5).abs() < 1e-2, "{values:?}");
        assert!((values[1] - 1.5).abs() < 1e-2, "{values:?}");
        assert_eq!(&values[2..], &[7.0, 7.0]);
    }
}
