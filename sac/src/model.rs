//! SAC's networks and losses (SPEC §8, thesis Table 4.5; Haarnoja et al. 2018).
//!
//! * **Actor**: the SPEC §8 body (visual encoder, concatenated vector
//!   observation, 4 × Dense 128 Swish) with two linear heads, the Gaussian's
//!   mean `μ` and log-std (state-dependent, squashed into `log_std_bounds` as
//!   CleanRL does). Actions are `a = tanh(u)`, `u = μ + σ·ε`.
//! * **Critics**: twin Q networks, each with its own body (own visual encoder);
//!   the action enters next to the vector observation, after the encoder (as
//!   in ML-Agents' value networks), and a linear head gives `Q(s, a)`.
//!
//! Both heads of the actor start small (weights × 0.01, zero bias): the first
//! policy has `μ ≈ 0` and `log σ ≈ (lo + hi)/2 = −1.5` (σ ≈ 0.22), close to the
//! PPO actor's start (σ = 1/3).

use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::softplus;
use deepfoids_learn::body::{infer_net, small_linear};
use deepfoids_learn::kernels::dense::DensePack;
use deepfoids_learn::kernels::infer::InferNet;
use deepfoids_learn::onnx::{Head, Metadata, export_policy};
use deepfoids_learn::policy::NoiseKey;
use deepfoids_learn::{ACTIONS, Body, BodyConfig, Grids};

const HALF_LOG_2PI: f32 = 0.918_938_5;
const LN_2: f32 = std::f32::consts::LN_2;

/// Architecture of the actor and the critics.
#[derive(Config, Debug)]
pub struct SacNetConfig {
    #[config(default = 128)]
    pub hidden: usize,
    #[config(default = 4)]
    pub layers: usize,
    #[config(default = -5.0)]
    pub log_std_min: f32,
    #[config(default = 2.0)]
    pub log_std_max: f32,
}

impl SacNetConfig {
    fn body(&self, extra_inputs: usize) -> BodyConfig {
        BodyConfig::new()
            .with_hidden(self.hidden)
            .with_layers(self.layers)
            .with_extra_inputs(extra_inputs)
    }

    pub fn init_actor(&self, device: &Device) -> Actor {
        Actor {
            body: self.body(0).init(device),
            mean: small_linear(self.hidden, ACTIONS, 0.01, device),
            log_std: small_linear(self.hidden, ACTIONS, 0.01, device),
            log_std_min: self.log_std_min,
            log_std_max: self.log_std_max,
        }
    }

    pub fn init_critic(&self, device: &Device) -> TwinQ {
        let q = || QNet {
            body: self.body(ACTIONS).init(device),
            head: LinearConfig::new(self.hidden, 1).init(device),
        };
        TwinQ { q1: q(), q2: q() }
    }
}

#[derive(Module, Debug)]
pub struct Actor {
    pub body: Body,
    pub mean: Linear,
    pub log_std: Linear,
    log_std_min: f32,
    log_std_max: f32,
}

impl Actor {
    /// The actor (body and tanh-squashed Gaussian head) as ONNX with
    /// ML-Agents' interface.
    pub fn onnx(&self, meta: &Metadata) -> Vec<u8> {
        export_policy(
            &self.body,
            Head::Squashed {
                mean: &self.mean,
                log_std: &self.log_std,
                bounds: self.bounds(),
            },
            meta,
        )
    }

    /// The Gaussian's mean and log-std, both `[B, 3]`, before squashing.
    pub fn forward(&self, grids: &Grids, vector: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        self.heads(self.body.forward(grids, vector))
    }

    /// The same on Burn's own layers (the kernels' reference).
    pub fn forward_reference(&self, grid: Tensor<4>, vector: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let b = &self.body;
        self.heads(b.trunk_reference(b.encode_reference(grid), vector))
    }

    fn heads(&self, h: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let mean = self.mean.forward(h.clone());
        let t = self.log_std.forward(h).tanh();
        let (lo, hi) = (self.log_std_min, self.log_std_max);
        let log_std = (t + 1.0).mul_scalar(0.5 * (hi - lo)) + lo;
        (mean, log_std)
    }

