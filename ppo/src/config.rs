//! PPO hyperparameters (thesis Table 4.4, SPEC §8), read from
//! `configs/train/ppo.toml`. A plain serde struct: unknown keys are rejected
//! and missing keys take the documented defaults.

use deepfoids_env::Phase;
use deepfoids_env::config::ConfigError;
use deepfoids_learn::plan::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// How experience is cut into updates (SPEC §8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Rollout {
    /// ML-Agents' (the default, Table 4.4 as ML-Agents runs it): each agent's
    /// trajectory ends after `time_horizon` decisions or at the end of its
    /// episode and then joins the buffer; an update happens once the buffer
    /// holds at least `buffer_size` transitions (1,000 coho: after 64
    /// decisions, 64,000 transitions).
    MlAgents,
    /// The scheme before issue 12: every `ceil(buffer_size / agents)`
    /// decisions of a behaviour (11 for 1,000 coho), every agent's trajectory
    /// is cut there, bootstrapped, and the buffer is used; `time_horizon`
    /// cuts still apply within.
    Synchronous,
}

/// How the learning rate changes over the budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// From `learning_rate` to 0 at the end of the budget (ML-Agents' "linear").
    Linear,
    Constant,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PpoConfig {
    /// Adam learning rate at the start. Table 4.4: 0.001.
    pub learning_rate: f64,
    /// Learning-rate schedule. Table 4.4: linear decay.
    pub lr_schedule: Schedule,
    /// Discount factor γ. Table 4.4: 0.99.
    pub gamma: f32,
    /// GAE λ. Table 4.4: 0.95.
    pub gae_lambda: f32,
    /// Clip range ε of the surrogate objective. Table 4.4: 0.2.
    pub clip_epsilon: f32,
    /// Value-loss coefficient c. Table 4.4: 0.5.
    pub value_coef: f32,
    /// Entropy coefficient β. Table 4.4: 0.0005.
    pub entropy_coef: f32,
    /// How experience is cut into updates: "ml-agents" (default) or "synchronous".
    pub rollout: Rollout,
    /// Transitions needed for an update, per behaviour. Table 4.4: 10240.
    pub buffer_size: usize,
    /// Minibatch size. Table 4.4: 1024.
    pub batch_size: usize,
    /// Passes over the buffer per update. Table 4.4: 3.
    pub epochs: usize,
    /// Decisions per trajectory: an agent's trajectory is cut there and
    /// bootstrapped from the critic. Table 4.4: 64.
    pub time_horizon: usize,
    /// Global gradient-norm clip, applied to the actor's and the critic's parameters separately. 0.5.
    pub max_grad_norm: f32,
    /// Normalise advantages per minibatch (mean 0, std 1). true.
    pub normalize_advantages: bool,
    /// Divide rewards by the running std of the discounted return before GAE. true.
    pub normalize_rewards: bool,
    /// Initial log-std of the Gaussian policy. −1.0986 = ln(1/3): ML-Agents feeds
    /// `clamp(a, −3, 3)/3` to the environment, so its initial σ = 1 is σ ≈ 0.33 in
    /// environment units; with σ = 1 here, random speed and pitch changes make
    /// living so costly that crashing (−300, episode over) pays.
    pub init_log_std: f32,
    /// Width of the dense layers. SPEC §8: 128.
    pub hidden: usize,
    /// Dense Swish layers. SPEC §8: 4.
    pub layers: usize,
    /// Adam ε (PyTorch's 1e−8; Burn's default is 1e−5).
    pub adam_epsilon: f64,
    /// Save a checkpoint every this many agent decisions. 100,000.
    pub checkpoint_every: u64,
    /// Checkpoints kept (older ones are deleted). 5.
    pub keep_checkpoints: usize,
    /// A progress line every this many agent decisions of a behaviour when
    /// stdout is not a terminal (ML-Agents' `summary_freq`). 50,000.
    pub progress_every: u64,
    /// Agent decisions per species, `[pretraining, transfer]` (thesis §4.5.2).
    pub budgets: BTreeMap<String, [u64; 2]>,
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            learning_rate: 0.001,
            lr_schedule: Schedule::Linear,
            gamma: 0.99,
            gae_lambda: 0.95,
            clip_epsilon: 0.2,
            value_coef: 0.5,
            entropy_coef: 0.0005,
            rollout: Rollout::MlAgents,
            buffer_size: 10240,
            batch_size: 1024,
            epochs: 3,
            time_horizon: 64,
            max_grad_norm: 0.5,
            normalize_advantages: true,
            normalize_rewards: true,
            init_log_std: -1.0986,
            hidden: 128,
            layers: 4,
            adam_epsilon: 1e-8,
            checkpoint_every: 100_000,
            keep_checkpoints: 5,
            progress_every: 50_000,
            budgets: thesis_budgets(),
        }
    }
}

