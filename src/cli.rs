//! Argument parsing and dispatch.

use crate::commands::bench::BenchCommand;
use crate::commands::{
    self, compare::CompareArgs, eval::EvalArgs, export::ExportArgs, pipeline::PipelineArgs,
    render::RenderArgs, replay::ReplayArgs, reproduce::ReproduceArgs, sensor_view::SensorViewArgs,
    simulate::SimulateArgs, train::TrainArgs,
};
use anyhow::{Context, Result};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use deepfoids_env::ConfigDirs;
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "deepfoids",
    version,
    about = "Multi-agent reinforcement-learning simulation of farmed fish schools (DeepFoids in Rust)",
    long_about = None
)]
pub struct Cli {
    /// Folder of the TOML configuration [default: ./configs, else $DEEPFOIDS_CONFIGS, else the repository's]
    #[arg(long, global = true, value_name = "DIR")]
    pub configs: Option<PathBuf>,
    /// Reward profile: a folder of `rewards/` in the configuration with the pretrain and transfer weights and SPEC §4/§6.1/§6.2 switches (`mean_then_budget_space20`, `thesis`, `legacy`, …) [default: mean_then_budget_space20; the quickstart: thesis]
    #[arg(long, global = true, value_name = "NAME")]
    pub reward_profile: Option<String>,
    /// Worker threads, 1 to 1024 (0 is refused) [default: one per core]
    #[arg(long, global = true, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// List the scenes with species, fish count, cage and density
    Scenes,
    /// Run a scene with a policy and write trajectories.csv
    Simulate(SimulateArgs),
    /// Draw what one fish sees: its stacked grid-sensor frames as a PNG
    SensorView(SensorViewArgs),
    /// Judge a school: P, M, state shares, collisions, depth — CSV, JSON and plots
    Eval(EvalArgs),
    /// Train one policy per behaviour of a scene (PPO or SAC)
    Train(TrainArgs),
    /// Pretrain a species in its default scene, then transfer-learn into each of its scenes
    Pipeline(PipelineArgs),
    /// Reproduce the thesis' claims (§4.5): train, evaluate, judge each claim, write a report
    Reproduce(ReproduceArgs),
    /// Export a trained policy to ONNX (Unity ML-Agents' interface)
    Export(ExportArgs),
    /// Compare runs (e.g. PPO against SAC): learning curves, reward terms, and a table of evaluations
    Compare(CompareArgs),
    /// Render a labelled image dataset (YOLO, COCO, masks) of a scene driven by a policy
    Render(RenderArgs),
    /// Count the fish in a cage video or folder of frames (thesis §4.4): the estimate is the max over frames
    Count(commands::count::CountArgs),
    /// Train the one-class fish detector `count` uses from `render` folders, exported to ONNX
    TrainDetector(commands::train_detector::TrainDetectorArgs),
    /// Fig. 4.12: black-pixel density in 16 annuli of fisheye frames, folder A against folder B
    ImageStats(commands::image_stats::ImageStatsArgs),
    /// Watch a school: one self-contained HTML replay (3D, scrub, follow a fish, P/M), and GIF clips
    Replay(ReplayArgs),
    /// Benchmarks
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
}

/// `--threads`: 1 to `MAX_THREADS`. 0 is refused rather than read as "all
/// cores" (rayon's meaning) or "one" (what it silently meant before): leaving
/// the option out already means one thread per core.
fn parse_threads(s: &str) -> Result<usize, String> {
    let max = deepfoids_env::limits::MAX_THREADS;
    match s.parse::<usize>() {
        Ok(0) => Err("0 threads cannot run anything; give 1 or more, or leave --threads out for one thread per core".into()),
        Ok(n) if n <= max => Ok(n),
        Ok(n) => Err(format!("{n} is above the limit of {max} threads")),
        Err(_) => Err(format!("`{s}` is not a thread count (1 to {max})")),
    }
}

/// Let negative numbers through as option values (`--seconds -1`), so that
/// the option's check refuses them with its range ("must be ≥ 0") instead of
/// clap reading `-1` as an unknown flag. Set on every (sub)command: clap's
/// setting does not reach subcommands by itself.
pub fn negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.allow_negative_numbers(true)
        .mut_subcommands(negative_numbers)
}

/// Parse the command line and run the command.
pub fn run() -> Result<()> {
    let matches = negative_numbers(Cli::command()).get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    let mut dirs = cli
        .configs
        .clone()
        .map(ConfigDirs::new)
        .unwrap_or_else(ConfigDirs::discover);
    match (&cli.reward_profile, &cli.command) {
        (Some(profile), _) => dirs = dirs.with_reward_profile(profile),
        // The quickstart's own profile, unless one is asked for.
        (None, None) => {
            dirs = dirs.with_reward_profile(commands::quickstart::QUICKSTART.reward_profile)
        }
        (None, Some(_)) => {}
    }
    match cli.command {
        None => commands::quickstart::default_job(&dirs),
        Some(Command::Scenes) => commands::scenes::run(&dirs),
        Some(Command::Simulate(a)) => commands::simulate::run(&dirs, &a),
        Some(Command::SensorView(a)) => commands::sensor_view::run(&dirs, &a),
        Some(Command::Eval(a)) => commands::eval::run(&dirs, &a),
        Some(Command::Train(a)) => commands::train::run(&dirs, &a).map(|_| ()),
        Some(Command::Pipeline(a)) => commands::pipeline::run(&dirs, &a),
        Some(Command::Reproduce(a)) => commands::reproduce::run(&dirs, &a),
        Some(Command::Export(a)) => commands::export::run(&a),
        Some(Command::Compare(a)) => commands::compare::run(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Train(a),
        }) => commands::bench::train(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Env(a),
        }) => commands::bench::env(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Policy(a),
        }) => commands::bench::policy(&a),
        Some(Command::Render(a)) => commands::render::run(&dirs, &a),
        Some(Command::Replay(a)) => commands::replay::run(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Render(a),
        }) => commands::render::bench(&dirs, &a),
        Some(Command::Count(a)) => commands::count::run(&a),
        Some(Command::TrainDetector(a)) => commands::train_detector::run(&a),
        Some(Command::ImageStats(a)) => commands::image_stats::run(&a),
        Some(Command::Bench {
            what: BenchCommand::Count(a),
        }) => commands::count::bench(&a),
    }
}