    /// The log-std bounds `[lo, hi]`.
    pub fn bounds(&self) -> [f32; 2] {
        [self.log_std_min, self.log_std_max]
    }

    /// Both heads side by side (`[hidden, 6]`: mean, then raw log-std) for the
    /// fused forward.
    pub fn head_pack(&self) -> DensePack {
        let (m, s) = (
            deepfoids_learn::body::dense_pack(&self.mean),
            deepfoids_learn::body::dense_pack(&self.log_std),
        );
        let mut w = Vec::with_capacity(m.d_in * 2 * ACTIONS);
        for i in 0..m.d_in {
            w.extend_from_slice(&m.w[i * ACTIONS..(i + 1) * ACTIONS]);
            w.extend_from_slice(&s.w[i * ACTIONS..(i + 1) * ACTIONS]);
        }
        DensePack {
            d_in: m.d_in,
            d_out: 2 * ACTIONS,
            w,
            b: [m.b, s.b].concat(),
        }
    }

    /// The actor for the fused forward: `[n, 6]` per sample, the mean and the
    /// raw log-std head (squash it with [`Actor::squash_log_std`]).
    pub fn infer_net(&self) -> InferNet {
        let mut net = infer_net(&[(&self.body, None)]);
        net.trunks[0].head = Some(self.head_pack());
        net
    }

    /// The raw log-std head's value → log σ in the bounds.
    pub fn squash_log_std(&self, raw: f32) -> f32 {
        let (lo, hi) = (self.log_std_min, self.log_std_max);
        lo + 0.5 * (hi - lo) * (raw.tanh() + 1.0)
    }
}

#[derive(Module, Debug)]
pub struct QNet {
    pub body: Body,
    pub head: Linear,
}

impl QNet {
    /// `Q(s, a)` `[B]`.
    pub fn forward(&self, grids: &Grids, vector: Tensor<2>, action: Tensor<2>) -> Tensor<1> {
        self.from_encoded(self.body.encode(grids), vector, action)
    }

    /// `Q(s, a)` `[B]` from the grid already encoded by [`Body::encode`].
    pub fn from_encoded(
        &self,
        encoded: Tensor<2>,
        vector: Tensor<2>,
        action: Tensor<2>,
    ) -> Tensor<1> {
        let x = Tensor::cat(vec![vector, action], 1);
        self.head
            .forward(self.body.trunk_forward(encoded, x))
            .flatten(0, 1)
    }
}

/// The twin critics.
#[derive(Module, Debug)]
pub struct TwinQ {
    pub q1: QNet,
    pub q2: QNet,
}

impl TwinQ {
    pub fn forward(
        &self,
        grids: &Grids,
        vector: Tensor<2>,
        action: Tensor<2>,
    ) -> (Tensor<1>, Tensor<1>) {
        self.from_encoded(self.encode(grids), vector, action)
    }

    /// Both critics' encodings of the grids (read once for both).
    pub fn encode(&self, grids: &Grids) -> (Tensor<2>, Tensor<2>) {
        let mut e = Body::encode_many(&[&self.q1.body, &self.q2.body], grids);
        (e.remove(0), e.remove(0))
    }

    /// Both critics for the fused forward (`[n, 1]` each; the action enters
    /// as the trunk's extra input).
    pub fn infer_net(&self) -> InferNet {
        infer_net(&[
            (&self.q1.body, Some(&self.q1.head)),
            (&self.q2.body, Some(&self.q2.head)),
        ])
    }

    /// Both `Q(s, a)` from the grid's encodings.
    pub fn from_encoded(
        &self,
        encoded: (Tensor<2>, Tensor<2>),
        vector: Tensor<2>,
        action: Tensor<2>,
    ) -> (Tensor<1>, Tensor<1>) {
        (
            self.q1
                .from_encoded(encoded.0, vector.clone(), action.clone()),
            self.q2.from_encoded(encoded.1, vector, action),
        )
    }
}

