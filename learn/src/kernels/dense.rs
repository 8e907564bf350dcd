//! A dense layer with Swish (SiLU) on flat slices — the trunk of SPEC §8:
//! `z = x·W + b`, `y = z·σ(z)`; backward `dz = dy·σ(z)·(1 + z·(1 − σ(z)))`,
//! `dW = xᵀ·dz`, `db = Σ dz`, `dx = dz·Wᵀ`. Burn's `Linear` layout: W `[in, out]`.

use super::{TASK, par_tasks, sgemm, sum_rows};
use rayon::prelude::*;

#[inline]
fn sigmoid(z: f32) -> f32 {
    1.0 / (1.0 + (-z).exp())
}

/// Weights of a dense layer, copied out of a Burn `Linear`.
#[derive(Clone, Debug)]
pub struct DensePack {
    pub d_in: usize,
    pub d_out: usize,
    /// `[d_in, d_out]`.
    pub w: Vec<f32>,
    /// `[d_out]`.
    pub b: Vec<f32>,
}

/// Gradients of a [`DensePack`].
#[derive(Clone, Debug)]
pub struct DenseGrads {
    pub w: Vec<f32>,
    pub b: Vec<f32>,
}

impl DensePack {
    /// `z = x·W + b` for `n` rows of `x` (row stride `x_rs`) into `z` `[n, d_out]`.
    pub fn affine(&self, x: &[f32], x_rs: usize, n: usize, z: &mut [f32]) {
        sgemm(
            n,
            self.d_out,
            self.d_in,
            x,
            [x_rs, 1],
            &self.w,
            [self.d_out, 1],
            z,
            [self.d_out, 1],
            false,
        );
        super::add_bias(z, n, self.d_out, &self.b);
    }

    /// Swish layer forward for a batch `x` `[n, d_in]`: `(y, z)`, both `[n, d_out]`.
    pub fn forward_silu(&self, x: &[f32]) -> (Vec<f32>, Vec<f32>) {
        let n = x.len() / self.d_in;
        let (mut y, mut z) = (vec![0.0; n * self.d_out], vec![0.0; n * self.d_out]);
        y.par_chunks_mut(TASK * self.d_out)
            .zip(z.par_chunks_mut(TASK * self.d_out))
            .enumerate()
            .for_each(|(t, (y, z))| {
                let rows = y.len() / self.d_out;
                let xs = &x[t * TASK * self.d_in..];
                self.affine(xs, self.d_in, rows, z);
                for (o, &v) in y.iter_mut().zip(z.iter()) {
                    *o = v * sigmoid(v);
                }
            });
        (y, z)
    }

    /// Swish layer in place on a task's rows: `x` `[n, d_in]` → `y` `[n, d_out]`.
    pub fn silu_rows(&self, x: &[f32], n: usize, y: &mut [f32]) {
        self.affine(x, self.d_in, n, y);
        for v in y[..n * self.d_out].iter_mut() {
            *v *= sigmoid(*v);
        }
    }

    /// Swish layer backward from `dy` `[n, d_out]` with the forward's `x` and
    /// `z`: the weight gradients and, with `input_grad`, `dx` `[n, d_in]`.
    pub fn backward_silu(
        &self,
        x: &[f32],
        z: &[f32],
        dy: &[f32],
        input_grad: bool,
    ) -> (DenseGrads, Option<Vec<f32>>) {
        let (di, dout) = (self.d_in, self.d_out);
        let n = x.len() / di;
        let task = |t: usize, dx: Option<&mut [f32]>| {
            let (first, m) = (t * TASK, TASK.min(n - t * TASK));
            let mut dz = vec![0.0f32; m * dout];
            for (i, d) in dz.iter_mut().enumerate() {
                let zv = z[first * dout + i];
                let s = sigmoid(zv);
                *d = dy[first * dout + i] * s * (1.0 + zv * (1.0 - s));
            }
            let mut g = DenseGrads {
                w: vec![0.0; di * dout],
                b: vec![0.0; dout],
            };
            // dW [in, out] = xᵀ [in, m] · dz [m, out]
            sgemm(
                di,
                dout,
                m,
                &x[first * di..],
                [1, di],
                &dz,
                [dout, 1],
                &mut g.w,
                [dout, 1],
                false,
            );
            sum_rows(&dz, m, dout, &mut g.b);
            if let Some(dx) = dx {
                // dx [m, in] = dz [m, out] · Wᵀ [out, in]
                sgemm(
                    m,
                    di,
                    dout,
                    &dz,
                    [dout, 1],
                    &self.w,
                    [1, dout],
                    dx,
                    [di, 1],
                    false,
                );
            }
            g
        };
        let (parts, dx) = par_tasks(n, di, input_grad, task);
        let mut parts = parts.into_iter();
        let mut g = parts.next().unwrap_or(DenseGrads {
            w: vec![0.0; di * dout],
            b: vec![0.0; dout],
        });
        for p in parts {
            g.w.iter_mut().zip(&p.w).for_each(|(a, b)| *a += b);
            g.b.iter_mut().zip(&p.b).for_each(|(a, b)| *a += b);
        }
        (g, dx)
    }
}
