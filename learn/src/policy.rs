//! Trained actors driving scenes: what `eval`, `simulate`, `export`, `render`
//! and `bench policy` need of a run, whatever its algorithm.

use crate::checkpoint::{BehaviourState, PolicySource, RunState, find_source, policy_dir};
use crate::error::Result;
use crate::onnx::Metadata;
use deepfoids_env::config::ActionTiming;
use deepfoids_env::rng::{Purpose, Stream};
use deepfoids_env::{Env, GridFormat, GridsRef, Policy, PolicyError};
use std::path::{Path, PathBuf};

/// What keys the exploration noise of a batch's agents: agent `a` of a batch
/// whose first fish is `first` draws from `(seed, first + a, tick)`, so a
/// seeded run samples the same actions whatever the batching.
#[derive(Clone, Copy, Debug)]
pub struct NoiseKey {
    pub seed: u64,
    pub first: usize,
    pub tick: u64,
}

impl NoiseKey {
    /// The noise stream of agent `a` of the batch.
    pub fn stream(&self, a: usize) -> Stream {
        Stream::new(
            self.seed,
            Purpose::Exploration,
            (self.first + a) as u64,
            self.tick,
        )
    }
}

/// One behaviour's trained actor.
pub trait Actor {
    /// Deterministic actions `[n, 3]` in [−1, 1] on the fused kernels
    /// (`grids` `[n, 18, 20, 34]` as floats or bytes, `vectors` `[n, 6]`).
    fn deterministic(&self, grids: GridsRef<'_>, vectors: &[f32]) -> Vec<f32>;

    /// The same on Burn's own layers from float grids (the benchmark's and
    /// the tests' reference).
    fn deterministic_reference(&self, grids: &[f32], vectors: &[f32]) -> Vec<f32>;

    /// Sampled actions, the noise of agent `a` from [`NoiseKey::stream`].
    fn sample(&self, grids: GridsRef<'_>, vectors: &[f32], key: NoiseKey) -> Vec<f32>;

    /// The actor as ONNX with ML-Agents' interface.
    fn onnx(&self, meta: &Metadata) -> Vec<u8>;
}

/// Loads behaviour `source` of a policy folder as an actor.
pub type ActorLoader<'a> = dyn Fn(&Path, &RunState, &BehaviourState) -> Result<Box<dyn Actor>> + 'a;

/// The actors of a run, one per behaviour of the scene they drive (a
/// behaviour missing from the run takes the actor of one of its species).
pub struct ActorPolicy {
    actors: Vec<Box<dyn Actor>>,
    /// Act with the deterministic output (default) instead of sampling.
    pub deterministic: bool,
    pub seed: u64,
    /// The policy folder (final/ or a checkpoint).
    pub source: PathBuf,
    pub state: RunState,
    /// How the policy was trained to act (SPEC §4), from its run's `config.toml`.
    pub action_timing: Option<ActionTiming>,
}

/// How the policy of run folder `run` was trained to act (SPEC §4): its
/// `config.toml`'s `[scene.rewards.timing] actions`. A run trained before
/// per-step actions existed has no such key and acted per decision. `None`
/// when the folder has no readable `config.toml`.
pub fn trained_action_timing(run: &Path) -> Option<ActionTiming> {
    let text = std::fs::read_to_string(run.join("config.toml")).ok()?;
    let config: toml::Table = text.parse().ok()?;
    let rewards = config.get("scene")?.get("rewards")?;
    let actions = rewards
        .get("timing")
        .and_then(|t| t.get("actions"))
        .and_then(|a| a.as_str());
    Some(match actions {
        Some("per_step") => ActionTiming::PerStep,
        _ => ActionTiming::PerDecision,
    })
}

impl ActorPolicy {
    /// Run `run`'s policy (its `final/`, or checkpoint `step`) for `env`'s behaviours.
    pub fn load(
        run: &Path,
        step: Option<u64>,
        env: &Env,
        deterministic: bool,
        seed: u64,
        loader: &ActorLoader<'_>,
    ) -> Result<Self> {
        let dir = policy_dir(run, step)?;
        let state = RunState::load(&dir)?;
        state.check_layout(&dir)?;
        let sources = [PolicySource {
            dir: dir.clone(),
            state: state.clone(),
        }];
        let actors = env
            .behaviours()
            .iter()
            .map(|b| {
                let (src, bs) = find_source(&sources, &b.name, &b.species)?;
                loader(&src.dir, &src.state, bs)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            actors,
            deterministic,
            seed,
            source: dir,
            state,
            action_timing: trained_action_timing(run),
        })
    }

    /// The actor of behaviour `b`.
    pub fn actor(&self, b: usize) -> &dyn Actor {
        self.actors[b].as_ref()
    }
}

impl Policy for ActorPolicy {
    fn name(&self) -> String {
        format!("{} ({})", self.state.run_id, self.state.algo)
    }

    fn action_timing(&self) -> Option<ActionTiming> {
        self.action_timing
    }

    /// The fused kernels act on the sensor's bytes, conv 1 on their non-zeros.
    fn grid_format(&self) -> Option<GridFormat> {
        Some(GridFormat::Bytes)
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        let out = env.output();
        for (b, batch) in out.behaviours.iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let actor = &self.actors[b];
            actions[b] = if self.deterministic {
                actor.deterministic(batch.observations(), &batch.vectors)
            } else {
                let key = NoiseKey {
                    seed: self.seed,
                    first: batch.first,
                    tick: out.tick,
                };
                actor.sample(batch.observations(), &batch.vectors, key)
            };
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's config.toml names its action timing; one written before the
    /// per-step reading has none and acted per decision; no file, no timing.
    #[test]
    fn a_run_remembers_how_its_policy_acts() {
        let dir = std::env::temp_dir().join(format!("deepfoids-timing-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert_eq!(trained_action_timing(&dir), None);
        let config = dir.join("config.toml");
        std::fs::write(&config, "[scene.rewards]\nw_nd = 1.5\n").unwrap();
        assert_eq!(trained_action_timing(&dir), Some(ActionTiming::PerDecision));
        std::fs::write(
            &config,
            "[scene.rewards]\nw_nd = 1.5\n[scene.rewards.timing]\nactions = \"per_step\"\n",
        )
        .unwrap();
        assert_eq!(trained_action_timing(&dir), Some(ActionTiming::PerStep));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
