//! Argument parsing and dispatch.

use crate::commands;
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use deepfoids_env::{ConfigDirs, Phase};
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
    /// Worker threads [default: one per core]
    #[arg(long, global = true, value_name = "N")]
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
    /// Benchmarks
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
}

/// Options shared by every command that simulates.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Scene id (see `deepfoids scenes`) or path to a scene TOML file
    #[arg(long, value_name = "ID|PATH")]
    pub scene: String,
    /// Random seed: fish traits, placement, respawns, chases and random actions
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Reward weights of this phase
    #[arg(long, default_value = "pretrain", value_parser = parse_phase)]
    pub phase: Phase,
}

fn parse_phase(s: &str) -> Result<Phase, String> {
    s.parse()
}

#[derive(Args, Debug)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Who acts: `random`, `foids`, `boids`
    #[arg(long, default_value = "random")]
    pub policy: String,
    /// Simulated seconds
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Output folder [default: runs/simulate-<scene>-s<seed>]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Who acts: `foids`, `boids`, `random`
    #[arg(long, default_value = "foids")]
    pub policy: String,
    /// Simulated seconds
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Output folder [default: runs/eval-<scene>-<policy>-s<seed>]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct SensorViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Index of the fish to look through (0-based)
    #[arg(long, default_value_t = 0)]
    pub fish: usize,
    /// Ticks to simulate (random actions) before looking
    #[arg(long, default_value_t = 10)]
    pub step: u64,
    /// Output PNG
    #[arg(long, default_value = "view.png", value_name = "PNG")]
    pub out: PathBuf,
}

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Environment speed: agent-decisions per second with random actions, sensor included
    Env(BenchEnvArgs),
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
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Parse the command line and run the command.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    let dirs = cli
        .configs
        .clone()
        .map(ConfigDirs::new)
        .unwrap_or_else(ConfigDirs::discover);
    match cli.command {
        None => commands::default_job(&dirs),
        Some(Command::Scenes) => commands::scenes::run(&dirs),
        Some(Command::Simulate(a)) => commands::simulate::run(&dirs, &a),
        Some(Command::SensorView(a)) => commands::sensor_view::run(&dirs, &a),
        Some(Command::Eval(a)) => commands::eval::run(&dirs, &a),
        Some(Command::Bench {
            what: BenchCommand::Env(a),
        }) => commands::bench::env(&dirs, &a),
    }
}
