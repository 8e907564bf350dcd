//! The network body of SPEC §8 (the thesis' Fig. 4.3, ML-Agents' "simple"
//! visual encoder), shared by every actor and critic, as a Burn Config +
//! Module pair.
//!
//! # Shapes
//! * grid `[B, 18, 20, 34]` → zero-pad the azimuth by one column each side
//!   (the blind sector behind, see [`crate::kernels::geometry`]) → `[B, 18, 20, 36]`
//!   → Conv 18→16, 8×8, stride 4, LeakyReLU → `[B, 16, 4, 8]`
//!   → Conv 16→32, 4×4, stride 2, LeakyReLU → `[B, 32, 1, 3]` → flatten `[B, 96]`
//!   → Dense `hidden`, LeakyReLU → the encoding `[B, hidden]`;
//! * concatenated with the vector observation `[B, 6]` (and `extra_inputs`,
//!   e.g. SAC's action) → `layers` × Dense `hidden` with Swish → `[B, hidden]`.
//!
//! On the Flex backend the encoder and the Swish layers run as the
//! hand-written kernels ([`crate::kernels`]); elsewhere (and in the parity
//! tests) as Burn's `Conv2d`, `Linear`, `leaky_relu` and `silu`.

use crate::kernels::dense::DensePack;
use crate::kernels::encoder::EncoderPack;
use crate::kernels::geometry::*;
use crate::kernels::infer::{InferNet, TrunkPack};
use crate::kernels::ops::{self, EncoderLayers, Grids};
use crate::tensor::to_vec;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Linear, LinearConfig, PaddingConfig2d};
use burn::prelude::*;
use burn::tensor::activation::{leaky_relu, silu};
use deepfoids_env::VECTOR_OBS;

/// The encoder layout of this build, recorded in every checkpoint. Layout 1
/// was the stock encoder on 34 columns (blind to columns 28–33); layout 2
/// pads the azimuth (issue 11 item 2).
pub const ENCODER_LAYOUT: u32 = 2;

/// Number of action dimensions `(Δv, Δθx, Δθy)`.
pub const ACTIONS: usize = 3;

/// The visual encoder and the dense trunk (each actor and critic has its own).
#[derive(Config, Debug)]
pub struct BodyConfig {
    /// Width of every dense layer. SPEC §8: 128.
    #[config(default = 128)]
    pub hidden: usize,
    /// Dense Swish layers after the concatenation. SPEC §8: 4.
    #[config(default = 4)]
    pub layers: usize,
    /// Negative slope of the LeakyReLUs (PyTorch's default, as ML-Agents).
    #[config(default = 0.01)]
    pub leaky_slope: f64,
    /// Run on the hand-written kernels where the backend has them (Flex).
    /// Same weights, same results up to rounding; off: Burn's own layers.
    #[config(default = true)]
    pub kernels: bool,
    /// Inputs concatenated after the vector observation (SAC's critics take
    /// the action there, as ML-Agents' value networks do). 0 for actors.
    #[config(default = 0)]
    pub extra_inputs: usize,
}

#[derive(Module, Debug)]
pub struct Body {
    pub conv1: Conv2d,
    pub conv2: Conv2d,
    pub fc_grid: Linear,
    pub trunk: Vec<Linear>,
    leaky_slope: f64,
    kernels: bool,
}

impl BodyConfig {
    pub fn init(&self, device: &Device) -> Body {
        let mut trunk = Vec::with_capacity(self.layers);
        let mut d_in = self.hidden + VECTOR_OBS + self.extra_inputs;
        for _ in 0..self.layers {
            trunk.push(LinearConfig::new(d_in, self.hidden).init(device));
            d_in = self.hidden;
        }
        Body {
            conv1: Conv2dConfig::new([C_IN, C1], [K1, K1])
                .with_stride([S1, S1])
                .with_padding(PaddingConfig2d::Explicit(0, AZ_PAD, 0, AZ_PAD))
                .init(device),
            conv2: Conv2dConfig::new([C1, C2], [K2, K2])
                .with_stride([S2, S2])
                .init(device),
            fc_grid: LinearConfig::new(CONV_FLAT, self.hidden).init(device),
            trunk,
            leaky_slope: self.leaky_slope,
            kernels: self.kernels,
        }
    }
}

impl Body {
    pub fn hidden(&self) -> usize {
        self.fc_grid.weight.dims()[1]
    }

    pub fn slope(&self) -> f64 {
        self.leaky_slope
    }

    /// Whether this body tries the hand-written kernels.
    pub fn uses_kernels(&self) -> bool {
        self.kernels
    }

