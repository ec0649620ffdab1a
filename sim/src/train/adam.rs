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
    /// first float and `lr_color` for the rest, and clears the buffers.
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
        let shared: &[GradBuf] = grads;
        // Dense walk over slots, but a touched-flag test is all an
        // untouched slot costs (one byte per worker).
        values
            .par_chunks_mut(len)
            .zip(self.m.par_chunks_mut(len))
            .zip(self.v.par_chunks_mut(len))
            .enumerate()
            .with_min_len(4096)
            .for_each(|(s, ((val, m), v))| {
                if !dense && !shared.iter().any(|g| g.mark[s]) {
                    return;
                }
                for i in 0..len {
                    let mut g = 0.0;
                    for buf in shared {
                        g += buf.grad[s * len + i];
                    }
                    let lr = if i == 0 { lr_density } else { lr_color };
                    m[i] = b1 * m[i] + (1.0 - b1) * g;
                    v[i] = b2 * v[i] + (1.0 - b2) * g * g;
                    let mh = m[i] / bc1;
                    let vh = v[i] / bc2;
                    val[i] -= lr * mh / (vh.sqrt() + eps);
                }
            });
        grads.par_iter_mut().for_each(|g| g.clear(len));
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
                buf.touched.push(0);
                for i in 0..len {
                    buf.grad[i] = 0.5 * 2.0 * (values[i] - (w as f32 + i as f32)) / 1.0;
                }
            }
            adam.step(&mut values, len, &mut bufs, 0.05, 0.05);
            assert!(bufs
                .iter()
                .all(|b| b.touched.is_empty() && b.grad.iter().all(|&g| g == 0.0)));
        }
        // Minimum of Σ_w (x − (w + i))² is the mean, i + 0.5.
        assert!((values[0] - 0.5).abs() < 1e-2, "{values:?}");
        assert!((values[1] - 1.5).abs() < 1e-2, "{values:?}");
        assert_eq!(&values[2..], &[7.0, 7.0]);
    }
}
