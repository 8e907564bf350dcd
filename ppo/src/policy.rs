//! A trained PPO actor: acting on the fused kernels (deterministic: the
//! clipped mean; sampled: `clip(μ + σ·ε)`), its reference on Burn's layers,
//! and its ONNX export.

use crate::model::ActorCritic;
use crate::train::{model_config, model_file};
use burn::prelude::*;
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::checkpoint::{BehaviourState, RunState, load_module};
use deepfoids_learn::kernels::encoder::GridsRef;
use deepfoids_learn::kernels::infer::InferNet;
use deepfoids_learn::onnx::Metadata;
use deepfoids_learn::policy::{Actor, NoiseKey};
use deepfoids_learn::tensor::{tensor2, tensor4, to_vec};
use deepfoids_learn::{ACTIONS, Algorithm, Result};
use std::path::Path;

/// One behaviour's trained PPO actor.
pub struct PpoActor {
    pub model: ActorCritic,
    net: InferNet,
    log_std: Vec<f32>,
}

impl PpoActor {
    pub fn new(model: ActorCritic) -> Self {
        Self {
            net: model.actor_net(),
            log_std: model.log_std_values(),
            model,
        }
    }

    /// Behaviour `source` of the PPO policy folder `dir` (state `state`).
    pub fn load(dir: &Path, state: &RunState, source: &BehaviourState) -> Result<Self> {
        RunState::load_policy(dir, Algorithm::Ppo, "a PPO actor is loaded")?;
        let model = model_config(state.hidden, state.layers, 0.0).init(&Device::flex());
        Ok(Self::new(load_module(
            model,
            &model_file(dir, &source.name),
        )?))
    }

    /// The Gaussian's mean `[n, 3]` (fused forward).
    pub fn mean(&self, grids: GridsRef<'_>, vectors: &[f32]) -> Vec<f32> {
        self.net.forward(grids, vectors).remove(0)
    }
}

impl Actor for PpoActor {
    fn deterministic(&self, grids: GridsRef<'_>, vectors: &[f32]) -> Vec<f32> {
        self.mean(grids, vectors)
            .into_iter()
            .map(|x| x.clamp(-1.0, 1.0))
            .collect()
    }

    fn deterministic_reference(&self, grids: &[f32], vectors: &[f32]) -> Vec<f32> {
        let n = vectors.len() / VECTOR_OBS;
        let dev = Device::flex();
        let mean = self.model.actor_reference(
            tensor4(grids.to_vec(), n, &dev),
            tensor2(vectors.to_vec(), n, VECTOR_OBS, &dev),
        );
        to_vec(mean.clamp(-1.0, 1.0))
    }

    fn sample(&self, grids: GridsRef<'_>, vectors: &[f32], key: NoiseKey) -> Vec<f32> {
        let mut out = self.mean(grids, vectors);
        for (a, act) in out.chunks_mut(ACTIONS).enumerate() {
            let mut noise = key.stream(a);
            for (k, x) in act.iter_mut().enumerate() {
                *x = (*x + self.log_std[k].exp() * noise.normal()).clamp(-1.0, 1.0);
            }
        }
        out
    }

    fn onnx(&self, meta: &Metadata) -> Vec<u8> {
        self.model.actor_onnx(meta)
    }
}

/// Behaviour `source` of a PPO policy folder as an [`Actor`].
pub fn load_actor(dir: &Path, state: &RunState, source: &BehaviourState) -> Result<Box<dyn Actor>> {
    Ok(Box::new(PpoActor::load(dir, state, source)?))
}
