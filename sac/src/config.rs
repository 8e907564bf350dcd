//! SAC hyperparameters (thesis Table 4.5, SPEC §8), read from
//! `configs/train/sac.toml`. A plain serde struct: unknown keys are rejected
//! and missing keys take the documented defaults.

use deepfoids_env::Phase;
use deepfoids_env::config::ConfigError;
use deepfoids_learn::plan::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SacConfig {
    /// Adam learning rate, `[pretraining, transfer]`. Table 4.5: 0.001 / 0.0005.
    pub learning_rate: [f64; 2],
    /// Initial entropy coefficient α, `[pretraining, transfer]`. Table 4.5: 0.3 / 0.
    /// Zero switches the entropy term and its tuning off.
    pub init_entropy_coef: [f64; 2],
    /// Target entropy of the automatic α tuning: −|A| = −3.
    pub target_entropy: f64,
    /// Polyak factor of the target critics. Table 4.5: 0.005.
    pub tau: f32,
    /// Discount factor γ. Table 4.5: 0.99.
    pub gamma: f32,
    /// Transitions per gradient update. Table 4.5: 1024.
    pub batch_size: usize,
    /// Replay capacity in transitions, per behaviour. Table 4.5: 102,400.
    pub buffer_size: usize,
    /// Agent steps per gradient update, on average. Table 4.5: 1000
    /// (with 1,000 fish, one update per decision step).
    pub steps_per_update: f64,
    /// Agent steps collected (with the untrained policy) before the first update.
    pub learning_starts: u64,
    /// Table 4.5's time horizon (64). One-step TD targets do not use it; kept so
    /// the resolved config shows every value of the table.
    pub time_horizon: usize,
    /// Width of the dense layers. SPEC §8: 128.
    pub hidden: usize,
    /// Dense Swish layers. SPEC §8: 4.
    pub layers: usize,
    /// The actor's log σ is `lo + (hi − lo)·(tanh(x) + 1)/2` (CleanRL's bounds).
    pub log_std_bounds: [f32; 2],
    /// Adam ε (PyTorch's 1e−8).
    pub adam_epsilon: f64,
    /// Save the replay buffer with each checkpoint (off: smaller checkpoints, but
    /// a resumed run starts with an empty buffer).
    pub save_replay_buffer: bool,
    /// Write the scalars every this many agent decisions of a behaviour
    /// (10,240: PPO's cadence, so the two algorithms' curves line up).
    pub summary_every: u64,
    /// Save a checkpoint every this many agent decisions.
    pub checkpoint_every: u64,
    /// Checkpoints kept (older ones are deleted).
    pub keep_checkpoints: usize,
    /// A progress line every this many agent decisions of a behaviour when
    /// stdout is not a terminal (ML-Agents' `summary_freq`). 50,000.
    pub progress_every: u64,
    /// Agent decisions per species, `[pretraining, transfer]` (thesis §4.5.2).
    pub budgets: BTreeMap<String, [u64; 2]>,
}

impl Default for SacConfig {
    fn default() -> Self {
        Self {
            learning_rate: [0.001, 0.0005],
            init_entropy_coef: [0.3, 0.0],
            target_entropy: -3.0,
            tau: 0.005,
            gamma: 0.99,
            batch_size: 1024,
            buffer_size: 102_400,
            steps_per_update: 1000.0,
            learning_starts: 5000,
            time_horizon: 64,
            hidden: 128,
            layers: 4,
            log_std_bounds: [-5.0, 2.0],
            adam_epsilon: 1e-8,
            save_replay_buffer: true,
            summary_every: 10_240,
            checkpoint_every: 100_000,
            keep_checkpoints: 2,
            progress_every: 50_000,
            budgets: thesis_budgets(),
        }
    }
}

fn phase_index(phase: Phase) -> usize {
    match phase {
        Phase::Pretrain => 0,
        Phase::Transfer => 1,
    }
}

impl TrainConfigFile for SacConfig {
    const FILE: &'static str = "sac.toml";

