//! `deepfoids compare`: runs side by side — learning curves, reward terms and
//! a table of evaluations (see `deepfoids_experiments::compare`).

use crate::args::whole;
use anyhow::Result;
use clap::Args;
use deepfoids_env::ConfigDirs;
use deepfoids_experiments::compare::CompareOptions;
use deepfoids_experiments::pretrained;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Run folders (two or more); `pretrained:<species>` names a shipped policy
    #[arg(value_name = "RUN", required = true, num_args = 2.., value_parser = pretrained::parse_run)]
    pub runs: Vec<PathBuf>,
    /// Scene to evaluate every run in [default: the first run's]
    #[arg(long, value_name = "ID|PATH")]
    pub scene: Option<String>,
    /// Simulated seconds per evaluation
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Evaluation seeds 0..N, the same for every run
    #[arg(value_parser = whole::<u64>, long, default_value_t = 3, value_name = "N")]
    pub seeds: u64,
    /// Weight of the exponential moving average of the curves (TensorBoard's smoothing)
    #[arg(long, default_value_t = 0.6, value_name = "W")]
    pub smoothing: f64,
    /// Output folder
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Evaluate with the policies' means instead of sampled actions (the default, as Unity's inference did)
    #[arg(long)]
    pub deterministic: bool,
}

pub fn run(dirs: &ConfigDirs, args: &CompareArgs) -> Result<()> {
    deepfoids_experiments::compare::run(
        dirs,
        &CompareOptions {
            runs: args.runs.clone(),
            scene: args.scene.clone(),
            seconds: args.seconds,
            seeds: args.seeds,
            smoothing: args.smoothing,
            out: args.out.clone(),
            deterministic: args.deterministic,
        },
    )
}