    fn layers(&self) -> EncoderLayers<'_> {
        EncoderLayers {
            conv1: &self.conv1,
            conv2: &self.conv2,
            fc: &self.fc_grid,
            slope: self.leaky_slope as f32,
        }
    }

    /// # Shapes
    /// grids `[B, 18, 20, 34]`, vector `[B, 6 + extra_inputs]` → `[B, hidden]`.
    pub fn forward(&self, grids: &Grids, vector: Tensor<2>) -> Tensor<2> {
        self.trunk_forward(self.encode(grids), vector)
    }

    /// The visual encoder: grids `[B, 18, 20, 34]` → `[B, hidden]`.
    pub fn encode(&self, grids: &Grids) -> Tensor<2> {
        Self::encode_many(&[self], grids).remove(0)
    }

    /// Several bodies' encoders on the same grids (on the kernels: unpacked
    /// and convolved once for all of them).
    pub fn encode_many(bodies: &[&Body], grids: &Grids) -> Vec<Tensor<2>> {
        if bodies.iter().all(|b| b.kernels) {
            let layers: Vec<_> = bodies.iter().map(|b| b.layers()).collect();
            if let Some(out) = ops::encode(&layers, grids) {
                let [n, _] = out.dims();
                return bodies
                    .iter()
                    .scan(0, |at, b| {
                        let h = b.hidden();
                        let part = out.clone().slice([0..n, *at..*at + h]);
                        *at += h;
                        Some(part)
                    })
                    .collect();
            }
        }
        let dev = bodies[0].fc_grid.weight.val().device();
        let grid = grids.to_tensor(&dev);
        bodies
            .iter()
            .map(|b| b.encode_reference(grid.clone()))
            .collect()
    }

    /// The encoder on Burn's own layers (the reference of the kernels).
    pub fn encode_reference(&self, grid: Tensor<4>) -> Tensor<2> {
        let x1 = leaky_relu(self.conv1.forward(grid), self.leaky_slope);
        let x2 = leaky_relu(self.conv2.forward(x1), self.leaky_slope);
        let x: Tensor<2> = x2.flatten(1, 3);
        leaky_relu(self.fc_grid.forward(x), self.leaky_slope)
    }

    /// The dense trunk on encodings `[B, hidden]` and vectors
    /// `[B, 6 + extra_inputs]` → `[B, hidden]`.
    pub fn trunk_forward(&self, encoded: Tensor<2>, vector: Tensor<2>) -> Tensor<2> {
        let mut x = Tensor::cat(vec![encoded, vector], 1);
        for layer in &self.trunk {
            x = match self
                .kernels
                .then(|| ops::dense_silu(x.clone(), layer))
                .flatten()
            {
                Some(y) => y,
                None => silu(layer.forward(x)),
            };
        }
        x
    }

    /// The trunk on Burn's own layers (the reference of the kernels).
    pub fn trunk_reference(&self, encoded: Tensor<2>, vector: Tensor<2>) -> Tensor<2> {
        let mut x = Tensor::cat(vec![encoded, vector], 1);
        for layer in &self.trunk {
            x = silu(layer.forward(x));
        }
        x
    }

    /// The weights of several bodies' encoders for the fused forward.
    pub fn encoder_pack(bodies: &[&Body]) -> EncoderPack {
        let k = bodies.len();
        let mut w1 = Vec::with_capacity(C1 * k * PATCH1);
        let mut b1 = Vec::with_capacity(C1 * k);
        let (mut w2, mut b2, mut wfc, mut bfc) = (vec![], vec![], vec![], vec![]);
        for b in bodies {
            let bias = |c: &Conv2d| c.bias.as_ref().map_or_else(Vec::new, |p| to_vec(p.val()));
            w1.extend(to_vec(b.conv1.weight.val()));
            b1.extend(bias(&b.conv1));
            w2.push(to_vec(b.conv2.weight.val()));
            b2.push(bias(&b.conv2));
            let fc = dense_pack(&b.fc_grid);
            wfc.push(fc.w);
            bfc.push(fc.b);
        }
        EncoderPack::new(
            k,
            bodies[0].hidden(),
            bodies[0].leaky_slope as f32,
            w1,
            b1,
            w2,
            b2,
            wfc,
            bfc,
        )
    }

    /// This body's trunk and `head` for the fused forward.
    pub fn trunk_pack(&self, head: Option<&Linear>) -> TrunkPack {
        TrunkPack {
            layers: self.trunk.iter().map(dense_pack).collect(),
            head: head.map(dense_pack),
        }
    }
}

/// A `Linear`'s weights `[in, out]` and bias (zeros without one) as plain floats.
pub fn dense_pack(l: &Linear) -> DensePack {
    let [d_in, d_out] = l.weight.dims();
    DensePack {
        d_in,
        d_out,
        w: to_vec(l.weight.val()),
        b: l.bias
            .as_ref()
            .map_or_else(|| vec![0.0; d_out], |b| to_vec(b.val())),
    }
}

/// The fused forward of several bodies on the same grids, each with its head.
pub fn infer_net(parts: &[(&Body, Option<&Linear>)]) -> InferNet {
    let bodies: Vec<&Body> = parts.iter().map(|p| p.0).collect();
    InferNet {
        encoder: Body::encoder_pack(&bodies),
        trunks: parts.iter().map(|(b, h)| b.trunk_pack(*h)).collect(),
    }
}

/// A linear layer whose weights are scaled by `scale` and whose bias is zero;
/// the new values are leaves (detached, requiring gradients where the old
/// ones did). Policy heads start so ("small last layer", CleanRL).
pub fn small_linear(d_in: usize, d_out: usize, scale: f32, device: &Device) -> Linear {
    let mut l = LinearConfig::new(d_in, d_out).init(device);
    let leaf = |t: Tensor<2>| {
        let grad = t.is_require_grad();
        let t = t.mul_scalar(scale).detach();
        if grad { t.require_grad() } else { t }
    };
    l.weight = l.weight.map(leaf);
    l.bias = l.bias.map(|b| {
        b.map(|t| {
            let z = t.zeros_like();
            if t.is_require_grad() {
                z.require_grad()
            } else {
                z
            }
        })
    });
    l
}
