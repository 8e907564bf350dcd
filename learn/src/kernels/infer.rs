//! The fused forward without autodiff, for acting: `K` bodies on the same
//! grids (the grids are unpacked and convolved once for all of them), each
//! body's trunk and a linear head, on weights copied out of the Burn modules
//! (a snapshot, refreshed after each update). Rollouts, evaluation and SAC's
//! targets run here; training runs through [`super::ops`].

use super::dense::DensePack;
use super::encoder::{EncoderPack, GridsRef};
use super::{TASK, sgemm};
use rayon::prelude::*;

/// One body's trunk (Swish layers) and its linear head.
#[derive(Clone, Debug)]
pub struct TrunkPack {
    pub layers: Vec<DensePack>,
    /// A linear head (no activation), if any.
    pub head: Option<DensePack>,
}

impl TrunkPack {
    /// Width of the output: the head's, else the last layer's.
    pub fn out_width(&self) -> usize {
        match (&self.head, self.layers.last()) {
            (Some(h), _) => h.d_out,
            (None, Some(l)) => l.d_out,
            (None, None) => 0,
        }
    }

    /// Width of the first layer's input.
    pub fn in_width(&self) -> usize {
        self.layers.first().map_or(0, |l| l.d_in)
    }
}

/// `K` bodies for the fused forward.
#[derive(Clone, Debug)]
pub struct InferNet {
    pub encoder: EncoderPack,
    pub trunks: Vec<TrunkPack>,
}

/// The inputs of a trunk after the encoding: `[vector | extra]` per sample.
#[derive(Clone, Copy, Debug)]
pub struct TrunkInputs<'a> {
    /// `[n, 6]`.
    pub vectors: &'a [f32],
    /// `[n, width]` (e.g. SAC's actions), or empty.
    pub extra: &'a [f32],
    pub extra_width: usize,
}

impl InferNet {
    /// The encodings `[n, K·hidden]`.
    pub fn encode(&self, grids: GridsRef<'_>) -> Vec<f32> {
        let mut out = vec![0.0; grids.len() * self.encoder.k * self.encoder.hidden];
        self.encoder.infer(grids, &mut out);
        out
    }

    /// Body `b`'s trunk and head on encodings `enc` (`[n, K·hidden]`, from
    /// [`encode`](Self::encode)) and the trunk inputs: `[n, out_width]`.
    pub fn trunk(&self, b: usize, enc: &[f32], inputs: TrunkInputs<'_>) -> Vec<f32> {
        let (k, hid) = (self.encoder.k, self.encoder.hidden);
        let n = enc.len() / (k * hid);
        let trunk = &self.trunks[b];
        let vw = inputs.vectors.len() / n.max(1);
        let ew = inputs.extra_width;
        let width = trunk.out_width();
        let mut out = vec![0.0; n * width];
        out.par_chunks_mut(TASK * width)
            .enumerate()
            .for_each(|(t, out)| {
                let first = t * TASK;
                let m = out.len() / width;
                // x = [encoding | vector | extra]
                let d0 = hid + vw + ew;
                let mut x = vec![0.0f32; m * d0];
                for i in 0..m {
                    let s = first + i;
                    let row = &mut x[i * d0..(i + 1) * d0];
                    row[..hid]
                        .copy_from_slice(&enc[s * k * hid + b * hid..s * k * hid + (b + 1) * hid]);
                    row[hid..hid + vw].copy_from_slice(&inputs.vectors[s * vw..(s + 1) * vw]);
                    if ew > 0 {
                        row[hid + vw..].copy_from_slice(&inputs.extra[s * ew..(s + 1) * ew]);
                    }
                }
                for layer in &trunk.layers {
                    let mut y = vec![0.0f32; m * layer.d_out];
                    layer.silu_rows(&x, m, &mut y);
                    x = y;
                }
                match &trunk.head {
                    Some(h) => h.affine(&x, h.d_in, m, out),
                    None => out.copy_from_slice(&x),
                }
            });
        out
    }

    /// Every body's output on the same grids and vectors (no extra inputs).
    pub fn forward(&self, grids: GridsRef<'_>, vectors: &[f32]) -> Vec<Vec<f32>> {
        let enc = self.encode(grids);
        let inputs = TrunkInputs {
            vectors,
            extra: &[],
            extra_width: 0,
        };
        (0..self.trunks.len())
            .map(|b| self.trunk(b, &enc, inputs))
            .collect()
    }
}

/// `y = x·W + b` for a small linear layer, in plain floats (heads applied
/// outside the fused pass).
pub fn linear(x: &[f32], layer: &DensePack) -> Vec<f32> {
    let n = x.len() / layer.d_in;
    let mut y = vec![0.0; n * layer.d_out];
    sgemm(
        n,
        layer.d_out,
        layer.d_in,
        x,
        [layer.d_in, 1],
        &layer.w,
        [layer.d_out, 1],
        &mut y,
        [layer.d_out, 1],
        false,
    );
    super::add_bias(&mut y, n, layer.d_out, &layer.b);
    y
}
