//! A trained policy driving a scene: implements the environment's
//! [`Policy`](deepfoids_env::Policy), so `eval` and `simulate` take a run folder.

use crate::checkpoint::{RunState, policy_dir};
use crate::model::{ACTIONS, ActorCritic, ActorCriticConfig, BodyConfig};
use crate::train::{Backend, load_weights};
use anyhow::Result;
use burn::prelude::*;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{Env, Policy, PolicyError, VECTOR_OBS};
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};
use std::path::{Path, PathBuf};

/// The actors of a run, one per behaviour of the scene it drives.
pub struct TrainedPolicy {
    models: Vec<ActorCritic>,
    dev: Device,
    /// Act with the clipped mean (default) instead of sampling.
    pub deterministic: bool,
    pub seed: u64,
    pub source: PathBuf,
    pub state: RunState,
}

impl TrainedPolicy {
    /// Load the policy of `run` (its `final/`, or checkpoint `step`) for the behaviours of `env`.
    /// A behaviour missing from the run takes the policy of one of the same species.
    pub fn load(
        run: &Path,
        step: Option<u64>,
        env: &Env,
        backend: Backend,
        deterministic: bool,
        seed: u64,
    ) -> Result<Self> {
        let dir = policy_dir(run, step)?;
        let state = RunState::load(&dir)?;
        let dev = backend.device();
        let cfg = ActorCriticConfig::new()
            .with_body(
                BodyConfig::new()
                    .with_hidden(state.hidden)
                    .with_layers(state.layers)
                    .with_gemm_conv(backend.gemm_conv()),
            )
            .with_init_log_std(state.init_log_std);
        let models = env
            .behaviours()
            .iter()
            .map(|b| load_weights(&dir, &state, &b.name, &b.species, cfg.init(&dev)))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            models,
            dev,
            deterministic,
            seed,
            source: dir,
            state,
        })
    }

    /// The actor of behaviour `b` (for export and tests).
    pub fn model(&self, b: usize) -> &ActorCritic {
        &self.models[b]
    }
}

impl Policy for TrainedPolicy {
    fn name(&self) -> String {
        format!("{} ({})", self.state.run_id, self.state.algo)
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        let out = env.output();
        for (b, batch) in out.behaviours.iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let n = batch.n_agents;
            let grid = Tensor::<4>::from_data(
                TensorData::new(
                    batch.grids.clone(),
                    [n, STACKED_CHANNELS, EL_CELLS, AZ_CELLS],
                ),
                &self.dev,
            );
            let vector = Tensor::<2>::from_data(
                TensorData::new(batch.vectors.clone(), [n, VECTOR_OBS]),
                &self.dev,
            );
            let (mean, log_std) = self.models[b].actor(grid, vector);
            let mean = mean
                .into_data()
                .try_into_vec::<f32>()
                .map_err(|e| format!("{e:?}"))?;
            let log_std = log_std
                .into_data()
                .try_into_vec::<f32>()
                .map_err(|e| format!("{e:?}"))?;
            let dst = &mut actions[b];
            dst.resize(n * ACTIONS, 0.0);
            for a in 0..n {
                let mut noise = Stream::new(
                    self.seed,
                    Purpose::Exploration,
                    (batch.first + a) as u64,
                    out.tick,
                );
                for k in 0..ACTIONS {
                    let mu = mean[a * ACTIONS + k];
                    let x = if self.deterministic {
                        mu
                    } else {
                        mu + log_std[k].exp() * noise.normal()
                    };
                    dst[a * ACTIONS + k] = x.clamp(-1.0, 1.0);
                }
            }
        }
        Ok(())
    }
}
