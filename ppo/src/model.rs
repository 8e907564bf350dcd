//! The policy network of SPEC §8 (the thesis' Fig. 4.3, ML-Agents' "simple"
//! visual encoder), as Burn Config + Module pairs.
//!
//! # Shapes
//! * grid `[B, 18, 20, 34]` → Conv 18→16, 8×8, stride 4, LeakyReLU → `[B, 16, 4, 7]`
//!   → Conv 16→32, 4×4, stride 2, LeakyReLU → `[B, 32, 1, 2]` → flatten `[B, 64]`
//!   → Dense 128, LeakyReLU;
//! * concatenated with the vector observation `[B, 6]` → `[B, 134]` → 4 × Dense 128 with Swish;
//! * actor: linear head `[B, 3]` (the Gaussian mean) and a learned state-independent
//!   log-std `[3]`; critic: its own body and a linear head `[B, 1]`.
//!
//! Initialisation: Burn's defaults (Kaiming uniform) everywhere, except the
//! actor's mean head, scaled by 0.01 with a zero bias so the first policy's
//! means are near zero (the "small last layer" detail of CleanRL's PPO).

use burn::module::Param;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::{leaky_relu, silu};
use deepfoids_env::VECTOR_OBS;
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};

/// Number of action dimensions `(Δv, Δθx, Δθy)`.
pub const ACTIONS: usize = 3;

const fn conv_out(n: usize, k: usize, s: usize) -> usize {
    (n - k) / s + 1
}

/// Width of the flattened convolution output: 32 × 1 × 2.
pub const CONV_FLAT: usize =
    32 * conv_out(conv_out(EL_CELLS, 8, 4), 4, 2) * conv_out(conv_out(AZ_CELLS, 8, 4), 4, 2);

/// The visual encoder and the dense trunk shared by actor and critic (each has its own).
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
    /// Run the convolutions as GEMMs ([`conv1_gemm`], [`conv2_gemm`]): much faster
    /// on the flex backend, slower on ndarray. Same weights, same results.
    #[config(default = true)]
    pub gemm_conv: bool,
    /// Inputs concatenated after the vector observation (SAC's critics take the
    /// action there, as ML-Agents' value networks do). 0 for PPO.
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
    gemm_conv: bool,
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
            conv1: Conv2dConfig::new([STACKED_CHANNELS, 16], [8, 8])
                .with_stride([4, 4])
                .init(device),
            conv2: Conv2dConfig::new([16, 32], [4, 4])
                .with_stride([2, 2])
                .init(device),
            fc_grid: LinearConfig::new(CONV_FLAT, self.hidden).init(device),
            trunk,
            leaky_slope: self.leaky_slope,
            gemm_conv: self.gemm_conv,
        }
    }
}

/// Conv 18→16, 8×8, stride 4 on `[B, 18, 20, 34]` → `[B, 16, 4, 7]`, as matrix
/// products on `conv`'s own weights (`[16, 18, 8, 8]`, the usual layout).
///
/// Stride 4 is half the kernel, so the input splits into 4×4 blocks
/// (`[B, C, 5, 4, 8, 4]`, the last two columns unused, as in the convolution)
/// and each output is the sum over the 2×2 neighbouring blocks `(bi, bj)` of a
/// block times the matching quarter of the kernel: four GEMMs of
/// `[B·28, C·16] × [C·16, 16]`. Same numbers as `Conv2d` (up to rounding),
/// several times faster forward and backward on the CPU backends.
pub fn conv1_gemm(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [b, c, _, _] = x.dims();
    let [o, _, _, _] = conv.weight.val().dims();
    let blocks: Tensor<6> = x
        .slice([0..b, 0..c, 0..20, 0..32])
        .reshape([b, c, 5, 4, 8, 4]);
    let weight = conv.weight.val();
    let mut out: Option<Tensor<2>> = None;
    for bi in 0..2 {
        for bj in 0..2 {
            // [B, C, i, r, j, s] → [B, i, j, C, r, s] → [B·28, C·16]
            let a: Tensor<2> = blocks
                .clone()
                .slice([0..b, 0..c, bi..bi + 4, 0..4, bj..bj + 7, 0..4])
                .permute([0, 2, 4, 1, 3, 5])
                .reshape([b * 28, c * 16]);
            let w: Tensor<2> = weight
                .clone()
                .slice([0..o, 0..c, 4 * bi..4 * bi + 4, 4 * bj..4 * bj + 4])
                .reshape([o, c * 16])
                .transpose();
            let term = a.matmul(w);
            out = Some(match out {
                Some(acc) => acc + term,
                None => term,
            });
        }
    }
    let mut out = out.expect("four terms");
    if let Some(bias) = &conv.bias {
        out = out + bias.val().unsqueeze();
    }
    out.reshape([b, 4, 7, o]).permute([0, 3, 1, 2])
}