/// Reparameterised sample of the squashed Gaussian: `u = μ + σ·ε`, `a = tanh(u)`,
/// and its log-density `[B]` with the change-of-variables correction
/// (Haarnoja et al. 2018, Eq. 21):
///
/// `log π(a|s) = Σ_k [ −ε_k²/2 − log σ_k − ½ log 2π − log(1 − tanh²u_k) ]`,
///
/// with `log(1 − tanh²u) = 2·(log 2 − u − softplus(−2u))`, exact and stable for
/// large `|u|` (where `1 − tanh²u` underflows).
pub fn squashed_sample(
    mean: Tensor<2>,
    log_std: Tensor<2>,
    eps: Tensor<2>,
) -> (Tensor<2>, Tensor<1>) {
    let u = mean + log_std.clone().exp() * eps.clone();
    let action = u.clone().tanh();
    let log_det = (u.clone().neg() - softplus(u.mul_scalar(-2.0), 1.0) + LN_2).mul_scalar(2.0);
    let per_dim = eps.powf_scalar(2.0).mul_scalar(-0.5) - log_std - HALF_LOG_2PI - log_det;
    (action, per_dim.sum_dim(1).flatten(0, 1))
}

/// `tanh(μ + σ·ε)` for actor outputs `heads` `[n, 2·ACTIONS]` (mean, raw
/// log-std, turned into log σ by `log_std`); agent `a`'s noise is
/// [`NoiseKey::stream`], so acting and training draw the same actions.
pub fn squash_heads(
    heads: &[f32],
    key: NoiseKey,
    log_std: impl Fn(f32) -> f32,
    actions: &mut [f32],
) {
    use deepfoids_learn::ACTIONS;
    for (a, row) in heads.chunks_exact(2 * ACTIONS).enumerate() {
        let mut noise = key.stream(a);
        let eps = [noise.normal(), noise.normal(), noise.normal()];
        let ls: [f32; ACTIONS] = std::array::from_fn(|k| log_std(row[ACTIONS + k]));
        squashed_sample_f32(
            &row[..ACTIONS],
            &ls,
            &eps,
            &mut actions[a * ACTIONS..(a + 1) * ACTIONS],
        );
    }
}

/// [`squashed_sample`] for one agent in plain floats: the action and its log-density.
pub fn squashed_sample_f32(mean: &[f32], log_std: &[f32], eps: &[f32], action: &mut [f32]) -> f32 {
    let mut logp = 0.0;
    for k in 0..mean.len() {
        let u = mean[k] + log_std[k].exp() * eps[k];
        action[k] = u.tanh();
        let log_det = 2.0 * (LN_2 - u - softplus_f32(-2.0 * u));
        logp += -0.5 * eps[k] * eps[k] - log_std[k] - HALF_LOG_2PI - log_det;
    }
    logp
}

fn softplus_f32(x: f32) -> f32 {
    if x > 20.0 { x } else { x.exp().ln_1p() }
}

/// The soft Bellman target of the twin critics (Fujimoto et al.'s clipped double
/// Q with SAC's entropy bonus):
///
/// `y = r + γ·(1 − terminated)·(min(Q'₁(s', a'), Q'₂(s', a')) − α·log π(a'|s'))`,
/// `a' ~ π(·|s')`. A truncated transition bootstraps (its `terminated` is false).
pub fn twin_q_target(
    rewards: &[f32],
    terminated: &[bool],
    next_q1: &[f32],
    next_q2: &[f32],
    next_logp: &[f32],
    alpha: f32,
    gamma: f32,
) -> Vec<f32> {
    (0..rewards.len())
        .map(|i| {
            let soft = next_q1[i].min(next_q2[i]) - alpha * next_logp[i];
            rewards[i] + if terminated[i] { 0.0 } else { gamma * soft }
        })
        .collect()
}

/// The entropy coefficient, tuned automatically in log space (Haarnoja et al.
/// 2018b, Eq. 18, as CleanRL): the loss `J(log α) = −log α · mean(log π + H̄)`
/// with target entropy `H̄ = −3`, minimised by Adam. `alpha = 0` switches the
/// term off (fine tuning): `alpha()` is then 0 and [`step`](Self::step) does nothing.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EntropyCoef {
    pub log_alpha: f64,
    pub enabled: bool,
    /// Adam's moments and step count for `log_alpha`.
    pub m: f64,
    pub v: f64,
    pub t: u64,
}