impl TrainConfigFile for PpoConfig {
    const FILE: &'static str = "ppo.toml";

    #[rustfmt::skip]
    fn sizes(&self) -> Vec<SizeBound> {
        vec![
            ("hidden", self.hidden as u64, 1, MAX_HIDDEN, "SPEC §8: 128"),
            ("layers", self.layers as u64, 1, MAX_LAYERS, "SPEC §8: 4"),
            ("epochs", self.epochs as u64, 1, MAX_EPOCHS, "Table 4.4: 3"),
            ("time_horizon", self.time_horizon as u64, 1, MAX_TIME_HORIZON, "Table 4.4: 64"),
            ("buffer_size", self.buffer_size as u64, 1, MAX_BUFFER, "Table 4.4: 10240"),
            ("batch_size", self.batch_size as u64, 1, self.buffer_size as u64, "at most buffer_size; Table 4.4: 1024"),
            ("keep_checkpoints", self.keep_checkpoints as u64, 1, MAX_KEEP_CHECKPOINTS, "5"),
        ]
    }

    fn validate(&self, path: &std::path::Path) -> Result<(), ConfigError> {
        let bad = |field: &str, msg: String| Err(ConfigError::invalid(path, field, msg));
        if !(self.learning_rate > 0.0 && self.learning_rate <= 1.0) {
            return bad(
                "learning_rate",
                format!("must lie in (0, 1], got {}", self.learning_rate),
            );
        }
        for (field, v) in [("gamma", self.gamma), ("gae_lambda", self.gae_lambda)] {
            if !(0.0..=1.0).contains(&v) {
                return bad(field, format!("must lie in [0, 1], got {v}"));
            }
        }
        for (field, v) in [
            ("clip_epsilon", self.clip_epsilon),
            ("max_grad_norm", self.max_grad_norm),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return bad(field, format!("must be a finite number above 0, got {v}"));
            }
        }
        let counts = [
            ("batch_size", self.batch_size as u64),
            ("epochs", self.epochs as u64),
            ("time_horizon", self.time_horizon as u64),
            ("hidden", self.hidden as u64),
            ("checkpoint_every", self.checkpoint_every),
            ("progress_every", self.progress_every),
        ];
        check_counts(path, &counts, self.batch_size, self.buffer_size)
    }
}

impl PpoConfig {
    /// The thesis' budget of a behaviour of `species` in `phase` (its own agent decisions).
    pub fn budget(&self, species: &str, phase: Phase) -> u64 {
        budget_of(&self.budgets, species, phase)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepfoids_env::ConfigDirs;

    /// An edit of the defaults, and the error it must give.
    type Case = (fn(&mut PpoConfig), &'static str);

    #[test]
    fn the_shipped_file_holds_table_4_4() {
        let dirs = ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"));
        let c = PpoConfig::load(&dirs).unwrap();
        assert_eq!(c, PpoConfig::default());
        assert_eq!(c.budget("coho", Phase::Pretrain), 4_000_000);
        assert_eq!(c.budget("seabream", Phase::Transfer), 2_000_000);
    }

    /// Regression (issue 25): `time_horizon = 0` was reported as an error of
    /// `buffer_size`. Each field is named by itself, with its range.
    #[test]
    fn each_bad_value_names_its_own_field_and_range() {
        let path = std::path::Path::new("configs/train/ppo.toml");
        #[rustfmt::skip]
        let cases: [Case; 8] = [
            (|c| c.time_horizon = 0, "field `time_horizon`: must be at least 1, got 0"),
            (|c| c.epochs = 0, "field `epochs`: must be at least 1, got 0"),
            (|c| c.hidden = 0, "field `hidden`: must be at least 1, got 0"),
            (|c| c.batch_size = 0, "field `batch_size`: must be at least 1, got 0"),
            (|c| c.buffer_size = 100, "field `buffer_size`: must be at least batch_size (1024), got 100"),
            (|c| c.gae_lambda = 1.5, "field `gae_lambda`: must lie in [0, 1], got 1.5"),
            (|c| c.max_grad_norm = -1.0, "field `max_grad_norm`: must be a finite number above 0, got -1"),
            (|c| c.progress_every = 0, "field `progress_every`: must be at least 1, got 0"),
        ];
        for (edit, want) in cases {
            let mut c = PpoConfig::default();
            edit(&mut c);
            let e = c.validate(path).unwrap_err().to_string();
            assert_eq!(e, format!("configs/train/ppo.toml: {want}"));
        }
    }
}
