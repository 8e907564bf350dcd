//! Soft actor-critic for DeepFoids (SPEC §8; thesis §4.5.6, Table 4.5): a
//! tanh-squashed Gaussian actor and twin Q critics per behaviour, with a
//! replay buffer that stores each grid frame once, quantised, on the shared
//! learning core `deepfoids-learn` (network, kernels, run driver).

pub mod config;
pub mod model;
pub mod policy;
pub mod replay;
pub mod train;

pub use config::SacConfig;
pub use policy::{SacActor, load_actor};
pub use train::Sac;

use deepfoids_learn::driver::{RunArgs, TrainOutcome, run};

/// Train SAC on a scene (see `deepfoids_learn::driver`).
pub fn train(trainer: &Sac, args: RunArgs) -> deepfoids_learn::Result<TrainOutcome> {
    run(trainer, args)
}
