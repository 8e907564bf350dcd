//! Run folders, checkpoints and the saved state of a run.
//!
//! ```text
//! runs/<run-id>/
//!   config.toml                 the resolved PPO config, scene and arguments
//!   scalars.csv                 behaviour, step, tag, value (the TensorBoard scalars)
//!   tb/<behaviour>/events.*     TensorBoard event files, one folder per behaviour
//!   checkpoints/step-NNNNNNNNNN/  <behaviour>.model.bpk, <behaviour>.optim.bpk, state.json
//!   final/                      <behaviour>.model.bpk, state.json
//! ```
//! Checkpoint folders appear atomically (written under a temporary name, then
//! renamed), so a kill at any moment leaves only whole checkpoints.

use crate::config::PpoConfig;
use anyhow::{Context, Result, bail};
use deepfoids_env::Phase;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Running mean and variance (Chan et al.'s parallel update), for reward scaling.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunningMeanStd {
    pub mean: f64,
    pub var: f64,
    pub count: f64,
}

impl Default for RunningMeanStd {
    fn default() -> Self {
        Self {
            mean: 0.0,
            var: 1.0,
            count: 1e-4,
        }
    }
}

impl RunningMeanStd {
    /// Fold a batch of values in.
    pub fn update(&mut self, xs: &[f64]) {
        if xs.is_empty() {
            return;
        }
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        let delta = mean - self.mean;
        let total = self.count + n;
        self.mean += delta * n / total;
        let m2 = self.var * self.count + var * n + delta * delta * self.count * n / total;
        self.var = m2 / total;
        self.count = total;
    }

    pub fn std(&self) -> f64 {
        (self.var + 1e-8).sqrt()
    }
}

/// Per-behaviour training state.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BehaviourState {
    pub name: String,
    pub species: String,
    pub size_class: String,
    pub agent_steps: u64,
    pub updates: u64,
    pub reward_norm: RunningMeanStd,
}

/// Everything needed to continue a run exactly, besides the weights and the optimisers.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunState {
    pub algo: String,
    pub run_id: String,
    pub scene: String,
    pub phase: Phase,
    pub seed: u64,
    pub backend: String,
    /// Agent decisions so far, all behaviours.
    pub agent_steps: u64,
    /// The budget (agent decisions).
    pub budget: u64,
    /// Environment ticks so far (the exploration noise is keyed by it).
    pub ticks: u64,
    /// Environment resets so far (the env is reseeded with `seed + resets`).
    pub resets: u64,
    pub wall_seconds: f64,
    pub init_from: Option<String>,
    /// Architecture, to rebuild the networks when loading.
    pub hidden: usize,
    pub layers: usize,
    pub init_log_std: f32,
    pub behaviours: Vec<BehaviourState>,
}

impl RunState {
    pub fn save(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)?;
        deepfoids_env::io::write_atomic(dir.join("state.json"), text.as_bytes())?;
        Ok(())
    }

    pub fn load(dir: &Path) -> Result<Self> {
        let path = dir.join("state.json");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        serde_json::from_str(&text)
            .with_context(|| format!("{} is not a run state", path.display()))
    }

    pub fn behaviour(&self, name: &str) -> Option<&BehaviourState> {
        self.behaviours.iter().find(|b| b.name == name)
    }

    /// The model file of behaviour `name` in a checkpoint or final folder.
    pub fn model_file(dir: &Path, name: &str) -> PathBuf {
        dir.join(format!("{name}.model.bpk"))
    }

    pub fn optim_file(dir: &Path, name: &str) -> PathBuf {
        dir.join(format!("{name}.optim.bpk"))
    }

    pub fn matches_architecture(&self, cfg: &PpoConfig) -> bool {
        self.hidden == cfg.hidden && self.layers == cfg.layers
    }
}

/// Checkpoint folders of a run, oldest first.
pub fn checkpoints(run_dir: &Path) -> Vec<(u64, PathBuf)> {
    let mut v: Vec<(u64, PathBuf)> = std::fs::read_dir(run_dir.join("checkpoints"))
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let name = e.file_name().to_string_lossy().into_owned();
                    let step = name.strip_prefix("step-")?.parse().ok()?;
                    Some((step, e.path()))
                })
                .filter(|(_, p)| p.join("state.json").is_file())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// The folder of checkpoint `step`.
pub fn checkpoint_dir(run_dir: &Path, step: u64) -> PathBuf {
    run_dir.join("checkpoints").join(format!("step-{step:010}"))
}

/// Delete all but the newest `keep` checkpoints.
pub fn prune(run_dir: &Path, keep: usize) {
    let all = checkpoints(run_dir);
    for (_, dir) in all.iter().take(all.len().saturating_sub(keep.max(1))) {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// The folder holding a run's policy: `final/`, or with `step` that checkpoint,
/// or the newest checkpoint if the run has no final policy yet.
pub fn policy_dir(run_dir: &Path, step: Option<u64>) -> Result<PathBuf> {
    if !run_dir.is_dir() {
        bail!(
            "{} is not a run folder (it does not exist)",
            run_dir.display()
        );
    }
    let all = checkpoints(run_dir);
    if let Some(step) = step {
        return match all.iter().find(|(s, _)| *s == step) {
            Some((_, p)) => Ok(p.clone()),
            None => bail!(
                "run {} has no checkpoint at step {step}; it has: {}",
                run_dir.display(),
                all.iter()
                    .map(|(s, _)| s.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
    }
    let fin = run_dir.join("final");
    if fin.join("state.json").is_file() {
        return Ok(fin);
    }
    match all.last() {
        Some((_, p)) => Ok(p.clone()),
        None => bail!(
            "{} holds no trained policy (no final/ and no checkpoints/step-*/)",
            run_dir.display()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn running_variance_matches_the_batch_formula() {
        let xs: Vec<f64> = (0..100)
            .map(|i| (i as f64 * 0.37).sin() * 5.0 + 2.0)
            .collect();
        let mut r = RunningMeanStd {
            mean: 0.0,
            var: 0.0,
            count: 0.0,
        };
        for c in xs.chunks(7) {
            r.update(c);
        }
        let mean = xs.iter().sum::<f64>() / 100.0;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 100.0;
        assert!((r.mean - mean).abs() < 1e-9 && (r.var - var).abs() < 1e-9);
    }
}
