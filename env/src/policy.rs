//! Who chooses the actions. A [`Policy`] fills one action buffer per behaviour
//! for the behaviours that decided; scripted baselines and learned policies
//! implement the same trait, so every evaluation drives the world the same way.

use crate::env::Env;
use crate::rng::{Purpose, Stream};

/// Errors a policy may report.
pub type PolicyError = Box<dyn std::error::Error + Send + Sync>;

/// Chooses actions for the agents of an [`Env`].
pub trait Policy {
    /// A short name for logs and tables.
    fn name(&self) -> String;

    /// Fill `actions[b]` (`n_agents × 3` floats in [−1, 1]) for every behaviour
    /// `b` with `env.awaiting(b)`, from `env.output()` and `env.world()`.
    fn act(&mut self, env: &Env, actions: &mut [Vec<f32>]) -> Result<(), PolicyError>;
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
