//! Environment statistics of one behaviour between two log lines, shared by
//! the trainers (PPO and SAC log the same `Environment/…`, `Reward/…` and
//! `School/…` scalars, in raw rewards).

use crate::logger::Logger;
use anyhow::Result;
use deepfoids_env::metrics::order_parameters;
use deepfoids_env::{BehaviourBatch, N_TERMS, StepOutput, TERM_NAMES};

/// Sums since the last log line.
#[derive(Default)]
struct Window {
    decisions: u64,
    reward: f64,
    terms: [f64; N_TERMS],
    terminations: u64,
    episodes: u64,
    episode_return: f64,
    episode_length: f64,
    p: f64,
    m: f64,
    pm_samples: u64,
}

/// Per-agent episode returns and the window of one behaviour.
pub struct EpisodeStats {
    first: usize,
    episode_return: Vec<f64>,
    episode_length: Vec<u32>,
    window: Window,
}

impl EpisodeStats {
    /// For the `n` agents starting at fish `first`.
    pub fn new(first: usize, n: usize) -> Self {
        Self {
            first,
            episode_return: vec![0.0; n],
            episode_length: vec![0; n],
            window: Window::default(),
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
                w.episodes += 1;
                w.episode_return += self.episode_return[a];
                w.episode_length += self.episode_length[a] as f64;
                self.episode_return[a] = 0.0;
                self.episode_length[a] = 0;
            }
            w.reward += r as f64;
            for (t, v) in batch.terms[a].iter().enumerate() {
                w.terms[t] += *v as f64;
            }
            w.terminations += term as u64;
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

    /// Write the window's scalars at `step` and start a new window; returns the
    /// mean reward per decision and, if episodes ended, their mean cumulative reward.
    pub fn log(&mut self, logger: &mut Logger, b: usize, step: u64) -> Result<(f64, Option<f64>)> {
        let w = std::mem::take(&mut self.window);
        let dec = w.decisions.max(1) as f64;
        let episode = (w.episodes > 0).then(|| w.episode_return / w.episodes as f64);
        if let Some(ep) = episode {
            logger.scalar(b, "Environment/Cumulative Reward", ep, step)?;
            logger.scalar(
                b,
                "Environment/Episode Length",
                w.episode_length / w.episodes as f64,
                step,
            )?;
        }
        logger.scalar(b, "Environment/Reward per Decision", w.reward / dec, step)?;
        logger.scalar(
            b,
            "Environment/Boundary Collisions per Decision",
            w.terminations as f64 / dec,
            step,
        )?;
        for (t, name) in TERM_NAMES.iter().enumerate() {
            logger.scalar(b, &format!("Reward/{name}"), w.terms[t] / dec, step)?;
        }
        let pm = w.pm_samples.max(1) as f64;
        logger.scalar(b, "School/P", w.p / pm, step)?;
        logger.scalar(b, "School/M", w.m / pm, step)?;
        Ok((w.reward / dec, episode))
    }
}