/// Conv 16→32, 4×4, stride 2 on `[B, 16, 4, 7]` → `[B, 32, 1, 2]` as one GEMM of
/// the two patches (columns 0–3 and 2–5) against the weights `[32, 16·4·4]`.
pub fn conv2_gemm(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [b, c, _, _] = x.dims();
    let [o, _, _, _] = conv.weight.val().dims();
    let patch = |j: usize| -> Tensor<2> {
        x.clone()
            .slice([0..b, 0..c, 0..4, 2 * j..2 * j + 4])
            .reshape([b, c * 16])
    };
    let a = Tensor::cat(vec![patch(0), patch(1)], 0); // [2B, C·16], patch-major
    let w: Tensor<2> = conv.weight.val().reshape([o, c * 16]).transpose();
    let mut out = a.matmul(w); // [2B, O]
    if let Some(bias) = &conv.bias {
        out = out + bias.val().unsqueeze();
    }
    // [2, B, O] → [B, O, 1, 2]
    out.reshape([2, b, o])
        .permute([1, 2, 0])
        .reshape([b, o, 1, 2])
}

impl Body {
    /// # Shapes
    /// grid `[B, 18, 20, 34]`, vector `[B, 6 + extra_inputs]` → `[B, hidden]`.
    pub fn forward(&self, grid: Tensor<4>, vector: Tensor<2>) -> Tensor<2> {
        self.trunk_forward(self.encode(grid), vector)
    }

    /// The visual encoder: grid `[B, 18, 20, 34]` → `[B, hidden]`.
    pub fn encode(&self, grid: Tensor<4>) -> Tensor<2> {
        let (x1, x2): (Tensor<4>, Tensor<4>);
        if self.gemm_conv {
            x1 = leaky_relu(conv1_gemm(&self.conv1, grid), self.leaky_slope);
            x2 = leaky_relu(conv2_gemm(&self.conv2, x1), self.leaky_slope);
        } else {
            x1 = leaky_relu(self.conv1.forward(grid), self.leaky_slope);
            x2 = leaky_relu(self.conv2.forward(x1), self.leaky_slope);
        }
        let x: Tensor<2> = x2.flatten(1, 3);
        leaky_relu(self.fc_grid.forward(x), self.leaky_slope)
    }

    /// The dense trunk on encoded grids `[B, hidden]` and vectors
    /// `[B, 6 + extra_inputs]` → `[B, hidden]`.
    pub fn trunk_forward(&self, encoded: Tensor<2>, vector: Tensor<2>) -> Tensor<2> {
        let mut x = Tensor::cat(vec![encoded, vector], 1);
        for layer in &self.trunk {
            x = silu(layer.forward(x));
        }
        x
    }
}

/// Actor and critic, each with its own body.
#[derive(Config, Debug)]
pub struct ActorCriticConfig {
    #[config(default = "BodyConfig::new()")]
    pub body: BodyConfig,
    /// Initial log standard deviation of the Gaussian policy (0: σ = 1).
    #[config(default = 0.0)]
    pub init_log_std: f32,
}

#[derive(Module, Debug)]
pub struct ActorCritic {
    pub actor_body: Body,
    pub actor_mean: Linear,
    /// State-independent log standard deviation, `[3]`.
    pub log_std: Param<Tensor<1>>,
    pub critic_body: Body,
    pub critic_head: Linear,
}

