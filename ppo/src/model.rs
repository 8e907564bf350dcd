//! PPO's actor-critic (SPEC §8): two bodies of `deepfoids_learn::Body`, a
//! Gaussian mean head `[B, 3]` with a learned state-independent log-std `[3]`
//! for the actor, a value head `[B, 1]` for the critic.
//!
//! Initialisation: Burn's defaults (Kaiming uniform) everywhere, except the
//! actor's mean head, scaled by 0.01 with a zero bias so the first policy's
//! means are near zero (the "small last layer" detail of CleanRL's PPO).

use burn::module::Param;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use deepfoids_learn::body::{infer_net, small_linear};
use deepfoids_learn::kernels::infer::InferNet;
use deepfoids_learn::onnx::{Head, Metadata, export_policy};
use deepfoids_learn::tensor::to_vec;
use deepfoids_learn::{ACTIONS, Body, BodyConfig, Grids};

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
        ActorCritic {
            actor_body: self.body.init(device),
            actor_mean: small_linear(self.body.hidden, ACTIONS, 0.01, device),
            log_std: Param::from_tensor(Tensor::full([ACTIONS], self.init_log_std, device)),
            critic_body: self.body.init(device),
            critic_head: LinearConfig::new(self.body.hidden, 1).init(device),
        }
    }
}

impl ActorCritic {
    /// The actor (body and Gaussian head) as ONNX with ML-Agents' interface.
    pub fn actor_onnx(&self, meta: &Metadata) -> Vec<u8> {
        let log_std = self.log_std.val();
        export_policy(
            &self.actor_body,
            Head::Gaussian {
                mean: &self.actor_mean,
                log_std: &log_std,
            },
            meta,
        )
    }

    /// The Gaussian's mean `[B, 3]`, its log-std `[3]` and the state value
    /// `[B]`; both encoders read the grids in one pass.
    pub fn forward(&self, grids: &Grids, vector: Tensor<2>) -> (Tensor<2>, Tensor<1>, Tensor<1>) {
        let mut enc = Body::encode_many(&[&self.actor_body, &self.critic_body], grids);
        let (ea, ec) = (enc.remove(0), enc.remove(0));
        let mean = self
            .actor_mean
            .forward(self.actor_body.trunk_forward(ea, vector.clone()));
        let value = self
            .critic_head
            .forward(self.critic_body.trunk_forward(ec, vector))
            .flatten(0, 1);
        (mean, self.log_std.val(), value)
    }

    /// The Gaussian's mean `[B, 3]` and log-std `[3]`.
    pub fn actor(&self, grids: &Grids, vector: Tensor<2>) -> (Tensor<2>, Tensor<1>) {
        (
            self.actor_mean
                .forward(self.actor_body.forward(grids, vector)),
            self.log_std.val(),
        )
    }

    /// The mean `[B, 3]` on Burn's own layers (the kernels' reference).
    pub fn actor_reference(&self, grid: Tensor<4>, vector: Tensor<2>) -> Tensor<2> {
        let b = &self.actor_body;
        self.actor_mean
            .forward(b.trunk_reference(b.encode_reference(grid), vector))
    }

    /// Actor and critic for the fused forward: body 0 gives the mean `[n, 3]`,
    /// body 1 the value `[n, 1]`.
    pub fn infer_net(&self) -> InferNet {
        infer_net(&[
            (&self.actor_body, Some(&self.actor_mean)),
            (&self.critic_body, Some(&self.critic_head)),
        ])
    }

    /// The actor alone for the fused forward (the mean `[n, 3]`).
    pub fn actor_net(&self) -> InferNet {
        infer_net(&[(&self.actor_body, Some(&self.actor_mean))])
    }

    /// The log-std as plain floats.
    pub fn log_std_values(&self) -> Vec<f32> {
        to_vec(self.log_std.val())
    }
}