    #[rustfmt::skip]
    fn sizes(&self) -> Vec<SizeBound> {
        vec![
            ("hidden", self.hidden as u64, 1, MAX_HIDDEN, "SPEC §8: 128"),
            ("layers", self.layers as u64, 1, MAX_LAYERS, "SPEC §8: 4"),
            ("buffer_size", self.buffer_size as u64, 1, MAX_BUFFER, "Table 4.5: 102400"),
            ("batch_size", self.batch_size as u64, 1, self.buffer_size as u64, "at most buffer_size; Table 4.5: 1024"),
            ("keep_checkpoints", self.keep_checkpoints as u64, 1, MAX_KEEP_CHECKPOINTS, "2"),
        ]
    }

    fn validate(&self, path: &std::path::Path) -> Result<(), ConfigError> {
        let bad = |field: &str, msg: String| Err(ConfigError::invalid(path, field, msg));
        for (i, &lr) in self.learning_rate.iter().enumerate() {
            if !(lr > 0.0 && lr <= 1.0) {
                return bad(
                    &format!("learning_rate[{i}]"),
                    format!("must lie in (0, 1], got {lr}"),
                );
            }
        }
        for (i, &a) in self.init_entropy_coef.iter().enumerate() {
            if !(a >= 0.0 && a.is_finite()) {
                return bad(
                    &format!("init_entropy_coef[{i}]"),
                    format!("must be a finite number ≥ 0 (0: no entropy term), got {a}"),
                );
            }
        }
        if !self.target_entropy.is_finite() {
            return bad(
                "target_entropy",
                format!("must be a finite number, got {}", self.target_entropy),
            );
        }
        if !(self.tau > 0.0 && self.tau <= 1.0) {
            return bad("tau", format!("must lie in (0, 1], got {}", self.tau));
        }
        if !(0.0..=1.0).contains(&self.gamma) {
            return bad("gamma", format!("must lie in [0, 1], got {}", self.gamma));
        }
        let counts = [
            ("batch_size", self.batch_size as u64),
            ("hidden", self.hidden as u64),
            ("layers", self.layers as u64),
            ("checkpoint_every", self.checkpoint_every),
            ("summary_every", self.summary_every),
            ("progress_every", self.progress_every),
        ];
        check_counts(path, &counts, self.batch_size, self.buffer_size)?;
        if !(self.steps_per_update >= 1.0 && self.steps_per_update.is_finite()) {
            return bad(
                "steps_per_update",
                format!(
                    "must be a finite number ≥ 1 (agent steps per update), got {}",
                    self.steps_per_update
                ),
            );
        }
        let [lo, hi] = self.log_std_bounds;
        if !(lo < hi && lo.is_finite() && hi.is_finite()) {
            return bad(
                "log_std_bounds",
                format!("must be two finite numbers [low, high] with low < high, got [{lo}, {hi}]"),
            );
        }
        Ok(())
    }
}

impl SacConfig {
    pub fn lr(&self, phase: Phase) -> f64 {
        self.learning_rate[phase_index(phase)]
    }

    pub fn init_alpha(&self, phase: Phase) -> f64 {
        self.init_entropy_coef[phase_index(phase)]
    }

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
    type Case = (fn(&mut SacConfig), &'static str);

    #[test]
    fn the_shipped_file_holds_table_4_5() {
        let dirs = ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"));
        let c = SacConfig::load(&dirs).unwrap();
        assert_eq!(c, SacConfig::default());
    }

    #[test]
    fn a_bad_value_names_the_field() {
        let c = SacConfig {
            tau: 0.0,
            ..Default::default()
        };
        let e = c.validate(std::path::Path::new("sac.toml")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "sac.toml: field `tau`: must lie in (0, 1], got 0"
        );
    }

    /// Issue 25: fields once checked in groups are each named by themselves.
    #[test]
    fn each_grouped_field_is_named_by_itself() {
        let path = std::path::Path::new("sac.toml");
        #[rustfmt::skip]
        let cases: [Case; 4] = [
            (|c| c.layers = 0, "field `layers`: must be at least 1, got 0"),
            (|c| c.summary_every = 0, "field `summary_every`: must be at least 1, got 0"),
            (|c| c.batch_size = 0, "field `batch_size`: must be at least 1, got 0"),
            (|c| c.learning_rate = [0.001, 2.0], "field `learning_rate[1]`: must lie in (0, 1], got 2"),
        ];
        for (edit, want) in cases {
            let mut c = SacConfig::default();
            edit(&mut c);
            let e = c.validate(path).unwrap_err().to_string();
            assert_eq!(e, format!("sac.toml: {want}"));
        }
    }
}
