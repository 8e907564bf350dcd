//! Soft actor-critic on Burn for DeepFoids (SPEC §8; thesis §4.5.6, Table 4.5):
//! a tanh-squashed Gaussian actor and twin Q critics per behaviour, with a
//! replay buffer that stores each grid frame once, quantised.
//!
//! Runs share the PPO crate's run folders, logs and checkpoint layout
//! (`deepfoids_ppo::checkpoint`), so `eval`, `compare` and `pipeline` treat
//! both algorithms alike.

pub mod config;
pub mod model;
pub mod policy;
pub mod replay;
pub mod train;

pub use config::SacConfig;
pub use policy::SacPolicy;
pub use train::{SacTrainArgs, train};
