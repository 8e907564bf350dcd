//! `deepfoids train`: train one policy per behaviour of a scene, then evaluate it.

use crate::args::whole;
use crate::args::{TrainOptionArgs, parse_phase};
use anyhow::Result;
use clap::Args;
use deepfoids_env::{ConfigDirs, Phase};
use deepfoids_experiments::training::{Trained, check_start, prepare_run_dir, train_scene};
use deepfoids_experiments::{bounds, load_scene, lock_dir, pretrained};
use deepfoids_learn::Budget;
use std::path::PathBuf;

#[derive(Args, Debug, Clone)]
pub struct TrainArgs {
    /// Scene id or path
    #[arg(long, value_name = "ID|PATH")]
    pub scene: String,
    /// Reward weights and budget of this phase
    #[arg(long, default_value = "pretrain", value_parser = parse_phase)]
    pub phase: Phase,
    /// Start from the weights of these runs (transfer learning; comma-separated
    /// or repeated, e.g. one per species): each behaviour takes the weights of
    /// a behaviour of the same name, else of the same species; steps start at 0;
    /// `pretrained:<species>` names a shipped policy
    #[arg(long, value_name = "RUN", value_delimiter = ',', value_parser = pretrained::parse_run)]
    pub init_from: Vec<PathBuf>,
    /// Agent decisions to train, per behaviour (each counts its own, as ML-Agents'
    /// max_steps) [default: the thesis' budget for its species and phase]
    #[arg(value_parser = whole::<u64>, long)]
    pub steps: Option<u64>,
    /// Agent decisions to train per fish: a behaviour of n fish trains n × this
    /// (equal training per fish in scenes of different school sizes; e.g. 13630
    /// gives density_sparse's 38 fish 517,940 steps and density_dense's 587
    /// fish 8,000,810)
    #[arg(value_parser = whole::<u64>, long, value_name = "DECISIONS", conflicts_with = "steps")]
    pub steps_per_fish: Option<u64>,
    /// Run name [default: <algo>-<scene>-<phase>-s<seed>]
    #[arg(long)]
    pub run_id: Option<String>,
    /// Continue the run from its last checkpoint
    #[arg(long)]
    pub resume: bool,
    /// Replace an existing run folder
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub opts: TrainOptionArgs,
}

impl TrainArgs {
    /// `--steps` or `--steps-per-fish`, if either is given.
    pub fn budget(&self) -> Option<Budget> {
        self.steps
            .map(Budget::Steps)
            .or(self.steps_per_fish.map(Budget::PerFish))
    }
}

pub fn run(dirs: &ConfigDirs, args: &TrainArgs) -> Result<Trained> {
    let opts = args.opts.options();
    let scene = load_scene(dirs, &args.scene, args.phase)?;
    let run_id = args.run_id.clone().unwrap_or_else(|| {
        format!(
            "{}-{}-{}-s{}",
            opts.algo.as_str(),
            scene.id,
            args.phase.as_str(),
            opts.seed
        )
    });
    let run_dir = opts.runs_dir.join(&run_id);
    if let Some(steps) = args.steps {
        bounds::train_steps("--steps", steps)?;
    }
    if let Some(per_fish) = args.steps_per_fish {
        bounds::train_steps("--steps-per-fish", per_fish)?;
    }
    let steps = args.budget();
    if !args.resume {
        // Before --force removes anything; train_scene checks again and prints the notes.
        check_start(dirs, &scene, steps, &args.init_from, &opts)?;
    }
    // One process per run folder, for the life of this one (issue 13 item 2).
    let _lock = lock_dir(&run_dir).map_err(|e| {
        if args.force {
            e.context("--force does not replace a run that is in use")
        } else {
            e
        }
    })?;
    prepare_run_dir(&run_dir, args.resume, args.force)?;
    train_scene(
        dirs,
        scene,
        &run_dir,
        &run_id,
        steps,
        &args.init_from,
        args.resume,
        &opts,
    )
}
