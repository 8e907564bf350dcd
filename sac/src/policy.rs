//! A trained SAC actor: acting on the fused kernels (deterministic `tanh(μ)`,
//! sampled `tanh(μ + σ(s)·ε)`), its reference on Burn's layers, and its ONNX
//! export.

use crate::model::{Actor as SacNet, squash_heads};
use crate::train::{SacState, actor_file, net_config, state_file};
use burn::prelude::*;
use deepfoids_env::VECTOR_OBS;
use deepfoids_learn::checkpoint::{BehaviourState, RunState, load_json, load_module};
use deepfoids_learn::kernels::encoder::GridsRef;
use deepfoids_learn::kernels::infer::InferNet;
use deepfoids_learn::onnx::Metadata;
use deepfoids_learn::policy::{Actor, NoiseKey};
use deepfoids_learn::tensor::{tensor2, tensor4, to_vec};
use deepfoids_learn::{ACTIONS, Algorithm, Result};
use std::path::Path;

/// One behaviour's trained SAC actor.
pub struct SacActor {
    pub actor: SacNet,
    net: InferNet,
}

impl SacActor {
    pub fn new(actor: SacNet) -> Self {
        Self {
            net: actor.infer_net(),
            actor,
        }
    }

    /// Behaviour `source` of the SAC policy folder `dir` (state `state`).
    pub fn load(dir: &Path, state: &RunState, source: &BehaviourState) -> Result<Self> {
        RunState::load_policy(dir, Algorithm::Sac, "a SAC actor is loaded")?;
        let st: SacState = load_json(&state_file(dir, &source.name), "SAC's state")?;
        let net = net_config(state.hidden, state.layers, st.log_std_bounds);
        let actor = load_module(
            net.init_actor(&Device::flex()),
            &actor_file(dir, &source.name),
        )?;
        Ok(Self::new(actor))
    }

    /// The mean and raw log-std `[n, 6]` (fused forward).
    fn heads(&self, grids: GridsRef<'_>, vectors: &[f32]) -> Vec<f32> {
        self.net.forward(grids, vectors).remove(0)
    }
}

impl Actor for SacActor {
    fn deterministic(&self, grids: GridsRef<'_>, vectors: &[f32]) -> Vec<f32> {
        self.heads(grids, vectors)
            .chunks_exact(2 * ACTIONS)
            .flat_map(|row| row[..ACTIONS].iter().map(|x| x.tanh()))
            .collect()
    }

    fn deterministic_reference(&self, grids: &[f32], vectors: &[f32]) -> Vec<f32> {
        let n = vectors.len() / VECTOR_OBS;
        let dev = Device::flex();
        let (mean, _) = self.actor.forward_reference(
            tensor4(grids.to_vec(), n, &dev),
            tensor2(vectors.to_vec(), n, VECTOR_OBS, &dev),
        );
        to_vec(mean.tanh())
    }

    fn sample(&self, grids: GridsRef<'_>, vectors: &[f32], key: NoiseKey) -> Vec<f32> {
        let heads = self.heads(grids, vectors);
        let mut out = vec![0.0; heads.len() / 2];
        squash_heads(&heads, key, |x| self.actor.squash_log_std(x), &mut out);
        out
    }

    fn onnx(&self, meta: &Metadata) -> Vec<u8> {
        self.actor.onnx(meta)
    }
}

/// Behaviour `source` of a SAC policy folder as an [`Actor`].
pub fn load_actor(dir: &Path, state: &RunState, source: &BehaviourState) -> Result<Box<dyn Actor>> {
    Ok(Box::new(SacActor::load(dir, state, source)?))
}
