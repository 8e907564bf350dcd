//! `deepfoids bench`: the arguments of each measurement
//! ([`deepfoids_experiments::bench`] runs them).

use crate::args::whole;
use crate::args::{algorithm, parse_backend};
use anyhow::Result;
use clap::{Args, Subcommand};
use deepfoids_env::ConfigDirs;
use deepfoids_experiments::bench::{self, TrainBench};
use deepfoids_learn::Algorithm;
use deepfoids_ppo::Rollout;
use std::path::PathBuf;

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Environment speed: agent-decisions per second with random actions, sensor included
    Env(BenchEnvArgs),
    /// Training speed: agent-steps per second end to end, and its split
    Train(BenchTrainArgs),
    /// Inference speed of a trained policy: Burn against its ONNX export through tract
    Policy(BenchPolicyArgs),
    /// Dataset rendering speed: frames per second with all labels
    Render(super::render::BenchRenderArgs),
    /// Counting speed: frames per second of `count` on a video or folder of frames
    Count(super::count::BenchCountArgs),
}

#[derive(Args, Debug)]
pub struct BenchPolicyArgs {
    /// Run folder of the policy
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Agents per forward pass
    #[arg(value_parser = whole::<usize>, long, default_value_t = 1000)]
    pub agents: usize,
    /// Timed repetitions
    #[arg(value_parser = whole::<usize>, long, default_value_t = 10)]
    pub reps: usize,
}

#[derive(Args, Debug)]
pub struct BenchTrainArgs {
    /// Scene id or path
    #[arg(long, default_value = "seabream_default", value_name = "ID|PATH")]
    pub scene: String,
    /// Agent decisions to train, per behaviour [default: enough for at least 3 updates
    /// of every behaviour, and at least 30,000]
    #[arg(value_parser = whole::<u64>, long)]
    pub steps: Option<u64>,
    /// Training algorithm
    #[arg(long, default_value = "ppo", value_parser = algorithm())]
    pub algo: Algorithm,
    /// Compute backend
    #[arg(long, default_value = "flex", value_parser = parse_backend)]
    pub backend: deepfoids_learn::Backend,
    /// PPO's rollout: `ml-agents` or `synchronous` [default: configs/train/ppo.toml's]
    #[arg(long, value_parser = parse_rollout)]
    pub rollout: Option<Rollout>,
    #[arg(value_parser = whole::<u64>, long, default_value_t = 0)]
    pub seed: u64,
}

#[derive(Args, Debug)]
pub struct BenchEnvArgs {
    /// Scene id or path
    #[arg(long, default_value = "coho_default", value_name = "ID|PATH")]
    pub scene: String,
    /// Simulated seconds to time (after the warm-up)
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Simulated seconds of warm-up, not timed
    #[arg(long, default_value_t = 2.0)]
    pub warmup: f64,
    #[arg(value_parser = whole::<u64>, long, default_value_t = 0)]
    pub seed: u64,
    /// How the sensor hands out the grids: `bytes` (what training and the
    /// trained policies use) or `floats` (the Python environment, ONNX)
    #[arg(long, value_enum, default_value_t = Grids::Bytes)]
    pub grids: Grids,
}

/// How `bench env`'s sensor hands out the grids.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Grids {
    Bytes,
    Floats,
}

fn parse_rollout(s: &str) -> Result<Rollout, String> {
    match s {
        "ml-agents" => Ok(Rollout::MlAgents),
        "synchronous" => Ok(Rollout::Synchronous),
        other => Err(format!(
            "unknown rollout `{other}`; allowed: ml-agents, synchronous"
        )),
    }
}

/// `deepfoids bench env`.
pub fn env(dirs: &ConfigDirs, args: &BenchEnvArgs) -> Result<()> {
    let format = match args.grids {
        Grids::Bytes => deepfoids_env::GridFormat::Bytes,
        Grids::Floats => deepfoids_env::GridFormat::Floats,
    };
    bench::env(
        dirs,
        &args.scene,
        args.seconds,
        args.warmup,
        args.seed,
        format,
    )
}

/// `deepfoids bench train`.
pub fn train(dirs: &ConfigDirs, args: &BenchTrainArgs) -> Result<()> {
    bench::train(
        dirs,
        &TrainBench {
            scene: args.scene.clone(),
            steps: args.steps,
            algo: args.algo,
            backend: args.backend,
            rollout: args.rollout,
            seed: args.seed,
        },
    )
}

/// `deepfoids bench policy`.
pub fn policy(args: &BenchPolicyArgs) -> Result<()> {
    bench::policy(&args.run, args.agents, args.reps)
}
