//! A trained SAC actor driving a scene (the environment's [`Policy`]): acts with
//! `tanh(μ)` (deterministic, the default) or samples `tanh(μ + σ·ε)`.

use crate::model::{Actor, SacNetConfig, squashed_sample_f32};
use crate::train::{SacExtra, net_config};
use anyhow::{Context, Result};
use burn::prelude::*;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{Env, Policy, PolicyError, VECTOR_OBS};
use deepfoids_ppo::Backend;
use deepfoids_ppo::checkpoint::{RunState, policy_dir};
use deepfoids_ppo::model::ACTIONS;
use deepfoids_ppo::train::{tensor2, tensor4, to_vec};
use std::path::{Path, PathBuf};

pub struct SacPolicy {
    actors: Vec<Actor>,
    dev: Device,
    pub deterministic: bool,
    pub seed: u64,
    pub source: PathBuf,
    pub state: RunState,
}

/// Load the actor of behaviour `name` (or of one of the same species) from a policy folder.
pub fn load_actor(
    dir: &Path,
    state: &RunState,
    name: &str,
    species: &str,
    actor: Actor,
) -> Result<Actor> {
    let source = state
        .behaviour(name)
        .or_else(|| state.behaviours.iter().find(|b| b.species == species))
        .with_context(|| {
            format!(
                "{} has no policy for behaviour {name} or species {species}; it has: {}",
                dir.display(),
                state
                    .behaviours
                    .iter()
                    .map(|b| b.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
    let file = RunState::model_file(dir, &source.name);
    actor
        .try_load_file(&file)
        .map_err(|e| anyhow::anyhow!("cannot load {}: {e:?}", file.display()))
}

impl SacPolicy {
    /// Load the actors of a SAC run (its `final/`, or checkpoint `step`) for the behaviours of `env`.
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
        if state.algo != "sac" {
            anyhow::bail!("{} holds a {} policy, not SAC", dir.display(), state.algo);
        }
        let extra = SacExtra::load(&dir)?;
        let cfg: SacNetConfig =
            net_config(state.hidden, state.layers, extra.log_std_bounds, backend);
        let dev = backend.device();
        let actors = env
            .behaviours()
            .iter()
            .map(|b| load_actor(&dir, &state, &b.name, &b.species, cfg.init_actor(&dev)))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            actors,
            dev,
            deterministic,
            seed,
            source: dir,
            state,
        })
    }

    pub fn actor(&self, b: usize) -> &Actor {
        &self.actors[b]
    }
}

impl Policy for SacPolicy {
    fn name(&self) -> String {
        format!("{} (sac)", self.state.run_id)
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        let out = env.output();
        for (b, batch) in out.behaviours.iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let n = batch.n_agents;
            let (mean, log_std) = self.actors[b].forward(
                tensor4(batch.grids.clone(), n, &self.dev),
                tensor2(batch.vectors.clone(), n, VECTOR_OBS, &self.dev),
            );
            let (mean, log_std) = (to_vec(mean), to_vec(log_std));
            let dst = &mut actions[b];
            dst.resize(n * ACTIONS, 0.0);
            for a in 0..n {
                let r = a * ACTIONS..(a + 1) * ACTIONS;
                if self.deterministic {
                    for k in r.clone() {
                        dst[k] = mean[k].tanh();
                    }
                } else {
                    let mut noise = Stream::new(
                        self.seed,
                        Purpose::Exploration,
                        (batch.first + a) as u64,
                        out.tick,
                    );
                    let eps = [noise.normal(), noise.normal(), noise.normal()];
                    squashed_sample_f32(&mean[r.clone()], &log_std[r.clone()], &eps, &mut dst[r]);
                }
            }
        }
        Ok(())
    }
}
