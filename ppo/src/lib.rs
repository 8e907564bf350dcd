//! PPO on Burn for DeepFoids (SPEC §8; thesis §4.2, Table 4.4): one Gaussian
//! policy per behaviour, trained in the multi-agent environment, with the
//! two-step scheme of pretraining and transfer learning.

pub mod checkpoint;
pub mod config;
pub mod gae;
pub mod gaussian;
pub mod logger;
pub mod model;
pub mod policy;
pub mod stats;
pub mod train;

pub use config::PpoConfig;
pub use policy::TrainedPolicy;
pub use train::{Backend, BufferMemory, TrainArgs, TrainOutcome, train};
