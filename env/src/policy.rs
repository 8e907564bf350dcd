//! Who chooses the actions. A [`Policy`] fills one action buffer per behaviour
//! for the behaviours that decided; scripted baselines and learned policies
//! implement the same trait, so every evaluation drives the world the same way
//! ([`act_and_step`]).

use crate::config::ActionTiming;
use crate::env::{Env, EnvError, StepOutput};
use crate::rng::{Purpose, Stream};
use crate::traits::FishParams;
use deepfoids_sensors::GridFormat;

/// Errors a policy may report while it acts.
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    /// Its model could not compute the actions (e.g. the ONNX runtime failed).
    #[error("inference failed: {0}")]
    Inference(String),
    /// Its model does not fit what the scene hands it (species, shapes).
    #[error("does not fit the scene: {0}")]
    Mismatch(String),
}

/// Chooses actions for the agents of an [`Env`].
pub trait Policy {
    /// A short name for logs and tables.
    fn name(&self) -> String;

    /// Fill `actions[b]` (`n_agents × 3` floats in [−1, 1]) for every behaviour
    /// `b` with `env.awaiting(b)`, from `env.output()` and `env.world()`.
    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError>;

    /// The model parameters (speed range, light steepness) this policy's own
    /// model gives fish `fish` for the decision it just chose, if they differ
    /// from its species' (SPEC §4: the species' range, floor included, holds
    /// for every fish unless a rule-based model publishes its own, as Foids
    /// does for the night and for hovering). Called by [`act_and_step`] after
    /// [`Policy::act`]. Default: `None` (the species' values).
    fn fish_params(&self, _env: &Env, _fish: usize) -> Option<FishParams> {
        None
    }

    /// How this policy's actions are meant to act (SPEC §4), if its own model
    /// fixes it: the rule-based baselines steer per decision (their papers'
    /// reading, and what their published parameters were tuned for).
    /// [`act_and_step`] sets it on the env. Default: `None` (the reward profile's).
    fn action_timing(&self) -> Option<ActionTiming> {
        None
    }

    /// Whether the env's mirrored fish (the reward profile's
    /// `mirrored_share`) act as this policy's mirror image. A policy that acts
    /// on the observations: yes (default). A rule-based model that steers
    /// from the world, not from what the fish sees: no, [`act_and_step`]
    /// turns mirroring off.
    fn mirrors(&self) -> bool {
        true
    }

    /// How this policy reads the grids, if it cares: the fused-kernel actors
    /// act on bytes, the ONNX runtime on floats. [`act_and_step`] sets it on
    /// the env. Default: `None` (whatever the env hands out).
    fn grid_format(&self) -> Option<GridFormat> {
        None
    }
}

/// Errors of [`act_and_step`].
#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    #[error("policy {policy}: {source}")]
    Policy { policy: String, source: PolicyError },
    #[error(transparent)]
    Env(#[from] EnvError),
}

/// One tick driven by `policy`: its actions for the behaviours awaiting them,
/// each of their fish's [`FishParams`] (the policy's, else the species'), then
/// [`Env::step`].
pub fn act_and_step<'e>(
    policy: &mut dyn Policy,
    env: &'e mut Env,
    actions: &mut [Vec<f32>],
) -> Result<&'e StepOutput, DriveError> {
    if let Some(t) = policy.action_timing() {
        env.set_action_timing(t);
    }
    if let Some(f) = policy.grid_format() {
        env.set_grid_format(f);
    }
    env.set_mirroring(policy.mirrors());
    policy
        .act(env, actions)
        .map_err(|source| DriveError::Policy {
            policy: policy.name(),
            source,
        })?;
    for b in 0..env.behaviours().len() {
        if !env.awaiting(b) {
            continue;
        }
        for i in env.behaviours()[b].range() {
            let p = policy
                .fish_params(env, i)
                .unwrap_or_else(|| env.species_params(i));
            if p != env.fish_params(i) {
                env.set_fish_params(i, p)?;
            }
        }
    }
    Ok(env.step(actions)?)
}

/// Uniform random actions in [−1, 1]³, keyed by `(seed, fish, tick)`.
#[derive(Clone, Debug)]
pub struct RandomPolicy {
    pub seed: u64,
}

impl Policy for RandomPolicy {
    fn name(&self) -> String {
        "random".into()
    }

    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError> {
        let tick = env.output().tick;
        for (b, info) in env.behaviours().iter().enumerate() {
            if !env.awaiting(b) {
                continue;
            }
            let out = &mut actions[b];
            out.resize(info.count * 3, 0.0);
            for (a, act) in out.chunks_mut(3).enumerate() {
                let mut s = Stream::new(self.seed, Purpose::Policy, (info.first + a) as u64, tick);
                for x in act {
                    *x = s.range(-1.0, 1.0);
                }
            }
        }
        Ok(())
    }
}

/// Empty action buffers sized for `env`'s behaviours.
pub fn action_buffers(env: &Env) -> Vec<Vec<f32>> {
    env.behaviours()
        .iter()
        .map(|b| vec![0.0; b.count * 3])
        .collect()
}