impl EntropyCoef {
    pub fn new(init: f64) -> Self {
        Self {
            // Off: α is 0 and log α unused (kept finite so `sac.json` stays valid JSON).
            log_alpha: if init > 0.0 { init.ln() } else { 0.0 },
            enabled: init > 0.0,
            m: 0.0,
            v: 0.0,
            t: 0,
        }
    }

    pub fn alpha(&self) -> f64 {
        if self.enabled {
            self.log_alpha.exp()
        } else {
            0.0
        }
    }

    /// The loss `−log α · (mean log π + H̄)` and its gradient `−(mean log π + H̄)`.
    pub fn loss_and_grad(&self, mean_logp: f64, target_entropy: f64) -> (f64, f64) {
        let g = -(mean_logp + target_entropy);
        (self.log_alpha * g, g)
    }

    /// One Adam step (β = 0.9, 0.999) on `log α`; returns the loss.
    pub fn step(&mut self, mean_logp: f64, target_entropy: f64, lr: f64, eps: f64) -> f64 {
        if !self.enabled {
            return 0.0;
        }
        let (loss, g) = self.loss_and_grad(mean_logp, target_entropy);
        let (b1, b2) = (0.9, 0.999);
        self.t += 1;
        self.m = b1 * self.m + (1.0 - b1) * g;
        self.v = b2 * self.v + (1.0 - b2) * g * g;
        let m_hat = self.m / (1.0 - b1.powi(self.t as i32));
        let v_hat = self.v / (1.0 - b2.powi(self.t as i32));
        self.log_alpha -= lr * m_hat / (v_hat.sqrt() + eps);
        loss
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t2(v: Vec<f32>, rows: usize, dev: &Device) -> Tensor<2> {
        let cols = v.len() / rows;
        Tensor::from_data(TensorData::new(v, [rows, cols]), dev)
    }

    /// μ = (0, 0.5, −1), log σ = (0, ln 0.5, −1), ε = (1, −2, 0.5):
    /// u = (1, −0.5, −1 + 0.5·e⁻¹ = −0.816060), a = tanh u;
    /// log N terms: −0.5 − 0 − 0.918939 = −1.418939; −2 + 0.693147 − 0.918939 = −2.225791;
    /// −0.125 + 1 − 0.918939 = −0.043939; sum −3.688669.
    /// log(1 − tanh²u): ln(1 − 0.761594²) = −0.867562; ln(1 − 0.462117²) = −0.240229;
    /// ln(1 − 0.672920²) = −0.602980 (tanh(−0.816060) = −0.672920); sum −1.710771.
    /// log π = −3.688669 + 1.710771 = −1.977898.
    #[test]
    fn tanh_log_prob_by_hand() {
        let dev = Device::flex();
        let mean = t2(vec![0.0, 0.5, -1.0], 1, &dev);
        let log_std = t2(vec![0.0, 0.5f32.ln(), -1.0], 1, &dev);
        let eps = t2(vec![1.0, -2.0, 0.5], 1, &dev);
        let (a, logp) = squashed_sample(mean, log_std, eps);
        let a = a.into_data().try_to_vec::<f32>().unwrap();
        let logp = logp.into_scalar::<f32>();
        let u3 = -1.0 + 0.5 * (-1.0f32).exp();
        assert!((a[0] - 1f32.tanh()).abs() < 1e-6);
        assert!((a[1] - (-0.5f32).tanh()).abs() < 1e-6);
        assert!((a[2] - u3.tanh()).abs() < 1e-6);
        assert!((logp + 1.977_898).abs() < 1e-4, "{logp}");
        // The scalar version agrees.
        let mut act = [0.0; 3];
        let lp = squashed_sample_f32(
            &[0.0, 0.5, -1.0],
            &[0.0, 0.5f32.ln(), -1.0],
            &[1.0, -2.0, 0.5],
            &mut act,
        );
        assert!((lp + 1.977_898).abs() < 1e-4, "{lp}");
        assert!((act[2] - u3.tanh()).abs() < 1e-6);
    }

    /// Far in the tail (u = 20) the naive `log(1 − tanh²u)` is −∞ in f32; the
    /// stable form gives 2·(ln 2 − 20 − softplus(−40)) = −38.613706.
    #[test]
    fn tanh_correction_is_finite_in_the_tail() {
        let dev = Device::flex();
        let (_, logp) = squashed_sample(
            t2(vec![20.0], 1, &dev),
            t2(vec![0.0], 1, &dev),
            t2(vec![0.0], 1, &dev),
        );
        let logp = logp.into_scalar::<f32>();
        // −0 − 0 − 0.918939 + 38.613706 = 37.694767
        assert!((logp - 37.694_767).abs() < 1e-3, "{logp}");
    }

    /// r = (1, −300, 2), terminated = (no, yes, no), Q'₁ = (10, 5, −4), Q'₂ = (12, 3, −6),
    /// log π' = (−1, 0.5, 2), α = 0.2, γ = 0.99:
    /// y₁ = 1 + 0.99·(10 + 0.2) = 11.098; y₂ = −300 (no bootstrap);
    /// y₃ = 2 + 0.99·(−6 − 0.4) = −4.336.
    #[test]
    fn twin_q_target_by_hand() {
        let y = twin_q_target(
            &[1.0, -300.0, 2.0],
            &[false, true, false],
            &[10.0, 5.0, -4.0],
            &[12.0, 3.0, -6.0],
            &[-1.0, 0.5, 2.0],
            0.2,
            0.99,
        );
        let want = [11.098, -300.0, -4.336];
        for (a, b) in y.iter().zip(want) {
            assert!((a - b).abs() < 1e-4, "{y:?}");
        }
    }

    /// α₀ = 0.3, mean log π = −1 (entropy ≈ 1), H̄ = −3: the gradient of
    /// −log α·(−1 − 3) is +4 and the loss ln 0.3 · 4 = −4.815891. The entropy is
    /// above its target, so α must fall: Adam's first step moves log α by
    /// exactly −lr (m̂/√v̂ = 1), to α = 0.3·e^−0.001.
    #[test]
    fn entropy_coefficient_loss_by_hand() {
        let mut c = EntropyCoef::new(0.3);
        let (loss, g) = c.loss_and_grad(-1.0, -3.0);
        assert!((g - 4.0).abs() < 1e-12);
        assert!((loss - 0.3f64.ln() * 4.0).abs() < 1e-12);
        c.step(-1.0, -3.0, 0.001, 1e-8);
        assert!(
            (c.alpha() - 0.3 * (-0.001f64).exp()).abs() < 1e-9,
            "{}",
            c.alpha()
        );
        // Entropy below the target (log π = 5 > 3): α grows.
        let mut c = EntropyCoef::new(0.3);
        c.step(5.0, -3.0, 0.001, 1e-8);
        assert!(c.alpha() > 0.3);
        // Off: α = 0 and stays 0.
        let mut off = EntropyCoef::new(0.0);
        assert_eq!(off.step(5.0, -3.0, 0.001, 1e-8), 0.0);
        assert_eq!(off.alpha(), 0.0);
        // Both states survive `sac.json`.
        for c in [EntropyCoef::new(0.0), EntropyCoef::new(0.3)] {
            let back: EntropyCoef =
                serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
            assert_eq!(back, c);
        }
    }

    #[test]
    fn shapes() {
        let dev = Device::flex();
        let cfg = SacNetConfig::new();
        let actor = cfg.init_actor(&dev);
        let critic = cfg.init_critic(&dev);
        let grid = Tensor::<4>::zeros([2, 18, 20, 34], &dev);
        let vector = Tensor::<2>::zeros([2, 6], &dev);
        let grids = Grids::Dense(grid);
        let (m, s) = actor.forward(&grids, vector.clone());
        assert_eq!(m.dims(), [2, 3]);
        let s = s.into_data().try_to_vec::<f32>().unwrap();
        assert!(s.iter().all(|x| (x + 1.5).abs() < 0.1), "{s:?}");
        let (q1, q2) = critic.forward(&grids, vector, Tensor::zeros([2, 3], &dev));
        assert_eq!(q1.dims(), [2]);
        assert_eq!(q2.dims(), [2]);
    }
}
