//! What a training run needs, known before it starts (issue 25): the memory
//! of its networks, experience and updates, and when its first update comes.
//!
//! Both are asked before a run folder is made, so that a config that cannot
//! fit, or a budget that would train nothing, is refused with one line that
//! names the file, the field and the figure instead of an OOM kill, an
//! allocation backtrace or a run that "finishes" with 0 updates.
//!
//! # Memory (per behaviour of `n` agents)
//! * **Networks.** [`body_params`] counts a body's parameters from SPEC §8's
//!   shapes; each trainable parameter costs [`TRAIN_BYTES_PER_PARAM`] (the
//!   weight, its gradient, Adam's two moments, the kernels' packed copies for
//!   acting and for the update, and Burn's transient copies in the step).
//! * **Experience.** Each algorithm's buffers ([`crate::frames`]: 1,360 bytes a
//!   quantised frame), counted from its own formula.
//! * **Update.** Per minibatch sample and body, the encoder's share
//!   ([`UPDATE_BYTES_PER_SAMPLE`]) and the dense layers' activations and
//!   gradients (`layers + 2` of `hidden` floats, four copies); acting's
//!   outputs and scratch per agent ([`ACTING_BYTES_PER_AGENT`]).
//!
//! The figures are upper bounds measured against a counting allocator
//! (`tests/train_config_fuzz.rs` in the root package).

use crate::kernels::geometry::{C_IN, C1, C2, CONV_FLAT, K1, K2};
use deepfoids_env::VECTOR_OBS;
use deepfoids_env::config::ConfigError;
use std::path::Path;

/// Widest dense layer a training config may ask for (SPEC §8: 128).
pub const MAX_HIDDEN: u64 = 4096;
/// Most dense Swish layers (SPEC §8: 4).
pub const MAX_LAYERS: u64 = 32;
/// Most passes over PPO's buffer per update (Table 4.4: 3; ML-Agents 3–10).
pub const MAX_EPOCHS: u64 = 100;
/// Longest time horizon in decisions (Table 4.4: 64).
pub const MAX_TIME_HORIZON: u64 = 100_000;
/// Largest buffer in transitions (Table 4.4: 10,240; Table 4.5: 102,400);
/// the memory check decides below this.
pub const MAX_BUFFER: u64 = 100_000_000;
/// Most checkpoints kept.
pub const MAX_KEEP_CHECKPOINTS: u64 = 1_000;

/// One size of a training config with a hard bound: the field, its value,
/// the allowed range, and what the tables use (e.g. "Table 4.4: 64").
pub type SizeBound = (&'static str, u64, u64, u64, &'static str);

/// A trainer's config file, `<configs>/train/<FILE>` (`ppo.toml`,
/// `sac.toml`): read with serde, then each field checked by itself
/// ([`validate`](Self::validate)), then the sizes' hard bounds
/// ([`sizes`](Self::sizes)); the memory they need together is checked before
/// a run starts (`driver::check_run`).
pub trait TrainConfigFile: serde::de::DeserializeOwned {
    /// The file's name under `<configs>/train/`.
    const FILE: &'static str;

    /// Each field by itself: the message names it with its allowed range
    /// (issue 25: `time_horizon = 0` was blamed on `buffer_size`).
    fn validate(&self, path: &Path) -> Result<(), ConfigError>;

    /// The sizes with a hard bound (this module's `MAX_*`).
    fn sizes(&self) -> Vec<SizeBound>;

    /// `<configs>/train/<FILE>`.
    fn path(dirs: &deepfoids_env::ConfigDirs) -> std::path::PathBuf {
        dirs.root.join("train").join(Self::FILE)
    }

    /// `<configs>/train/<FILE>`, read and checked.
    fn load(dirs: &deepfoids_env::ConfigDirs) -> Result<Self, ConfigError> {
        let path = Self::path(dirs);
        let cfg: Self = deepfoids_env::config::read_toml(&path)?;
        cfg.validate(&path)?;
        cfg.check_sizes(&path)?;
        Ok(cfg)
    }

    /// Every [`sizes`](Self::sizes) entry lies in its range.
    fn check_sizes(&self, path: &Path) -> Result<(), ConfigError> {
        for (field, value, lo, hi, usual) in self.sizes() {
            check_size(path, field, value, lo, hi, usual)?;
        }
        Ok(())
    }
}

/// The checks both trainers' files share: every `(field, value)` of `counts`
/// is at least 1, and `buffer_size` holds at least one minibatch.
pub fn check_counts(
    path: &Path,
    counts: &[(&str, u64)],
    batch_size: usize,
    buffer_size: usize,
) -> Result<(), ConfigError> {
    if let Some((field, _)) = counts.iter().find(|(_, v)| *v == 0) {
        return Err(ConfigError::invalid(
            path,
            *field,
            "must be at least 1, got 0",
        ));
    }
    if buffer_size < batch_size {
        return Err(ConfigError::invalid(
            path,
            "buffer_size",
            format!("must be at least batch_size ({batch_size}), got {buffer_size}"),
        ));
    }
    Ok(())
}

