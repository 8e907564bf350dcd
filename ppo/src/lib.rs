//! PPO for DeepFoids (SPEC §8; thesis §4.2, Table 4.4): one Gaussian policy
//! per behaviour, ML-Agents' rollout of per-agent trajectories, on the shared
//! learning core `deepfoids-learn` (network, kernels, run driver).

pub mod config;
pub mod gae;
pub mod gaussian;
pub mod inflight;
pub mod model;
pub mod policy;
pub mod reward_scale;
pub mod rollout;
pub mod train;

pub use config::{PpoConfig, Rollout};
pub use policy::{PpoActor, load_actor};
pub use train::Ppo;

use deepfoids_learn::driver::{RunArgs, TrainOutcome, run};

/// Train PPO on a scene (see `deepfoids_learn::driver`).
pub fn train(trainer: &Ppo, args: RunArgs) -> deepfoids_learn::Result<TrainOutcome> {
    run(trainer, args)
}
