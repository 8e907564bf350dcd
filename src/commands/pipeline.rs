//! `deepfoids pipeline`: the two-step scheme of thesis §4.5.2 (see
//! `deepfoids_experiments::pipeline`).

use crate::args::TrainOptionArgs;
use crate::args::whole;
use anyhow::Result;
use clap::Args;
use deepfoids_env::ConfigDirs;
use deepfoids_experiments::pipeline::PipelineOptions;

#[derive(Args, Debug)]
pub struct PipelineArgs {
    /// Species to train: its default scene, then every scene with only this
    /// species; `all`: every species, then every scene (mixed ones included)
    #[arg(long)]
    pub species: String,
    /// Pretraining budget per behaviour (agent decisions) [default: the thesis' budget]
    #[arg(value_parser = whole::<u64>, long)]
    pub pretrain_steps: Option<u64>,
    /// Transfer budget per behaviour and scene [default: the thesis' budget]
    #[arg(value_parser = whole::<u64>, long)]
    pub transfer_steps: Option<u64>,
    /// Only these target scenes (comma-separated) [default: all of the species, or all]
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Run name [default: pipeline-<algo>-<species>-s<seed>]
    #[arg(long)]
    pub run_id: Option<String>,
    #[command(flatten)]
    pub opts: TrainOptionArgs,
}

pub fn run(dirs: &ConfigDirs, args: &PipelineArgs) -> Result<()> {
    deepfoids_experiments::pipeline::run(
        dirs,
        &PipelineOptions {
            species: args.species.clone(),
            pretrain_steps: args.pretrain_steps,
            transfer_steps: args.transfer_steps,
            scenes: args.scenes.clone(),
            run_id: args.run_id.clone(),
            opts: args.opts.options(),
        },
    )
}