/// The thesis' budgets in agent decisions per species, `[pretraining,
/// transfer]` (§4.5.2).
pub fn thesis_budgets() -> std::collections::BTreeMap<String, [u64; 2]> {
    std::collections::BTreeMap::from([
        ("coho".to_string(), [4_000_000, 1_000_000]),
        ("yellowtail".to_string(), [2_000_000, 2_000_000]),
        ("seabream".to_string(), [2_000_000, 2_000_000]),
    ])
}

/// The budget of a behaviour of `species` in `phase` from a `budgets` table
/// (2,000,000 for a species it does not name).
pub fn budget_of(
    budgets: &std::collections::BTreeMap<String, [u64; 2]>,
    species: &str,
    phase: deepfoids_env::Phase,
) -> u64 {
    let k = match phase {
        deepfoids_env::Phase::Pretrain => 0,
        deepfoids_env::Phase::Transfer => 1,
    };
    budgets.get(species).map_or(2_000_000, |b| b[k])
}

/// `field = value` of the training config `path` must lie in `lo..=hi`;
/// `usual` says what the tables use (e.g. "Table 4.4: 64").
pub fn check_size(
    path: &Path,
    field: &str,
    value: u64,
    lo: u64,
    hi: u64,
    usual: &str,
) -> Result<(), ConfigError> {
    if (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(ConfigError::invalid(
        path,
        field,
        format!("{value} is out of range: allowed {lo} to {hi} ({usual})"),
    ))
}

/// Bytes per trainable parameter while training (see the module docs):
/// measured ≈ 35 with everything else of a run at 1,024 × 4 layers.
pub const TRAIN_BYTES_PER_PARAM: u64 = 48;

/// Bytes per minibatch sample and body in an update, besides the dense
/// layers: the quantised stack, the encoder's activations and gradients on
/// the non-zero cells (the update reads compact grids, never an f32 stack).
/// Measured 6–7 kB per sample and body (PPO and SAC, 10 fish, batches of 128
/// to 1,024; `experiments/tests/train_config_fuzz.rs`), plus the non-zero
/// inputs the forward pass keeps for the backward pass (8 bytes each, at
/// most a quarter of the 12,240 inputs when conv 1 runs sparse: ≤ 24.5 kB);
/// 40 KiB leaves room for denser grids.
pub const UPDATE_BYTES_PER_SAMPLE: u64 = 40 * 1024;

/// Bytes per agent while acting: its outputs, values and the fused
/// forward's share of scratch, rounded up.
pub const ACTING_BYTES_PER_AGENT: u64 = 16 * 1024;

/// Fixed costs of a learner: Burn's device, the optimiser's records and
/// the kernels' thread scratch (a generous 64 MiB).
pub const LEARNER_FIXED_BYTES: u64 = 64 << 20;

/// Parameters of one body (SPEC §8, [`crate::body`]): conv 18→16 8×8,
/// conv 16→32 4×4, dense 96→`hidden`, then `layers` dense `hidden` layers,
/// the first of which also takes the vector observation and `extra_inputs`.
pub fn body_params(hidden: u64, layers: u64, extra_inputs: u64) -> u64 {
    let conv1 = (C_IN * C1 * K1 * K1 + C1) as u64;
    let conv2 = (C1 * C2 * K2 * K2 + C2) as u64;
    let fc = CONV_FLAT as u64 * hidden + hidden;
    let first = (hidden + VECTOR_OBS as u64 + extra_inputs) * hidden + hidden;
    let rest = layers.saturating_sub(1) * (hidden * hidden + hidden);
    conv1 + conv2 + fc + first + rest
}

/// The update's activations for a minibatch of `batch` through `bodies`
/// bodies of `hidden` × `layers`.
pub fn update_bytes(batch: u64, bodies: u64, hidden: u64, layers: u64) -> u64 {
    let dense = (layers + 2) * hidden * 4 * 4;
    batch
        .saturating_mul(bodies)
        .saturating_mul(UPDATE_BYTES_PER_SAMPLE + dense)
}

/// The networks' part of a learner with `params` trainable parameters.
pub fn networks_part(params: u64, hidden: usize, layers: usize) -> Part {
    Part {
        name: "networks",
        bytes: params
            .saturating_mul(TRAIN_BYTES_PER_PARAM)
            .saturating_add(LEARNER_FIXED_BYTES),
        fields: format!("hidden = {hidden}, layers = {layers}"),
    }
}

/// The update's part: minibatches of `batch_size` through `bodies` bodies,
/// and acting for `agents` agents.
pub fn update_part(
    batch_size: usize,
    bodies: u64,
    hidden: usize,
    layers: usize,
    agents: usize,
) -> Part {
    Part {
        name: "update",
        bytes: update_bytes(batch_size as u64, bodies, hidden as u64, layers as u64)
            .saturating_add((agents as u64).saturating_mul(ACTING_BYTES_PER_AGENT)),
        fields: format!("batch_size = {batch_size}, hidden = {hidden}, layers = {layers}"),
    }
}

/// One part of a run's memory: what it is, its bytes, and the config fields
/// that set it (for the message that refuses it).
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub name: &'static str,
    pub bytes: u64,
    /// E.g. "hidden = 128, layers = 4".
    pub fields: String,
}