impl ActorCriticConfig {
    pub fn init(&self, device: &Device) -> ActorCritic {
        let mut actor_mean = LinearConfig::new(self.body.hidden, ACTIONS).init(device);
        // Small last layer: means start near zero. The scaled values are new leaves
        // (detached, requiring gradients), not results of an operation on the old ones.
        let leaf = |t: Tensor<2>| {
            if t.is_require_grad() {
                t.detach().require_grad()
            } else {
                t.detach()
            }
        };
        actor_mean.weight = actor_mean.weight.map(|w| leaf(w.mul_scalar(0.01)));
        actor_mean.bias = actor_mean.bias.map(|b| {
            b.map(|t| {
                let z = t.zeros_like();
                if t.is_require_grad() {
                    z.require_grad()
                } else {
                    z
                }
            })
        });
        ActorCritic {
            actor_body: self.body.init(device),
            actor_mean,
            log_std: Param::from_tensor(Tensor::full([ACTIONS], self.init_log_std, device)),
            critic_body: self.body.init(device),
            critic_head: LinearConfig::new(self.body.hidden, 1).init(device),
        }
    }
}

impl ActorCritic {
    /// The Gaussian's mean `[B, 3]` and log-std `[3]`.
    pub fn actor(&self, grid: Tensor<4>, vector: Tensor<2>) -> (Tensor<2>, Tensor<1>) {
        (
            self.actor_mean
                .forward(self.actor_body.forward(grid, vector)),
            self.log_std.val(),
        )
    }

    /// The state value `[B]`.
    pub fn value(&self, grid: Tensor<4>, vector: Tensor<2>) -> Tensor<1> {
        self.critic_head
            .forward(self.critic_body.forward(grid, vector))
            .flatten(0, 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random(shape: [usize; 4], seed: u32, dev: &Device) -> Tensor<4> {
        let n: usize = shape.iter().product();
        let v: Vec<f32> = (0..n)
            .map(|i| {
                (((i as u32)
                    .wrapping_mul(2654435761)
                    .wrapping_add(seed.wrapping_mul(97))
                    >> 16) as f32
                    / 32768.0)
                    - 1.0
            })
            .collect();
        Tensor::from_data(TensorData::new(v, shape), dev)
    }

    fn max_diff<const D: usize>(a: Tensor<D>, b: Tensor<D>) -> f32 {
        (a - b).abs().max().into_scalar::<f32>()
    }

    /// The GEMM convolutions give `Conv2d`'s outputs and gradients.
    #[test]
    fn gemm_convolutions_match_conv2d() {
        let dev = Device::flex().autodiff();
        let conv1 = Conv2dConfig::new([18, 16], [8, 8])
            .with_stride([4, 4])
            .init(&dev);
        let conv2 = Conv2dConfig::new([16, 32], [4, 4])
            .with_stride([2, 2])
            .init(&dev);
        let x = random([3, 18, 20, 34], 1, &dev).require_grad();
        let (y_ref, y) = (conv1.forward(x.clone()), conv1_gemm(&conv1, x.clone()));
        assert_eq!(y.dims(), [3, 16, 4, 7]);
        assert!(max_diff(y_ref.clone(), y.clone()) < 1e-4);
        let (z_ref, z) = (
            conv2.forward(y_ref.clone()),
            conv2_gemm(&conv2, y_ref.clone()),
        );
        assert_eq!(z.dims(), [3, 32, 1, 2]);
        assert!(max_diff(z_ref.clone(), z.clone()) < 1e-4);
        // Gradients with respect to the weights and the input agree.
        let g_ref = (conv2.forward(conv1.forward(x.clone())).powf_scalar(2.0))
            .sum()
            .backward();
        let g = (conv2_gemm(&conv2, conv1_gemm(&conv1, x.clone())).powf_scalar(2.0))
            .sum()
            .backward();
        let w1 = (
            conv1.weight.val().grad(&g_ref).unwrap(),
            conv1.weight.val().grad(&g).unwrap(),
        );
        let w2 = (
            conv2.weight.val().grad(&g_ref).unwrap(),
            conv2.weight.val().grad(&g).unwrap(),
        );
        let gx = (x.grad(&g_ref).unwrap(), x.grad(&g).unwrap());
        let scale = w1.0.clone().abs().max().into_scalar::<f32>();
        assert!(max_diff(w1.0, w1.1) < 1e-3 * scale.max(1.0));
        assert!(max_diff(w2.0, w2.1) < 1e-3 * scale.max(1.0));
        assert!(max_diff(gx.0, gx.1) < 1e-3 * scale.max(1.0));
    }
}
