//! The DeepFoids sea-cage world (SPEC §1–7): species, sites and scenes from
//! TOML, the cage, light and temperature, fish kinematics with the
//! decision-interval scheme, collisions, dominance and chases, the seven-term
//! reward, per-agent episodes, and the multi-agent [`Env`].
//!
//! No learning library is involved: observations, rewards and actions are flat
//! `f32` buffers, one contiguous batch per behaviour.

pub mod baselines;
pub mod cage;
mod chase;
pub mod collide;
pub mod config;
pub mod env;
pub mod forces;
pub mod kinematics;
pub mod limits;
pub mod memory;
pub mod metrics;
mod physics;
pub mod policy;
pub mod reward;
pub mod rng;
pub mod scene;
mod sensing;
mod state;
pub mod sun;
pub mod traits;
pub mod world;

pub use config::{ConfigDirs, ConfigError, Phase};
pub use deepfoids_sensors::{GridFormat, GridsRef};
pub use env::{
    BehaviourBatch, BehaviourInfo, Env, EnvError, FishState, N_TERMS, StageTimes, StepOutput,
    TERM_NAMES, VECTOR_OBS,
};
pub use policy::{Policy, PolicyError, RandomPolicy};
pub use scene::Scene;
pub use traits::FishParams;
pub use world::{Chase, World};