/// A training run's memory, by part.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MemoryPlan {
    pub parts: Vec<Part>,
}

impl MemoryPlan {
    pub fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0u64, |s, p| s.saturating_add(p.bytes))
    }

    /// Add `other`'s parts to the part of the same name.
    pub fn merge(&mut self, other: MemoryPlan) {
        for p in other.parts {
            match self.parts.iter_mut().find(|q| q.name == p.name) {
                Some(q) => q.bytes = q.bytes.saturating_add(p.bytes),
                None => self.parts.push(p),
            }
        }
    }

    /// The largest part.
    pub fn largest(&self) -> Option<&Part> {
        self.parts.iter().max_by_key(|p| p.bytes)
    }

    /// "networks 1.2 MB (hidden = 128, layers = 4); experience …".
    pub fn describe(&self) -> String {
        self.parts
            .iter()
            .map(|p| {
                format!(
                    "{} {} ({})",
                    p.name,
                    deepfoids_env::memory::human(p.bytes),
                    p.fields
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// When a behaviour's first update comes, and how many its budget makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UpdatePlan {
    /// No budget below this many agent steps makes an update, however the
    /// episodes end (PPO: the buffer must hold `buffer_size` transitions).
    pub earliest: u64,
    /// Agent steps of the behaviour before its first update when no episode
    /// ends early (PPO: an episode end closes a trajectory early, which
    /// brings updates forward — an untrained school that crashes often
    /// updates far sooner — and shifts the agent's later joins by up to a
    /// time horizon).
    pub first: u64,
    /// Agent steps between updates after the first.
    pub every: u64,
}

impl UpdatePlan {
    /// Updates a budget of `budget` agent steps makes.
    pub fn updates(&self, budget: u64) -> u64 {
        if budget < self.first {
            0
        } else {
            1 + (budget - self.first) / self.every.max(1)
        }
    }

    /// The smallest budget that makes `k` updates (`k` ≥ 1).
    pub fn budget_for(&self, k: u64) -> u64 {
        self.first
            .saturating_add(k.saturating_sub(1).saturating_mul(self.every.max(1)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SPEC §8's body at 128 × 4: conv 1 18·16·64 + 16 = 18,448; conv 2
    /// 16·32·16 + 32 = 8,224; dense 96·128 + 128 = 12,416; the first trunk
    /// layer (128 + 6)·128 + 128 = 17,280; three more 3 × 16,512 = 49,536.
    #[test]
    fn the_body_of_spec_8_has_105_904_parameters() {
        assert_eq!(
            body_params(128, 4, 0),
            18_448 + 8_224 + 12_416 + 17_280 + 49_536
        );
        assert_eq!(body_params(128, 4, 3) - body_params(128, 4, 0), 3 * 128);
    }

    /// PPO's 1,000 coho under ML-Agents' rollout: a trajectory joins every 64
    /// decisions, 64,000 transitions ≥ 10,240: the first update at the
    /// decision that brings 64,000 agent steps, if the budget is above that,
    /// then every 64,000. 30,000 steps make none, 64,000 none, 200,000 make 3.
    #[test]
    fn updates_in_a_budget() {
        let p = UpdatePlan {
            earliest: 11_001,
            first: 64_001,
            every: 64_000,
        };
        assert_eq!(p.updates(30_000), 0);
        assert_eq!(p.updates(64_000), 0);
        assert_eq!(p.updates(64_001), 1);
        assert_eq!(p.updates(200_000), 3);
        assert_eq!(p.budget_for(3), 192_001);
        assert_eq!(p.updates(p.budget_for(3)), 3);
    }

    #[test]
    fn plans_merge_by_part_and_name_the_largest() {
        let part = |name, bytes| Part {
            name,
            bytes,
            fields: String::new(),
        };
        let mut a = MemoryPlan {
            parts: vec![part("networks", 10), part("experience", 5)],
        };
        a.merge(MemoryPlan {
            parts: vec![part("experience", 20), part("update", 1)],
        });
        assert_eq!(a.total(), 36);
        assert_eq!(a.largest().unwrap().name, "experience");
        assert_eq!(a.parts.len(), 3);
    }
}
