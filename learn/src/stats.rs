//! Environment statistics of one behaviour, shared by the trainers (PPO and
//! SAC log the same `Environment/…`, `Reward/…` and `School/…` scalars, in
//! raw rewards): a window between two log points, and a longer one between
//! two progress lines.

use crate::error::Result;
use crate::logger::Scalars;
use deepfoids_env::metrics::order_parameters;
use deepfoids_env::{BehaviourBatch, N_TERMS, StepOutput, TERM_NAMES};

/// The index of r_BC (the net collision) among the reward terms.
const R_BC: usize = 0;

/// Sums since the last log point.
#[derive(Clone, Default)]
struct Window {
    decisions: u64,
    reward: f64,
    terms: [f64; N_TERMS],
    /// Decisions that paid r_BC: the fish hit the net, whether that ended
    /// its episode or bounced it back (`boundary_ends_episode = false`).
    boundary_collisions: u64,
    episodes: u64,
    episode_return: f64,
    episode_return_sq: f64,
    episode_length: f64,
    p: f64,
    m: f64,
    pm_samples: u64,
}

impl Window {
    fn add(&mut self, o: &Window) {
        self.decisions += o.decisions;
        self.reward += o.reward;
        for (a, b) in self.terms.iter_mut().zip(&o.terms) {
            *a += b;
        }
        self.boundary_collisions += o.boundary_collisions;
        self.episodes += o.episodes;
        self.episode_return += o.episode_return;
        self.episode_return_sq += o.episode_return_sq;
        self.episode_length += o.episode_length;
        self.p += o.p;
        self.m += o.m;
        self.pm_samples += o.pm_samples;
    }
}

/// What a window said: the mean reward per decision and, if episodes ended,
/// their mean cumulative reward.
#[derive(Clone, Copy, Debug)]
pub struct WindowSummary {
    pub reward_per_decision: f64,
    pub cumulative_reward: Option<f64>,
}

/// A progress line's numbers (since the previous line).
#[derive(Clone, Copy, Debug, Default)]
pub struct ProgressSummary {
    pub decisions: u64,
    pub episodes: u64,
    /// Mean and standard deviation of the cumulative reward of the episodes ended.
    pub cumulative_reward: Option<(f64, f64)>,
    pub reward_per_decision: f64,
    pub p: f64,
    pub m: f64,
}

/// Per-agent episode returns and the windows of one behaviour.
pub struct EpisodeStats {
    first: usize,
    episode_return: Vec<f64>,
    episode_length: Vec<u32>,
    window: Window,
    progress: Window,
}

impl EpisodeStats {
    /// For the `n` agents starting at fish `first`.
    pub fn new(first: usize, n: usize) -> Self {
        Self {
            first,
            episode_return: vec![0.0; n],
            episode_length: vec![0; n],
            window: Window::default(),
            progress: Window::default(),
        }
    }

    /// Fold in a decision's rewards, episode ends and the school's P and M.
    pub fn record(&mut self, batch: &BehaviourBatch, out: &StepOutput) {
        let w = &mut self.window;
        for a in 0..batch.n_agents {
            let (r, term, trunc) = (batch.rewards[a], batch.terminated[a], batch.truncated[a]);
            self.episode_return[a] += r as f64;
            self.episode_length[a] += 1;
            if term || trunc {
                let ret = self.episode_return[a];
                w.episodes += 1;
                w.episode_return += ret;
                w.episode_return_sq += ret * ret;
                w.episode_length += self.episode_length[a] as f64;
                self.episode_return[a] = 0.0;
                self.episode_length[a] = 0;
            }
            w.reward += r as f64;
            for (t, v) in batch.terms[a].iter().enumerate() {
                w.terms[t] += *v as f64;
            }
            w.boundary_collisions += (batch.terms[a][R_BC] != 0.0) as u64;
        }
        let idx: Vec<usize> = (self.first..self.first + batch.n_agents).collect();
        let (p, m) = order_parameters(&out.fish.position, &out.fish.heading, Some(&idx));
        w.p += p as f64;
        w.m += m as f64;
        w.pm_samples += 1;
        w.decisions += batch.n_agents as u64;
    }

    /// Decisions in the window.
    pub fn decisions(&self) -> u64 {
        self.window.decisions
    }

    /// Write the window's scalars and start a new window.
    pub fn log(&mut self, out: &mut Scalars<'_>) -> Result<WindowSummary> {
        let w = std::mem::take(&mut self.window);
        self.progress.add(&w);
        let dec = w.decisions.max(1) as f64;
        let episode = (w.episodes > 0).then(|| w.episode_return / w.episodes as f64);
        if let Some(ep) = episode {
            out.put("Environment/Cumulative Reward", ep)?;
            out.put(
                "Environment/Episode Length",
                w.episode_length / w.episodes as f64,
            )?;
        }
        out.put("Environment/Reward per Decision", w.reward / dec)?;
        out.put(
            "Environment/Boundary Collisions per Decision",
            w.boundary_collisions as f64 / dec,
        )?;
        for (t, name) in TERM_NAMES.iter().enumerate() {
            out.put(&format!("Reward/{name}"), w.terms[t] / dec)?;
        }
        let pm = w.pm_samples.max(1) as f64;
        out.put("School/P", w.p / pm)?;
        out.put("School/M", w.m / pm)?;
        Ok(WindowSummary {
            reward_per_decision: w.reward / dec,
            cumulative_reward: episode,
        })
    }

    /// The numbers since the last progress line (logged windows only), and
    /// start a new progress window.
    pub fn take_progress(&mut self) -> ProgressSummary {
        let w = std::mem::take(&mut self.progress);
        let pm = w.pm_samples.max(1) as f64;
        ProgressSummary {
            decisions: w.decisions,
            episodes: w.episodes,
            cumulative_reward: (w.episodes > 0).then(|| {
                let k = w.episodes as f64;
                let mean = w.episode_return / k;
                let var = (w.episode_return_sq / k - mean * mean).max(0.0);
                (mean, var.sqrt())
            }),
            reward_per_decision: w.reward / w.decisions.max(1) as f64,
            p: w.p / pm,
            m: w.m / pm,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Boundary collisions are read off r_BC's place among the terms.
    #[test]
    fn r_bc_is_the_boundary_collision_term() {
        assert_eq!(TERM_NAMES[R_BC], "boundary_collision");
    }
}
